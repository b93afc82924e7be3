"""The smallest model within a tolerance (``run --tolerance-stops``), on a tiny scene.

In process on the synthetic closed room (its true splats standing in for a fit), then
through the CLI on the nine 48x48 views of ``posed_hdr_scene``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import run_cli

from gaslight_usd.cli.main import main
from gaslight_usd.errors import EXIT_USAGE
from gaslight_usd.fit.smallest import candidates, choose_smallest, model_bytes, score
from gaslight_usd.fit.synthetic import synthetic_data
from gaslight_usd.ply import read_ply


def _scene_with_sh1():
    truth, data = synthetic_data()
    sh = np.zeros((truth.count, 4, 3), np.float32)
    sh[:, 0] = truth.sh[:, 0]
    truth.sh = sh  # degree 1 with zero higher bands: dropping them costs nothing
    return truth, data


def test_model_bytes_counts_ply_floats():
    assert model_bytes(10, 0) == 10 * 4 * (11 + 3)
    assert model_bytes(10, 3) == 10 * 4 * (11 + 48)


def test_candidates_are_sorted_by_bytes_and_keep_the_kept():
    truth, data = _scene_with_sh1()
    rank = np.arange(truth.count)[::-1]
    cands = candidates(truth, rank, keep=[0, 1])
    sizes = [model_bytes(n, d) for n, d, _ in cands]
    assert sizes == sorted(sizes)
    smallest = cands[0][2]
    assert smallest.sh_degree == 0
    # the kept indices are in every candidate (splat 0's position survives the cut)
    assert any(np.allclose(p, truth.positions[0]) for p in smallest.positions)


def test_a_loose_tolerance_takes_the_smallest_and_zero_costs_nothing():
    truth, data = _scene_with_sh1()
    cams, imgs = data.cameras, data.images
    loose, small = choose_smallest(truth, cams, cams[::3], imgs[::3], 100.0)
    assert (loose.splats, loose.sh_degree) == (round(truth.count * 0.0625), 0)
    assert small.count == loose.splats and small.sh_degree == 0
    assert loose.error_stops > loose.full_error_stops  # dropping 94% of the splats shows
    tight, kept = choose_smallest(truth, cams, cams[::3], imgs[::3], 0.0)
    assert tight.cost_stops <= 1e-9
    # the SH band was zero: degree 0 at full count is as good, and smaller
    assert tight.sh_degree == 0 and tight.bytes < tight.full_bytes
    assert abs(score(kept, cams[::3], imgs[::3]) - tight.error_stops) < 1e-9
    assert tight.full_error_stops < 0.05  # the truth renders its own views


def test_run_tolerance_stops_reports_and_writes_the_chosen_model(tmp_path, posed_hdr_scene):
    out = tmp_path / "out"
    res = run_cli("run", str(posed_hdr_scene / "hdr"), "--poses",
                  str(posed_hdr_scene / "sparse"), "-o", str(out), "--to", "splats",
                  "--budget", "900", "--iterations", "80", "--tolerance-stops", "0.25")
    assert res.returncode == 0, res.stderr
    report = json.loads((out / "report.json").read_text())
    fit = next(s for s in report["stages"] if s["metadata"].get("model_choice"))
    choice = fit["metadata"]["model_choice"]
    assert 0 < choice["splats"] <= choice["full_splats"]
    assert choice["cost_stops"] <= 0.25 + 1e-9
    assert abs(choice["error_stops"] - choice["full_error_stops"] - choice["cost_stops"]) < 1e-3
    assert choice["bytes"] == model_bytes(choice["splats"], choice["sh_degree"])
    tried = choice["candidates"]
    assert tried[-1]["splats"] == choice["splats"]
    assert all(t["error_stops"] > choice["full_error_stops"] + 0.25 for t in tried[:-1])
    ply = read_ply(out / "splats.ply")
    assert ply.count == choice["splats"] and ply.sh_degree == choice["sh_degree"]
    assert "model " in res.stdout and "--tolerance-stops 0.25" in res.stdout


def test_run_rejects_a_negative_tolerance(tmp_path, posed_hdr_scene, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["run", str(posed_hdr_scene / "hdr"), "--poses", str(posed_hdr_scene / "sparse"),
              "-o", str(tmp_path / "o"), "--tolerance-stops", "-1"])
    assert exit_.value.code == EXIT_USAGE
    err = capsys.readouterr().err
    assert "expected a number of stops >= 0, got '-1'" in err
    assert len(err.strip().splitlines()[-1]) < 200
    assert not (tmp_path / "o").exists()


def test_a_fit_with_no_held_out_view_says_so(tmp_path, posed_hdr_scene):
    """Found by the stability sweep (4 photos: nothing told): with fewer than 8 views the
    fit holds none out; the run now warns, and the model choice says what it scored on."""
    from gaslight_usd.poses import read_poses, write_poses

    model = read_poses(posed_hdr_scene / "sparse")
    keep = model.cameras[:4]
    hdr = tmp_path / "hdr"
    hdr.mkdir()
    for cam in keep:
        name = cam.name.rsplit(".", 1)[0] + ".exr"
        (hdr / name).symlink_to(posed_hdr_scene / "hdr" / name)
    write_poses(tmp_path / "sparse", type(model)(cameras=keep, points=model.points))
    out = tmp_path / "out"
    res = run_cli("run", str(hdr), "--poses", str(tmp_path / "sparse"), "-o", str(out),
                  "--to", "splats", "--budget", "600", "--iterations", "30",
                  "--tolerance-stops", "0.5")
    assert res.returncode == 0, res.stderr
    assert "warning: only 4 views, none held out" in res.stderr
    assert "warning: tolerance 0.5 stops (training views: the fit held none out)" in res.stderr
    report = json.loads((out / "report.json").read_text())
    choice = next(s for s in report["stages"] if s["metadata"].get("model_choice"))[
        "metadata"]["model_choice"]
    assert choice["scored_on_held_out"] is False and choice["scored_on"] == ["view_00"]
