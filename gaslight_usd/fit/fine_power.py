"""A measured compact light's power where it is drawn finer than it was fitted.

A bulb a few fitting pixels wide is fitted as a cluster of overlapping splats. Drawn at
the fitting size, the antialiasing filter spreads each small splat over a pixel at a low
opacity, and the cluster's splats add up; drawn finer, each splat is smaller and more
opaque, and those in front hide those behind, so the cluster shows less light than it
did to the fit. A probe, an HDRI or a renderer draws it finer: ``balanced``'s bare bulb
from true HDR views matched its views within 0.05 stops at the fitting size and came out
0.4-0.55 stops short at four times it, and 0.3-0.4 stops short at the probes beside it
(``gaslight2usd bench --suite chain --scene bulb:7 --method "truth HDR" --preset
balanced``; docs/measurements.md).

So each light the views measured (:func:`.light_seeds.measured_light_seeds`) is brightened
until, drawn at :data:`FINE` x the fitting size, the pixels round it in the training views
that frame it hold the light those views measured there, to within
:data:`TOLERANCE_STOPS` (:func:`matched_light`). A
light's colour does not change any splat's opacity, so its share of a pixel is linear in
the factor. A light every view clipped is not touched here: its power is weighed from the
surfaces it lights, with the light drawn fine (:mod:`.power`). One the other views clipped
and a darker frame measured (the README's capture) is matched to that frame
(:func:`measuring_views`): the clipped views bound it only from below, and the fit drew it
over what the frame measured.

The same factor also takes back what the fit's floaters hid. A fit leaves dim, loose
splats in the room, and on the few rays from the cameras to a bulb they hide part of it
(on the hall's bulb from its true HDR views, 10-25 % in the views that framed it); the
fit brightens the bulb to make up, and towards a probe off those rays, which nothing
hides, the bulb comes out that much too bright (0.3-0.4 stops). So each view's window is
drawn without the splats across its sight line to the light farther than
:data:`FRONT_CLEAR_SIZES` of its sizes from it (:func:`in_front`): the light is matched
to its views as the room shows it, not through the fit's floaters, and those splats are
left out of the fit (the views saw the light whole, so the room has nothing there; kept,
they would hide the matched light from the cameras' side). What lies that close round
the light (a shade, the light's own glow) stays. Measured by ``gaslight2usd bench
--suite chain --method "truth HDR"`` (``docs/measurements.md``, session 55).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..cameras import PinholeCamera
from ..render import render
from ..splats import SplatScene
from .power import scaled_sh

FINE = 4
"""How many times finer than the fitting size the light is drawn to find its factor
(the cluster's light converges by then: 3 % between 4 and 8 times on ``bulb:7``)."""
MAX_FACTOR_STOPS = 1.0
"""The factor is kept within this many stops of 1."""
TOLERANCE_STOPS = 0.1
"""Only the part of the factor beyond this is applied: the views' fine drawing and the
probes' disagree by about this much where nothing saturates (``fast``'s bulb from true
HDR: factors of 0.05-0.11 stops where the probes already read it within 0.04), so a
smaller factor is not evidence of a missing power."""
MIN_VIEWS = 2
"""Views that must frame the light whole for a factor (one view's window is one sample of
a cluster's fine drawing: on ``shade:7`` a speck above the shade got the cap from one).
A clipped light a darker frame measured needs only that frame: its clipped outlines in
three or more other views already say it is a light (:func:`.light_seeds.find_light_seeds`),
and the README's capture shoots one such frame per light."""
MIN_SHARE = 0.05
"""A view counts only where the light gives at least this share of its window's light."""
MARGIN_PX = 2
"""Fitting pixels round the light's outline in each view's window."""
FRONT_CLEAR_SIZES = 2.0
"""Splats across a view's sight line to the light, nearer the camera than this many of the
light's sizes from it, are left out of that view's drawing and of the fit (module
docstring). A fixed 0.15 m cleared less (``bulb:11``'s bulb from its true HDR views +0.19
stops at the middle probe where two sizes left +0.12, from +0.23); a shaded lamp's shade
lies within two sizes of its bulb."""


@dataclass
class FinePower:
    """One light's factor and what it was read from."""

    position: np.ndarray
    rows: np.ndarray
    """The light's splats (indices into the scene)."""
    factor: float
    views: int
    cleared: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """Splats in front of it that hid it from its views (indices into the scene), left
    out with :func:`with_fine_power`."""

    def as_dict(self) -> dict[str, Any]:
        return {"position": [round(float(v), 4) for v in self.position],
                "splats": int(len(self.rows)), "views": self.views,
                "factor_stops": round(math.log2(self.factor), 3),
                "floaters_cleared": int(len(self.cleared))}


def _window(cam: PinholeCamera, centre: np.ndarray, size: float
            ) -> tuple[int, int, int, int] | None:
    """(u0, v0, u1, v1) fitting pixels round the light, None unless it lies whole
    inside the frame, in front of the camera."""
    uv, z = cam.project(centre[None])
    if z[0] <= 0:
        return None
    r = int(math.ceil(cam.fx * size / z[0])) + MARGIN_PX
    u, v = int(uv[0, 0]), int(uv[0, 1])
    u0, v0, u1, v1 = u - r, v - r, u + r + 1, v + r + 1
    if u0 < 0 or v0 < 0 or u1 > cam.width or v1 > cam.height:
        return None
    return u0, v0, u1, v1


def measuring_views(centre: np.ndarray, size: float, cameras: list[PinholeCamera],
                    images: list[np.ndarray], floors: list[np.ndarray | None],
                    y_weights: np.ndarray, white: float) -> list[int]:
    """Indices of ``cameras`` that frame a clipped light at ``centre`` whole, clipped
    nothing round it and read it over twice ``white`` (a darker frame shot for it, as
    :func:`.power.light_sighting` calls "measured"): the views its fine drawing is matched
    to when the others clipped it."""
    y = np.asarray(y_weights, np.float32)
    out = []
    for i, (cam, image, floor) in enumerate(zip(cameras, images, floors, strict=True)):
        box = _window(cam, centre, size)
        if box is None:
            continue
        u0, v0, u1, v1 = box
        if floor is not None and bool((floor[v0:v1, u0:u1] > 0).any()):
            continue
        if float((image[v0:v1, u0:u1] @ y).max()) > 2.0 * white:
            out.append(i)
    return out


def _fine_crop(cam: PinholeCamera, box: tuple[int, int, int, int], fine: int) -> PinholeCamera:
    """The camera of ``box`` (fitting pixels) drawn ``fine`` times finer."""
    u0, v0, u1, v1 = box
    return PinholeCamera((u1 - u0) * fine, (v1 - v0) * fine, cam.fx * fine, cam.fy * fine,
                         (cam.cx - u0) * fine, (cam.cy - v0) * fine, cam.R, cam.t,
                         name=cam.name)


def in_front(scene: SplatScene, eye: np.ndarray, centre: np.ndarray, size: float,
             clear: float) -> np.ndarray:
    """(N,) splats across the sight line from ``eye`` to a light at ``centre`` (their
    3-sigma reach comes within ``size`` of it) and more than ``clear`` nearer ``eye``."""
    eye, centre = np.asarray(eye, np.float64), np.asarray(centre, np.float64)
    axis = centre - eye
    length = float(np.linalg.norm(axis))
    axis /= max(length, 1e-12)
    rel = scene.positions.astype(np.float64) - eye
    along = rel @ axis
    off = np.linalg.norm(rel - along[:, None] * axis, axis=1)
    return (along > 0) & (along < length - clear) & (off <= 3.0 * scene.scales.max(axis=1)
                                                      + size)


def matched_light(scene: SplatScene, rows: np.ndarray, centre: np.ndarray, size: float,
                  cameras: list[PinholeCamera], images: list[np.ndarray],
                  y_weights: np.ndarray, fine: int = FINE,
                  tolerance: float = TOLERANCE_STOPS, keep: np.ndarray | None = None,
                  min_views: int = MIN_VIEWS) -> tuple[float, int, np.ndarray]:
    """(factor, views, cleared): what the splats ``rows`` (a light at ``centre``, ``size``
    its radius) must be brightened by so that, drawn ``fine`` x finer without the splats
    in front of it (:func:`in_front`, :data:`FRONT_CLEAR_SIZES`), the windows round it in
    ``cameras`` hold what ``images`` (their views at fitting size) measured there; the
    median over the views that frame it whole, less :data:`TOLERANCE_STOPS` (1.0 and 0
    views where fewer than ``min_views`` do); and the indices of the splats left out
    in front of it in the views that counted (none without a factor). ``keep``: (N,)
    splats never left out (the room's walls, which a light flush with one is seen along;
    other lights); all of them keeps every splat, the matching as it was before floaters
    were cleared."""
    y = np.asarray(y_weights, np.float32)
    is_light = np.zeros(scene.count, bool)
    is_light[rows] = True
    is_light_or_kept = is_light if keep is None else is_light | keep
    factors, cleared = [], np.zeros(scene.count, bool)
    for cam, image in zip(cameras, images, strict=True):
        box = _window(cam, centre, size)
        if box is None:
            continue
        u0, v0, u1, v1 = box
        measured = float((image[v0:v1, u0:u1] @ y).sum())
        crop = _fine_crop(cam, box, fine)
        front = (in_front(scene, cam.center, centre, size, FRONT_CLEAR_SIZES * size)
                 & ~is_light_or_kept)
        drawn = float((render(scene.subset(~front), crop).image.numpy() @ y).sum()) / fine**2
        without = float((render(scene.subset(~front & ~is_light), crop).image.numpy() @ y
                         ).sum()) / fine**2
        shown = drawn - without
        if shown <= MIN_SHARE * max(drawn, 1e-30):
            continue
        factors.append(1.0 + (measured - drawn) / shown)
        cleared |= front
    if len(factors) < min_views:
        return 1.0, 0, np.zeros(0, np.int64)
    stops = math.log2(max(float(np.median(factors)), 2.0**-MAX_FACTOR_STOPS))
    stops = math.copysign(min(max(abs(stops) - tolerance, 0.0), MAX_FACTOR_STOPS), stops)
    return 2.0**stops, len(factors), np.flatnonzero(cleared)


def _cleared(count: int, lights: list[FinePower]) -> np.ndarray:
    """(count,) the splats :func:`with_fine_power` leaves out of a scene of ``count``."""
    drop = np.zeros(count, bool)
    for light in lights:
        if light.views and len(light.rows):
            drop[light.cleared] = True
    return drop


def with_fine_power(scene: SplatScene, lights: list[FinePower]) -> SplatScene:
    """``scene`` with each light's splats brightened by its factor and the splats cleared
    from in front of it left out (they hid it from its views; the room has nothing there)."""
    sh = scene.sh.copy()
    for light in lights:
        if light.views and len(light.rows):
            sh[light.rows] = scaled_sh(scene.sh[light.rows], light.factor)
    drop = _cleared(scene.count, lights)
    out = replace(scene, sh=sh, metadata=dict(scene.metadata))
    return out.subset(np.flatnonzero(~drop)) if drop.any() else out


def rows_after(lights: list[FinePower], count: int) -> list[np.ndarray]:
    """Each light's rows in the scene :func:`with_fine_power` returns, from a scene of
    ``count`` splats (its rows are the scene's before the clearing)."""
    drop = _cleared(count, lights)
    new_index = np.cumsum(~drop) - 1
    return [new_index[light.rows[~drop[light.rows]]] for light in lights]
