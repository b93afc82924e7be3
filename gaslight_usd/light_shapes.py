"""Which of the set's lights are flat panels in a wall or ceiling, and their rectangles.

A window, a skylight or a ceiling panel is a rectangle in the room's wall or
ceiling that emits into the room; a TD expects it as a ``UsdLux.RectLight`` there,
not as a sphere floating in front of it (the rig, :mod:`gaslight_usd.usd.rig`). The
fit knows the room's planes (``fit_metrics.room_box``, :func:`gaslight_usd.fit.planes.room_box`:
normals towards the cameras), so a light (:class:`gaslight_usd.lights.Light`) is a
panel when

* its centre lies within :data:`ON_PLANE_SHARE` of the captured space's median depth
  of one of those planes, and
* its splats spread off that plane by at most :data:`FLAT_RATIO` of their larger
  spread within it (a bulb hung by a wall is round, not flat).

Its rectangle lies in the plane (nudged :data:`NUDGE_SHARE` of the median depth into
the room, so it is not coplanar with a wall mesh of the set), its sides along the room's
other planes where one is square to it (windows and panels are set square to their
walls), its half-sizes the light's spread along them (a uniform box of the splats'
spread, as :attr:`Light.extent <gaslight_usd.lights.Light.extent>`). Sets without a
room box (a fit that found no two facing walls) keep every light round.

Where the views outlined a lit rectangle on the light's plane
(:mod:`gaslight_usd.flat_outlines`), that rectangle is the panel's, flat splats or not,
and holds a light the fit left up to :data:`OUTLINED_OFF_SHARE` in front of the plane:
the splats' spread is not a window's size, the photos' clipped outline is.

``gaslight2usd bench --suite chain`` (``rig_irradiance_psnr``, ``rect_iou_<light>``)
measures what writing panels as rectangles does to the rig's light at the probes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .flat_outlines import SQUARE_COS, Outline, side_axis

ON_PLANE_SHARE = 0.05
"""A panel's centre lies within this share of the captured space's median depth of its
plane: a window or panel the fit found sits in its plane to a few centimetres, a hanging
bulb a good share of the room's height away (docs/measurements.md, session 48)."""
OUTLINED_OFF_SHARE = 0.35
"""A light this far off a plane (share of the median depth) is that plane's panel where an
outline there holds it (:func:`panel_of`): a fit can leave a window's light that far in
front of it (``gaslight2usd bench --suite chain``, ``rect_iou_<light>``;
``docs/measurements.md``, session 49)."""
FLAT_RATIO = 0.75
"""A panel's spread off its plane is at most this share of its larger spread in it."""
NUDGE_SHARE = 0.005
"""The rectangle sits this share of the median depth in front of its plane."""


@dataclass
class Panel:
    """A flat light's rectangle: ``centre + s * half_size[0] * u + t * half_size[1] * v``
    for s, t in [-1, 1], emitting towards ``normal`` (into the room)."""

    centre: np.ndarray
    normal: np.ndarray
    u: np.ndarray
    v: np.ndarray
    """``u x v = -normal``: a ``UsdLux.RectLight``'s X, Y (it emits along its -Z)."""
    half_size: np.ndarray
    plane_offset: float
    """How far the light's centre was from its plane (before it was put on it)."""
    outlined: bool = False
    """The rectangle is one the views outlined (:mod:`gaslight_usd.flat_outlines`), not
    the splats' spread."""
    single_view: bool = False
    """...by one view alone (:attr:`gaslight_usd.flat_outlines.Outline.single_view`)."""
    measured_sides: int = 0
    """...with this many sides where a view that measured the light sees it end
    (:attr:`gaslight_usd.flat_outlines.Outline.measured_sides`)."""

    @property
    def area(self) -> float:
        return float(4.0 * self.half_size[0] * self.half_size[1])

    def corners(self) -> np.ndarray:
        """(4, 3) corners, counter-clockwise seen from the front."""
        hu, hv = self.half_size[0] * self.u, self.half_size[1] * self.v
        return np.stack([self.centre - hu - hv, self.centre - hu + hv,
                         self.centre + hu + hv, self.centre + hu - hv])

    def as_dict(self) -> dict[str, Any]:
        return {"centre": [round(float(x), 5) for x in self.centre],
                "normal": [round(float(x), 5) for x in self.normal],
                "width": round(float(2 * self.half_size[0]), 5),
                "height": round(float(2 * self.half_size[1]), 5),
                "plane_offset": round(self.plane_offset, 5)}


def room_planes(metadata: Mapping[str, Any]) -> list[tuple[np.ndarray, float]]:
    """(unit normal towards the cameras, offset = normal . x) of the fit's room box."""
    fit = metadata.get("fit_metrics")
    box = fit.get("room_box") if isinstance(fit, Mapping) else None
    planes = []
    for plane in box or []:
        normal = np.asarray(plane.get("normal", ()), np.float64)
        if normal.shape != (3,) or not np.all(np.isfinite(normal)):
            continue
        length = float(np.linalg.norm(normal))
        if length > 0 and np.isfinite(float(plane.get("offset", np.nan))):
            planes.append((normal / length, float(plane["offset"]) / length))
    return planes


def _spread(extent: np.ndarray, axes: np.ndarray, direction: np.ndarray) -> float:
    """Half-size of the light's uniform box along ``direction``."""
    return float(np.sqrt(((extent * (axes @ direction)) ** 2).sum()))


def panel_of(position: np.ndarray, extent: np.ndarray, axes: np.ndarray,
             planes: Sequence[tuple[np.ndarray, float]], median_depth: float,
             outlines: Sequence[Outline] = (), compact: np.ndarray | None = None
             ) -> Panel | None:
    """The light's rectangle in a room plane, or None when it is not a flat panel there.

    ``position``, ``extent`` and ``axes``: the light's centre, half-sizes and their
    directions (rows), as :class:`gaslight_usd.lights.Light` holds them. ``outlines``:
    the rectangles the views saw lit on the room's planes (:mod:`gaslight_usd.flat_outlines`):
    one on the light's plane that holds its centre is its rectangle, flat or not, and
    holds it up to :data:`OUTLINED_OFF_SHARE` off the plane (a window's light the fit
    left floating in front of it) unless the photos outlined a compact light there
    (``compact`` (K, 4) centres and sizes, :func:`gaslight_usd.lights.outlined_lights`:
    a lamp hanging in front of a window is a lamp)."""
    if not planes or not np.isfinite(median_depth) or median_depth <= 0:
        return None
    position = np.asarray(position, np.float64)
    extent, axes = np.asarray(extent, np.float64), np.asarray(axes, np.float64)
    offsets = np.array([normal @ position - offset for normal, offset in planes])
    k = int(np.argmin(np.abs(offsets)))
    normal = planes[k][0]
    on_plane = abs(offsets[k]) <= ON_PLANE_SHARE * median_depth
    if on_plane or (abs(offsets[k]) <= OUTLINED_OFF_SHARE * median_depth
                    and not _near_compact(position, compact, ON_PLANE_SHARE * median_depth)):
        outline = _holding_outline(position, normal, planes[k][1], outlines,
                                   ON_PLANE_SHARE * median_depth, on_plane)
        if outline is not None:
            return outlined_panel(outline, median_depth, float(offsets[k]))
    if not on_plane:
        return None
    # no square plane: the light's own longest direction in the plane
    longest = axes[int(np.argmax(np.linalg.norm(axes - np.outer(axes @ normal, normal),
                                                axis=1) * extent))]
    u = side_axis(normal, [m for m, _ in planes], longest)
    v = np.cross(u, normal)
    half = np.array([_spread(extent, axes, u), _spread(extent, axes, v)])
    if _spread(extent, axes, normal) > FLAT_RATIO * half.max() or half.min() <= 0:
        return None
    centre = position - offsets[k] * normal + NUDGE_SHARE * median_depth * normal
    return Panel(centre=centre, normal=normal.copy(), u=u, v=v, half_size=half,
                 plane_offset=float(offsets[k]))


def outlined_panel(outline: Outline, median_depth: float, plane_offset: float = 0.0) -> Panel:
    """The panel an outline gives: its rectangle, nudged off its plane as every panel is
    (``plane_offset``: how far the light it was found for was from the plane)."""
    normal = np.asarray(outline.normal, np.float64)
    return Panel(centre=outline.centre + NUDGE_SHARE * median_depth * normal,
                 normal=normal.copy(), u=outline.u.copy(), v=np.cross(outline.u, normal),
                 half_size=outline.half_size.copy(), plane_offset=plane_offset, outlined=True,
                 single_view=outline.single_view, measured_sides=outline.measured_sides)


def drawn_on_outline(positions: np.ndarray, power: np.ndarray, outline: Outline,
                     median_depth: float) -> bool:
    """Whether the splats at ``positions`` (N, 3) that carry ``power`` (N,; 0 for those
    that are no light's) over ``outline``'s rectangle, up to :data:`OUTLINED_OFF_SHARE`
    in front of its plane, lie on the plane: their power-weighted median distance to it
    within :data:`ON_PLANE_SHARE` (shares of ``median_depth``). What one view outlined
    is a light on the plane only where the fit drew one there (:class:`Outline`)."""
    rel = np.asarray(positions, np.float64) - outline.centre
    off = rel @ outline.normal
    over = ((np.abs(rel @ outline.u) <= outline.half_size[0])
            & (np.abs(rel @ outline.v) <= outline.half_size[1])
            & (off >= -ON_PLANE_SHARE * median_depth)
            & (off <= OUTLINED_OFF_SHARE * median_depth) & (np.asarray(power) > 0))
    if not over.any():
        return False
    order = np.argsort(np.abs(off[over]))
    weights = np.cumsum(np.asarray(power, np.float64)[over][order])
    median = float(np.abs(off[over])[order][np.searchsorted(weights, weights[-1] / 2.0)])
    return median <= ON_PLANE_SHARE * median_depth


def _near_compact(position: np.ndarray, compact: np.ndarray | None, reach: float) -> bool:
    """Whether ``position`` lies within twice a compact outlined light's size (or
    ``reach``) of its centre."""
    if compact is None or not len(compact):
        return False
    compact = np.asarray(compact, np.float64).reshape(-1, 4)
    gap = np.linalg.norm(compact[:, :3] - position, axis=1)
    return bool(np.any(gap <= np.maximum(2.0 * compact[:, 3], reach)))


def _holding_outline(position: np.ndarray, normal: np.ndarray, offset: float,
                     outlines: Sequence[Outline], tolerance: float, on_plane: bool = True
                     ) -> Outline | None:
    """The clean outline (one that fills its rectangle) with the most lit cells on the
    plane (``normal``, ``offset``) that holds ``position`` within ``tolerance``; None when
    none does. One that one view alone outlined holds only a light ``on_plane``: one view
    outlines a lamp in front of a wall on the wall all the same."""
    held = [o for o in outlines
            if o.clean and (on_plane or not o.single_view)
            and float(o.normal @ normal) > 1.0 - SQUARE_COS ** 2 / 2
            and abs(float(o.normal @ o.centre) - offset) <= tolerance
            and o.holds(position, tolerance)]
    return max(held, key=lambda o: o.cells) if held else None


def solid_angle(corners: np.ndarray, point: np.ndarray) -> float:
    """Solid angle (sr) of the planar quadrilateral ``corners`` (4, 3) seen from ``point``:
    two triangles, each by Van Oosterom and Strackee's formula."""
    rel = np.asarray(corners, np.float64) - np.asarray(point, np.float64)
    total = 0.0
    for a, b, c in ((rel[0], rel[1], rel[2]), (rel[0], rel[2], rel[3])):
        la, lb, lc = np.linalg.norm(a), np.linalg.norm(b), np.linalg.norm(c)
        num = abs(float(a @ np.cross(b, c)))
        den = la * lb * lc + (a @ b) * lc + (a @ c) * lb + (b @ c) * la
        total += 2.0 * float(np.arctan2(num, den))
    return total
