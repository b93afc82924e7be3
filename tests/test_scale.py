"""Working sizes (issue 23): the area resample, exact intrinsics, views at the working size,
and the peak memory of a run on 12 MP photos bounded by the working size, not the photos."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from gaslight_usd.bench.suite_scale import RUN_MAIN, photo_set, run_measured, upscale_photos
from gaslight_usd.errors import InputError
from gaslight_usd.evaluation.resample import area_resize as dense_area_resize
from gaslight_usd.fit.data import box_downscale, load_fit_data, scale_camera_to
from gaslight_usd.fit.presets import PRESETS, uplift_size
from gaslight_usd.imageio import read_header, read_image, write_exr
from gaslight_usd.locate import example_room
from gaslight_usd.poses import read_poses
from gaslight_usd.poses.colmap import ColmapModel, write_model
from gaslight_usd.resize import area_resize, fit_within

EXAMPLE = example_room()


def test_fit_within_keeps_the_aspect_and_never_enlarges():
    assert fit_within(4032, 3024, 512) == (512, 384)
    assert fit_within(3024, 4032, 512) == (384, 512)
    assert fit_within(480, 360, 120) == (120, 90)
    assert fit_within(480, 360, 512) == (480, 360)
    assert fit_within(480, 360, 0) == (480, 360)
    assert fit_within(4000, 1, 100) == (100, 1)


def test_area_resize_is_the_box_filter_for_integer_ratios_and_keeps_the_mean():
    rng = np.random.default_rng(3)
    img = (rng.random((360, 480, 3)) ** 4 * 1000).astype(np.float32)  # HDR-like range
    assert np.array_equal(area_resize(img, 120, 90), box_downscale(img, 4))
    odd = area_resize(img, 131, 97)  # a non-integer ratio: fractional pixels weighted
    assert odd.shape == (97, 131, 3) and odd.dtype == np.float32
    assert odd.mean() == pytest.approx(img.mean(), rel=1e-5)
    ref = dense_area_resize(img, 97, 131)  # the evaluation's dense-weights version
    assert np.allclose(odd, ref, rtol=1e-5, atol=1e-3)
    # a 2x3 block of a step edge: the covered shares, computed by hand
    step = np.zeros((2, 3), np.float32)
    step[:, 2] = 3.0
    assert np.allclose(area_resize(step, 2, 1), [[0.0, 2.0]])  # 1.5 px each: 0, (0.5*0+3)/1.5
    with pytest.raises(ValueError):
        area_resize(img, 481, 360)


def test_scaled_camera_sees_a_point_where_the_shrunk_image_has_it():
    cam = read_poses(EXAMPLE / "sparse" / "0").cameras[0]
    small = scale_camera_to(cam, 131, 98)
    pts = np.array([[0.3, 1.2, 0.4], [-1.0, 0.8, 1.5], [0.0, 0.0, 0.0]])
    uv, z = cam.project(pts)
    uv_small, z_small = small.project(pts)
    assert np.allclose(z, z_small)
    # pixel centres at +0.5: x maps to x * 131 / 480 and y to y * 98 / 360
    assert np.allclose(uv_small, uv * [131 / 480, 98 / 360])


def test_presets_name_working_sizes_and_the_uplift_size_follows():
    assert [PRESETS[n].working_size for n in ("fast", "balanced", "best")] == [120, 240, 2048]
    assert uplift_size(PRESETS["fast"]) == 512 and uplift_size(PRESETS["best"]) == 2048


@pytest.fixture(scope="module")
def shrunk_views(tmp_path_factory):
    """The example's true HDR views shrunk to 240 x 180 (as ``run`` writes them)."""
    root = tmp_path_factory.mktemp("shrunk")
    for path in sorted((EXAMPLE / "truth").glob("*.exr")):
        img = read_image(path)
        write_exr(root / path.name, area_resize(img.pixels, 240, 180), img.colour_space,
                  {k: v for k, v in img.metadata.items() if k.startswith("gaslight:")})
    return root


def test_fit_reads_evenly_shrunk_views_with_exact_intrinsics(shrunk_views):
    sparse = EXAMPLE / "sparse" / "0"
    full = load_fit_data(EXAMPLE / "truth", sparse, working_size=120)
    small = load_fit_data(shrunk_views, sparse, working_size=120)
    true_cam = read_poses(sparse).cameras[0]
    for a, b in zip(full.cameras, small.cameras, strict=True):
        assert (a.width, a.height) == (b.width, b.height) == (120, 90)
        assert np.allclose([b.fx, b.fy, b.cx, b.cy], [a.fx, a.fy, a.cx, a.cy])
    assert full.cameras[0].fx == pytest.approx(true_cam.fx / 4)
    assert full.cameras[0].cx == pytest.approx(true_cam.cx / 4)
    for a, b in zip(full.images, small.images, strict=True):  # 480->120 == 480->240->120
        assert np.allclose(a, b, rtol=1e-3, atol=1e-4)  # the EXRs hold half floats


def test_a_view_of_another_shape_is_refused_naming_it(shrunk_views, tmp_path):
    bad = tmp_path / "hdr"
    shutil.copytree(shrunk_views, bad)
    img = read_image(bad / "view_03.exr")
    write_exr(bad / "view_03.exr", img.pixels[:170], img.colour_space)
    with pytest.raises(InputError, match=r"view_03\.exr.*240x170.*shrunk evenly"):
        load_fit_data(bad, EXAMPLE / "sparse" / "0")


def _posed_set(root: Path, photos: list[Path], width: int, height: int) -> Path:
    """The true poses of ``photos`` with the cameras scaled to ``width`` x ``height``."""
    model = read_poses(EXAMPLE / "sparse" / "0")
    names = {p.name for p in photos}
    cams = [scale_camera_to(c, width, height) for c in model.cameras if c.name in names]
    return write_model(root / "sparse", ColmapModel(cameras=cams))


def _peak_of_run(photos: Path, sparse: Path, out: Path) -> tuple[float, dict]:
    cmd = [sys.executable, "-P", "-c", RUN_MAIN, "run", str(photos), "--poses", str(sparse),
           "-o", str(out), "--to", "splats", "--preset", "fast", "--budget", "2000",
           "--iterations", "60", "-q"]  # memory, not the fit, is measured: few steps
    code, _, peak, _ = run_measured(cmd, out.with_suffix(".log"))
    assert code == 0, out.with_suffix(".log").read_text()[-2000:]
    return peak, json.loads((out / "report.json").read_text())


def test_a_run_on_12_megapixel_photos_stays_within_the_working_size_memory(tmp_path):
    """8 photos of 4032 x 3024: the run may use what the same run on the example's own
    480 x 360 photos uses (the working size is the same) plus a few decoded photos, not
    a copy of every photo (8 x 2 x 146 MB before). One photo is read at a time, but a
    read holds two float copies for a moment (OpenImageIO's buffer and numpy's)."""
    originals = sorted((EXAMPLE / "photos").glob("*.jpg"))[:8]
    small = photo_set(originals, tmp_path / "small", 8)
    big_photos = upscale_photos(small, tmp_path / "big", 4032, 3024)
    peak_small, _ = _peak_of_run(small, _posed_set(tmp_path / "ps", originals, 480, 360),
                                 tmp_path / "out-small")
    peak_big, report = _peak_of_run(tmp_path / "big",
                                    _posed_set(tmp_path / "pb", big_photos, 4032, 3024),
                                    tmp_path / "out-big")
    photo_gb = 4032 * 3024 * 3 * 4 / 1024 ** 3  # one decoded float32 photo
    assert peak_big < peak_small + 4 * photo_gb, (peak_small, peak_big)
    hdr = read_header(tmp_path / "out-big" / "hdr" / "view_00.exr")
    assert (hdr.width, hdr.height) == (512, 384)  # uplifted at the fit's uplift size
    fit = next(s for s in report["stages"] if s["name"] == "fit")
    assert fit["counts"]["views"] == 8


def test_run_uplifts_at_the_presets_uplift_size_unless_told_to_keep_full_size():
    from gaslight_usd.pipeline import with_working_size

    assert with_working_size({})["uplift"]["max_size"] == 512  # fast by default
    assert with_working_size({"fit": {"preset": "best"}})["uplift"]["max_size"] == 2048
    kept = with_working_size({"uplift": {"max_size": 0}, "fit": {"preset": "fast"}})
    assert kept["uplift"]["max_size"] == 0  # --keep-hdr full


def test_run_extracts_sfm_features_at_the_presets_size_unless_told():
    from gaslight_usd.pipeline import with_working_size

    assert with_working_size({})["poses"] == {"max_image_size": 640,  # fast by default
                                              "max_features": 1024}
    best = with_working_size({"fit": {"preset": "best"}})["poses"]
    assert best == {"max_image_size": 1600, "max_features": 8192}
    given = with_working_size({"poses": {"max_image_size": 2000, "scale": 2.0}})["poses"]
    assert given == {"max_image_size": 2000, "max_features": 1024, "scale": 2.0}


def test_the_scale_bench_measures_a_childs_peak_memory(tmp_path):
    grab = "import numpy as np; a = np.ones(400 * 2**20 // 8); a += 1"  # 400 MiB touched
    code, seconds, peak, cpu = run_measured([sys.executable, "-c", grab], tmp_path / "log")
    assert code == 0 and seconds > 0 and 0 < cpu < 60
    assert 400 / 1024 < peak < 400 / 1024 + 0.3
    spin = "import time; t = time.process_time()\nwhile time.process_time() - t < 1.0: pass"
    assert 1.0 <= run_measured([sys.executable, "-c", spin], tmp_path / "log").cpu_seconds < 3
    code = run_measured([sys.executable, "-c", "raise SystemExit(3)"], tmp_path / "log").code
    assert code == 3


def test_the_scale_bench_cases_and_sizes():
    from gaslight_usd.bench.suite_scale import cases, photo_size

    assert photo_size(12.0) == (4032, 3024) and photo_size(0.2) == (480, 360)
    assert photo_size(1.0) == (1155, 866)
    assert cases({"quick": True}) == [(12, 0.2), (12, 3.0)]
    assert cases({"photos": (12, 96), "megapixels": (12.0,)}) == [(12, 12.0), (96, 12.0)]
    assert len(cases({})) == 6


def test_the_poses_bench_solves_enlarged_photos_at_each_feature_size(tmp_path, monkeypatch):
    from gaslight_usd.bench import suite_poses

    calls = []

    def fake(photos, truth, matcher, model, seed=0, scene_size=None, **sfm):
        calls.append((len(photos), photos[0].parent.name, sfm.get("max_image_size")))
        return {"setting": f"{matcher}/{model}", "photos": len(photos)}

    monkeypatch.setattr(suite_poses, "solve_and_score", fake)
    rows = suite_poses.run({"megapixels": [0.2], "out": tmp_path})
    assert calls[0] == (24, "photos", None)  # the photos as shot, COLMAP's own size
    assert calls[1:] == [(24, "480x360", s) for s in suite_poses.EXTRACTION_SIZES]
    assert [r["max_image_size"] for r in rows] == [0, *suite_poses.EXTRACTION_SIZES]
    assert rows[0]["setting"] == "480x360 as shot"
    assert rows[1]["setting"] == "480x360, features at 640" and rows[1]["megapixels"] == 0.17
