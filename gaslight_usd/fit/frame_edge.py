"""Lights the frame cuts in every photo that sees them: their size and power are guesses.

A lamp on the frame's edge shows only part of its clipped region; if no photo frames it
whole, its extent (and so the power the uplift and the fit give it) is unmeasured, and
the fit may lose it altogether (``gaslight2usd bench --suite stability --perturb
light_half_out``: the room's lamp cut in every photo; the fit left no splat within
0.3 m of it and said nothing). The check reads the views, not the splats (the fit may
have no splat where the lamp is):

1. each view's **light regions**: at :data:`ANALYSIS_SIZE`, pixels whose HDR luminance
   is at or over the set's white (the clipped level; a darker frame's measured lamp is
   over it too), in connected regions (:func:`white_ratios`, :func:`light_regions`).
   Area-averaged, pixels a noisy photo clipped here and there fall under the white; a
   lamp stays over it. A region within :data:`EDGE_PX` of the border is **cut**; one up to
   :data:`MAX_REGION_SHARE` of the frame is **compact** (a lamp, not a wall lit past
   the white);
2. the compact cut regions' centroid rays, two by two from different views, meet
   (within :data:`RAY_GAP_DEG`) at candidate places;
3. each candidate is projected into every view. A view *cuts* it when it lands (within
   :data:`REACH_PX`) on a compact cut region, *frames it whole* when on a region clear
   of the border, *misses* it when it lies well inside the frame on no region (hidden,
   or no light there). A candidate cut by :data:`MIN_VIEWS` views or more, framed whole
   by none and missed by fewer than half as many as cut it, is a cut place; places
   landing on a shared region are one, and a light when one of its regions reads
   :data:`LIGHT_PEAK` whites or more.

Occlusion is not modelled (a view that misses a light may only not see it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..cameras import PinholeCamera
from ..colour import AT_WHITE
from ..resize import area_resize, fit_within

ANALYSIS_SIZE = 160
"""Long side (pixels) the views are area-averaged to before their regions are found
(at the photos' 480 px, the generated rooms' render noise clipped pixels in specks that
placed lights outside the room; at 80-240 px none did, and the cut lamp, 2 px across at
80 px, still read 18 whites)."""
EDGE_PX = 1
"""A region with a pixel this close to the frame's border (view pixels) is cut by it."""
MAX_REGION_SHARE = 0.02
"""Regions up to this share of the frame are compact: only they place candidates and
count as cutting one (a large region's centroid ray points at nothing in particular)."""
RAY_GAP_DEG = 2.0
"""Two views' region rays closer than this angle (seen from the nearer camera) meet."""
REACH_PX = 2.0
"""A candidate lands on a region within this many view pixels of it."""
MAX_RAYS = 1500
"""At most this many cut regions place candidates (the brightest): pairs grow with the
square, and a capture of hundreds of photos should not spend minutes here."""
MIN_VIEWS = 3
"""Views that must cut a candidate (two make it; a third confirms it is one light)."""
LIGHT_PEAK = 4.0
"""A light's brightest region reads at least this many whites (the uplift's prediction
over the clip): the room's cut lamp read 14-20, a floor patch a bare bulb lit past the
white 2. With an uplift that predicts nothing over the white (``uplift.linear``) no
region does, and the check stays quiet: it cannot tell a lamp from a lit wall."""

NONE, WHOLE, CUT, LARGE_CUT, MISSED, OUT = 0, 1, 2, 3, -1, 4
"""What a candidate meets in a view (:func:`landing`)."""


@dataclass
class CutLight:
    position: np.ndarray
    """Where the cut regions' rays meet (world frame): the median of its candidates."""
    views: list[str]
    """The photos that see it, each cutting it."""
    peak: float = 0.0
    """Its brightest region's brightest pixel, in whites."""

    def as_dict(self) -> dict:
        return {"position": [round(float(v), 4) for v in self.position],
                "views": list(self.views), "peak_whites": round(float(self.peak), 2),
                "warning": self.sentence()}

    def sentence(self) -> str:
        where = ", ".join(f"{v:.2f}" for v in self.position)
        listed = ", ".join(self.views[:5]) + (" ..." if len(self.views) > 5 else "")
        return (f"a light at ({where}) is cut by the frame edge in every photo that sees "
                f"it ({len(self.views)}: {listed}): its size and power are a guess; frame "
                "it whole in at least one photo")


@dataclass
class LightRegions:
    """One view's light regions."""

    labels: np.ndarray
    """(H, W) int32: region number (1..K), 0 elsewhere."""
    kind: np.ndarray
    """(K + 1,) int8 per region: :data:`WHOLE`, :data:`CUT` (compact) or
    :data:`LARGE_CUT` (entry 0: :data:`NONE`)."""
    centroids: np.ndarray
    """(K, 2) region centres (x, y) in pixels, COLMAP convention (pixel centres +0.5)."""
    nearest: np.ndarray
    """(H, W) int32: the region within :data:`REACH_PX` of each pixel (0: none)."""
    peak: np.ndarray
    """(K + 1,) the brightest pixel of each region, in whites (entry 0: 0)."""


def light_regions(ratio: np.ndarray, edge_px: int = EDGE_PX, reach: float = REACH_PX
                  ) -> LightRegions:
    """The 8-connected regions of ``ratio`` (luminance in whites) at the white or over it
    (:data:`gaslight_usd.colour.AT_WHITE`), each one's kind and peak, and the
    nearest-region map."""
    mask = ratio >= AT_WHITE
    labels, count = ndimage.label(mask, structure=np.ones((3, 3), bool))
    h, w = mask.shape
    border = np.zeros(mask.shape, bool)
    e = max(int(edge_px), 1)
    border[:e] = border[-e:] = True
    border[:, :e] = border[:, -e:] = True
    touches = np.zeros(count + 1, bool)
    touches[np.unique(labels[border & mask])] = True
    area = np.bincount(labels.ravel(), minlength=count + 1)
    kind = np.where(touches, np.where(area <= MAX_REGION_SHARE * h * w, CUT, LARGE_CUT),
                    WHOLE).astype(np.int8)
    kind[0] = NONE
    if not count:
        return LightRegions(labels.astype(np.int32), kind, np.zeros((0, 2)),
                            np.zeros(mask.shape, np.int32), np.zeros(1))
    ys, xs = np.nonzero(labels)
    lab = labels[ys, xs]
    cx = np.bincount(lab, xs + 0.5, minlength=count + 1)[1:] / area[1:]
    cy = np.bincount(lab, ys + 0.5, minlength=count + 1)[1:] / area[1:]
    dist, (iy, ix) = ndimage.distance_transform_edt(labels == 0, return_indices=True)
    nearest = np.where(dist <= reach, labels[iy, ix], 0).astype(np.int32)
    peak = np.concatenate([[0.0], ndimage.maximum(ratio, labels, np.arange(1, count + 1))])
    return LightRegions(labels.astype(np.int32), kind, np.stack([cx, cy], axis=1), nearest,
                        peak)


def pixel_rays(cam: PinholeCamera, uv: np.ndarray) -> np.ndarray:
    """(N, 3) unit world directions through pixel positions ``uv`` (COLMAP convention)."""
    d = np.stack([(uv[:, 0] - cam.cx) / cam.fx, (uv[:, 1] - cam.cy) / cam.fy,
                  np.ones(len(uv))], axis=1) @ cam.R
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def meeting_points(o1: np.ndarray, d1: np.ndarray, o2: np.ndarray, d2: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Midpoints of the closest approach of ray pairs (origins ``o``, unit directions
    ``d``, all (N, 3)) and the gap there as an angle (radians) from the nearer origin;
    inf where a ray would meet behind its origin or the rays are parallel."""
    w = o1 - o2
    b = np.sum(d1 * d2, axis=1)
    d, e = np.sum(d1 * w, axis=1), np.sum(d2 * w, axis=1)
    denom = 1.0 - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (b * e - d) / denom
        t = (e - b * d) / denom
        p1, p2 = o1 + s[:, None] * d1, o2 + t[:, None] * d2
        gap = np.linalg.norm(p1 - p2, axis=1) / np.minimum(s, t)
    gap = np.where((s > 0) & (t > 0) & (denom > 1e-9), np.arctan(gap), np.inf)
    return 0.5 * (p1 + p2), gap


def landing(cam: PinholeCamera, regions: LightRegions, points: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """What each of (N, 3) ``points`` meets in this view, and the region (0: none).

    Kinds: the region's (:data:`WHOLE`, :data:`CUT`, :data:`LARGE_CUT`); :data:`MISSED`
    on no region though well inside the frame (:data:`EDGE_PX` + :data:`REACH_PX` from
    the border); :data:`NONE` on no region near the border; :data:`OUT` out of the
    frame. Points up to :data:`REACH_PX` outside the frame count as in it (a cut
    light's centre lies on the border)."""
    uv, z = cam.project(points)
    h, w = regions.nearest.shape
    x = np.nan_to_num(uv[:, 0] * (w / cam.width), nan=-1e9, posinf=-1e9, neginf=-1e9)
    y = np.nan_to_num(uv[:, 1] * (h / cam.height), nan=-1e9, posinf=-1e9, neginf=-1e9)
    near = (z > 0) & (x > -REACH_PX) & (x < w + REACH_PX) & (y > -REACH_PX) & \
        (y < h + REACH_PX)
    m = EDGE_PX + REACH_PX
    well = (z > 0) & (x >= m) & (x < w - m) & (y >= m) & (y < h - m)
    ix = np.clip(np.floor(x), 0, w - 1).astype(np.int64)
    iy = np.clip(np.floor(y), 0, h - 1).astype(np.int64)
    region = np.where(near, regions.nearest[iy, ix], 0)
    kind = regions.kind[region]
    kind = np.where(~near, OUT, np.where((kind == NONE) & well, MISSED, kind))
    return kind.astype(np.int8), region


def white_ratios(images: list[np.ndarray], white: float, weights: np.ndarray,
                 long_side: int = ANALYSIS_SIZE) -> list[np.ndarray]:
    """Per view ``(h, w)`` float32 luminance in whites, after an area average to
    ``long_side`` (views already smaller keep their size)."""
    out = []
    for image in images:
        h, w = image.shape[:2]
        small = area_resize(np.asarray(image, np.float32), *fit_within(w, h, long_side))
        out.append(small @ np.asarray(weights, np.float32) / np.float32(white))
    return out


def cut_lights(cameras: list[PinholeCamera], ratios: list[np.ndarray], names: list[str],
               min_views: int = MIN_VIEWS) -> list[CutLight]:
    """Lights cut by the frame in every view that sees them (module docstring), most
    views first.

    ``ratios``: per view ``(H, W)`` luminance in whites (:func:`white_ratios`), the
    view's camera's image shrunk evenly to that size.
    """
    if len(cameras) < 2:
        return []
    regions = [light_regions(r) for r in ratios]
    origins, dirs, owner, bright = [], [], [], []
    for v, (cam, reg) in enumerate(zip(cameras, regions, strict=True)):
        picked = np.flatnonzero(reg.kind == CUT) - 1
        if not len(picked):
            continue
        h, w = reg.labels.shape
        dirs.append(pixel_rays(cam, reg.centroids[picked] * [cam.width / w, cam.height / h]))
        origins.append(np.repeat(cam.center[None], len(picked), axis=0))
        owner.append(np.full(len(picked), v))
        bright.append(reg.peak[picked + 1])
    if not owner:
        return []
    o, d, view = np.concatenate(origins), np.concatenate(dirs), np.concatenate(owner)
    if len(view) > MAX_RAYS:
        top = np.argsort(-np.concatenate(bright), kind="stable")[:MAX_RAYS]
        o, d, view = o[top], d[top], view[top]
    a, b = np.triu_indices(len(view), k=1)
    pair = view[a] != view[b]
    points, gap = meeting_points(o[a[pair]], d[a[pair]], o[b[pair]], d[b[pair]])
    points = points[gap < math.radians(RAY_GAP_DEG)]
    if not len(points):
        return []
    met = [landing(cam, reg, points) for cam, reg in zip(cameras, regions, strict=True)]
    kinds = np.stack([k for k, _ in met])
    cutting = (kinds == CUT).sum(0)
    lone = (cutting >= min_views) & ~np.any(kinds == WHOLE, axis=0) & \
        (2 * (kinds == MISSED).sum(0) < cutting)
    if not lone.any():
        return []
    where = np.stack([r for _, r in met])[:, lone]
    peaks = np.stack([reg.peak[r] for reg, r in zip(regions, where, strict=True)])
    found = _group(points[lone], kinds[:, lone] == CUT, where, peaks, names)
    return [light for light in found if light.peak >= LIGHT_PEAK]


def _group(points: np.ndarray, cut_in: np.ndarray, region: np.ndarray, peaks: np.ndarray,
           names: list[str]) -> list[CutLight]:
    """One light per set of candidates that land on a shared cut region in some view
    (``cut_in``, ``region``, ``peaks``: (V, N)); its place is the median of its
    candidates', its views those that cut any of them, its peak their brightest."""
    n = len(points)
    offsets = np.concatenate([[0], np.cumsum(region.max(axis=1) + 1)])
    views, cands = np.nonzero(cut_in)
    nodes = n + offsets[views] + region[views, cands]
    size = n + int(offsets[-1])
    graph = coo_matrix((np.ones(len(cands)), (cands, nodes)), shape=(size, size))
    _, labels = connected_components(graph, directed=False)
    out = []
    for g in np.unique(labels[:n]):
        members = labels[:n] == g
        seen = np.flatnonzero(cut_in[:, members].any(axis=1))
        peak = float(np.max(np.where(cut_in[:, members], peaks[:, members], 0.0)))
        out.append(CutLight(np.median(points[members], axis=0), [names[v] for v in seen],
                            peak))
    return sorted(out, key=lambda light: -len(light.views))
