"""Large flat surfaces (walls, floor, ceiling) as planes the fit keeps its splats on.

A handful of photos leave a splat's depth loosely tied: on a plain wall a splat
a few centimetres in front of or behind it looks the same in every photo, and a
short fit hardly moves its splats (``fast``'s position steps add up to a few
centimetres). Scattered about a wall, they are harmless in the photos but wrong
for light: a window's splats spread 0.1-0.4 m off its wall put its power in the
wrong place for a probe half a metre away. So the planes the initial points lie
on are found once, and through the fit every splat near a plane's patch (a
little in front of it, or further behind it, where no camera sees) is put back
on it after each step, and pulled flat along it by :meth:`PlanePrior.flatness`.
Measured by ``gaslight2usd bench --suite chain`` (the probes near the lights).

Which planes: the main directions are the normals of the planes RANSAC finds
first in the points, squared up as a room's are (:func:`main_axes`; for the room's
box, the views' triangulated points' where they give all three, the planes kept square
to them: :func:`sparse_axes`, the start's fill carries its depth errors); along each,
the offsets where the points crowd are planes (:func:`find_planes`), if the
cameras are all on one side, the points cover a patch both ways and the patch
hides few points behind it. A room's walls pass; a slice through the room at a
table's height does not (the room lies behind it). A plain ceiling, whose fill is
scattered behind it, is held where the walls stop at it (:func:`_caps`); a plain
floor, which furniture hides from the walls' points, is not. Bright clumps the fit
leaves floating in front of a lit patch of a plane (a window) go onto it
(:func:`bright_floaters`). The same planes, where they make a room's box
(:func:`room_box`; a window's wall too sparse to be a plane added where the points
beyond the cameras crowd, :func:`far_walls`), stop a light sunk behind a ceiling few
photos see and hold a window's splats on its wall (:mod:`.sunk_lights`), with the plane
prior on or off.
Sweeping a scene's main directions for planes is Gallup et al. 2007's idea; here
it runs over the points, not pixels: pixel-wise photo-consistency on plain
walls put only a quarter of their pixels within 6 cm (``fast``'s 120-pixel
views).

Scale: distances are shares of the initial points' extent (the box holding the
central 96 % of them), so the rule reads the same in metres or in SfM units.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch
from scipy.spatial import cKDTree

from ..render.project import quat_to_rotmat
from ..splats import SplatScene

INLIER_SHARE = 0.01
"""Inlier distance: this share of the initial points' extent (0.07 m in a 5 x 4 x 3 m
room); also the offset histogram's bin (half of it)."""
REACH = 2.0
"""Splats up to this many inlier distances in front of a plane are put on it..."""
REACH_BEHIND = 5.0
"""...and up to this many behind it, where no camera can see them (the fill's smear
behind a wall, a window's light sunk behind it)."""
LIFT = 0.25
"""A free splat (a clipped light's, whose depth from the photos is a guess) near a plane
is kept at least this many inlier distances in front of it: drawn over the held wall,
not hidden behind it."""
MIN_POINTS_SHARE = 0.01
"""A plane holds at least this share of the initial points..."""
PEAK_OVER_MEDIAN = 2.5
"""...and its offset bin this many times the median bin's count along its direction (a
wall with a large window in it crowds 2.6-3.6 times the median bin where the room's
furniture fills the bins between the walls: ``panels:7``'s window wall, at 4 refused)."""
MIN_SPAN = 0.15
"""...and spans at least this share of the extent both ways (a wall, not a shelf)."""
MAX_BEHIND = 1.0
"""...and, seen from the cameras, hides no more than this many points (a share of its
own) behind its patch: a wall hides only the fill's smear; a slice through the room
(at a table's height, a lamp's) hides the room above or below it. A plain ceiling or
floor, which the sparse points barely find, has its fill scattered behind it and is
refused here too (a table top can crowd like a floor); :func:`_caps` takes the ceiling
back."""
MIN_CAMERAS_IN_FRONT = 0.9
"""Share of the cameras on one side of a plane (a room's wall has them all inside)."""
CANDIDATES = 512
"""Three-point draws of the RANSAC that finds the main directions."""
CAP_WALLS_BEYOND = 0.05
"""A ceiling (or floor) refused for what it hides is held where at most this share of
its walls' points lie beyond it (:func:`_caps`): 1.8-4.7 % at the chain bench's
ceilings, 4.5-20 % at the table tops and shelves below them (init points, seed 0)..."""
CAP_CROWD = 0.75
"""...and it crowds at least this share of the most points any plane along its direction
does (the chain bench's ceilings crowd the most; a false floor at a table top 60 %)."""
FLOAT_REACH = 12.0
"""A bright splat up to this many inlier distances in front of a plane (0.9 m in a
5 x 4 x 3 m room) may be a floater of a lit patch of it (:func:`bright_floaters`)..."""
FLOAT_BRIGHT = 4.0
"""...when it is this many times brighter than the held splats' median..."""
FLOAT_MATCH = 0.25
"""...and the plane's splats under it, within :data:`FLOAT_RADIUS`, include one at least
this share as bright (a window's own; a lamp in front of a wall is hundreds of times the
wall behind it)."""
FLOAT_RADIUS = 2.0
"""Inlier distances around a floater's foot on the plane searched for its patch."""
KEEP_OUT_SIZES = 3.0
"""Splats within this many of a seeded compact light's sizes are that light's, never a
floater (:mod:`.light_seeds`)."""


@dataclass
class Plane:
    normal: np.ndarray
    """(3,) unit normal, towards the cameras."""
    offset: float
    """normal . x of the plane's points."""
    lo: np.ndarray
    """(2,) lower corner of the patch its points cover in the plane's (u, v) axes."""
    hi: np.ndarray
    axes: np.ndarray
    """(2, 3) in-plane axes."""
    points: int

    def as_dict(self) -> dict:
        return {"normal": [round(float(v), 5) for v in self.normal],
                "offset": round(float(self.offset), 5), "points": self.points,
                "size": [round(float(v), 4) for v in self.hi - self.lo]}

    def crossing(self, eye: np.ndarray, target: np.ndarray) -> np.ndarray:
        """(K,) the ratio along ``eye + (target - eye) * r`` where each ray crosses this
        plane's patch from its front (the cameras' side), ``inf`` where it does not."""
        step = (target - eye) @ self.normal
        height = eye @ self.normal - self.offset
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = -height / step
        uv = (eye + (target - eye) * np.where(np.isfinite(ratio), ratio, 0.0)[:, None]
              ) @ self.axes.T
        hit = ((height > 0) & (step < 0) & np.all((uv >= self.lo) & (uv <= self.hi), axis=1))
        return np.where(hit, ratio, np.inf)


def on_a_plane(point: np.ndarray, reach: float, planes: list[Plane]) -> bool:
    """Whether ``point`` lies within ``reach`` of one of ``planes``' patches (either side)."""
    return bool(_near_patches(np.asarray(point, np.float64).reshape(1, 3),
                              np.array([float(reach)]), planes)[0])


def on_planes(scene: SplatScene, planes: list[Plane]) -> np.ndarray:
    """(N,) splats whose 3-sigma reach touches one of ``planes``' patches."""
    return _near_patches(scene.positions.astype(np.float64), 3.0 * scene.scales.max(axis=1),
                         planes)


def _near_patches(points: np.ndarray, reach: np.ndarray, planes: list[Plane]) -> np.ndarray:
    """(N,) points within their ``reach`` of one of ``planes``' patches (either side)."""
    out = np.zeros(len(points), bool)
    for plane in planes:
        uv = points @ plane.axes.T
        out |= ((np.abs(points @ plane.normal - plane.offset) <= reach)
                & np.all((uv >= plane.lo - reach[:, None]) & (uv <= plane.hi + reach[:, None]),
                         axis=1))
    return out


def _nearer_fit(points: np.ndarray, normal: np.ndarray, offset: float, tau: float,
                max_tilt: float | None = None) -> tuple[np.ndarray, float]:
    """The plane ``normal . x = offset`` refitted by least squares to the ``points``
    ever nearer it (the fill's smear pulls a single fit off); where ``max_tilt`` is
    given and the fit leans further off ``normal``, the plane as given; ``max_tilt`` 0:
    only the offset is refitted."""
    start = normal
    for share in (1.0, 0.5, 0.25):
        held = points[np.abs(points @ normal - offset) < share * tau]
        if len(held) < 3:
            break
        centre = held.mean(axis=0)
        if max_tilt == 0:
            offset = float(normal @ centre)
            continue
        fitted = np.linalg.eigh(np.cov((held - centre).T))[1][:, 0]
        if max_tilt is not None:
            fitted = fitted if fitted @ start > 0 else -fitted
            if np.linalg.norm(fitted - start) > max_tilt:
                return start, offset
        normal, offset = fitted, float(fitted @ centre)
    return normal, offset


def _ransac_normal(points: np.ndarray, pool: np.ndarray, tau: float,
                   rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The normal of the plane holding most of ``points[pool]`` and its inliers (bool)."""
    tri = points[rng.choice(pool, (CANDIDATES, 3))]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normals, axis=1)
    ok = length > 1e-12
    normals = normals[ok] / length[ok, None]
    offsets = (normals * tri[ok, 0]).sum(axis=1)
    scored = points[pool[:4000]]  # the draws' cost is candidates x points
    best = int(np.argmax((np.abs(scored @ normals.T - offsets) < tau).sum(axis=0)))
    inliers = np.zeros(len(points), bool)
    inliers[pool] = np.abs(points[pool] @ normals[best] - offsets[best]) < tau
    normal, _ = _nearer_fit(points[inliers], normals[best], offsets[best], tau)
    return normal, inliers


def main_axes(points: np.ndarray, tau: float, rng: np.random.Generator) -> np.ndarray:
    """(k <= 3, 3) orthonormal directions of the scene's large planes: the normal of the
    plane RANSAC finds first, the next plane's at least 60 deg from it (squared up to
    it), and their cross product (a room's walls, floor and ceiling)."""
    pool = rng.permutation(len(points))
    normals = []
    for _ in range(4):
        if len(pool) < max(MIN_POINTS_SHARE * len(points), 3):
            break
        normal, inliers = _ransac_normal(points, pool, tau, rng)
        if inliers.sum() < MIN_POINTS_SHARE * len(points):
            break
        normals.append(normal)
        pool = pool[~inliers[pool]]
    if not normals:
        return np.zeros((0, 3))
    first = normals[0]
    for other in normals[1:]:
        if abs(other @ first) < 0.5:
            second = other - (other @ first) * first
            second /= np.linalg.norm(second)
            return np.stack([first, second, np.cross(first, second)])
    return first[None]


def _peaks(values: np.ndarray, width: float) -> list[float]:
    """Offsets where ``values`` crowd: local maxima of their histogram (bins ``width``,
    smoothed 1-2-1) over :data:`MIN_POINTS_SHARE` of them and :data:`PEAK_OVER_MEDIAN`
    times the median bin."""
    edges = np.arange(values.min() - width, values.max() + 2 * width, width)
    counts = np.convolve(np.histogram(values, edges)[0], [0.25, 0.5, 0.25], mode="same")
    level = max(MIN_POINTS_SHARE * len(values), PEAK_OVER_MEDIAN * float(np.median(counts)))
    tops = [i for i in range(1, len(counts) - 1) if counts[i] >= level
            and counts[i] >= counts[i - 1] and counts[i] > counts[i + 1]]
    return [float(edges[i] + width / 2) for i in tops]


OWN_TILT = 0.1
"""A plane's own least-squares normal is taken where it leans at most this far (about
6 deg) off its main direction (the main directions are squared up to the first wall's,
so the others inherit its error)."""


def sparse_axes(points: np.ndarray, rng: np.random.Generator) -> np.ndarray | None:
    """(3, 3) the main directions (:func:`main_axes`) of the views' triangulated
    ``points`` (N, 3), where they give all three; else None.

    The start's fill points carry its depth errors: from the photos' uplifted views the
    room's box, found in sparse and fill points together, leaned with them (walls and
    ceiling together), while the sparse points alone give its directions
    (``docs/measurements.md``, session 53)."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    if len(points) < 30:
        return None
    lo, hi = np.percentile(points, 2, axis=0), np.percentile(points, 98, axis=0)
    axes = main_axes(points, INLIER_SHARE * float(np.linalg.norm(hi - lo)), rng)
    return axes if len(axes) == 3 else None


def find_planes(points: np.ndarray, cameras: np.ndarray, rng: np.random.Generator,
                axes: np.ndarray | None = None) -> tuple[list[Plane], float]:
    """The large planes ``points`` lie on (module docstring) and the inlier distance.
    ``cameras``: (V, 3) the views' centres (a plane has them on one side); ``axes``:
    the directions to look along (:func:`sparse_axes`), else the points' own
    (:func:`main_axes`)."""
    points = np.asarray(points, np.float64)
    if len(points) < 30:
        return [], 0.0
    lo, hi = np.percentile(points, 2, axis=0), np.percentile(points, 98, axis=0)
    extent = float(np.linalg.norm(hi - lo))
    tau = INLIER_SHARE * extent
    planes: list[Plane] = []
    hiding: list[tuple[Plane, int]] = []  # refused for what they hide, and their axis
    crowds: dict[int, _Crowds] = {}
    # the sparse points' directions are the room's: a plane does not lean off them
    # towards the fill's smear
    lean = OWN_TILT if axes is None else 0.0
    if axes is None:
        axes = main_axes(points, tau, rng)
    for k, axis in enumerate(axes):
        along = points @ axis
        other = np.eye(3)[int(np.argmin(np.abs(axis)))]  # the world axis least like it
        u = other - (other @ axis) * axis
        u /= np.linalg.norm(u)
        axes = np.stack([u, np.cross(axis, u)])
        for peak in _peaks(along, tau / 2):
            near = np.abs(along - peak) < tau / 2
            offset = float(along[near].mean())
            normal, offset = _nearer_fit(points, axis, offset, tau, lean)
            if any(abs(q.normal @ normal) > 1 - OWN_TILT ** 2 / 2
                   and abs(np.sign(q.normal @ normal) * q.offset - offset) < tau
                   for q in planes):
                continue  # a wall off square crowds at two offsets: one plane
            near = np.abs(points @ normal - offset) < tau / 2
            side = np.sign(cameras @ normal - offset)
            front = 1.0 if (side > 0).sum() >= (side < 0).sum() else -1.0
            if (side == front).mean() < MIN_CAMERAS_IN_FRONT:
                continue  # cameras on both sides: a slice through the room
            uv = points[near] @ axes.T
            p_lo, p_hi = np.percentile(uv, 2, axis=0), np.percentile(uv, 98, axis=0)
            if np.min(p_hi - p_lo) < MIN_SPAN * extent:
                continue  # a strip (a shelf's edge, a row of points): nothing to hold
            within = np.all((points @ axes.T >= p_lo) & (points @ axes.T <= p_hi), axis=1)
            behind = within & (front * (points @ normal - offset) < -REACH * tau)
            plane = Plane(front * normal, front * offset, p_lo, p_hi, axes, int(near.sum()))
            crowds.setdefault(k, _Crowds(axis)).add(plane)
            if behind.sum() > MAX_BEHIND * near.sum():
                hiding.append((plane, k))  # it would hide what the views saw behind it
                continue
            planes.append(plane)
    return planes + _caps(points, planes, hiding, crowds, tau), tau


BOUND_MIN_POINTS = 50
"""A plane that bounds a light's move (:func:`room_box`) holds at least this many of the
initial points... (a fit from 200 points found tilted 8-27-point planes, one 0.4 m under
the ceiling)"""
BOUND_MIN_SHARE = 0.02
"""...and this share of them (a ceiling few photos see holds 2.8-3.3 % of ``fast``'s 4000
on the chain bench's rooms)."""


def room_box(planes: list[Plane], total: int) -> list[Plane]:
    """The planes of ``planes`` (from ``total`` initial points) trusted to bound where a
    light is: a room's box, not whatever the main directions made of a sparse capture.

    A light the photos sink behind a ceiling few of them see is stopped where its ray
    crosses the room's planes (:mod:`.sunk_lights`); a wrong plane there would pull a
    light into the room. So a bound needs two facing walls (opposite normals, the
    cameras between them), each holding :data:`BOUND_MIN_POINTS` and
    :data:`BOUND_MIN_SHARE` of the points; their normal and the direction most of the
    other strong planes square to it agree on make the room's frame, and every strong
    plane along one of its three directions bounds. Without such a pair (a room whose
    main directions came out diagonal, as ``shade:7``'s from photos do) nothing bounds."""
    least = max(BOUND_MIN_POINTS, BOUND_MIN_SHARE * total)
    strong = [p for p in planes if p.points >= least]
    square = 1 - OWN_TILT ** 2 / 2
    for i, first in enumerate(strong):
        for second in strong[i + 1:]:
            if first.normal @ second.normal < -square and first.offset + second.offset < 0:
                return _along_frame(strong, first.normal, square)
    return []


def _along_frame(planes: list[Plane], axis: np.ndarray, square: float) -> list[Plane]:
    """The ``planes`` along ``axis`` or along the frame square to it that most of the
    others agree on (``square``: the least |cos| of two directions taken as one)."""
    def along(a: np.ndarray, b: np.ndarray) -> bool:
        return abs(a @ b) > square

    across = [p for p in planes if abs(p.normal @ axis) < OWN_TILT]
    frame = [axis]
    if across:
        def agreeing(p: Plane) -> tuple[int, int]:
            return (sum(along(p.normal, q.normal) or abs(p.normal @ q.normal) < OWN_TILT
                        for q in across), p.points)
        second = max(across, key=agreeing).normal
        frame += [second, np.cross(axis, second)]
    return [p for p in planes if any(along(p.normal, d) for d in frame)]


UP_TILT = 0.5
"""The cameras' mean up (their image's -y) picks the frame's direction within this |cos|
of it... (phones and tripods are held upright; a room's vertical is its frame's)"""
WALL_TOP_SHARE = 0.95
"""...a wall's top is this quantile of its points along the vertical (a wall's points
reach 5 % short of a plain top, and the ceiling's smear runs past it)..."""
WALL_TOPS_AGREE = 4.0
"""...and the walls' tops agree to within this many inlier distances (0.3 m in a
5 x 4 x 3 m room; 0.19 m on ``panels:7``'s ``balanced`` initial points)."""


def ceiling_from_walls(box: list[Plane], points: np.ndarray, tau: float,
                       up: np.ndarray) -> Plane | None:
    """The ceiling where the walls of a room's ``box`` (:func:`room_box`) stop, when
    the box has none: ``up`` is the cameras' mean up direction.

    A ceiling few photos see is smeared in depth, more so with more initial points:
    ``panels:7``'s from photos spreads from 2.3 to 3.4 m over ``balanced``'s 20,000, a hump
    no offset bin crowds like a plane, so :func:`find_planes` has no ceiling and a panel
    sunk above it is not bounded (it sat 0.18 m over the ceiling). The walls still run up
    to the ceiling and stop there: their points' :data:`WALL_TOP_SHARE` quantile along the
    vertical, where at least two walls agree (:data:`WALL_TOPS_AGREE`), is the ceiling
    (2.99 m there, the ceiling is at 3.0; at the 0.98 quantile the ceiling's own smear
    along the walls put it at 3.19, above the panel's place). The floor is not taken so:
    furniture hides the walls' feet (their lowest points lie 0.4-0.6 m up)."""
    up = np.asarray(up, np.float64)
    norm = np.linalg.norm(up)
    if not box or norm == 0:
        return None
    up = up / norm
    if any(p.normal @ up < -(1 - OWN_TILT ** 2 / 2) for p in box):
        return None  # the box has its ceiling
    walls = [p for p in box if abs(p.normal @ up) < OWN_TILT]
    if len(walls) < 2:
        return None
    # the frame's direction square to the walls' normals, turned to the cameras' up
    stack = np.array([w.normal for w in walls])
    vertical = np.linalg.svd(stack)[2][-1]
    vertical = vertical * np.sign(vertical @ up)
    if vertical @ up < UP_TILT:
        return None
    tops = []
    for wall in walls:
        # its points across its patch, up and down all of them (the patch's own 2-98 %
        # stop short of the top; past its sides lie the ceiling's smear and the corners)
        across = int(np.argmin(np.abs(wall.axes @ vertical)))
        u = points @ wall.axes[across]
        on = ((np.abs(points @ wall.normal - wall.offset) < tau / 2)
              & (u >= wall.lo[across]) & (u <= wall.hi[across]))
        if on.sum() >= BOUND_MIN_POINTS:
            tops.append(float(np.quantile(points[on] @ vertical, WALL_TOP_SHARE)))
    if len(tops) < 2 or max(tops) - min(tops) > WALL_TOPS_AGREE * tau:
        return None
    height = float(np.median(tops))
    other = np.eye(3)[int(np.argmin(np.abs(vertical)))]
    u = other - (other @ vertical) * vertical
    u /= np.linalg.norm(u)
    axes = np.stack([u, np.cross(vertical, u)])
    uv = points @ axes.T
    lo, hi = np.percentile(uv, 2, axis=0), np.percentile(uv, 98, axis=0)
    return Plane(-vertical, -height, lo, hi, axes, 0)


SPARSE_BAND = 3.0
"""A ceiling's triangulated points are those within this many inlier distances of it...
"""
SPARSE_CLEAR = 3.0
"""...and this many from every other plane of the box (a wall's top is no ceiling)..."""
SPARSE_MIN = 8
"""...and their median is the ceiling's height where at least this many are."""


def ceiling_at_sparse_points(box: list[Plane], sparse: np.ndarray, tau: float,
                             up: np.ndarray) -> list[Plane]:
    """``box`` with its ceiling (a plane facing down along ``up``, the cameras' mean up)
    at the median height of the triangulated ``sparse`` points on it, away from the walls.

    The box's planes are found in the start's points, sparse and fill together, and a
    ceiling few photos see is smeared deep in the fill: from photos the ``panels`` rooms'
    fill crowded under the ceiling, and their panels, outlined on that plane and drawn
    there, came out too bright under them (``gaslight2usd bench --suite chain --scene
    panels:2``; ``docs/measurements.md``, session 66), while the sparse points on the
    ceiling itself lay on it. The walls are left as found: photos
    see them square on, and furniture stands in front of them."""
    up = np.asarray(up, np.float64)
    sparse = np.asarray(sparse, np.float64).reshape(-1, 3)
    if not np.linalg.norm(up) or not len(sparse) or not box:
        return box
    up = up / np.linalg.norm(up)
    out = []
    for plane in box:
        if plane.normal @ up > -(1 - OWN_TILT ** 2 / 2):
            out.append(plane)
            continue
        height = sparse @ plane.normal - plane.offset
        uv = sparse @ plane.axes.T
        on = ((np.abs(height) < SPARSE_BAND * tau)
              & np.all((uv >= plane.lo) & (uv <= plane.hi), axis=1))
        for other in box:
            if other is not plane:
                on &= np.abs(sparse @ other.normal - other.offset) > SPARSE_CLEAR * tau
        if on.sum() < SPARSE_MIN:
            out.append(plane)
            continue
        out.append(Plane(plane.normal, float(plane.offset + np.median(height[on])),
                         plane.lo, plane.hi, plane.axes, plane.points))
    return out


FAR_WALL_CROWD = 2.0
"""A room box's missing far wall is the offset where the points beyond the cameras crowd
most, when it crowds at least this many times their median bin and the emptiest bin
between the cameras and it (:func:`far_walls`)..."""
FAR_WALL_SHARE = 0.005
"""...and holds at least this share of all the points."""


def far_walls(box: list[Plane], points: np.ndarray, cameras: np.ndarray, tau: float,
              up: np.ndarray) -> list[Plane]:
    """The walls a room's ``box`` (:func:`room_box`) misses on one side of its walls' main
    directions: ``cameras`` (V, 3) the views' centres, ``up`` their mean up direction.

    A wall with a large window holds few points round the window and hides the window's
    fill behind it, so :func:`find_planes` refuses it (its bin crowds too little,
    :data:`PEAK_OVER_MEDIAN`, or it hides too much, :data:`MAX_BEHIND`), and without it
    the window's floating splats have no plane to go onto (:mod:`.sunk_lights`: the
    chain bench's ``bulb:7`` and ``hall:5`` from photos, ``room_faces_missing``; with a
    dark frame of the window the hall had neither end wall). Beyond the cameras, along a
    main direction with no wall on its far side (the box's walls' normals and the
    direction square to them and the vertical), the points still crowd most at the far
    wall (``bulb:7``: 55 points in its bin against a median of 17; the hall's 37 against
    14, 64 against 20 with the dark frame): that offset, where it crowds
    :data:`FAR_WALL_CROWD` times the median bin and the emptiest bin between the cameras
    and it (furniture just past the cameras crowds the first bins and only thins away
    from them: ``bulb:11`` with dark frames had a wall put 0.7 m inside the room) and
    holds :data:`FAR_WALL_SHARE` of the points, is the far wall, squared to the box (its
    patch the opposite wall's, else the points' spread over it). Only walls; only for the
    box, which bounds where lights may be moved, not for the plane prior. Measured by
    ``gaslight2usd bench --suite chain`` (the probe by the window)."""
    up = np.asarray(up, np.float64)
    norm = float(np.linalg.norm(up))
    if not box or norm == 0 or len(points) < 30:
        return []
    up = up / norm
    square = 1 - OWN_TILT ** 2 / 2
    walls = [p for p in box if abs(p.normal @ up) <= OWN_TILT]
    if not walls:
        return []
    level = [p.normal for p in box if abs(p.normal @ up) >= square]
    vertical = level[0] * np.sign(level[0] @ up) if level else up
    across = np.cross(vertical, walls[0].normal)
    across /= np.linalg.norm(across)
    sides = [(wall.normal, wall) for wall in walls]
    sides += [(sign * across, None) for sign in (1.0, -1.0)
              if not any(abs(w.normal @ across) >= square for w in walls)]
    out = []
    for direction, near in sides:
        if any(p.normal @ direction < -square for p in box + out):
            continue  # the box has a wall on that side
        along = points @ direction  # increasing away from the cameras, across the room
        start = float((cameras @ direction).max()) + 2.0 * tau
        stop = float(np.percentile(along, 99.5)) + tau
        if stop <= start + 4.0 * tau:
            continue
        edges = np.arange(start, stop + tau / 2, tau / 2)
        counts = np.convolve(np.histogram(along, edges)[0], [0.25, 0.5, 0.25], mode="same")
        top = int(np.argmax(counts))
        if (top == 0 or counts[top] < FAR_WALL_CROWD * float(np.median(counts))
                or counts[top] < FAR_WALL_CROWD * float(counts[:top].min())
                or counts[top] < FAR_WALL_SHARE * len(points)):
            continue
        crowd = np.abs(along - (edges[top] + tau / 4)) < tau / 2
        offset = float(along[crowd].mean())
        if near is not None:
            lo, hi, axes = near.lo, near.hi, near.axes
        else:
            axes = np.stack([np.cross(direction, vertical), vertical])
            uv = points @ axes.T
            lo, hi = np.percentile(uv, 2, axis=0), np.percentile(uv, 98, axis=0)
        out.append(Plane(-direction, -offset, lo, hi, axes, int(crowd.sum())))
    return out


class _Crowds:
    """Where the points crowd along one main direction (the planes' offsets along it)."""

    def __init__(self, axis: np.ndarray):
        self.axis = axis
        self.offsets = np.zeros(0)
        self.counts = np.zeros(0, int)

    def add(self, plane: Plane) -> None:
        sign = 1.0 if plane.normal @ self.axis > 0 else -1.0
        self.offsets = np.append(self.offsets, sign * plane.offset)
        self.counts = np.append(self.counts, plane.points)


def _caps(points: np.ndarray, walls: list[Plane], hiding: list[tuple[Plane, int]],
          crowds: dict[int, _Crowds], tau: float) -> list[Plane]:
    """The ceiling (or floor) among the crowds refused for the points they hide.

    The sparse points barely see a plain ceiling: its few points crowd at its height,
    but its fill scatters up to half a metre behind it, more than it holds, so
    :data:`MAX_BEHIND` refuses it as it refuses a table top. The walls tell the two
    apart: they run up to the ceiling and stop there, while they go on past a table
    top. So the outermost crowd on its side of the cameras along a direction square to
    the walls is a plane (square to their own normals) where at
    most :data:`CAP_WALLS_BEYOND` of the walls' points lie beyond it (by more than
    :data:`REACH`), and it crowds at least :data:`CAP_CROWD` of the most any plane does
    along that direction (a floor's few points under furniture crowd no more than a
    table top, and stay unheld)."""
    caps = []
    for plane, k in hiding:
        square = [w for w in walls if abs(w.normal @ plane.normal) < OWN_TILT]
        if not square:
            continue
        crowd = crowds[k]
        sign = 1.0 if plane.normal @ crowd.axis > 0 else -1.0
        beyond = sign * crowd.offsets - plane.offset < -tau  # far side from the cameras
        if beyond.any() or plane.points < CAP_CROWD * crowd.counts.max():
            continue
        # square to the walls' own normals (a ceiling's own fit leans to its smear, and
        # the squared-up main direction inherits the first wall's error)
        stack = np.array([w.normal for w in square])
        _, strength, rows = np.linalg.svd(stack)
        normal = rows[-1] if len(square) > 1 and strength[1] > 0.5 else crowd.axis
        normal = normal * np.sign(normal @ plane.normal)
        offset = plane.offset
        for share in (1.0, 0.5, 0.25):
            near = np.abs(points @ normal - offset) < share * tau
            offset = float((points[near] @ normal).mean()) if near.sum() >= 3 else offset
        plane = Plane(normal, offset, plane.lo, plane.hi, plane.axes, plane.points)
        on_walls = np.zeros(len(points), bool)
        for wall in square:
            uv = points @ wall.axes.T
            on_walls |= ((np.abs(points @ wall.normal - wall.offset) < tau / 2)
                         & np.all((uv >= wall.lo) & (uv <= wall.hi), axis=1))
        past = points[on_walls] @ plane.normal - plane.offset < -REACH * tau
        if on_walls.any() and past.mean() <= CAP_WALLS_BEYOND:
            caps.append(plane)
    return caps


def bright_floaters(points: np.ndarray, lum: np.ndarray, on_plane: np.ndarray,
                    planes: list[Plane], tau: float,
                    keep_out: list[tuple[np.ndarray, float]] | None = None) -> np.ndarray:
    """Per point, the plane whose lit patch it floats in front of (-1: none).

    A window's light seen by every photo against the window lies anywhere in the space
    those photos' window cones share: a uniformly bright patch is photo-consistent at
    any depth there, so the fit leaves clumps of it up to a metre in front of the wall.
    The photos see them over the window, but a probe half a metre from it is inside the
    clumps: they fog its whole view (a dozen splats on the chain bench's ``bulb:7``;
    docs/measurements.md, session 26). Emitters lie on surfaces: a bright point
    (:data:`FLOAT_BRIGHT` x the median of the points ``on_plane``, each one's plane index
    or -1) within :data:`FLOAT_REACH` in front of a plane's patch, over a patch of it
    about as bright (:data:`FLOAT_MATCH`), is taken for that patch's light. ``keep_out``:
    (centre, size) of compact lights the photos' outlines place, whose points are never
    floaters.
    """
    out = np.full(len(points), -1)
    held = on_plane >= 0
    if not held.any() or not planes:
        return out
    cand = (~held) & (lum > FLOAT_BRIGHT * float(np.median(lum[held])))
    for centre, size in keep_out or []:
        cand &= np.linalg.norm(points - centre, axis=1) > KEEP_OUT_SIZES * size
    nearest = np.full(len(points), np.inf)
    for k, plane in enumerate(planes):
        mine = np.flatnonzero(on_plane == k)
        d = points @ plane.normal - plane.offset
        uv = points @ plane.axes.T
        inside = np.all((uv >= plane.lo) & (uv <= plane.hi), axis=1)
        pick = np.flatnonzero(cand & inside & (d > 0) & (d <= FLOAT_REACH * tau)
                              & (d < nearest))
        if not len(pick) or not len(mine):
            continue
        near_count = min(16, len(mine))
        dist, idx = cKDTree(uv[mine]).query(uv[pick], k=near_count,
                                            distance_upper_bound=FLOAT_RADIUS * tau)
        dist, idx = dist.reshape(len(pick), -1), idx.reshape(len(pick), -1)
        under = np.where(np.isfinite(dist), lum[mine][np.minimum(idx, len(mine) - 1)], 0.0)
        lit = under.max(axis=1) >= FLOAT_MATCH * lum[pick]
        out[pick[lit]] = k
        nearest[pick[lit]] = d[pick[lit]]
    return out


class PlanePrior:
    """The planes of :func:`find_planes` and which splats they hold."""

    def __init__(self, planes: list[Plane], tau: float, device: str | torch.device = "cpu"):
        self.planes, self.tau = planes, tau
        f = torch.float32
        self.normals = torch.tensor(np.array([p.normal for p in planes]).reshape(-1, 3),
                                    dtype=f, device=device)
        self.offsets = torch.tensor([p.offset for p in planes], dtype=f, device=device)
        self.member = torch.zeros(0, dtype=torch.long, device=device)
        self.lifted = torch.zeros(0, dtype=torch.long, device=device)
        """Each free splat's plane it is kept in front of (-1: none)."""
        self.floating = torch.zeros(0, dtype=torch.bool, device=device)
        """Bright floaters brought back onto their plane (:func:`bright_floaters`)."""

    def assign(self, means: torch.Tensor, free: torch.Tensor | None = None,
               lum: torch.Tensor | None = None,
               keep_out: list[tuple[np.ndarray, float]] | None = None) -> None:
        """Each splat's plane (-1: none): the nearest whose patch (grown by the reach)
        holds it, within :data:`REACH` in front of it or :data:`REACH_BEHIND` behind.
        Splats marked ``free`` (bool; a light's, whose depth is the lights' machinery's
        to find) are not held; those behind a plane, or less than :data:`LIFT` in
        front, are kept :data:`LIFT` in front of it (drawn over the wall, not hidden
        behind it). With the splats' luminance ``lum``, bright floaters in front of a lit
        patch (:func:`bright_floaters`; ``keep_out`` its compact lights) go onto it:
        held, or, if free, :data:`LIFT` in front of it."""
        n = means.shape[0]
        self.floating = torch.zeros(n, dtype=torch.bool, device=means.device)
        if not self.planes:
            self.member = torch.full((n,), -1, dtype=torch.long, device=means.device)
            self.lifted = self.member.clone()
            return
        x = means.detach().double().cpu().numpy()
        reach = REACH * self.tau
        dist = np.full((n, len(self.planes)), np.inf)
        for k, plane in enumerate(self.planes):
            d = x @ plane.normal - plane.offset  # > 0: the cameras' side
            uv = x @ plane.axes.T
            inside = np.all((uv >= plane.lo - reach) & (uv <= plane.hi + reach), axis=1)
            near = (d < reach) & (d > -REACH_BEHIND * self.tau)
            dist[:, k] = np.where(inside & near, np.abs(d), np.inf)
        best = dist.argmin(axis=1)
        member = np.where(np.isfinite(dist[np.arange(n), best]), best, -1)
        lifted = np.full(n, -1)
        free = np.zeros(n, bool) if free is None else free.detach().cpu().numpy()
        lifted[free] = member[free]
        member[free] = -1
        if lum is not None:
            floats = bright_floaters(x, lum.detach().double().cpu().numpy(),
                                     np.where(member >= 0, member, lifted), self.planes,
                                     self.tau, keep_out)
            on = floats >= 0
            member[on & ~free] = floats[on & ~free]
            lifted[on & free] = floats[on & free]
            self.floating = torch.as_tensor(on, device=means.device)
        self.member = torch.as_tensor(member, dtype=torch.long, device=means.device)
        self.lifted = torch.as_tensor(lifted, dtype=torch.long, device=means.device)

    def held(self) -> int:
        return int((self.member >= 0).sum())

    @torch.no_grad()
    def snap(self, means: torch.Tensor) -> None:
        """Put the held splats back on their planes, and the lifted ones at least
        :data:`LIFT` in front of theirs (floaters brought back: just that) (in place)."""
        for which, gap, at_most in ((self.member, 0.0, False), (self.lifted, LIFT, True)):
            on = which >= 0
            if not bool(on.any()):
                continue
            n = self.normals[which[on]]
            off = (means[on] * n).sum(dim=1) - self.offsets[which[on]] - gap * self.tau
            if at_most and len(self.floating) == len(on):
                off = torch.where(self.floating[on], off, off.clamp(max=0.0))
            elif at_most:
                off = off.clamp(max=0.0)
            means[on] = means[on] - off[:, None] * n

    def flatness(self, quats: torch.Tensor, log_scales: torch.Tensor) -> torch.Tensor:
        """Mean thickness of the held splats along their plane's normal, in inlier
        distances (a disc lying in the plane: 0)."""
        on = self.member >= 0
        if not bool(on.any()):
            return log_scales.sum() * 0.0
        rot = quat_to_rotmat(quats[on])  # columns: the splat's axes
        along = (rot * self.normals[self.member[on]][:, :, None]).sum(dim=1)  # (m, 3)
        thick = torch.sqrt(((torch.exp(log_scales[on]) * along) ** 2).sum(dim=1) + 1e-20)
        return (thick / self.tau).mean()

    def as_dict(self) -> dict:
        return {"planes": [p.as_dict() for p in self.planes],
                "inlier_distance": round(float(self.tau), 5), "splats_held": self.held(),
                "lights_lifted": int((self.lifted >= 0).sum()),
                "floaters_on_planes": int(self.floating.sum())}

    def state_dict(self) -> dict:
        return {"tau": self.tau, "member": self.member.cpu(), "lifted": self.lifted.cpu(),
                "floating": self.floating.cpu(),
                "planes": [asdict(p) for p in self.planes]}

    @classmethod
    def from_state(cls, state: dict, device: str | torch.device = "cpu") -> PlanePrior:
        prior = cls([Plane(**p) for p in state["planes"]], state["tau"], device)
        prior.member = state["member"].to(device)
        prior.lifted = state["lifted"].to(device)
        if "floating" in state:
            prior.floating = state["floating"].to(device)
        return prior
