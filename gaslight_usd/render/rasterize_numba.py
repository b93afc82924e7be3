"""The tile rasterizer as compiled CPU kernels (numba), forward and backward.

The same image as :func:`.rasterize.rasterize` (the pure-torch version, kept
for other devices and as the reference these kernels are tested against):
per pixel, front-to-back over its tile's depth-sorted splat list,
``alpha = min(0.99, o exp(-0.5 d^T Sigma^-1 d))``, alphas under 1/255
skipped, compositing stopped before the splat that would take the
transmittance under 1e-4.

Why a kernel: the torch version pads every tile's list to its group's
longest, evaluates every (splat, pixel) pair even behind opaque surfaces and
keeps the whole (tile, list, pixel) tensors for autograd; a per-pixel loop
stops where the pixel is opaque and keeps only the final transmittance and
the last splat used. The backward pass walks each pixel's list back to front
(as 3DGS does) rebuilding the transmittance by division.

Parallel over tiles (``prange``); gradients are written per (splat, tile)
pair -- a pair belongs to one tile, so no two threads write the same slot --
and summed per splat afterwards in a fixed order: results do not depend on
the thread count or on scheduling.
"""

from __future__ import annotations

import numba
import numpy as np
import torch
from numba import njit, prange

from .project import ALPHA_MAX, ALPHA_MIN, T_MIN, Projected
from .rasterize import TILE, tile_pairs

PAIR_GRADS = 9
"""Per pair: d mean x, d mean y, d conic a, b, c, d colour r, g, b, d opacity."""
CHUNK = 4
"""Tiles handed to a thread at a time (tiles differ a lot in work)."""


@njit(parallel=True, cache=True, fastmath=True)
def _forward_kernel(means2d, conics, colours, opac, log_floor, splat, starts, tiles_x, tile,
                    width, height, rgb, final_t, n_used):  # pragma: no cover - compiled
    n_tiles = len(starts) - 1
    for t in prange(n_tiles):
        s0, s1 = starts[t], starts[t + 1]
        ty = t // tiles_x
        tx = t - ty * tiles_x
        for ly in range(tile):
            y = ty * tile + ly
            if y >= height:
                break
            py = np.float32(y + 0.5)
            for lx in range(tile):
                x = tx * tile + lx
                if x >= width:
                    break
                px = np.float32(x + 0.5)
                trans = np.float32(1.0)
                r = np.float32(0.0)
                g = np.float32(0.0)
                b = np.float32(0.0)
                last = s0
                for p in range(s0, s1):
                    i = splat[p]
                    dx = px - means2d[i, 0]
                    dy = py - means2d[i, 1]
                    power = (np.float32(-0.5) * (conics[i, 0] * dx * dx + conics[i, 2] * dy * dy)
                             - conics[i, 1] * dx * dy)
                    if power < log_floor[i]:  # alpha < 1/255: no exp needed
                        continue
                    if power > 0.0:
                        power = np.float32(0.0)
                    alpha = min(np.float32(ALPHA_MAX), opac[i] * np.exp(power))
                    if alpha < ALPHA_MIN:
                        continue
                    after = trans * (np.float32(1.0) - alpha)
                    if after < T_MIN:
                        break
                    w = alpha * trans
                    r += w * colours[i, 0]
                    g += w * colours[i, 1]
                    b += w * colours[i, 2]
                    trans = after
                    last = p + 1
                rgb[y, x, 0] = r
                rgb[y, x, 1] = g
                rgb[y, x, 2] = b
                final_t[y, x] = trans
                n_used[y, x] = last


@njit(parallel=True, cache=True, fastmath=True)
def _backward_kernel(means2d, conics, colours, opac, log_floor, splat, starts, tiles_x, tile,
                     width, height, final_t, n_used, grad_rgb, grad_acc,
                     pair_grad):  # pragma: no cover - compiled
    n_tiles = len(starts) - 1
    for t in prange(n_tiles):
        s0 = starts[t]
        ty = t // tiles_x
        tx = t - ty * tiles_x
        for ly in range(tile):
            y = ty * tile + ly
            if y >= height:
                break
            py = np.float32(y + 0.5)
            for lx in range(tile):
                x = tx * tile + lx
                if x >= width:
                    break
                px = np.float32(x + 0.5)
                gr = grad_rgb[y, x, 0]
                gg = grad_rgb[y, x, 1]
                gb = grad_rgb[y, x, 2]
                ga = grad_acc[y, x]
                trans = final_t[y, x]
                # colour and alpha composited behind the current splat, per unit transmittance
                back_r = np.float32(0.0)
                back_g = np.float32(0.0)
                back_b = np.float32(0.0)
                back_a = np.float32(0.0)
                for p in range(n_used[y, x] - 1, s0 - 1, -1):
                    i = splat[p]
                    dx = px - means2d[i, 0]
                    dy = py - means2d[i, 1]
                    ca, cb, cc = conics[i, 0], conics[i, 1], conics[i, 2]
                    power = np.float32(-0.5) * (ca * dx * dx + cc * dy * dy) - cb * dx * dy
                    if power < log_floor[i]:
                        continue
                    flat = power > 0.0
                    if flat:
                        power = np.float32(0.0)
                    raw = opac[i] * np.exp(power)
                    clamped = raw > ALPHA_MAX
                    alpha = min(np.float32(ALPHA_MAX), raw)
                    if alpha < ALPHA_MIN:
                        continue
                    trans = trans / (np.float32(1.0) - alpha)
                    w = alpha * trans
                    cr, cg, cbl = colours[i, 0], colours[i, 1], colours[i, 2]
                    pair_grad[p, 5] += gr * w
                    pair_grad[p, 6] += gg * w
                    pair_grad[p, 7] += gb * w
                    d_alpha = trans * (gr * (cr - back_r) + gg * (cg - back_g)
                                       + gb * (cbl - back_b) + ga * (np.float32(1.0) - back_a))
                    keep = np.float32(1.0) - alpha
                    back_r = alpha * cr + keep * back_r
                    back_g = alpha * cg + keep * back_g
                    back_b = alpha * cbl + keep * back_b
                    back_a = alpha + keep * back_a
                    if clamped:
                        continue
                    d_log = d_alpha * alpha  # d alpha / d log alpha = alpha
                    pair_grad[p, 8] += d_log / opac[i]
                    if flat:
                        continue
                    pair_grad[p, 0] += d_log * (ca * dx + cb * dy)
                    pair_grad[p, 1] += d_log * (cb * dx + cc * dy)
                    pair_grad[p, 2] += d_log * np.float32(-0.5) * dx * dx
                    pair_grad[p, 3] += d_log * -dx * dy
                    pair_grad[p, 4] += d_log * np.float32(-0.5) * dy * dy


def _as_np(t: torch.Tensor) -> np.ndarray:
    return np.ascontiguousarray(t.detach().cpu().numpy())


class _Composite(torch.autograd.Function):
    """(means2d, conics, colours, opacities) -> premultiplied colour (H, W, 3), alpha (H, W)."""

    @staticmethod
    def forward(ctx, means2d, conics, colours, opacities, splat, starts, layout):
        tiles_x, tile, width, height = layout
        arrays = [_as_np(v) for v in (means2d, conics, colours, opacities)]
        # exponent under which alpha < 1/255, a little low so rounding never skips a pixel
        # the exact test would keep (that test still runs after the exp)
        arrays.append((np.log(ALPHA_MIN / np.maximum(arrays[3], 1e-30)) - 1e-3).astype(
            np.float32))
        rgb = np.zeros((height, width, 3), np.float32)
        final_t = np.ones((height, width), np.float32)
        n_used = np.zeros((height, width), np.int64)
        with numba.parallel_chunksize(CHUNK):
            _forward_kernel(*arrays, splat, starts, tiles_x, tile, width, height, rgb, final_t,
                            n_used)
        ctx.arrays, ctx.splat, ctx.starts, ctx.layout = arrays, splat, starts, layout
        ctx.final_t, ctx.n_used = final_t, n_used
        return torch.from_numpy(rgb), torch.from_numpy(1.0 - final_t)

    @staticmethod
    def backward(ctx, grad_rgb, grad_acc):
        tiles_x, tile, width, height = ctx.layout
        pair_grad = np.zeros((len(ctx.splat), PAIR_GRADS), np.float32)
        with numba.parallel_chunksize(CHUNK):
            _backward_kernel(*ctx.arrays, ctx.splat, ctx.starts, tiles_x, tile, width, height,
                             ctx.final_t, ctx.n_used, _as_np(grad_rgb.float()),
                             _as_np(grad_acc.float()), pair_grad)
        count = len(ctx.arrays[3])
        grads = torch.zeros(count, PAIR_GRADS).index_add_(
            0, torch.from_numpy(ctx.splat), torch.from_numpy(pair_grad))
        return (grads[:, 0:2], grads[:, 2:5], grads[:, 5:8], grads[:, 8], None, None, None)


def rasterize_numba(proj: Projected, width: int, height: int, background: torch.Tensor,
                    tile: int = TILE,
                    pairs: tuple[torch.Tensor, torch.Tensor] | None = None
                    ) -> tuple[torch.Tensor, torch.Tensor]:
    """Composite projected splats -> image (H, W, 3) and alpha (H, W); float32 CPU tensors.

    Drop-in for :func:`.rasterize.rasterize`, differentiable in the splats'
    screen means, conics, colours, opacities and in ``background``. ``pairs``: the
    (splat, tile) pairs to composite (default: :func:`.rasterize.tile_pairs`).
    """
    tiles_x, tiles_y = -(-width // tile), -(-height // tile)
    splat, tile_id = pairs if pairs is not None else tile_pairs(
        proj.means2d, proj.extents, proj.depths, tiles_x, tiles_y, tile)
    counts = torch.bincount(tile_id, minlength=tiles_x * tiles_y)
    starts = np.zeros(tiles_x * tiles_y + 1, np.int64)
    np.cumsum(counts.numpy(), out=starts[1:])
    rgb, acc = _Composite.apply(proj.means2d, proj.conics, proj.colours, proj.opacities,
                                np.ascontiguousarray(splat.numpy()), starts,
                                (tiles_x, tile, width, height))
    return rgb + (1.0 - acc)[..., None] * background, acc
