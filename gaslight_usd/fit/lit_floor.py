"""A floor the sparse points miss, found where the views' lit patch on it agrees.

A plain floor has no features, and furniture hides its edges from the walls' points, so
the sparse points often hold none of it (the chain bench's ``sun`` room: its lowest
point 0.23 m up) and the fit's start fills floor pixels from the walls' planes carried
down: a sunlit patch on the floor, the room's brightest surface, started 1 m over to
1.5 m under the floor, and the fit drew it there. Yet every view that measured the
patch outlines it sharply (many times the room's median): on a horizontal plane at the
floor's height the views' outlines of it coincide, and above or below it they slide
apart. So horizontal planes below the cameras and the points are swept, each scored by
how much the views' lit cells on it disagree (cells some views saw lit and others,
framing them too, saw dark), and the floor is where they disagree least, when that is
well under the sweep's typical disagreement
(:data:`MAX_DISAGREEMENT`, :data:`DIP`). A room with no lit patch on its floor has
none: nothing agrees anywhere under the cameras.

Photos' clipped outlines mostly disagree at every height (each holds whatever passed
that photo's white, more of it the longer the exposure), so from photos a floor is seldom
found: it is found from views that measured the patch (true HDR views, merged brackets),
and from two darker frames aimed at it from two places, swept alone
(:func:`views_lit_floor`; one frame pins no depth).

The fit's start puts the patch and the floor round it on it
(:func:`gaslight_usd.fit.init.surface_fill_points`: a pixel takes the depth the patch's
cells and the sparse points give where the views agree on its colour better there, the
patch's own pixels go onto it, nothing is filled under it), its splats there start as
discs lying on it (:func:`floor_discs`), and the room's box bounds with it
(:mod:`.sunk_lights`, the outlines). Measured by ``gaslight2usd bench --suite chain``
(``sun`` rooms: the probes in the middle and over the patch; figures in
``docs/measurements.md``, session 52).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..cameras import PinholeCamera
from ..flat_outlines import LIT_SHARE, MIN_CELLS, MIN_VIEWS, lit_masks, look_up
from .init import depth_rays
from .planes import INLIER_SHARE, OWN_TILT, UP_TILT, Plane, main_axes

SWEEP_SHARE = 1.5
"""Heights are swept from the lowest camera down this many times the sparse points'
vertical spread (their 2-98 % range)..."""
ABOVE_POINTS = 0.03
"""...up to the points' lowest 2 % plus this share of that spread: a floor holds no
point under it (a desk's lit top, with the floor's points below it, is no floor)."""
COARSE_STEPS = 48
"""Heights tried on the coarse pass; then the best is refined :data:`FINE_STEPS` each way
at a tenth of the step."""
FINE_STEPS = 10
CELL_SHARE = 0.01
"""A cell's side on the swept planes, as a share of the points' vertical spread (the
fine pass halves it)."""
MAX_DISAGREEMENT = 0.35
"""A floor's views disagree on at most this share of their lit votes... (``sun:5``'s
true HDR views: 0.25 at the floor, 0.5-1.0 a metre off it)"""
DIP = 0.6
"""...and on at most this share of the sweep's median disagreement."""


@dataclass
class LitFloor:
    """The floor under the cameras where the views' lit patch lies."""

    normal: np.ndarray
    """(3,) unit, up (towards the cameras)."""
    offset: float
    """normal . x of the floor's points."""
    points: np.ndarray
    """(K, 3) the centres of the cells the views agree are lit on it (the patch)."""
    seen: np.ndarray
    """(V, K) bool: which views saw each of them lit."""
    disagreement: float
    """The share of the views' lit votes on it that other views framing the cell contradict."""
    cell: float
    """The side of the cells ``points`` are the centres of."""

    def lit_at(self, view: int, points: np.ndarray) -> np.ndarray:
        """(n,) whether each of ``points`` (n, 3), on the floor, lies in a cell ``view``
        saw lit."""
        if not len(self.points) or not len(points):
            return np.zeros(len(points), bool)
        dist, near = cKDTree(self.points).query(points)
        return (dist <= self.cell) & self.seen[view][near]

    def as_dict(self) -> dict:
        return {"normal": [round(float(x), 5) for x in self.normal],
                "offset": round(float(self.offset), 5), "cells": int(len(self.points)),
                "disagreement": round(float(self.disagreement), 4)}


def _in_plane_axes(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    other = np.eye(3)[int(np.argmin(np.abs(normal)))]
    u = other - (other @ normal) * normal
    u /= np.linalg.norm(u)
    return u, np.cross(normal, u)


def room_vertical(points: np.ndarray, up: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The room's vertical: of the main directions of the points' planes
    (:func:`.planes.main_axes`), the one nearest ``up`` (the cameras' mean up, which
    leans with the way they look: 1.8 deg on ``sun:5``, 3 cm a metre) where it
    is within :data:`.planes.UP_TILT` of it, else ``up``."""
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    if len(points) < MIN_CELLS:
        return up
    lo, hi = np.percentile(points, [2, 98], axis=0)
    axes = main_axes(points, INLIER_SHARE * float(np.linalg.norm(hi - lo)), rng)
    if not len(axes):
        return up
    best = axes[int(np.argmax(np.abs(axes @ up)))]
    best = best * np.sign(best @ up)
    return best if best @ up >= UP_TILT else up


def _lit_rays(cameras: Sequence[PinholeCamera], lit: Sequence[np.ndarray | None]
              ) -> list[np.ndarray]:
    """Per view, the world directions (n, 3) through the centres of its lit pixels."""
    out = []
    for cam, mask in zip(cameras, lit, strict=True):
        if mask is None:
            out.append(np.zeros((0, 3)))
            continue
        y, x = np.nonzero(mask)
        px = np.stack([(x + 0.5) * cam.width / mask.shape[1],
                       (y + 0.5) * cam.height / mask.shape[0]], axis=1)
        out.append(depth_rays(cam, px))
    return out


def disagreement(height: float, normal: np.ndarray, cell: float,
                 cameras: Sequence[PinholeCamera], lit: Sequence[np.ndarray | None],
                 rays: Sequence[np.ndarray]) -> tuple[float, np.ndarray, np.ndarray]:
    """(the share of lit votes contradicted, the lit cells' centres (K, 3), which views saw
    each lit (V, K)) on the plane at ``height``, cut in cells of side ``cell``: the cells
    some view's lit pixels (``rays``, :func:`_lit_rays`) land in, each looked up in the
    views that frame it; a lit vote is contradicted where fewer of those views saw the
    cell lit than dark (``min(seen, framed - seen) / seen`` over the cells
    :data:`MIN_VIEWS` views frame); inf where they cast fewer than :data:`MIN_CELLS`."""
    u, v = _in_plane_axes(normal)
    hits = []
    for cam, dirs in zip(cameras, rays, strict=True):
        down = dirs @ normal
        t = (height - cam.center @ normal) / np.where(down < 0, down, -np.inf)
        at = cam.center + dirs[t > 0] * t[t > 0, None]
        hits.append(np.floor(np.stack([at @ u, at @ v], 1) / cell).astype(np.int64))
    cells = np.unique(np.concatenate(hits), axis=0) if hits else np.zeros((0, 2), np.int64)
    centres = height * normal + (cells[:, :1] + 0.5) * cell * u + (cells[:, 1:] + 0.5) * cell * v
    framed = np.zeros(len(centres), np.int32)
    seen = np.zeros((len(cameras), len(centres)), bool)
    for k, (cam, mask) in enumerate(zip(cameras, lit, strict=True)):
        if mask is not None and cam.center @ normal > height:
            inside, seen[k] = look_up(cam, mask, centres)
            framed += inside
    lit_votes = seen.sum(0)
    judged = framed >= MIN_VIEWS
    votes = int(lit_votes[judged].sum())
    if votes < MIN_CELLS:
        return float("inf"), centres, seen
    contradicted = np.minimum(lit_votes, framed - lit_votes)[judged].sum()
    good = judged & (lit_votes >= LIT_SHARE * np.maximum(framed, 1))
    return float(contradicted / votes), centres[good], seen[:, good]


def find_lit_floor(cameras: Sequence[PinholeCamera], lit: Sequence[np.ndarray | None],
                   up: np.ndarray, points: np.ndarray) -> LitFloor | None:
    """The floor under ``cameras`` where their ``lit`` masks (:func:`gaslight_usd.
    flat_outlines.lit_masks`; None: the view does not count) agree (module docstring),
    ``up`` the room's vertical (:func:`room_vertical`), ``points`` (N, 3) the sparse
    points; None where no lit patch pins one."""
    up = np.asarray(up, np.float64)
    norm = float(np.linalg.norm(up))
    points = np.asarray(points, np.float64).reshape(-1, 3)
    if norm == 0 or len(points) < MIN_CELLS or len(cameras) < MIN_VIEWS:
        return None
    up = up / norm
    centres = np.array([c.center for c in cameras], np.float64)
    low, high = np.percentile(points @ up, [2, 98])
    spread = float(high - low)
    lowest_camera = float((centres @ up).min())
    top = min(low + ABOVE_POINTS * spread, lowest_camera - ABOVE_POINTS * spread)
    bottom = lowest_camera - SWEEP_SHARE * spread
    if spread <= 0 or top <= bottom:
        return None
    rays = _lit_rays(cameras, lit)
    coarse = np.linspace(bottom, top, COARSE_STEPS)
    scores = np.array([disagreement(h, up, CELL_SHARE * spread, cameras, lit, rays)[0]
                       for h in coarse])
    finite = np.isfinite(scores)
    if finite.sum() < 3:
        return None
    best = int(np.argmin(np.where(finite, scores, np.inf)))
    fine = coarse[best] + (np.arange(-FINE_STEPS, FINE_STEPS + 1) / FINE_STEPS
                           * (coarse[1] - coarse[0]))
    fine = fine[fine <= top]
    refined = [disagreement(h, up, CELL_SHARE * spread / 2, cameras, lit, rays) for h in fine]
    pick = int(np.argmin([r[0] for r in refined]))
    score, cells, seen = refined[pick]
    if not (score <= MAX_DISAGREEMENT and score <= DIP * float(np.median(scores[finite]))
            and len(cells) >= MIN_CELLS):
        return None
    return LitFloor(normal=up, offset=float(fine[pick]), points=cells, seen=seen,
                    disagreement=score, cell=CELL_SHARE * spread / 2)


def views_lit_floor(cameras: Sequence[PinholeCamera], images: Sequence[np.ndarray],
                    floors: Sequence[np.ndarray | None], measuring: Sequence[bool],
                    weights: np.ndarray, up: np.ndarray, points: np.ndarray
                    ) -> LitFloor | None:
    """:func:`find_lit_floor` from the views (``images`` (H, W, 3) linear, their clip
    ``floors``, None where nothing clipped): first from those ``measuring`` light over the
    photos' white alone (darker frames: the light is what stands over each one's median,
    its few clipped pixels included), where :data:`MIN_VIEWS` of them do, then from every
    view's lit outlines (:func:`gaslight_usd.flat_outlines.lit_masks`). From the README's
    capture the photos' clipped outlines of a sunlit patch hold the floor round it that
    passed each one's white and disagree at every height (``sun:5``: 0.64 at the floor,
    0.64-0.78 within 0.6 m of it: no floor), and the fit drew the patch smeared from 0.7 m
    under the floor to 0.45 m over it; two frames aimed at it from two places agree at
    the floor (0.16, found 2 cm under it) (``docs/measurements.md``, session 57)."""
    if sum(bool(m) for m in measuring) >= MIN_VIEWS:
        masks = [lit_masks([image], [None], weights)[0] if m else None
                 for image, m in zip(images, measuring, strict=True)]
        found = find_lit_floor(cameras, masks, up, points)
        if found is not None:
            return found
    return find_lit_floor(cameras, lit_masks(images, floors, weights), up, points)


def floor_plane(floor: LitFloor | None, box: Sequence[Plane], points: np.ndarray
                ) -> Plane | None:
    """``floor`` as a plane of the room's box (:func:`.planes.room_box`) where the box has
    no floor, its patch the ``points``' (N, 3) spread over it (2-98 %)."""
    if floor is None or any(p.normal @ floor.normal > 1 - OWN_TILT ** 2 / 2 for p in box):
        return None
    axes = np.stack(_in_plane_axes(floor.normal))
    uv = np.asarray(points, np.float64).reshape(-1, 3) @ axes.T
    if not len(uv):
        return None
    lo, hi = np.percentile(uv, 2, axis=0), np.percentile(uv, 98, axis=0)
    return Plane(floor.normal.copy(), floor.offset, lo, hi, axes, len(floor.points))


FLAT = 0.1
"""The start's splats on a lit floor are discs this thin across it (their side's share)."""


def floor_discs(points: np.ndarray, floor: LitFloor | None, tolerance: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """(indices of the ``points`` (N, 3) within ``tolerance`` of ``floor``, the unit
    quaternion w x y z that turns a splat's z axis to the floor's normal): the start's
    splats there are made discs lying on it (the trainer shrinks that axis by
    :data:`FLAT`). Round, a lit patch's splats (opacity about 0.25 each) covered it less
    from straight above than from the photos' slant, and the patch read 0.14-0.43 stops
    short from the room's middle; a flatter fit everywhere cost 2 dB (``docs/
    measurements.md``, session 52)."""
    if floor is None or not len(points):
        return np.zeros(0, np.int64), np.array([1.0, 0.0, 0.0, 0.0])
    normal = np.asarray(floor.normal, np.float64)
    on = np.flatnonzero(np.abs(np.asarray(points) @ normal - floor.offset) <= tolerance)
    if normal[2] < -1 + 1e-9:  # z turned to -z: half a turn about x
        return on, np.array([0.0, 1.0, 0.0, 0.0])
    quat = np.concatenate([[1.0 + normal[2]], np.cross([0.0, 0.0, 1.0], normal)])
    return on, quat / np.linalg.norm(quat)
