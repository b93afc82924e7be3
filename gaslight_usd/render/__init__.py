"""The project's splat renderer, shared by fitting and HDRI rendering.

One public function, :func:`render`: differentiable, tile-based, front-to-back
alpha compositing of projected 3D Gaussians (EWA splatting as in 3DGS) with SH
view-dependent colour. Projection and SH are vectorised torch; the compositing
runs as compiled CPU kernels (:mod:`.rasterize_numba`, 2.4-3.9x faster than
torch here) for float32 on the CPU, and as pure vectorised torch
(:mod:`.rasterize`) on other devices or when ``GASLIGHT_RASTERIZER=torch``.
:func:`render_reference` is the dense every-pixel-by-every-splat version both
are tested against.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import torch

from ..cameras import PinholeCamera
from ..splats import SplatScene
from .params import SplatParams
from .project import DEFAULT_NEAR, Projected, project
from .rasterize import TILE, rasterize, rasterize_dense
from .sh import eval_sh

__all__ = ["RenderOutput", "SplatParams", "eval_sh", "rasterizer_for", "render",
           "render_reference"]


@dataclass
class RenderOutput:
    """What :func:`render` returns.

    - ``image``   (H, W, 3) float32 linear HDR colour, background composited
    - ``alpha``   (H, W) accumulated opacity in [0, 1]
    - ``means2d`` (M, 2) screen positions of the M splats in view (grad retained
      when rendering with gradients: the view-space gradient densification uses)
    - ``index``   (M,) which of the N input splats those are
    """

    image: torch.Tensor
    alpha: torch.Tensor
    means2d: torch.Tensor
    index: torch.Tensor


def _as_params(scene_or_params: SplatScene | SplatParams, device: str | torch.device | None
               ) -> SplatParams:
    if isinstance(scene_or_params, SplatParams):
        return scene_or_params if device is None else scene_or_params.to(device)
    return SplatParams.from_scene(scene_or_params, device=device or "cpu")


RASTERIZER_ENV = "GASLIGHT_RASTERIZER"
"""``numba`` (the default on the CPU) or ``torch`` (the default elsewhere)."""
RASTERIZERS = ("numba", "torch")


def rasterizer_for(device: torch.device, dtype: torch.dtype):
    """The compositing function for tensors on ``device``: numba kernels for float32 on
    the CPU, vectorised torch otherwise (or wherever ``$GASLIGHT_RASTERIZER=torch``)."""
    wanted = os.environ.get(RASTERIZER_ENV, "").strip().lower() or None
    if wanted is not None and wanted not in RASTERIZERS:
        raise ValueError(f"${RASTERIZER_ENV}={wanted!r}: expected one of "
                         + ", ".join(RASTERIZERS))
    if wanted != "torch" and torch.device(device).type == "cpu" and dtype == torch.float32:
        from .rasterize_numba import rasterize_numba

        return rasterize_numba
    if wanted == "numba":
        raise ValueError(f"${RASTERIZER_ENV}=numba needs float32 tensors on the CPU")
    return rasterize


def _background(background, device) -> torch.Tensor:
    bg = torch.as_tensor(background, dtype=torch.float32, device=device).reshape(-1)
    if bg.numel() not in (1, 3):
        raise ValueError("background must be a scalar or 3 values")
    return bg.expand(3) if bg.numel() == 1 else bg


def _project(params: SplatParams, camera: PinholeCamera, sh_degree: int | None,
             near: float, pose: tuple[torch.Tensor, torch.Tensor] | None = None
             ) -> Projected:
    return project(params.means, params.quats, params.log_scales, params.opacity_logits,
                   params.sh, camera, sh_degree=sh_degree, near=near, pose=pose,
                   antialiased=params.antialiased)


def render(scene_or_params: SplatScene | SplatParams, camera: PinholeCamera,
           background: float | tuple[float, float, float] | torch.Tensor = 0.0,
           sh_degree: int | None = None, near: float = DEFAULT_NEAR,
           device: str | torch.device | None = None, tile: int = TILE,
           pose: tuple[torch.Tensor, torch.Tensor] | None = None) -> RenderOutput:
    """Render splats seen by a pinhole camera (COLMAP conventions).

    Args:
        scene_or_params: a :class:`~gaslight_usd.splats.SplatScene` (converted,
            no gradients) or a :class:`SplatParams` whose tensors may require
            grad: ``means`` (N, 3), ``quats`` (N, 4) w x y z, ``log_scales``
            (N, 3), ``opacity_logits`` (N,), ``sh_dc`` (N, 3), ``sh_rest``
            (N, K - 1, 3) with K = (degree + 1)**2.
        camera: ``width`` x ``height`` pinhole, world-to-camera R (3, 3), t (3,);
            pixel centres at integer + 0.5.
        background: scalar or (3,) linear colour behind the splats.
        sh_degree: SH degree to evaluate (default: all stored); lower values use
            only the first (degree + 1)**2 coefficients.
        near: splats whose centre has camera z <= near are skipped (a splat is
            drawn whole or not at all: no clipping of splats across the plane).
        device: where to render (default: where the tensors are; CPU for a scene).
        tile: tile size in pixels.
        pose: world-to-camera ``(R, t)`` tensors replacing the camera's pose
            (may require grad: pose refinement); intrinsics stay the camera's.

    Returns:
        :class:`RenderOutput` with ``image`` (H, W, 3) float32 linear HDR
        (colour = 0.5 + SH, clamped at 0 only) and ``alpha`` (H, W).
    """
    params = _as_params(scene_or_params, device)
    dev = params.means.device
    bg = _background(background, dev)
    proj = _project(params, camera, sh_degree, near, pose)
    if proj.means2d.requires_grad:
        proj.means2d.retain_grad()
    composite = rasterizer_for(dev, params.means.dtype)
    image, alpha = composite(proj, camera.width, camera.height, bg, tile=tile)
    return RenderOutput(image=image, alpha=alpha, means2d=proj.means2d, index=proj.index)


def render_reference(scene_or_params: SplatScene | SplatParams, camera: PinholeCamera,
                     background: float | tuple[float, float, float] = 0.0,
                     sh_degree: int | None = None, near: float = DEFAULT_NEAR
                     ) -> RenderOutput:
    """Dense reference of :func:`render` (every pixel x every splat; small sizes only)."""
    params = _as_params(scene_or_params, None)
    bg = _background(background, params.means.device)
    proj = _project(params, camera, sh_degree, near)
    image, alpha = rasterize_dense(proj, camera.width, camera.height, bg)
    return RenderOutput(image=image, alpha=alpha, means2d=proj.means2d, index=proj.index)
