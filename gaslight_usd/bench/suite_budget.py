"""Bench suite "budget": model no more than the scene needs, with the cost shown.

One fit of the bundled room from its true HDR views (true poses, so the model's size
is what is measured, not the uplift), then the model cut down the ways a user can:

* ``splat budget`` -- the top share of splats by contribution
  (:func:`gaslight_usd.fit.smallest.contribution_rank`, as ``run --tolerance-stops``);
* ``SH degree`` -- every splat, SH coefficients above a degree dropped;
* ``palette`` -- the instancer's emitter palette at k colours
  (:mod:`gaslight_usd.usd.palette`); error: 95th percentile brightness error (stops);
* ``rig`` -- the light rig with at most k lights (:func:`gaslight_usd.usd.rig.fit_rig`);
  error: log2(1 + its relative irradiance error at the probe).

With ``--refit`` each splat budget of the cut-down rows is also fitted from scratch
(``splat budget (refit)``: ``fit.budget`` set to that count, same seed and views), so a
user sees what cutting one fit loses against fitting small (the fit then chooses which
splats to grow under the budget); its ``seconds`` is that fit's.

Splat and SH rows carry ``error_stops`` (log-luminance RMSE on the fit's held-out
views), ``cost_stops`` (that minus the full model's) and ``irradiance_psnr`` at probe 0
against the path-traced truth; ``seconds`` is what the form costs to make or draw (the
probe panorama's render, the palette's or the rig's fit), ``size_bytes`` its float32
size. The chart puts error against size; ``budget-time.png`` error against seconds.
The smallest form within a tolerance is then read off the table::

    gaslight2usd bench --suite budget -o DIR
    gaslight2usd bench --suite budget --refit -o DIR   # + one fit per budget
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..fit import fit_splats, load_fit_data, preset
from ..fit.smallest import candidates, contribution_rank, model_bytes, score
from ..locate import example_room
from .suite_chain import TRUTH_SPACE, irradiance_psnr

NAME = "budget"
DESCRIPTION = "error against model size and time: splat budget, SH degree, palette, rig size"
X = ("size_bytes", "model size (bytes, float32)")
Y = ("error_stops", "error (stops)")
HIGHER_IS_BETTER = False
FRONT_BY = "method"
"""Each way of cutting the model has its own error: a Pareto front per method."""
TABLE = ("size_bytes", "seconds", "error_stops", "cost_stops", "irradiance_psnr")
PALETTE_SIZES = (1, 2, 4, 8, 16, 32)
RIG_SIZES = (1, 2, 4, 8)
FIT_STEPS = {"iterations": 200}
"""The budget fit is shortened so the suite runs in minutes (``--full``: the preset's)."""


def notes(options: dict[str, Any]) -> list[str]:
    steps = "" if options.get("full") else f", {FIT_STEPS['iterations']} steps"
    refit = ("; 'splat budget (refit)': each budget fitted from scratch (seconds: its fit)"
             if options.get("refit") else " (no refit; --refit fits each budget too)")
    return [f"room from true HDR views, preset {(options.get('presets') or ('fast',))[0]}"
            f"{steps}; splat shares ranked by contribution{refit}; palette and rig "
            "errors are against the splats themselves, not the truth"]


def _probe(folder: Path) -> tuple[np.ndarray, dict[str, Any]]:
    probes = json.loads((folder / "probes" / "probes.json").read_text())["probes"]
    return np.asarray(probes[0]["position"], np.float64), probes[0]


def splat_rows(result, data, folder: Path, held: list[int], train: list[int],
               quick: bool, space: str) -> list[dict[str, Any]]:
    """Every (share, SH degree) candidate: held-out error, size, probe render seconds."""
    scene = result.scene
    cams = result.cameras
    backdrop = int(result.metrics.get("backdrop_splats", 0))
    keep = np.arange(scene.count - backdrop, scene.count)
    rank = contribution_rank(scene, [cams[i] for i in train])
    views_c, views_i = [cams[i] for i in held], [data.images[i] for i in held]
    full_err = score(scene, views_c, views_i)
    rows = []
    for count, degree, cand in candidates(scene, rank, keep):
        is_sh = count == scene.count
        if quick and not (is_sh or degree == scene.sh_degree):
            continue
        err = score(cand, views_c, views_i)
        t0 = time.perf_counter()
        psnr = math.nan if quick else probe0_psnr(cand, folder, space)
        seconds = time.perf_counter() - t0
        for method in (("SH degree",) if is_sh else ()) + (
                ("splat budget",) if degree == scene.sh_degree else ()):
            rows.append({"method": method,
                         "setting": f"{count} splats, SH {degree}",
                         "splats": count, "sh_degree": degree,
                         "size_bytes": model_bytes(count, degree),
                         "seconds": round(seconds, 3), "error_stops": round(err, 4),
                         "cost_stops": round(err - full_err, 4),
                         "irradiance_psnr": psnr})
    return rows


def refit_rows(data, cfg, seed: int, counts: list[int], held: list[int], folder: Path,
               full_err: float, quick: bool, space: str) -> list[dict[str, Any]]:
    """Each budget in ``counts`` fitted from scratch with ``cfg`` (``fit.budget`` = the
    count): held-out error on the same ``held`` views, cost against the full fit's
    ``full_err``, probe 0 PSNR, and the fit's seconds."""
    rows = []
    for count in sorted(counts):
        t0 = time.perf_counter()
        result = fit_splats(data, cfg.updated(budget=int(count)), seed=seed)
        seconds = time.perf_counter() - t0
        scene = result.scene
        err = score(scene, [result.cameras[i] for i in held], [data.images[i] for i in held])
        rows.append({"method": "splat budget (refit)",
                     "setting": f"budget {count}: {scene.count} splats, SH {scene.sh_degree}",
                     "splats": scene.count, "sh_degree": scene.sh_degree, "budget": int(count),
                     "size_bytes": model_bytes(scene.count, scene.sh_degree),
                     "seconds": round(seconds, 2), "error_stops": round(err, 4),
                     "cost_stops": round(err - full_err, 4),
                     "irradiance_psnr": math.nan if quick else probe0_psnr(scene, folder,
                                                                            space)})
    return rows


def probe0_psnr(scene, folder: Path, space: str) -> float:
    """Irradiance PSNR (dB) of ``scene``'s panorama at the room's first probe against the
    path-traced one (:func:`.suite_chain.irradiance_psnr`)."""
    from ..colour import convert
    from ..imageio import read_image
    from ..render.envmap import render_latlong

    position, probe = _probe(folder)
    truth = read_image(folder / "probes" / probe["name"]).pixels
    pano = render_latlong(scene, position, truth.shape[1])
    if space != TRUTH_SPACE:
        pano = convert(pano, space, TRUTH_SPACE)
    return irradiance_psnr(np.maximum(pano, 0.0), truth)


def palette_rows(scene, quick: bool) -> list[dict[str, Any]]:
    """Emitter palette at each size: p95 brightness error (stops), fit seconds."""
    from ..usd.instancer import emitter_mask
    from ..usd.palette import DEFAULT_THRESHOLD, _palette_for

    colours = scene.base_colours[emitter_mask(scene, DEFAULT_THRESHOLD)]
    rows = []
    if not len(colours):
        return rows
    for k in PALETTE_SIZES[:3] if quick else PALETTE_SIZES:
        t0 = time.perf_counter()
        pal = _palette_for(colours, k, 0)
        seconds = time.perf_counter() - t0
        rows.append({"method": "palette", "setting": f"{pal.size} colours",
                     "palette_size": pal.size, "size_bytes": pal.size * 12,
                     "seconds": round(seconds, 3),
                     "error_stops": round(float(np.percentile(pal.stops_error, 95)), 4)})
    return rows


def rig_rows(scene, position: np.ndarray, space: str, quick: bool) -> list[dict[str, Any]]:
    """Light rig with at most k lights: log2(1 + relative irradiance error), fit seconds."""
    from ..render.envmap import render_latlong
    from ..usd.instancer import emitter_mask
    from ..usd.palette import DEFAULT_THRESHOLD
    from ..usd.rig import EVAL_WIDTH, fit_rig

    mask = emitter_mask(scene, DEFAULT_THRESHOLD)
    if not mask.any():
        return []
    full = render_latlong(scene, position, EVAL_WIDTH)
    dome = render_latlong(scene.subset(~mask), position, EVAL_WIDTH)
    rows = []
    for k in RIG_SIZES[:2] if quick else RIG_SIZES:
        t0 = time.perf_counter()
        lights, metrics = fit_rig(scene, position, dome, full, mask, 0.0, space, None,
                                  max_lights=k)
        seconds = time.perf_counter() - t0
        n = metrics["lights"]
        rows.append({"method": "rig", "setting": f"{n} lights (max {k})", "lights": n,
                     "size_bytes": n * 4 * 7, "seconds": round(seconds, 3),
                     "error_stops": round(math.log2(1 + metrics["irradiance_error"]), 4)})
    return rows


def run(options: dict[str, Any]) -> list[dict[str, Any]]:
    quick = bool(options.get("quick"))
    seed = int(options.get("seed", 0))
    preset_name = (options.get("presets") or ("fast",))[0]
    folder = example_room()
    cfg = preset(preset_name) if options.get("full") else preset(preset_name).updated(
        **FIT_STEPS)
    data = load_fit_data(folder / "truth", folder / "sparse" / "0",
                         working_size=cfg.working_size)
    t0 = time.perf_counter()
    result = fit_splats(data, cfg, seed=seed)
    fit_seconds = time.perf_counter() - t0
    names = list(data.names)
    held = [names.index(n) for n in result.metrics["held_out_views"]]
    train = [i for i in range(len(names)) if i not in held]
    position, _ = _probe(folder)
    rows = splat_rows(result, data, folder, held, train, quick, data.colour_space)
    if options.get("refit"):
        full = next(r for r in rows if r["method"] == "splat budget"
                    and r["splats"] == result.scene.count)
        counts = [r["splats"] for r in rows if r["method"] == "splat budget"
                  and r["splats"] < result.scene.count]
        rows += refit_rows(data, cfg, seed, counts[:1] if quick else counts, held, folder,
                           full["error_stops"] - full["cost_stops"], quick,
                           data.colour_space)
    rows += palette_rows(result.scene, quick)
    rows += rig_rows(result.scene, position, data.colour_space, quick)
    for r in rows:
        r["fit_seconds"] = round(fit_seconds, 2)
        r["full_splats"] = result.scene.count
    draw_time_chart(rows, Path(options.get("out") or "."))
    return rows


def draw_time_chart(rows: list[dict[str, Any]], out: Path) -> Path:
    """``budget-time.png``: error (stops) against seconds, one line per method."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..atomic import atomic_path

    fig = Figure(figsize=(6, 4))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    for method in dict.fromkeys(r["method"] for r in rows):
        pts = sorted((r["seconds"], r["error_stops"]) for r in rows if r["method"] == method)
        ax.plot(*zip(*pts, strict=True), "o-", label=method)
    ax.set_xlabel("seconds to make or draw the form (s)")
    ax.set_ylabel("error (stops)")
    ax.set_title("budget: error against time")
    ax.legend(fontsize=8)
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    path = out / "budget-time.png"
    with atomic_path(path) as tmp:
        fig.savefig(str(tmp), format="png", dpi=90)
    return path
