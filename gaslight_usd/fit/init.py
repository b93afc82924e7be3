"""Initial splats: from the HDR-coloured sparse points, or, when the poses carry
none, from a small plane sweep over the training views.

Plane sweep (points-free start): random pixels of random training views are
pushed along their rays to the candidate depth (geometric steps spanning 0.05x
to 20x the camera spread) where the other views agree best on the colour
(lowest spread of log colour among the views that see that point); the pixel's
HDR colour is the splat's colour. Pixels with no view to agree with go to a
random depth. Scales start at the mean distance to the 3 nearest neighbours.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..cameras import PinholeCamera
from ..poses import colour_points


def neighbour_scales(points: np.ndarray) -> np.ndarray:
    k = min(4, len(points))
    if k < 2:
        return np.full(len(points), 0.01)
    dist, _ = cKDTree(points).query(points, k=k)
    return np.clip(dist[:, 1:].mean(1), 1e-4, None)


def _sample(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    h, w = image.shape[:2]
    x = np.clip(uv[..., 0].astype(np.int64), 0, w - 1)
    y = np.clip(uv[..., 1].astype(np.int64), 0, h - 1)
    return image[y, x]


def plane_sweep_points(cameras: list[PinholeCamera], images: list[np.ndarray], count: int,
                       rng: np.random.Generator, depth_steps: int = 32
                       ) -> tuple[np.ndarray, np.ndarray]:
    """(count, 3) points and (count, 3) colours from photo-consistent depths."""
    centres = np.array([c.center for c in cameras])
    spread = max(float(np.linalg.norm(centres - centres.mean(0), axis=1).max()), 1e-2)
    depths = spread * np.geomspace(0.05, 20.0, depth_steps)
    src = rng.integers(0, len(cameras), count)
    pts = np.empty((count, 3))
    cols = np.empty((count, 3), np.float32)
    for v, cam in enumerate(cameras):
        idx = np.flatnonzero(src == v)
        if not len(idx):
            continue
        px = rng.uniform([0, 0], [cam.width, cam.height], (len(idx), 2))
        rays = np.stack([(px[:, 0] - cam.cx) / cam.fx, (px[:, 1] - cam.cy) / cam.fy,
                         np.ones(len(idx))], -1) @ cam.R
        cand = cam.center + rays[:, None, :] * depths[None, :, None]  # (n, D, 3)
        logs = []
        for o, other in enumerate(cameras):
            if o == v:
                continue
            uv, z = other.project(cand.reshape(-1, 3))
            inside = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < other.width) & \
                     (uv[:, 1] >= 0) & (uv[:, 1] < other.height)
            val = np.log(np.maximum(_sample(images[o], uv), 1e-4)).mean(-1)
            logs.append(np.where(inside, val, np.nan).reshape(len(idx), depth_steps))
        own = np.log(np.maximum(_sample(images[v], px), 1e-4)).mean(-1)[:, None]
        stack = np.stack(logs)  # (V-1, n, D)
        seen = np.isfinite(stack).sum(0)
        diff = np.where(seen[None] > 0, np.abs(stack - own[None]), 0.0)
        err = np.nansum(diff, axis=0) / np.maximum(seen, 1)
        err = np.where(seen >= 1, err + 0.5 / np.maximum(seen, 1), np.inf)
        best = np.argmin(err, axis=1)
        lost = ~np.isfinite(err[np.arange(len(idx)), best])
        best[lost] = rng.integers(0, depth_steps, int(lost.sum()))
        pts[idx] = cand[np.arange(len(idx)), best]
        cols[idx] = _sample(images[v], px)
    return pts, cols


def initial_points(model, cameras: list[PinholeCamera], images: list[np.ndarray],
                   names: list[str], count: int, rng: np.random.Generator
                   ) -> tuple[np.ndarray, np.ndarray, str]:
    """Points, HDR colours and how they were made ("sparse points" or "plane sweep")."""
    if len(model.points) >= 16:
        colours = colour_points(model, dict(zip(names, images, strict=True)))
        pts = np.asarray(model.points, np.float64)
        if len(pts) > count:
            pick = rng.choice(len(pts), count, replace=False)
            pts, colours = pts[pick], colours[pick]
        return pts, colours, "sparse points"
    pts, cols = plane_sweep_points(cameras, images, count, rng)
    return pts, cols, "plane sweep"
