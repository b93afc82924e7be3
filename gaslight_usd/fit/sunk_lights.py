"""Lights the fit sank behind the surface they are seen through, put back on it.

A light only one photo frames has no parallax: the fit can put its splats anywhere
along that photo's rays, and where the room's surface around it is well fitted (other
photos see that ceiling or wall) it often leaves them behind it. The photo that framed
the light is satisfied, every other view sees the surface in front of them, and from
anywhere inside the room the light is gone: the chain bench's ``panels`` room, fitted
from its photos, had the ceiling panel one photo frames 0.2-0.8 m above the ceiling,
4.3 stops short at the room's middle probe (``docs/measurements.md``, session 17).

The photos still say where it can be. A bright splat (over the white) lying in the cone
of a compact light region of some photo (:mod:`gaslight_usd.sightings`: an outline over
that photo's white, clear of the frame, at most
:data:`gaslight_usd.fit.light_seeds.MAX_CONE_DEG` across) is on that photo's rays. When
it lies outside the captured space (:mod:`gaslight_usd.capture`: the free space the
cameras' median point sees, bounded by the fit's opaque surfaces; the lights finder
calls what is outside backdrop and never a light), it is moved back along that photo's
ray to where the ray leaves the space, the first place there no photo contradicts, its
scales shrunk in proportion so that the photo draws it on the same pixels. (The fit's
depth next to such a light, in the one photo that frames it, is no guide: it is
smeared by the sunk splats themselves.) The move is refused where another training
photo frames the new place: there parallax placed the light (:mod:`.light_seeds` seeds
compact lights two views frame, inside the space), and a bright splat outside the space
on a compact light's rays is something else (the lit ceiling behind a lamp; what a
lampshade hides from the space's one viewpoint, the ``shade`` room). Broad lights
(windows) are not held by a compact outline; nothing here moves them.

``gaslight2usd bench --suite chain --scene panels`` measures what it buys (the panels'
power at the probes, ``light_dist_*``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cameras import PinholeCamera
from ..capture import capture_space
from ..sightings import Sightings
from ..splats import SplatScene
from ..surroundings import splat_sigma
from .light_seeds import MAX_CONE_DEG, framing

RAY_STEPS = 128
"""Samples along a sunk splat's ray where it is tested against the captured space."""


@dataclass
class SurfacedLights:
    """What :func:`surface_sunk_lights` moved."""

    moved: int
    """Splats moved."""
    power_share: float
    """Their share of the bright splats' power (radiance x area x opacity)."""
    mean_move: float
    """Mean distance moved (scene units)."""
    refused: int
    """Sunk splats left where they were: more than one photo frames the new place."""

    def as_dict(self) -> dict:
        return {"moved": self.moved, "power_share": round(self.power_share, 4),
                "mean_move": round(self.mean_move, 4), "refused": self.refused}


def surface_sunk_lights(scene: SplatScene, cameras: list[PinholeCamera], whites: np.ndarray,
                        weights: np.ndarray, sightings: Sightings
                        ) -> tuple[SplatScene, SurfacedLights]:
    """``scene`` with its sunk bright splats moved onto the surface they are seen
    through (module docstring), and what moved. ``cameras``: the training views;
    ``whites`` (V,): each view's white, in the scene's units; ``weights``: luminance
    weights; ``sightings``: the views' light regions
    (:func:`gaslight_usd.sightings.sight_lights`, same views)."""
    lum = scene.base_colours @ np.asarray(weights, np.float32)
    nothing = SurfacedLights(0, 0.0, 0.0, 0)
    compact = np.flatnonzero(sightings.whole
                             & (sightings.radii <= np.radians(MAX_CONE_DEG)))
    bright = np.flatnonzero((lum > float(np.median(whites))) & (scene.opacities > 0.05))
    if not len(bright) or not len(compact) or len(cameras) < 2:
        return scene, nothing
    pos = scene.positions.astype(np.float64)
    # the view whose compact outline holds each bright splat (nearest its axis)
    angle = sightings.angles(pos[bright])[:, compact] / sightings.radii[compact][None]
    nearest = np.argmin(angle, axis=1)
    held = angle[np.arange(len(bright)), nearest] <= 1.0
    best_view = np.where(held, sightings.view[compact][nearest], -1)
    centres = np.array([cam.center for cam in cameras])
    probe = scene.subset(np.arange(scene.count))
    probe.metadata = {**scene.metadata, "exposure_scale": float(np.median(whites))}
    space = capture_space(probe, centres)
    sigma = splat_sigma(scene)
    outside = ~space.inside(pos[bright], reach=2.0 * sigma[bright])
    cand = (best_view >= 0) & outside
    if not cand.any():
        return scene, nothing
    idx = bright[cand]
    eye = centres[best_view[cand]]  # (K, 3)
    t = np.linspace(0.0, 1.0, RAY_STEPS + 1)[1:]
    along = eye[:, None] + (pos[idx] - eye)[:, None, :] * t[None, :, None]  # (K, S, 3)
    # the last sample before the ray first leaves the space, each sample with the reach
    # the lights finder gives a splat (two sigmas) shrunk to its distance there
    reach = 2.0 * sigma[idx][:, None] * t[None]
    inside = space.inside(along.reshape(-1, 3), reach.ravel()).reshape(len(idx), -1)
    first_out = np.argmin(inside, axis=1)
    leaves = inside[:, 0] & ~inside[:, -1]
    if not leaves.any():
        return scene, nothing
    target = eye + (pos[idx] - eye) * t[np.maximum(first_out - 1, 0)][:, None]
    # only where the one photo it is moved along frames the new place: elsewhere the
    # photos' parallax placed the light, and a splat outside the space on its rays is
    # something else (the lit ceiling behind a lamp, or what a shade hides from the
    # space's one viewpoint)
    refused = leaves & (framing(target, cameras, margin=0.0).sum(axis=1) > 1)
    move = leaves & ~refused
    idx_moved = idx[move]
    area = scene.opacities * np.prod(np.sort(scene.scales, axis=1)[:, 1:], axis=1)
    power = lum * area
    out = scene.subset(np.arange(scene.count))
    ratio = (np.linalg.norm(target[move] - eye[move], axis=1)
             / np.maximum(np.linalg.norm(pos[idx_moved] - eye[move], axis=1), 1e-12))
    out.positions[idx_moved] = target[move].astype(out.positions.dtype)
    out.log_scales[idx_moved] = (scene.log_scales[idx_moved]
                                 + np.log(ratio)[:, None]).astype(out.log_scales.dtype)
    report = SurfacedLights(
        moved=int(len(idx_moved)),
        power_share=float(power[idx_moved].sum() / max(power[bright].sum(), 1e-30)),
        mean_move=float(np.linalg.norm(target[move] - pos[idx_moved], axis=1).mean())
        if len(idx_moved) else 0.0,
        refused=int(refused.sum()))
    return out, report
