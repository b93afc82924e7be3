"""Faint splats floating just in front of a camera, dropped after the fit.

A fit leaves faint splats in the open air a few decimetres from where photos were taken,
where the training views pin little down (so near a camera, each covers few pixels of
the others). A probe placed where a photo was taken (under a lamp, where the
photographer stood to shoot it) sees them from inside, and the lights through them
dimmed: from under a shaded lamp, a few centimetres from the photo aimed straight up at
it, the window read over half a stop short (``gaslight2usd bench --suite chain --scene
shade:7 --method "recursive + extra dark frames"``; ``docs/measurements.md``, session 67).

So after the fit the splats fainter than :data:`OPACITY`, no brighter than
:data:`DIM_RATIO` x the median splat, within :data:`NEAR_SHARE` of the scene's extent of
a camera and farther than :data:`.fog.FOG_CLEAR_SHARE` of it from every plane of the
room's box are dropped, unless the held-out views object (:data:`HELD_OUT_SLACK_STOPS`).
Something really there that near a camera is a surface (opaque), a light (bright) or the
room's own wall. Unlike fog (:mod:`.fog`), which is dropped midway so that the fit
refits the room without it, these go at the end: the photos hardly weigh them, and
dropping every faint open-air splat midway sent fits elsewhere (better in some rooms,
worse in others).
"""

from __future__ import annotations

import numpy as np

from ..splats import SplatScene
from .fog import FOG_CLEAR_SHARE, box_clearance
from .planes import Plane

OPACITY = 0.6
"""Splats at least this opaque near a camera are kept: a surface seen close up (a third
of the floaters that dimmed that window were over the fog's 0.3)."""
DIM_RATIO = 4.0
"""Splats brighter than this many times the median splat are kept: a light's glow."""
HELD_OUT_SLACK_STOPS = 0.02
"""The drop is refused where the held-out views read more than this much worse without
the splats (log-luminance RMSE, stops): then they were something those photos saw (one
run of the bundled example's fit needed its few by over half a stop; the shaded rooms'
floaters cost a hundredth or less; ``docs/measurements.md``, session 67)."""
NEAR_SHARE = 0.25
"""How near a camera (share of the scene's extent, about 0.4 m in the chain bench's
rooms) a faint splat is the camera's floater."""


def camera_floaters(scene: SplatScene, centres: np.ndarray, planes: list[Plane],
                    extent: float, y_weights: np.ndarray, fitted: int | None = None
                    ) -> np.ndarray:
    """(N,) the splats of ``scene`` that float faint in front of a camera (module
    docstring); ``centres`` (C, 3) the cameras' centres, ``planes`` the room's box,
    ``extent`` the scene's size, ``fitted`` how many leading splats are the fit's (the
    rest, a backdrop, are never taken). None are without a box or cameras."""
    out = np.zeros(scene.count, bool)
    centres = np.asarray(centres, np.float64).reshape(-1, 3)
    fitted = scene.count if fitted is None else fitted
    if not planes or not len(centres) or fitted <= 0:
        return out
    points = scene.positions[:fitted].astype(np.float64)
    clearance = box_clearance(points, planes)
    gap = np.full(fitted, np.inf)
    for centre in centres:  # one pass per camera: no (N, C, 3) array
        gap = np.minimum(gap, np.linalg.norm(points - centre, axis=1))
    level = scene.base_colours[:fitted].astype(np.float64) @ np.asarray(y_weights, np.float64)
    out[:fitted] = ((scene.opacities[:fitted] < OPACITY)
                    & (level <= DIM_RATIO * float(np.median(level)))
                    & (gap < NEAR_SHARE * extent)
                    & (clearance > FOG_CLEAR_SHARE * extent))
    return out
