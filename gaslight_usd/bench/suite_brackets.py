"""Bench suite "brackets": AEB folders as photographers shoot them, grouped and merged.

Each shoot (:func:`~gaslight_usd.evaluation.bracket_shoot.aeb_shoot`) is one
folder of JPEGs: five positions shot as hand-held auto-exposure brackets
(0/-2/+2 EV three times, -4..+4, 0/-3/+3/-6/+6; brightest frames >= 60 %
clipped) and two single photos, one of them shot right after a bracket at the
next exposure of its step. Sources: truth views of the bundled example
(``room``) and crops of the shared panoramas (``panoramas``, when present).
The folder goes through the ``uplift.bracket`` converter as ``gaslight2usd
hdr --method bracket`` runs it, once per camera response (``ocio``: the sRGB
input transform; ``debevec``: recovered per bracket, slow, so full runs
only). Quick mode: ``room`` with ``ocio``. Per position:

- ``grouped``: 1 when its frames, and only they, became one HDR view;
- ``median_stop_err`` / ``p95_stop_err``: |log2| luminance error of the HDR
  view against the true radiance at the EXIF scale (nominal shutter labels
  included), on pixels some frame saw, 4 px border left out (hand-held shift);
- ``scale_free_stop_err``: the same after removing the view's median log ratio
  (the merge alone, without the EXIF labels' rounding);
- ``views``: HDR views the whole folder gave (7 when every position and single
  is one view), ``seconds``: the stage's wall time for the folder.
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import numpy as np

NAME = "brackets"
DESCRIPTION = "AEB folders from real HDR: grouping and per-bracket merge error vs true radiance"
X = ("seconds", "grouping + merge seconds per folder")
Y = ("median_stop_err", "median |log2| error vs true radiance (stops)")
HIGHER_IS_BETTER = False
TABLE = ("frames", "step_ev", "grouped", "median_stop_err", "scale_free_stop_err",
         "p95_stop_err", "brightest_clipped", "darkest_median_level", "views", "seconds")
RESPONSES = ("ocio", "debevec")


def _sources(quick: bool) -> dict[str, list[np.ndarray]]:
    from ..evaluation.bracket_shoot import panorama_scenes, room_scenes
    from ..locate import shared_hdri_dir

    sources = {"room": room_scenes([0, 6, 9, 15, 21, 3, 12])}
    if not quick and (shared_hdri_dir() / "night.exr").exists():
        sources["panoramas"] = panorama_scenes(7)
    return sources


def _errors(pixels: np.ndarray, pos: Any, reference_ev: float) -> tuple[float, float, float]:
    truth = pos.expected(reference_ev).mean(axis=-1)
    seen = pos.seen()
    seen[:4], seen[-4:], seen[:, :4], seen[:, -4:] = False, False, False, False
    err = np.log2(np.maximum(pixels.mean(axis=-1), 1e-9) / np.maximum(truth, 1e-12))[seen]
    return (float(np.median(np.abs(err))), float(np.median(np.abs(err - np.median(err)))),
            float(np.percentile(np.abs(err), 95)))


def _frame_levels(pos: Any) -> tuple[float, float]:
    from ..imageio import read_image

    by_time = sorted(pos.frames, key=lambda f: f.true_time)
    bright = read_image(by_time[-1].path).pixels.max(axis=-1)
    dark = read_image(by_time[0].path).pixels.max(axis=-1)
    return float(np.mean(bright >= 0.99)), float(np.median(dark))


def run_shoot(scenes: list[np.ndarray], response: str, work: Path) -> list[dict[str, Any]]:
    """Shoot, merge through the converter, score each position (see the module doc)."""
    from ..chain import ChainRun
    from ..evaluation.bracket_shoot import aeb_shoot
    from ..imageio import read_image
    from ..kinds import Artifact, Kind
    from ..progress import Progress
    from ..registry import Settings

    shoot = aeb_shoot(scenes[:5], work / "photos", scenes[5:7])
    out = work / f"hdr-{response}"
    settings = Settings.resolved(working_space="lin_rec709")
    runner = ChainRun(out, settings, progress=Progress(quiet=True))
    runner.run([Artifact(Kind.LDR_VIEWS, shoot.folder)], [Kind.HDR_VIEWS],
               choose={"uplift": "uplift.bracket"}, outputs={Kind.HDR_VIEWS: out},
               options={"uplift": {"response": response}}, resume=False)
    record = runner.records[-1]
    exrs = {read_image(p).metadata.get("gaslight:bracket"): p for p in out.glob("*.exr")}
    rows = []
    for pos in shoot.positions:
        key = ",".join(p.name for p in pos.photos)
        clipped, dark = _frame_levels(pos)
        row: dict[str, Any] = {"case": pos.name, "frames": len(pos.frames),
                               "step_ev": round(float(np.diff(sorted(
                                   np.log2([f.true_time for f in pos.frames])))[0]), 2),
                               "grouped": int(key in exrs), "brightest_clipped": clipped,
                               "darkest_median_level": dark, "views": len(exrs),
                               "seconds": record.seconds}
        if key in exrs:
            img = read_image(exrs[key])
            med, free, p95 = _errors(img.pixels, pos, img.metadata["gaslight:reference_ev"])
            row |= {"median_stop_err": med, "scale_free_stop_err": free, "p95_stop_err": p95}
        else:
            row |= {"median_stop_err": np.nan, "scale_free_stop_err": np.nan,
                    "p95_stop_err": np.nan}
        rows.append(row)
    return rows


def run(options: dict[str, Any]) -> list[dict[str, Any]]:
    quick = bool(options.get("quick"))
    rows = []
    for source, scenes in _sources(quick).items():
        for response in RESPONSES[:1] if quick else RESPONSES:
            with tempfile.TemporaryDirectory(prefix="gaslight-brackets-") as tmp:
                for row in run_shoot(scenes, response, Path(tmp)):
                    rows.append({"method": f"bracket {response}", "setting": source, **row})
    return rows


def notes(options: dict[str, Any]) -> list[str]:
    return ["160x120 JPEGs (quality 95) with EXIF nominal shutter labels, f/8, ISO 100, "
            "capture times; brightest frame shifted (1.0, -1.5) px; photon + read noise"]
