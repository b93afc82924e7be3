"""Rough edges a new user met on the first day (issue 24, items 9 and 10): what
``info`` says of environment maps and .tx files, a probe point outside the set,
help that matches the tool, photos without EXIF exposure, and USD provenance
paths that survive a move."""

from __future__ import annotations

import json
import logging
import os

import numpy as np
import pytest
from pxr import Usd

from gaslight_usd.cli.main import build_parser, main
from gaslight_usd.ply import write_ply
from gaslight_usd.splats import SplatScene

from .conftest import write_jpeg


def room_ply(path, n=400):
    """Splats on the walls of a 4 x 3 x 4 box centred on (0, 1.5, 0)."""
    rng = np.random.default_rng(2)
    pos = rng.uniform([-2, 0, -2], [2, 3, 2], (n, 3))
    axis = rng.integers(0, 3, n)
    side = rng.integers(0, 2, n)
    walls = np.array([[-2, 0, -2], [2, 3, 2]])
    pos[np.arange(n), axis] = walls[side, axis]
    scene = SplatScene.from_activated(pos, np.full((n, 3), 0.5), np.full((n, 3), 0.3),
                                      np.full(n, 0.95))
    return write_ply(path, scene)


@pytest.fixture(scope="module")
def probes(tmp_path_factory):
    root = tmp_path_factory.mktemp("probes")
    ply = room_ply(root / "room.ply")
    assert main(["hdri", str(ply), "--at", "0,1.5,0", "-o", str(root / "p.exr"), "--size",
                 "32", "--cube", "--tx", "-q"]) == 0
    return root


@pytest.mark.parametrize(("name", "envmap", "fmt"), [
    ("p.exr", "latlong", "openexr"), ("p.cube.exr", "cube", "openexr"),
    ("p.tx", "latlong", "tiff")])
def test_info_reads_tx_and_names_the_envmap(probes, name, envmap, fmt, capsys):
    assert main(["info", str(probes / name), "--json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    assert (facts["envmap"], facts["format"]) == (envmap, fmt)
    assert facts["max"][0] == pytest.approx(0.5, rel=0.05)  # the walls' radiance


def test_info_says_no_envmap_for_a_plain_image(tmp_path, capsys):
    jpg = write_jpeg(tmp_path / "a.jpg", np.full((8, 8, 3), 100, np.uint8))
    assert main(["info", str(jpg), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["envmap"] is None


def test_a_probe_far_outside_the_splats_is_warned_about(probes, tmp_path, capsys):
    ply = probes / "room.ply"
    assert main(["hdri", str(ply), "--at", "0,1.5,135", "-o", str(tmp_path / "far.exr"),
                 "--size", "16", "--json"]) == 0
    captured = capsys.readouterr()
    assert "probe point 0,1.5,135 lies 13" in captured.err
    assert "sees the set from outside" in captured.err
    assert json.loads(captured.out)["warnings"][0].startswith("probe point 0,1.5,135")
    # inside the room, clear of the walls' splats (their sigma is 0.3 m here): no warning
    assert main(["hdri", str(ply), "--at", "0.5,1,-1", "-o", str(tmp_path / "in.exr"),
                 "--size", "16"]) == 0
    assert "warning" not in capsys.readouterr().err
    # just beyond a wall is not outside the set; it is among that wall's splats
    assert main(["hdri", str(ply), "--at", "0,1.5,2.3", "-o", str(tmp_path / "near.exr"),
                 "--size", "16"]) == 0
    err = capsys.readouterr().err
    assert "sees the set from outside" not in err
    assert "probe point 0,1.5,2.3 lies inside the fit's splats" in err


def test_usd_source_is_relative_to_the_usd_file(probes, tmp_path):
    out = tmp_path / "usd" / "scene.usda"
    assert main(["export", str(probes / "room.ply"), "-o", str(out), "--as",
                 "particlefield", "-q"]) == 0
    stage = Usd.Stage.Open(str(out))
    source = stage.GetDefaultPrim().GetAttribute("gaslight:source").Get()
    assert source == os.path.relpath((probes / "room.ply").resolve(), out.parent.resolve())
    assert source.startswith("../") and source.endswith("room.ply")
    assert (out.parent / source).resolve() == (probes / "room.ply").resolve()


def test_photos_without_exif_exposure_are_named_in_a_warning(tmp_path, caplog):
    from gaslight_usd.poses.views import load_views

    folder = tmp_path / "photos"
    folder.mkdir()
    img = np.full((8, 8, 3), 90, np.uint8)
    write_jpeg(folder / "a.jpg", img, exposure_time=1 / 60, f_number=4, iso=100)
    write_jpeg(folder / "b.jpg", img)
    with caplog.at_level(logging.WARNING, logger="gaslight_usd.poses.views"):
        load_views(folder, "sRGB Encoded Rec.709 (sRGB)", "ACEScg")
    assert "1 of 2 photos carry no EXIF exposure (ExposureTime): b.jpg" in caplog.text
    caplog.clear()
    (folder / "b.jpg").unlink()
    with caplog.at_level(logging.WARNING, logger="gaslight_usd.poses.views"):
        load_views(folder, "sRGB Encoded Rec.709 (sRGB)", "ACEScg")
    assert "EXIF" not in caplog.text


def help_of(command):
    parser = build_parser(command)
    sub = next(a for a in parser._actions if a.dest == "command")
    return sub.choices[command]


def test_help_matches_the_tool():
    fit = help_of("fit")
    assert "14-view" not in fit.description and "24 views" in fit.description
    run = help_of("run")
    options = {o: a for a in run._actions for o in a.option_strings}
    assert "--cube" in options  # run --help speaks of cube maps: it can make them
    for name in ("-o", "--seed", "--at", "--cube"):
        assert options[name].help, name
    assert {o: a for a in fit._actions for o in a.option_strings}["--preset"].help
    for command in ("export", "hdri"):  # they read no photos
        flags = {o for a in help_of(command)._actions for o in a.option_strings}
        assert "--input-space" not in flags and "--working-space" in flags
    flags = {o for a in help_of("hdr")._actions for o in a.option_strings}
    assert "--input-space" in flags


def test_run_cube_reaches_the_hdri_step():
    from gaslight_usd.cli._points import attach_point_values

    args = build_parser("run").parse_args(attach_point_values(
        ["run", "x.ply", "-o", "out", "--cube", "--at", "-1,2,3"]))
    assert args.cube and args.at == [(-1.0, 2.0, 3.0)]


def test_sigterm_stops_run_as_ctrl_c_does(tmp_path):
    """A farm stops a job with SIGTERM: exit 130 and 'interrupted', temporary files gone,
    no stack dump (pycolmap's SIGTERM handler would print one), a rerun resumes."""
    import signal
    import subprocess
    import sys
    import time

    from gaslight_usd.atomic import PARTIAL_MARK
    from gaslight_usd.locate import example_room

    out = tmp_path / "out"
    cmd = [sys.executable, "-P", "-m", "gaslight_usd.cli.main", "run",
           str(example_room() / "photos"), "-o", str(out), "--to", "splats"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while not (out / "hdr").is_dir() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.2)  # stop it once the uplift is written, in SfM or the fit
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err and "SIGTERM" not in err, err
    assert not [p for p in out.rglob("*") if PARTIAL_MARK in p.name]
