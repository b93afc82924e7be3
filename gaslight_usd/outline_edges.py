"""A lit rectangle's edges where the views that measured it see its light end.

The views' outlines of a window or panel (:mod:`gaslight_usd.flat_outlines`) are cells
lit in most views that frame them: a cell is lit where its centre falls in a pixel over a
share of the light's level, and a pixel at the edge is partly light. So an outline runs
up to a pixel past the light on each side, and a small light's rectangle comes out too
large, with as much too much light once redrawn at the level the views read inside
(``docs/measurements.md``, session 53).

A view that measured the light (nothing clipped round the edge) says where it ends to a
fraction of a pixel: across the edge its reading falls from the light's level to the
surface's beyond, and a blurred edge crosses halfway where the light stops. So each side
is read along a band across it, in each such view (bilinear, at the view's size), the
profile scaled from the view's own inside level (the middle of the rectangle) to what it
reads at the band's far end, and the side is put where the profile first falls under
half; the median over the views that measured that side (a lamp or plant in front of it
in one view is outvoted). A side no view measured stays where the outline put it:
clipped photos say only where the light passed their white, not where it ends.

Measured by ``gaslight2usd bench --suite chain`` (``power_err_panel_*`` and the
irradiance at the probes under the panels).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from .cameras import PinholeCamera, bilinear
from .flat_outlines import Outline

BAND_SHARE = 0.5
"""Each side is read this share of its half-size either way across it..."""
BAND_DEPTH_SHARE = 0.1
"""...and at most this share of the camera's distance (a wide window's side need not be
read half a metre out, where other lights may lie)."""
ACROSS = 41
"""Points read across a side..."""
ALONG = 13
"""...at this many places along it, within :data:`ALONG_SHARE` of its half-length of its
middle (clear of the corners)."""
ALONG_SHARE = 0.6
INNER = 9
"""The view's inside level: the median over this many x this many points of the
rectangle's middle (within :data:`ALONG_SHARE` of its half-sizes of its centre)."""
CONTRAST = 4.0
"""A view measured a side where its inside level is over this many times what it reads
beyond the side: a dim view of the light says nothing sharp about its edge."""


def _read(cam: PinholeCamera, lum: np.ndarray, points: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray]:
    """(luminance (N,), inside the frame and in front (N,)) of ``lum`` (H, W), at any size
    covering ``cam``'s frame, read bilinearly at ``points`` (N, 3)."""
    uv, z = cam.project(points)
    h, w = lum.shape
    x, y = uv[:, 0] * w / cam.width, uv[:, 1] * h / cam.height
    ok = (z > 0) & np.isfinite(x) & np.isfinite(y) & (x >= 0.5) & (x <= w - 0.5) \
        & (y >= 0.5) & (y <= h - 0.5)
    return bilinear(lum[..., None], np.where(ok, x, 0.5), np.where(ok, y, 0.5))[:, 0], ok


def _crossing(profile: np.ndarray, offsets: np.ndarray) -> float | None:
    """Where ``profile`` (scaled: 1 inside, 0 beyond) first falls under half, going out
    along ``offsets``; None where it starts under half or never falls under it."""
    if profile[0] < 0.5:
        return None
    down = np.flatnonzero((profile[:-1] >= 0.5) & (profile[1:] < 0.5))
    if not len(down):
        return None
    k = int(down[0])
    step = profile[k] - profile[k + 1]
    return float(offsets[k] + (profile[k] - 0.5) / step * (offsets[k + 1] - offsets[k]))


def luminances(images: Sequence[np.ndarray], floors: Sequence[np.ndarray | None],
                weights: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray | None]]:
    """(each view's luminance (H, W), where it clipped (H, W) or None) of HDR ``images``
    with clip ``floors`` (None or 0 where nothing clipped), ``weights`` the luminance
    weights: what :func:`side_offsets` reads."""
    weights = np.asarray(weights, np.float64)
    lums = [np.asarray(image, np.float64) @ weights for image in images]
    clipped = [None if floor is None or not bool(np.any(np.asarray(floor) > 0))
               else np.asarray(floor) > 0 for floor in floors]
    return lums, clipped


def side_offsets(outline: Outline, cameras: Sequence[PinholeCamera],
                 lums: Sequence[np.ndarray], clipped: Sequence[np.ndarray | None]
                 ) -> np.ndarray:
    """(2, 2): how far each side of ``outline`` lies past where the views that measured it
    see the light end (module docstring): rows u, v; columns the - and + side; positive
    outwards; nan where no view measured that side. ``lums``, ``clipped``: the views'
    luminance and clip masks (:func:`luminances`)."""
    centre = np.asarray(outline.centre, np.float64)
    normal = np.asarray(outline.normal, np.float64)
    half = np.asarray(outline.half_size, np.float64)
    axes = (np.asarray(outline.u, np.float64), np.asarray(outline.v, np.float64))
    grid = (np.arange(INNER) + 0.5) / INNER * 2.0 - 1.0
    ga, gb = np.meshgrid(grid * ALONG_SHARE * half[0], grid * ALONG_SHARE * half[1],
                         indexing="ij")
    inner = centre + ga.reshape(-1, 1) * axes[0] + gb.reshape(-1, 1) * axes[1]
    found: list[list[list[float]]] = [[[], []], [[], []]]
    for cam, lum, clip in zip(cameras, lums, clipped, strict=True):
        distance = float((cam.center - centre) @ normal)
        if distance <= 0:
            continue
        inside, ok = _read(cam, lum, inner)
        if not ok.all():
            continue
        level = float(np.median(inside))
        for axis in (0, 1):
            a, b = axes[axis], axes[1 - axis]
            band = min(BAND_SHARE * half[axis], BAND_DEPTH_SHARE * distance)
            offsets = np.linspace(-band, band, ACROSS)
            along = np.linspace(-ALONG_SHARE, ALONG_SHARE, ALONG) * half[1 - axis]
            oo, tt = np.meshgrid(offsets, along, indexing="ij")
            for side, sign in enumerate((-1.0, 1.0)):
                points = (centre + (sign * (half[axis] + oo.reshape(-1, 1))) * a
                          + tt.reshape(-1, 1) * b)
                values, seen = _read(cam, lum, points)
                if not seen.all():
                    continue
                if clip is not None:
                    x, y, _ = cam.pixels_of(points, clip.shape)
                    if bool(clip[y, x].any()):
                        continue
                profile = values.reshape(oo.shape).mean(axis=1)
                beyond = float(profile[-1])
                if level <= CONTRAST * max(beyond, 0.0) or level <= 0:
                    continue
                where = _crossing((profile - beyond) / (level - beyond), offsets)
                if where is not None:
                    found[axis][side].append(where)
    out = np.full((2, 2), np.nan)
    for axis in (0, 1):
        for side in (0, 1):
            if found[axis][side]:
                out[axis, side] = -float(np.median(found[axis][side]))
    return out


def refine_outlines(outlines: Sequence[Outline], cameras: Sequence[PinholeCamera],
                    images: Sequence[np.ndarray], floors: Sequence[np.ndarray | None],
                    weights: np.ndarray) -> list[Outline]:
    """Each of ``outlines`` with its sides where the views that measured it see the light
    end (:func:`refine_edges`); ``images``: the ``cameras``' HDR views, ``floors``: their
    clip floors (None or 0 where nothing clipped), ``weights``: luminance weights."""
    if not outlines:
        return []
    lums, clipped = luminances(images, floors, weights)
    return [refine_edges(outline, cameras, lums, clipped) for outline in outlines]


def refine_edges(outline: Outline, cameras: Sequence[PinholeCamera],
                 lums: Sequence[np.ndarray], clipped: Sequence[np.ndarray | None]
                 ) -> Outline:
    """``outline`` with each side the views measured moved to where they see the light end
    (:func:`side_offsets`); the rest as it was."""
    past = side_offsets(outline, cameras, lums, clipped)
    if np.isnan(past).all():
        return outline
    half = np.asarray(outline.half_size, np.float64)
    # the - side moves in by past[:, 0], the + side by past[:, 1]
    moved = np.nan_to_num(past, nan=0.0)
    low, high = -half + moved[:, 0], half - moved[:, 1]
    if bool((high - low <= 0).any()):
        return outline
    shift = (low + high) / 2.0
    centre = (np.asarray(outline.centre, np.float64) + shift[0] * np.asarray(outline.u)
              + shift[1] * np.asarray(outline.v))
    half_size = (high - low) / 2.0
    return replace(outline, centre=centre, half_size=half_size,
                   measured_sides=int(np.isfinite(past).sum()),
                   fill=outline.fill_within(centre, half_size))
