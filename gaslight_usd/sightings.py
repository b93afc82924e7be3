"""Where the photos saw light: the views' regions over the white, as cones from the cameras.

The splats say where the fit put light; the photos say where light was seen. A fit can
leave a patch of wall brighter than white where no photo saw anything over it (a floater
seen from a direction no photo took, a surface lit in the fit by a smeared light), and
it can put a flat light at any depth along the rays that see it. The views settle both:

- each view's **light regions** (luminance at or over the white, in blocks of the view
  at most :data:`gaslight_usd.fit.frame_edge.ANALYSIS_SIZE` across, a block over the
  white when any of its pixels is: a bulb a pixel wide is not averaged away) become
  **cones** from its camera: the ray to the region's centroid (in a view that clipped
  nothing weighted by its blocks' luminance: the light, not the lit wall round it), and
  the widest angle of any of its blocks from it plus half a block (:func:`sight_lights`);
- a light no cone holds any of is **not seen** by the photos (:meth:`Sightings.seen`):
  nothing over the white was photographed where it is;
- a light two views frame **whole** (regions clear of the border) from at least
  :data:`MIN_BASELINE_DEG` apart is **placed** where the regions' centroid rays meet
  (:meth:`Sightings.locate`): the outline fixes the depth the splats cannot.

The fit stage stores the cones in the splats' metadata (``light_sightings``); the
lights finder (:mod:`gaslight_usd.lights`) reads them back. ``python
examples/check_lights.py SCENE OUT`` measures what they change against a generated
room's true lights.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import ndimage

from .cameras import PinholeCamera
from .colour import AT_WHITE

MAX_REGIONS_PER_VIEW = 48
"""Regions kept per view, the most whites (summed over the region) first: a noisy or
busy photo's specks over the white should not swell the splats' metadata."""
MIN_BASELINE_DEG = 10.0
"""Two whole outlines place a light only when their rays meet at this angle or more:
nearer parallel, a pixel of outline error moves the meeting point along the rays by
more than the light's size (the window's outlines 6-7 deg apart put it 0.64 m off,
docs/measurements.md)."""
MIN_HOLD_SHARE = 0.5
"""A view's region stands for a light only when its cone holds this share of the light's
power: a light's own outline holds all of it (the splats smear along that view's rays,
inside its cone), while another light's outline only crosses a corner of it (on the
chain bench's bulb room a bare bulb's cone held 4 % of the window's splats and, with the
window's own outline, placed the window 1.8 m off)."""
MAX_RESIDUAL_SHARE = 1.0
"""The placed point must lie within this share of each region's cone (its rays agree)."""


@dataclass
class Sightings:
    """Light regions of the views as cones from the cameras (module docstring)."""

    origins: np.ndarray
    """(V, 3) camera centres."""
    view: np.ndarray
    """(R,) int: each region's view."""
    axes: np.ndarray
    """(R, 3) unit centroid rays."""
    radii: np.ndarray
    """(R,) cone half-angles (radians)."""
    whole: np.ndarray
    """(R,) bool: the region is clear of the frame's border."""
    whites: np.ndarray
    """(R,) the region's luminance summed, in whites x analysis pixels (its ranking)."""
    white: float

    @property
    def count(self) -> int:
        return int(len(self.view))

    def angles(self, points: np.ndarray) -> np.ndarray:
        """(N, R) angle (radians) of each point from each region's centroid ray."""
        rel = np.asarray(points, np.float64).reshape(-1, 3)[:, None] - self.origins[self.view][None]
        norm = np.maximum(np.linalg.norm(rel, axis=2), 1e-30)
        cos = np.einsum("nrk,rk->nr", rel, self.axes) / norm
        return np.arccos(np.clip(cos, -1.0, 1.0))

    def holding(self, points: np.ndarray) -> np.ndarray:
        """(N, R) bool: which regions' cones hold each point."""
        return self.angles(points) <= self.radii[None]

    def seen(self, points: np.ndarray) -> np.ndarray:
        """(N,) bool: some photo saw light over the white where each point lies."""
        if not self.count:
            return np.zeros(len(np.asarray(points).reshape(-1, 3)), bool)
        return self.holding(points).any(axis=1)

    def locate(self, points: np.ndarray, weights: np.ndarray) -> dict[str, Any] | None:
        """Where the whole outlines holding a light's splats (``points`` (N, 3),
        ``weights`` (N,) their power) meet, or None when fewer than two views frame it
        whole from :data:`MIN_BASELINE_DEG` apart or the rays do not agree.

        Per view, the whole region holding the most of the light's power, and at least
        :data:`MIN_HOLD_SHARE` of it, stands for it.
        Returns ``position``, ``views`` (their indices), ``baseline_deg`` and
        ``residual_share`` (the worst ray's miss over its cone).
        """
        if not self.count:
            return None
        hold = self.holding(points) & self.whole[None]
        w = np.asarray(weights, np.float64)
        share = w @ hold / max(float(w.sum()), 1e-30)  # (R,)
        best: dict[int, int] = {}
        for r in np.flatnonzero(share >= MIN_HOLD_SHARE):
            v = int(self.view[r])
            if v not in best or share[r] > share[best[v]]:
                best[v] = int(r)
        if len(best) < 2:
            return None
        regions = np.array(sorted(best.values()))
        o, d = self.origins[self.view[regions]], self.axes[regions]
        between = np.degrees(np.arccos(np.clip(d @ d.T, -1.0, 1.0)))
        baseline = float(between.max())
        if baseline < MIN_BASELINE_DEG:
            return None
        # least squares: the point nearest all the rays
        proj = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
        point = np.linalg.solve(proj.sum(0), np.einsum("rij,rj->i", proj, o))
        miss = self.angles(point)[0, regions] / np.maximum(self.radii[regions], 1e-9)
        ahead = ((point - o) * d).sum(1) > 0
        if not ahead.all() or float(miss.max()) > MAX_RESIDUAL_SHARE:
            return None
        return {"position": point, "views": self.view[regions].tolist(),
                "baseline_deg": baseline, "residual_share": float(miss.max())}

    def as_dict(self) -> dict[str, Any]:
        """For the splats' metadata: the white and one row per region,
        ``[view, axis x, y, z, half-angle deg, whole, whites]`` (origins are the
        metadata's ``cameras.centres``)."""
        rows = [[int(v), *(round(float(a), 6) for a in ax), round(math.degrees(float(r)), 4),
                 int(bool(w)), round(float(s), 2)]
                for v, ax, r, w, s in zip(self.view, self.axes, self.radii, self.whole,
                                          self.whites, strict=True)]
        return {"white": self.white, "regions": rows}

    @classmethod
    def from_metadata(cls, metadata: Mapping[str, Any]) -> Sightings | None:
        """The sightings a PLY's metadata records, or None (older files, other tools)."""
        from .capture import camera_centres

        block = metadata.get("light_sightings")
        origins = camera_centres(metadata)
        if not isinstance(block, Mapping) or origins is None:
            return None
        try:
            rows = np.asarray(block.get("regions") or [], np.float64).reshape(-1, 7)
            white = float(block.get("white", 1.0))
        except (TypeError, ValueError):
            return None
        view = rows[:, 0].astype(np.int64)
        if len(view) and (view.min() < 0 or view.max() >= len(origins)):
            return None
        axes = rows[:, 1:4] / np.maximum(np.linalg.norm(rows[:, 1:4], axis=1, keepdims=True),
                                         1e-30)
        return cls(origins, view, axes, np.radians(rows[:, 4]), rows[:, 5] > 0.5, rows[:, 6],
                   white)


@dataclass
class PeakMap:
    """A view's luminance as block maxima at most
    :data:`gaslight_usd.fit.frame_edge.ANALYSIS_SIZE` across, taken from the photo's
    own resolution (:func:`peak_map`): a bulb two pixels wide in a 12 MP photo is
    still over the white here, where a view shrunk to the fit's working size has
    averaged it into the wall."""

    peaks: np.ndarray
    """(h, w) float32 block maxima of the luminance (specks removed)."""
    block: int
    """Full-size pixels per block side."""
    size: tuple[int, int]
    """(width, height) of the full-size view."""
    white: float | None = None
    """The view's own white at full size (the median of its clip floors), None when it
    clipped nothing."""
    clipped: np.ndarray | None = None
    """(h, w) bool: the blocks holding a pixel the photo clipped; None: not known."""


def peak_map(image: np.ndarray, weights: np.ndarray, white: float | None,
             clipped: np.ndarray | None = None) -> PeakMap:
    """``image`` (H, W, 3) linear HDR as a :class:`PeakMap`; ``white``: its own white
    (specks over it are removed, :func:`without_specks`; None: none removed);
    ``clipped``: (H, W) bool, the pixels the photo clipped."""
    lum = np.asarray(image, np.float32) @ np.asarray(weights, np.float32)
    if white is not None and white > 0:
        lum = without_specks(lum / np.float32(white)) * np.float32(white)
    peaks, k = block_max(lum)
    own = float(white) if white is not None and white > 0 else None
    held = None if clipped is None else block_max(np.asarray(clipped, np.float32))[0] > 0
    return PeakMap(peaks.astype(np.float32), k, (int(image.shape[1]), int(image.shape[0])),
                   own, held)


def sight_lights(cameras: list[PinholeCamera], images: Sequence[np.ndarray | PeakMap],
                 white: float | Sequence[float], weights: np.ndarray,
                 measured: bool | Sequence[bool] = False) -> Sightings:
    """The light regions of ``images`` (linear HDR, one per camera, or their
    :class:`PeakMap`) over ``white`` (luminance with ``weights``; one for all views,
    or one per view: see :func:`view_whites`), as cones from the cameras (module
    docstring). ``measured`` (one for all views, or one per view): the view clipped
    nothing, so its regions' brightness is measured and each cone's ray goes to the
    region's brightness-weighted centroid (:func:`_bright_centroids`); a clipped
    view's region holds the uplift's fill, whose shape is a guess, and keeps its plain
    centroid."""
    from .fit.frame_edge import WHOLE, light_regions, pixel_rays

    per_view = np.broadcast_to(np.asarray(white, np.float64), (len(images),))
    weigh = np.broadcast_to(np.asarray(measured, bool), (len(images),))
    view, axes, radii, whole, whites = [], [], [], [], []
    for v, (cam, image) in enumerate(zip(cameras, images, strict=True)):
        peaks = image if isinstance(image, PeakMap) else peak_map(image, weights, per_view[v])
        ratio = peaks.peaks / np.float32(per_view[v])
        reg = light_regions(ratio)
        count = len(reg.centroids)
        if not count:
            continue
        # camera pixels per block (the camera may be at another size than the view)
        sx = peaks.block * cam.width / peaks.size[0]
        sy = peaks.block * cam.height / peaks.size[1]
        summed = ndimage.sum(ratio, reg.labels, np.arange(1, count + 1))
        keep = np.argsort(-summed, kind="stable")[:MAX_REGIONS_PER_VIEW]
        ys, xs = np.nonzero(reg.labels)
        lab = reg.labels[ys, xs] - 1
        centroids = (_bright_centroids(ratio[ys, xs], xs, ys, lab, count) if weigh[v]
                     else reg.centroids)
        axis = pixel_rays(cam, centroids * [sx, sy])
        rays = pixel_rays(cam, np.stack([(xs + 0.5) * sx, (ys + 0.5) * sy], axis=1))
        ang = np.arccos(np.clip((rays * axis[lab]).sum(1), -1.0, 1.0))
        widest = np.zeros(count)
        np.maximum.at(widest, lab, ang)
        pixel = math.atan(0.5 * max(sx / cam.fx, sy / cam.fy))  # half an analysis pixel
        view.append(np.full(len(keep), v))
        axes.append(axis[keep])
        radii.append(widest[keep] + pixel)
        whole.append(reg.kind[keep + 1] == WHOLE)
        whites.append(summed[keep])
    recorded = float(np.median(per_view)) if len(per_view) else 1.0
    if not view:
        return Sightings(np.array([c.center for c in cameras]).reshape(-1, 3),
                         np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0),
                         np.zeros(0, bool), np.zeros(0), recorded)
    return Sightings(np.array([c.center for c in cameras]), np.concatenate(view),
                     np.concatenate(axes), np.concatenate(radii), np.concatenate(whole),
                     np.concatenate(whites), recorded)


def _bright_centroids(ratio: np.ndarray, xs: np.ndarray, ys: np.ndarray, lab: np.ndarray,
                      count: int) -> np.ndarray:
    """(count, 2) each region's centroid (x, y, pixel centres at +0.5) weighted by its
    blocks' luminance in whites.

    A region holds everything over the white round a light: in an HDR view (merged
    brackets, true HDR) the walls a bare bulb lights are over the white too, and the
    region's plain centroid lies off the bulb, enough for two views 15 degrees apart
    to place the bulb metres off. Weighted, the bulb thousands of whites bright is the
    region's centre; a region of even brightness (a window) keeps its plain centroid.
    Only for views that clipped nothing: a clipped photo's region holds the uplift's
    fill, and weighted by it the bulbs the fit seeds and weighs moved (``gaslight2usd
    bench --suite chain --method "truth HDR"`` and ``--method recursive``; figures in
    docs/measurements.md)."""
    w = np.maximum(np.asarray(ratio, np.float64), 1e-12)
    total = np.bincount(lab, w, minlength=count)
    cx = np.bincount(lab, w * (xs + 0.5), minlength=count) / total
    cy = np.bincount(lab, w * (ys + 0.5), minlength=count) / total
    return np.stack([cx, cy], axis=1)


def view_whites(floors: Sequence[np.ndarray | None], fallback: float) -> np.ndarray:
    """(V,) each view's own white: the median of its clipped pixels' clip floors, or
    ``fallback`` for a view that clipped nothing.

    One white for a set shot with auto-exposure is wrong for most of its views: the
    views differ by stops, so in a view exposed brighter than the median a lit wall
    over the shared white merges with the bare bulb it surrounds into one region (the
    chain bench's bulb room, the four views that frame the bulb: its region 12-26 % of
    the frame at one shared white, under 0.1 % at each view's own), and the bulb is
    never seen as the small light it is.
    """
    out = np.full(len(floors), float(fallback))
    for v, floor in enumerate(floors):
        if floor is not None and np.any(floor > 0):
            out[v] = float(np.median(floor[floor > 0]))
    return out


def without_specks(ratio: np.ndarray) -> np.ndarray:
    """``ratio`` (luminance in whites) with the pixels over the white that no 2 x 2
    block over the white holds (isolated specks, 1-pixel lines) put just under it.

    Sensor noise and a path tracer's fireflies put such specks all over a photo; as
    regions they make cones that hold any point in space (the chain bench's shaded-lamp
    room: 48 regions in every view, most of them specks, and hundreds of places the
    views "agreed" on a light). A light 2 pixels across survives.
    """
    over = ratio >= AT_WHITE
    kept = ndimage.binary_opening(over, structure=np.ones((2, 2), bool))
    return np.where(over & ~kept, np.minimum(ratio, np.float32(0.999)), ratio)


def block_max(image: np.ndarray, long_side: int | None = None) -> tuple[np.ndarray, int]:
    """(H, W) ``image`` shrunk to at most ``long_side`` (default
    :data:`gaslight_usd.fit.frame_edge.ANALYSIS_SIZE`) across by the maximum over
    square blocks of k x k pixels (the last row and column of blocks may be partial),
    and k."""
    from .fit.frame_edge import ANALYSIS_SIZE

    h, w = image.shape
    k = max(1, math.ceil(max(h, w) / (long_side or ANALYSIS_SIZE)))
    if k == 1:
        return image, 1
    bh, bw = math.ceil(h / k), math.ceil(w / k)
    padded = np.full((bh * k, bw * k), -np.inf, image.dtype)
    padded[:h, :w] = image
    return padded.reshape(bh, k, bw, k).max(axis=(1, 3)), k
