"""Time a batch as docs/measurements.md reports it, and kill one to see it resume.

On the manifest of ``make_scenes.py``, each into its own folder under OUT:

1. ``--jobs 1``, ``--jobs 2`` and ``--dask local:2``: wall times and their ratios;
2. the same ``--jobs 1`` command again, nothing changed: every scene skipped;
3. ``--jobs 2`` killed with SIGKILL (the whole process group, as a farm kills a
   job) once two scenes are finished, then run again: the finished scenes are
   skipped with their files untouched, the temporary files of the killed writes
   are gone, and every output opens (PLY, EXR, USD).

Prints one JSON object; the load average before and after each run says how
busy the machine was (other work shares it)::

    python examples/batch/measure.py /tmp/scenes/batch.toml /tmp/measure
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

CLI = str(Path(sys.executable).with_name("gaslight2usd"))


def load() -> list[float]:
    return [round(v, 2) for v in os.getloadavg()]


def batch(manifest: Path, out: Path, *extra: str) -> dict:
    """One ``gaslight2usd batch`` run: wall seconds, exit status, its batch.json."""
    before = load()
    t0 = time.perf_counter()
    res = subprocess.run([CLI, "batch", str(manifest), "-o", str(out), "-q", *extra],
                         capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    report = json.loads((out / "batch.json").read_text())
    return {"command": f"gaslight2usd batch {manifest} -o {out} -q {' '.join(extra)}".strip(),
            "seconds": round(seconds, 1), "exit": res.returncode,
            "statuses": [s["status"] for s in report["scenes"]],
            "load_before": before, "load_after": load(), "table": res.stdout}


def mtimes(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.name.startswith(".") and p.name != "batch.log"}


def partials(out: Path) -> list[str]:
    return sorted(str(p.relative_to(out)) for p in out.rglob("*") if ".partial-" in p.name)


def finished_scenes(out: Path) -> list[str]:
    done = []
    for log in sorted(out.glob("*/batch.log")):
        lines = log.read_text(errors="replace").splitlines()
        if lines and lines[-1].startswith("done in"):
            done.append(log.parent.name)
    return done


def every_output_opens(out: Path) -> dict[str, int]:
    """Open every PLY, EXR and USD layer under ``out``; count them (raises on a bad one)."""
    from pxr import Usd

    from gaslight_usd.imageio import read_image
    from gaslight_usd.ply import read_ply

    counts = {"ply": 0, "exr": 0, "usd": 0}
    for path in sorted(out.rglob("*")):
        if path.name.startswith("."):
            continue
        if path.suffix == ".ply":
            read_ply(path)
            counts["ply"] += 1
        elif path.suffix == ".exr":
            read_image(path)
            counts["exr"] += 1
        elif path.suffix in (".usda", ".usdc"):
            assert Usd.Stage.Open(str(path)) is not None, path
            counts["usd"] += 1
    return counts


def same_splats(a: Path, b: Path) -> bool:
    """Whether two PLYs hold the same splats (their headers name their own folders)."""
    from gaslight_usd.ply import read_ply

    x, y = read_ply(a), read_ply(b)
    return all(np.array_equal(getattr(x, k), getattr(y, k)) for k in
               ("positions", "log_scales", "rotations", "opacity_logits", "sh"))


def current_stage(log: Path) -> str | None:
    """The stage a scene's log says is running (its last ``[i/n step] name:`` line)."""
    if not log.exists():
        return None
    lines = log.read_text(errors="replace").split("=== ")[-1].splitlines()
    if lines and lines[-1].startswith("done in"):
        return None
    started = [ln.split("] ", 2)[1] for ln in lines if ln.count("] ") >= 2 and ": " in ln
               and ln.split("] ", 2)[1].startswith("[")]
    return started[-1].strip("[]") if started else None


def kill_and_resume(manifest: Path, out: Path, after: int = 2) -> dict:
    """SIGKILL a ``--jobs 2`` batch once ``after`` scenes are done and a running one is in
    its fit, then run it again."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([CLI, "batch", str(manifest), "-o", str(out), "-q", "--jobs", "2"],
                            start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)

    def running() -> dict[str, str]:
        stages = {log.parent.name: current_stage(log) for log in out.glob("*/batch.log")}
        return {k: v for k, v in stages.items() if v}

    while proc.poll() is None and not (len(finished_scenes(out)) >= after and any(
            "fit" in v for v in running().values())):
        time.sleep(0.2)
    stages_at_kill = running()
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    killed_at = round(time.perf_counter() - t0, 1)
    done = finished_scenes(out)
    kept = {name: mtimes(out / name) for name in done}
    left = partials(out)
    rerun = batch(manifest, out, "--jobs", "2")
    report = json.loads((out / "batch.json").read_text())
    return {
        "killed_after_s": killed_at, "scenes_finished_before_kill": done,
        "stages_running_at_kill": stages_at_kill,
        "temporary_files_left_by_the_kill": left,
        "rerun": rerun,
        "finished_scenes_skipped": all(s["status"] == "skipped" for s in report["scenes"]
                                       if s["name"] in done),
        "finished_scenes_untouched": all(mtimes(out / n) == kept[n] for n in done),
        "temporary_files_after_rerun": partials(out),
        "outputs_open": every_output_opens(out),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("manifest", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--kill-only", action="store_true",
                        help="only part 3 (OUT/j1 from an earlier full run is compared with)")
    args = parser.parse_args()
    out = args.out
    result: dict = {"cores": os.cpu_count()}
    runs = ["kill"]
    if not args.kill_only:
        result["jobs1"] = batch(args.manifest, out / "j1", "--jobs", "1")
        result["jobs2"] = batch(args.manifest, out / "j2", "--jobs", "2")
        result["dask_local2"] = batch(args.manifest, out / "dask", "--dask", "local:2")
        result["rerun_no_change"] = batch(args.manifest, out / "j1", "--jobs", "1")
        base = result["jobs1"]["seconds"]
        result["ratios_to_jobs1"] = {k: round(result[k]["seconds"] / base, 2)
                                     for k in ("jobs2", "dask_local2", "rerun_no_change")}
        runs = ["j2", "dask", "kill"]
    result["kill"] = kill_and_resume(args.manifest, out / "kill")
    names = sorted(p.parent.name for p in (out / "j1").glob("*/splats.ply"))
    result["splats_same_as_jobs1"] = {
        k: all(same_splats(out / k / n / "splats.ply", out / "j1" / n / "splats.ply")
               for n in names) for k in runs}
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
