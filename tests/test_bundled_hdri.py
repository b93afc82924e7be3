"""The small real panoramas that ship in tests/data/hdri, and the script that makes them:
real HDR range on every clone, clamp flags that still hold, pixels the script reproduces."""

from __future__ import annotations

import importlib.util

import numpy as np
import OpenImageIO as oiio
import pytest
from conftest import REPO, TEST_HDRI

from gaslight_usd.evaluation import reference as ref
from gaslight_usd.evaluation.metrics import luminance
from gaslight_usd.imageio import read_image, write_exr
from gaslight_usd.locate import shared_hdri_dir

NAMES = ("city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset")
UNCLAMPED = ("courtyard", "forest", "night", "sunset")
FULL_SIZE = shared_hdri_dir()
"""The full-size shared set, where the checkout has it (``$GASLIGHT_HDRI_DIR`` overrides)."""


def _script():
    spec = importlib.util.spec_from_file_location(
        "make_test_hdris", REPO / "tests" / "data" / "make_test_hdris.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


make_test_hdris = _script()


def test_the_panoramas_ship_small_and_half_float():
    files = sorted(TEST_HDRI.glob("*.exr"))
    assert [p.stem for p in files] == list(NAMES)
    assert sum(p.stat().st_size for p in files) < 1.5e6
    assert "CC0" in (TEST_HDRI / "LICENSE.txt").read_text()
    for path in files:
        spec = oiio.ImageInput.open(str(path)).spec()
        assert (spec.width, spec.height, spec.nchannels) == (256, 128, 3)
        assert spec.format == oiio.HALF and spec.get_string_attribute("compression") == "zip"
        assert read_image(path).colour_space == "Linear Rec.709 (sRGB)"


def test_the_panoramas_keep_real_hdr_range_and_bright_unclipped_lights(bundled_hdri):
    sources = {s.name: s for s in ref.shared_sources()}
    for name, source in sources.items():
        y = luminance(source.pixels)
        assert np.log2(y.max() / np.percentile(y, 1)) > 11, name  # real HDR: > 11 stops
    for name in UNCLAMPED:  # a bright light, trusted: >= 8 stops over the median
        y = luminance(sources[name].pixels)
        assert sources[name].light_truth and y.max() > 2 ** 8 * np.median(y), name
    assert luminance(sources["night"].pixels).max() > 2 ** 15 * np.median(
        luminance(sources["night"].pixels))


def test_clamped_cores_stay_at_the_clamp_level_and_are_flagged(bundled_hdri):
    sources = {s.name: s for s in ref.shared_sources()}
    for name, level in ref.SHARED_CLAMP_LEVELS.items():
        source = sources[name]
        assert source.clamp_level == level and not source.light_truth
        core = source.clamp_mask() > 0
        # kept (not averaged away), and small: a sun's few pixels, studio's lamp tops
        assert 1 <= core.sum() < 0.005 * core.size, name
        assert source.pixels[core].max() >= 0.9 * level, name


def test_shrink_keeps_power_and_the_clamped_core():
    image = np.full((8, 16, 3), 0.5, np.float32)
    image[1, 2] = (1000.0, 900.0, 800.0)  # a one-pixel light in block (0, 0)
    image[6, 13] = (3.0, 5.0, 4.0)  # in block (1, 3): brightest by its green channel
    image[7, 12] = (4.5, 4.5, 4.5)
    small = make_test_hdris.shrink(image, 4, clamp_level=None)
    assert small.shape == (2, 4, 3)
    np.testing.assert_allclose(small.mean((0, 1)), image.mean((0, 1)), rtol=1e-6)  # power
    np.testing.assert_allclose(small[0, 0], 0.5 * 15 / 16 + np.array([1000, 900, 800]) / 16)
    np.testing.assert_allclose(small[0, 1], 0.5)
    clamped = make_test_hdris.shrink(image, 4, clamp_level=4.0)  # flags >= 2: two blocks
    np.testing.assert_array_equal(clamped[0, 0], (1000.0, 900.0, 800.0))
    np.testing.assert_array_equal(clamped[1, 3], (3.0, 5.0, 4.0))  # one pixel, not mixed
    np.testing.assert_allclose(clamped[0, 1:], small[0, 1:])
    np.testing.assert_allclose(clamped[1, :3], small[1, :3])


def test_script_refuses_bad_input_and_writes_nothing(tmp_path, capsys):
    assert make_test_hdris.main(["--source", str(tmp_path / "none"),
                                 "--out", str(tmp_path / "out")]) == 3
    assert "none: no EXR panoramas here" in capsys.readouterr().err
    odd = tmp_path / "odd"
    odd.mkdir()
    write_exr(odd / "a.exr", np.ones((4, 8, 3), np.float32), "lin_rec709")
    write_exr(odd / "b.exr", np.ones((6, 12, 3), np.float32), "lin_rec709")
    assert make_test_hdris.main(["--source", str(odd), "--out", str(tmp_path / "out"),
                                 "--factor", "4"]) == 3
    err = capsys.readouterr().err
    assert "b.exr: 12x6 does not divide by the factor 4" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(not (FULL_SIZE / "forest.exr").exists()
                    or FULL_SIZE.resolve() == TEST_HDRI.resolve(),
                    reason="the full-size panoramas are not here: provide ../shared/data/hdri "
                           "or set GASLIGHT_HDRI_DIR (see tests/data/README.md)")
def test_the_script_makes_exactly_the_shipped_pixels(tmp_path):
    written = make_test_hdris.make(FULL_SIZE, tmp_path, 4)
    assert [p.name for p in written] == [f"{n}.exr" for n in NAMES]
    for path in written:
        np.testing.assert_array_equal(read_image(path).pixels,
                                      read_image(TEST_HDRI / path.name).pixels)
