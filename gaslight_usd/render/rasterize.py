"""Tile-based front-to-back alpha compositing of screen-space Gaussians (3DGS).

Pure vectorised torch, differentiable by autograd. Every splat is paired with
the tiles its alpha > 1/255 footprint touches; pairs are sorted by (tile,
depth) and laid out as padded per-tile lists. The Gaussian exponent of every
(pair, pixel) comes from one matrix product (it is a quadratic in the pixel's
offset from its tile centre), the transmittance from a cumulative product
along each list, and the colour from a batched matrix product. There is no
loop over pixels or splats: a short loop runs over groups of tiles of similar
load (padding wastes less than half); when the work is large, each group's
activations are recomputed in the backward pass (gradient checkpointing) to
bound memory.

Per pixel, as in 3DGS: alpha = min(0.99, o exp(-0.5 d^T Sigma^-1 d)); alphas
under 1/255 are skipped; compositing stops before the splat that would take
the transmittance under 1e-4.
"""

from __future__ import annotations

import torch
from torch.utils.checkpoint import checkpoint

from .project import ALPHA_MAX, ALPHA_MIN, T_MIN, Projected

TILE = 8
GROUP_ELEMENTS = 12_000_000
"""(tile, list slot, pixel) entries handled in one batch."""


def tile_pairs(means2d: torch.Tensor, extents: torch.Tensor, depths: torch.Tensor,
               tiles_x: int, tiles_y: int, tile: int,
               x_tiles: tuple[torch.Tensor, torch.Tensor] | None = None
               ) -> tuple[torch.Tensor, torch.Tensor]:
    """(splat, tile) pairs sorted by tile, then front to back.

    ``x_tiles``: each splat's first and last tile column (default: the image's), so
    one image can hold several views side by side (:mod:`.many`).
    Returns ``splat`` (P,) and ``tile_id`` (P,) = ty * tiles_x + tx.
    """
    with torch.no_grad():
        lo = torch.floor((means2d - extents) / tile).long()
        hi = torch.floor((means2d + extents) / tile).long()
        first, last = x_tiles if x_tiles is not None else (0, tiles_x - 1)
        x0 = torch.minimum(torch.maximum(lo[:, 0], torch.as_tensor(first)),
                           torch.as_tensor(last))
        x1 = torch.minimum(torch.maximum(hi[:, 0], torch.as_tensor(first)),
                           torch.as_tensor(last))
        y0 = lo[:, 1].clamp(0, tiles_y - 1)
        y1 = hi[:, 1].clamp(0, tiles_y - 1)
        w = x1 - x0 + 1
        counts = w * (y1 - y0 + 1)
        splat = torch.repeat_interleave(torch.arange(len(counts), device=counts.device), counts)
        starts = torch.cumsum(counts, 0) - counts
        offset = torch.arange(len(splat), device=counts.device) - starts[splat]
        tx = x0[splat] + offset % w[splat]
        ty = y0[splat] + torch.div(offset, w[splat], rounding_mode="floor")
        tile_id = ty * tiles_x + tx
        rank = torch.empty_like(depths, dtype=torch.long)
        rank[torch.argsort(depths, stable=True)] = torch.arange(len(depths), device=depths.device)
        key = tile_id * max(len(depths), 1) + rank[splat]
        order = torch.argsort(key)
        return splat[order], tile_id[order]


def pair_coefficients(means2d, conics, opacities, splat, tile_id, tiles_x: int, tile: int
                      ) -> torch.Tensor:
    """(P, 6) coefficients c so that log alpha = c . (1, u, v, u^2, uv, v^2) at a pixel.

    (u, v) is the pixel centre relative to its tile's centre (small numbers,
    so the expansion loses no precision that matters).
    """
    half = tile / 2.0
    ox = (tile_id % tiles_x).to(means2d.dtype) * tile + half
    oy = torch.div(tile_id, tiles_x, rounding_mode="floor").to(means2d.dtype) * tile + half
    mu = means2d[splat]
    A = ox - mu[:, 0]
    B = oy - mu[:, 1]
    con = conics[splat]
    a, b, c = con[:, 0], con[:, 1], con[:, 2]
    k0 = -0.5 * a * A * A - b * A * B - 0.5 * c * B * B + torch.log(opacities[splat])
    return torch.stack([k0, -a * A - b * B, -b * A - c * B, -0.5 * a, -b, -0.5 * c], -1)


def _pixel_basis(tile: int, device, dtype) -> torch.Tensor:
    """(6, tile*tile) monomials (1, u, v, u^2, uv, v^2) of the tile's pixel centres."""
    local = torch.arange(tile * tile, device=device)
    u = (local % tile).to(dtype) + 0.5 - tile / 2.0
    v = torch.div(local, tile, rounding_mode="floor").to(dtype) + 0.5 - tile / 2.0
    return torch.stack([torch.ones_like(u), u, v, u * u, u * v, v * v])


def _composite(coef: torch.Tensor, colours: torch.Tensor, basis: torch.Tensor
               ) -> tuple[torch.Tensor, torch.Tensor]:
    """coef (T, K, 6), colours (T, K, 3), basis (6, px) -> colour (T, px, 3), alpha (T, px).

    Padding rows carry k0 = -inf (alpha 0).
    """
    alpha = torch.exp((coef @ basis).clamp_max(0.0)).clamp_max(ALPHA_MAX)  # (T, K, px)
    alpha = alpha * (alpha >= ALPHA_MIN)
    keep = 1.0 - alpha
    trans_after = torch.cumprod(keep, dim=1)
    trans = trans_after / keep  # keep >= 0.01: no zeros
    with torch.no_grad():
        alive = trans_after >= T_MIN
    weight = alpha * trans * alive
    rgb = weight.transpose(1, 2) @ colours
    return rgb, weight.sum(1)


def rasterize(proj: Projected, width: int, height: int, background: torch.Tensor,
              tile: int = TILE) -> tuple[torch.Tensor, torch.Tensor]:
    """Composite projected splats -> image (H, W, 3) and alpha (H, W)."""
    dev, dt = proj.means2d.device, proj.means2d.dtype
    tiles_x, tiles_y = -(-width // tile), -(-height // tile)
    n_tiles, px = tiles_x * tiles_y, tile * tile
    splat, tile_id = tile_pairs(proj.means2d, proj.extents, proj.depths, tiles_x, tiles_y,
                                tile)
    rgb = torch.zeros(n_tiles, px, 3, device=dev, dtype=dt)
    acc = torch.zeros(n_tiles, px, device=dev, dtype=dt)
    if len(splat):
        coef = pair_coefficients(proj.means2d, proj.conics, proj.opacities, splat, tile_id,
                                 tiles_x, tile)
        pad = torch.tensor([[-torch.inf, 0, 0, 0, 0, 0]], device=dev, dtype=dt)
        coef = torch.cat([coef, pad])
        cols = torch.cat([proj.colours[splat], proj.colours.new_zeros(1, 3)])
        basis = _pixel_basis(tile, dev, dt)
        with torch.no_grad():
            counts = torch.bincount(tile_id, minlength=n_tiles)
            slot = torch.arange(len(splat), device=dev) - (torch.cumsum(counts, 0) - counts)[
                tile_id]
            busy = torch.nonzero(counts).squeeze(1)
            level = torch.floor(torch.log2(counts[busy].double())).long()
            levels = level.unique().tolist()
            kmaxes = {lv: int(counts[busy[level == lv]].max()) for lv in levels}
            total = sum(kmaxes[lv] * int((level == lv).sum()) for lv in levels) * px
            local = torch.full((n_tiles,), -1, dtype=torch.long, device=dev)
        rows, rgbs, accs = [], [], []
        for lv in levels:
            kmax = kmaxes[lv]
            for chunk in torch.split(busy[level == lv], max(1, GROUP_ELEMENTS // (kmax * px))):
                with torch.no_grad():
                    local.fill_(-1)
                    local[chunk] = torch.arange(len(chunk), device=dev)
                    mine = torch.nonzero(local[tile_id] >= 0).squeeze(1)
                    table = torch.full((len(chunk), kmax), len(splat), dtype=torch.long,
                                       device=dev)
                    table[local[tile_id[mine]], slot[mine]] = mine
                args = (coef[table], cols[table], basis)
                if total > GROUP_ELEMENTS and torch.is_grad_enabled():
                    r, a = checkpoint(_composite, *args, use_reentrant=False)
                else:
                    r, a = _composite(*args)
                rows.append(chunk)
                rgbs.append(r)
                accs.append(a)
        index = torch.cat(rows)
        rgb = rgb.index_put((index,), torch.cat(rgbs))
        acc = acc.index_put((index,), torch.cat(accs))
    rgb = rgb + (1.0 - acc)[..., None] * background
    image = (rgb.reshape(tiles_y, tiles_x, tile, tile, 3).permute(0, 2, 1, 3, 4)
             .reshape(tiles_y * tile, tiles_x * tile, 3)[:height, :width])
    alpha = (acc.reshape(tiles_y, tiles_x, tile, tile).permute(0, 2, 1, 3)
             .reshape(tiles_y * tile, tiles_x * tile)[:height, :width])
    return image, alpha


def rasterize_dense(proj: Projected, width: int, height: int, background: torch.Tensor
                    ) -> tuple[torch.Tensor, torch.Tensor]:
    """Reference: every pixel against every splat, no tiles (small sizes only)."""
    dev = proj.means2d.device
    order = torch.argsort(proj.depths, stable=True)
    mu, con = proj.means2d[order], proj.conics[order]
    ys, xs = torch.meshgrid(torch.arange(height, device=dev) + 0.5,
                            torch.arange(width, device=dev) + 0.5, indexing="ij")
    dx = xs.reshape(1, -1) - mu[:, 0:1]
    dy = ys.reshape(1, -1) - mu[:, 1:2]
    power = -0.5 * (con[:, 0:1] * dx * dx + con[:, 2:3] * dy * dy) - con[:, 1:2] * dx * dy
    alpha = (proj.opacities[order][:, None] * torch.exp(power.clamp_max(0.0))).clamp_max(
        ALPHA_MAX)
    alpha = alpha * (alpha >= ALPHA_MIN)
    keep = torch.cumprod(1.0 - alpha, 0)
    trans = torch.cat([torch.ones_like(keep[:1]), keep[:-1]])
    alive = (keep >= T_MIN).detach()
    weight = alpha * trans * alive
    rgb = weight.T @ proj.colours[order]
    acc = weight.sum(0)
    rgb = rgb + (1.0 - acc)[:, None] * background
    return rgb.reshape(height, width, 3), acc.reshape(height, width)
