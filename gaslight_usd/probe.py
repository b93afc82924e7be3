"""The default probe point: inside the captured space, where the cameras stood.

The centre of the splats' bounds is dragged away by far backdrop splats (on the
example it lay behind the window wall, on an unseen room 4.3 m outside it), so
an HDRI rendered there is lit from outside the set. The default is instead the
cameras' median point (their median height included: a probe at eye level, as
the photos were taken), moved to free space when splats crowd it: the nearest
point of a small grid around it, inside the captured space, whose distance to
every opaque splat's 2-sigma footprint is at least :data:`CLEARANCE_SHARE` of
the captured space's median depth (or, if none is that clear, the clearest).
Without recorded camera centres (a PLY from another tool) the start is the
opaque splats' per-axis median.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .capture import OPAQUE, CaptureSpace, camera_centres, capture_space
from .splats import SplatScene
from .surroundings import splat_sigma

CLEARANCE_SHARE = 0.1
"""Free distance wanted around the probe, as a share of the median depth (25 cm in a
5 x 4 m room)."""
SEARCH_SHARE = 0.4
"""The probe may move at most this share of the median depth."""
GRID = 9
"""Candidate points per axis of the search grid."""
NEIGHBOURS = 16


@dataclass
class ProbeChoice:
    position: np.ndarray
    how: str
    clearance: float
    moved: float

    def as_dict(self) -> dict:
        return {"position": [round(float(v), 6) for v in self.position], "how": self.how,
                "clearance": round(self.clearance, 6), "moved": round(self.moved, 6)}


def clearance(scene: SplatScene, points: np.ndarray) -> np.ndarray:
    """(M,) distance from each point to the nearest opaque splat's 2-sigma footprint."""
    opaque = scene.opacities > OPAQUE
    points = np.asarray(points, np.float64).reshape(-1, 3)
    if opaque.sum() == 0:
        return np.full(len(points), np.inf)
    pos = scene.positions[opaque].astype(np.float64)
    reach = 2.0 * splat_sigma(scene)[opaque]
    k = min(NEIGHBOURS, len(pos))
    dist, idx = cKDTree(pos).query(points, k=k)
    dist, idx = dist.reshape(len(points), k), idx.reshape(len(points), k)
    return np.maximum((dist - reach[idx]).min(axis=1), 0.0)


def default_probe(scene: SplatScene, space: CaptureSpace | None = None) -> ProbeChoice:
    """The default probe point of ``scene`` and how it was chosen (module docstring)."""
    space = space or capture_space(scene)
    cams = camera_centres(scene.metadata)
    if cams is not None:
        start = np.median(cams, axis=0)
        how = (f"median of {len(cams)} camera centres (height {start[1]:.3g}, the cameras' "
               "median)")
    else:
        opaque = scene.opacities > OPAQUE
        pos = scene.positions[opaque] if opaque.any() else scene.positions
        start = np.median(pos, axis=0).astype(np.float64) if len(pos) else np.zeros(3)
        how = "per-axis median of the opaque splats (no camera centres recorded)"
    depth = space.median_depth()
    if not np.isfinite(depth) or depth <= 0:
        return ProbeChoice(start, how, float(clearance(scene, start[None])[0]), 0.0)
    want = CLEARANCE_SHARE * depth
    here = float(clearance(scene, start[None])[0])
    if here >= want:
        return ProbeChoice(start, how + "; free space around it", here, 0.0)
    steps = np.linspace(-SEARCH_SHARE * depth, SEARCH_SHARE * depth, GRID)
    grid = np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), -1).reshape(-1, 3) + start
    grid = grid[space.inside(grid)]
    if len(grid) == 0:
        return ProbeChoice(start, how + "; no free space found near it", here, 0.0)
    free = clearance(scene, grid)
    moved = np.linalg.norm(grid - start, axis=1)
    ok = free >= want
    pick = int(np.argmin(np.where(ok, moved, np.inf))) if ok.any() else int(np.argmax(free))
    return ProbeChoice(grid[pick], how + f"; moved {moved[pick]:.3g} to free space "
                       f"(clearance {free[pick]:.3g}, wanted {want:.3g})",
                       float(free[pick]), float(moved[pick]))
