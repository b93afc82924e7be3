"""Environment maps rendered from a point: cube faces and lat-long panoramas.

Cube maps follow OpenEXR's ``envmap=cube`` (ImfEnvmap.cpp, CubeMap::direction
and pixelPosition): six square faces stacked vertically in the order
+X, -X, +Y, -Y, +Z, -Z. Within a face, OpenEXR puts the first and last pixel
centres exactly on the cube's edges (position / (size - 1) * 2 - 1), so each
face is a pinhole camera with f = (size - 1) / 2 and principal point size / 2
(pixel centres at +0.5): a field of view a little over 90 degrees. Per face
(image right, image down, view direction) in the world frame:

    +X: (+Z, -Y, +X)   -X: (-Z, -Y, -X)   +Y: (+X, -Z, +Y)
    -Y: (+X, +Z, -Y)   +Z: (-X, -Y, +Z)   -Z: (+X, -Y, -Z)

Lat-long panoramas follow :mod:`gaslight_usd.cameras` (OpenEXR envmap=latlong).
Both are drawn through many narrow views and resampled (:mod:`.sphere_views`: why a
90 degree face drawn directly gets large splats near the probe wrong), every pixel
an area average of sub-pixel directions (:func:`latlong_supersample`).

Splats whose centre lies nearer to the probe than ``near`` along a view's axis, or
behind it, are skipped by that view (a splat is never clipped in part). So a probe
placed inside a splat does not see that splat, and a splat right next to the probe
is left out rather than smeared over the whole sphere by the projection's
linearisation.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import replace
from functools import lru_cache

import numpy as np
import torch

from ..cameras import (
    CUBE_FACE_AXES,
    CUBE_FACES,
    PinholeCamera,
    bilinear,
    latlong_directions,
    sample_latlong,
)
from ..splats import SplatScene
from . import SplatParams, render
from .many import render_many
from .sphere_views import Feed, feeds, sphere_views

PROBE_NEAR = 1e-3


def cube_face_cameras(position, size: int) -> list[PinholeCamera]:
    """Six pinhole cameras at ``position`` (3,), one per face in CUBE_FACES order."""
    if size < 2:
        raise ValueError(f"cube face size must be at least 2, got {size}")
    pos = np.asarray(position, np.float64).reshape(3)
    f = (size - 1) / 2.0
    cams = []
    for name in CUBE_FACES:
        R = np.stack(CUBE_FACE_AXES[name])
        cams.append(PinholeCamera(size, size, f, f, size / 2.0, size / 2.0, R, -R @ pos,
                                  name=name))
    return cams


def _params(scene: SplatScene | SplatParams, device: str) -> SplatParams:
    if isinstance(scene, SplatParams):
        return scene.detach().to(device)
    return SplatParams.from_scene(scene, device=device)


def render_cube(scene: SplatScene | SplatParams, position, size: int, device: str = "cpu",
                near: float = PROBE_NEAR, supersample: int | None = None) -> np.ndarray:
    """Cube map (6, size, size, 3) float32 linear HDR seen from ``position``.

    ``supersample``: sub-pixels per axis (default: as a lat-long of four faces' width)."""
    if size < 2:
        raise ValueError(f"cube face size must be at least 2, got {size}")
    s = latlong_supersample(4 * size) if supersample is None else max(1, int(supersample))
    views, fed = _cube_lookup(int(size), s)
    pos = np.asarray(position, np.float64).reshape(3)
    out = _draw(_params(scene, device), pos, views, fed, 6 * (size * s) ** 2, near, None)
    out = out.reshape(6, size, s, size, s, 3).mean(axis=(2, 4), dtype=np.float64)
    return out.astype(np.float32)


@lru_cache(maxsize=4)
def _latlong_lookup(width: int) -> tuple[list[PinholeCamera], list[Feed]]:
    """The views (at the origin) and what each feeds of a lat-long ``width`` wide."""
    views = sphere_views(2.0 * math.pi / width)
    return views, feeds(views, latlong_directions(width, width // 2).reshape(-1, 3))


@lru_cache(maxsize=4)
def _cube_lookup(size: int, s: int) -> tuple[list[PinholeCamera], list[Feed]]:
    """The views and what each feeds of a cube map's faces at ``s`` x ``s`` sub-pixels
    a pixel: face k's sub-pixel (row, col) is direction ``k * (size s)^2 + row * size s
    + col``. A face's pixel centres span ``(size - 1) / 2`` of focal length (OpenEXR)."""
    fine = size * s
    sub = (np.arange(fine) + 0.5) / s  # sub-pixel centres in face pixels
    local = (sub - size / 2.0) / ((size - 1) / 2.0)
    gx, gy = np.meshgrid(local, local)
    cam_dirs = np.stack([gx, gy, np.ones_like(gx)], axis=-1).reshape(-1, 3)
    dirs = np.concatenate([cam_dirs @ np.stack(CUBE_FACE_AXES[name]) for name in CUBE_FACES])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    views = sphere_views(2.0 / ((size - 1) * s))
    return views, feeds(views, dirs)


VIEWS_PER_PASS = 24
"""Views drawn together on the CPU (:func:`.many.render_many`): bounds the images held."""


def _draw(params: SplatParams, pos: np.ndarray, views: list[PinholeCamera],
          fed: list[Feed], count: int, near: float, rotation: np.ndarray | None
          ) -> np.ndarray:
    """(count, 3) float32: every direction the views feed, seen from ``pos``."""
    placed = []
    for view in views:
        rot = np.asarray(view.R) if rotation is None else np.asarray(view.R) @ rotation
        placed.append(replace(view, R=rot, t=-rot @ pos))
    out = np.zeros((count, 3), np.float32)
    many = params.means.device.type == "cpu" and params.means.dtype == torch.float32
    with torch.no_grad():
        for start in range(0, len(placed), VIEWS_PER_PASS):
            group = placed[start:start + VIEWS_PER_PASS]
            if many:
                images = render_many(params, group, near=near)
            else:
                images = [render(params, v, background=0.0, near=near).image.cpu().numpy()
                          for v in group]
            for image, feed in zip(images, fed[start:start + VIEWS_PER_PASS], strict=True):
                out[feed.index] += feed.weight * bilinear(image, feed.x, feed.y, wrap_x=False)
    return out


SAMPLING_WIDTH = 2048
"""Lat-long width (0.18 degree pixels) a panorama is at least drawn at before it is
box-filtered to the width asked for (:func:`latlong_supersample`)."""
MAX_SUPERSAMPLE = 16


def latlong_supersample(width: int) -> int:
    """Sub-pixels per axis for a lat-long of ``width``: its pixels are area averages.

    Each lat-long pixel is drawn from ``s x s`` directions (the panorama at ``s``
    times the width, box-filtered down), not from one lookup. Why: a fitted light
    is a cluster of overlapping, nearly opaque splats far smaller than a coarse
    pixel; drawn at that pixel size every splat is widened to about a pixel
    (even with the antialiased mode's opacity compensation the cluster turns
    from opaque to translucent, so splats hidden behind others add their light)
    and the light gains power. Drawn at about the resolution it was fitted at
    and averaged, it keeps it. On the example's balanced fit the lamp seen from
    probes 1 and 2 in 512 x 256 panoramas carried 1.49x and 1.42x the true
    power drawn once per pixel, 0.90x and 1.02x at s = 4 (in its own pinhole
    views: 0.89-0.93x).
    """
    return max(1, min(MAX_SUPERSAMPLE, math.ceil(SAMPLING_WIDTH / max(int(width), 1))))


def render_latlong(scene: SplatScene | SplatParams, position, width: int,
                   device: str = "cpu", near: float = PROBE_NEAR,
                   supersample: int | None = None, rotation: np.ndarray | None = None
                   ) -> np.ndarray:
    """Lat-long panorama (width // 2, width, 3) float32 linear HDR from ``position``.

    ``supersample``: sub-pixels per axis (default :func:`latlong_supersample`).
    ``rotation``: the panorama's axes are those of a frame ``rotation`` @ x of the
    scene's (e.g. the true world of a scene solved by SfM in a frame of its own).
    """
    s = latlong_supersample(width) if supersample is None else max(1, int(supersample))
    if width % 2:
        s = 1  # an odd width's height (width // 2) has no s-fold refinement
    fine = int(width) * s
    pos = np.asarray(position, np.float64).reshape(3)
    params = _params(scene, device)
    key = _fine_key(params, pos, fine, near, rotation)
    out = _FINE_DRAWN.get(key)
    if out is None:
        out = _draw_fine(params, pos, fine, near, rotation)
        _FINE_DRAWN.clear()  # one kept: a run draws the same probe twice in a row at most
        _FINE_DRAWN[key] = out
    out = out.copy()
    if s > 1:
        out = out.reshape(width // 2, s, width, s, 3).mean(axis=(1, 3), dtype=np.float64)
    return out.astype(np.float32)


_FINE_DRAWN: dict[bytes, np.ndarray] = {}
"""The last fine panorama drawn (:func:`render_latlong`), by :func:`_fine_key`: ``run``'s
export draws the whole scene at the default probe for its light rig (256 wide, 8-fold)
and its ``hdri`` stage draws it again (1024 wide, 2-fold), both 2048 wide before the
box filter."""


def _fine_key(params: SplatParams, pos: np.ndarray, fine: int, near: float,
              rotation: np.ndarray | None) -> bytes:
    """A digest of everything a fine panorama depends on (splats' tensors included)."""
    h = hashlib.blake2b(digest_size=20)
    for t in (params.means, params.quats, params.log_scales, params.opacity_logits,
              params.sh_dc, params.sh_rest):
        a = t.detach().cpu().contiguous().numpy()
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    h.update(np.asarray(pos, np.float64).tobytes())
    h.update(np.asarray(rotation if rotation is not None else np.eye(3), np.float64).tobytes())
    h.update(f"{fine} {near!r} {params.antialiased} {params.means.device}".encode())
    return h.digest()


def _draw_fine(params: SplatParams, pos: np.ndarray, fine: int, near: float,
               rotation: np.ndarray | None) -> np.ndarray:
    """(fine // 2, fine, 3) float32 lat-long, one lookup per pixel."""
    views, fed = _latlong_lookup(fine)
    out = _draw(params, pos, views, fed, fine // 2 * fine, near, rotation)
    return out.reshape(fine // 2, fine, 3)


def _face_lookup(directions: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Directions (..., 3) -> face index and continuous pixel coordinates in that face."""
    d = np.asarray(directions, np.float64)
    axis = np.argmax(np.abs(d), axis=-1)
    sign_neg = np.take_along_axis(d, axis[..., None], -1)[..., 0] < 0
    face = axis * 2 + sign_neg
    axes = np.stack([np.stack(CUBE_FACE_AXES[n]) for n in CUBE_FACES])  # (6, 3, 3)
    basis = axes[face]  # (..., 3, 3): right, down, forward
    local = np.einsum("...ij,...j->...i", basis, d)
    f, c = (size - 1) / 2.0, size / 2.0
    x = f * local[..., 0] / local[..., 2] + c
    y = f * local[..., 1] / local[..., 2] + c
    return face, x, y


def cube_to_latlong(faces: np.ndarray, width: int) -> np.ndarray:
    """Resample a cube map (6, S, S, C) to a lat-long panorama (width // 2, width, C)."""
    faces = np.asarray(faces, np.float32)
    if faces.ndim != 4 or faces.shape[0] != 6 or faces.shape[1] != faces.shape[2]:
        raise ValueError(f"expected cube faces (6, S, S, C), got {faces.shape}")
    size = faces.shape[1]
    dirs = latlong_directions(width, width // 2)
    face, x, y = _face_lookup(dirs, size)
    # Sample all faces stacked vertically: face k occupies rows k*S .. (k+1)*S.
    x = np.clip(x, 0.5, size - 0.5)
    y = np.clip(y, 0.5, size - 0.5) + face * size
    stacked = faces.reshape(6 * size, size, -1)
    return bilinear(stacked, x, y, wrap_x=False)


def latlong_to_cube(image: np.ndarray, size: int) -> np.ndarray:
    """Resample a lat-long panorama (H, W, C) to cube faces (6, size, size, C)."""
    image = np.asarray(image, np.float32)
    out = []
    for cam in cube_face_cameras(np.zeros(3), size):
        out.append(sample_latlong(image, cam.ray_directions()))
    return np.stack(out)
