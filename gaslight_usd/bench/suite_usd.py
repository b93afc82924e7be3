"""Suite "usd": seconds to write a ParticleField from a 3DGS PLY, ours vs NVIDIA's.

Both tools run as command-line subprocesses on the same PLY (SH degree 3), in
turn, in one run: ``gaslight2usd export PLY -o X.usda --as particlefield``
(which also runs UsdValidation on what it wrote) and ``usd-convert-gsplat -i
PLY -o X.usdc`` from its own venv (it pins numpy==2.3.1; set
``$GASLIGHT_GSPLAT_VENV`` or use /work/venv-gsplat). Each written
ParticleField is read back and compared with the PLY's own values (positions,
linear scales, opacities, unit quaternions up to sign, SH): ``mismatch`` is
the largest absolute difference. Also reported: our in-process write time
(read PLY + author + save, no interpreter start-up), each command's start-up
alone (``--help``), and the command's speed-up once both start-ups are taken
off (``speedup_after_startup``).
"""

from __future__ import annotations

import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

NAME = "usd"
DESCRIPTION = "PLY -> USD ParticleField write time: gaslight2usd vs usd-convert-gsplat"
X = ("seconds", "seconds to write the ParticleField (s)")
Y = ("mismatch", "max abs difference from the PLY's values")
HIGHER_IS_BETTER = False
TABLE = ("seconds", "startup_seconds", "speedup_vs_usd_convert_gsplat", "speedup_after_startup",
         "mismatch")

GSPLAT_VENV = Path(os.environ.get("GASLIGHT_GSPLAT_VENV", "/work/venv-gsplat"))


def synthetic_ply(path: Path, count: int, seed: int = 0) -> Path:
    """A 3DGS PLY with ``count`` random splats, SH degree 3, normals as zeros."""
    from gaslight_usd.ply import write_ply
    from gaslight_usd.splats import SplatScene

    rng = np.random.default_rng(seed)
    scene = SplatScene(
        positions=rng.normal(size=(count, 3)).astype(np.float32) * 2,
        rotations=rng.normal(size=(count, 4)).astype(np.float32),
        log_scales=rng.uniform(-5, -2, (count, 3)).astype(np.float32),
        opacity_logits=rng.normal(size=count).astype(np.float32),
        sh=(rng.normal(size=(count, 16, 3)) * 0.5).astype(np.float32),
        normals=np.zeros((count, 3), np.float32),
    )
    write_ply(path, scene)
    return path


def mismatch(usd_path: Path, ply_path: Path) -> float:
    """Largest abs difference between the written ParticleField and the PLY."""
    from pxr import Usd, UsdVol

    from gaslight_usd.ply import read_ply
    from gaslight_usd.usd.particlefield import read_particle_field

    scene = read_ply(ply_path)
    stage = Usd.Stage.Open(str(usd_path))
    prims = [p for p in stage.Traverse() if p.IsA(UsdVol.ParticleField3DGaussianSplat)]
    got = read_particle_field(prims[0])
    q = got["orientations"]
    ref_q = scene.unit_rotations
    sign = np.sign(np.sum(q * ref_q, axis=1, keepdims=True))
    diffs = [
        np.abs(got["positions"] - scene.positions).max(),
        np.abs(got["scales"] - scene.scales).max(),
        np.abs(got["opacities"] - scene.opacities).max(),
        np.abs(q * sign - ref_q).max(),
        np.abs(got["sh"] - scene.sh).max(),
    ]
    return float(max(diffs))


def _timed(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"{cmd[0]} failed: {done.stderr.strip()[-500:]}")
    return seconds


def _ours_in_process(ply: Path, out: Path) -> float:
    from gaslight_usd.ply import read_ply
    from gaslight_usd.usd.scene import ExportOptions, export_usd

    t0 = time.perf_counter()
    export_usd(read_ply(ply), out, ExportOptions(variants=("particlefield",)),
               validate_output=False)
    return time.perf_counter() - t0


def run(options: dict) -> list[dict]:
    quick = bool(options.get("quick"))
    out = Path(options.get("out") or "bench-usd") / "usd"
    out.mkdir(parents=True, exist_ok=True)
    count = int(options.get("splats") or (5_000 if quick else 200_000))
    repeats = 1 if quick else 3
    ply = synthetic_ply(out / f"splats_{count}.ply", count, int(options.get("seed", 0)))
    gaslight = shutil.which("gaslight2usd") or str(Path(sys.executable).with_name("gaslight2usd"))
    theirs = GSPLAT_VENV / "bin" / "usd-convert-gsplat"
    setting = f"{count} splats, SH 3"
    times: dict[str, list[float]] = {"gaslight2usd": [], "usd-convert-gsplat": [],
                                     "gaslight2usd (in-process)": []}
    # Start-up of each command alone (--help: interpreter, imports, argument parsing), so
    # the fixed cost both tools pay can be told from the conversion itself.
    startup: dict[str, list[float]] = {"gaslight2usd": [], "usd-convert-gsplat": []}
    ours_usd, their_usd = out / "ours.usda", out / "theirs.usdc"
    for _ in range(repeats):  # interleaved, so machine load hits both alike
        times["gaslight2usd"].append(_timed(
            [gaslight, "export", str(ply), "-o", str(ours_usd), "--as", "particlefield", "-q"]))
        times["gaslight2usd (in-process)"].append(_ours_in_process(ply, out / "inproc.usda"))
        startup["gaslight2usd"].append(_timed([gaslight, "export", "--help"]))
        if theirs.exists():
            times["usd-convert-gsplat"].append(_timed(
                [str(theirs), "-i", str(ply), "-o", str(their_usd)]))
            startup["usd-convert-gsplat"].append(_timed([str(theirs), "--help"]))
    rows = []
    ours_mismatch = mismatch(ours_usd, ply)
    for method in ("gaslight2usd", "gaslight2usd (in-process)"):
        rows.append({"method": method, "setting": setting, "splats": count,
                     "seconds": statistics.median(times[method]),
                     "mismatch": ours_mismatch, "repeats": repeats})
    if times["usd-convert-gsplat"]:
        theirs_s = statistics.median(times["usd-convert-gsplat"])
        rows.append({"method": "usd-convert-gsplat", "setting": setting, "splats": count,
                     "seconds": theirs_s, "mismatch": mismatch(their_usd, ply),
                     "repeats": repeats})
        for row in rows[:2]:
            row["speedup_vs_usd_convert_gsplat"] = theirs_s / row["seconds"]
        ours_start = statistics.median(startup["gaslight2usd"])
        theirs_start = statistics.median(startup["usd-convert-gsplat"])
        rows[0]["startup_seconds"] = ours_start
        rows[-1]["startup_seconds"] = theirs_start
        rows[0]["speedup_after_startup"] = (theirs_s - theirs_start) / max(
            rows[0]["seconds"] - ours_start, 1e-9)
    else:
        rows[0]["note"] = (f"usd-convert-gsplat not found at {theirs}: comparison skipped "
                           "(python3 -m venv /work/venv-gsplat && /work/venv-gsplat/bin/pip "
                           "install 'usd-convert-gsplat[usd]')")
    return rows


if __name__ == "__main__":  # python -m gaslight_usd.bench.suite_usd [--quick]
    import json

    result = run({"quick": "--quick" in sys.argv, "out": Path("bench-usd")})
    print(json.dumps(result, indent=1))
