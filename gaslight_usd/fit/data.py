"""The fitting data: HDR views matched to posed cameras, checked before any work.

HDR views are ``<photo stem>.exr`` files; each is matched to the posed image of
the same stem. Missing views, extra posed images without a view, or a view
whose size is not its camera's (or the camera's shrunk evenly, as ``run``
uplifts photos at the working size) fail with one InputError naming the folder
and what disagrees, before a pixel is read. Views are read one at a time and
shrunk to the fit's working size (area average, :mod:`gaslight_usd.resize`)
with their intrinsics scaled to match, so memory grows with the working size,
not with the photos' megapixels.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from ..cameras import PinholeCamera
from ..colour import luminance_weights
from ..errors import InputError
from ..imageio import read_channel, read_header, read_image
from ..poses import read_poses
from ..poses.colmap import ColmapModel
from ..poses.views import CLIP_FLOOR_CHANNEL, DARK_CEILING_CHANNEL, hdr_view_paths
from ..resize import area_resize, fit_within
from ..sightings import PeakMap, peak_map

RING_RATIO = 64.0
"""A view that measured a light over this many times the set's white (a bulb's dark
frame measures thousands; photos alone, auto-exposed, stayed under 16 on the chain
bench's six rooms) makes the measured ring round the clipped regions a bound
(:meth:`FitData.loss_floors`)."""


@dataclass
class FitData:
    """Posed HDR views at fitting resolution (linear, float32)."""

    names: list[str]
    cameras: list[PinholeCamera]
    images: list[np.ndarray]
    """(H, W, 3) float32 linear HDR, one per camera."""
    model: ColmapModel
    colour_space: str
    attributes: dict[str, Any] = field(default_factory=dict)
    """Header facts of the views (exposure scale, method...), from the first view."""
    downscale: int = 1
    paths: list[Path] = field(default_factory=list)
    """The full-resolution HDR view of each camera (empty for in-memory data)."""
    floors: list[np.ndarray | None] = field(default_factory=list)
    """Per view ``(H, W)`` lower bounds on the luminance where its photo clipped, 0 where
    it measured (see :func:`fit_floor`); empty or None: every pixel was measured."""

    ceilings: list[np.ndarray | None] = field(default_factory=list)
    """Per view ``(H, W)`` upper bounds on the luminance where its photo crushed to black,
    0 where it measured (see :func:`fit_ceiling`); empty or None: none crushed."""

    peaks: list[PeakMap] = field(default_factory=list)
    """Per view its luminance peaks from the full-size view (:func:`peak_map`), for
    finding small lights the working size averages away; empty for in-memory data."""

    def light_views(self) -> list[np.ndarray | PeakMap]:
        """Per view what to find its lights in: its full-size peaks when read from
        files, else its image at fitting size."""
        if len(self.peaks) == len(self.images):
            return list(self.peaks)
        return list(self.images)

    def floor(self, index: int) -> np.ndarray | None:
        """View ``index``'s clip floor, None when it has no clipped pixel."""
        if index >= len(self.floors) or self.floors[index] is None:
            return None
        f = self.floors[index]
        return f if bool(np.any(f > 0)) else None

    def ceiling(self, index: int) -> np.ndarray | None:
        """View ``index``'s dark ceiling, None when its photo crushed no pixel."""
        if index >= len(self.ceilings) or self.ceilings[index] is None:
            return None
        c = self.ceilings[index]
        return c if bool(np.any(c > 0)) else None

    left_out: list[str] = field(default_factory=list)
    """HDR views (stems) with no pose, left out of the fit (e.g. SfM did not register them)."""

    def measures_highlights(self, factor: float = 2.0) -> list[int]:
        """Views that measured, unclipped, light brighter than ``factor`` x the set's
        white (the median over clipped views of their brightest clip floor).

        Such a view (a darker frame shot for the lights, or an auto-exposure that
        dropped) is the only measurement of a light every other photo clipped, so the
        fit must train on it: held out, it would leave that light to the bounds and
        the uplift's guess. Empty when no view clipped (the white is unknown).
        """
        whites = [float(f.max()) for f in (self.floor(i) for i in range(len(self.images)))
                  if f is not None]
        if not whites:
            return []
        white = float(np.median(whites))
        weights = luminance_weights(self.colour_space)
        keep = []
        for i, image in enumerate(self.images):
            lum = image @ weights.astype(np.float32)
            floor = self.floor(i)
            measured = lum if floor is None else lum[floor <= 0]
            if measured.size and float(measured.max()) > factor * white:
                keep.append(i)
        return keep

    def loss_floors(self) -> list[np.ndarray | None]:
        """Per view the clip floor the fit's loss holds (:meth:`floor`), with the
        measured ring of pixels round each clipped region a bound too (at its measured
        luminance) where some view measured a light over :data:`RING_RATIO` x the
        set's white (a dark frame of a bulb).

        The photo that clips a bulb measures the pixels right round it; a splat as bright
        as the dark frame measured the bulb spreads a pixel-wide tail over that ring at
        the fitting size (the antialiasing filter), which those measurements punish far
        more than the dark frame's own black (a bound a few whites high) does, so the fit
        held the bulb 0.3-1.35 stops under what the dark frame measured (``gaslight2usd
        bench --suite chain --method "recursive + extra dark frames"``: `bulb:11`'s
        drawn 1.53 stops under its dark frame at the fitting size). As a bound, the ring
        still keeps its light from going dark. Sets without such a view keep their
        floors (the ring's freedom cost the photos alone up to 19 dB)."""
        floors = [self.floor(i) for i in range(len(self.images))]
        if not self.measures_highlights(RING_RATIO):
            return floors
        weights = luminance_weights(self.colour_space or None, fallback=True)
        out: list[np.ndarray | None] = []
        for floor, image in zip(floors, self.images, strict=True):
            if floor is None:
                out.append(None)
                continue
            clipped = floor > 0
            ring = ndimage.binary_dilation(clipped, np.ones((3, 3), bool)) & ~clipped
            lum = image @ weights.astype(np.float32)
            out.append(np.where(ring, np.maximum(lum, 1e-6), floor).astype(np.float32))
        return out

    def split(self, holdout_every: int) -> tuple[list[int], list[int]]:
        """Training and held-out view indices (every ``holdout_every``-th held out).

        A view that :meth:`measures_highlights` is never held out: the nearest other
        view (the next one, then the one before) is held out in its place.
        """
        n = len(self.cameras)
        if holdout_every <= 1 or n < 3:
            return list(range(n)), []
        keep = set(self.measures_highlights())
        held: list[int] = []
        for slot in range(holdout_every // 2, n, holdout_every):
            for i in sorted(range(n), key=lambda j: (abs(j - slot), j < slot)):
                if i not in keep and i not in held:
                    held.append(i)
                    break
        held = sorted(held)
        return [i for i in range(n) if i not in held], held


def scale_camera(cam: PinholeCamera, factor: int) -> PinholeCamera:
    """The camera for an image downscaled by ``factor`` (pixel centres kept at +0.5)."""
    return PinholeCamera(cam.width // factor, cam.height // factor, cam.fx / factor,
                         cam.fy / factor, cam.cx / factor, cam.cy / factor, cam.R, cam.t,
                         name=cam.name)


def scale_camera_to(cam: PinholeCamera, width: int, height: int) -> PinholeCamera:
    """The camera for its image area-resized to ``width`` x ``height`` (pixel centres at
    +0.5: ``x`` maps to ``x * width / cam.width``, so focal lengths and principal point
    scale by the same ratios)."""
    sx, sy = width / cam.width, height / cam.height
    return PinholeCamera(width, height, cam.fx * sx, cam.fy * sy, cam.cx * sx, cam.cy * sy,
                         cam.R, cam.t, name=cam.name)


def evenly_shrunk(width: int, height: int, cam: PinholeCamera) -> bool:
    """Whether a ``width`` x ``height`` view is its camera's image shrunk evenly (each
    side the camera's times one ratio, rounded), as the uplift writes working-size views."""
    if (width, height) == (cam.width, cam.height):
        return True
    if width > cam.width or height > cam.height:
        return False
    return fit_within(cam.width, cam.height, max(width, height)) == (width, height)


def box_downscale(image: np.ndarray, factor: int) -> np.ndarray:
    if factor == 1:
        return image
    h, w = (image.shape[0] // factor) * factor, (image.shape[1] // factor) * factor
    c = image.shape[2]
    return image[:h, :w].reshape(h // factor, factor, w // factor, factor, c).mean(
        axis=(1, 3)).astype(np.float32)


def fit_floor(floor: np.ndarray, image: np.ndarray, weights: np.ndarray,
              size: tuple[int, int], downscale: int = 1) -> np.ndarray:
    """A full-size clip floor at fitting resolution (``size`` = (width, height) of the
    area resample, then the integer ``downscale``).

    A fitting pixel that covers any clipped photo pixel is a bound: the mean, over
    its photo pixels, of the clipped ones' floors and the measured ones' luminance
    (a lower bound on its mean luminance). Pixels with nothing clipped get 0.
    """
    clipped = floor > 0
    bound = np.where(clipped, floor, image @ weights.astype(np.float32))[..., None]
    low = box_downscale(area_resize(bound.astype(np.float32), *size), downscale)[..., 0]
    share = box_downscale(area_resize(clipped.astype(np.float32)[..., None], *size),
                          downscale)[..., 0]
    return np.where(share > 0, np.maximum(low, 1e-6), 0.0).astype(np.float32)


CRUSHED_SHARE = 0.5
"""A fitting pixel is bounded above (:func:`fit_ceiling`) where at least this share of
its photo pixels were crushed to black; with fewer it stays a measurement, the crushed
ones counted at their (near-zero) recorded value."""


def fit_ceiling(ceiling: np.ndarray, image: np.ndarray, weights: np.ndarray,
                size: tuple[int, int], downscale: int = 1) -> np.ndarray | None:
    """A full-size dark ceiling at fitting resolution (as :func:`fit_floor`), or None
    where no fitting pixel is bounded: the mean, over the fitting pixel's photo pixels,
    of the crushed ones' ceilings and the measured ones' luminance (an upper bound on its
    mean luminance), where :data:`CRUSHED_SHARE` of them were crushed; 0 elsewhere."""
    crushed = ceiling > 0
    bound = np.where(crushed, ceiling, image @ weights.astype(np.float32))[..., None]
    high = box_downscale(area_resize(bound.astype(np.float32), *size), downscale)[..., 0]
    share = box_downscale(area_resize(crushed.astype(np.float32)[..., None], *size),
                          downscale)[..., 0]
    out = np.where(share >= CRUSHED_SHARE, np.maximum(high, 1e-9), 0.0).astype(np.float32)
    return out if bool(np.any(out > 0)) else None


def match_views(hdr_dir: Path, model: ColmapModel, left_out: list[str] | None = None
                ) -> list[tuple[PinholeCamera, Path]]:
    """Pair each posed camera with its EXR by stem; InputError on any disagreement.

    With a ``left_out`` list, views without a pose (photos SfM could not
    register) are named in it and skipped instead of failing the fit.
    """
    exrs = {p.stem: p for p in hdr_view_paths(hdr_dir)}
    posed = {Path(c.name).stem: c for c in model.cameras}
    missing = sorted(set(posed) - set(exrs))
    unposed = sorted(set(exrs) - set(posed))
    if missing:
        raise InputError(f"{len(missing)} posed image(s) have no HDR view: "
                         f"{', '.join(missing[:5])}{' ...' if len(missing) > 5 else ''} "
                         f"(expected <photo stem>.exr)", hdr_dir)
    if unposed and left_out is not None and len(unposed) < len(exrs):
        left_out.extend(unposed)
    elif unposed:
        raise InputError(f"{len(unposed)} HDR view(s) have no pose: "
                         f"{', '.join(unposed[:5])}{' ...' if len(unposed) > 5 else ''}",
                         hdr_dir)
    pairs = []
    for stem in sorted(posed):
        cam, path = posed[stem], exrs[stem]
        spec = read_header(path)
        if not evenly_shrunk(spec.width, spec.height, cam):
            raise InputError(f"view is {spec.width}x{spec.height} but its camera "
                             f"{cam.name!r} is {cam.width}x{cam.height} (nor that size "
                             "shrunk evenly)", path)
        pairs.append((cam, path))
    return pairs


def check_overlap(cameras: list[PinholeCamera], points: np.ndarray | None = None) -> None:
    """Fail when some view shares no visible region with any other view.

    Each camera's frustum is sampled on a 5x5 grid of rays at depths spanning
    the scene (the sparse points' depths when present, else 0.1x to 10x the
    camera spread); a view overlaps another when some of its samples project
    inside that view in front of it.
    """
    n = len(cameras)
    if n < 2:
        raise InputError("fitting needs at least 2 posed HDR views")
    centres = np.array([c.center for c in cameras])
    spread = float(np.linalg.norm(centres - centres.mean(0), axis=1).max())
    if points is not None and len(points) >= 8:
        d = np.linalg.norm(points - centres.mean(0), axis=1)
        depths = np.quantile(d, [0.05, 0.25, 0.5, 0.75, 0.95])
    else:
        base = max(spread, 1e-3)
        depths = base * np.geomspace(0.1, 10.0, 7)
    g = (np.arange(5) + 0.5) / 5
    samples = []
    for cam in cameras:
        px = np.stack(np.meshgrid(g * cam.width, g * cam.height), -1).reshape(-1, 2)
        rays = np.stack([(px[:, 0] - cam.cx) / cam.fx, (px[:, 1] - cam.cy) / cam.fy,
                         np.ones(len(px))], -1) @ cam.R
        samples.append((cam.center + rays[None] * depths[:, None, None]).reshape(-1, 3))
    lonely = []
    for i, pts in enumerate(samples):
        seen = False
        for j, other in enumerate(cameras):
            if j == i:
                continue
            uv, z = other.project(pts)
            inside = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < other.width) & \
                     (uv[:, 1] >= 0) & (uv[:, 1] < other.height)
            if inside.any():
                seen = True
                break
        if not seen:
            lonely.append(cameras[i].name)
    if lonely:
        raise InputError(f"view(s) {', '.join(lonely[:5])} overlap no other view: splats "
                         "cannot be fitted to a region only one photo sees")


def load_view(path: Path, cam: PinholeCamera, working_size: int = 0, downscale: int = 1
              ) -> tuple[np.ndarray, PinholeCamera, Any, np.ndarray | None, PeakMap,
                         np.ndarray | None]:
    """One HDR view at fitting size, its camera to match, the image read, its clip
    floor at fitting size (None when its photo clipped nothing, see :func:`fit_floor`),
    its full-size luminance peaks (:func:`gaslight_usd.sightings.peak_map`, specks
    over its own white removed: the median of its full-size clip floors) and its dark
    ceiling at fitting size (None when its photo crushed nothing, :func:`fit_ceiling`).

    The view's camera is ``cam`` scaled to the view's own size (working-size
    views from ``run``), then both are shrunk so the long side is at most
    ``working_size`` (0: the view's size), then by the integer ``downscale``.
    The full-size pixels are dropped on return: one view at a time is held.
    """
    img = read_image(path)
    h, w = img.pixels.shape[:2]
    cam = scale_camera_to(cam, w, h)
    size = fit_within(w, h, working_size)
    full = np.maximum(img.pixels, 0.0)
    pixels = area_resize(full, *size)
    cam = scale_camera_to(cam, *size)
    pixels = box_downscale(pixels, downscale)
    floor = read_channel(path, CLIP_FLOOR_CHANNEL)
    weights = luminance_weights(img.colour_space, fallback=True)
    if floor is not None and np.any(floor > 0):
        peaks = peak_map(full, weights, float(np.median(floor[floor > 0])), floor > 0)
        floor = fit_floor(floor, full, weights, size, downscale)
    else:
        peaks = peak_map(full, weights, None)
        floor = None
    ceiling = read_channel(path, DARK_CEILING_CHANNEL)
    if ceiling is not None and np.any(ceiling > 0):
        ceiling = fit_ceiling(ceiling, full, weights, size, downscale)
    else:
        ceiling = None
    img.pixels = np.empty((0, 0, 3), np.float32)
    return (np.ascontiguousarray(pixels, np.float32), scale_camera(cam, downscale), img,
            floor, peaks, ceiling)


def load_fit_data(hdr_dir: str | Path, poses: str | Path, downscale: int = 1,
                  working_size: int = 0) -> FitData:
    """Read poses and HDR views, check they agree and overlap, shrink to the working size
    (long side, 0: the views' own) and then by the integer ``downscale``."""
    hdr_dir = Path(hdr_dir)
    model = read_poses(poses)
    left_out: list[str] = []
    pairs = match_views(hdr_dir, model, left_out)
    check_overlap([c for c, _ in pairs], model.points)
    names, cams, images, paths, floors, peaks, ceilings = [], [], [], [], [], [], []
    space, attrs = "", {}
    for cam, path in pairs:
        paths.append(path)
        pixels, scaled, img, floor, peak, ceiling = load_view(path, cam, working_size,
                                                              downscale)
        if not space:
            space = img.colour_space
            attrs = {k: v for k, v in img.metadata.items() if k.startswith("gaslight:")}
        names.append(Path(cam.name).stem)
        cams.append(scaled)
        images.append(pixels)
        floors.append(floor)
        peaks.append(peak)
        ceilings.append(ceiling)
    return FitData(names=names, cameras=cams, images=images, model=model, colour_space=space,
                   attributes=attrs, downscale=downscale, paths=paths, floors=floors,
                   left_out=left_out, peaks=peaks, ceilings=ceilings)
