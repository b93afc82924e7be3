"""Damaged and hostile files into every subcommand that reads them (issue 19, item 3).

Each case takes one good file (a photo as JPEG, PNG or TIFF, an HDR view as EXR, a 3DGS
PLY, a USD stage, a COLMAP text model, a transforms.json, a batch manifest), damages
it (truncated, bytes flipped, a block zeroed, a number made NaN, huge or a word, a
line dropped or doubled, emptied) and hands it to the subcommands that read it.
Whatever it does, the answer is a clean one: exit 0 with the output written (a dry
run: nothing written), or a non-zero exit with one ``gaslight2usd: error:`` line
naming the file, never an internal error or a traceback, and no output, half-written
or whole. Seeded: the same cases every run.
``GASLIGHT_FUZZ_CASES=2000 pytest tests/test_fuzz.py`` runs more.
"""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from conftest import run_cli, write_jpeg

from gaslight_usd.atomic import PARTIAL_MARK
from gaslight_usd.imageio import write_exr
from gaslight_usd.locate import example_room
from gaslight_usd.ply import write_ply
from gaslight_usd.splats import SplatScene

CASES = int(os.environ.get("GASLIGHT_FUZZ_CASES", "160"))
KINDS = ("jpg", "png", "tif", "exr", "ply", "usda", "usdc", "colmap", "transforms",
         "manifest")
NUMBER = re.compile(rb"-?\d+\.?\d*(?:e[-+]?\d+)?")
HOSTILE_NUMBERS = (b"nan", b"inf", b"-inf", b"1e400", b"-1", b"0", b"99999999999", b"abc", b"")


@pytest.fixture(scope="module")
def originals(tmp_path_factory) -> dict[str, Path]:
    """One good file (or folder) of each kind."""
    root = tmp_path_factory.mktemp("good")
    rng = np.random.default_rng(0)
    pixels = (rng.random((48, 64, 3)) * 200).astype(np.uint8)
    pixels[10:14, 20:24] = 255  # a clipped lamp
    write_jpeg(root / "photo.jpg", pixels, exposure_time=0.01)
    for ext in ("png", "tif"):
        out = oiio.ImageOutput.create(str(root / f"photo.{ext}"))
        out.open(str(root / f"photo.{ext}"), oiio.ImageSpec(64, 48, 3, oiio.UINT8))
        out.write_image(pixels)
        out.close()
    hdr = rng.random((32, 64, 3)).astype(np.float32)
    hdr[4, 5] = 300.0
    write_exr(root / "view.exr", hdr, "ACEScg")
    n = 200
    scene = SplatScene.from_activated(
        positions=rng.normal(0, 1, (n, 3)).astype(np.float32),
        colours=rng.random((n, 3)).astype(np.float32) * 3,
        scales=np.full((n, 3), 0.05, np.float32),
        rotations=np.tile(np.array([1, 0, 0, 0], np.float32), (n, 1)),
        opacities=np.full(n, 0.8, np.float32),
        metadata={"colour_space": "ACEScg"})
    write_ply(root / "splats.ply", scene)
    assert run_cli("export", str(root / "splats.ply"), "-o", str(root / "scene.usda"),
                   "--as", "particlefield", "-q").returncode == 0
    usdc = sorted(root.glob("*.usdc"))
    assert usdc, "export wrote no .usdc layer"
    shutil.copy(usdc[0], root / "layer.usdc")
    sparse = root / "sparse"
    shutil.copytree(example_room() / "sparse" / "0", sparse)
    assert run_cli("poses", "--from", str(sparse), "-o", str(root / "transforms.json"),
                   "-q").returncode == 0
    photos = root / "shot" / "photos"
    photos.mkdir(parents=True)
    shutil.copy(root / "photo.jpg", photos / "a.jpg")
    (root / "shots.toml").write_text(
        '[defaults]\ntargets = ["splats", "usd", "hdri"]\npreset = "fast"\n'
        'colour = { working_space = "ACEScg" }\n\n[[scenes]]\nname = "shot"\n'
        'photos = "shot/photos"\nprobes = [[0, 1.5, 0], [1.2, 1.5, -0.8]]\n'
        'camera_height = 1.6\n[scenes.options.hdri]\nsize = 256\n')
    assert run_cli("batch", str(root / "shots.toml"), "-o", str(root / "b"),
                   "--dry-run").returncode == 0
    return {"manifest": root / "shots.toml", "jpg": root / "photo.jpg",
            "png": root / "photo.png", "tif": root / "photo.tif",
            "exr": root / "view.exr", "ply": root / "splats.ply",
            "usda": root / "scene.usda", "usdc": root / "layer.usdc",
            "colmap": sparse, "transforms": root / "transforms.json"}


def damage(data: bytes, rng: np.random.Generator, text: bool) -> tuple[bytes, str]:
    """``data`` damaged one way, and what was done."""
    how = rng.choice(["truncate", "flip", "zero", "empty", "number", "line"] if text else
                     ["truncate", "truncate", "flip", "flip", "zero", "empty", "header"])
    if how == "empty" or not data:
        return b"", "emptied"
    if how == "truncate":
        cut = int(rng.integers(0, len(data)))
        return data[:cut], f"truncated at {cut} of {len(data)} bytes"
    if how == "header":
        return data[:16], "only the first 16 bytes"
    if how == "flip":
        buf = bytearray(data)
        at = rng.integers(0, len(buf), int(rng.integers(1, 17)))
        for i in at:
            buf[i] ^= int(rng.integers(1, 256))
        return bytes(buf), f"{len(at)} bytes flipped"
    if how == "zero":
        start = int(rng.integers(0, len(data)))
        size = int(rng.integers(1, 256))
        return data[:start] + bytes(min(size, len(data) - start)) + data[start + size:], \
            f"{size} bytes zeroed at {start}"
    if how == "number":
        found = list(NUMBER.finditer(data))
        if not found:
            return data[: len(data) // 2], "halved"
        m = found[int(rng.integers(0, len(found)))]
        new = HOSTILE_NUMBERS[int(rng.integers(0, len(HOSTILE_NUMBERS)))]
        return data[:m.start()] + new + data[m.end():], f"{m.group().decode()!r} -> {new!r}"
    lines = data.split(b"\n")
    i = int(rng.integers(0, len(lines)))
    if rng.random() < 0.5:
        return b"\n".join(lines[:i] + lines[i + 1:]), f"line {i + 1} dropped"
    return b"\n".join(lines[:i + 1] + lines[i:]), f"line {i + 1} doubled"


def damaged_copy(kind: str, good: Path, where: Path, rng: np.random.Generator
                 ) -> tuple[Path, str]:
    """A damaged copy of the good file (for a COLMAP model: one of its three files)."""
    if kind == "colmap":
        folder = where / "sparse"
        shutil.copytree(good, folder)
        target = folder / ["cameras.txt", "images.txt", "points3D.txt"][int(rng.integers(0, 3))]
        data, how = damage(target.read_bytes(), rng, text=True)
        target.write_bytes(data)
        return folder, f"{target.name}: {how}"
    target = where / good.name
    data, how = damage(good.read_bytes(), rng, text=kind in ("usda", "transforms", "manifest"))
    if kind == "manifest":  # its scene's photos, where the manifest says they are
        shutil.copytree(good.parent / "shot", where / "shot")
    target.write_bytes(data)
    return target, how


def commands(kind: str, path: Path, out: Path) -> list[tuple[list[str], Path | None]]:
    """The subcommands that read this kind of file, and the output each would write."""
    if kind in ("jpg", "png", "tif"):
        return [(["info", str(path)], None),
                (["hdr", str(path.parent), "-o", str(out / "hdr"), "--method", "recursive"],
                 out / "hdr")]
    if kind == "exr":
        return [(["info", str(path), "--preview", str(out / "p.png")], out / "p.png")]
    if kind == "ply":
        return [(["info", str(path)], None),
                (["export", str(path), "-o", str(out / "s.usda"), "--as", "instancer"],
                 out / "s.usda"),
                (["hdri", str(path), "-o", str(out / "probe.exr"), "--size", "64",
                  "--at=0,0,0"], out / "probe.exr")]
    if kind in ("usda", "usdc"):
        return [(["info", str(path)], None)]
    if kind == "manifest":  # checked whole before any work; --dry-run writes nothing
        return [(["batch", str(path), "-o", str(out / "batch"), "--dry-run"], out / "batch")]
    return [(["poses", "--from", str(path), "-o", str(out / "model")], out / "model")]


@pytest.mark.parametrize("case", range(CASES))
def test_damaged_files_get_a_clear_answer(case, originals, tmp_path):
    rng = np.random.default_rng(1000 + case)
    kind = KINDS[case % len(KINDS)]
    inputs = tmp_path / "in"
    inputs.mkdir()
    path, how = damaged_copy(kind, originals[kind], inputs, rng)
    if kind in ("jpg", "png", "tif"):  # a set: the damaged photo among good ones
        shutil.copy(originals["jpg"], inputs / "good_1.jpg")
    for argv, output in commands(kind, path, tmp_path / "out"):
        (tmp_path / "out").mkdir(exist_ok=True)
        res = run_cli(*argv, "-q")
        said = f"{kind} ({how}) -> {' '.join(argv[:1])}: exit {res.returncode}\n{res.stderr}"
        assert "internal error" not in res.stderr and "Traceback" not in res.stderr, said
        assert res.returncode in (0, 1, 2, 3), said
        if res.returncode:
            errors = [ln for ln in res.stderr.splitlines() if ln.startswith("gaslight2usd: error:")]
            assert len(errors) == 1, said
            # the damaged file (a photo set's error may name the set's folder; a COLMAP
            # model's, the one of its three files)
            named = {path.name} | ({str(path.parent)} if kind in ("jpg", "png", "tif") else
                                   {"cameras.txt", "images.txt", "points3D.txt"}
                                   if kind == "colmap" else set())
            assert any(n in errors[0] for n in named), said
            if output is not None:
                assert not output.exists(), f"{said}\nleft {output}"
        elif output is not None and "--dry-run" not in argv:
            assert output.exists(), said
        elif output is not None:
            assert not output.exists(), f"{said}\n--dry-run wrote {output}"
        left = [p.name for p in (tmp_path / "out").rglob("*") if PARTIAL_MARK in p.name]
        assert not left, f"{said}\ntemporary files left: {left}"


def test_found_by_fuzzing_a_damaged_usd_layer_is_named_not_an_internal_error(originals,
                                                                              tmp_path):
    bad = tmp_path / "scene.usda"
    text = originals["usda"].read_text()
    bad.write_text(text[: text.index("{") + 1] + ' custom int broken = "a string"\n')
    res = run_cli("info", str(bad))
    assert res.returncode == 3
    assert res.stderr.startswith("gaslight2usd: error:") and "scene.usda" in res.stderr
    assert "not a readable USD stage" in res.stderr


def test_found_by_fuzzing_a_ragged_transform_matrix_is_named(originals, tmp_path):
    import json

    data = json.loads(originals["transforms"].read_text())
    data["frames"][1]["transform_matrix"][2] = [0.0, 1.0]
    bad = tmp_path / "transforms.json"
    bad.write_text(json.dumps(data))
    res = run_cli("poses", "--from", str(bad), "-o", str(tmp_path / "model"))
    assert res.returncode == 3 and not (tmp_path / "model").exists()
    assert "frame 1" in res.stderr and "transforms.json" in res.stderr


def test_found_by_fuzzing_a_ply_with_values_no_splat_can_have_is_named(originals, tmp_path):
    from gaslight_usd.ply import read_ply

    scene = read_ply(originals["ply"])
    for field, value in (("rotations", 0.0), ("log_scales", 1e9), ("opacity_logits", np.nan)):
        broken = scene.subset(np.arange(scene.count))
        getattr(broken, field)[7] = value
        write_ply(tmp_path / f"{field}.ply", broken)
        for argv in (["info"], ["export", "-o", str(tmp_path / f"{field}.usda")]):
            res = run_cli(argv[0], str(tmp_path / f"{field}.ply"), *argv[1:])
            assert res.returncode == 3, (field, res.stderr)
            assert "the first: splat 7" in res.stderr and f"{field}.ply" in res.stderr
        assert not (tmp_path / f"{field}.usda").exists()
