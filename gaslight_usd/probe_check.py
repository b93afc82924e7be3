"""Is a probe point where its HDRI can be trusted? Four checks, each a one-line warning.

* **Outside the set.** A typo in ``--at`` (a sign, a unit: 135 for 1.35) still
  renders an HDRI, of the set seen from afar: nearly black, or one bright blob. The
  point is judged against the box holding the central 96 % of the splats on each axis
  (far backdrop splats do not widen it); a point further outside that box than a
  quarter of its diagonal is reported.
* **Inside a light's reach.** A flat featureless light (a window, a panel) fits at any
  depth along the rays that see it, and a fit leaves some of its splats floating in
  front of it: harmless from the cameras, but a probe among them sees them close up
  and its HDRI comes out stops too bright. A point closer to a light's centre than
  :data:`NEAR_LIGHT_RADII` of its radii is reported.
* **Inside the splats.** A fit can leave splats floating in the open (a flat light's
  featureless face fits any depth along the rays that see it), and a probe placed among
  them sees them from inside, spread over its whole view: its HDRI is washed out or
  darkened everywhere, not only towards a light. The opacity the splats lay on the point
  itself (:func:`inside_alpha`) over :data:`INSIDE_ALPHA` is reported.
* **A light seen from where no photo saw it.** The splats hold what the photos showed of
  a light; from a side no photo looked at, its power is the fit's guess (a lamp in a
  shade, photographed from the side, shows the probe under it a bright opening no photo
  saw). Per light, the smallest angle at the light between the point and a photo that
  saw it (a light region of that photo holds it, :mod:`gaslight_usd.sightings`) is
  reported in the stage's metadata, and a point more than :data:`UNSEEN_LIGHT_DEG` from
  every such photo is warned about.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .cameras import quaternion_to_matrix
from .sightings import Sightings
from .splats import SplatScene

CENTRAL_SHARE = 0.96
FAR_FRACTION = 0.25
NEAR_LIGHT_RADII = 1.5
"""A probe closer than this many of a light's radii to its centre is warned about: on a
room never tuned on, the chain bench's probe by the window lies inside this reach of the
fitted window and its irradiance is far off even from true HDR views, while its probes
further out and the bundled example's (all well outside it) are not (``gaslight2usd bench
--suite chain --scene panels``; figures in docs/measurements.md)."""


INSIDE_ALPHA = 0.1
"""A probe on which the fit's splats lay this much opacity or more is warned about: a
fit from true HDR views of the chain bench's shaded-lamp room leaves window-bright splats
floating round its probe by the window, stops too bright, where the probes of its other
rooms lie among none (``gaslight2usd bench --suite chain``, its ``inside_alpha`` column;
figures in docs/measurements.md, session 44)."""
INSIDE_SIGMAS = 3.0
"""Splats farther than this many of their sigmas from the point lay nothing on it."""


UNSEEN_LIGHT_DEG = 30.0
"""A probe that sees a light from further than this (degrees, at the light) from every
photo that saw it is warned about. On the chain bench's rooms fitted from their true
HDR views (no level to guess: what is left is the fit's shape) the lights' power errors
at the probes grow several-fold past it, most for a lamp in a shade photographed from
the side and seen from below (``gaslight2usd bench --suite chain``, its
``unseen_deg_<light>`` columns beside ``power_err_<light>``; figures in
docs/measurements.md, session 37)."""


def unseen_angles(point: Sequence[float], positions: np.ndarray,
                  sightings: Sightings | None) -> np.ndarray:
    """``(L,)`` per light at ``positions`` ``(L, 3)``: the smallest angle (degrees), at
    the light, between ``point`` and a camera whose photo saw light over the white there
    (one of its ``sightings``' regions holds the light); NaN where none did or nothing
    is known of the photos (``sightings`` None)."""
    positions = np.asarray(positions, np.float64).reshape(-1, 3)
    out = np.full(len(positions), np.nan)
    if sightings is None or not sightings.count or not len(positions):
        return out
    p = np.asarray(point, np.float64)
    held = sightings.holding(positions)  # (L, R)
    to_point = p[None] - positions
    to_point /= np.maximum(np.linalg.norm(to_point, axis=1, keepdims=True), 1e-12)
    to_cams = sightings.origins[sightings.view][None] - positions[:, None]  # (L, R, 3)
    to_cams /= np.maximum(np.linalg.norm(to_cams, axis=2, keepdims=True), 1e-12)
    cos = np.where(held, np.einsum("lrk,lk->lr", to_cams, to_point), -np.inf)
    best = cos.max(axis=1)
    seen = np.isfinite(best)
    out[seen] = np.degrees(np.arccos(np.clip(best[seen], -1.0, 1.0)))
    return out


def unseen_light_warning(point: Sequence[float], lights: Sequence,
                         sightings: Sightings | None) -> str | None:
    """A one-line warning when ``point`` sees one of ``lights`` (objects with
    ``position``) from more than :data:`UNSEEN_LIGHT_DEG` off every photo that saw it,
    naming the worst; else None."""
    if not lights:
        return None
    angles = unseen_angles(point, np.array([light.position for light in lights]), sightings)
    if not np.any(angles > UNSEEN_LIGHT_DEG):
        return None
    worst = int(np.nanargmax(angles))
    where = ",".join(f"{v:.4g}" for v in np.asarray(point, np.float64))
    centre = ", ".join(f"{v:.3g}" for v in lights[worst].position)
    return (f"probe point {where} sees a light (centre {centre}) from {angles[worst]:.0f} "
            "degrees off every photo that saw it: its power there is the fit's guess, not "
            "a measurement (a shade's opening, a panel's face seen from a side no photo "
            "took); photograph the light from near the probe")


def inside_alpha(point: Sequence[float], scene: SplatScene) -> float:
    """The opacity ``scene``'s splats lay on ``point`` itself: ``1 - prod(1 - o_i
    exp(-m_i^2 / 2))``, ``m_i`` the point's Mahalanobis distance from splat ``i`` (its
    scales and rotation), over the splats within :data:`INSIDE_SIGMAS` of it."""
    p = np.asarray(point, np.float64)
    offset = scene.positions.astype(np.float64) - p
    reach = INSIDE_SIGMAS * scene.scales.max(axis=1)
    near = np.flatnonzero(np.einsum("ij,ij->i", offset, offset) < reach * reach)
    if not len(near):
        return 0.0
    rot = quaternion_to_matrix(scene.rotations[near])  # local -> world
    local = np.einsum("nji,nj->ni", rot, offset[near]) / scene.scales[near]
    m2 = np.einsum("ij,ij->i", local, local)
    alpha = scene.opacities[near] * np.exp(-0.5 * m2) * (m2 < INSIDE_SIGMAS ** 2)
    return float(1.0 - np.prod(1.0 - np.clip(alpha, 0.0, 1.0)))


def inside_warning(point: Sequence[float], scene: SplatScene) -> str | None:
    """A one-line warning when the splats lay :data:`INSIDE_ALPHA` or more opacity on
    ``point`` (:func:`inside_alpha`), else None."""
    alpha = inside_alpha(point, scene)
    if alpha < INSIDE_ALPHA:
        return None
    where = ",".join(f"{v:.4g}" for v in np.asarray(point, np.float64))
    return (f"probe point {where} lies inside the fit's splats (they lay opacity "
            f"{alpha:.2f} on it): its HDRI sees them from within, spread over its whole "
            "view; move the probe a little, or look for splats floating there in the PLY")


def splat_box(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Low and high corners of the box holding the central share of the positions."""
    tail = (1.0 - CENTRAL_SHARE) / 2.0
    lo, hi = np.quantile(np.asarray(positions, np.float64), [tail, 1.0 - tail], axis=0)
    return lo, hi


def outside_warning(point: Sequence[float], positions: np.ndarray) -> str | None:
    """A one-line warning when ``point`` lies far outside the splats, else None."""
    if len(positions) == 0:
        return None
    lo, hi = splat_box(positions)
    p = np.asarray(point, np.float64)
    gap = float(np.linalg.norm(np.maximum(lo - p, 0.0) + np.maximum(p - hi, 0.0)))
    diagonal = float(np.linalg.norm(hi - lo))
    if gap <= FAR_FRACTION * max(diagonal, 1e-9):
        return None
    span = ", ".join(f"{axis} {a:.3g}..{b:.3g}" for axis, a, b in zip("xyz", lo, hi,
                                                                      strict=True))
    where = ",".join(f"{v:.4g}" for v in p)
    return (f"probe point {where} lies {gap:.3g} units outside the splats (most lie within "
            f"{span}): its HDRI sees the set from outside")


def near_light_warning(point: Sequence[float], lights: Sequence) -> str | None:
    """A one-line warning when ``point`` lies within :data:`NEAR_LIGHT_RADII` radii of one
    of ``lights`` (objects with ``position`` (3,) and ``radius``, e.g.
    :class:`gaslight_usd.lights.Light`), naming the nearest in radii; else None."""
    p = np.asarray(point, np.float64)
    near = [(float(np.linalg.norm(p - np.asarray(light.position, np.float64)))
             / max(float(light.radius), 1e-9), light) for light in lights]
    near = [(r, light) for r, light in near if r < NEAR_LIGHT_RADII]
    if not near:
        return None
    radii, light = min(near, key=lambda t: t[0])
    where = ",".join(f"{v:.4g}" for v in p)
    centre = ", ".join(f"{v:.3g}" for v in light.position)
    return (f"probe point {where} lies {radii:.2g} radii from a light (centre {centre}, "
            f"radius {light.radius:.3g}): a flat light's splats float in front of it and a "
            "probe this close sees them large, so its HDRI can be stops too bright; put "
            f"probes at least {NEAR_LIGHT_RADII:g} radii from the lights")
