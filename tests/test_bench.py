"""The bench framework: medians, Pareto front, reports, suite discovery, the uplift
suite's methods and registration hook, and the CLI end to end."""

from __future__ import annotations

import csv
import json
import math
import sys
import types
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
import torch

import gaslight_usd.bench as bench
from gaslight_usd.bench import suite_uplift
from gaslight_usd.bench.chart import pareto_front
from gaslight_usd.bench.runner import aggregate, run_suite
from gaslight_usd.cli.main import main
from gaslight_usd.evaluation import reference


def test_aggregate_medians_skip_nan_and_text():
    rows = [
        {"method": "a", "setting": "s", "t": 1.0, "e": 3.0, "note": "x", "flag": True},
        {"method": "a", "setting": "s", "t": 3.0, "e": math.nan},
        {"method": "a", "setting": "s", "t": 8.0, "e": 5.0},
        {"method": "b", "setting": "s", "t": 2.0, "e": math.nan},
    ]
    med = {m["method"]: m for m in aggregate(rows)}
    assert med["a"]["cases"] == 3 and med["a"]["t"] == 3.0 and med["a"]["e"] == 4.0
    assert "note" not in med["a"] and "flag" not in med["a"]
    assert math.isnan(med["b"]["e"])


def test_pareto_front_by_hand():
    pts = [{"x": 1, "y": 10}, {"x": 2, "y": 20}, {"x": 3, "y": 15}, {"x": 0.5, "y": 5},
           {"x": 2, "y": 20}, {"x": math.nan, "y": 99}]
    assert pareto_front(pts, "x", "y", True) == [True, True, False, True, True, False]
    # Lower-is-better Y: the cheapest point with the lowest error dominates everything.
    assert pareto_front(pts[:4], "x", "y", False) == [False, False, False, True]


def _tiny_suite() -> types.ModuleType:
    module = types.ModuleType("suite_tiny")
    module.NAME = "tiny"
    module.DESCRIPTION = "two methods, three cases"
    module.X = ("seconds", "seconds (s)")
    module.Y = ("error", "error (stops)")
    module.HIGHER_IS_BETTER = False

    def run(options):
        return [{"method": m, "setting": "default", "case": i, "seconds": t * (i + 1),
                 "error": e + i} for m, t, e in (("fast", 0.1, 2.0), ("slow", 1.0, 0.5))
                for i in range(3)]

    module.run = run
    return module


def test_run_suite_writes_csv_json_and_chart(tmp_path):
    result = run_suite(_tiny_suite(), {"quick": True, "seed": 0}, tmp_path)
    assert result.ok and len(result.rows) == 6
    med = {m["method"]: m for m in result.medians}
    assert med["fast"]["seconds"] == pytest.approx(0.2) and med["slow"]["error"] == 1.5
    assert med["fast"]["pareto"] and med["slow"]["pareto"]  # a genuine trade-off
    with open(tmp_path / "tiny.csv") as fh:
        assert len(list(csv.DictReader(fh))) == 6
    report = json.loads((tmp_path / "tiny.json").read_text())
    assert report["y"] == {"key": "error", "label": "error (stops)"}
    assert {m["method"] for m in report["medians"]} == {"fast", "slow"}
    png = oiio.ImageBuf(str(tmp_path / "tiny.png"))
    assert png.spec().width > 400 and png.spec().nchannels >= 3
    pixels = png.get_pixels(oiio.FLOAT)
    assert pixels.std() > 0.05  # not a blank canvas


def test_reference_methods_stay_off_the_front(tmp_path):
    module = _tiny_suite()
    module.REFERENCES = ("slow",)
    result = run_suite(module, {}, tmp_path)
    med = {m["method"]: m for m in result.medians}
    assert med["fast"]["pareto"] and not med["slow"]["pareto"]


def test_failing_suite_is_reported_not_raised(tmp_path):
    module = _tiny_suite()

    def broken(options):
        raise RuntimeError("boom")

    module.run = broken
    result = run_suite(module, {}, tmp_path)
    assert not result.ok and "boom" in result.error and not result.files


def test_discovery_survives_a_broken_suite(tmp_path, monkeypatch):
    (tmp_path / "suite_broken.py").write_text("import not_a_real_module_xyz\n")
    (tmp_path / "suite_incomplete.py").write_text("NAME = 'half'\n")
    monkeypatch.setattr(bench, "__path__", [*bench.__path__, str(tmp_path)])
    found = bench.discover_suites()
    assert "uplift" in found.suites
    assert "not_a_real_module_xyz" in found.broken["suite_broken"]
    assert "missing" in found.broken["suite_incomplete"]
    for name in ("suite_broken", "suite_incomplete"):
        sys.modules.pop(f"gaslight_usd.bench.{name}", None)


def test_uplift_suite_baseline_oracle_and_a_registered_method(bundled_hdri):
    def twice_the_baseline(ldr, curve):
        return 2.0 * suite_uplift.ldr_baseline(ldr, curve)

    suite_uplift.register_uplift_method("test-double", twice_the_baseline)
    try:
        rows = suite_uplift.run({"quick": True, "seed": 0, "count": 3,
                                 "methods": ["ldr-baseline", "oracle", "test-double"]})
    finally:
        suite_uplift._METHODS.pop("test-double", None)
    by = {(r["method"], r["case"]): r for r in rows}
    cases = sorted({r["case"] for r in rows})
    assert len(rows) == 9 and not any("error" in r for r in rows)
    for case in cases:
        oracle, base, double = (by[(m, case)] for m in ("oracle", "ldr-baseline", "test-double"))
        assert oracle["relight_mse"] == 0 and oracle["pu21_psnr"] == 100.0
        assert base["relight_psnr"] < 100.0
        # Exposure alignment makes a 2x copy of the baseline score exactly like it.
        assert double["exposure_scale"] == pytest.approx(base["exposure_scale"] / 2, rel=1e-5)
        for key in ("relight_mse", "pu21_psnr", "log_lum_rmse_stops"):
            assert double[key] == pytest.approx(base[key], rel=1e-4, abs=1e-9)
        if base["light_truth"] and base["light_clipped"]:
            assert base["light_power_err_stops"] < 0  # the clipped light is lost
        else:
            assert math.isnan(base["light_power_err_stops"])


def test_bad_method_output_becomes_an_error_row(bundled_hdri):
    suite_uplift.register_uplift_method("test-wrong-shape", lambda ldr, curve: ldr[:2])
    try:
        rows = suite_uplift.run({"quick": True, "count": 1, "methods": ["test-wrong-shape"]})
    finally:
        suite_uplift._METHODS.pop("test-wrong-shape", None)
    assert "shape" in rows[0]["error"] and math.isnan(rows[0]["relight_psnr"])


def test_cli_bench_prints_baseline_medians(tmp_path, capsys, bundled_hdri):
    code = main(["bench", "--suite", "uplift", "--quick", "--count", "2", "-q",
                 "-o", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0
    assert "ldr-baseline" in out and "relight_psnr" in out and "pu21_psnr" in out
    for name in ("uplift.csv", "uplift.json", "uplift.png", "bench.json"):
        assert (tmp_path / name).stat().st_size > 0
    report = json.loads((tmp_path / "uplift.json").read_text())
    baseline = next(m for m in report["medians"] if m["method"] == "ldr-baseline")
    assert 5.0 < baseline["relight_psnr"] < 100.0 and np.isfinite(baseline["pu21_psnr"])


def test_cli_unknown_suite_is_a_bad_input(tmp_path, capsys):
    assert main(["bench", "--suite", "nope", "-o", str(tmp_path)]) == 3
    assert "unknown suite" in capsys.readouterr().err


def test_render_suite_times_both_back_ends_on_the_same_image():
    from gaslight_usd.bench import suite_render

    rows = suite_render.run({"quick": True, "seed": 0})
    cuda = ["cuda"] if torch.cuda.is_available() else []
    assert [r["device"] for r in rows] == ["cpu", "cpu", *cuda]
    assert [r["backend"] for r in rows] == ["numba", "torch", *["torch" for _ in cuda]]
    numba_row, torch_row = rows[:2]
    for r in rows[2:]:  # the same scene on the GPU: the same coverage
        assert r["mean_alpha"] == pytest.approx(torch_row["mean_alpha"], abs=1e-3)
    assert numba_row["splats"] == torch_row["splats"] == 10_000
    # the same scene composited by both: the same coverage
    assert numba_row["mean_alpha"] == pytest.approx(torch_row["mean_alpha"], abs=1e-3)
    assert 0.2 < numba_row["mean_alpha"] < 1.0
    for r in rows:
        assert r["ms_forward"] > 0 and r["ms_backward"] > 0
    assert numba_row["speedup"] == pytest.approx(
        torch_row["ms_forward_backward"] / numba_row["ms_forward_backward"], rel=0.02)


def test_region_mean_oracle_keeps_each_clipped_regions_true_energy(bundled_hdri):
    sources = reference.shared_sources()
    pair = next(p for p in (reference.make_pair(sources[i % len(sources)], i, 0, 128, 96)
                            for i in range(20)) if 0.01 < p.clipped_fraction < 0.5)
    filled = suite_uplift.region_mean_oracle(pair)
    labels, count = suite_uplift.clipped_regions(pair.ldr)
    assert count >= 1
    for region in range(1, count + 1):
        inside = labels == region
        # Flat, and the truth's mean: the region's power is exact.
        np.testing.assert_allclose(filled[inside].mean(0), pair.truth[inside].mean(0), rtol=1e-4)
        assert np.ptp(filled[inside], axis=0).max() == 0
    outside = labels == 0
    np.testing.assert_array_equal(filled[outside],
                                  suite_uplift.ldr_baseline(pair.ldr, pair.curve)[outside])
    assert "region-mean-oracle" in suite_uplift.REFERENCES
    # Half a stop over: every region's fill times sqrt(2), never below the photo's own value
    # (a floor that binds only where a channel the photo did not clip reads above the
    # region's mean: rare, so each region's mean rises by sqrt(2)); unclipped pixels untouched.
    over = suite_uplift.region_mean_oracle(pair, 0.5)
    baseline = suite_uplift.ldr_baseline(pair.ldr, pair.curve)
    clipped = labels > 0
    np.testing.assert_allclose(over[clipped],
                               np.maximum(filled[clipped] * 2 ** 0.5, baseline[clipped]),
                               rtol=1e-6)
    assert np.mean(filled[clipped] * 2 ** 0.5 < baseline[clipped]) < 0.01
    for region in range(1, count + 1):
        inside = labels == region
        np.testing.assert_allclose(over[inside].mean(0), filled[inside].mean(0) * 2 ** 0.5,
                                   rtol=1e-2)
    np.testing.assert_array_equal(over[outside], filled[outside])
    # Under: never below what the photo itself shows there.
    under = suite_uplift.region_mean_oracle(pair, -8.0)
    np.testing.assert_allclose(under, np.maximum(filled * 2.0 ** -8, baseline), rtol=1e-6)
    assert {"region-mean-oracle-0.5-stop-under", "region-mean-oracle-0.5-stop-over"} <= set(
        suite_uplift.REFERENCES)


def test_true_energy_reference_rescales_the_fast_prediction_per_region(bundled_hdri):
    from gaslight_usd.bench.uplift_methods import recursive_fast, with_true_energy

    sources = reference.shared_sources()
    pair = next(p for p in (reference.make_pair(sources[i % len(sources)], i, 0, 128, 96)
                            for i in range(20)) if 0.01 < p.clipped_fraction < 0.5)
    pred = recursive_fast(pair.ldr, pair.curve)
    fixed = with_true_energy(pred, pair)
    labels, count = suite_uplift.clipped_regions(pair.ldr)
    for region in range(1, count + 1):
        inside = labels == region
        np.testing.assert_allclose(fixed[inside].mean(0), pair.truth[inside].mean(0), rtol=1e-4)
        # Shape kept: a constant factor per channel.
        ratio = fixed[inside] / np.maximum(pred[inside], 1e-12)
        np.testing.assert_allclose(ratio, np.broadcast_to(ratio[0], ratio.shape), rtol=1e-4)
    np.testing.assert_array_equal(fixed[labels == 0], pred[labels == 0])


def test_fit_suite_blurred_truth_yardstick_falls_with_the_blur():
    """The true probes blurred by 1 and 5 px: every score worsens with the blur, and the
    peak-anchored PU21 (truth's peak at 1000 cd/m^2) reads higher than the white-anchored."""
    from gaslight_usd.bench import suite_fit

    if not suite_fit._example_ready():
        pytest.skip("the bundled example examples/room is missing: it ships with the "
                    "project (git checkout examples/room, or set GASLIGHT_EXAMPLE)")
    sharp, soft = suite_fit.blurred_truth_rows(sigmas=(1.0, 5.0), relight=False)
    assert sharp["setting"] == "sigma 1 px" and soft["setting"] == "sigma 5 px"
    for key in ("probe_pu21_psnr", "probe_pu21_psnr_peak"):
        assert soft[key] < sharp[key] - 3.0
    assert soft["probe_log_lum_rmse"] > sharp["probe_log_lum_rmse"]
    assert 24.0 < soft["probe_pu21_psnr_peak"] < 31.0  # about 27: the fit issue's yardstick
    assert soft["probe_pu21_psnr"] < 22.0


def test_brackets_suite_groups_every_position_and_scores_the_merge(tmp_path):
    from gaslight_usd.bench import suite_brackets
    from gaslight_usd.locate import example_room

    if not (example_room() / "truth" / "view_21.exr").exists():
        pytest.skip("the bundled example's truth views are not here")
    rows = suite_brackets.run({"quick": True})
    assert [r["case"] for r in rows] == [f"position{i}" for i in range(1, 6)]
    assert all(r["grouped"] == 1 and r["views"] == 7 for r in rows)
    assert all(r["brightest_clipped"] >= 0.6 for r in rows)
    assert all(0 < r["median_stop_err"] < 0.1 for r in rows)


def test_budget_suite_refit_fits_each_budget_from_scratch():
    """``--refit``: a fit per budget on the synthetic room's views; each stays within its
    budget, scores on the same held-out views as the full fit it is compared with (its
    cost is its error minus the full fit's), and the smaller budget keeps fewer splats."""
    from gaslight_usd.bench.suite_budget import notes, refit_rows
    from gaslight_usd.fit import fit_splats, preset
    from gaslight_usd.fit.smallest import model_bytes, score
    from gaslight_usd.fit.synthetic import synthetic_data

    _, data = synthetic_data()
    cfg = preset("fast").updated(working_size=0, iterations=24, init_points=400,
                                 densify_every=8, checkpoint_every=8, sh_raise_every=12)
    full = fit_splats(data, cfg, seed=0)
    held = [data.names.index(n) for n in full.metrics["held_out_views"]]
    assert held
    full_err = score(full.scene, [full.cameras[i] for i in held],
                     [data.images[i] for i in held])
    rows = refit_rows(data, cfg, 0, [300, 120], held, Path("no-probes"), full_err,
                      True, "lin_rec709")  # quick: no probe render, so no folder read
    assert [r["budget"] for r in rows] == [120, 300]
    for r in rows:
        assert r["method"] == "splat budget (refit)"
        assert 0 < r["splats"] <= r["budget"]
        assert r["size_bytes"] == model_bytes(r["splats"], r["sh_degree"])
        assert r["cost_stops"] == pytest.approx(r["error_stops"] - full_err, abs=2e-4)
        assert r["seconds"] > 0 and math.isnan(r["irradiance_psnr"])
    assert rows[0]["splats"] < rows[1]["splats"]
    assert "refit" in notes({"refit": True})[0] and "--refit" in notes({})[0]


def test_wall_offset_is_the_median_distance_of_opaque_splats_near_the_walls():
    from gaslight_usd.bench.suite_chain import wall_offset
    from gaslight_usd.splats import SplatScene

    room = {"min": [-2.5, 0.0, -2.0], "max": [2.5, 3.0, 2.0]}
    pos = np.array([[2.45, 1.0, 0.0],    # 5 cm off the wall x = 2.5
                    [0.0, 1.0, -1.9],    # 10 cm off z = -2
                    [0.0, 1.0, 1.98],    # 2 cm off z = 2
                    [0.0, 1.5, 0.0],     # mid-room: not a wall's
                    [2.49, 1.0, 0.0],    # faint: not counted
                    [2.0, 1.0, 1.99]])   # the backdrop's: not counted
    opacity = np.array([0.9, 0.9, 0.9, 0.9, 0.1, 0.9])
    n = len(pos)
    scene = SplatScene.from_activated(pos, np.ones((n, 3)), np.full((n, 3), 0.01), opacity)
    assert wall_offset(scene, room, backdrop=1) == pytest.approx(0.05, abs=1e-6)
    assert np.isnan(wall_offset(scene.subset(np.array([3])), room, backdrop=0))


def test_chain_scores_the_fits_room_box_against_the_rooms_faces():
    from gaslight_usd.bench.suite_chain import room_box_fit

    room = {"min": [-2.5, 0.0, -2.0], "max": [2.5, 3.0, 2.0]}
    tilt = np.radians(3.0)
    ceiling = np.array([np.sin(tilt), -np.cos(tilt), 0.0])  # faces down, 3 deg off
    planes = [{"normal": [1.0, 0.0, 0.0], "offset": -2.5},          # the x- wall
              {"normal": [0.0, 0.0, -1.0], "offset": -1.9},         # z+, 10 cm in
              {"normal": list(ceiling), "offset": float(ceiling @ [0.0, 3.02, 0.0])},
              {"normal": [0.0, 1.0, 0.0], "offset": 0.46}]          # a table top, no floor
    row = room_box_fit(planes, room)
    assert row["room_faces_found"] == 3
    assert row["room_faces_missing"] == "x+ floor z-"
    assert row["room_face_offset_m"] == pytest.approx(0.1, abs=1e-3)
    assert row["room_box_tilt_deg"] == pytest.approx(3.0, abs=0.01)
    empty = room_box_fit([], room)
    assert empty["room_faces_found"] == 0 and math.isnan(empty["room_face_offset_m"])
    assert empty["room_faces_missing"] == "x- x+ floor ceiling z- z+"


@pytest.mark.slow
def test_chain_methods_pick_the_planes(monkeypatch, tmp_path):
    """``truth HDR``: the example's true HDR views fitted with the default ``plane_prior``
    (``auto``: on, they clip nothing; a few steps, the plumbing, not the accuracy),
    ``truth HDR, planes off`` without."""
    from gaslight_usd.bench import suite_chain
    from gaslight_usd.fit import preset
    from gaslight_usd.locate import example_room

    example = example_room()
    if not (example / "truth").is_dir():
        pytest.skip("the example's true HDR views are not here")
    tiny = preset("fast").updated(iterations=6, budget=800, init_points=600,
                                  backdrop_tiles=0, working_size=60)
    monkeypatch.setattr(suite_chain, "preset", lambda name: tiny)
    held = suite_chain.fitted_scene(example, "truth HDR", tmp_path / "a", "fast", 0)
    free = suite_chain.fitted_scene(example, "truth HDR, planes off", tmp_path / "b", "fast", 0)
    assert held[3]["planes"] is not None and len(held[3]["planes"]["planes"]) >= 2
    assert free[3]["planes"] is None
    assert held[2] == free[2] == 1.0  # true radiance either way
    from gaslight_usd.lights import power_source
    assert power_source(held[0].metadata) == "measured"  # its lights' power is known
    assert "uplift_fill" not in held[3]  # no uplift, no fill to score


@pytest.mark.slow
def test_chain_scores_the_uplifts_fill_of_each_light(monkeypatch, tmp_path):
    """A method that uplifts the photos carries each light's fill error to the bench's
    rows (a few fitting steps: the plumbing; the values are the uplift's alone)."""
    from gaslight_usd.bench import suite_chain
    from gaslight_usd.fit import preset
    from gaslight_usd.locate import example_room

    example = example_room()
    if not (example / "truth").is_dir():
        pytest.skip("the example's true HDR views are not here")
    tiny = preset("fast").updated(iterations=6, budget=800, init_points=600,
                                  backdrop_tiles=0, working_size=60, infer_power=False)
    monkeypatch.setattr(suite_chain, "preset", lambda name: tiny)
    scene, _, scale, metrics = suite_chain.fitted_scene(example, "recursive", tmp_path, "fast",
                                                        0)
    fill = metrics["uplift_fill"]
    assert fill["fill_views_lamp"] >= 3 and fill["fill_err_lamp"] < -3.0
    assert fill["fill_views_window"] >= 3 and abs(fill["fill_err_window"]) < 1.5
    # its lights are scored as the export writes them: clipped power a prediction, and
    # the fit's own word on the lights it weighed (gaslight_usd.lights)
    from gaslight_usd.lights import power_source
    assert power_source(scene.metadata) == "predicted"
    assert scene.metadata["fit_metrics"]["clipped_lights"] == metrics["clipped_lights"]
    # what the fit seeded on the views' empty clipped patches is reported (fit.holes)
    assert {"splats", "empty_pixels"} <= set(metrics["holes_filled"])
    # each probe's row says how much the splats lay on the probe point itself
    from gaslight_usd.probe_check import inside_alpha
    probes = json.loads((example / "probes" / "probes.json").read_text())["probes"]
    from gaslight_usd.usd.rig import build_rig
    rows = suite_chain.probe_rows(scene, example, scale, relight=False,
                                  rig=build_rig(scene, width=64))
    assert [row["inside_alpha"] for row in rows] == [
        inside_alpha(p["position"], scene) for p in probes]
    # and how the rig the export writes lights each probe
    assert all(np.isfinite(row["rig_irradiance_psnr"]) for row in rows)


def test_chain_scores_a_sunlit_patch_like_a_light():
    """The ``sun`` room's sunlit floor gets its own power error at a probe: the light from
    the patch's directions, found against true."""
    from gaslight_usd.bench.suite_chain import lit_regions, power_errors
    from gaslight_usd.cameras import latlong_directions

    info = {"sun_patch": {"min_xz": [-0.45, 0.05], "max_xz": [0.45, 0.85]}}
    (patch,) = lit_regions(info)
    assert patch["name"] == "sun_patch" and lit_regions({}) == []
    # the README's capture aims a darker frame at it as at the lights
    from gaslight_usd.bench.suite_chain import dark_frame_targets

    lights = [{"name": "window", "kind": "rectangle", "center": [2.5, 1.6, 0.2]}]
    assert [t["name"] for t in dark_frame_targets({**info, "lights": lights})] == [
        "window", "sun_patch", "sun_patch"]  # twice: two places pin the floor's depth
    position = np.array([0.0, 0.6, 0.45])
    dirs = latlong_directions(256, 128)
    t = -position[1] / np.minimum(dirs[..., 1], -1e-9)
    hit = position + t[..., None] * dirs
    on_patch = ((dirs[..., 1] < 0) & (hit[..., 0] > -0.45) & (hit[..., 0] < 0.45)
                & (hit[..., 2] > 0.05) & (hit[..., 2] < 0.85))
    truth = np.where(on_patch[..., None], 40.0, 0.0).astype(np.float32) * np.ones(3, np.float32)
    found = truth / 4  # two stops short on the patch, nothing elsewhere
    errors = power_errors(found, truth, [patch], position)
    assert errors["power_err_sun_patch"] == pytest.approx(-2.0, abs=1e-6)
