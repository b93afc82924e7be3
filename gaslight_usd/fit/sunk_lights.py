"""Light the fit left off the room's surfaces, put back on them along the photos' rays.

A light's depth comes from parallax, and a fit gets it wrong two ways. A light only one
photo frames can sit anywhere along that photo's rays; where the room around it is well
fitted, the fit often leaves it behind the ceiling or wall: the chain bench's ``panels``
room, fitted from its photos, had the ceiling panel one photo frames 0.2-0.8 m above the
ceiling, where the lights finder calls it backdrop, 4.3 stops short at the room's middle
probe (``docs/measurements.md``, session 17). A broad, even light (a window) is
consistent with the photos at many depths, and a fit smears some of it along the rays
into the room: the ``bulb`` room's window left bright splats 0.2-0.7 m in front of it,
around the probe 0.5 m from the window (irradiance PSNR there -3.9 dB).

The photos say where such light can be. A bright splat (over the white) lying in the
cone of a light region of some photo (:mod:`gaslight_usd.sightings`: an outline over
that photo's white) is on that photo's rays, and the first place along them no photo
contradicts is the room's boundary: where the ray leaves the captured space
(:mod:`gaslight_usd.capture`, the free space the cameras' median point sees, bounded by
the fit's opaque surfaces; the lights finder calls what is outside it backdrop). Two
cases are moved there, shrunk or grown in proportion so that the photo draws them on the
same pixels:

- a splat held by a **compact** outline (whole, at most
  :data:`gaslight_usd.fit.light_seeds.MAX_CONE_DEG` across) and outside the space:
  sunk. (A compact light inside the space may hang in the room, a lamp: it stays.)
- a splat held only by **broad** outlines, inside the space and short of the ray's exit
  by more than :data:`FLOAT_SHARE`: floating. Broad lights are windows, skylights and
  large panels, set in the room's boundary.

A move is refused where another training view would see the new place unoccluded and
its photo saw no light there (a light in another room seen through a gap, a broad lamp
hanging in the room, stay where the photos put them). The fit's own depth next to such a
light is no guide: it is smeared by the misplaced splats themselves.

``gaslight2usd bench --suite chain --scene panels --scene bulb`` measures what it buys
(the lights' power at the probes, ``light_dist_*``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cameras import PinholeCamera
from ..capture import capture_space
from ..sightings import Sightings
from ..splats import SplatScene
from ..surroundings import splat_sigma
from .light_seeds import MAX_CONE_DEG
from .power import depth_map

RAY_STEPS = 128
"""Samples along a light splat's ray where it is tested against the captured space."""
FLOAT_SHARE = 0.1
"""A broad light's splat nearer than its ray's exit from the captured space by more than
this share of the exit's distance floats in the room (smeared along the rays)."""
OCCLUDED_SHARE = 0.05
"""Another view's depth this share nearer than the moved splat hides it from that view."""


@dataclass
class SurfacedLights:
    """What :func:`surface_sunk_lights` moved (sunk and floating splats together)."""

    moved: int
    """Splats moved."""
    power_share: float
    """Their share of the bright splats' power (radiance x area x opacity)."""
    mean_move: float
    """Mean distance moved (scene units)."""
    refused: int
    """Sunk splats left where they were: another view saw no light at the new place."""

    def as_dict(self) -> dict:
        return {"moved": self.moved, "power_share": round(self.power_share, 4),
                "mean_move": round(self.mean_move, 4), "refused": self.refused}


def _pixels(cam: PinholeCamera, points: np.ndarray, shape: tuple[int, ...]
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Row, column (clipped to the image), depth and whether inside, for ``points``
    in ``cam`` drawn at ``shape``."""
    uv, z = cam.project(points)
    h, w = shape[:2]
    x = np.floor(uv[:, 0] * w / cam.width)
    y = np.floor(uv[:, 1] * h / cam.height)
    inside = (z > 0) & (x >= 0) & (x < w) & (y >= 0) & (y < h)
    return (np.clip(np.nan_to_num(y), 0, h - 1).astype(np.int64),
            np.clip(np.nan_to_num(x), 0, w - 1).astype(np.int64), z, inside)


def surface_sunk_lights(scene: SplatScene, cameras: list[PinholeCamera],
                        images: list[np.ndarray], whites: np.ndarray, weights: np.ndarray,
                        sightings: Sightings) -> tuple[SplatScene, SurfacedLights]:
    """``scene`` with its sunk and floating light splats moved onto the room's boundary
    (module docstring), and what moved. ``cameras``/``images``: the training
    views (any size, framing as the cameras); ``whites`` (V,): each view's white, in
    its image's units; ``weights``: luminance weights; ``sightings``: the views' light
    regions (:func:`gaslight_usd.sightings.sight_lights`, same views)."""
    lum = scene.base_colours @ np.asarray(weights, np.float32)
    nothing = SurfacedLights(0, 0.0, 0.0, 0)
    compact = sightings.whole & (sightings.radii <= np.radians(MAX_CONE_DEG))
    bright = np.flatnonzero((lum > float(np.median(whites))) & (scene.opacities > 0.05))
    if not len(bright) or not sightings.count or len(cameras) < 2:
        return scene, nothing
    pos = scene.positions.astype(np.float64)
    image_lum = [np.asarray(im, np.float32) @ np.asarray(weights, np.float32)
                 for im in images]
    # the view whose outline holds each bright splat (nearest its axis), compact first
    angle = sightings.angles(pos[bright]) / np.maximum(sightings.radii, 1e-9)[None]
    in_compact = np.where(compact[None], angle, np.inf)
    in_broad = np.where(~compact[None], angle, np.inf)
    near_c, near_b = np.argmin(in_compact, axis=1), np.argmin(in_broad, axis=1)
    row = np.arange(len(bright))
    held_c = in_compact[row, near_c] <= 1.0
    held_b = ~held_c & (in_broad[row, near_b] <= 1.0)
    best_view = np.where(held_c, sightings.view[near_c],
                         np.where(held_b, sightings.view[near_b], -1))
    probe = scene.subset(np.arange(scene.count))
    probe.metadata = {**scene.metadata, "exposure_scale": float(np.median(whites))}
    space = capture_space(probe, np.array([cam.center for cam in cameras]))
    sigma = splat_sigma(scene)
    outside = ~space.inside(pos[bright], reach=2.0 * sigma[bright])
    # compact lights outside the space come in; broad ones inside it may go out
    movable = (held_c & outside) | (held_b & ~outside)
    reach_far = float(np.linalg.norm(space.box[1] - space.box[0]))
    target = pos.copy()
    sunk = np.zeros(scene.count, bool)
    for v in np.unique(best_view[movable]):
        pick = movable & (best_view == v)
        idx = bright[pick]
        eye = cameras[v].center
        dist = np.linalg.norm(pos[idx] - eye, axis=1)
        # samples from the camera out to the splat (sunk) or past it to the box's far
        # side (floating); each with the reach the lights finder gives a splat (two
        # sigmas), scaled to its distance there as the splat would be
        span = np.where(outside[pick], 1.0, np.maximum(reach_far / np.maximum(dist, 1e-9), 1.0))
        t = span[:, None] * np.linspace(0.0, 1.0, RAY_STEPS + 1)[None, 1:]
        along = eye + (pos[idx] - eye)[:, None, :] * t[..., None]  # (K, S, 3)
        reach = 2.0 * sigma[idx][:, None] * t
        inside = space.inside(along.reshape(-1, 3), reach.ravel()).reshape(len(idx), -1)
        first_out = np.argmin(inside, axis=1)
        leaves = inside[:, 0] & ~inside.all(axis=1)
        scale = t[np.arange(len(idx)), np.maximum(first_out - 1, 0)]  # last sample inside
        ok = leaves & np.where(outside[pick], True, scale - 1.0 > FLOAT_SHARE * scale)
        keep = idx[ok]
        target[keep] = eye + (pos[keep] - eye) * scale[ok][:, None]
        sunk[keep] = True
    if not sunk.any():
        return scene, nothing
    idx = np.flatnonzero(sunk)
    refused = np.zeros(len(idx), bool)
    for v, (cam, y) in enumerate(zip(cameras, image_lum, strict=True)):
        row, col, z, inside = _pixels(cam, target[idx], y.shape)
        if not inside.any():
            continue
        depth = depth_map(scene, cam)
        drow, dcol, _, _ = _pixels(cam, target[idx], depth.shape)
        open_view = inside & (depth[drow, dcol] >= z * (1.0 - OCCLUDED_SHARE))
        refused |= open_view & (y[row, col] < whites[v])
    idx_moved = idx[~refused]
    area = scene.opacities * np.prod(np.sort(scene.scales, axis=1)[:, 1:], axis=1)
    power = lum * area
    out = scene.subset(np.arange(scene.count))
    if len(idx_moved):
        eye = np.array([cameras[v].center for v in best_view[np.searchsorted(bright,
                                                                             idx_moved)]])
        ratio = (np.linalg.norm(target[idx_moved] - eye, axis=1)
                 / np.maximum(np.linalg.norm(pos[idx_moved] - eye, axis=1), 1e-12))
        out.positions[idx_moved] = target[idx_moved].astype(out.positions.dtype)
        out.log_scales[idx_moved] = (scene.log_scales[idx_moved]
                                     + np.log(ratio)[:, None]).astype(out.log_scales.dtype)
    report = SurfacedLights(
        moved=int(len(idx_moved)),
        power_share=float(power[idx_moved].sum() / max(power[bright].sum(), 1e-30)),
        mean_move=float(np.linalg.norm(target[idx_moved] - pos[idx_moved], axis=1).mean())
        if len(idx_moved) else 0.0,
        refused=int(refused.sum()))
    return out, report
