"""The stability suite's parts (``gaslight2usd bench --suite stability``): the capture
faults made from the bundled room's truth, the break rule and what counts as told."""

from __future__ import annotations

import json
import math

import numpy as np
import OpenImageIO as oiio
import pytest
from conftest import run_cli, write_jpeg

from gaslight_usd.bench.perturb import box_blur_rows, make_capture, sees
from gaslight_usd.bench.suite_chain import scene_lights
from gaslight_usd.bench.suite_stability import (
    BREAK_DB,
    BREAK_STOPS,
    mark_breaks,
    summaries,
    sweep,
    told_lines,
)
from gaslight_usd.errors import GaslightError
from gaslight_usd.imageio import read_image
from gaslight_usd.locate import example_room
from gaslight_usd.poses import read_poses
from gaslight_usd.uplift.checks import clipped_photos_warning


def test_box_blur_keeps_the_mean_and_spreads_a_point():
    img = np.zeros((2, 9, 3), np.float32)
    img[:, 4] = 9.0
    out = box_blur_rows(img, 3)
    assert np.allclose(out[0, :, 0], [0, 0, 0, 3, 3, 3, 0, 0, 0])
    assert box_blur_rows(img, 1) is img


@pytest.fixture(scope="module")
def room():
    folder = example_room()
    return folder, scene_lights(json.loads((folder / "scene.json").read_text()))


def test_captures_drop_crop_and_reexpose_as_asked(room, tmp_path):
    folder, lights = room
    lamp = np.asarray(next(li for li in lights if li["name"] == "lamp")["center"])
    four = make_capture(folder, tmp_path / "p", "photos", 4, lights=lights)
    assert len(list(four.photos.glob("*.jpg"))) == 4 and len(read_poses(four.poses).cameras) == 4
    one = make_capture(folder, tmp_path / "o", "light_one_view", 1, lights=lights)
    cams = read_poses(one.poses).cameras
    assert sum(sees(c, lamp)[0] for c in cams) == 1
    half = make_capture(folder, tmp_path / "h", "light_half_out", 1, lights=lights)
    for cam in read_poses(half.poses).cameras:
        photo = read_image(half.photos / cam.name).pixels
        assert photo.shape[:2] == (cam.height, cam.width) == (360, 320)
        seen, (u, _) = sees(cam, lamp)
        if seen:  # the lamp's centre on the crop's left or right edge
            assert min(abs(u), abs(u - cam.width)) < 1.0
    clipped = make_capture(folder, tmp_path / "c", "clipped_frames", 2, lights=lights)
    firsts = sorted(clipped.photos.glob("*.jpg"))
    assert read_image(firsts[0]).pixels.min() > 0.95  # 8 stops over: all white


def test_break_rule_and_silent_flag():
    def row(kind, strength, psnr, told=0, error=None, finite=True):
        return {"method": "recursive", "preset": "fast", "perturbation": kind,
                "strength": strength, "irradiance_psnr": psnr, "told_count": told,
                "told": "warning: x" if told else "", "error": error, "finite": finite}
    rows = [row("none", 0.0, 12.0), row("none", 0.0, 10.0),
            row("noise", 0.1, 11.0 - BREAK_DB + 0.5), row("noise", 0.2, 11.0 - BREAK_DB - 0.5),
            row("jpeg", 10, 5.0, told=1), row("photos", 4, math.nan, told=1, error="E: no"),
            row("blur", 5, 11.0, finite=False)]
    mark_breaks(rows)
    by = {(r["perturbation"], r["strength"]): r for r in rows}
    assert not by["noise", 0.1]["broken"] and by["noise", 0.2]["broken"]
    assert by["noise", 0.2]["silent"] and not by["jpeg", 10]["silent"]
    assert by["photos", 4]["broken"] and by["blur", 5]["broken"]  # error; NaN/Inf
    assert by["noise", 0.2]["drop_db"] == pytest.approx(BREAK_DB + 0.5)
    summary = {s["perturbation"]: s for s in summaries(rows)}
    assert summary["noise"]["breaks_at"] == 0.2 and summary["noise"]["silent"]
    assert summary["noise"]["curve"].startswith("0.1:-2.5dB")


def test_a_light_gone_astray_breaks_though_the_psnr_holds():
    """Near the floor a run barely loses PSNR when a light goes astray; the power rule
    sees it: the worst light's power BREAK_STOPS + 0.5 further off breaks the run."""
    def row(kind, strength, power):
        return {"method": "recursive", "preset": "fast", "perturbation": kind,
                "strength": strength, "irradiance_psnr": 10.0, "power_err_stops_max": power,
                "told_count": 0, "told": "", "error": None, "finite": True}
    rows = [row("none", 0.0, 6.0), row("exposure", 1.0, 6.0 + BREAK_STOPS - 0.5),
            row("light_half_out", 1.0, 6.0 + BREAK_STOPS + 0.5)]
    mark_breaks(rows)
    by = {r["perturbation"]: r for r in rows}
    assert not by["exposure"]["broken"] and by["light_half_out"]["broken"]
    assert by["light_half_out"]["power_worse_stops"] == pytest.approx(BREAK_STOPS + 0.5)
    assert by["light_half_out"]["drop_db"] == 0.0 and by["light_half_out"]["silent"]


def test_told_lines_and_the_sweep():
    text = "[case] step 40\n[case] warning: 2 views dark\nuplift.x does not apply (y); using z\n"
    assert told_lines(text) == ["[case] warning: 2 views dark",
                                "uplift.x does not apply (y); using z"]
    assert sweep({"perturbations": ["jpeg"], "full": True}) == {"jpeg": (60, 30, 10)}
    assert set(sweep({})) >= {"photos", "noise", "pose_noise", "light_one_view"}
    with pytest.raises(GaslightError, match="unknown perturbation"):
        sweep({"perturbations": ["rain"]})


# -- regressions: what the sweep found breaking silently, now told -------------------------
@pytest.mark.parametrize("method", ["linear", "recursive"])
def test_a_mostly_clipped_photo_is_named(method, photo_folder, tmp_path):
    white = np.full((48, 64, 3), 255, np.uint8)
    write_jpeg(photo_folder / "shot_white.jpg", white, exposure_time=1 / 30, f_number=4.0,
               iso=100)
    res = run_cli("hdr", str(photo_folder), "-o", str(tmp_path / "hdr"), "--method", method)
    assert res.returncode == 0, res.stderr
    lines = [ln for ln in res.stderr.splitlines() if "mostly clipped" in ln]
    assert len(lines) == 1
    assert "1 of 4 photo(s)" in lines[0] and "shot_white.jpg (100%)" in lines[0]
    assert "shot_0.jpg" not in lines[0]  # its 8x8 clipped corner is 2% of it


@pytest.mark.parametrize("method", ["linear", "recursive"])
def test_a_low_quality_jpeg_is_named(method, photo_folder, tmp_path):
    """The sweep's JPEG 30 and 10 moved the lights 1-1.5 stops, silently: a photo saved
    under quality 50 is now named (the fixture's photos are saved at 95)."""
    src = photo_folder / "shot_1.jpg"
    pixels = oiio.ImageBuf(str(src)).get_pixels(oiio.UINT8)
    spec = oiio.ImageSpec(oiio.ImageInput.open(str(src)).spec())
    spec.attribute("Compression", "jpeg:20")
    path = photo_folder / "shot_low.jpg"
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec) and out.write_image(pixels)
    out.close()
    res = run_cli("hdr", str(photo_folder), "-o", str(tmp_path / "hdr"), "--method", method)
    assert res.returncode == 0, res.stderr
    lines = [ln for ln in res.stderr.splitlines() if "low JPEG quality" in ln]
    assert len(lines) == 1 and "1 of 4 photo(s)" in lines[0]
    assert "shot_low.jpg (~20)" in lines[0] and "shot_1.jpg" not in lines[0]


def test_clipped_photos_warning_threshold():
    assert clipped_photos_warning(["a", "b"], [0.5, 0.2]) is None
    text = clipped_photos_warning(["a", "b"], [0.51, 0.9])
    assert text.startswith("2 of 2 photo(s) are mostly clipped") and "b (90%)" in text
