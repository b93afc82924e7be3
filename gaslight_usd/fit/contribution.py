"""How much each splat adds to the views: the blend weight it gets, summed over pixels."""

from __future__ import annotations

import torch

from ..cameras import PinholeCamera
from ..render import SplatParams, rasterizer_for
from ..render.project import project


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
