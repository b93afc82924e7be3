"""Is a clipped bright thing a lamp, or a surface the lamps lit?

The lights finder takes any bright cluster the photos clipped for a light. A surface
the lamps light strongly clips too when it is pale (a yellow box 3.5 m from the
``bulb`` room's lamp, framed by one photo of a ``balanced`` fit), and weighed as a light
by its surroundings it came out 85x its fill in the output (``docs/measurements.md``,
session 23). Depth does not tell the two apart: the fit places both where the photos
put them.

Physics does: a matte surface reflects at most the light that reaches it, so it reads
at most ``E / pi`` where ``E`` is its irradiance. A lamp reads far more than that. The
test takes the brightest the photos read the light (its clip floor where they clipped
it), and the irradiance at it from the rest of the room and the *other* weighed lights
at their weighed power, and asks what albedo a surface there would need to read that
bright. At or under :data:`LIT_SURFACE_ALBEDO` it may well be a lit surface: it is not
weighed, and keeps the uplift's fill. Measured by ``gaslight2usd bench --suite chain``
(power errors per light and every light's ``lit_surface_albedo``).
"""

from __future__ import annotations

import math

import numpy as np

from ..cameras import PinholeCamera

LIT_SURFACE_ALBEDO = 1.0
"""A clipped light that a matte surface of at most this albedo, lit by what the weighing
says lights it, would read as bright as the photos read it, is taken for a lit surface
(the physical bound: on the chain bench's fits every real lamp and panel needed about
twice that or more, the clipped box under it; ``docs/measurements.md``, session 23)."""


def light_reading(position: np.ndarray, cameras: list[PinholeCamera],
                  images: list[np.ndarray], floors: list[np.ndarray | None],
                  weights: np.ndarray) -> tuple[float, np.ndarray | None]:
    """The brightest the views that frame ``position`` read it (the 3x3 pixel block's
    most, clipped pixels at their clip floor), and the mean unit direction from it to
    those views (where a surface there faces: the views saw its lit side). ``(0,
    None)`` where no view frames it."""
    position = np.asarray(position, np.float64)
    reading, towards = 0.0, []
    for cam, img, floor in zip(cameras, images, floors, strict=True):
        h, w = img.shape[:2]
        uv, z = cam.project(position[None])
        x, y = int(uv[0, 0] * w / cam.width), int(uv[0, 1] * h / cam.height)
        if not (z[0] > 0 and 0 <= x < w and 0 <= y < h):
            continue
        block = (slice(max(0, y - 1), y + 2), slice(max(0, x - 1), x + 2))
        lum = img[block] @ weights
        if floor is not None:
            lum = np.where(floor[block] > 0, floor[block], lum)
        reading = max(reading, float(lum.max()))
        to_cam = cam.center - position
        towards.append(to_cam / np.linalg.norm(to_cam))
    if not towards:
        return 0.0, None
    facing = np.mean(towards, axis=0)
    norm = float(np.linalg.norm(facing))
    return reading, (facing / norm if norm > 0 else np.asarray(towards[0]))


def lit_surface_albedos(readings: np.ndarray, irradiance: np.ndarray,
                        factors: np.ndarray) -> np.ndarray:
    """Per light ``j``: the albedo a matte surface at it would need to read
    ``readings[j]``, lit by the rest of the room (``irradiance[j, 0]``) and the other
    lights (``irradiance[j, 1 + i]`` at their fills, times ``factors[i]``).

    ``irradiance`` is ``(L, 1 + L)``: gathered at each light, facing its views
    (:func:`light_reading`). NaN entries (a point too close to a light to aim at it; a
    light's own column) count as no light: less light makes a surface less likely. Inf
    where nothing lights it at all."""
    irr = np.nan_to_num(np.asarray(irradiance, np.float64), nan=0.0)
    lights = irr[:, 1:].copy()
    np.fill_diagonal(lights, 0.0)
    total = irr[:, 0] + lights @ np.asarray(factors, np.float64)
    return np.where(total > 0, math.pi * np.asarray(readings, np.float64)
                    / np.maximum(total, 1e-30), np.inf)
