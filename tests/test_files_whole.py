"""Files read whole or not at all, outputs checked before work, points with a minus.

Each test here failed before its fix: a truncated EXR read as black (exit 0), a
truncated JPEG flowed into ``hdr``, an unwritable output was "internal error"
(exit 1), ``--at -1.2,...`` was rejected by argparse and ``run --at garbage``
crashed after starting work.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from gaslight_usd.cli.main import main
from gaslight_usd.errors import EXIT_BAD_INPUT, EXIT_USAGE, InputError
from gaslight_usd.imageio import read_image, write_exr
from gaslight_usd.ply import write_ply
from gaslight_usd.splats import SplatScene

from .conftest import write_jpeg


def truncated_copy(src, dst, keep=0.5):
    data = src.read_bytes()
    dst.write_bytes(data[: int(len(data) * keep)])
    return dst


def shell_ply(path, n=300):
    rng = np.random.default_rng(1)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    scene = SplatScene.from_activated(2 * d, 0.5 + 0.4 * np.abs(d), np.full((n, 3), 0.3),
                                      np.full(n, 0.95))
    return write_ply(path, scene)


@pytest.fixture
def truncated_exr(tmp_path):
    rng = np.random.default_rng(0)
    whole = write_exr(tmp_path / "whole.exr", rng.uniform(1, 5, (64, 96, 3)), "ACEScg")
    return truncated_copy(whole, tmp_path / "cut.exr")


def test_truncated_exr_is_an_input_error_naming_the_file(truncated_exr, capsys):
    with pytest.raises(InputError, match="truncated or corrupt") as err:
        read_image(truncated_exr)
    assert err.value.path == truncated_exr
    assert main(["info", str(truncated_exr)]) == EXIT_BAD_INPUT
    message = capsys.readouterr().err
    assert "cut.exr" in message and "truncated" in message
    assert message.count("\n") == 1  # one line, not one per missing chunk


def test_truncated_jpeg_stops_hdr_and_writes_nothing(photo_folder, tmp_path, capsys):
    cut = truncated_copy(photo_folder / "shot_1.jpg", tmp_path / "cut.jpg", keep=0.4)
    shutil.move(cut, photo_folder / "shot_1.jpg")
    out = tmp_path / "hdr"
    assert main(["hdr", str(photo_folder), "-o", str(out), "--method", "linear", "-q"]) \
        == EXIT_BAD_INPUT
    assert "shot_1.jpg" in capsys.readouterr().err
    assert not out.exists()


def test_truncated_jpeg_stops_poses_naming_it(photo_folder, tmp_path, capsys):
    cut = truncated_copy(photo_folder / "shot_2.jpg", tmp_path / "cut.jpg", keep=0.4)
    shutil.move(cut, photo_folder / "shot_2.jpg")
    out = tmp_path / "sparse"
    assert main(["poses", str(photo_folder), "-o", str(out), "-q"]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "shot_2.jpg: truncated or corrupt image" in err
    assert not out.exists()


def test_whole_jpeg_still_reads_with_its_pixels(tmp_path):
    pixels = np.zeros((16, 24, 3), np.uint8)
    pixels[:, 12:] = 200
    img = read_image(write_jpeg(tmp_path / "ok.jpg", pixels))
    assert img.pixels.shape == (16, 24, 3)
    assert img.pixels[:, :10].max() < 0.02 and img.pixels[:, 14:].min() > 0.5


def test_orientation_still_applied(tmp_path):
    pixels = np.zeros((8, 16, 3), np.uint8)
    pixels[:, :4] = 255  # a bright left edge
    img = read_image(write_jpeg(tmp_path / "rot.jpg", pixels, orientation=6))
    assert img.pixels.shape == (16, 8, 3)  # turned 90 degrees clockwise: left edge on top
    assert img.pixels[:3].mean() > 0.8 and img.pixels[-3:].mean() < 0.05


@pytest.mark.parametrize("argv", [
    ["export", "{ply}", "-o", "/sys/gaslight-test/scene.usda", "--as", "particlefield"],
    ["hdri", "{ply}", "-o", "/proc/gaslight-test/p.exr", "--size", "16"],
    ["run", "{ply}", "-o", "{ply}", "--to", "hdri"],
    ["run", "{ply}", "-o", "{tmp}/sub/x", "--to", "hdri"],
    ["poses", "--from", "{tmp}/model", "-o", "{ply}"],
    ["hdr", "{tmp}/model", "-o", "{ply}", "--method", "linear"],
    ["fit", "{tmp}/model", "--poses", "{tmp}/model", "-o", "/sys/gaslight-test.ply"],
])
def test_unwritable_outputs_are_bad_input_with_one_line(argv, tmp_path, capsys):
    ply = shell_ply(tmp_path / "s.ply")
    (tmp_path / "sub").write_text("a file where a folder should be")
    _model_folder(tmp_path / "model")
    args = [a.format(ply=ply, tmp=tmp_path) for a in argv]
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(args) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.startswith("gaslight2usd: error: ") and "internal" not in err
    assert err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


def _model_folder(folder):
    """A one-camera COLMAP text model."""
    folder.mkdir()
    (folder / "cameras.txt").write_text("1 PINHOLE 32 24 30 30 16 12\n")
    (folder / "images.txt").write_text("1 1 0 0 0 0 0 0 1 a.jpg\n\n")
    (folder / "points3D.txt").write_text("")


def test_batch_into_a_file_is_bad_input(tmp_path, photo_folder, capsys):
    manifest = tmp_path / "m.json"
    manifest.write_text(json.dumps({"scenes": [{"name": "a", "inputs": [str(photo_folder)]}]}))
    target = tmp_path / "taken"
    target.write_text("x")
    assert main(["batch", str(manifest), "-o", str(target), "-q"]) == EXIT_BAD_INPUT
    assert "taken: exists and is a file" in capsys.readouterr().err


def test_points_with_a_negative_first_coordinate_parse(tmp_path):
    ply = shell_ply(tmp_path / "s.ply")
    out = tmp_path / "p.exr"
    assert main(["hdri", str(ply), "--at", "-1.2,0.35,-0.58", "--at", "0,0,0", "-o", str(out),
                 "--size", "16", "-q"]) == 0
    from gaslight_usd.imageio import read_header

    first = read_header(tmp_path / "p.000.exr")
    assert tuple(first.getattribute("gaslight:probePosition")) == pytest.approx((-1.2, 0.35, -0.58))
    # run takes the same points (its HDRIs are 2048 wide: too slow here, so parse only)
    from gaslight_usd.cli._points import attach_point_values
    from gaslight_usd.cli.main import build_parser

    argv = ["run", str(ply), "-o", str(tmp_path / "run"), "--at", "-0.5,0,0.25", "--at",
            "1,-2,3"]
    args = build_parser("run").parse_args(attach_point_values(argv))
    assert args.at == [(-0.5, 0.0, 0.25), (1.0, -2.0, 3.0)]


@pytest.mark.parametrize("bad", ["garbage", "1,2", "1,2,nan"])
def test_run_rejects_a_bad_point_before_any_work(bad, tmp_path, capsys):
    ply = shell_ply(tmp_path / "s.ply")
    out = tmp_path / "run"
    with pytest.raises(SystemExit) as exit_:
        main(["run", str(ply), "-o", str(out), "--to", "hdri", "--at", bad])
    assert exit_.value.code == EXIT_USAGE
    assert "expected X,Y,Z" in capsys.readouterr().err
    assert not out.exists()


def test_run_rejects_an_unknown_usd_form(tmp_path, capsys):
    ply = shell_ply(tmp_path / "s.ply")
    with pytest.raises(SystemExit) as exit_:
        main(["run", str(ply), "-o", str(tmp_path / "run"), "--as", "instancr"])
    assert exit_.value.code == EXIT_USAGE
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("argv", [["run", "{ply}", "-o", "{tmp}/run", "--budget", "0"],
                                  ["fit", "{tmp}", "--poses", "{tmp}", "-o", "{tmp}/f.ply",
                                   "--iterations", "-3"]])
def test_counts_are_checked_before_any_work(argv, tmp_path, capsys):
    ply = shell_ply(tmp_path / "s.ply")
    with pytest.raises(SystemExit) as exit_:
        main([a.format(ply=ply, tmp=tmp_path) for a in argv])
    assert exit_.value.code == EXIT_USAGE
    assert "expected a whole number >= 1" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.ply"]
