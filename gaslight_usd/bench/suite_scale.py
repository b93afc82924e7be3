"""Bench suite "scale": the whole chain's time and peak memory against photo count and size.

Users shoot sets of 20-100 photos of 12-24 MP; what must not happen is that
time and memory grow with the camera's megapixels. Each case runs
``gaslight2usd run PHOTOS -o OUT --preset P`` (SfM, uplift, fit, USD, HDRI) as
a subprocess on the bundled example's photos upscaled to the case's size (EXIF
kept, so exposures and the focal prior still hold) and reads the time of each
stage from its ``report.json``; peak memory is the child's ``ru_maxrss`` as
``os.wait4`` reports it: the largest resident set of the process and of any
process it waited for (not their sum; the chain runs in one process). Sets of
more than 24 photos repeat the 24 under new names: the work grows as with new
photos, the scene does not (re-rendering 96 views takes too long for a bench).

Default cases: 24 photos at 0.2 / 3 / 12 MP and 12 / 48 / 96 photos at 12 MP
(fast preset); ``--photos`` and ``--megapixels`` give the grid, ``--preset``
the presets; quick: 12 photos at 0.2 and 3 MP. Each run's splats are scored at the
example's probes (:func:`probe_accuracy`), so a faster run that lost accuracy shows.
Besides the runner's chart (wall seconds against peak memory) it draws
``scale_curves.png``: seconds and peak memory against the set's total megapixels, a
line per photo size.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, NamedTuple

from ..atomic import atomic_path
from ..errors import GaslightError
from ..imageio import LDR_EXTENSIONS, list_images
from ..locate import example_room

NAME = "scale"
DESCRIPTION = "whole chain on upscaled photos: seconds and peak memory vs photo count and size"
X = ("seconds", "wall seconds (whole chain)")
Y = ("peak_rss_gb", "peak memory (GB, largest resident set)")
HIGHER_IS_BETTER = False
TABLE = ("photos", "megapixels", "seconds", "cpu_s", "peak_rss_gb", "uplift_s", "poses_s", "fit_s",
         "export_s", "hdri_s", "splats", "probe_pu21_psnr_aligned", "median_rotation_error_deg")
EXAMPLE = example_room()
STAGES = ("uplift", "poses", "fit", "export", "hdri")
DEFAULT_CASES = ((24, 0.2), (24, 3.0), (24, 12.0), (12, 12.0), (48, 12.0), (96, 12.0))
QUICK_CASES = ((12, 0.2), (12, 3.0))
NAMED_SIZES = {12.0: (4032, 3024), 3.0: (2016, 1512), 0.2: (480, 360)}
"""Phone-like sizes (4:3); 0.2 MP is the example's own 480 x 360."""
RUN_MAIN = "import sys; from gaslight_usd.cli.main import main; sys.exit(main())"
"""The CLI as ``python -P -c RUN_MAIN ...``: ``-P`` keeps the working directory off
``sys.path``, so a source checkout's ``gaslight_usd`` folder (which lacks the
converters that the installed package maps in) is never imported instead."""


def photo_size(megapixels: float, width: int = 480, height: int = 360) -> tuple[int, int]:
    """The size of a ``width`` x ``height`` photo upscaled to about ``megapixels`` (never
    below its own; 12 and 3 MP are the usual 4032 x 3024 and 2016 x 1512)."""
    if megapixels in NAMED_SIZES and (width, height) == (480, 360):
        return NAMED_SIZES[megapixels]
    k = max(1.0, math.sqrt(megapixels * 1e6 / (width * height)))
    return round(width * k), round(height * k)


def upscale_photos(src: Path, dst: Path, width: int, height: int) -> list[Path]:
    """Every photo of ``src`` enlarged to ``width`` x ``height`` into ``dst`` (JPEG, EXIF
    and the other metadata kept); photos already there are reused.

    Pixels are replicated (nearest), not interpolated: a real 12 MP photo is sharp,
    and a smooth enlargement blurs a clipped lamp's edge into a near-white ring,
    which the fast predictor reads as a white wall that only just clips (on the
    example's view_00-07 shrunk back to 512 px, the uplift's brightest pixels were
    93/60/76/31 from the 480 px photos, 69/17/4/52 from replicated pixels and
    10/1/2/1 from a smooth enlargement).
    """
    import OpenImageIO as oiio

    dst.mkdir(parents=True, exist_ok=True)
    out = []
    for path in list_images(src, LDR_EXTENSIONS):
        target = dst / f"{path.stem}.jpg"
        if not target.exists():
            buf = oiio.ImageBuf(str(path))
            big = oiio.ImageBufAlgo.resample(buf, interpolate=False,
                                             roi=oiio.ROI(0, width, 0, height, 0, 1, 0, 3))
            big.specmod().attribute("Compression", "jpeg:92")
            with atomic_path(target) as tmp:
                if not big.write(str(tmp), "uint8", "jpeg"):
                    raise GaslightError(f"cannot write {target}: {big.geterror()}")
        out.append(target)
    return out


def photo_set(photos: list[Path], folder: Path, count: int) -> Path:
    """A folder of ``count`` photos: links to ``photos``, repeated under new names when
    ``count`` exceeds them (``view_00_r1.jpg`` ...)."""
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(count):
        src = photos[i % len(photos)]
        rep = i // len(photos)
        link = folder / (src.name if rep == 0 else f"{src.stem}_r{rep}{src.suffix}")
        if not link.exists():
            link.symlink_to(src.resolve())
    return folder


# A small launcher between the caller and the measured command. Linux counts the
# memory a process had before its exec in its peak (ru_maxrss), and a child forked
# from a big process (a pytest run with torch loaded, 1.3 GB) starts out that big.
# The launcher's own pre-exec peak stays with the launcher; the command it starts
# is forked from a small interpreter, so its peak is its own.
_LAUNCH = ("import os, subprocess, sys; p = subprocess.Popen(sys.argv[2:]); "
           "_, status, usage = os.wait4(p.pid, 0); "
           "open(sys.argv[1], 'w').write(f'{usage.ru_maxrss} "
           "{usage.ru_utime + usage.ru_stime}'); "
           "sys.exit(os.waitstatus_to_exitcode(status))")


class Measured(NamedTuple):
    code: int
    seconds: float
    """Wall seconds."""
    peak_gb: float
    """Peak resident set (GiB) of the command and its waited-for children."""
    cpu_seconds: float
    """User + system CPU seconds of all their threads: on a machine shared with other
    work it still compares runs when wall seconds do not."""


def run_measured(command: list[str], log: Path) -> Measured:
    """Run ``command`` through a small launcher process that reads its ``os.wait4``."""
    peak_file = log.with_name(log.name + ".peak")
    peak_file.unlink(missing_ok=True)
    t0 = time.perf_counter()
    with open(log, "wb") as out:
        code = subprocess.run([sys.executable, "-P", "-c", _LAUNCH, str(peak_file), *command],
                              stdout=out, stderr=subprocess.STDOUT).returncode
    seconds = time.perf_counter() - t0
    peak_kib, cpu = (map(float, peak_file.read_text().split()) if peak_file.is_file()
                     else (0.0, 0.0))
    peak_file.unlink(missing_ok=True)
    return Measured(code, seconds, peak_kib / 1024 ** 2, cpu)  # KiB -> GiB


def run_case(photos: Path, out: Path, preset: str, extra: tuple[str, ...] = ()
             ) -> dict[str, Any]:
    """One whole-chain run of ``photos`` into ``out``: seconds per stage, peak memory."""
    cmd = [sys.executable, "-P", "-c", RUN_MAIN, "run", str(photos), "-o", str(out), "--preset",
           preset, "--fresh", "-q", *extra]
    code, wall, peak, cpu = run_measured(cmd, out.with_suffix(".log"))
    row: dict[str, Any] = {"seconds": round(wall, 2), "cpu_s": round(cpu, 1),
                           "peak_rss_gb": round(peak, 3), "exit_code": code}
    report = out / "report.json"
    if report.exists():
        stages = json.loads(report.read_text())["stages"]
        for stage in stages:
            row[f"{stage['name']}_s"] = stage["seconds"]
            if stage["name"] == "fit":
                row["splats"] = stage["counts"].get("splats")
    if code != 0:
        row["error"] = out.with_suffix(".log").read_text(errors="replace")[-400:]
    return row


def probe_accuracy(out: Path, example: Path = EXAMPLE) -> dict[str, float]:
    """The run's splats scored at the example's probes, as the fit suite scores them.

    The run solved its own poses (SfM frame, unknown scale): its cameras are
    similarity-aligned onto the true ones by name, and each probe is drawn from the
    true probe point mapped into the run's frame with the true frame's axes.
    Medians over the probes (:func:`.suite_fit.probe_scores`, no relight).
    """
    import numpy as np

    from ..imageio import read_image
    from ..ply import read_ply
    from ..poses import read_poses
    from ..poses.frame import align_and_compare, split_similarity
    from ..render.envmap import PROBE_NEAR, render_latlong
    from .suite_fit import probe_scores

    cmp = align_and_compare(read_poses(out / "sparse"), read_poses(example / "sparse" / "0"))
    s, rot, t = split_similarity(cmp["similarity"])  # x_true = s * rot @ x_run + t
    scene = read_ply(out / "splats.ply")
    info = json.loads((example / "probes" / "probes.json").read_text())
    truths = [read_image(example / "probes" / p["name"]).pixels for p in info["probes"]]
    panos = [render_latlong(scene, rot.T @ (np.asarray(p["position"], np.float64) - t) / s,
                            truth.shape[1], near=PROBE_NEAR / s, rotation=rot)
             for p, truth in zip(info["probes"], truths, strict=True)]
    scores = probe_scores(panos, truths, relight=False)
    return {"probe_pu21_psnr_aligned": round(scores["probe_pu21_psnr_aligned"], 3),
            "probe_log_lum_rmse": round(scores["probe_log_lum_rmse"], 4),
            "median_rotation_error_deg": round(cmp["median_rotation_error_deg"], 4)}


def cases(options: dict[str, Any]) -> list[tuple[int, float]]:
    counts, sizes = options.get("photos"), options.get("megapixels")
    if counts or sizes:
        return [(n, mp) for mp in (sizes or (12.0,)) for n in (counts or (24,))]
    return list(QUICK_CASES if options.get("quick") else DEFAULT_CASES)


def run(options: dict[str, Any]) -> list[dict[str, Any]]:
    if not (EXAMPLE / "photos").is_dir():
        raise GaslightError(f"the scale suite needs the bundled example's photos at {EXAMPLE}")
    out = Path(options.get("out") or ".") / "scale-runs"
    progress = options.get("progress")
    rows = []
    for preset in options.get("presets") or ("fast",):
        for count, mp in cases(options):
            w, h = photo_size(mp)
            src = (EXAMPLE / "photos" if (w, h) == (480, 360) else
                   out / "photos" / f"{w}x{h}")
            photos = (list_images(src, LDR_EXTENSIONS) if src == EXAMPLE / "photos" else
                      upscale_photos(EXAMPLE / "photos", src, w, h))
            folder = photo_set(photos, out / "sets" / f"{count}x{w}x{h}", count)
            if progress is not None:
                progress.message(f"{preset}: {count} photos of {w}x{h}")
            row = run_case(folder, out / f"{preset}-{count}x{w}x{h}", preset)
            if row["exit_code"] == 0:
                row.update(probe_accuracy(out / f"{preset}-{count}x{w}x{h}"))
            rows.append({"method": preset, "setting": f"{count} x {w * h / 1e6:.1f} MP",
                         "photos": count, "megapixels": round(w * h / 1e6, 2),
                         "width": w, "height": h, **row})
    curves_chart(rows, Path(options.get("out") or ".") / "scale_curves.png")
    return rows


def notes(options: dict[str, Any]) -> list[str]:
    return [f"cases (photos, MP): {cases(options)}; presets: "
            f"{', '.join(options.get('presets') or ('fast',))}; {os.cpu_count()} cores",
            "peak memory: ru_maxrss of the run (largest process, not a sum)"]


def curves_chart(rows: list[dict[str, Any]], path: Path) -> Path:
    """Seconds (per stage stacked as lines) and peak memory against the set's megapixels."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.5), dpi=110)
    FigureCanvasAgg(fig)
    left, right = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    groups: dict[tuple[str, float], list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r["method"], r["megapixels"]), []).append(r)
    for (preset, mp), members in sorted(groups.items()):
        members.sort(key=lambda r: r["photos"])
        total = [r["photos"] * r["megapixels"] for r in members]
        label = f"{preset}, {mp:g} MP photos"
        left.plot(total, [r["seconds"] for r in members], "o-", label=label)
        right.plot(total, [r["peak_rss_gb"] for r in members], "o-", label=label)
        for r, x in zip(members, total, strict=True):
            left.annotate(f"{r['photos']}", (x, r["seconds"]), fontsize=7,
                          textcoords="offset points", xytext=(3, 3))
    for ax, ylabel in ((left, "wall seconds (whole chain)"), (right, "peak memory (GB)")):
        ax.set_xscale("symlog", linthresh=1.0)
        ax.set_xlabel("photos x megapixels (the set's total MP)")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("gaslight2usd run: time and memory against the set's size")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    return path
