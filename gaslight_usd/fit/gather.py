"""The light arriving at points of a fitted scene: from the room at large and from each
clipped light (:mod:`gaslight_usd.fit.power` weighs the lights with it).

Everything but the lights comes from a coarse cube map at each point (it is smooth); each
light from a narrow view aimed at it, fine enough that its small splats keep their
power. Every splat occludes. Splats are drawn in the antialiased mode with
view-independent colours (one channel a source), so a footprint keeps its integral at
any pixel size.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from ..cameras import PinholeCamera
from ..render import SplatParams, render
from ..render.envmap import cube_face_cameras
from ..render.many import render_many
from ..splats import SplatScene, rgb_to_sh_dc

CUBE_SIZE = 12
LIGHT_VIEW_SIZE = 24
"""The least size (pixels across) of the view aimed at a light (:func:`light_view_size`)."""
MAX_LIGHT_VIEW_SIZE = 192
LIGHT_PIXELS_PER_GRAIN = 3.0
"""How many pixels a light's typical splat (its median largest scale) spans at least in
the view aimed at it. Coarser, a cluster of tiny nearly opaque splats turns translucent
(even in the antialiased mode each splat is widened to about a pixel and its opacity
cut), the splats behind shine through and the light gains power, and its factor comes
out low (a ``balanced`` fit's small bulb splats at a fixed 24 pixels:
``docs/measurements.md``, session 22)."""
POINTS_PER_BATCH = 64
"""Surface points whose cube maps are drawn in one pass (:mod:`gaslight_usd.render.many`)."""


def depth_map(scene: SplatScene, camera: PinholeCamera) -> np.ndarray:
    """``(H, W)`` alpha-weighted depth of the splats seen by ``camera`` (inf where none)."""
    z = (scene.positions.astype(np.float64) @ camera.R.T + camera.t)[:, 2]
    params = channel_scene(scene, np.repeat(np.maximum(z, 0.0)[:, None], 3, 1))
    with torch.no_grad():
        out = render(params, camera, background=0.0)
    alpha = out.alpha.cpu().numpy()
    return np.where(alpha > 0.5, out.image[..., 0].cpu().numpy() / np.maximum(alpha, 1e-6),
                    np.inf)




def pixel_directions(cams: list[PinholeCamera]) -> tuple[np.ndarray, np.ndarray]:
    """World directions ``(B, H W, 3)`` and solid angles ``(B, H W)`` of the pixels of
    ``B`` cameras of one size."""
    x, y = np.meshgrid(np.arange(cams[0].width) + 0.5, np.arange(cams[0].height) + 0.5)
    intr = np.array([[c.fx, c.fy, c.cx, c.cy] for c in cams], np.float64)[:, None]
    u = (x.ravel()[None] - intr[..., 2]) / intr[..., 0]
    v = (y.ravel()[None] - intr[..., 3]) / intr[..., 1]
    rays = np.stack([u, v, np.ones_like(u)], -1)  # (B, HW, 3) camera frame
    d = np.einsum("bpi,bij->bpj", rays, np.stack([c.R for c in cams]))  # camera -> world
    norm = np.linalg.norm(d, axis=-1)
    return d / norm[..., None], 1.0 / (intr[..., 0] * intr[..., 1]) / norm ** 3


def aimed_camera(position: np.ndarray, target: np.ndarray, half_angle: float, size: int
                 ) -> PinholeCamera:
    """A square pinhole at ``position`` looking at ``target``, ``2 half_angle`` wide."""
    fwd = (target - position) / np.linalg.norm(target - position)
    up = np.array([0.0, 1.0, 0.0]) if abs(fwd[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    rot = np.stack([right, np.cross(fwd, right), fwd])
    f = (size / 2.0) / math.tan(half_angle)
    return PinholeCamera(size, size, f, f, size / 2.0, size / 2.0, rot, -rot @ position)


def light_view_size(half_angles: np.ndarray, distances: np.ndarray, grain: float) -> int:
    """Pixels across the views aimed at a light from ``distances`` with ``half_angles``,
    so that its typical splat (``grain`` across, scene units) spans
    :data:`LIGHT_PIXELS_PER_GRAIN` pixels in each, within [:data:`LIGHT_VIEW_SIZE`,
    :data:`MAX_LIGHT_VIEW_SIZE`]."""
    if len(distances) == 0 or grain <= 0:
        return LIGHT_VIEW_SIZE
    needed = 2.0 * np.tan(half_angles) * distances * LIGHT_PIXELS_PER_GRAIN / grain
    return int(np.clip(math.ceil(float(needed.max())), LIGHT_VIEW_SIZE, MAX_LIGHT_VIEW_SIZE))


def channel_scene(scene: SplatScene, channels: np.ndarray) -> SplatParams:
    """The scene's geometry with view-independent colours ``channels`` (N, 3), drawn in the
    antialiased mode (a splat's footprint keeps its integral at any pixel size)."""
    sh = np.zeros((scene.count, 1, 3), np.float32)
    sh[:, 0] = rgb_to_sh_dc(channels.astype(np.float32))
    return SplatParams.from_scene(SplatScene(scene.positions, scene.rotations, scene.log_scales,
                                             scene.opacity_logits, sh,
                                             metadata={"antialiased": True}))


def gather_irradiance(scene: SplatScene, groups: list[np.ndarray], points: np.ndarray,
                      normals: np.ndarray, offsets: np.ndarray, weights: np.ndarray
                      ) -> np.ndarray:
    """``(P, 1 + L)`` irradiance luminance at each point: from everything but the
    clipped lights (a coarse cube map: it is smooth), then from each light as fitted
    (a narrow view aimed at the light, fine enough that its small splats keep their
    power); every splat occludes. NaN where a point is too close to a light."""
    lum = scene.base_colours @ weights
    is_light = np.zeros(scene.count, bool)
    for g in groups:
        is_light[g] = True
    chans = np.zeros((scene.count, 3), np.float32)
    chans[~is_light, 0] = lum[~is_light]
    for j, g in enumerate(groups[:2]):
        chans[g, 1 + j] = lum[g]
    rest = channel_scene(scene, chans)
    extra = []
    for start in range(2, len(groups), 3):
        more = np.zeros((scene.count, 3), np.float32)
        for c, g in enumerate(groups[start:start + 3]):
            more[g, c] = lum[g]
        extra.append(channel_scene(scene, more))
    centres = [scene.positions[g].astype(np.float64).mean(0) for g in groups]
    radii = [float(np.linalg.norm(scene.positions[g] - c, axis=1).max()
                   + 3.0 * scene.scales[g].max()) for g, c in zip(groups, centres, strict=True)]
    grains = [float(np.median(scene.scales[g].max(1))) for g in groups]
    cube_dirs, cube_omega = pixel_directions(cube_face_cameras(np.zeros(3), CUBE_SIZE))
    cube_dirs, cube_omega = cube_dirs.reshape(-1, 3), cube_omega.ravel()
    out = np.full((len(points), 1 + len(groups)), np.nan)
    eyes = points + normals * offsets[:, None]
    nears = 0.5 * offsets
    for lo in range(0, len(points), POINTS_PER_BATCH):
        part = slice(lo, min(lo + POINTS_PER_BATCH, len(points)))
        faces = [cam for eye in eyes[part] for cam in cube_face_cameras(eye, CUBE_SIZE)]
        cubes = render_many(rest, faces, near=np.repeat(nears[part], 6))
        cubes = cubes[..., 0].reshape(-1, 6 * CUBE_SIZE * CUBE_SIZE)
        cosine = np.clip(normals[part] @ cube_dirs.T, 0, None)
        out[part, 0] = np.sum(cosine * cube_omega * cubes, axis=1)
    for j, (c, r, grain) in enumerate(zip(centres, radii, grains, strict=True)):
        dist = np.linalg.norm(c - eyes, axis=1)
        aimed = np.flatnonzero(dist >= 2.0 * r)
        halves = np.arcsin(np.minimum(0.99, r / dist[aimed])) * 1.2
        size = light_view_size(halves, dist[aimed], grain)
        cams = [aimed_camera(eyes[p], c, float(h), size)
                for p, h in zip(aimed, halves, strict=True)]
        params = rest if j < 2 else extra[(j - 2) // 3]
        channel = 1 + j if j < 2 else (j - 2) % 3
        if not cams:
            continue
        images = render_many(params, cams, near=nears[aimed])
        d, o = pixel_directions(cams)
        cosine = np.clip(np.einsum("bpi,bi->bp", d, normals[aimed]), 0, None)
        out[aimed, 1 + j] = np.sum(cosine * o * images[..., channel].reshape(len(cams), -1),
                                   axis=1)
    return out
