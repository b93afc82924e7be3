"""The power of clipped lights, inferred from the surfaces they light.

A photo that clips a lamp says only that the lamp is brighter than white; the
uplift's fill is a guess. The diffuse surfaces around it were measured, and
they carry the lamp's power: a matte surface point ``s`` with albedo ``rho_s``
has radiance

    L_s = rho_s / pi * (E_s + sum_j k_j D_js)

where ``E_s`` is the irradiance from every splat that is not a clipped light
(measured surfaces, unclipped lights), ``D_js`` the irradiance from light ``j``
as fitted and ``k_j`` the factor its fitted power is off by. Each term comes
from a small cube map rendered at the surface point with the fitted splats
(lights and the rest written into separate colour channels, so one render
gives all of them; occlusion by every splat included).

Albedo varies with the surface's texture, but it does not know where the lamp
is: with the right ``k`` the albedos ``pi L_s / (E_s + sum_j k_j D_js)`` do not
depend on how much of a point's light comes from the lamp. So ``k`` is chosen
to make the log-albedos as uniform as possible (least variance, trimmed of the
10 % worst points), subject to no albedo above 1. Points whose light is mostly
indirect pin the albedo scale, points near the lamp then pin ``k``; the
uncertainty (stops) is the spread of ``log2 k`` over bootstrap resamples of
the points. The estimate is fused with the uplift's (the fill, ``k = 1``, with
:data:`PREDICTOR_SIGMA_STOPS`) by inverse variances.

A light is a cluster of splats brighter than what the photos could record
where they saw them (the views' clip floors): see :func:`clipped_light_splats`.
Measured by ``gaslight2usd bench --suite chain`` (power errors per light).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..cameras import PinholeCamera, quaternion_to_matrix
from ..render import SplatParams, render
from ..render.envmap import cube_face_cameras, render_cube
from ..splats import SplatScene, rgb_to_sh_dc, sh_dc_to_rgb

PREDICTOR_SIGMA_STOPS = 1.5
"""How far the uplift's fill of a clipped light is typically off (stops, 1 sigma): the
fast predictor's median power error on real panoramas is about 2 stops before its
shrink (``gaslight2usd bench --suite uplift``)."""
CUBE_SIZE = 12
LIGHT_VIEW_SIZE = 24
SAMPLE_POINTS = 120
MAX_LIGHTS = 6
LOG2_K_RANGE = (-6.0, 10.0)
MIN_DIRECT_SHARE = 0.03
"""A light that gives the sampled surfaces less than this share of their light (median,
as fitted) cannot be weighed by them."""


@dataclass
class LightPower:
    """One clipped light and where its power came from."""

    position: np.ndarray
    splats: np.ndarray
    """Indices into the scene."""
    factor: float = 1.0
    """What its splats' radiance was multiplied by."""
    source: str = "predicted"
    """``predicted`` (the uplift's fill), ``inferred`` (the lit surfaces), or ``fused``."""
    uncertainty_stops: float = PREDICTOR_SIGMA_STOPS
    details: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {"position": [round(float(v), 4) for v in self.position],
                "splats": int(len(self.splats)), "factor": round(self.factor, 4),
                "power_source": self.source,
                "power_uncertainty_stops": round(self.uncertainty_stops, 3), **self.details}


def clipped_light_splats(scene: SplatScene, cameras: list[PinholeCamera],
                         floors: list[np.ndarray | None], weights: np.ndarray) -> np.ndarray:
    """Boolean mask of splats that only clipped pixels saw, brighter than the clip floor.

    A splat is a clipped light when, in the views whose frame holds its centre, most
    land on clipped pixels, and its luminance is at least half the floor there
    (what the photo recorded: anything dimmer was measurable and is a surface).
    """
    pos = scene.positions.astype(np.float64)
    lum = scene.base_colours @ weights
    hits = np.zeros(scene.count)
    seen = np.zeros(scene.count)
    bright = np.zeros(scene.count, bool)
    for cam, floor in zip(cameras, floors, strict=True):
        uv, z = cam.project(pos)
        inside = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & (uv[:, 1] >= 0) & \
                 (uv[:, 1] < cam.height)
        seen += inside
        if floor is None:
            continue
        h, w = floor.shape
        ix = np.clip((uv[inside, 0] * w / cam.width).astype(int), 0, w - 1)
        iy = np.clip((uv[inside, 1] * h / cam.height).astype(int), 0, h - 1)
        f = floor[iy, ix]
        idx = np.nonzero(inside)[0]
        hits[idx] += f > 0
        bright[idx[(f > 0) & (lum[idx] >= 0.5 * f)]] = True
    return bright & (hits >= 0.5 * np.maximum(seen, 1)) & (hits > 0)


def group_lights(scene: SplatScene, mask: np.ndarray, radius: float) -> list[np.ndarray]:
    """Clusters (index arrays) of the masked splats, linked within ``radius``; the
    brightest :data:`MAX_LIGHTS` by power (luminance x area x opacity)."""
    idx = np.nonzero(mask)[0]
    if not len(idx):
        return []
    tree = cKDTree(scene.positions[idx])
    graph = tree.sparse_distance_matrix(tree, radius, output_type="coo_matrix")
    count, labels = connected_components(graph, directed=False)
    power = (scene.base_colours[idx].sum(1) * scene.opacities[idx]
             * np.prod(scene.scales[idx], axis=1) ** (2 / 3))
    groups = [idx[labels == c] for c in range(count)]
    totals = np.array([power[labels == c].sum() for c in range(count)])
    return [groups[c] for c in np.argsort(-totals)[:MAX_LIGHTS]]


def surface_samples(scene: SplatScene, exclude: np.ndarray, count: int, rng: np.random.Generator,
                    eye: np.ndarray, measured: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices and unit normals of opaque flat splats to read the lit surfaces at.

    Only the first ``measured`` splats (the fit's; the backdrop's are guesses) that are
    not in ``exclude``; the normal is the shortest axis, turned towards ``eye``.
    """
    scales = scene.scales
    flat = scales.min(1) < 0.35 * np.median(scales, axis=1)
    ok = (scene.opacities > 0.6) & flat & ~exclude
    ok[measured:] = False
    cand = np.nonzero(ok)[0]
    if len(cand) > count:
        cand = np.sort(rng.choice(cand, count, replace=False))
    rot = quaternion_to_matrix(scene.rotations[cand])
    axis = np.argmin(scales[cand], axis=1)
    normals = np.take_along_axis(rot, axis[:, None, None].repeat(3, 1), 2)[..., 0]
    to_eye = eye - scene.positions[cand]
    normals *= np.sign(np.sum(normals * to_eye, axis=1, keepdims=True) + 1e-12)
    return cand, normals


def pixel_directions(cam: PinholeCamera) -> tuple[np.ndarray, np.ndarray]:
    """World directions ``(H W, 3)`` and solid angles ``(H W,)`` of a camera's pixels."""
    x, y = np.meshgrid(np.arange(cam.width) + 0.5, np.arange(cam.height) + 0.5)
    u, v = (x - cam.cx) / cam.fx, (y - cam.cy) / cam.fy
    d = np.stack([u, v, np.ones_like(u)], -1) @ cam.R  # camera -> world
    norm = np.linalg.norm(d, axis=-1)
    return (d / norm[..., None]).reshape(-1, 3), (1.0 / (cam.fx * cam.fy) / norm ** 3).ravel()


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
    cube_dirs, cube_omega = [], []
    for cam in cube_face_cameras(np.zeros(3), CUBE_SIZE):
        d, o = pixel_directions(cam)
        cube_dirs.append(d)
        cube_omega.append(o)
    cube_dirs, cube_omega = np.concatenate(cube_dirs), np.concatenate(cube_omega)
    out = np.full((len(points), 1 + len(groups)), np.nan)
    for p, (x, n, off) in enumerate(zip(points, normals, offsets, strict=True)):
        eye = x + n * off
        cube = render_cube(rest, eye, CUBE_SIZE, near=0.5 * off).reshape(-1, 3)
        out[p, 0] = float((np.clip(cube_dirs @ n, 0, None) * cube_omega) @ cube[:, 0])
        for j, (c, r) in enumerate(zip(centres, radii, strict=True)):
            dist = float(np.linalg.norm(c - eye))
            if dist < 2.0 * r:
                continue
            cam = aimed_camera(eye, c, math.asin(min(0.99, r / dist)) * 1.2, LIGHT_VIEW_SIZE)
            params = rest if j < 2 else extra[(j - 2) // 3]
            channel = 1 + j if j < 2 else (j - 2) % 3
            with torch.no_grad():
                img = render(params, cam, background=0.0, near=0.5 * off).image.cpu().numpy()
            d, o = pixel_directions(cam)
            out[p, 1 + j] = float((np.clip(d @ n, 0, None) * o) @
                                  img.reshape(-1, 3)[:, channel])
    return out


def albedo_spread(log2_k: np.ndarray, radiance: np.ndarray, irr: np.ndarray,
                  trim: float = 0.1) -> float:
    """Trimmed variance of the log-albedos for light factors ``2**log2_k``; infinite
    when an albedo would exceed 1."""
    total = irr[:, 0] + irr[:, 1:] @ (2.0 ** log2_k)
    albedo = math.pi * radiance / np.maximum(total, 1e-12)
    if np.quantile(albedo, 0.97) > 1.0:
        return math.inf
    la = np.log2(np.maximum(albedo, 1e-9))
    dev = np.abs(la - np.median(la))
    keep = dev <= np.quantile(dev, 1.0 - trim)
    return float(np.var(la[keep]))


def solve_factors(radiance: np.ndarray, irr: np.ndarray, grid_step: float = 0.125
                  ) -> np.ndarray:
    """``log2 k`` per light minimising :func:`albedo_spread` (coordinate grid search)."""
    lights = irr.shape[1] - 1
    k = np.zeros(lights)
    grid = np.arange(LOG2_K_RANGE[0], LOG2_K_RANGE[1] + 1e-9, grid_step)
    for _ in range(3 if lights > 1 else 1):
        for j in range(lights):
            scores = []
            for g in grid:
                trial = k.copy()
                trial[j] = g
                scores.append(albedo_spread(trial, radiance, irr))
            scores = np.asarray(scores)
            if np.isfinite(scores).any():
                k[j] = grid[int(np.argmin(scores))]
    return k


def infer_light_power(scene: SplatScene, cameras: list[PinholeCamera],
                      floors: list[np.ndarray | None], weights: np.ndarray, extent: float,
                      measured: int | None = None, seed: int = 0, bootstrap: int = 24
                      ) -> tuple[SplatScene, list[LightPower]]:
    """Rescale each clipped light's splats by the fused power factor (module docstring).

    ``extent``: the scene's size (lights are clusters linked within 2 % of it);
    ``measured``: how many leading splats the fit made (the rest is backdrop).
    Returns the rescaled scene and one :class:`LightPower` per light.
    """
    mask = clipped_light_splats(scene, cameras, floors, weights)
    groups = group_lights(scene, mask, 0.02 * extent)
    if not groups:
        return scene, []
    rng = np.random.default_rng(seed)
    eye = np.mean([c.center for c in cameras], axis=0)
    cand, normals = surface_samples(scene, mask, SAMPLE_POINTS, rng, eye,
                                    measured if measured is not None else scene.count)
    lights = [LightPower(position=scene.positions[g].mean(0), splats=g) for g in groups]
    if len(cand) < 20:
        for light in lights:
            light.details["note"] = "too few lit surfaces to infer its power"
        return scene, lights
    offsets = 2.0 * scene.scales[cand].max(1) + 0.01 * extent
    irr = gather_irradiance(scene, groups, scene.positions[cand].astype(np.float64), normals,
                            offsets, weights)
    radiance = scene.base_colours[cand] @ weights
    useful = np.all(np.isfinite(irr), axis=1) & (irr[:, 0] + irr[:, 1:].sum(1) > 0) & \
        (radiance > 0)
    radiance, irr = radiance[useful], irr[useful]
    if len(radiance) < 20:
        for light in lights:
            light.details["note"] = "too few lit surfaces to infer its power"
        return scene, lights
    best = solve_factors(radiance, irr)
    boots = []
    for _ in range(bootstrap):
        pick = rng.integers(0, len(radiance), len(radiance))
        boots.append(solve_factors(radiance[pick], irr[pick], grid_step=0.25))
    spread = np.std(np.asarray(boots), axis=0) if boots else np.full(len(groups), 9.0)
    out = scene.subset(np.arange(scene.count))
    out.sh = scene.sh.copy()
    for j, light in enumerate(lights):
        # judged at the solution: a light the fit left 5 stops short barely lights the
        # surfaces as fitted, and that is what the factor corrects
        lit = irr[:, 1:] * 2.0 ** best[None]
        lit_share = float(np.median(lit[:, j] / np.maximum(irr[:, 0] + lit.sum(1), 1e-12)))
        light.details.update({"inferred_log2_factor": round(float(best[j]), 3),
                              "median_direct_share": round(lit_share, 3),
                              "surface_points": int(len(radiance))})
        at_bound = not LOG2_K_RANGE[0] < best[j] < LOG2_K_RANGE[1]
        if at_bound or lit_share < MIN_DIRECT_SHARE:
            # the surfaces barely see this light (or the search ran off its range):
            # its power is not identifiable from them; the fill stands
            light.details["note"] = "lights too little of the measured surfaces to infer"
            continue
        sigma_inf = max(float(spread[j]), 0.1)
        w_inf, w_pred = 1 / sigma_inf ** 2, 1 / PREDICTOR_SIGMA_STOPS ** 2
        log2_k = (w_inf * best[j]) / (w_inf + w_pred)
        light.factor = float(2.0 ** log2_k)
        light.uncertainty_stops = float((w_inf + w_pred) ** -0.5)
        light.source = "inferred" if w_inf > 4 * w_pred else "fused"
        light.details["inferred_sigma_stops"] = round(sigma_inf, 3)
        out.sh[light.splats] = scaled_sh(scene.sh[light.splats], light.factor)
    return out, lights


def scaled_sh(sh: np.ndarray, factor: float) -> np.ndarray:
    """SH coefficients ``(N, K, 3)`` whose radiance is ``factor`` x theirs (3DGS's DC
    carries a +0.5 offset, so the DC term is rescaled through the colour)."""
    out = sh * np.float32(factor)
    out[:, 0] = rgb_to_sh_dc(sh_dc_to_rgb(sh[:, 0]) * np.float32(factor))
    return out.astype(np.float32)
