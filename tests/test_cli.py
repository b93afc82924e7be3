"""The CLI as a user runs it: a real subprocess, real files."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pxr import Usd, UsdGeom

from gaslight_usd.imageio import write_exr
from gaslight_usd.ply import write_ply
from gaslight_usd.splats import SplatScene

# The installed console script (not `python -m`, which would import the source tree
# from the working directory instead of the installed package).
CLI = [str(Path(sys.executable).with_name("gaslight2usd"))]


def run_cli(*args):
    return subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True, timeout=120)


@pytest.fixture
def exr_file(tmp_path):
    pixels = np.full((8, 16, 3), 0.25, np.float32)
    pixels[2, 3] = [512.0, 256.0, 128.0]  # a lamp
    return write_exr(tmp_path / "probe.exr", pixels, "ACEScg")


def test_info_exr_text_and_json(exr_file):
    res = run_cli("info", exr_file, "--json")
    assert res.returncode == 0, res.stderr
    facts = json.loads(res.stdout)
    assert (facts["width"], facts["height"]) == (16, 8)
    assert facts["channels"] == ["R", "G", "B"]
    assert facts["max"] == pytest.approx([512, 256, 128])
    assert facts["colour_space"] in ("ACEScg", "lin_ap1_scene")
    # 1st percentile is the wall at 0.25; the lamp's luminance is ~ 0.27*512+0.67*256+...
    assert 9.5 < facts["dynamic_range_stops"] < 10.5
    text = run_cli("info", exr_file)
    assert "dynamic_range_stops" in text.stdout and "width: 16" in text.stdout


def test_info_ply(tmp_path):
    scene = SplatScene.from_activated(
        positions=np.arange(12, dtype=np.float32).reshape(4, 3),
        colours=np.array([[0.2] * 3, [0.5] * 3, [40.0, 30.0, 20.0], [2.0, 0.1, 0.1]]),
        scales=np.full(4, 0.05), opacities=np.full(4, 0.8), sh_degree=2,
        metadata={"colour_space": "ACEScg"})
    path = write_ply(tmp_path / "s.ply", scene)
    facts = json.loads(run_cli("info", path, "--json").stdout)
    assert facts["splats"] == 4 and facts["sh_degree"] == 2
    assert facts["emitters_above_1"] == 2
    assert facts["colour_max"] == pytest.approx(40.0, rel=1e-4)
    assert facts["bounds_max"] == pytest.approx([9, 10, 11])
    assert facts["metadata"]["colour_space"] == "ACEScg"


def test_info_ply_says_the_photos_light_regions_in_a_line(tmp_path):
    rows = [[0, 0.0, 0.0, 1.0, 2.0, 1, 40.0], [0, 0.6, 0.0, 0.8, 1.0, 0, 3.0],
            [1, 0.0, 0.0, 1.0, 2.0, 1, 30.0]]
    scene = SplatScene.from_activated(
        positions=np.zeros((1, 3), np.float32), colours=np.full((1, 3), 0.5),
        scales=np.full(1, 0.05), opacities=np.full(1, 0.8),
        metadata={"cameras": {"centres": [[0, 0, 0], [1, 0, 0], [2, 0, 0]]},
                  "light_sightings": {"white": 0.9, "regions": rows}})
    path = write_ply(tmp_path / "s.ply", scene)
    facts = json.loads(run_cli("info", path, "--json").stdout)
    assert facts["metadata"]["light_sightings"] == (
        "3 light regions over white 0.9 (2 framed whole) in 2 of 3 photos")


def test_info_usd(tmp_path):
    path = tmp_path / "s.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(root.GetPrim())
    UsdGeom.Sphere.Define(stage, "/World/Ball")
    stage.GetRootLayer().Save()
    facts = json.loads(run_cli("info", path, "--json").stdout)
    assert facts["up_axis"] == "Y" and facts["meters_per_unit"] == 1.0
    assert facts["prim_types"] == {"Sphere": 1, "Xform": 1}
    assert facts["default_prim"] == "/World"


def test_missing_file_is_one_line_naming_it(tmp_path):
    res = run_cli("info", tmp_path / "nope.exr")
    assert res.returncode == 3
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "nope.exr" in lines[0] and "no such file" in lines[0]


def test_unknown_colour_space_fails_before_writing(photo_folder, tmp_path):
    out = tmp_path / "hdr"
    res = run_cli("hdr", photo_folder, "-o", out, "--method", "linear",
                  "--working-space", "ACEScgg")
    assert res.returncode == 3
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "'ACEScgg'" in lines[0] and "'ACEScg'" in lines[0]
    assert not out.exists()


def test_empty_folder_fails_naming_it(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    out = tmp_path / "hdr"
    res = run_cli("hdr", empty, "-o", out, "--method", "linear", "-q")
    assert res.returncode == 3
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and str(empty) in lines[0] and "no images" in lines[0]
    assert not out.exists()


def test_hdr_linear_writes_one_exr_per_photo(photo_folder, tmp_path):
    out = tmp_path / "hdr"
    res = run_cli("hdr", photo_folder, "-o", out, "--method", "linear", "--json", "-q")
    assert res.returncode == 0, res.stderr
    assert sorted(p.name for p in out.glob("*.exr")) == ["shot_0.exr", "shot_1.exr",
                                                         "shot_2.exr"]
    assert json.loads(res.stdout)["views"] == 3
    assert json.loads((out / "report.json").read_text())["status"] == "done"


def test_help_documents_exit_codes():
    res = run_cli("--help")
    assert res.returncode == 0
    for code in ("0 ", "1 ", "2 ", "3 ", "130"):
        assert code in res.stdout


def test_run_poses_option_takes_only_poses(photo_folder, tmp_path):
    out = tmp_path / "out"
    res = run_cli("run", photo_folder, "--poses", photo_folder, "-o", out, "-q")
    assert res.returncode == 3
    assert "--poses: not a COLMAP model or transforms.json" in res.stderr
    assert str(photo_folder) in res.stderr and not out.exists()
    # Real poses given by option are an input like any other: here the HDR views
    # and the poses are made or taken, and the report names the given poses.
    from gaslight_usd.poses.colmap import ColmapModel, write_model

    write_model(tmp_path / "sparse", ColmapModel(cameras=[]))
    res = run_cli("run", photo_folder, "--poses", tmp_path / "sparse", "-o", out,
                  "--to", "hdr", "--method", "linear", "-q")
    assert res.returncode == 0, res.stderr
    report = json.loads((out / "report.json").read_text())
    assert str(tmp_path / "sparse") in json.dumps(report["inputs"])
