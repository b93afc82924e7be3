"""``OUT/batch.json`` and the table ``batch`` prints: one summary per scene.

Read from each scene's ``report.json`` after the batch (shared storage holds it
whichever machine ran the scene): status, time per stage (``skip`` where the
stage matched and was not run), the fingerprints that decided it, output sizes,
the fit's held-out error and the lights the export found. Schema:
``schemas/batch.schema.json``.
"""

from __future__ import annotations

import contextlib
import json
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from .chain import REPORT_FILE, output_files
from .manifest import Scene
from .progress import format_seconds
from .provenance import tool_version

BATCH_FILE = "batch.json"
LOG_FILE = "batch.log"


def batch_report(scenes: list[Scene], outcomes: dict[str, dict[str, Any]],
                 plans: dict[str, dict[str, Any]], out_dir: Path, started: datetime,
                 seconds: float, jobs: int, dask: str | None,
                 manifest: str | Path | None, interrupted: bool) -> dict[str, Any]:
    """``batch.json``: the batch and one summary per scene (see ``scene_summary``)."""
    entries = [scene_summary(s, outcomes[s.name], plans[s.name]) for s in scenes]
    counts = {k: sum(e["status"] == k for e in entries)
              for k in ("done", "skipped", "failed", "interrupted", "not started")}
    status = "interrupted" if interrupted else ("failed" if counts["failed"] else "done")
    return {
        "tool": "gaslight2usd", "version": tool_version(), "status": status,
        "manifest": str(manifest) if manifest else None, "out": str(out_dir),
        "started": started.isoformat(timespec="seconds"),
        "finished": datetime.now(UTC).isoformat(timespec="seconds"),
        "seconds": round(seconds, 3), "jobs": jobs, "dask": dask, "counts": counts,
        "scenes": entries,
    }


def scene_summary(scene: Scene, outcome: dict[str, Any],
                  plan: dict[str, Any]) -> dict[str, Any]:
    """One scene's line of ``batch.json``, from its outcome and its ``report.json``.

    Stages keep their fingerprints (the hashes that decide a skip); ``skipped`` is
    a stage that matched and was not run this time.
    """
    out = Path(scene.job.out_dir)
    report: dict[str, Any] = {}
    with contextlib.suppress(OSError, json.JSONDecodeError):
        report = json.loads((out / REPORT_FILE).read_text())
    scene_skipped = outcome["status"] == "skipped"
    stages, sizes, metrics = [], {}, {}
    lights: list[dict[str, Any]] | None = None
    for rec in report.get("stages", []):
        status = "skipped" if scene_skipped or rec["status"] == "resumed" else rec["status"]
        stages.append({"name": rec["name"], "converter": rec["converter"], "status": status,
                       "seconds": rec["seconds"] if status != "skipped" else 0.0,
                       "fingerprint": rec.get("fingerprint"),
                       "output_fingerprint": rec.get("output_fingerprint"),
                       "error": rec.get("error")})
        if rec["status"] in ("done", "resumed"):
            files = output_files(Path(rec["output"]), rec.get("metadata", {}))
            sizes[rec["name"]] = int(sum(_size(f) for f in files))
        m, c = rec.get("metrics", {}), rec.get("counts", {})
        if rec["name"] == "fit":
            metrics.update({"splats": c.get("splats"),
                            "held_out_log_lum_rmse_stops": m.get("held_out_log_lum_rmse_stops"),
                            "held_out_pu21_psnr": m.get("held_out_pu21_psnr")})
        elif rec["name"] == "export":
            if "lights" in m:  # the lights finder ran (the rig's export)
                lights = [{"position": lt.get("position"), "radius": lt.get("radius"),
                           "power": max(lt.get("power") or [0.0])}
                          for lt in m["lights"].get("lights", [])]
            if "rig" in m:
                metrics["rig_lights"] = m["rig"].get("lights")
        elif rec["name"] == "uplift":
            metrics["hdr_views"] = c.get("views")
        elif rec["name"] == "hdri":
            metrics["probes"] = c.get("probes")
    log_text = outcome.get("log") or ""
    return {
        "name": scene.name, "status": outcome["status"], "seconds": outcome["seconds"],
        "error": outcome.get("error"), "out_dir": str(out), "log": str(out / LOG_FILE),
        "host": outcome.get("host"),
        "planned": [{"name": s["name"], "action": s["action"], "why": s["why"]}
                    for s in plan.get("stages", [])],
        "stages": stages, "bytes": sizes, "metrics": metrics,
        "lights_found": None if lights is None else len(lights), "lights": lights or [],
        "log_tail": log_text.splitlines()[-10:] if outcome["status"] == "failed" else [],
    }


def _size(path: Path) -> int:
    if path.is_file():
        return path.stat().st_size
    if path.is_dir():
        return sum(p.stat().st_size for p in path.rglob("*")
                   if p.is_file() and not p.name.startswith("."))
    return 0


def summary_table(report: dict[str, Any]) -> str:
    """The short per-scene table ``batch`` prints: status, time per stage, size,
    splats, held-out error and lights found."""
    names: list[str] = []
    for scene in report["scenes"]:
        names += [s["name"] for s in scene["stages"] if s["name"] not in names]
    head = ["scene", "status", "time", *names, "size", "splats", "err(st)", "lights"]
    rows = [head]
    for scene in report["scenes"]:
        by = {s["name"]: s for s in scene["stages"]}
        cells = []
        for name in names:
            s = by.get(name)
            cells.append("-" if s is None else "skip" if s["status"] == "skipped"
                         else f"{s['seconds']:.1f}" if s["status"] == "done" else s["status"])
        m = scene["metrics"]
        rmse = m.get("held_out_log_lum_rmse_stops")
        rows.append([scene["name"], scene["status"], f"{scene['seconds']:.1f}s", *cells,
                     _megabytes(sum(scene["bytes"].values())),
                     str(m.get("splats") or "-"), "-" if rmse is None else f"{rmse:.2f}",
                     "-" if scene["lights_found"] is None else str(scene["lights_found"])])
    widths = [max(len(r[i]) for r in rows) for i in range(len(head))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
             for r in rows]
    for scene in report["scenes"]:
        if scene["error"]:
            lines.append(f"{scene['name']}: {scene['error']}")
    c = report["counts"]
    lines.append(f"{c['done']} done, {c['skipped']} skipped, {c['failed']} failed"
                 + (f", {c['interrupted']} interrupted, {c['not started']} not started"
                    if report["status"] == "interrupted" else "")
                 + f" in {format_seconds(report['seconds'])} -> {report['out']}/{BATCH_FILE}")
    return "\n".join(lines)


def _megabytes(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n else "-"
