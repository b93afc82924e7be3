"""Narrow pinhole views all round a point, and which of them draw each direction.

A panorama or cube map is drawn through ordinary pinhole views, then resampled. Splats
are drawn with a linearised (EWA) projection and sorted by depth along the view's axis;
both are exact only near that axis. Far off it the linearisation is badly wrong for a
large splat close to the probe: a bright splat 60 degrees off a 90 degree view's axis has
its footprint stretched back towards the centre of the frame, where it paints over
whatever is there. Beside a window (0.5 m in front of it) the wall round the window came
out twice as bright as a narrow view aimed at the same wall showed it, and the window's
power at the probe was too high by more than the fit's own error.

So every view here is narrow: :data:`VIEW_COUNT` views whose axes are spread evenly over
the sphere (a golden-angle spiral), each :data:`FRAME_DEG` from its axis to its frame's
edge. A splat far outside a view's frame is culled by it, and the pixels a view feeds
are all within :data:`BLEND_DEG` of its axis; every direction is blended from the views
within that angle, weighted by ``(cos angle - cos BLEND_DEG)^2`` (no hard seams). The
spiral leaves no direction farther than about 11.3 degrees from its nearest axis, so
every direction has a view.

Measured against Mitsuba's ray-marched ellipsoids by ``tests/consumers/mitsuba_numbers.py``
and on the chain bench's probes (``gaslight2usd bench --suite chain``); figures in
``docs/measurements.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..cameras import PinholeCamera

VIEW_COUNT = 192
"""Views round the point. More and narrower views follow the splats' true (non-linear)
projection more closely and cost a projection of the scene each."""

BLEND_DEG = 12.5
"""A direction is drawn by the views whose axes lie within this angle of it."""

FRAME_DEG = BLEND_DEG + 1.0
"""Axis to frame edge of each view: the blend's directions and a bilinear margin."""


def view_axes(count: int = VIEW_COUNT) -> np.ndarray:
    """``(count, 3)`` unit vectors spread evenly over the sphere (a golden-angle spiral)."""
    i = np.arange(count) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / count)
    azimuth = math.pi * (1.0 + math.sqrt(5.0)) * i
    return np.stack([np.cos(azimuth) * np.sin(polar), np.cos(polar),
                     np.sin(azimuth) * np.sin(polar)], axis=1)


def view_basis(forward: np.ndarray) -> np.ndarray:
    """(3, 3) rows image right, image down, forward for a view along ``forward``."""
    forward = np.asarray(forward, np.float64)
    up = np.array([0.0, 1.0, 0.0]) if abs(forward[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(up, forward)
    right /= np.linalg.norm(right)
    return np.stack([right, np.cross(forward, right), forward])


def sphere_views(pixel_angle: float, count: int = VIEW_COUNT,
                 frame_deg: float = FRAME_DEG) -> list[PinholeCamera]:
    """Square views at the origin whose centre pixels span ``pixel_angle`` radians."""
    half = math.tan(math.radians(frame_deg))
    f = 1.0 / math.tan(pixel_angle)
    size = int(math.ceil(2.0 * half * f)) + 2
    return [PinholeCamera(size, size, f, f, size / 2.0, size / 2.0, view_basis(axis),
                          np.zeros(3), name=f"view{k}")
            for k, axis in enumerate(view_axes(count))]


@dataclass(frozen=True)
class Feed:
    """The directions one view draws: their indices, continuous pixel coordinates in the
    view and blend weights (``(n, 1)``, summing to 1 over the views of a direction)."""

    index: np.ndarray
    x: np.ndarray
    y: np.ndarray
    weight: np.ndarray


def feeds(views: list[PinholeCamera], directions: np.ndarray,
          blend_deg: float = BLEND_DEG) -> list[Feed]:
    """Per view, the directions ``(n, 3)`` (unit, the views' frame) it draws."""
    dirs = np.asarray(directions, np.float64).reshape(-1, 3)
    limit = math.cos(math.radians(blend_deg))
    raw, total = [], np.zeros(len(dirs))
    for view in views:
        R = np.asarray(view.R, np.float64)
        # the directions near the view's axis first: only those are projected
        idx = np.flatnonzero(dirs @ R[2] > limit)
        local = dirs[idx] @ R.T
        z = local[:, 2]
        x = view.fx * local[:, 0] / z + view.cx
        y = view.fy * local[:, 1] / z + view.cy
        w = (z - limit) ** 2
        total[idx] += w
        raw.append((idx, np.clip(x, 0.5, view.width - 0.5),
                    np.clip(y, 0.5, view.height - 0.5), w))
    if len(dirs) and total.min() <= 0.0:
        raise ValueError(f"{len(views)} views within {blend_deg} degrees leave directions "
                         "undrawn")
    return [Feed(idx, x, y, (w / total[idx]).astype(np.float32)[:, None])
            for idx, x, y, w in raw]
