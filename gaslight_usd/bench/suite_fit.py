"""Bench suite "fit": held-out error against splat count and against time.

On the bundled example (``examples/room``: truth HDR views with the TRUE
poses, so the fit alone is measured) when it is present, else on the
synthetic closed scene of :mod:`gaslight_usd.fit.synthetic`. Every
densification round of a fit gives a row (seconds so far, splats, held-out
log-luminance RMSE in stops); the finished fit gives a row with its kept
splat count, held-out PU21-PSNR and wall seconds. Quick mode: the synthetic
scene, a 120-step fit (well under a minute).
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from ..evaluation.metrics import log_luminance_rmse, pu21_psnr
from ..fit import fit_splats, load_fit_data, preset
from ..fit.synthetic import synthetic_data
from ..imageio import read_image
from ..locate import example_room
from ..render.envmap import render_latlong
from ..splats import SplatScene

NAME = "fit"
DESCRIPTION = "splat fitting: held-out HDR error vs seconds and splat count"
X = ("seconds", "fit seconds (wall)")
Y = ("held_out_log_lum_rmse", "held-out log-luminance RMSE (stops)")
HIGHER_IS_BETTER = False
TABLE = ("seconds", "splats", "held_out_log_lum_rmse", "held_out_pu21_psnr",
         "probe_pu21_psnr", "probe_log_lum_rmse")
EXAMPLE = example_room()


def _example_ready() -> bool:
    return (EXAMPLE / "digests.json").exists() and (EXAMPLE / "truth").is_dir()


def probe_errors(scene: SplatScene, example: Path = EXAMPLE) -> dict[str, float]:
    """Panoramas rendered at the example's probe points against the true probes (medians)."""
    info = json.loads((example / "probes" / "probes.json").read_text())
    errs: dict[str, list[float]] = {"probe_pu21_psnr": [], "probe_pu21_psnr_aligned": [],
                                    "probe_log_lum_rmse": []}
    for probe in info["probes"]:
        truth = read_image(example / "probes" / probe["name"]).pixels
        pano = render_latlong(scene, probe["position"], truth.shape[1])
        errs["probe_pu21_psnr"].append(pu21_psnr(pano, truth, align=False))
        errs["probe_pu21_psnr_aligned"].append(pu21_psnr(pano, truth, align=True))
        errs["probe_log_lum_rmse"].append(log_luminance_rmse(pano, truth))
    return {k: float(sorted(v)[len(v) // 2]) for k, v in errs.items()}


def run(options: dict[str, Any]) -> list[dict[str, Any]]:
    quick = bool(options.get("quick"))
    seed = int(options.get("seed", 0))
    rows: list[dict[str, Any]] = []
    if quick or not _example_ready():
        cases = [("synthetic", "fast", {"downscale": 1, "iterations": 120,
                                        "init_points": 1500, "densify_every": 30})]
        if not quick:
            cases.append(("synthetic", "balanced", {"downscale": 1, "iterations": 600}))
    else:
        cases = [("room", "fast", {}), ("room", "balanced", {})]
    for scene, name, changes in cases:
        cfg = preset(name).updated(**changes)
        if scene == "synthetic":
            data = synthetic_data(seed=seed)[1]
        else:
            data = load_fit_data(EXAMPLE / "truth", EXAMPLE / "sparse" / "0", cfg.downscale)
        t0 = time.perf_counter()
        result = fit_splats(data, cfg, seed=seed, progress=options.get("progress"))
        seconds = time.perf_counter() - t0
        for h in result.history:
            rows.append({"method": f"fit {name}", "setting": f"{scene} step {h['step']}",
                         "scene": scene, "seconds": h["seconds"], "splats": h["splats"],
                         "held_out_log_lum_rmse": h["held_out_log_lum_rmse"]})
        m = result.metrics
        rows.append({"method": f"fit {name}", "setting": f"{scene} final",
                     "scene": scene, "seconds": round(seconds, 2), "splats": m["splats"],
                     "held_out_log_lum_rmse": m["held_out_log_lum_rmse_stops"],
                     "held_out_pu21_psnr": m["held_out_pu21_psnr"],
                     "sh_degree": m["sh_degree"], "iterations": m["iterations"],
                     "backdrop_splats": m["backdrop_splats"], "init": m["init"],
                     **(probe_errors(result.scene) if scene == "room" else {})})
    return rows
