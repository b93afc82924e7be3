"""Fog: large, faint splats in the room's open air, dropped midway through the fit.

A fit of a clipped set leaves broad translucent splats floating between the room's
surfaces (opacity 0.17-0.22, 11-23 cm wide, as dim as the walls): each training view
sees through them to a wall and they shade it a little, which the rest of the fit makes
up for. A probe among them sees them from inside, and one whose line to a light crosses
them sees the light dimmed: ``bulb:11`` s1's bulb read 0.67 stops short from the probe
by its window, -0.02 without the three on that line. So at the end of the densify window
the splats fainter than :data:`FOG_OPACITY`, wider than :data:`FOG_WIDTH_SHARE` of the
scene's extent and farther than :data:`FOG_CLEAR_SHARE` of it from every plane of the
room's box (:func:`gaslight_usd.fit.planes.room_box`) are dropped, and the fit's
remaining steps refit the room without them (dropped after the fit instead, the views'
light they carried went with them: 3-7 dB lost at some probes). Measured by ``gaslight2usd
bench --suite chain --method "recursive + extra dark frames"`` (``docs/measurements.md``,
session 62).
"""

from __future__ import annotations

import numpy as np

from ..splats import SplatScene
from .planes import Plane

FOG_OPACITY = 0.3
"""Splats at least this opaque are surfaces, or lights, whatever their place."""
FOG_WIDTH_SHARE = 0.05
"""...narrower than this share of the scene's extent (8 cm in the chain bench's rooms) are
detail: a lamp's cord, a chair's edge..."""
FOG_CLEAR_SHARE = 0.18
"""...and nearer than this share of it (0.3 m there) to a plane of the room's box are
the walls' and the ceiling's own."""


def box_clearance(points: np.ndarray, planes: list[Plane]) -> np.ndarray:
    """(N,) each point's distance to the nearest of ``planes`` (unbounded, either side)."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    return np.min(np.abs(points @ np.array([p.normal for p in planes], np.float64).T
                         - np.array([p.offset for p in planes], np.float64)), axis=1)


def fog_splats(scene: SplatScene, planes: list[Plane], extent: float) -> np.ndarray:
    """(N,) the splats of ``scene`` that are fog (module docstring), ``planes`` the room's
    box and ``extent`` the scene's size (the cameras' spread); none without a box."""
    if not planes or scene.count == 0:
        return np.zeros(scene.count, bool)
    clearance = box_clearance(scene.positions, planes)
    return ((scene.opacities < FOG_OPACITY)
            & (scene.scales.max(axis=1) > FOG_WIDTH_SHARE * extent)
            & (clearance > FOG_CLEAR_SHARE * extent))
