"""HDR uplift: merge, recursion, predictors, panoramas, the converter and CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from conftest import TEST_HDRI, run_cli, write_jpeg

from gaslight_usd import colour
from gaslight_usd.errors import InputError
from gaslight_usd.imageio import read_image
from gaslight_usd.uplift import (
    GAMMA22,
    SRGB,
    available_predictors,
    get_predictor,
    input_transform,
    merge_stack,
    stack_weights,
    uplift_recursive,
)
from gaslight_usd.uplift.fast_predictor import (
    FEATURES,
    PARAMS_FILE,
    PARTIAL_LIMIT,
    PROFILES,
    FastPredictor,
    Mlp,
    RegionFeatures,
    fill_clipped,
    peak_cap,
    profile_weights,
    spread,
)
from gaslight_usd.uplift.merge import trapezoid
from gaslight_usd.uplift.panorama import faces_to_latlong, latlong_to_faces, uplift_panorama
from gaslight_usd.uplift.predictors import ReexposePredictor


def lamp_scene(size: int = 64, peak: float = 1000.0) -> np.ndarray:
    """Linear HDR: a grey gradient wall and a Gaussian lamp of the given peak."""
    y, x = np.mgrid[0:size, 0:size].astype(np.float32)
    wall = 0.05 + 0.3 * x / size
    r2 = (x - size * 0.6) ** 2 + (y - size * 0.4) ** 2
    lamp = peak * np.exp(-r2 / (2 * (size / 16) ** 2))
    hdr = (wall + lamp)[..., None] * np.array([1.0, 0.9, 0.7], np.float32)
    return hdr.astype(np.float32)


def test_paper_weights_hand_values():
    v = np.array([0.0, 0.1, 0.5, 0.8, 0.9, 1.0], np.float32)
    np.testing.assert_allclose(trapezoid(v, 0.0, 0.8), [1, 1, 1, 1, 0.5, 0], atol=1e-6)  # EV 0
    np.testing.assert_allclose(trapezoid(v, 0.5, 0.5), [0, 0.2, 1, 0.4, 0.2, 0], atol=1e-6)
    np.testing.assert_allclose(trapezoid(v, 0.5, 1.0), [0, 0.2, 1, 1, 1, 1], atol=1e-6)  # darkest
    w = stack_weights(np.stack([v, v, v]), [0.0, -2.0, -4.0])
    np.testing.assert_allclose(w[0], trapezoid(v, 0.0, 0.8))
    np.testing.assert_allclose(w[2], trapezoid(v, 0.5, 1.0))


def test_merge_of_exact_exposures_recovers_radiance():
    hdr = lamp_scene(peak=3000.0)
    evs = [0.0, -2.0, -4.0, -6.0, -8.0, -10.0, -12.0]
    stack = [np.clip(GAMMA22.to_encoded(np.clip(hdr * 2.0 ** e, 0, 1)), 0, 1) for e in evs]
    merged = merge_stack(stack, evs, GAMMA22)
    np.testing.assert_allclose(merged, hdr, rtol=1e-3)


def test_recursion_with_oracle_takes_just_enough_steps():
    hdr = lamp_scene(peak=1000.0)
    photo = SRGB.to_encoded(np.clip(hdr, 0, 1))
    res = uplift_recursive(photo, get_predictor("oracle", hdr=hdr), SRGB)
    # 1000 / 4**5 = 0.98 still encodes above 0.9; 1000 / 4**6 = 0.24 does not.
    assert res.evs == [0.0, -2.0, -4.0, -6.0, -8.0, -10.0, -12.0]
    np.testing.assert_allclose(res.linear, hdr, rtol=2e-3)
    three = uplift_recursive(photo, get_predictor("oracle", hdr=hdr), SRGB, max_steps=3)
    assert three.darker_steps == 3 and three.linear.max() == pytest.approx(64.0, rel=1e-3)
    loose = uplift_recursive(photo, get_predictor("oracle", hdr=hdr), SRGB, threshold=0.995)
    assert loose.darker_steps == 5  # 1000 / 4**5 encodes to 0.990


def test_unclipped_photo_gets_no_step_and_stays_exact():
    hdr = lamp_scene(peak=0.5)
    photo = SRGB.to_encoded(hdr)
    for name in ("fast", "reexpose"):
        res = uplift_recursive(photo, get_predictor(name), SRGB)
        assert res.evs == [0.0]
        np.testing.assert_allclose(res.linear, SRGB.to_linear(photo), rtol=1e-6)


def test_reexpose_predictor_keeps_the_baseline():
    hdr = lamp_scene(peak=100.0)
    photo = SRGB.to_encoded(np.clip(hdr, 0, 1))
    res = uplift_recursive(photo, ReexposePredictor(), SRGB)
    assert res.darker_steps == 1  # the re-exposed clip (0.25) is below the threshold
    np.testing.assert_allclose(res.linear, SRGB.to_linear(photo), rtol=1e-3, atol=1e-6)


def test_fast_predictor_fills_clipped_lamp_and_keeps_the_rest():
    hdr = lamp_scene(size=96, peak=400.0)
    photo = np.round(SRGB.to_encoded(np.clip(hdr, 0, 1)) * 255) / 255
    clipped = photo.max(axis=-1) >= 0.99
    assert clipped.sum() > 20
    res = uplift_recursive(photo, FastPredictor(), SRGB)
    out = res.linear
    # nothing left at the clip level: every clipped pixel is predicted above white
    assert np.all(out[clipped].max(axis=-1) > 1.0)
    assert res.stack[-1].max() < 0.9
    # unclipped pixels are the plain linearisation
    np.testing.assert_allclose(out[~clipped], SRGB.to_linear(photo)[~clipped], rtol=1e-3,
                               atol=1e-5)
    # the lamp's energy is closer to the truth than the clipped photo's
    truth, base = hdr[clipped].sum(), SRGB.to_linear(photo)[clipped].sum()
    assert abs(np.log2(out[clipped].sum() / truth)) < abs(np.log2(base / truth))
    # brighter towards the lamp centre (the profile has a shape, not a flat fill)
    centre = np.unravel_index(np.argmax(hdr[..., 0]), hdr.shape[:2])
    assert out[centre].max() >= np.percentile(out[clipped].max(axis=-1), 90)


def test_fast_predictor_shrinks_its_estimates_towards_white():
    from gaslight_usd.uplift.fast_predictor import SHRINK, region_features

    hdr = lamp_scene(size=96, peak=400.0)
    photo = np.round(SRGB.to_encoded(np.clip(hdr, 0, 1)) * 255) / 255
    regions = region_features(SRGB.to_linear(photo).astype(np.float32), photo.astype(np.float32))
    raw, shipped = FastPredictor(shrink=1.0), FastPredictor()
    assert 0 < SHRINK < 1 and shipped.shrink == SHRINK
    np.testing.assert_allclose(shipped.region_log_means(regions),
                               SHRINK * raw.region_log_means(regions), rtol=1e-6)
    clipped = photo.max(axis=-1) >= 0.99
    energy = [uplift_recursive(photo, f, SRGB).linear[clipped].sum() for f in (shipped, raw)]
    assert 1.0 * clipped.sum() < energy[0] < energy[1]


def test_fast_predictor_agrees_with_itself_down_the_stack():
    hdr = lamp_scene(size=64, peak=5000.0)
    photo = SRGB.to_encoded(np.clip(hdr, 0, 1))
    fast = FastPredictor()
    res = uplift_recursive(photo, fast, SRGB)
    estimate = fast.estimate(photo, SRGB)
    for img, ev in zip(res.stack[1:], res.evs[1:], strict=True):
        expected = SRGB.to_encoded(np.clip(estimate * 2.0 ** ev, 0, 1))
        np.testing.assert_allclose(img, expected, atol=1e-5)


def _square_region(size: int = 9, side: int = 5) -> RegionFeatures:
    mask = np.zeros((size, size), bool)
    lo = (size - side) // 2
    mask[lo:lo + side, lo:lo + side] = True
    from scipy import ndimage

    return RegionFeatures(mask=mask, labels=mask.astype(np.int32),
                          features=np.zeros((1, len(FEATURES)), np.float32),
                          chroma=np.ones((1, 3), np.float32),
                          depth=ndimage.distance_transform_edt(mask).astype(np.float32),
                          area=np.array([float(side * side)]))


def test_spread_is_a_cone_that_keeps_the_mean_and_respects_the_cap():
    # 5x5 square: depths 1 (16 px), 2 (8 px), 3 (centre); mean depth 35 / 25 = 1.4
    region = _square_region()
    depth = region.depth[region.mask]
    values = spread(region, np.array([np.log2(3.0)]), cap=1e6)
    np.testing.assert_allclose(values, 1 + 2 * depth / 1.4, rtol=1e-6)
    assert values.mean() == pytest.approx(3.0, rel=1e-6)
    # cap 4: flattened halfway (w = 0.4375 d / 1.4 + 0.5625), the centre exactly at the cap
    capped = spread(region, np.array([np.log2(3.0)]), cap=4.0)
    np.testing.assert_allclose(capped, 1 + 2 * (0.4375 * depth / 1.4 + 0.5625), rtol=1e-6)
    assert capped.max() == pytest.approx(4.0) and capped.mean() == pytest.approx(3.0)
    # a cap below the mean: uniform at the cap
    np.testing.assert_allclose(spread(region, np.array([np.log2(3.0)]), cap=2.5), 2.5)


def test_fast_predictor_leaves_no_clipped_pixel_even_when_it_overshoots():
    """"No clipped pixel left": the darkest exposure of the stack is below the threshold.

    A predictor forced to guess 2^30 x white everywhere is capped at what EV -12
    shows at 0.85, so the recursion ends within its 6 steps with nothing clipped,
    and the merge returns the (capped) estimate.
    """
    hdr = lamp_scene(size=64, peak=1e7)
    photo = SRGB.to_encoded(np.clip(hdr, 0, 1))
    clipped = photo.max(axis=-1) >= 0.99
    params = json.loads(PARAMS_FILE.read_text())
    params["model"]["layers"][-1][1] = [30.0]
    params["model"]["layers"][-1][0] = [[0.0]] * len(params["model"]["layers"][-1][0])
    greedy = FastPredictor(params)
    res = uplift_recursive(photo, greedy, SRGB)
    assert res.darker_steps == 6 and res.stack[-1].max() < 0.9
    cap = peak_cap(SRGB)
    assert cap == pytest.approx(4096 * SRGB.to_linear(np.float32(0.85)), rel=1e-6)
    assert res.linear.max() == pytest.approx(cap, rel=2e-3)
    assert np.all(np.isfinite(res.linear)) and np.all(res.linear[clipped].max(axis=-1) >= 1.0)
    for fast in (FastPredictor(), greedy):  # the shipped model, same guarantee
        for threshold in (0.9, 0.95):
            r = uplift_recursive(photo, fast, SRGB, threshold=threshold)
            assert r.stack[-1].max() < threshold


def test_profile_mix_keeps_the_mean_and_peaks_with_the_power():
    region = _square_region()
    depth = region.depth[region.mask]
    cone = profile_weights(region)
    np.testing.assert_allclose(cone, depth / 1.4, rtol=1e-6)  # the default: the cone
    for k, power in enumerate(PROFILES):
        mix = np.zeros((1, len(PROFILES)))
        mix[0, k] = 1.0
        w = profile_weights(region, mix)
        np.testing.assert_allclose(w, depth ** power / np.mean(depth ** power), rtol=1e-6)
    half = np.full((1, len(PROFILES)), 1.0 / len(PROFILES))
    w = profile_weights(region, half)
    assert w.mean() == pytest.approx(1.0, rel=1e-6)
    # the centre (depth 3) of the steepest shape holds 3^12 / (16 + 8 * 2^12 + 3^12) of it
    steep = np.zeros((1, len(PROFILES)))
    steep[0, -1] = 1.0
    centre = profile_weights(region, steep)[depth == 3].item() / 25
    assert PROFILES[-1] == 12.0
    assert centre == pytest.approx(3.0 ** 12 / (16 + 8 * 2.0 ** 12 + 3.0 ** 12), rel=1e-6)


def test_fill_clipped_bounds_a_channel_by_the_measured_ones():
    """Hand values: one all-clipped pixel and one where only blue clips, sky-blue ring."""
    region = _square_region(size=5, side=1)  # a single clipped pixel region, depth 1
    mask = np.zeros((5, 5), bool)
    mask[2, 2] = mask[2, 3] = True
    labels = mask.astype(np.int32)
    region = RegionFeatures(mask=mask, labels=labels, features=region.features,
                            chroma=np.array([[0.5, 0.8, 1.0]], np.float32),
                            depth=mask.astype(np.float32), area=np.array([2.0]))
    encoded = np.full((5, 5, 3), 0.5, np.float32)
    encoded[2, 2] = 1.0                      # all channels clip
    encoded[2, 3] = [0.8, 0.9, 1.0]          # only blue clips
    linear = SRGB.to_linear(encoded)
    value = np.array([6.0, 6.0], np.float32)  # brightest-channel estimate of both pixels
    ring = fill_clipped(linear, encoded, region, value)
    np.testing.assert_allclose(ring[2, 2], [3.0, 4.8, 6.0], rtol=1e-6)  # 6 x ring colour
    r, g = SRGB.to_linear(np.float32(0.8)), SRGB.to_linear(np.float32(0.9))
    implied = max(r / 0.5, g / 0.8)  # what red and green say blue is, through the ring
    np.testing.assert_allclose(ring[2, 3], [r, g, PARTIAL_LIMIT * implied], rtol=1e-5)
    assert ring[2, 3, 2] < 6.0 / 3  # not the 6x estimate: a sky stays a sky
    # half white: the all-clipped pixel takes (0.5 ring + 0.5 white) x 6
    half = fill_clipped(linear, encoded, region, value, np.array([0.5], np.float32))
    np.testing.assert_allclose(half[2, 2], [4.5, 5.4, 6.0], rtol=1e-6)
    np.testing.assert_array_equal(half[~mask], linear[~mask])  # the rest untouched


def test_one_output_model_renders_cones_in_the_ring_colour():
    params = json.loads(PARAMS_FILE.read_text())["model"]
    width = len(params["layers"][-1][1])
    hidden = len(params["layers"][-1][0])
    # a full model: mean, profile mix, colour share (random last layer, seeded)
    rng = np.random.default_rng(5)
    params["layers"][-1] = [rng.normal(size=(hidden, 2 + len(PROFILES))).tolist(),
                            rng.normal(size=2 + len(PROFILES)).tolist()]
    log_mean, mix, share = Mlp(params).heads(np.zeros((3, len(FEATURES)), np.float32))
    np.testing.assert_allclose(mix.sum(axis=1), 1.0, rtol=1e-6)
    assert np.all(mix > 0) and np.all((share > 0) & (share < 1)) and np.all(log_mean >= 0)
    assert width in (1, 2 + len(PROFILES))  # the shipped model is one of both kinds
    params["layers"][-1][1] = [2.0]
    params["layers"][-1][0] = [[0.0]] * len(params["layers"][-1][0])
    log_mean, mix, share = Mlp(params).heads(np.zeros((3, len(FEATURES)), np.float32))
    np.testing.assert_allclose(log_mean, np.log1p(np.exp(2.0)), rtol=1e-6)
    np.testing.assert_array_equal(mix[:, PROFILES.index(1.0)], 1.0)
    np.testing.assert_array_equal(share, 1.0)


def test_fast_predictor_keeps_a_sky_where_only_blue_clips():
    """Clear sky 1.2-1.5x white in blue only: blue stays near the truth, not a blue lamp."""
    y, x = np.mgrid[0:96, 0:128].astype(np.float32)
    level = 1.5 - 0.9 * (y / 96) + 0.05 * np.sin(x / 15)
    hdr = (level[..., None] * np.array([0.45, 0.62, 1.0], np.float32)).astype(np.float32)
    photo = np.round(SRGB.to_encoded(np.clip(hdr, 0, 1)) * 255) / 255
    clipped = photo.max(axis=-1) >= 0.99
    assert 0.1 < clipped.mean() < 0.7 and not np.any(photo[clipped][:, :2] >= 0.99)
    out = uplift_recursive(photo, FastPredictor(), SRGB).linear
    blue, truth = out[clipped][:, 2], hdr[clipped][:, 2]
    assert np.all(blue >= 0.99)  # 0.99: the merge's round trip
    assert np.all(blue / truth < 1.25)  # never above what red and green imply (x 1.1)
    assert np.median(np.abs(np.log2(blue / truth))) < 0.5
    np.testing.assert_allclose(out[clipped][:, :2], SRGB.to_linear(photo)[clipped][:, :2],
                               rtol=1e-3)


def test_fast_predictor_stays_near_white_for_sky_that_only_just_clips():
    """A smooth bright sky 1.3x white at most: no hard, bright "sun" may appear in it."""
    y, x = np.mgrid[0:96, 0:128].astype(np.float32)
    sky = 1.3 - 0.9 * (y / 96) ** 1.5 + 0.05 * np.sin(x / 20)
    hdr = (sky[..., None] * np.array([0.85, 0.95, 1.0], np.float32)).astype(np.float32)
    photo = np.round(SRGB.to_encoded(np.clip(hdr, 0, 1)) * 255) / 255
    clipped = photo.max(axis=-1) >= 0.99
    assert 0.05 < clipped.mean() < 0.6
    out = uplift_recursive(photo, FastPredictor(), SRGB).linear
    truth_energy, out_energy = hdr[clipped].sum(), out[clipped].sum()
    assert abs(np.log2(out_energy / truth_energy)) < 1.0
    assert out.max() < 8.0


@pytest.mark.parametrize(("name", "least_gain"), [("forest", 1.5), ("night", 2.0),
                                                  ("sunset", 0.0)])
def test_fast_predictor_relights_unseen_crops(name, least_gain):
    """Relight PSNR gain over the baseline on crops neither calibration nor bench uses.

    Calibration panoramas, unseen crops (seed 7, small renders): a gain. The crops
    come from the bundled 256x128 copies (tests/data/README.md): their area averaging
    spreads night's small lamps over bigger, dimmer pixels (same power), which the
    predictor, calibrated on the full-size panoramas, lifts less well, so night's bar
    is 2 dB where the full-size panorama clears 2.5 dB. sunset's hazy low sun is much
    dimmer than the other suns: the gain is small there, but no loss.
    """
    from gaslight_usd.bench.calibrate import evaluation_curve
    from gaslight_usd.evaluation.reference import load_source, make_pair
    from gaslight_usd.evaluation.relight import RelightRenderer, relight_scores

    source = load_source(TEST_HDRI / f"{name}.exr")
    renderer = RelightRenderer(resolution=48, spp=8, env_height=64, seed=3)
    fast, gains = FastPredictor(), []
    for i in range(6):
        pair = make_pair(source, i, seed=7, width=128, height=96, aim_light_fraction=1.0)
        curve = evaluation_curve(pair.curve)
        if (pair.ldr.max(axis=-1) >= 0.99).sum() < 4:
            continue
        truth = renderer.render(pair.truth, "perspective")
        out = uplift_recursive(pair.ldr, fast, curve).linear
        scores = [relight_scores(img, pair.truth, renderer, "perspective", truth).psnr
                  for img in (out, curve.to_linear(pair.ldr))]
        gains.append(scores[0] - scores[1])
    print(name, np.round(gains, 2))
    assert len(gains) >= 4
    assert np.mean(gains) > least_gain


def test_input_transform_splits_srgb_exactly():
    t = input_transform("sRGB Encoded Rec.709 (sRGB)", "ACEScg")
    assert t.exact
    rng = np.random.default_rng(1)
    v = rng.random((100, 3), dtype=np.float32)
    truth = colour.convert(v, "sRGB Encoded Rec.709 (sRGB)", "ACEScg")
    np.testing.assert_allclose(t.to_working(t.curve.to_linear(v)), truth, atol=1e-4)
    np.testing.assert_allclose(t.curve.to_linear(v), SRGB.to_linear(v), atol=1e-4)


def test_predictor_registry_names_and_errors():
    names = available_predictors()
    assert {"fast", "oracle", "reexpose", "diffusion"} <= set(names)
    with pytest.raises(InputError, match="unknown predictor 'nope'"):
        get_predictor("nope")
    with pytest.raises(InputError, match="ground-truth"):
        get_predictor("oracle")


def test_diffusion_without_diffusers_or_weights_is_a_clear_error(monkeypatch):
    from gaslight_usd.uplift import diffusion

    monkeypatch.delenv(diffusion.ENV_WEIGHTS, raising=False)
    with pytest.raises(InputError, match="diffusers|weights"):
        get_predictor("diffusion")


@pytest.mark.skipif(not __import__("gaslight_usd.uplift.diffusion", fromlist=["x"])
                    .diffusers_available(),
                    reason="diffusers is an optional extra: pip install '.[diffusion]'")
def test_diffusion_plumbing_with_a_tiny_random_network():
    from gaslight_usd.uplift.diffusion import DiffusionPredictor, tiny_components

    pred = DiffusionPredictor(components=tiny_components(), device="cpu", steps=2,
                              resolution=32)
    photo = SRGB.to_encoded(np.clip(lamp_scene(size=40, peak=50.0), 0, 1))
    out = pred.darker(photo, SRGB, 0.0)
    assert out.shape == photo.shape and np.all((out >= 0) & (out <= 1))
    again = DiffusionPredictor(components=tiny_components(), device="cpu", steps=2,
                               resolution=32).darker(photo, SRGB, 0.0)
    np.testing.assert_allclose(out, again, atol=1e-5)  # seeded


def tiny_weights_folder(folder: Path) -> Path:
    """A diffusers folder (unet, vae, CLIP text encoder and tokenizer, scheduler) of a
    randomly initialised network shaped like GaSLight's, written with save_pretrained:
    what a user's --weights folder holds, only tiny. The tokenizer's vocabulary is the
    letters of the two prompts (no download)."""
    import torch
    from diffusers import StableDiffusionPipeline
    from transformers import CLIPTextConfig, CLIPTextModel, CLIPTokenizer

    from gaslight_usd.uplift.diffusion import tiny_components

    parts = tiny_components()
    letters = sorted(set("darkbright"))
    tokens = ["<|startoftext|>", "<|endoftext|>", *letters, *(ch + "</w>" for ch in letters)]
    (folder / "vocab.json").write_text(json.dumps({t: i for i, t in enumerate(tokens)}))
    (folder / "merges.txt").write_text("#version: 0.2\n")
    tokenizer = CLIPTokenizer(str(folder / "vocab.json"), str(folder / "merges.txt"),
                              model_max_length=8)
    torch.manual_seed(0)
    text = CLIPTextModel(CLIPTextConfig(vocab_size=len(tokens), hidden_size=8,
                                        intermediate_size=16, num_hidden_layers=1,
                                        num_attention_heads=2, max_position_embeddings=8,
                                        bos_token_id=0, eos_token_id=1, pad_token_id=1))
    pipe = StableDiffusionPipeline(vae=parts["vae"], text_encoder=text, tokenizer=tokenizer,
                                   unet=parts["unet"], scheduler=parts["scheduler"],
                                   safety_checker=None, feature_extractor=None,
                                   requires_safety_checker=False)
    pipe.save_pretrained(str(folder / "weights"))
    return folder / "weights"


@pytest.mark.skipif(not __import__("gaslight_usd.uplift.diffusion", fromlist=["x"])
                    .diffusers_available(),
                    reason="diffusers is an optional extra: pip install '.[diffusion]'")
def test_diffusion_weights_folder_loads_and_drives_the_recursion(tmp_path, monkeypatch):
    """The real loading path (--weights / $GASLIGHT_WEIGHTS -> from_pretrained, the
    prompts through the tokenizer and text encoder) feeding the paper's recursion."""
    from gaslight_usd.uplift.diffusion import ENV_WEIGHTS, DiffusionPredictor

    weights = tiny_weights_folder(tmp_path)
    monkeypatch.setenv(ENV_WEIGHTS, str(weights))
    pred = DiffusionPredictor(device="cpu", steps=2, resolution=32)
    assert set(pred.c["text_embeddings"]) == {"dark", "bright"}
    assert pred.c["text_embeddings"]["dark"].shape == (1, 8, 8)  # tokens x width
    photo = SRGB.to_encoded(np.clip(lamp_scene(size=40, peak=50.0), 0, 1))
    result = uplift_recursive(photo, pred, SRGB, max_steps=2)
    assert result.evs[0] == 0.0 and result.min_ev <= -2.0  # the lamp clips: at least one step
    assert result.linear.shape == photo.shape and np.isfinite(result.linear).all()
    again = uplift_recursive(photo, DiffusionPredictor(weights=weights, device="cpu", steps=2,
                                                       resolution=32), SRGB, max_steps=2)
    np.testing.assert_allclose(result.linear, again.linear, rtol=1e-5, atol=1e-6)  # seeded
    with pytest.raises(InputError, match="no such weights"):
        DiffusionPredictor(weights=tmp_path / "missing", device="cpu")


def test_panorama_faces_round_trip_and_seamless_uplift():
    h, w = 64, 128
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    pano = np.stack([0.2 + 0.3 * np.sin(2 * np.pi * x / w) ** 2, 0.3 + 0.2 * y / h,
                     np.full_like(x, 0.4)], axis=-1)
    back = faces_to_latlong(latlong_to_faces(pano, 48), w, h)
    inner = slice(4, h - 4)  # the poles are undersampled by any cube
    np.testing.assert_allclose(back[inner], pano[inner], atol=0.02)
    doubled = uplift_panorama(pano, lambda face: face * 2.0, face_size=48)
    np.testing.assert_allclose(doubled[inner], 2 * back[inner], rtol=1e-4, atol=1e-5)


def write_png16(path: Path, pixels: np.ndarray) -> Path:
    data = np.round(np.clip(pixels, 0, 1) * 65535).astype(np.uint16)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), oiio.ImageSpec(data.shape[1], data.shape[0], 3, oiio.UINT16))
    out.write_image(data)
    out.close()
    return path


def test_cli_recursive_writes_views_with_metadata(tmp_path):
    photos = tmp_path / "photos"
    photos.mkdir()
    lamp = SRGB.to_encoded(np.clip(lamp_scene(size=64, peak=300.0), 0, 1))
    write_jpeg(photos / "lamp.jpg", np.round(lamp * 255).astype(np.uint8), exposure_time=0.01)
    dull = SRGB.to_encoded(lamp_scene(size=64, peak=0.2))
    write_jpeg(photos / "dull.jpg", np.round(dull * 255).astype(np.uint8), exposure_time=0.01)
    white = np.full((64, 64, 3), 255, np.uint8)
    write_jpeg(photos / "white.jpg", white, exposure_time=0.01)
    write_jpeg(photos / "black.jpg", np.zeros_like(white), exposure_time=0.01)
    write_png16(photos / "deep.tif", lamp)  # a 16-bit TIFF
    out = tmp_path / "hdr"
    r = run_cli("hdr", str(photos), "-o", str(out), "--json", "-q", "--save-stacks",
                "--working-space", "lin_rec709")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["views"] == 5
    lamp_view = read_image(out / "lamp.exr")
    md = lamp_view.metadata
    assert md["gaslight:method"] == "recursive" and md["gaslight:predictor"] == "fast"
    assert md["gaslight:ev_steps"] >= 1 and md["gaslight:clipped_fraction_before"] > 0
    assert md["gaslight:clipped_fraction_after"] == 0
    assert lamp_view.pixels.max() > 1.0
    assert (out / "stacks" / "lamp_ev-2.png").exists()
    dull_view = read_image(out / "dull.exr")
    assert dull_view.metadata["gaslight:ev_steps"] == 0
    base = read_image(photos / "dull.jpg", to_space="lin_rec709").pixels
    np.testing.assert_allclose(dull_view.pixels, base, rtol=2e-3, atol=2e-4)
    # documented results: a black photo stays black; a white one has nothing to
    # extrapolate from (no unclipped border) and stays at white
    assert read_image(out / "black.exr").pixels.max() == 0
    white_view = read_image(out / "white.exr").pixels
    assert white_view.min() == pytest.approx(white_view.max())
    tif = read_image(out / "deep.exr")
    assert tif.metadata["gaslight:ev_steps"] >= 1 and tif.pixels.max() > 1.0


def test_cli_rejects_bad_threshold_and_unknown_predictor(tmp_path, photo_folder):
    r = run_cli("hdr", str(photo_folder), "-o", str(tmp_path / "a"), "--threshold", "0")
    assert r.returncode == 3 and "threshold" in r.stderr
    r = run_cli("hdr", str(photo_folder), "-o", str(tmp_path / "b"), "--method", "recursive",
                "--predictor", "nope")
    assert r.returncode == 3 and "unknown predictor" in r.stderr
