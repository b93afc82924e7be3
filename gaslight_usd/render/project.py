"""EWA splatting: 3D Gaussians -> 2D screen-space Gaussians (Zwicker et al. 2002,
"EWA Splatting"; the 3DGS formulation, Kerbl et al. 2023).

Sigma3 = R S S^T R^T from scale and rotation; Sigma2 = J W Sigma3 W^T J^T + 0.3 I,
with J the Jacobian of the pinhole projection at the splat centre (its x/z and
y/z clamped to 1.3x the field of view, as 3DGS does, so splats far outside the
frame do not blow up) and the 0.3 px^2 low-pass dilation of 3DGS.

``antialiased``: the dilation also scales the opacity by
``sqrt(det Sigma2 / det(Sigma2 + 0.3 I))`` (the 2D filter of Mip-Splatting, Yu et
al. CVPR 2024; gsplat's "antialiased" mode), so a splat's footprint integral no
longer grows when it covers less than a pixel. Without it a cluster of tiny
bright splats (a 5 cm lamp fitted at 0.14 deg/px) renders brighter the coarser
the camera: 1.19x the true power at the example's probe 1, whose 512 x 256
panorama has 0.7 deg pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ..cameras import PinholeCamera
from .sh import eval_sh

ALPHA_MIN = 1.0 / 255.0
ALPHA_MAX = 0.99
T_MIN = 1e-4
DILATION = 0.3
DEFAULT_NEAR = 0.01
"""Splats whose centre is nearer than this (camera z, scene units) are skipped."""


@dataclass
class Projected:
    """Screen-space splats that may be visible (M of the N input splats).

    - ``index``     (M,) index into the input splats
    - ``means2d``   (M, 2) pixel coordinates (pixel centres at +0.5)
    - ``conics``    (M, 3) inverse 2D covariance (a, b, c) = [[a, b], [b, c]]
    - ``depths``    (M,) camera z
    - ``colours``   (M, 3) linear colour seen from this camera
    - ``opacities`` (M,) in (0, 1)
    - ``extents``   (M, 2) half-width, half-height (px) outside which alpha < 1/255
    """

    index: torch.Tensor
    means2d: torch.Tensor
    conics: torch.Tensor
    depths: torch.Tensor
    colours: torch.Tensor
    opacities: torch.Tensor
    extents: torch.Tensor


def quat_to_rotmat(quats: torch.Tensor) -> torch.Tensor:
    """(N, 4) w x y z (any norm) -> (N, 3, 3)."""
    q = quats / quats.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    w, x, y, z = q.unbind(-1)
    return torch.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ], dim=-1).reshape(-1, 3, 3)


MAX_LEVEL = 2.0 * math.log(255.0)
"""The largest Mahalanobis level a splat can reach 1/255 at (an opaque one)."""


def jacobian_limits(camera: PinholeCamera) -> tuple[float, float]:
    """How far off-axis (x/z, y/z) the projection's Jacobian is evaluated: 1.3x the
    field of view, as 3DGS does, so splats far outside the frame do not blow up."""
    return (1.3 * max(camera.cx, camera.width - camera.cx) / camera.fx,
            1.3 * max(camera.cy, camera.height - camera.cy) / camera.fy)


def in_frustum(cam: torch.Tensor, max_scale: torch.Tensor, opacity_ok: torch.Tensor,
               intrinsics: torch.Tensor, limits: torch.Tensor, size: tuple[int, int],
               near: float | torch.Tensor) -> torch.Tensor:
    """(..., N) bool from camera-space centres ``cam`` (..., N, 3): the splats that may
    be visible, a superset of what :func:`project` draws. ``intrinsics`` (..., 1, 4) fx
    fy cx cy and ``limits`` (..., 1, 2) broadcast over the splats, as does ``near`` when
    a tensor; ``size`` is (width, height).

    The cheap test that lets :mod:`.many` skip the covariance work for splats a small
    view cannot see (a 12 px cube face or a narrow aimed view sees a few percent of a
    room). Conservative by construction: a splat's screen covariance is at most
    ``(f s / z)^2 (1 + lim^2)`` along an axis (``s`` its largest scale, ``lim`` the
    clamped Jacobian's slope), so its extent is at most ``sqrt(MAX_LEVEL (that +
    DILATION))``; its opacity only falls further in the antialiased mode."""
    z = cam[..., 2]
    keep = (z > near) & opacity_ok
    inv_z = 1.0 / torch.maximum(z, torch.as_tensor(near, dtype=z.dtype, device=z.device))
    for axis in (0, 1):
        f, c = intrinsics[..., axis], intrinsics[..., 2 + axis]
        lim = limits[..., axis]
        pos = f * cam[..., axis] * inv_z + c
        reach = torch.sqrt(MAX_LEVEL * ((f * max_scale * inv_z) ** 2 * (1.0 + lim * lim)
                                        + DILATION))
        keep &= (pos + reach + 1e-3 > 0) & (pos - reach - 1e-3 < size[axis])
    return keep


OPACITY_LOGIT_MIN = math.log(ALPHA_MIN / (1.0 - ALPHA_MIN))
"""Under this opacity logit a splat never reaches 1/255 anywhere."""


@dataclass
class ScreenGaussians:
    """2D Gaussians of splats in camera space (one row per splat, or per (camera,
    splat) pair when projecting into many cameras at once)."""

    uv: torch.Tensor
    depths: torch.Tensor
    conics: torch.Tensor
    opacities: torch.Tensor
    extents: torch.Tensor


def screen_gaussians(cam: torch.Tensor, R: torch.Tensor, quats: torch.Tensor,
                     log_scales: torch.Tensor, opacity_logits: torch.Tensor,
                     intrinsics: torch.Tensor, limits: torch.Tensor, antialiased: bool
                     ) -> ScreenGaussians:
    """The EWA projection (module docstring) of splats whose centres are ``cam`` (M, 3)
    in camera space, ``R`` the world-to-camera rotation (3, 3) or one per row (M, 3, 3);
    ``intrinsics`` fx fy cx cy and ``limits`` (:func:`jacobian_limits`) as (4,) / (2,)
    or one row each (M, 4) / (M, 2). Differentiable."""
    x, y, z = cam.unbind(-1)
    fx, fy, cx, cy = intrinsics.unbind(-1)
    lim_x, lim_y = limits.unbind(-1)
    inv_z = 1.0 / z
    u = fx * x * inv_z + cx
    v = fy * y * inv_z + cy
    tx = torch.minimum(torch.maximum(x * inv_z, -lim_x), lim_x) * z
    ty = torch.minimum(torch.maximum(y * inv_z, -lim_y), lim_y) * z
    zeros = torch.zeros_like(z)
    J = torch.stack([fx * inv_z + zeros, zeros, -fx * tx * inv_z * inv_z,
                     zeros, fy * inv_z + zeros, -fy * ty * inv_z * inv_z], -1).reshape(-1, 2, 3)
    rot = quat_to_rotmat(quats)
    M = rot * torch.exp(log_scales)[:, None, :]  # R S
    T = J @ (R if R.dim() == 3 else R[None]) @ M  # (M, 2, 3)
    cov = T @ T.transpose(1, 2)
    a = cov[:, 0, 0] + DILATION
    b = cov[:, 0, 1]
    c = cov[:, 1, 1] + DILATION
    det = (a * c - b * b).clamp_min(1e-12)
    conics = torch.stack([c / det, -b / det, a / det], -1)
    opac = torch.sigmoid(opacity_logits)
    if antialiased:
        det_raw = (cov[:, 0, 0] * cov[:, 1, 1] - b * b).clamp_min(0.0)
        opac = opac * torch.sqrt(det_raw / det + 1e-12)
    with torch.no_grad():
        # Mahalanobis level where opacity * exp(-0.5 k) falls to 1/255.
        level = 2.0 * torch.log((opac * 255.0).clamp_min(1.0))
        ext = torch.stack([torch.sqrt(level * a), torch.sqrt(level * c)], -1) + 1e-3
    return ScreenGaussians(torch.stack([u, v], -1), z, conics, opac, ext)


def on_screen(g: ScreenGaussians, width: int, height: int) -> torch.Tensor:
    """(M,) bool: reaches 1/255 somewhere and overlaps the ``width`` x ``height`` frame."""
    u, v = g.uv.unbind(-1)
    return ((g.opacities > ALPHA_MIN) & (u + g.extents[:, 0] > 0)
            & (u - g.extents[:, 0] < width) & (v + g.extents[:, 1] > 0)
            & (v - g.extents[:, 1] < height))


def project(means: torch.Tensor, quats: torch.Tensor, log_scales: torch.Tensor,
            opacity_logits: torch.Tensor, sh: torch.Tensor, camera: PinholeCamera,
            sh_degree: int | None = None, near: float = DEFAULT_NEAR,
            pose: tuple[torch.Tensor, torch.Tensor] | None = None,
            antialiased: bool = False) -> Projected:
    """Project N splats into ``camera``; drop those behind it or surely off-screen.

    ``pose``: world-to-camera ``(R (3, 3), t (3,))`` tensors used instead of the
    camera's own (differentiable: pose refinement); intrinsics stay the camera's.
    """
    dev, dt = means.device, means.dtype
    if pose is None:
        R = torch.as_tensor(camera.R, dtype=dt, device=dev)
        t = torch.as_tensor(camera.t, dtype=dt, device=dev)
        center = torch.as_tensor(camera.center, dtype=dt, device=dev)
    else:
        R, t = pose
        center = -(R.T @ t)
    with torch.no_grad():
        # every splat in front, not only :func:`in_frustum`'s: fewer rows round a few
        # values differently, and a fit is chaotic in its last bits (Adam scales an
        # isotropic splat's noise-level quaternion gradient to full steps), so culling
        # here gave other fits (docs/measurements.md, session 17) though no other image
        keep = (means @ R[2] + t[2]) > near
    index = torch.nonzero(keep).squeeze(1)
    m = means[index]
    intr = torch.tensor([camera.fx, camera.fy, camera.cx, camera.cy], dtype=dt, device=dev)
    lims = torch.tensor(jacobian_limits(camera), dtype=dt, device=dev)
    g = screen_gaussians(m @ R.T + t, R, quats[index], log_scales[index],
                         opacity_logits[index], intr, lims, antialiased)
    with torch.no_grad():
        sel = torch.nonzero(on_screen(g, camera.width, camera.height)).squeeze(1)
    dirs = m[sel] - center
    dirs = dirs / dirs.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    colours = eval_sh(sh[index[sel]], dirs, sh_degree)
    return Projected(index=index[sel], means2d=g.uv[sel], conics=g.conics[sel],
                     depths=g.depths[sel], colours=colours, opacities=g.opacities[sel],
                     extents=g.extents[sel])

