"""Photos whose EXIF exposure is wrong: the same surface points read brighter or darker
in them than in the other photos that see them.

The HDR views are in one radiance scale only if each photo's exposure is what its
EXIF says. Exposure compensation on a camera that does not record it, an ND filter, or
a wrong tag breaks that silently, and a fit then bends the splats to each view (it can:
each view sees its own side of a surface), so the fit's own errors do not show it.
The sparse points do: a point seen by several views is one surface, so in each view
its pixel's luminance, over the median of the views that see it, is that view's error.
The median of that ratio over a view's points is its offset in stops; a view more than
:data:`OUTLIER_STOPS` off is named. Clipped and black pixels say nothing and are left
out. Measured by ``gaslight2usd bench --suite stability --perturb exposure``.
"""

from __future__ import annotations

import numpy as np

from ..cameras import PinholeCamera
from .init import seen_by

OUTLIER_STOPS = 0.5
"""A view this many stops off the others on the same points is named."""
MIN_POINTS = 12
"""Fewest shared points a view needs for its offset to count."""


def view_offsets(points: np.ndarray, seen: np.ndarray | None, cameras: list[PinholeCamera],
                 images: list[np.ndarray], floors: list[np.ndarray | None],
                 weights: np.ndarray) -> np.ndarray:
    """(V,) each view's median log2 luminance ratio against the other views on the points
    it shares with them (NaN: too few). ``seen`` (V, N): which views' tracks hold each
    point (None: every view that has it in frame)."""
    n_views = len(cameras)
    logs = np.full((n_views, len(points)), np.nan)
    for v, (cam, image, floor) in enumerate(zip(cameras, images, floors, strict=True)):
        uv, z = cam.project(points)
        h, w = image.shape[:2]
        ok = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & (uv[:, 1] >= 0) & \
             (uv[:, 1] < cam.height)
        if seen is not None:
            ok &= seen[v]
        x = np.clip((uv[:, 0] * w / cam.width).astype(np.int64), 0, w - 1)
        y = np.clip((uv[:, 1] * h / cam.height).astype(np.int64), 0, h - 1)
        lum = image[y, x] @ weights
        if floor is not None:
            ok &= floor[y, x] <= 0
        ok &= lum > 0
        logs[v, ok] = np.log2(lum[ok])
    shared = np.isfinite(logs).sum(0) >= 3
    logs = logs[:, shared]
    offsets = np.full(n_views, np.nan)
    if not logs.size:
        return offsets
    centre = np.nanmedian(logs, axis=0)
    for v in range(n_views):
        d = logs[v] - centre
        d = d[np.isfinite(d)]
        if len(d) >= MIN_POINTS:
            offsets[v] = float(np.median(d))
    return offsets


def exposure_outliers(model, cameras: list[PinholeCamera], images: list[np.ndarray],
                      names: list[str], floors: list[np.ndarray | None],
                      weights: np.ndarray) -> list[dict[str, float | str]]:
    """Views more than :data:`OUTLIER_STOPS` off the others (name and stops, brighter
    positive), from ``model``'s sparse points; none without points."""
    points = np.asarray(model.points, np.float64).reshape(-1, 3)
    if len(points) < MIN_POINTS or len(cameras) < 3:
        return []
    offsets = view_offsets(points, seen_by(model, names), cameras, images, floors, weights)
    return [{"view": names[v], "stops": round(float(o), 2)} for v, o in enumerate(offsets)
            if np.isfinite(o) and abs(o) > OUTLIER_STOPS]
