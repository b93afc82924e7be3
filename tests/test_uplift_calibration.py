"""The fast predictor's calibration data and protocol: the shared panoramas' trust
table, crop weights, a reproducible small calibration with leave-one-panorama-out,
and the uplift bench's grouping (clamped crops out of the means, unclipped apart)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gaslight_usd.bench import calibrate, suite_uplift
from gaslight_usd.evaluation import shared_panoramas as shared
from gaslight_usd.evaluation.reference import load_source, make_pair
from gaslight_usd.evaluation.resample import area_resize
from gaslight_usd.imageio import write_exr

POLYHAVEN = shared.folder_path(shared.POLYHAVEN)
needs_polyhaven = pytest.mark.skipif(not (POLYHAVEN / "park.exr").exists(),
                                     reason="the Poly Haven panoramas are not here: provide "
                                     "../shared/data/hdri-polyhaven-512 beside the checkout "
                                     "(see tests/data/README.md)")


# -- the trust table --------------------------------------------------------------------

def test_table_names_are_unique_and_every_entry_says_why():
    names = [p.name for p in shared.PANORAMAS]
    assert len(names) == len(set(names)) == 25
    assert {p.folder for p in shared.PANORAMAS} == set(shared.FOLDERS)
    for p in shared.PANORAMAS:
        assert p.kind in (shared.TRUSTED, shared.CLAMPED, shared.NO_LIGHT) and p.reason
        assert (p.clamp_level is not None) == (p.kind == shared.CLAMPED)
    assert shared.BY_NAME["ph-city"].kind == shared.NO_LIGHT
    assert shared.BY_NAME["city"].kind == shared.CLAMPED
    assert shared.folder_of("ph-park") == shared.POLYHAVEN and shared.folder_of("x") == "?"


@needs_polyhaven
def test_loaded_panoramas_carry_the_tables_names_and_clamps():
    sources = {s.name: s for s in shared.load_shared(["ph-bridge", "ph-venice", "ph-park"])}
    assert sorted(sources) == ["ph-bridge", "ph-park", "ph-venice"]
    assert sources["ph-bridge"].clamp_level == 105.0 and not sources["ph-bridge"].light_truth
    assert sources["ph-park"].light_truth and sources["ph-venice"].light_truth
    # a "no light" panorama really has no bright source: its peak is a few x its median
    venice = sources["ph-venice"].pixels.max(axis=-1)
    assert venice.max() < 30 * np.median(venice)
    # a crop aimed at the clamped sun is untrusted, one of the unclipped park is trusted
    aimed = {"width": 64, "height": 48, "aim_light_fraction": 1.0}
    assert not make_pair(sources["ph-bridge"], 0, 5, **aimed).light_truth
    assert make_pair(sources["ph-park"], 0, 5, **aimed).light_truth


# -- calibration ------------------------------------------------------------------------

def _tiny_panoramas(folder) -> None:
    """Three 128 x 64 panoramas from real ones; ``sky`` with its sun clamped at the
    half-float ceiling (so its sun crops are untrusted)."""
    folder.mkdir()
    for stem in ("park", "lobby", "sky"):
        pixels = load_source(POLYHAVEN / f"{stem}.exr").pixels
        small = area_resize(pixels, 64, 128)
        if stem == "sky":
            small = np.minimum(small * (65504.0 / small.max()) * 4.0, 65504.0)
        write_exr(folder / f"{stem}.exr", small.astype(np.float32), "lin_rec709")


@needs_polyhaven
def test_small_calibration_is_reproducible_and_scores_each_panorama_left_out(tmp_path):
    _tiny_panoramas(tmp_path / "hdri")
    runs = []
    for k in range(2):  # collected and fitted twice from scratch: the same numbers
        params, lopo = tmp_path / f"p{k}.json", tmp_path / f"l{k}.json"
        cache = tmp_path / f"crops{k}.npz"
        assert calibrate.main(["--hdri", str(tmp_path / "hdri"), "--crops", "9",
                               "--iters", "15", "15", "--cache", str(cache),
                               "-o", str(params), "--lopo-output", str(lopo)]) == 0
        runs.append((json.loads(params.read_text()), json.loads(lopo.read_text()), cache))
    (p0, l0, cache), (p1, l1, _) = runs
    assert p0["model"] == p1["model"] and l0["models"] == l1["models"]
    r0 = p0["calibration"]["relight_psnr_64px"]
    assert r0 == p1["calibration"]["relight_psnr_64px"]
    data = calibrate._collect_cached(cache, [], 0, 0)
    assert set(data.panoramas) == {"park", "lobby", "sky"}
    # the clamped sun's crops: untrusted, weight 0, and not scored
    untrusted = ~data.trusted
    assert untrusted.any() and set(data.panoramas[untrusted]) == {"sky"}
    weights = calibrate.crop_weights(data, clamped=0.0)
    assert np.all(weights[untrusted] == 0) and np.all(weights[data.trusted] == 1)
    lopo = r0["leave_one_panorama_out"]
    assert lopo["all"]["crops"] == int(data.trusted.sum())
    assert sum(lopo[n]["crops"] for n in ("park", "lobby", "sky") if n in lopo) == int(
        data.trusted.sum())
    assert set(l0["models"]) == set(data.panoramas[weights > 0])
    for name, model in l0["models"].items():  # a left-out model differs from the full one
        assert model["layers"] != p0["model"]["layers"], name
    assert math.isfinite(lopo["all"]["gain"]["mean"])
    assert r0["fitted"]["crops"] == int(np.count_nonzero(weights))


def test_crop_weights_follow_the_table():
    n = 4
    data = calibrate.CropSet(
        features=np.zeros((n, 1)), log_mean=np.zeros(n), area=np.ones(n), log_cap=np.zeros(n),
        slot=np.arange(n) * calibrate.GROUPS, truth=np.zeros((n, 1, 3)),
        base=np.zeros((n, 1, 3)), units=np.zeros((n, calibrate.GROUPS, 1, 1)),
        ring=np.ones((n, calibrate.GROUPS, 3)), align=np.ones((n, 1), bool),
        trusted=np.array([True, False, True, True]),
        names=["ph-park-0001", "city-0002", "ph-venice-0003", "lobby-0004"])
    np.testing.assert_array_equal(calibrate.crop_weights(data, 0.0, 0.5), [1, 0, 0.5, 1])
    np.testing.assert_array_equal(calibrate.crop_weights(data, 0.25, 1.0, ("ph-park",)),
                                  [0, 0.25, 1, 1])


# -- the bench's grouping ---------------------------------------------------------------

def _row(case, method, psnr, *, trusted=True, clipped=True, folder="hdri"):
    return {"case": case, "method": method, "relight_psnr": psnr, "light_truth": trusted,
            "ldr_clipped": clipped, "folder": folder}


def test_bench_summaries_leave_clamped_crops_out_and_report_unclipped_apart():
    rows = []
    for method, shift in (("ldr-baseline", 0.0), ("m", 2.0)):
        rows += [_row("a-0", method, 20.0 + shift),
                 _row("b-1", method, 30.0 + 2 * shift, folder="hdri-polyhaven-512"),
                 _row("c-2", method, 10.0 - 5 * shift, trusted=False),  # clamped: left out
                 _row("d-3", method, 40.0, clipped=False)]               # nothing clipped
    got = {(s["group"], s["method"]): s for s in suite_uplift.summaries(rows)}
    m = got[("clipped", "m")]
    assert m["cases"] == 2 and m["relight_psnr_mean"] == pytest.approx(28.0)
    assert m["gain_mean"] == pytest.approx(3.0) and m["gain_median"] == pytest.approx(3.0)
    assert got[("clipped:hdri", "m")]["gain_mean"] == pytest.approx(2.0)
    assert got[("clipped:hdri-polyhaven-512", "m")]["gain_mean"] == pytest.approx(4.0)
    apart = got[("nothing-clipped", "m")]
    assert apart["cases"] == 1 and apart["gain_mean"] == 0.0
    assert got[("clamped (left out)", "-")] == {"group": "clamped (left out)", "method": "-",
                                               "cases": 1}
    groups = [s["group"] for s in suite_uplift.summaries(rows)]
    assert groups[0] == "clipped" and groups[-1] == "clamped (left out)"
    assert not any(g.startswith("clamped") for g in groups[:-1])


@needs_polyhaven
def test_bench_rows_say_folder_clipping_and_trust():
    rows = suite_uplift.run({"quick": True, "count": 2, "methods": ["ldr-baseline"]})
    for row in rows:
        assert row["folder"] == shared.folder_of(row["source"]) == shared.HDRI
        assert row["ldr_clipped"] in (True, False)
        assert suite_uplift.case_group(row) in ("clipped", "nothing-clipped", "clamped")
    assert [r["source"] for r in rows] == ["city", "courtyard"]


def test_other_files_of_the_hdri_folder_join_by_their_stem(tmp_path, monkeypatch):
    pixels = np.ones((8, 16, 3), np.float32)
    pixels[2, 3] = 500.0
    write_exr(tmp_path / "mine.exr", pixels, "lin_rec709")
    monkeypatch.setenv("GASLIGHT_HDRI_DIR", str(tmp_path))
    sources = shared.load_shared(folders=(shared.HDRI,))
    assert [s.name for s in sources] == ["mine"] and sources[0].light_truth
    assert float(sources[0].pixels.max()) == 500.0


@needs_polyhaven
def test_cli_bench_runs_only_the_methods_named(tmp_path, capsys):
    from gaslight_usd.cli.main import main

    code = main(["bench", "--suite", "uplift", "--quick", "--count", "1", "--method",
                 "ldr-baseline", "-q", "-o", str(tmp_path)])
    assert code == 0
    report = json.loads((tmp_path / "uplift.json").read_text())
    assert {r["method"] for r in report["rows"]} == {"ldr-baseline"}
    assert report["summaries"] and {s["method"] for s in report["summaries"]} <= {
        "ldr-baseline", "-"}
    code = main(["bench", "--suite", "uplift", "--quick", "--count", "1", "--method", "nope",
                 "-q", "-o", str(tmp_path / "bad")])
    assert code != 0 and "unknown uplift method" in json.dumps(
        json.loads((tmp_path / "bad" / "bench.json").read_text()))
