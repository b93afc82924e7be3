"""Bench suite "stability": where each uplift method breaks, and what the user is told.

On a generated room (the chain bench's scenes and probe scores, :mod:`.suite_chain`),
the photos are re-made from the true radiance with one thing a real capture gets
wrong (:mod:`.perturb`: fewer photos, sensor noise, JPEG quality, white balance and
exposure offsets, motion blur, a light half out of frame or seen once, photos with
nothing clipped, fully clipped frames, pose noise), at rising strengths. The chain then
runs as ``gaslight2usd run`` runs it (its uplift and fit converters, so their
warnings are what the user reads; true poses unless the perturbation moves them) and
is scored at the probes against the path-traced truth.

**Breaks** is defined as: the run fails, or its median irradiance PSNR over the probes
is more than :data:`BREAK_DB` dB below the unperturbed run of the same method and
preset, or its worst light's power at the probes (median over the probes of the largest
``|power_err|``) is more than :data:`BREAK_STOPS` stops further off than there, or a
splat or probe value is NaN/Inf. (A run already near the floor barely loses PSNR when a
light goes astray: the power rule sees it.) A break is **silent** when the run told
the user nothing: no ``warning:`` line, no fallback line, no error.

Rows: one per (method, preset, perturbation, strength, probe); ``told`` holds the
warning, fallback and error lines captured from the run. ``summaries`` gives, per
(method, preset, perturbation), the curve and its break point. Curves are drawn per
perturbation into ``stability-<kind>.png``. Default sweep: method ``recursive``,
preset ``fast``, every perturbation at the strengths of :data:`DEFAULT_STRENGTHS`
(about 15 min on 2 cores); ``--method``, ``--preset``, ``--perturb`` and ``--full``
(every strength of :data:`.perturb.KINDS`) widen it::

    gaslight2usd bench --suite stability -o DIR
"""

from __future__ import annotations

import io
import json
import math
import re
import shutil
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import GaslightError
from ..progress import Progress
from .perturb import KINDS, make_capture
from .suite_chain import absolute_scale, probe_rows, scene_dir, scene_lights

NAME = "stability"
DESCRIPTION = "where each uplift method breaks under capture faults, and what it said"
X = ("seconds", "uplift + fit seconds")
Y = ("irradiance_psnr", "probe irradiance PSNR (dB)")
HIGHER_IS_BETTER = True
TABLE = ("seconds", "irradiance_psnr", "drop_db", "power_worse_stops", "broken", "told_count")
METHODS = {"recursive": "uplift.recursive", "clipped photos": "uplift.linear"}
BREAK_DB = 3.0
BREAK_STOPS = 1.0
"""A run breaks when its median probe irradiance PSNR is this far below the unperturbed run."""
DEFAULT_STRENGTHS: dict[str, tuple[float, ...]] = {
    "photos": (8, 4), "noise": (0.05,), "jpeg": (30, 10), "white_balance": (0.3,),
    "exposure": (1.0,), "motion_blur": (15,), "light_half_out": (1,),
    "light_one_view": (1,), "no_clip": (1.0,), "clipped_frames": (6,), "pose_noise": (1.0,),
}
QUICK_STRENGTHS: dict[str, tuple[float, ...]] = {"photos": (4,), "clipped_frames": (6,)}
FIT_STEPS = {"iterations": 120, "working_size": 80}
"""The sweep's fits are shortened (fewer steps, smaller views) so that the default sweep
runs in minutes; ``--full`` fits with the preset as it is."""
TOLD = re.compile(r"warning|does not apply|fall(s|ing)? back|fallback|failed|left out|instead",
                  re.IGNORECASE)


def notes(options: dict[str, Any]) -> list[str]:
    return [f"breaks: the run fails, a NaN/Inf reaches the splats or probes, or the median "
            f"probe irradiance PSNR drops more than {BREAK_DB:g} dB below the unperturbed run, "
            f"or the worst light's power at the probes is {BREAK_STOPS:g} stop(s) further off; "
            "silent: broke with no warning, fallback or error told",
            "fits shortened to {iterations} steps at {working_size} px unless --full".format(
                **FIT_STEPS)]


def sweep(options: dict[str, Any]) -> dict[str, tuple[float, ...]]:
    """Perturbation -> strengths to run (mildest first)."""
    chosen = options.get("perturbations") or None
    base = KINDS if options.get("full") else (
        QUICK_STRENGTHS if options.get("quick") and not chosen else DEFAULT_STRENGTHS)
    kinds = chosen or list(base)
    unknown = [k for k in kinds if k not in KINDS]
    if unknown:
        raise GaslightError(f"stability suite: unknown perturbation {', '.join(unknown)} "
                            f"(choose from {', '.join(KINDS)})")
    return {k: base.get(k, KINDS[k]) for k in kinds}


def told_lines(text: str) -> list[str]:
    """The lines of a run's messages that warn, announce a fallback or report a failure."""
    return list(dict.fromkeys(line.strip() for line in text.splitlines() if TOLD.search(line)))


def finite_scene(scene) -> bool:
    """Whether every splat array of ``scene`` is finite."""
    arrays = (scene.positions, scene.rotations, scene.log_scales, scene.opacity_logits, scene.sh)
    return all(bool(np.isfinite(a).all()) for a in arrays)


def run_case(folder: Path, capture, method: str, preset_name: str, work: Path,
             seed: int, full: bool = False) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """The chain on one capture, as ``gaslight2usd run`` runs it (uplift and fit
    converters, so every warning they print is captured): (probe rows, run facts:
    seconds, told, error, finite)."""
    from ..imageio import read_image
    from ..kinds import Kind
    from ..pipeline import Job, run_job
    from ..ply import read_ply

    stream = io.StringIO()
    progress = Progress("case", stream=stream)
    facts: dict[str, Any] = {"error": None, "finite": True}
    info = json.loads((folder / "scene.json").read_text())
    fit_opts = {"preset": preset_name, "seed": seed, **({} if full else FIT_STEPS)}
    t0 = time.perf_counter()
    rows: list[dict[str, Any]] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            job = Job(inputs=[capture.photos, capture.poses], out_dir=work,
                      targets=(Kind.SPLATS,), choose={"uplift": METHODS[method]},
                      options={"fit": fit_opts}, resume=False)
            found = run_job(job, progress=progress)
            facts["seconds"] = time.perf_counter() - t0
            scene = read_ply(found[Kind.SPLATS].path)
            facts["finite"] = finite_scene(scene)
            first = sorted((work / "hdr").glob("*.exr"))[0]
            attrs = {k: v for k, v in read_image(first).metadata.items()
                     if k.startswith("gaslight:")}
            scale = absolute_scale(attrs, info["exposure"])
            rows = probe_rows(scene, folder, scale, relight=False)
        except (GaslightError, ValueError, RuntimeError, OSError) as exc:
            facts["error"] = f"{type(exc).__name__}: {exc}".splitlines()[0]
            facts["seconds"] = time.perf_counter() - t0
    told = told_lines(stream.getvalue()) + [f"warning: {w.message}" for w in caught]
    if facts["error"]:
        told.append(f"error: {facts['error']}")
    facts["told"] = told
    if any(not math.isfinite(r.get("irradiance_psnr", 0.0)) for r in rows):
        facts["finite"] = False
    return rows, facts


def run(options: dict[str, Any]) -> list[dict[str, Any]]:
    seed = int(options.get("seed", 0))
    out = Path(options.get("out") or ".")
    progress = options.get("progress")
    presets = options.get("presets") or ("fast",)
    methods = options.get("methods") or ("recursive",)
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise GaslightError(f"stability suite: unknown method {', '.join(unknown)} "
                            f"(choose from {', '.join(METHODS)})")
    scene_name = (options.get("scenes") or ("room",))[0]
    folder = scene_dir(scene_name, out, progress)
    lights = scene_lights(json.loads((folder / "scene.json").read_text()))
    cases = [("none", 0.0)] + [(k, s) for k, ss in sweep(options).items() for s in ss]
    rows: list[dict[str, Any]] = []
    work_root = out / "work" / "stability"
    for kind, strength in cases:
        cap_dir = work_root / f"{kind}-{strength:g}"
        capture = make_capture(folder, cap_dir / "capture", kind, strength, seed, lights)
        for preset_name in presets:
            for method in methods:
                if progress is not None:
                    progress.message(f"{kind} {strength:g}: {method} ({preset_name})")
                work = cap_dir / f"{method.replace(' ', '_')}-{preset_name}"
                probe, facts = run_case(folder, capture, method, preset_name, work, seed,
                                        bool(options.get("full")))
                base = {"method": method, "setting": f"{preset_name} {kind} {strength:g}",
                        "preset": preset_name, "scene": scene_name, "perturbation": kind,
                        "strength": strength, "capture": capture.note,
                        "seconds": round(facts["seconds"], 2), "error": facts["error"],
                        "finite": facts["finite"], "told": " | ".join(facts["told"]),
                        "told_count": len(facts["told"])}
                rows += [{**base, **r} for r in probe] or [
                    {**base, "probe": -1, "irradiance_psnr": math.nan}]
                shutil.rmtree(work, ignore_errors=True)
    mark_breaks(rows)
    draw_curves(rows, out)
    return rows


def mark_breaks(rows: list[dict[str, Any]]) -> None:
    """Add ``drop_db``, ``broken`` and ``silent`` to every row (per run, probes' median)."""
    runs: dict[tuple, list[dict[str, Any]]] = {}
    for r in rows:
        runs.setdefault((r["method"], r["preset"], r["perturbation"], r["strength"]), []).append(r)
    median = {k: _median(v, "irradiance_psnr") for k, v in runs.items()}
    power = {k: _median(v, "power_err_stops_max") for k, v in runs.items()}
    for (method, preset_name, kind, strength), members in runs.items():
        key, base = (method, preset_name, kind, strength), (method, preset_name, "none", 0.0)
        ref, value = median.get(base, math.nan), median[key]
        drop = ref - value if math.isfinite(ref) and math.isfinite(value) else math.nan
        worse = power[key] - power.get(base, math.nan)
        first = members[0]
        broken = bool(first["error"] or not first["finite"] or not math.isfinite(value)
                      or (math.isfinite(drop) and drop > BREAK_DB)
                      or (math.isfinite(worse) and worse > BREAK_STOPS))
        for r in members:
            r["drop_db"] = round(drop, 2) if math.isfinite(drop) else math.nan
            r["power_worse_stops"] = round(worse, 2) if math.isfinite(worse) else math.nan
            r["broken"] = broken
            r["silent"] = broken and not r["told_count"]


def _median(rows: list[dict[str, Any]], key: str) -> float:
    values = [float(r.get(key, math.nan)) for r in rows]
    return float(np.nanmedian(values)) if any(math.isfinite(v) for v in values) else math.nan


def summaries(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (method, preset, perturbation): its curve and the first strength that breaks."""
    out: dict[tuple, dict[str, Any]] = {}
    seen: set[tuple] = set()
    for r in rows:
        run_key = (r["method"], r["preset"], r["perturbation"], r["strength"])
        if r["perturbation"] == "none" or run_key in seen:
            continue
        seen.add(run_key)
        key = run_key[:3]
        entry = out.setdefault(key, {"method": key[0], "preset": key[1], "perturbation": key[2],
                                     "curve": [], "breaks_at": None, "silent": False,
                                     "told_at_break": "", "told": []})
        entry["told"] += [t for t in r["told"].split(" | ") if t and t not in entry["told"]]
        entry["curve"].append(f"{r['strength']:g}:{-r['drop_db']:+.1f}dB"
                              if math.isfinite(r["drop_db"]) else f"{r['strength']:g}:fail")
        if r["broken"] and entry["breaks_at"] is None:
            entry["breaks_at"] = r["strength"]
            entry["silent"] = r["silent"]
            entry["told_at_break"] = r["told"][:200]
    for entry in out.values():
        entry["curve"] = " ".join(entry["curve"])
        entry["told"] = " | ".join(entry["told"])[:300] or "nothing"
        if entry["breaks_at"] is None:
            entry["breaks_at"] = "none"
    return list(out.values())


def draw_curves(rows: list[dict[str, Any]], out: Path) -> list[Path]:
    """One PNG per perturbation: irradiance PSNR and drop against strength, a line per
    (method, preset), broken points ringed red, the break threshold dashed."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..atomic import atomic_path

    paths = []
    kinds = list(dict.fromkeys(r["perturbation"] for r in rows if r["perturbation"] != "none"))
    for kind in kinds:
        fig = Figure(figsize=(6, 4))
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(1, 1, 1)
        lines: dict[tuple, dict[float, tuple[float, bool]]] = {}
        for r in rows:
            if r["perturbation"] == kind:
                lines.setdefault((r["method"], r["preset"]), {})[r["strength"]] = (
                    -r["drop_db"] if math.isfinite(r["drop_db"]) else math.nan, r["broken"])
        for (method, preset_name), points in lines.items():
            xs = sorted(points)
            ys = [points[x][0] for x in xs]
            ax.plot(xs, ys, "o-", label=f"{method} ({preset_name})")
            bad = [(x, points[x][0]) for x in xs if points[x][1]]
            if bad:
                ax.plot(*zip(*bad, strict=True), "o", mfc="none", mec="red", ms=12)
        ax.axhline(-BREAK_DB, color="grey", ls="--", lw=1)
        ax.set_xlabel(f"{kind} strength")
        ax.set_ylabel("irradiance PSNR change vs unperturbed (dB)")
        ax.set_title(f"stability: {kind} (red ring: breaks)")
        ax.legend(fontsize=8)
        fig.tight_layout()
        path = out / f"stability-{kind}.png"
        out.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:
            fig.savefig(str(tmp), format="png", dpi=90)
        paths.append(path)
    return paths
