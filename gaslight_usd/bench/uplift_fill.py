"""How far the uplift's fill of each light is off, view by view, before any fitting.

The chain bench's power errors are the whole chain's: the uplift's guess for a clipped
light, then what the fit and the lights' weighing make of it. This splits off the first
part. In each view, the pixels that show a light (inside its footprint, the true radiance
within a factor 2 of the light's own, and clipped in the photo) are averaged in the
uplift's HDR view and in the truth; the log2 ratio is that view's fill error for the
light. Per light the bench reports the median over the views (``fill_err_<light>``),
their spread, the largest minus the smallest (``fill_spread_<light>``), and how many
views showed it clipped (``fill_views_<light>``). A spread of a stop or more is a light
the views disagree on, which the fit does not average away (a uniformly bright region
fits at any depth, so each view keeps its own level: ``docs/measurements.md``,
session 27).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..cameras import PinholeCamera
from ..colour import REC709_Y
from ..imageio import read_channel, read_image
from ..poses import read_poses
from ..poses.views import CLIP_FLOOR_CHANNEL

SHOWN_SHARE = 0.5
"""A pixel shows a light where it lies in the light's footprint and its true luminance is
within this share of the light's either way (a brighter light in front, a lit wall
beside it, or a pixel half on its edge do not count)."""


def light_footprint(light: dict[str, Any], camera: PinholeCamera, shape: tuple[int, int]
                  ) -> np.ndarray:
    """``(H, W)`` bool: the pixels a ``sphere`` or ``rectangle`` light (``scene.json``)
    covers in ``camera``'s image of ``shape``, occlusion aside (none for another kind)."""
    if light["kind"] == "sphere":
        dirs = np.random.default_rng(0).normal(size=(2048, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        points = np.asarray(light["center"]) + light["radius"] * dirs
    elif light["kind"] == "rectangle":
        c = np.asarray(light["corners"], np.float64)
        u, v = np.meshgrid(np.linspace(0, 1, 64), np.linspace(0, 1, 64))
        points = (c[0] + u.reshape(-1, 1) * (c[1] - c[0])
                  + v.reshape(-1, 1) * (c[3] - c[0]))
    else:
        return np.zeros(shape, bool)
    h, w = shape
    uv, z = camera.project(points)
    x = np.floor(uv[:, 0] * w / camera.width).astype(np.int64)
    y = np.floor(uv[:, 1] * h / camera.height).astype(np.int64)
    ok = (z > 0) & (x >= 0) & (x < w) & (y >= 0) & (y < h)
    mask = np.zeros(shape, bool)
    mask[y[ok], x[ok]] = True
    return mask


def view_fill_errors(fill: np.ndarray, floor: np.ndarray, truth: np.ndarray,
                     levels: dict[str, float], footprints: dict[str, np.ndarray]
                     ) -> dict[str, float]:
    """One view: per light (``levels``: its true luminance; ``footprints``: its pixels), the
    log2 ratio of the fill's mean to the truth's over the clipped pixels that show it;
    lights it does not show clipped are left out. ``fill`` and ``truth`` are luminance
    ``(H, W)`` in the same units, ``floor`` the view's clip floor."""
    out = {}
    for name, level in levels.items():
        shown = (footprints[name] & (floor > 0) & (truth >= SHOWN_SHARE * level)
                 & (truth <= level / SHOWN_SHARE))
        if shown.any():
            out[name] = float(np.log2(max(fill[shown].mean(), 1e-12) / truth[shown].mean()))
    return out


def fill_errors(folder: Path, hdr: Path, lights: list[dict[str, Any]], scale: float
                ) -> dict[str, float]:
    """The chain bench's ``fill_err_``, ``fill_spread_`` and ``fill_views_`` columns per
    light (module docstring) for the uplift's HDR views in ``hdr`` of the scene in
    ``folder`` (its true poses in ``sparse/0``); ``scale`` turns the views' relative
    radiance into the truth's."""
    info = json.loads((folder / "scene.json").read_text())
    cameras = {cam.name: cam for cam in read_poses(folder / "sparse" / "0").cameras}
    y = np.asarray(REC709_Y)
    levels = {light["name"]: float(np.asarray(light["radiance"]) @ y) for light in lights}
    errors: dict[str, list[float]] = {name: [] for name in levels}
    for view in info["views"]:
        exr = hdr / f"{Path(view['name']).stem}.exr"
        floor = read_channel(exr, CLIP_FLOOR_CHANNEL) if exr.exists() else None
        if floor is None:
            continue
        fill = read_image(exr).pixels @ y * scale
        truth = read_image(folder / view["truth"]).pixels @ y
        camera = cameras.get(view["name"])
        if camera is None or fill.shape != truth.shape:
            continue
        footprints = {light["name"]: light_footprint(light, camera, truth.shape)
                      for light in lights}
        for name, err in view_fill_errors(fill, floor, truth, levels, footprints).items():
            errors[name].append(err)
    out: dict[str, float] = {}
    for name, errs in errors.items():
        out[f"fill_views_{name}"] = len(errs)
        out[f"fill_err_{name}"] = round(float(np.median(errs)), 3) if errs else float("nan")
        out[f"fill_spread_{name}"] = (round(float(np.ptp(errs)), 3) if errs
                                      else float("nan"))
    return out
