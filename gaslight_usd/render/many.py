"""Many small views of one scene in one pass (no gradients).

The light weighing (:mod:`gaslight_usd.fit.power`) draws a 12 px cube map and a narrow
view aimed at each light from hundreds of surface points. One :func:`.render` call per
view spends its time in per-call overhead (a few milliseconds of small tensor ops for
a 12 x 12 image), not in the splats. Here the views' splats are projected together, one
row per (view, splat) pair that may be visible, and composited as one atlas image: view
``b`` owns the block of tiles ``[b * tiles_w, (b + 1) * tiles_w)``, and a splat is only
paired with tiles of its own view's block, so neighbouring views never bleed into each
other. Same pixels as :func:`.render` per view (``tests/test_render.py``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from ..cameras import PinholeCamera
from .params import SplatParams
from .project import (
    DEFAULT_NEAR,
    OPACITY_LOGIT_MIN,
    Projected,
    in_frustum,
    jacobian_limits,
    on_screen,
    screen_gaussians,
)
from .rasterize import TILE, tile_pairs
from .sh import eval_sh

PAIRS_PER_PASS = 4_000_000
"""(view, splat) candidates tested at once; bounds memory (about 100 bytes each)."""


def render_many(params: SplatParams, cameras: list[PinholeCamera],
                near: float | Sequence[float] = DEFAULT_NEAR, background: float = 0.0,
                sh_degree: int | None = None) -> np.ndarray:
    """``(B, H, W, 3)`` float32 images of ``params`` from ``cameras`` (all the same size;
    intrinsics and poses may differ), as :func:`gaslight_usd.render.render` draws each;
    ``near``: one for all, or one per camera. CPU float32 tensors (the compiled
    compositing kernels; the light weighing draws on the CPU whatever the fit's device)."""
    if params.means.device.type != "cpu" or params.means.dtype != torch.float32:
        raise ValueError("render_many draws float32 splats on the CPU")
    if not cameras:
        return np.zeros((0, 0, 0, 3), np.float32)
    width, height = cameras[0].width, cameras[0].height
    if any((c.width, c.height) != (width, height) for c in cameras):
        raise ValueError("render_many: every camera must have the same size")
    from .rasterize_numba import rasterize_numba

    dev, dt = params.means.device, params.means.dtype
    tiles_w, tiles_h = -(-width // TILE), -(-height // TILE)
    out = []
    nears = np.broadcast_to(np.asarray(near, np.float64), (len(cameras),))
    per_pass = max(1, PAIRS_PER_PASS // max(params.means.shape[0], 1))
    with torch.no_grad():
        for start in range(0, len(cameras), per_pass):
            group = cameras[start:start + per_pass]
            proj, view = _project_many(params, group, nears[start:start + per_pass],
                                       sh_degree, dt, dev, tiles_w * TILE)
            first = view * tiles_w
            atlas = (tiles_w * TILE * len(group), tiles_h * TILE)
            splat, tile_id = tile_pairs(proj.means2d, proj.extents, proj.depths,
                                        tiles_w * len(group), tiles_h, TILE,
                                        x_tiles=(first, first + tiles_w - 1))
            image, _ = rasterize_numba(proj, *atlas, torch.full((3,), background, dtype=dt),
                                       pairs=(splat, tile_id))
            blocks = image.reshape(tiles_h * TILE, len(group), tiles_w * TILE, 3)
            out.append(blocks.permute(1, 0, 2, 3)[:, :height, :width].numpy())
    return np.concatenate(out).astype(np.float32)


def _project_many(params: SplatParams, cameras: list[PinholeCamera], near: np.ndarray,
                  sh_degree: int | None, dt: torch.dtype, dev: torch.device, block: int
                  ) -> tuple[Projected, torch.Tensor]:
    """The pairs of every view in one :class:`Projected`, each view's screen positions
    moved right by ``block`` pixels per view (its place in the atlas), and each pair's
    view."""
    R = torch.as_tensor(np.stack([c.R for c in cameras]), dtype=dt, device=dev)
    t = torch.as_tensor(np.stack([c.t for c in cameras]), dtype=dt, device=dev)
    centres = torch.as_tensor(np.stack([c.center for c in cameras]), dtype=dt, device=dev)
    intr = torch.as_tensor([[c.fx, c.fy, c.cx, c.cy] for c in cameras], dtype=dt, device=dev)
    lims = torch.as_tensor([jacobian_limits(c) for c in cameras], dtype=dt, device=dev)
    cam = torch.einsum("bij,nj->bni", R, params.means) + t[:, None]
    keep = in_frustum(cam, torch.exp(params.log_scales.max(dim=1).values),
                      params.opacity_logits > OPACITY_LOGIT_MIN, intr[:, None], lims[:, None],
                      (cameras[0].width, cameras[0].height),
                      torch.tensor(near, dtype=dt, device=dev)[:, None])
    view, index = torch.nonzero(keep, as_tuple=True)
    g = screen_gaussians(cam[view, index], R[view], params.quats[index],
                         params.log_scales[index], params.opacity_logits[index], intr[view],
                         lims[view], params.antialiased)
    sel = torch.nonzero(on_screen(g, cameras[0].width, cameras[0].height)).squeeze(1)
    view, index = view[sel], index[sel]
    dirs = params.means[index] - centres[view]
    dirs = dirs / dirs.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    uv = g.uv[sel] + torch.stack([view.to(dt) * block, torch.zeros_like(view, dtype=dt)], -1)
    return Projected(index=index, means2d=uv, conics=g.conics[sel], depths=g.depths[sel],
                     colours=eval_sh(params.sh[index], dirs, sh_degree),
                     opacities=g.opacities[sel], extents=g.extents[sel]), view
