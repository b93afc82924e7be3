"""The captured space: where the cameras stood and what they saw around them.

A fit puts splats where the photos need them, and some land behind the walls
(depth is uncertain on flat, featureless or bright surfaces, and SfM noise
smears surfaces in depth): on the example about a third of a ``fast`` fit's
splats lie more than 5 cm outside the room. Lights, probes and rig lights
belong inside the set, so the set is taken as the union of the free space each
camera position sees: from every viewpoint (camera centres recorded in the
PLY's ``cameras`` metadata, at most :data:`MAX_VIEWPOINTS` of them; without
them the splats' median point) the visible surface is found per direction
(:mod:`gaslight_usd.surroundings`; surfaces are the opaque splats no brighter
than the photos' white, so lights hide nothing), and a point is inside when some
viewpoint sees it no farther than that surface plus a small reach. Splats outside are
*backdrop*: they may show in panoramas, but they are never lights.

Where the fit found the room's box (its walls, ceiling and floor: the PLY's
``fit_metrics.room_box``, :func:`gaslight_usd.fit.planes.room_box`), a point inside
that box is inside the set too, whatever the viewpoint sees: a floater under the
ceiling, or the least depth of a bin's neighbourhood, otherwise cuts the space short,
and a ceiling panel's splats on the ceiling were backdrop, never a light
(:data:`ROOM_SLACK`). A box of five sides (a plain floor the sparse points miss) is
closed on its sixth where the viewpoint sees the surfaces that way
(:func:`_missing_side`).

Where bright splats make most of what a direction shows (a window, a lit patch of
ceiling) there is no dim surface, and the boundary falls through to whatever lies
behind. The surfaces' *local planes*, fitted around such a hole and carried across it,
are where a light set in a wall or ceiling belongs (:meth:`CaptureSpace.inside`'s
boundaries).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .light_shapes import room_planes
from .splats import SplatScene
from .surroundings import Surroundings, bin_cover, planar_fill, scene_view, splat_sigma

MAX_VIEWPOINTS = 1
"""Viewpoints the space is seen from: the cameras' median point only. More (camera
centres spread through the list) see round occluders, but each sees through the walls'
depth smear at grazing angles: on the example's ``fast`` fit, 16 of them let 9 emitters
more than 5 cm outside the room through where the median point lets 5."""
BOX_QUANTILE = 0.01
"""Inside also means inside the box of the opaque splats' 1-99 percentiles per axis,
widened by :data:`BOX_PAD` of its size each side: a lone floater far behind the floor
can be alone in its direction bins, while a window is the set's extreme on its axis."""
BOX_PAD = 0.1
DEPTH_SLACK = 0.0
"""A point may lie this share of the surface's distance beyond it and still be inside."""
OPAQUE = 0.1
"""Splats fainter than this opacity do not make surfaces (they are haze)."""
SEAL_DEG = 22.5
"""The surfaces' local planes (:attr:`CaptureSpace.planes`) are fitted to the surfaces
within this angle of each direction: three bins of
:data:`gaslight_usd.surroundings.BINS` each side, across a window 1 m wide seen from
2.5 m."""
PLANE_SPREAD = 0.15
"""...and only where those surfaces lie on one plane to this share of their depth (RMS):
a fit's walls scatter 5-15 % in depth; a desk under a window, a corner or a smeared
ceiling is off more (on the chain bench's ``panels`` room, seed 1, a plane through the
smeared ceiling round a panel put the panel back 0.1-0.35 m above the ceiling; without
it, 0.0-0.2 m under)."""
ROOM_SLACK = 0.03
"""A point this share of the captured space's median depth behind a plane of the room's
box is still inside the room (the box's ceiling, where the walls stop, can be a few cm
off the one the panels are set in)."""
ROOM_SIDES = 5
"""The room's box counts only where it closes at least this many of the six sides
round the viewpoint (a floor the photos hardly see may be missing; with fewer, a side
with no plane would let in whatever the percentile box holds beyond it)."""
SIDE_COS = 0.9
"""Two planes close the same side when their inward normals are this close."""
MISSING_SIDE_DEG = 30.0
"""A box with five sides is closed on its sixth where the viewpoint sees the surfaces
within this angle of that side's direction (:func:`_missing_side`)."""


def room_half_spaces(metadata: Mapping[str, Any], viewpoint: np.ndarray
                     ) -> list[tuple[np.ndarray, float]]:
    """The fit's room box (``fit_metrics.room_box``) as inward ``(normal, offset)`` half
    spaces ``normal . x >= offset`` holding ``viewpoint``, or none where the box closes
    fewer than :data:`ROOM_SIDES` sides."""
    planes = [(n, o) for n, o in room_planes(metadata) if float(n @ viewpoint) > o]
    sides: list[np.ndarray] = []
    for normal, _ in planes:
        if all(float(normal @ side) < SIDE_COS for side in sides):
            sides.append(normal)
    return planes if len(sides) >= ROOM_SIDES else []


def camera_centres(metadata: Mapping[str, Any]) -> np.ndarray | None:
    """(M, 3) camera centres a PLY's metadata records (``cameras.centres``), or None."""
    cams = metadata.get("cameras")
    centres = cams.get("centres") if isinstance(cams, Mapping) else None
    try:
        arr = np.asarray(centres, np.float64).reshape(-1, 3)
    except (TypeError, ValueError):
        return None
    arr = arr[np.isfinite(arr).all(1)]
    return arr if len(arr) else None


def fit_backdrop_mask(scene: SplatScene) -> np.ndarray:
    """Splats the fit added as its unseen-surface backdrop (the last ones it wrote)."""
    fit = scene.metadata.get("fit_metrics")
    n = int(fit.get("backdrop_splats") or 0) if isinstance(fit, Mapping) else 0
    mask = np.zeros(scene.count, bool)
    if 0 < n <= scene.count:
        mask[scene.count - n:] = True
    return mask


@dataclass
class CaptureSpace:
    viewpoints: np.ndarray
    """(V, 3) points the space is seen from."""
    views: list[Surroundings]
    box: np.ndarray
    """(2, 3) low and high corners of the opaque splats' percentile box."""
    source: str
    """How the viewpoints were chosen (for reports)."""
    planes: list[np.ndarray] | None = None
    """Per view, (B,) the distance to the local plane of the surfaces carried across the
    bins where bright splats leave a hole in them (:func:`_planes`; ``inf`` elsewhere):
    None unless asked for."""
    room: list[tuple[np.ndarray, float]] = field(default_factory=list)
    """The room box's inward half spaces (:func:`room_half_spaces`); empty: no box."""
    room_slack: float = 0.0
    """How far behind the room's planes a point is still inside (m)."""

    def inside(self, points: np.ndarray, reach: np.ndarray | float = 0.0,
               boundary: str = "open", room: bool = True) -> np.ndarray:
        """(N,) True where some viewpoint sees ``points`` no farther than its boundary.

        ``reach`` (scalar or (N,)) lets a point lie that much beyond the boundary
        (a splat's own extent). ``boundary``: ``open``, the visible dim surfaces (they
        fall through at a window); ``sealed``, the surfaces' local planes across such
        holes (a window closed by its wall; needs ``planes``).
        """
        if boundary not in ("open", "sealed"):
            raise ValueError(f"boundary must be open or sealed, not {boundary!r}")
        if boundary == "sealed" and self.planes is None:
            raise ValueError("a sealed boundary needs capture_space(..., planes=True)")
        points = np.asarray(points, np.float64).reshape(-1, 3)
        reach = np.broadcast_to(np.asarray(reach, np.float64), (len(points),))
        seen = np.zeros(len(points), bool)
        in_box = np.all((points >= self.box[0]) & (points <= self.box[1]), axis=1)
        for k, view in enumerate(self.views):
            depth = view.depth
            if boundary == "sealed":
                depth = np.where(np.isfinite(self.planes[k]), self.planes[k], depth)
            b, r = view.bin_of(points)
            limit = depth[b] * (1.0 + DEPTH_SLACK) + reach
            seen |= r <= limit
        if room and self.room:
            normals = np.array([n for n, _ in self.room])
            offsets = np.array([o for _, o in self.room])
            margin = points @ normals.T - offsets[None] + (reach + self.room_slack)[:, None]
            seen |= np.all(margin >= 0.0, axis=1)
        return seen & in_box

    def median_depth(self) -> float:
        """Median distance from the viewpoints to their visible surfaces (a room's size)."""
        depths = np.concatenate([v.depth[np.isfinite(v.depth)] for v in self.views] or
                                [np.zeros(0)])
        return float(np.median(depths)) if len(depths) else float("nan")


def _pick(points: np.ndarray, count: int) -> np.ndarray:
    """At most ``count`` of ``points``, spread evenly through the list (deterministic)."""
    if len(points) <= count:
        return points
    return points[np.linspace(0, len(points) - 1, count).round().astype(int)]


def capture_space(scene: SplatScene, viewpoints: np.ndarray | None = None,
                  planes: bool = False) -> CaptureSpace:
    """The captured space of ``scene`` (module docstring); ``viewpoints`` override the
    cameras; ``planes``: also the surfaces' local planes (:attr:`CaptureSpace.planes`,
    for the ``sealed`` boundary)."""
    opaque = scene.opacities > OPAQUE
    if viewpoints is None:
        viewpoints = camera_centres(scene.metadata)
        source = f"camera centres ({0 if viewpoints is None else len(viewpoints)})"
    else:
        source = f"given viewpoints ({len(viewpoints)})"
    if viewpoints is None or len(viewpoints) == 0:
        pos = scene.positions[opaque] if opaque.any() else scene.positions
        viewpoints = np.median(pos, axis=0)[None] if len(pos) else np.zeros((1, 3))
        source = "the splats' per-axis median (no camera centres recorded)"
    viewpoints = np.asarray(viewpoints, np.float64).reshape(-1, 3)
    if len(viewpoints) > MAX_VIEWPOINTS:
        viewpoints = (np.median(viewpoints, axis=0)[None] if MAX_VIEWPOINTS == 1
                      else _pick(viewpoints, MAX_VIEWPOINTS))
        source += ", seen from their median point"
    # Surfaces are the dim splats: a lamp does not hide what lies just behind it, and a
    # window's own depth smear does not push the wall out.
    white = float(scene.metadata.get("exposure_scale", 1.0) or 1.0)
    surface = opaque & (scene.base_colours.max(axis=1) <= white)
    views = [scene_view(scene, v, mask=surface if surface.sum() >= 10 else opaque)
             for v in viewpoints]
    local = [_planes(scene, view, opaque & ~surface) for view in views] if planes else None
    pos = scene.positions[opaque] if opaque.sum() >= 10 else scene.positions
    if len(pos):
        box = np.quantile(pos, [BOX_QUANTILE, 1 - BOX_QUANTILE], axis=0).astype(np.float64)
        pad = BOX_PAD * (box[1] - box[0])
        box = np.stack([box[0] - pad, box[1] + pad])
    else:
        box = np.array([[-np.inf] * 3, [np.inf] * 3])
    space = CaptureSpace(viewpoints, views, box, source, local)
    space.room = room_half_spaces(scene.metadata, viewpoints.mean(axis=0))
    missing = _missing_side(space.room, views)
    if missing is not None:
        space.room.append(missing)
    if space.room:
        space.room_slack = ROOM_SLACK * space.median_depth()
        space.source += f", inside the fit's room box ({len(space.room)} planes)"
    return space


def _missing_side(room: list[tuple[np.ndarray, float]], views: list[Surroundings]
                  ) -> tuple[np.ndarray, float] | None:
    """The sixth side of a room box that closes five (a plain floor the sparse points
    miss), as an inward ``(normal, offset)`` half space through the median of the
    visible surfaces the viewpoints see within :data:`MISSING_SIDE_DEG` of its
    direction; None where the box has no side missing or nothing is seen that way.

    Open, that side let in whatever the percentile box holds beyond it: in the sun room
    of the README's capture, the splats of the sunlit patch the fit left under the floor
    were inside the set down to the box's bottom, 1.4 m under the floor, and the sunk
    lights' pass moved them there (:mod:`gaslight_usd.fit.sunk_lights`)."""
    normals = [n for n, _ in room]
    lonely = [n for n in normals if all(float(n @ m) > -SIDE_COS for m in normals)]
    # two planes may close the one side without an opposite (room_half_spaces)
    if len(normals) < 5 or not lonely or any(float(lonely[0] @ n) < SIDE_COS
                                             for n in lonely):
        return None
    inward = -np.asarray(lonely[0], np.float64)  # the missing side lies along -inward
    cos = np.cos(np.radians(MISSING_SIDE_DEG))
    offsets = []
    for view in views:
        toward = (view.directions @ -inward > cos) & np.isfinite(view.depth)
        points = view.point + view.depth[toward, None] * view.directions[toward]
        offsets.append(points @ inward)
    offsets = np.concatenate(offsets) if offsets else np.zeros(0)
    if not len(offsets):
        return None
    return inward, float(np.median(offsets))


def _planes(scene: SplatScene, view: Surroundings, bright: np.ndarray) -> np.ndarray:
    """(B,) ``view``'s distance to the local plane of its surfaces in the bins the
    ``bright`` opaque splats cover more than the dim surfaces do (a window, a lit patch:
    holes in the surfaces), fitted to the other bins within :data:`SEAL_DEG`
    (:func:`gaslight_usd.surroundings.planar_fill`); ``inf`` elsewhere."""
    if view.own_depth is None:
        return np.full(len(view.depth), np.inf)
    sigma = splat_sigma(scene)
    cover = [bin_cover(view.point, scene.positions[m], sigma[m], scene.opacities[m],
                       view.bins) for m in (bright, ~bright & (scene.opacities > OPAQUE))]
    holes = cover[0] > cover[1]
    if not holes.any():
        return np.full(len(view.depth), np.inf)
    # only across the holes: elsewhere the open boundary stands (a ceiling few photos
    # see is smeared deep, and its planes with it: the chain bench's panels room's
    # ceiling splats lie 0.7 m over it at the median)
    return np.where(holes, planar_fill(view.own_depth, view.directions, ~holes, SEAL_DEG,
                                       PLANE_SPREAD), np.inf)


def backdrop_mask(scene: SplatScene, space: CaptureSpace, room: bool = True) -> np.ndarray:
    """(N,) splats outside the captured space (``room``: the room's box counts,
    :meth:`CaptureSpace.inside`), or the fit's own unseen-surface backdrop."""
    outside = ~space.inside(scene.positions, reach=2.0 * splat_sigma(scene), room=room)
    return outside | fit_backdrop_mask(scene)
