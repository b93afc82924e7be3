"""How much each splat adds to the views: the blend weight it gets, summed over pixels."""

from __future__ import annotations

import numpy as np
import torch

from ..cameras import PinholeCamera
from ..render import SplatParams, rasterizer_for
from ..render.project import project

LOG_FLOOR = 1e-3
"""Added to luminances before their log in :func:`removal_gains`, as a share of each
view's median luminance (any units)."""


def contributions(params: SplatParams, cameras: list[PinholeCamera], sh_degree: int
                  ) -> tuple[torch.Tensor, torch.Tensor]:
    """Per splat: summed blend weight (pixel-equivalents) and weight x colour, over views.

    The gradient of the image sum w.r.t. a splat's colour is exactly the sum of
    its compositing weights, so one backward pass per view gives both.
    """
    n = params.count
    p = params.detach()
    weight = torch.zeros(n, device=p.means.device)
    radiance = torch.zeros(n, device=p.means.device)
    for cam in cameras:
        proj = project(p.means, p.quats, p.log_scales, p.opacity_logits, p.sh, cam,
                       sh_degree=sh_degree)
        colours = proj.colours.detach()
        proj.colours = torch.ones_like(colours, requires_grad=True)
        composite = rasterizer_for(colours.device, colours.dtype)
        image, _ = composite(proj, cam.width, cam.height, torch.zeros(3, device=colours.device))
        image[..., 0].sum().backward()
        w = proj.colours.grad[:, 0]
        weight.index_add_(0, proj.index, w)
        radiance.index_add_(0, proj.index, w * colours.mean(1))
    return weight, radiance


def removal_gains(params: SplatParams, cameras: list[PinholeCamera], images: list[np.ndarray],
                  floors: list[np.ndarray | None], sh_degree: int, y_weights: torch.Tensor
                  ) -> torch.Tensor:
    """Per splat: how much the views' fit would gain were it taken out, to first order
    (the log2-luminance squared error summed over the views' pixels; a clipped pixel is a
    bound: only light under its clip floor counts). Positive: the views fit better
    without it. Unlike :func:`contributions` it counts what a splat hides as well as
    what it draws (a faint splat in front of a bulb). It is the derivative of the error
    with respect to a factor on each splat's opacity, at 1 (``alpha * dE/dalpha``)."""
    n = params.count
    p = params.detach()
    gain = torch.zeros(n, device=p.means.device)
    y = torch.as_tensor(y_weights, dtype=torch.float32, device=p.means.device)
    for cam, image, floor in zip(cameras, images, floors, strict=True):
        proj = project(p.means, p.quats, p.log_scales, p.opacity_logits, p.sh, cam,
                       sh_degree=sh_degree)
        if not len(proj.index):
            continue  # nothing in this view: nothing to gain or lose
        factor = torch.ones_like(proj.opacities, requires_grad=True)
        proj.opacities = proj.opacities.detach() * factor
        proj.colours = proj.colours.detach()
        composite = rasterizer_for(proj.colours.device, proj.colours.dtype)
        drawn, _ = composite(proj, cam.width, cam.height,
                             torch.zeros(3, device=proj.colours.device))
        target = torch.as_tensor(np.asarray(image, np.float32), device=drawn.device) @ y
        tiny = LOG_FLOOR * float(target.median()) + 1e-12
        log_drawn = torch.log2(drawn @ y + tiny)
        error = log_drawn - torch.log2(target + tiny)
        if floor is not None:
            bound = torch.as_tensor(np.asarray(floor, np.float32), device=drawn.device)
            under = torch.clamp(log_drawn - torch.log2(bound + tiny), max=0.0)
            error = torch.where(bound > 0, under, error)
        (error ** 2).sum().backward()
        gain.index_add_(0, proj.index, factor.grad)
    return gain
