"""Initial splats: from the HDR-coloured sparse points, spread over the views'
surfaces, or, when there are no points at all, from a small plane sweep.

Sparse points (given, or triangulated from the HDR views by
:mod:`.triangulate`) are too few to start from alone (hundreds for a room), so
more points are added where the views see surfaces: random pixels of the
training views are pushed along their rays to the depth the sparse points that
project nearest to them in that view imply (points the view sees: its track when
known, else its frustum): their median depth, or, with the fit's planes on
(``FitConfig.plane_prior``), their plane's. A plane's inverse depth is an affine
function of the pixel, so an affine fit of the neighbours' inverse depths puts a
pixel between features on their plane, however obliquely the view sees it; where
the neighbours do not lie on one plane (an edge, a corner) the pixel takes their
median depth. The pixel's HDR colour is the point's colour. The median alone
leaves walls smeared about 0.1 m (median) off their planes on a generated room,
and a short fit hardly moves its splats (``fast``'s position steps add up to a
few centimetres), so the init's smear is the fit's.

Plane sweep (no points at all): random pixels of random training views are
pushed along their rays to the candidate depth (geometric steps spanning 0.05x
to 20x the camera spread) where the other views agree best on the colour
(lowest spread of log colour among the views that see that point); the pixel's
HDR colour is the splat's colour. Pixels with no view to agree with go to a
random depth. Scales start at the mean distance to the 3 nearest neighbours.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from ..cameras import PinholeCamera
from ..colour import luminance_weights
from ..poses import colour_points
from ..poses.colmap import ColmapModel
from .light_seeds import LightSeedPoints

if TYPE_CHECKING:  # lit_floor casts its rays with this module's depth_rays
    from .lit_floor import LitFloor


def neighbour_scales(points: np.ndarray) -> np.ndarray:
    k = min(4, len(points))
    if k < 2:
        return np.full(len(points), 0.01)
    dist, _ = cKDTree(points).query(points, k=k)
    return np.clip(dist[:, 1:].mean(1), 1e-4, None)


BRIGHT_RATIO = 64.0
"""Pixels this many times (6 stops) brighter than the views' median count as lamps
(windows, dimmer and flat, are left to the surface fill: they lie on walls)."""
BRIGHT_SHARE = 0.05
"""Share of the initial points placed on light sources (when there are any)."""


def _luma(y_weights: np.ndarray | None) -> np.ndarray:
    """Luminance weights as float64 (the views' own, else Rec.709's)."""
    return np.asarray(luminance_weights() if y_weights is None else y_weights, np.float64)


def _sample(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    h, w = image.shape[:2]
    x = np.clip(uv[..., 0].astype(np.int64), 0, w - 1)
    y = np.clip(uv[..., 1].astype(np.int64), 0, h - 1)
    return image[y, x]


def consistency_costs(v: int, px: np.ndarray, cand: np.ndarray,
                      cameras: list[PinholeCamera], images: list[np.ndarray]) -> np.ndarray:
    """(n, D) photo-consistency cost of candidate points ``cand`` (n, D, 3) for pixels
    ``px`` (n, 2) of view ``v``: the mean |log colour difference| to the other views that
    see the candidate, plus 0.5 / (how many do); inf where none does."""
    n, steps = cand.shape[:2]
    logs = []
    for o, other in enumerate(cameras):
        if o == v:
            continue
        uv, z = other.project(cand.reshape(-1, 3))
        inside = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < other.width) & \
                 (uv[:, 1] >= 0) & (uv[:, 1] < other.height)
        val = np.log(np.maximum(_sample(images[o], uv), 1e-4)).mean(-1)
        logs.append(np.where(inside, val, np.nan).reshape(n, steps))
    own = np.log(np.maximum(_sample(images[v], px), 1e-4)).mean(-1)[:, None]
    stack = np.stack(logs)  # (V-1, n, D)
    seen = np.isfinite(stack).sum(0)
    diff = np.where(seen[None] > 0, np.abs(stack - own[None]), 0.0)
    err = np.nansum(diff, axis=0) / np.maximum(seen, 1)
    return np.where(seen >= 1, err + 0.5 / np.maximum(seen, 1), np.inf)


def depth_rays(cam: PinholeCamera, px: np.ndarray) -> np.ndarray:
    """(n, 3) world directions (unit depth along the view axis) of pixels ``px``."""
    return np.stack([(px[:, 0] - cam.cx) / cam.fx, (px[:, 1] - cam.cy) / cam.fy,
                     np.ones(len(px))], -1) @ cam.R


def _sweep_depths(v: int, px: np.ndarray, cameras: list[PinholeCamera],
                  images: list[np.ndarray], depths: np.ndarray, rng: np.random.Generator
                  ) -> np.ndarray:
    """(n, 3) points: pixels ``px`` of view ``v`` at their most photo-consistent depth."""
    cam, n, steps = cameras[v], len(px), len(depths)
    cand = cam.center + depth_rays(cam, px)[:, None, :] * depths[None, :, None]  # (n, D, 3)
    err = consistency_costs(v, px, cand, cameras, images)
    best = np.argmin(err, axis=1)
    lost = ~np.isfinite(err[np.arange(n), best])
    best[lost] = rng.integers(0, steps, int(lost.sum()))
    return cand[np.arange(n), best]


def _sweep_range(cameras: list[PinholeCamera], depth_steps: int) -> np.ndarray:
    centres = np.array([c.center for c in cameras])
    spread = max(float(np.linalg.norm(centres - centres.mean(0), axis=1).max()), 1e-2)
    return spread * np.geomspace(0.05, 20.0, depth_steps)


def plane_sweep_points(cameras: list[PinholeCamera], images: list[np.ndarray], count: int,
                       rng: np.random.Generator, depth_steps: int = 32
                       ) -> tuple[np.ndarray, np.ndarray]:
    """(count, 3) points and (count, 3) colours from photo-consistent depths."""
    depths = _sweep_range(cameras, depth_steps)
    src = rng.integers(0, len(cameras), count)
    pts = np.empty((count, 3))
    cols = np.empty((count, 3), np.float32)
    for v, cam in enumerate(cameras):
        idx = np.flatnonzero(src == v)
        if not len(idx):
            continue
        px = rng.uniform([0, 0], [cam.width, cam.height], (len(idx), 2))
        pts[idx] = _sweep_depths(v, px, cameras, images, depths, rng)
        cols[idx] = _sample(images[v], px)
    return pts, cols


def measured_colours(points: np.ndarray, colours: np.ndarray, cameras: list[PinholeCamera],
                     images: list[np.ndarray], floors: list[np.ndarray | None],
                     guessed: np.ndarray | None = None,
                     y_weights: np.ndarray | None = None) -> np.ndarray:
    """``colours`` of the ``guessed`` points (default: all), raised to the brightest
    *measured* sample of each point in any view.

    A light's seed takes the colour of the pixel it was swept from, and most of its
    pixels come from photos where it clipped: the uplift's fill there is a guess,
    often stops low. A view whose photo measured the light unclipped (a dark frame,
    a lower auto-exposure; its clip floor is 0 there) knows better, and a short fit
    (``fast``: a few dozen steps on that one view) cannot climb the stops from the
    guess. The brightest such sample wins (occluders only make samples darker);
    a point no view measured, or one whose own pixel was measured, keeps its colour.
    ``y_weights``: the views' luminance weights (default Rec.709's).
    """
    luma = _luma(y_weights)
    best = np.asarray(colours, np.float32).copy()
    if guessed is not None and not guessed.any():
        return best
    best_y = best @ luma
    for cam, image, floor in zip(cameras, images, floors, strict=True):
        uv, z = cam.project(points)
        inside = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & \
                 (uv[:, 1] >= 0) & (uv[:, 1] < cam.height)
        sample = _sample(image, uv)
        if floor is not None:
            inside &= _sample(floor[..., None], uv)[:, 0] <= 0
        y = sample @ luma
        take = inside & (y > best_y)
        if guessed is not None:
            take &= guessed
        best[take], best_y[take] = sample[take], y[take]
    return best


SEED_REACH = 2.0
"""A measured light pixel whose ray passes within this many of a seeded light's sizes
goes onto that light (:func:`bright_points`)..."""
POINT_LIKE_DEG = 3.0
"""...when the light is a point to that view: at most this wide (half-angle). A bulb's
seed spans 0.9-1.5 deg from the chain bench's cameras, a ceiling panel's 5-6.5: a flat
light is no point, and the ray's point nearest its centre is off its face (`panels:7`
with dark frames lost 2.6-3.1 dB at its panel's probe so)."""


def _onto_seeds(cam: PinholeCamera, px: np.ndarray, swept: np.ndarray, centres: np.ndarray,
                sizes: np.ndarray) -> np.ndarray:
    """``swept`` (n, 3), the points of pixels ``px`` whose rays pass within
    :data:`SEED_REACH` sizes of a point-like seed (:data:`POINT_LIKE_DEG`; the first
    along the ray) and that the sweep put farther along the ray than that from the seed,
    moved to the ray's point nearest that seed's centre."""
    rays = depth_rays(cam, px)
    rays = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    rel = np.asarray(centres, np.float64) - cam.center  # (K, 3)
    along = rays @ rel.T  # (n, K)
    miss = np.linalg.norm(rel[None] - along[..., None] * rays[:, None], axis=-1)
    size = np.asarray(sizes, np.float64)[None]
    near = ((along > 0) & (miss <= SEED_REACH * size)
            & (size <= math.tan(math.radians(POINT_LIKE_DEG)) * along))
    first = np.argmin(np.where(near, along, np.inf), axis=1)
    depth = along[np.arange(len(px)), first]
    reach = SEED_REACH * np.asarray(sizes, np.float64)[first]
    # a sweep that found the light keeps its depth
    swept_depth = np.einsum("ij,ij->i", np.asarray(swept, np.float64) - cam.center, rays)
    hit = near.any(axis=1) & (np.abs(swept_depth - depth) > reach)
    out = np.array(swept, np.float64, copy=True)
    out[hit] = cam.center + rays[hit] * depth[hit, None]
    return out


def above_floor(eye: np.ndarray, points: np.ndarray, room_floor: LitFloor | None,
                view: int | None = None) -> np.ndarray:
    """``points`` (n, 3) seen from ``eye``, those under ``room_floor`` moved back along
    their rays onto it: nothing a view sees lies under the floor (a floor's pixels
    filled from the walls' planes carried down did, :mod:`.lit_floor`). With ``view``
    (the index of the view looking from ``eye``), a point whose ray meets the floor
    where that view saw the lit patch goes onto it too, from in front of it as well."""
    if room_floor is None or not len(points):
        return points
    normal, offset = room_floor.normal, room_floor.offset
    rays = points - eye
    height = float(eye @ normal) - offset
    drop = rays @ normal
    down = (drop < 0) & (height > 0)
    scale = np.where(down, height / np.where(down, -drop, 1.0), 1.0)
    crossing = eye + rays * scale[:, None]
    move = down & (points @ normal < offset)
    if view is not None:
        move |= down & room_floor.lit_at(view, crossing)
    out = points.copy()
    out[move] = crossing[move]
    return out


def _more_consistent(v: int, px: np.ndarray, first: np.ndarray, second: np.ndarray,
                     cameras: list[PinholeCamera], images: list[np.ndarray]) -> np.ndarray:
    """(n, 3): per pixel of view ``v``'s ``px``, ``first`` where the other views agree on
    its colour there better than at ``second`` (:func:`consistency_costs`), else
    ``second``."""
    differ = np.any(first != second, axis=1)
    if not differ.any():
        return second
    cost = consistency_costs(v, px[differ], np.stack([first[differ], second[differ]], 1),
                             cameras, images)
    out = second.copy()
    take = np.flatnonzero(differ)[cost[:, 0] < cost[:, 1]]
    out[take] = first[take]
    return out


def bright_points(cameras: list[PinholeCamera], images: list[np.ndarray], count: int,
                  rng: np.random.Generator, ratio: float = BRIGHT_RATIO,
                  depth_steps: int = 48, floors: list[np.ndarray | None] | None = None,
                  y_weights: np.ndarray | None = None,
                  seeds: tuple[np.ndarray, np.ndarray] | None = None,
                  room_floor: LitFloor | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Points on light sources: pixels over ``ratio`` x the median of all views, plane-swept.

    Lamps and windows have no features to triangulate and sit off the
    surfaces the sparse points describe, yet they light the scene; their own
    brightness makes their depth easy to find by photo-consistency. With the
    views' clip ``floors``, a point swept from a clipped pixel takes its brightest
    measured sample (:func:`measured_colours`); without them every pixel counts as
    measured and keeps its own colour. ``y_weights``: the views' luminance weights
    (default Rec.709's).

    ``seeds`` (centres (K, 3), sizes (K,)): the compact lights the clipped outlines
    placed (:mod:`.light_seeds`). A pixel its own view *measured* (a dark frame's bulb,
    with the clip ``floors``) whose ray passes within :data:`SEED_REACH` sizes of one
    that is a point to it (:data:`POINT_LIKE_DEG`) goes onto it where the sweep put it
    off the light's depth by more: the other views clipped that bulb, and their fills (a
    few times the white) agree with its thousands nowhere, so the sweep put ``bulb:11``'s
    dark-frame pixels 0.1-14 m off, and the fit grew a bright smear along the dark
    frame's rays and opaque splats round it that hid the bulb from the room.
    ``room_floor``: none goes under it (:func:`above_floor`).
    """
    luma = _luma(y_weights)
    lum = [im @ luma for im in images]
    level = ratio * float(np.median(np.concatenate([y[::4, ::4].ravel() for y in lum])))
    where = [np.argwhere(y > level) for y in lum]
    total = sum(len(w) for w in where)
    if not total or count <= 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.float32)
    depths = _sweep_range(cameras, depth_steps)
    pts, cols, clipped = [], [], []
    for v, yx in enumerate(where):
        n = min(len(yx), int(round(count * len(yx) / total)))
        if not n:
            continue
        pick = yx[rng.choice(len(yx), n, replace=False)]
        px = pick[:, ::-1] + rng.uniform(0, 1, (n, 2))
        at = _sweep_depths(v, px, cameras, images, depths, rng)
        floor = floors[v] if floors is not None else None
        clipped.append(np.zeros(n, bool) if floor is None else _sample(floor[..., None],
                                                                       px)[:, 0] > 0)
        if seeds is not None and floors is not None and len(seeds[0]):
            measured = ~clipped[-1]
            at[measured] = _onto_seeds(cameras[v], px[measured], at[measured], *seeds)
        pts.append(above_floor(cameras[v].center, at, room_floor, v))
        cols.append(_sample(images[v], px))
    if not pts:
        return np.zeros((0, 3)), np.zeros((0, 3), np.float32)
    pts, cols = np.concatenate(pts), np.concatenate(cols).astype(np.float32)
    if floors is not None:
        cols = measured_colours(pts, cols, cameras, images, floors, np.concatenate(clipped),
                                luma)
    return pts, cols


def seen_by(model: ColmapModel, names: list[str]) -> np.ndarray | None:
    """(V, N) which of the named views each sparse point's track holds (None: no tracks)."""
    tracks = model.tracks
    if tracks is None or len(tracks) != len(model.points) or not any(len(t) for t in tracks):
        return None
    stems = [Path(n).stem for n in model.names]
    ids = np.array([model.image_ids[stems.index(Path(n).stem)] for n in names], np.int64)
    lengths = np.fromiter((len(t) for t in tracks), np.int64, len(tracks))
    point_of = np.repeat(np.arange(len(tracks)), lengths)
    image_of = np.concatenate([np.asarray(t, np.int64).reshape(-1, 2)[:, 0] for t in tracks])
    lut = np.full(max(int(ids.max()), int(image_of.max(initial=0))) + 1, -1, np.int64)
    lut[ids] = np.arange(len(ids))
    row = lut[np.clip(image_of, 0, None)]
    seen = np.zeros((len(names), len(tracks)), bool)
    keep = row >= 0
    seen[row[keep], point_of[keep]] = True
    return seen


PLANE_RESIDUAL = 0.05
"""Largest misfit (a share of the neighbours' mean inverse depth) for which the
neighbours of a fill pixel count as one plane."""
PLANE_REACH = 1.3
"""How far past the neighbours' nearest and farthest depth an affine fit may reach
(an extrapolation past the neighbours' spread is not trusted further)."""


def fill_depths(px: np.ndarray, near_uv: np.ndarray, near_depth: np.ndarray) -> np.ndarray:
    """The depths of pixels ``px`` (n, 2) from their sparse neighbours' image positions
    ``near_uv`` (n, k, 2) and depths ``near_depth`` (n, k): an affine fit of inverse depth
    over the image where the neighbours lie on one plane, else their median depth."""
    inverse = 1.0 / near_depth
    design = np.concatenate([near_uv, np.ones(near_depth.shape + (1,))], axis=-1)
    coef = np.linalg.pinv(design) @ inverse[..., None]  # (n, 3, 1)
    misfit = np.abs((design @ coef)[..., 0] - inverse).max(axis=1) / inverse.mean(axis=1)
    at = (np.concatenate([px, np.ones((len(px), 1))], axis=1)[:, None, :] @ coef)[:, 0, 0]
    planar = ((misfit < PLANE_RESIDUAL) & (at > inverse.min(axis=1) / PLANE_REACH)
              & (at < inverse.max(axis=1) * PLANE_REACH))
    return np.where(planar, 1.0 / np.where(planar, at, 1.0), np.median(near_depth, axis=1))


def _neighbours_per_view(points: np.ndarray, seen: np.ndarray | None,
                         cameras: list[PinholeCamera]) -> tuple[list, list]:
    """Per view, the image positions (m, 2) and depths (m,) of the ``points`` it sees
    (its track's, with ``seen``, else those in its frame)."""
    rays_per_view, depths_per_view = [], []
    for v, cam in enumerate(cameras):
        uv, z = cam.project(points)
        ok = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & (uv[:, 1] >= 0) & \
             (uv[:, 1] < cam.height)
        if seen is not None:
            ok &= seen[v]
        rays_per_view.append(uv[ok])
        depths_per_view.append(z[ok])
    return rays_per_view, depths_per_view


def _filled(cam: PinholeCamera, px: np.ndarray, near_uv: np.ndarray, near_depth: np.ndarray,
            neighbours: int, planar: bool) -> np.ndarray:
    """(n, 3) pixels ``px`` of ``cam`` at the depth their nearest sparse neighbours
    (image positions ``near_uv``, depths ``near_depth``) imply (:func:`fill_depths`)."""
    _, near = cKDTree(near_uv).query(px, k=neighbours)
    depth = (fill_depths(px, near_uv[near], near_depth[near]) if planar
             else np.median(near_depth[near], axis=1))
    return cam.center + depth_rays(cam, px) * depth[:, None]


def surface_fill_points(points: np.ndarray, seen: np.ndarray | None,
                        cameras: list[PinholeCamera], images: list[np.ndarray], count: int,
                        rng: np.random.Generator, neighbours: int | None = None,
                        planar: bool = True, room_floor: LitFloor | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """(n <= count, 3) points on the views' surfaces and their HDR colours (module doc);
    ``planar`` off: each pixel at its 4 nearest neighbours' median depth (the fill
    before the planes, whose geometry the handling of clipped lights was tuned on);
    on, the 6 nearest (an affine fit needs more than 3). ``room_floor``: its lit patch's
    cells join the sparse points as neighbours where the views agree better on the
    colour at the depth they give, a pixel whose ray meets the floor where the view saw
    the patch lit goes there, and none goes under it (:func:`above_floor`)."""
    neighbours = neighbours or (6 if planar else 4)
    rays_per_view, depths_per_view = _neighbours_per_view(points, seen, cameras)
    with_floor = None
    if room_floor is not None and len(room_floor.points):
        with_floor = _neighbours_per_view(
            np.concatenate([points, room_floor.points]),
            None if seen is None else np.concatenate([seen, room_floor.seen], axis=1), cameras)
    usable = [v for v in range(len(cameras)) if len(depths_per_view[v]) >= neighbours]
    if not usable or count <= 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.float32)
    share = rng.multinomial(count, np.full(len(usable), 1.0 / len(usable)))
    pts, cols = [], []
    for v, n in zip(usable, share, strict=True):
        cam = cameras[v]
        px = rng.uniform([0, 0], [cam.width, cam.height], (n, 2))
        at = _filled(cam, px, rays_per_view[v], depths_per_view[v], neighbours, planar)
        if with_floor is not None:
            # the patch's cells are points on the floor as good as the sparse ones, but
            # far denser: a wall pixel over the patch whose neighbours they crowd takes
            # a depth between the two, so each pixel keeps the fill the views agree on
            near_floor = _filled(cam, px, with_floor[0][v], with_floor[1][v], neighbours,
                                 planar)
            at = _more_consistent(v, px, above_floor(cam.center, near_floor, room_floor, v),
                                  above_floor(cam.center, at, room_floor, v), cameras, images)
        pts.append(at)
        cols.append(_sample(images[v], px))
    return np.concatenate(pts), np.concatenate(cols).astype(np.float32)


def initial_points(model: ColmapModel, cameras: list[PinholeCamera], images: list[np.ndarray],
                   names: list[str], count: int, rng: np.random.Generator,
                   floors: list[np.ndarray | None] | None = None,
                   y_weights: np.ndarray | None = None,
                   seeded: LightSeedPoints | None = None, planar_fill: bool = True,
                   room_floor: LitFloor | None = None) -> tuple[np.ndarray, np.ndarray, str]:
    """Points, HDR colours and how they were made.

    "sparse points + surface fill" when the model has points, else "plane sweep";
    either way "+ N seeded lights" with ``seeded`` (points on the compact lights the
    clipped outlines place, :mod:`.light_seeds`; only those the other points leave
    bare, in place of the last surface-fill points). ``planar_fill``: fill pixels go on
    their neighbours' plane (:func:`fill_depths`), else to their median depth.
    ``floors``: the views' clip floors (None: every pixel measured), for the lights'
    colours (:func:`bright_points`); ``y_weights``: the views' luminance weights
    (default Rec.709's), to find the lights; ``room_floor``: a floor the sparse points
    miss (:mod:`.lit_floor`), for the fill and the lights' points.
    """
    known = (None if seeded is None or seeded.centres is None or seeded.sizes is None
             else (seeded.centres, seeded.sizes))
    pts, cols, how = _unseeded_points(model, cameras, images, names, count, rng, floors,
                                      y_weights, planar_fill, known, room_floor)
    if seeded is not None:
        seeded = seeded.missing_from(pts)
    if seeded is not None and seeded.lights:
        keep = max(min(len(pts), count - len(seeded.points)), 0)  # never past ``count``
        pts, cols = pts[:keep], cols[:keep]
        pts = np.concatenate([pts, seeded.points])
        cols = np.concatenate([cols, seeded.colours])
        how += f" + {seeded.lights} seeded light{'s' if seeded.lights > 1 else ''}"
    return pts, cols, how


def _unseeded_points(model: ColmapModel, cameras: list[PinholeCamera],
                     images: list[np.ndarray], names: list[str], count: int,
                     rng: np.random.Generator, floors: list[np.ndarray | None] | None,
                     y_weights: np.ndarray | None, planar_fill: bool = True,
                     seeds: tuple[np.ndarray, np.ndarray] | None = None,
                     room_floor: LitFloor | None = None
                     ) -> tuple[np.ndarray, np.ndarray, str]:
    if len(model.points) >= 16:
        colours = colour_points(model, dict(zip(names, images, strict=True)))
        pts = np.asarray(model.points, np.float64)
        if len(pts) > count // 2:
            pick = np.sort(rng.choice(len(pts), count // 2, replace=False))
            pts, colours = pts[pick], colours[pick]
        lights, light_colours = bright_points(cameras, images, int(BRIGHT_SHARE * count), rng,
                                              floors=floors, y_weights=y_weights, seeds=seeds,
                                              room_floor=room_floor)
        seen = seen_by(model, names)
        fill, fill_colours = surface_fill_points(np.asarray(model.points, np.float64), seen,
                                                 cameras, images,
                                                 count - len(pts) - len(lights), rng,
                                                 planar=planar_fill, room_floor=room_floor)
        return (np.concatenate([pts, lights, fill]),
                np.concatenate([colours, light_colours, fill_colours]),
                "sparse points + surface fill + light sources")
    pts, cols = plane_sweep_points(cameras, images, count, rng)
    return pts, cols, "plane sweep"
