"""Metrics against hand-computed cases, PU21 against its published reference values,
and the relighting protocol (small Mitsuba renders)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaslight_usd.cameras import latlong_directions
from gaslight_usd.evaluation import metrics as M
from gaslight_usd.evaluation import relight as R
from gaslight_usd.evaluation.pu21 import L_MAX, L_MIN, pu21_encode


def _scene(seed: int = 0) -> np.ndarray:
    """A plausible HDR image: mid-tones in [0.05, 0.9] and a small 2x2 lamp at 400."""
    rng = np.random.default_rng(seed)
    img = rng.uniform(0.05, 0.9, size=(24, 32, 3)).astype(np.float32)
    img[4:6, 10:12] = 400.0
    return img


# -- PU21 -------------------------------------------------------------------------------

def test_pu21_reference_values():
    # Reference values of the banding_glare encoding (ColorVideoVDP's encoder).
    got = pu21_encode(np.array([0.005, 1.0, 100.0, 10000.0]))
    np.testing.assert_allclose(got, [0.0, 36.5, 256.4, 595.4], atol=0.1)


def test_pu21_clamps_and_is_monotonic():
    lum = np.geomspace(1e-4, 1e5, 200)
    v = pu21_encode(lum)
    assert np.all(np.diff(v) >= 0)
    assert pu21_encode(1e-4) == pytest.approx(pu21_encode(L_MIN))
    assert pu21_encode(1e6) == pytest.approx(pu21_encode(L_MAX))
    with pytest.raises(ValueError):
        pu21_encode(1.0, "nonsense")


# -- identical images -------------------------------------------------------------------

def test_identical_images_score_perfectly():
    img = _scene()
    assert M.mse(img, img) == 0.0
    assert M.psnr(img, img) == M.PSNR_CAP_DB  # documented cap instead of infinity
    assert M.log_luminance_rmse(img, img) == 0.0
    assert M.relative_l1(img, img) == 0.0
    assert M.angular_error_deg(img, img) == pytest.approx(0.0, abs=1e-5)
    assert M.pu21_psnr(img, img) == M.PSNR_CAP_DB
    light = M.light_source_errors(img, img)
    assert light["power_err_stops"] == 0.0 and light["peak_err_stops"] == 0.0


# -- a one-stop exposure error ----------------------------------------------------------

def test_one_stop_brighter_reads_as_one_stop():
    truth = _scene()
    pred = 2.0 * truth
    assert M.log_luminance_rmse(pred, truth) == pytest.approx(1.0, abs=1e-5)
    assert M.relative_l1(pred, truth) == pytest.approx(1.0, abs=1e-5)
    assert M.relative_l1(truth / 2, truth) == pytest.approx(0.5, abs=1e-5)
    light = M.light_source_errors(pred, truth)
    assert light["power_err_stops"] == pytest.approx(1.0)
    assert light["peak_err_stops"] == pytest.approx(1.0)
    assert M.exposure_alignment_scale(pred, truth) == pytest.approx(0.5)
    aligned = M.hdr_errors(pred, truth, align=True)
    assert aligned["exposure_scale"] == pytest.approx(0.5)
    assert aligned["log_lum_rmse_stops"] == pytest.approx(0.0, abs=1e-6)
    assert aligned["relative_l1"] == pytest.approx(0.0, abs=1e-6)
    assert aligned["pu21_psnr"] >= 90.0
    unaligned = M.hdr_errors(pred, truth, align=False)
    assert unaligned["light_power_err_stops"] == pytest.approx(1.0)


def test_psnr_hand_computed():
    truth = np.full((4, 4, 3), 0.25)
    pred = np.full((4, 4, 3), 0.5)
    # MSE = 0.0625 -> PSNR = 10 log10(1 / 0.0625) = 12.0412 dB
    assert M.mse(pred, truth) == pytest.approx(0.0625)
    assert M.psnr(pred, truth) == pytest.approx(10 * math.log10(16))
    assert M.psnr_from_mse(0.01, peak=2.0) == pytest.approx(10 * math.log10(400))


def test_angular_error_hand_computed():
    truth = np.array([[[1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]])
    pred = np.array([[[0.0, 3.0, 0.0], [2.0, 2.0, 0.0]]])  # 90 degrees, then 0 degrees
    assert M.angular_error_deg(pred, truth) == pytest.approx(45.0)
    assert M.angular_error_deg(np.zeros((2, 2, 3)), np.ones((2, 2, 3))) == 0.0


def test_alignment_uses_only_well_exposed_truth_pixels():
    truth = np.zeros((10, 10, 3))
    truth[:5] = 0.5          # well exposed: in [0.2, 0.8]
    truth[5:] = 50.0         # a bright area that must not drive the alignment
    pred = truth.copy()
    pred[:5] *= 4.0          # the prediction is 2 stops too bright where it counts
    pred[5:] = 1.0
    assert M.exposure_alignment_scale(pred, truth) == pytest.approx(0.25)


def test_light_source_errors_of_a_clipped_lamp():
    truth = np.full((8, 8, 3), 0.5)
    truth[2:4, 2:4] = 1024.0             # the lamp: 4 pixels, 11 stops over 0.5
    clipped = np.minimum(truth, 1.0)     # what a linearised photo keeps
    errors = M.light_source_errors(clipped, truth)
    assert errors["region_pixels"] == 4
    assert errors["power_err_stops"] == pytest.approx(-10.0)  # log2(1 / 1024)
    assert errors["peak_err_stops"] == pytest.approx(-10.0)
    # Solid-angle weights only re-weight pixels inside the region.
    weights = np.ones((8, 8))
    weights[2, 2] = 3.0
    half_lamp = truth.copy()
    half_lamp[2, 2] = 0.0
    weighted = M.light_source_errors(half_lamp, truth, pixel_weights=weights)
    assert weighted["power_err_stops"] == pytest.approx(math.log2(3 / 6))


def test_pu21_psnr_scale_mapping():
    # Relative 1.0 -> 100 cd/m^2: a prediction 1 stop dark where truth is 1.0
    # loses exactly the PU difference between 100 and 50 cd/m^2.
    truth = np.ones((4, 4, 3))
    pred = truth / 2
    diff = pu21_encode(100.0) - pu21_encode(50.0)
    expected = 10 * math.log10(256.0 ** 2 / diff ** 2)
    assert M.pu21_psnr(pred, truth, align=False) == pytest.approx(expected, rel=1e-9)


def test_pu21_psnr_peak_anchors_the_truths_peak_at_1000_nits():
    # Truth: walls at 1, a lamp pixel at 2000 -> walls shown at 0.5 cd/m^2; a prediction one
    # stop dark on the walls loses the PU difference between 0.5 and 0.25 cd/m^2 there.
    truth = np.ones((4, 4, 3))
    truth[0, 0] = 2000.0
    pred = truth / 2
    pred[0, 0] = 2000.0
    diff = pu21_encode(0.5) - pu21_encode(0.25)
    expected = 10 * math.log10(256.0 ** 2 / (diff ** 2 * 15 / 16))
    assert M.pu21_psnr_peak(pred, truth) == pytest.approx(expected, rel=1e-9)
    # Only the scene's own range counts: scaling both images changes nothing ...
    assert M.pu21_psnr_peak(7 * pred, 7 * truth) == pytest.approx(expected, rel=1e-9)
    # ... unlike the photo-white anchor, under which the same pair scores lower here.
    assert M.pu21_psnr(pred, truth, align=False) < expected - 5
    with pytest.raises(ValueError, match="positive"):
        M.pu21_psnr_peak(pred, np.zeros_like(truth))


# -- relighting (Mitsuba) ----------------------------------------------------------------

@pytest.fixture(scope="module")
def renderer() -> R.RelightRenderer:
    return R.RelightRenderer(resolution=32, spp=4, env_height=32)


def test_perspective_image_fills_the_90_degree_patch():
    image = np.ones((30, 40, 3), np.float32)
    env = R.environment_from_perspective(image, env_height=64)
    assert env.shape == (64, 128, 3)
    lit = env[..., 0] > 0
    d = latlong_directions(128, 64)[lit]
    azimuth = np.degrees(np.arctan2(d[:, 0], d[:, 2]))
    elevation = np.degrees(np.arcsin(d[:, 1]))
    assert np.abs(azimuth).max() < 45.0 and elevation.min() > 0.0
    assert np.count_nonzero(lit) == 32 * 32  # 90 x 90 degrees of a 2:1 lat-long
    # Area resampling keeps the image's mean radiance in the patch.
    bright = np.zeros((30, 40, 3), np.float32)
    bright[3, 5] = 1200.0
    patch = R.environment_from_perspective(bright, 64)[:32, 48:80]
    assert patch.mean() == pytest.approx(bright.mean(), rel=1e-5)


def test_panorama_becomes_the_whole_environment():
    pano = np.random.default_rng(1).uniform(0, 5, (64, 128, 3)).astype(np.float32)
    env = R.environment_for(pano, env_height=32)
    assert env.shape == (32, 64, 3)
    assert env.mean() == pytest.approx(pano.mean(), rel=1e-5)


def test_relight_identical_and_exposure_shifted(renderer):
    truth = _scene()
    truth_render = renderer.render(truth)
    assert truth_render.shape == (32, 32, 3) and truth_render.max() > 0
    same = R.compare_renders(renderer.render(truth), truth_render)
    assert same.mse == 0.0 and same.psnr == M.PSNR_CAP_DB
    # One stop brighter: identical after exposure alignment.
    shifted = R.relight_scores(2 * truth, truth, renderer, truth_render=truth_render)
    assert shifted.exposure_scale == pytest.approx(0.5, rel=1e-4)
    assert shifted.mse < 1e-10
    assert shifted.angular_error_deg < 0.01


def test_swapped_environment_renders_like_a_fresh_scene(renderer):
    # The scene is built once and its texture swapped: the result must equal a
    # scene built from scratch with that texture (Mitsuba pads one column a side).
    other = _scene(seed=5) * np.array([1.0, 0.7, 0.4], np.float32)
    renderer.render(_scene())
    swapped = renderer.render(other)
    fresh = R.RelightRenderer(resolution=32, spp=4, env_height=32).render(other)
    np.testing.assert_array_equal(swapped, fresh)


def test_relight_sees_a_missing_lamp(renderer):
    truth = _scene()
    clipped = np.minimum(truth, 1.0)
    scores = R.relight_scores(clipped, truth, renderer)
    assert scores.mse > 1e-4 and scores.psnr < 50.0
    tinted = truth * np.array([1.0, 0.5, 0.5], np.float32)
    assert R.relight_scores(tinted, truth, renderer).angular_error_deg > 5.0
    assert renderer.variant in R.USABLE_VARIANTS


def test_without_libllvm_19_mitsuba_falls_back_instead_of_aborting(tmp_path):
    """With no vetted libLLVM, load_mitsuba takes scalar_rgb; Dr.Jit is never left to load an
    older LLVM on its own (Debian 12's LLVM 15 aborts the process on the first kernel)."""
    import os
    import subprocess
    import sys

    code = ("import os, warnings; os.environ.pop('DRJIT_LIBLLVM_PATH', None)\n"
            "from gaslight_usd.evaluation import relight as R\n"
            "R.LIBLLVM_CANDIDATES = ()\n"
            "assert not R.llvm_variant_usable()\n"
            "with warnings.catch_warnings(record=True) as w:\n"
            "    warnings.simplefilter('always')\n"
            "    mi = R.load_mitsuba()\n"
            "print(mi.variant(), any('libllvm19' in str(x.message) for x in w))\n")
    env = {k: v for k, v in os.environ.items() if k != "DRJIT_LIBLLVM_PATH"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         cwd=tmp_path, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["scalar_rgb", "True"]
