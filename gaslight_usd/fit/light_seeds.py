"""Initial splats on the compact lights the photos clipped, placed by their outlines.

A bare bulb clipped in every photo has no features for SfM to triangulate, and the
uplift fills it only a few times the white (not the thousands of times the walls it
is), so :func:`gaslight_usd.fit.init.bright_points`' brightness test passes it by and
no initial splat sits on it. The fit moves and splits the splats it has; it does not
make one where none is near, so the light vanishes (the chain bench's bulb room at
``fast``: nearest splat 0.35 m from the bulb).

Its clipped outline is still there in every photo that frames it: a small whole region
over that photo's white, a cone from the camera (:mod:`gaslight_usd.sightings`, each
view over its own white). Two such cones from views at least
:data:`gaslight_usd.sightings.MIN_BASELINE_DEG` apart whose centroid rays meet inside
both cones give a candidate point; a candidate stands when at least :data:`MIN_VIEWS`
views, and :data:`MIN_SUPPORT_SHARE` of the views that frame it (a view where it lies
in a cut or broad region says nothing, nor one whose photo clipped it there but whose
outline missed it: :func:`clipped_at`), hold it: a bulb is seen wherever it is framed,
bar an occluder; two specks of noise meet by chance and no third view agrees. Stood
candidates are taken most-agreed first (share, then views), each placed where its
holding views' rays meet (least squares), and the others within :data:`MERGE_SIZES`
sizes of it dropped, as is one that a view framing it holds no outline of while it holds
a taken light right beside it (:func:`_seen_elsewhere`). The fit starts
:data:`POINTS_PER_LIGHT` points in a ball of the outline's size on each light its other
initial points leave bare (:func:`seed_points`, :meth:`LightSeedPoints.missing_from`),
and records the lights in the splats' metadata
(``light_seeds``): one clipped in every view that frames it is a light to
:func:`gaslight_usd.lights.search_lights`. ``gaslight2usd bench --suite chain --scene
bulb`` measures what it buys.

Broad lights (outlines wider than :data:`MAX_CONE_DEG`: windows, big panels) are left
to the surface fill, which puts them on their walls.

Views that clipped nothing (merged brackets, true HDR) have no white; there the outlines
are read over :data:`MEASURED_LIGHT_RATIO` x the views' median level
(:func:`measured_light_seeds`). Those lights add no initial points (nothing clipped, the
brightness test's sweep starts them); they keep the plane prior's floater rule off a light
in front of a wall and are drawn fine at the end (``Trainer._measured_lights``,
:mod:`.fine_power`), and are not recorded as clipped lights.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from ..cameras import PinholeCamera
from ..sightings import MIN_BASELINE_DEG, PeakMap, Sightings, sight_lights
from .frame_edge import meeting_points

MAX_CONE_DEG = 6.0
"""Outlines this wide (half-angle) or narrower are compact lights (the chain bench's
bulb 1.0-1.4 deg, its shaded lamp 3.8-5.7, its ceiling panels 4.4-5.7; windows 6.5-14)."""
MIN_SUPPORT_SHARE = 2.0 / 3.0
"""Share of the views framing a candidate whose outlines must hold it."""
MIN_VIEWS = 3
"""Views whose outlines hold a seeded light, at least."""
MERGE_SIZES = 3.0
"""Candidates within this many of a taken light's sizes are that light."""
POINTS_PER_LIGHT = 12
"""Initial points per seeded light."""
MEASURED_LIGHT_RATIO = 64.0
"""Where no view clipped (merged brackets, true HDR views), a compact region this many
times the views' median luminance is a measured light (:func:`measured_light_seeds`):
the chain bench's bare bulb is about 50,000 times it; at 64 its rooms' true HDR views
give the bulb, one of two ceiling panels, the example's lamp, and the shaded lamp's
opening with a speck above it (docs/measurements.md, session 33)."""
CLIPPED_AT_WHITE = 0.95
"""A view whose photo clipped a place and whose peaks there reach this share of its white
counts neither for nor against a light there (:func:`clipped_at`)."""
FRAME_MARGIN = 0.02
"""A point counts as framed when it projects this share of the width inside the frame
(a light on the border is cut, and its outline is not whole)."""


@dataclass
class LightSeed:
    """A compact light found from its outlines."""

    position: np.ndarray
    """(3,) where the holding views' centroid rays meet."""
    size: float
    """Radius of the cones at the light, median over the holding views."""
    views: list[int]
    """The views whose outlines hold it."""
    framed: int
    """Views that frame it and hold it, or frame it and see no light there."""

    @property
    def share(self) -> float:
        """Share of the views that frame it whose outlines hold it (1: clipped
        wherever it is seen, as a bulb is; a clipped hot spot on a wall is measured
        under the white by a darker view)."""
        return len(self.views) / max(self.framed, 1)

    def as_dict(self) -> dict[str, Any]:
        return {"position": [round(float(v), 6) for v in self.position],
                "size": round(self.size, 6), "views": self.views, "framed": self.framed}


def framing(points: np.ndarray, cameras: list[PinholeCamera],
            margin: float = FRAME_MARGIN) -> np.ndarray:
    """(N, V) bool: each camera frames each point (in front, ``margin`` of the width
    inside the frame)."""
    out = np.zeros((len(points), len(cameras)), bool)
    for v, cam in enumerate(cameras):
        uv, z = cam.project(points)
        m = margin * cam.width
        out[:, v] = (z > 0) & (uv[:, 0] >= m) & (uv[:, 0] < cam.width - m) & \
            (uv[:, 1] >= m) & (uv[:, 1] < cam.height - m)
    return out


def _counted_framing(sightings: Sightings, compact: np.ndarray, points: np.ndarray,
                     cameras: list[PinholeCamera], held: np.ndarray,
                     light_views: list[np.ndarray | PeakMap] | None = None) -> np.ndarray:
    """(N, V) bool: the views that count for or against each point: those whose
    compact outlines hold it (``held``), and those that frame it and see no light
    there at all (a view where it lies in a cut or broad region says nothing, nor one
    whose photo clipped it there: :func:`clipped_at`)."""
    others = np.setdiff1d(np.arange(sightings.count), compact)
    if len(others):
        in_other, _ = _held_by_view(sightings, others, points, len(cameras))
    else:
        in_other = np.zeros_like(held)
    against = framing(points, cameras) & ~in_other
    if light_views is not None:
        against &= ~clipped_at(points, cameras, light_views)
    return held | against


def clipped_at(points: np.ndarray, cameras: list[PinholeCamera],
               light_views: list[np.ndarray | PeakMap]) -> np.ndarray:
    """(N, V) bool: each view's photo clipped the block where each point lies, and the
    uplift left it at about the view's white there (:data:`CLIPPED_AT_WHITE` of it, the
    most over the blocks round it).

    Such a view says the point is as bright as its white even where the outline missed
    it: the uplift may fill a clipped region at its clip level, and then half its pixels
    lie under the view's white (the median of its clip floors) and a bulb a few pixels
    across breaks into specks. Counted against the bulb, that view made it "not clipped
    wherever framed" and it vanished from the lights (the chain bench's ``bulb:11``, one
    view of the four framing its bulb). A place clipped in one colour channel is clipped
    under the white (on the example, a pale object: 0.7-0.85 of it in six views) and
    still counts against a light there."""
    out = np.zeros((len(points), len(cameras)), bool)
    for v, (cam, view) in enumerate(zip(cameras, light_views, strict=True)):
        if not isinstance(view, PeakMap) or view.clipped is None or not view.white:
            continue
        uv, z = cam.project(points)
        sx = view.block * cam.width / view.size[0]
        sy = view.block * cam.height / view.size[1]
        h, w = view.clipped.shape
        ratio = ndimage.maximum_filter(view.peaks / np.float32(view.white), size=3)
        at_white = view.clipped & (ratio >= CLIPPED_AT_WHITE)
        with np.errstate(invalid="ignore"):
            bx, by = np.floor(uv[:, 0] / sx), np.floor(uv[:, 1] / sy)
        inside = (z > 0) & (bx >= 0) & (bx < w) & (by >= 0) & (by < h)
        idx = np.flatnonzero(inside)
        out[idx, v] = at_white[by[idx].astype(int), bx[idx].astype(int)]
    return out


def _held_by_view(sightings: Sightings, regions: np.ndarray, points: np.ndarray,
                  views: int) -> tuple[np.ndarray, np.ndarray]:
    """(N, V) bool: some region of each view (of ``regions``) holds each point; and
    (N, R') the miss of each point from each of those regions over its cone."""
    rel = points[:, None] - sightings.origins[sightings.view[regions]][None]
    norm = np.maximum(np.linalg.norm(rel, axis=2), 1e-30)
    cos = np.einsum("nrk,rk->nr", rel, sightings.axes[regions]) / norm
    miss = np.arccos(np.clip(cos, -1.0, 1.0)) / np.maximum(sightings.radii[regions], 1e-9)
    onehot = np.zeros((len(regions), views))
    onehot[np.arange(len(regions)), sightings.view[regions]] = 1.0
    return ((miss <= 1.0) @ onehot) > 0, miss


def seed_lights(sightings: Sightings, cameras: list[PinholeCamera],
                light_views: list[np.ndarray | PeakMap] | None = None) -> list[LightSeed]:
    """The compact lights the outlines agree on (module docstring); ``light_views``
    (full-size peaks with their clip masks) let the views that clipped a place count
    neither for nor against it (:func:`clipped_at`)."""
    compact = np.flatnonzero(sightings.whole & (sightings.radii <= math.radians(MAX_CONE_DEG)))
    if len(compact) < MIN_VIEWS:
        return []
    a, b = np.triu_indices(len(compact), k=1)
    a, b = compact[a], compact[b]
    pair = sightings.view[a] != sightings.view[b]
    da, db = sightings.axes[a], sightings.axes[b]
    baseline = np.degrees(np.arccos(np.clip((da * db).sum(1), -1.0, 1.0)))
    pair &= baseline >= MIN_BASELINE_DEG
    a, b = a[pair], b[pair]
    if not len(a):
        return []
    oa, ob = sightings.origins[sightings.view[a]], sightings.origins[sightings.view[b]]
    mid, gap = meeting_points(oa, sightings.axes[a], ob, sightings.axes[b])
    fine = np.isfinite(gap)
    for r, o in ((a, oa), (b, ob)):
        rel = mid - o
        cos = (rel * sightings.axes[r]).sum(1) / np.maximum(np.linalg.norm(rel, axis=1), 1e-30)
        fine &= np.arccos(np.clip(cos, -1.0, 1.0)) <= sightings.radii[r]
    points = mid[fine]
    if not len(points):
        return []
    held, _ = _held_by_view(sightings, compact, points, len(cameras))
    framed = _counted_framing(sightings, compact, points, cameras, held, light_views)
    support = held.sum(1)
    stands = (support >= MIN_VIEWS) & (support >= MIN_SUPPORT_SHARE * framed.sum(1))
    # most agreed first: the share of framing views that hold it, then their number (a
    # clipped hot spot on a wall is measured under the white by a darker view; a bulb is
    # over it wherever it is framed)
    share = support / np.maximum(framed.sum(1), 1)
    order = np.flatnonzero(stands)[np.lexsort((-support[stands], -share[stands]))]
    seeds: list[LightSeed] = []
    taken = np.zeros(len(points), bool)
    for i in order:
        if taken[i]:
            continue
        placed = _place(sightings, compact, points[i], cameras, light_views)
        taken[i] = True
        if placed is None:
            continue
        seed, framing = placed
        if _seen_elsewhere(seed, framing, seeds, sightings.origins) or _beside_taken(seed, seeds):
            continue
        taken |= np.linalg.norm(points - seed.position, axis=1) <= MERGE_SIZES * seed.size
        seeds.append(seed)
    return seeds


def _beside_taken(seed: LightSeed, taken: list[LightSeed]) -> bool:
    """Whether ``seed`` was placed within :data:`MERGE_SIZES` of a ``taken`` light's
    sizes of it: a candidate far enough from that light to stand alone can still be
    placed beside it, where the rays of views seeing one bulb from far off (4 m, a pixel
    each at ``fast``) meet along their lines; ``hall:9``'s bulb was seeded three times, 9
    and 15 cm apart, and fitted as a streak through it."""
    return any(float(np.linalg.norm(seed.position - other.position)) <= MERGE_SIZES * other.size
               for other in taken)


def _seen_elsewhere(seed: LightSeed, framing: set[int], taken: list[LightSeed],
                    origins: np.ndarray) -> bool:
    """Whether a view that frames ``seed`` but does not hold it holds a ``taken`` light
    within :data:`MERGE_SIZES` of that light's sizes of it, as seen from that view: the
    view saw the light, beside where the seed is, and the seed is that light's outlines
    from the other views meeting again along their rays. A bulb four nearby views framed
    (a dark frame among them) had three of them meet again 0.24 and 0.36 m in front of
    it, each held with one view against (``bulb:11``); that view's dissent is the bulb
    itself, not an occluder."""
    for other in taken:
        for v in (framing - set(seed.views)) & set(other.views):
            to_seed, to_other = seed.position - origins[v], other.position - origins[v]
            dist = float(np.linalg.norm(to_other))
            cos = to_seed @ to_other / max(float(np.linalg.norm(to_seed)) * dist, 1e-30)
            if math.acos(min(max(cos, -1.0), 1.0)) <= MERGE_SIZES * math.atan2(other.size, dist):
                return True
    return False


def _place(sightings: Sightings, compact: np.ndarray, point: np.ndarray,
           cameras: list[PinholeCamera], light_views: list[np.ndarray | PeakMap] | None
           ) -> tuple[LightSeed, set[int]] | None:
    """The light at a candidate: per holding view its best-centred outline, the point
    nearest their rays, its size, and the views that count for or against it; None when
    that point leaves a holding cone."""
    _, miss = _held_by_view(sightings, compact, point[None], len(cameras))
    miss = miss[0]
    best: dict[int, int] = {}
    for r in np.flatnonzero(miss <= 1.0):
        v = int(sightings.view[compact[r]])
        if v not in best or miss[r] < miss[best[v]]:
            best[v] = r
    if len(best) < MIN_VIEWS:
        return None
    regions = compact[np.array(sorted(best.values()))]
    o, d = sightings.origins[sightings.view[regions]], sightings.axes[regions]
    proj = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
    placed = np.linalg.solve(proj.sum(0), np.einsum("rij,rj->i", proj, o))
    held, _ = _held_by_view(sightings, regions, placed[None], len(cameras))
    if int(held.sum()) < MIN_VIEWS:
        return None
    framed = _counted_framing(sightings, compact, placed[None], cameras, held, light_views)[0]
    size = float(np.median(np.linalg.norm(placed - o, axis=1) * np.tan(sightings.radii[regions])))
    return (LightSeed(placed, size, [int(v) for v in np.flatnonzero(held[0])],
                      int(framed.sum())), {int(v) for v in np.flatnonzero(framed)})


def seed_points(seeds: list[LightSeed], cameras: list[PinholeCamera],
                light_views: list[np.ndarray | PeakMap], images: list[np.ndarray],
                rng: np.random.Generator, y_weights: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) points in a ball of each seed's size around it, and (N, 3) their colours.

    A light's points share one colour: the brightest (luminance) of its views' pixels
    at its centre in ``images`` (at fitting size: the chroma), brightened to the most
    luminance ``light_views`` (the full-size peaks) hold there: the outline is over its
    view's white, so the light is at least that bright, where the fitting size has
    averaged it with its surroundings.
    """
    if not seeds:
        return np.zeros((0, 3)), np.zeros((0, 3), np.float32)
    y = np.asarray(y_weights, np.float32)
    pts, cols = [], []
    for seed in seeds:
        n = POINTS_PER_LIGHT
        direction = rng.normal(size=(n, 3))
        direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-12)
        radius = seed.size * rng.uniform(0.0, 1.0, n) ** (1.0 / 3.0)
        centre = seed.position[None]
        samples = np.concatenate([_sample_at(images[v], cameras[v], centre)
                                  for v in seed.views])
        colour = samples[int(np.argmax(samples @ y))]
        peak = max(float(_sample_at(_luminance(light_views[v], y), cameras[v], centre)[0, 0])
                   for v in seed.views)
        colour = colour * max(peak / max(float(colour @ y), 1e-12), 1.0)
        pts.append(seed.position + direction * radius[:, None])
        cols.append(np.tile(colour, (n, 1)))
    return np.concatenate(pts), np.concatenate(cols).astype(np.float32)


def _luminance(view: np.ndarray | PeakMap, y: np.ndarray) -> np.ndarray:
    """(h, w, 1) a light view's luminance (a peak map's peaks, an image's Y)."""
    if isinstance(view, PeakMap):
        return view.peaks[..., None]
    return (np.asarray(view, np.float32) @ y)[..., None]


def _sample_at(image: np.ndarray, cam: PinholeCamera, points: np.ndarray) -> np.ndarray:
    """(N, C) the pixels of ``image`` (any size, framing as ``cam``) the points land in."""
    uv, _ = cam.project(points)
    h, w = image.shape[:2]
    x = np.clip((uv[:, 0] * w / cam.width).astype(np.int64), 0, w - 1)
    y = np.clip((uv[:, 1] * h / cam.height).astype(np.int64), 0, h - 1)
    return image[y, x].astype(np.float32)


@dataclass
class LightSeedPoints:
    """Initial points on the seeded lights (:func:`seed_points`), in light order."""

    points: np.ndarray
    colours: np.ndarray
    lights: int
    centres: np.ndarray | None = None
    """(lights, 3) the lights' positions (None: not known, every light is kept)."""
    sizes: np.ndarray | None = None
    """(lights,) their sizes."""

    def missing_from(self, points: np.ndarray) -> LightSeedPoints:
        """Only the lights that ``points`` (the other initial points) leave bare: fewer
        than :data:`POINTS_PER_LIGHT` of them within the light's size. A lamp the
        brightness test already found keeps the start it had (its colour from its
        brightest measured pixel, not this seed's white)."""
        if self.centres is None or self.sizes is None or not self.lights or not len(points):
            return self
        tree = cKDTree(np.asarray(points, np.float64))
        counts = np.array([len(tree.query_ball_point(c, r))
                           for c, r in zip(self.centres, self.sizes, strict=True)])
        bare = counts < POINTS_PER_LIGHT
        per = len(self.points) // self.lights
        rows = np.repeat(bare, per)
        return LightSeedPoints(self.points[rows], self.colours[rows], int(bare.sum()),
                               self.centres[bare], self.sizes[bare])


def find_light_seeds(cameras: list[PinholeCamera], light_views: list[np.ndarray | PeakMap],
                     whites: np.ndarray, y_weights: np.ndarray) -> list[LightSeed]:
    """The compact lights the views' outlines over their ``whites``
    (:func:`gaslight_usd.sightings.view_whites`) place, found in ``light_views``
    (full-size peaks, :meth:`FitData.light_views`; module docstring)."""
    luma = np.asarray(y_weights, np.float64)
    return seed_lights(sight_lights(cameras, light_views, whites, luma), cameras, light_views)


def measured_light_seeds(cameras: list[PinholeCamera],
                         light_views: list[np.ndarray | PeakMap], images: list[np.ndarray],
                         y_weights: np.ndarray,
                         ratio: float = MEASURED_LIGHT_RATIO) -> list[LightSeed]:
    """The compact lights of views that clipped nothing, placed by their outlines over
    ``ratio`` x the views' median luminance (``images``: the fitting-size views, for the
    level; ``light_views``: where the outlines are read, as :func:`find_light_seeds`).

    The plane prior (on where nothing clipped) takes a bright splat floating in front
    of a lit patch of a wall for that patch's light and puts it on the wall
    (:func:`gaslight_usd.fit.planes.bright_floaters`); a bare bulb 0.9 m in front of
    the wall it lights is such a splat once a few of its splats have slid onto the
    wall, and at ``balanced`` the whole bulb followed them there (``gaslight2usd bench
    --suite chain --scene bulb:7 --method "truth HDR" --preset balanced``). The
    outlines place the bulb where it is, and its splats are kept off that rule.
    """
    luma = np.asarray(y_weights, np.float64)
    level = measured_level(images, luma)
    if not level > 0:
        return []
    whites = np.full(len(light_views), ratio * level)
    return seed_lights(sight_lights(cameras, light_views, whites, luma, measured=True),
                       cameras)


def measured_level(images: list[np.ndarray], y_weights: np.ndarray) -> float:
    """The views' median luminance (median over views of each view's median): the level
    :data:`MEASURED_LIGHT_RATIO` is counted from."""
    luma = np.asarray(y_weights, np.float64)
    return float(np.median([np.median(np.asarray(im, np.float64) @ luma) for im in images]))
