"""Reference LDR/HDR pairs: camera curves, crops, exposure, clipping, determinism,
light-truth flags, on the bundled real panoramas and on user HDR files."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import TEST_HDRI

from gaslight_usd.cameras import latlong_directions
from gaslight_usd.errors import InputError
from gaslight_usd.evaluation import curves
from gaslight_usd.evaluation import reference as ref
from gaslight_usd.evaluation.metrics import luminance
from gaslight_usd.imageio import read_image, write_exr

SMALL = {"width": 64, "height": 48}


@pytest.fixture(scope="module")
def sources() -> dict[str, ref.HDRSource]:
    """The bundled panoramas read as the default set (so their known clamp levels apply)."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("GASLIGHT_HDRI_DIR", str(TEST_HDRI))
        return {s.name: s for s in ref.shared_sources()}


# -- camera curves ----------------------------------------------------------------------

@pytest.mark.parametrize("curve", curves.CURVE_NAMES)
def test_curves_invert_and_span_unit_range(curve):
    x = np.linspace(0, 1, 2001)
    v = curves.encode(x, curve)
    assert v[0] == pytest.approx(0.0, abs=1e-6) and v[-1] == pytest.approx(1.0, abs=1e-6)
    assert np.all(np.diff(v) > 0)
    np.testing.assert_allclose(curves.decode(v, curve), x, atol=2e-6)


def test_curve_values_by_hand():
    # IEC 61966-2-1: the toe ends at 0.0031308 -> 0.04045; 0.18 -> 1.055*0.18^(1/2.4)-0.055
    assert curves.encode(np.array(0.0031308), "srgb") == pytest.approx(0.04045, abs=1e-5)
    assert curves.encode(np.array(0.18), "srgb") == pytest.approx(
        1.055 * 0.18 ** (1 / 2.4) - 0.055, abs=1e-6)
    assert curves.encode(np.array(0.5), "gamma2.2") == pytest.approx(0.5 ** (1 / 2.2))
    assert curves.encode(np.array(3.0), "srgb") == 1.0  # clipped at sensor white
    with pytest.raises(ValueError):
        curves.encode(np.zeros(3), "log-c")


# -- crops ------------------------------------------------------------------------------

def test_perspective_crop_looks_where_asked():
    # A synthetic panorama whose value is the direction's y component (+1):
    # the crop's centre reads sin(pitch) + 1, its top is brighter than its bottom.
    d = latlong_directions(256, 128)
    pano = np.repeat(d[..., 1:2] + 1.0, 3, axis=-1).astype(np.float32)
    cam = ref.look_camera(yaw_deg=40.0, pitch_deg=20.0, fov_deg=60.0, width=33, height=25)
    crop = ref.perspective_crop(pano, cam)
    assert crop[12, 16, 0] == pytest.approx(math.sin(math.radians(20)) + 1, abs=0.02)
    assert crop[0, 16, 0] > crop[-1, 16, 0]
    # A single bright pixel lands at the image centre when looked at.
    bright = np.zeros((128, 256, 3), np.float32)
    bright[40, 100] = 1000.0
    lon = -360.0 * ((100 + 0.5) / 256 - 0.5)
    lat = 180.0 * (0.5 - (40 + 0.5) / 128)
    cam = ref.look_camera(lon, lat, 30.0, 31, 31)
    crop = ref.perspective_crop(bright, cam, supersample=1)
    assert np.unravel_index(np.argmax(crop[..., 0]), crop.shape[:2]) == (15, 15)


def test_solid_angles_sum_to_the_view_cone():
    cam = ref.look_camera(0, 0, 90.0, 200, 200)
    # A 90 x 90 degree square pyramid subtends 4 asin(sin^2 45) = 4 asin(1/2) = 2 pi / 3 sr.
    assert ref.pixel_solid_angles(cam).sum() == pytest.approx(2 * math.pi / 3, rel=1e-3)


# -- pairs from the bundled real panoramas ----------------------------------------------

def test_pairs_are_deterministic_and_prefix_stable(sources):
    listed = list(sources.values())
    a = ref.build_pairs(listed, count=3, seed=7, **SMALL)
    b = ref.build_pairs(listed, count=4, seed=7, **SMALL)
    for pa, pb in zip(a, b[:3], strict=True):
        assert pa.name == pb.name
        assert np.array_equal(pa.truth, pb.truth) and np.array_equal(pa.ldr, pb.ldr)
    c = ref.build_pairs(listed, count=1, seed=8, **SMALL)
    assert not np.array_equal(a[0].truth, c[0].truth)


def test_pair_exposure_clipping_and_baseline(sources):
    pair = ref.make_pair(sources["forest"], 5, seed=3, **SMALL)
    y = luminance(pair.truth)
    assert np.median(y) == pytest.approx(0.18 * 2 ** pair.spec.ev_offset, rel=1e-4)
    assert pair.ldr.shape == pair.truth.shape == (48, 64, 3)
    assert np.array_equal(pair.ldr * 255, np.round(pair.ldr * 255))  # 8-bit levels
    clipped = pair.truth >= 1.0
    assert np.all(pair.ldr[clipped] == 1.0)
    baseline = curves.decode(pair.ldr, pair.curve)
    mid = (pair.ldr > 0.3) & (pair.ldr < 0.9)
    rel = np.abs(baseline[mid] - pair.truth[mid]) / pair.truth[mid]
    assert mid.sum() > 100 and rel.max() < 0.03  # only 8-bit quantisation left


def test_light_truth_flags_follow_the_clamped_sources(sources):
    assert sources["city"].clamp_level == 32000 and sources["studio"].clamp_level == 100
    for name in ("forest", "sunset", "courtyard", "night"):
        assert sources[name].light_truth
    # A crop aimed at city's clipped sun cannot judge light sources; forest's can.
    aimed = {"aim_light_fraction": 1.0, **SMALL}
    assert not ref.make_pair(sources["city"], 0, seed=0, **aimed).light_truth
    forest = ref.make_pair(sources["forest"], 0, seed=0, **aimed)
    assert forest.light_truth and forest.spec.aimed_at_light
    # City looking at the ground, away from the sun, is trustworthy again.
    cam = ref.look_camera(0, -60, 50, 32, 24)
    mask = ref.perspective_crop(sources["city"].clamp_mask()[..., None].repeat(3, -1), cam)
    assert mask.max() == 0.0


# -- user files -------------------------------------------------------------------------

def test_user_hdr_window_pairs_and_clamp_detection(tmp_path):
    rng = np.random.default_rng(0)
    img = rng.uniform(0.01, 2.0, (90, 150, 3)).astype(np.float32)
    img[10:12, 20:22] = 70000.0   # at the top of the half range: a clamped light
    path = tmp_path / "shot.exr"
    write_exr(path, img, "Linear Rec.709 (sRGB)", half=False)
    src = ref.load_source(path)
    assert not src.panorama and src.clamp_level == pytest.approx(70000.0)
    pairs = [ref.make_pair(src, i, seed=1, width=40, height=30) for i in range(6)]
    for pair in pairs:
        top, left, h, w = pair.spec.window
        inside = top <= 10 < top + h and left <= 20 < left + w
        assert pair.light_truth == (not inside)
        assert pair.truth.shape == (30, 40, 3)
    assert {p.light_truth for p in pairs} == {True, False}  # both cases were exercised


def test_write_pairs_round_trip(tmp_path):
    d = latlong_directions(128, 64)
    pano = (np.exp(3 * d[..., :1].repeat(3, -1)) + 0.1).astype(np.float32)
    src = ref.HDRSource("synthetic", pano, "Linear Rec.709 (sRGB)", panorama=True)
    pairs = ref.build_pairs([src], count=2, seed=0, width=32, height=24)
    folder = ref.write_pairs(pairs, tmp_path / "pairs")
    manifest = json.loads((folder / "pairs.json").read_text())
    assert [m["name"] for m in manifest] == ["synthetic-0000", "synthetic-0001"]
    back = read_image(folder / "synthetic-0000.truth.exr").pixels
    np.testing.assert_allclose(back, pairs[0].truth, rtol=2e-3, atol=1e-4)
    png = read_image(folder / "synthetic-0000.ldr.png", colour_space="Linear Rec.709 (sRGB)")
    np.testing.assert_allclose(png.pixels, pairs[0].ldr, atol=1e-6)


def test_bad_inputs_are_one_line_errors(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        ref.load_source(tmp_path / "missing.exr")
    with pytest.raises(InputError, match="no folder"):
        ref.shared_sources(tmp_path / "nothing-here")
    black = tmp_path / "black.exr"
    write_exr(black, np.zeros((4, 8, 3), np.float32), "Linear Rec.709 (sRGB)")
    with pytest.raises(InputError, match="black"):
        ref.load_source(black)
