"""A backdrop for what no training view saw, so panoramas have no black holes.

Photos of a room rarely see all of its ceiling or floor, yet a panorama
rendered inside the room (an HDRI for lighting) looks everywhere; where no
splat was fitted it would see the black background, which is no light at all.
After the fit, the box holding the fitted splats (their 0.5-99.5 percentile
centres per axis; for a room, its walls, floor and ceiling) is tiled with flat
opaque splats; only tiles that no training camera sees are kept, each coloured
by the median colour of the fitted splats nearest to it (lamps excluded), so
walls continue into the unseen ceiling with their own light. The fitted views
are unchanged (the tiles lie outside every training frustum).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..cameras import PinholeCamera
from ..colour import luminance_weights
from ..splats import SplatScene, logit, rgb_to_sh_dc

BOX_QUANTILE = 0.005
DONORS = 24
"""Fitted splats whose median colour a tile takes."""
LAMP_RATIO = 64.0
"""Splats this many times brighter than the median are lamps: not colour donors."""
TILE_OVERLAP = 0.6
"""Tile std-dev as a fraction of the tile spacing (neighbours overlap: no gaps)."""


def _tiles(lo: np.ndarray, hi: np.ndarray, count: int
           ) -> tuple[np.ndarray, np.ndarray, float]:
    """Centres (T, 3) of a grid on the box faces, each tile's face axis (T,), spacing."""
    size = np.maximum(hi - lo, 1e-6)
    area = 2.0 * (size[0] * size[1] + size[1] * size[2] + size[0] * size[2])
    spacing = float(np.sqrt(area / max(count, 1)))
    centres, axes = [], []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        nu = max(1, int(np.ceil(size[u] / spacing)))
        nv = max(1, int(np.ceil(size[v] / spacing)))
        gu = lo[u] + (np.arange(nu) + 0.5) * size[u] / nu
        gv = lo[v] + (np.arange(nv) + 0.5) * size[v] / nv
        uu, vv = np.meshgrid(gu, gv, indexing="ij")
        for level in (lo[axis], hi[axis]):
            pts = np.empty((uu.size, 3))
            pts[:, u], pts[:, v], pts[:, axis] = uu.ravel(), vv.ravel(), level
            centres.append(pts)
            axes.append(np.full(uu.size, axis))
    return np.concatenate(centres), np.concatenate(axes), spacing


def _seen(points: np.ndarray, cameras: list[PinholeCamera]) -> np.ndarray:
    seen = np.zeros(len(points), bool)
    for cam in cameras:
        uv, z = cam.project(points)
        seen |= (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & \
                (uv[:, 1] >= 0) & (uv[:, 1] < cam.height)
    return seen


def unseen_backdrop(scene: SplatScene, cameras: list[PinholeCamera], count: int,
                    room: int | None = None, y_weights: np.ndarray | None = None
                    ) -> SplatScene:
    """Flat tiles on the splats' box where no camera looks (see the module doc); may be empty.

    ``count`` tiles cover the whole box; at most ``room`` are kept (the grid is
    made coarser to fit). ``y_weights``: the scene's luminance weights (default
    Rec.709's), to tell lamps from surfaces.
    """
    opaque = scene.opacities > 0.3
    room = count if room is None else min(room, count)
    if room <= 0 or opaque.sum() < DONORS:
        return scene.subset(np.zeros(0, np.int64))
    centres = scene.positions[opaque]
    colours = scene.base_colours[opaque]
    lo = np.quantile(centres, BOX_QUANTILE, axis=0)
    hi = np.quantile(centres, 1.0 - BOX_QUANTILE, axis=0)
    for _ in range(4):
        tiles, axes, spacing = _tiles(lo, hi, count)
        hidden = ~_seen(tiles, cameras)
        if hidden.sum() <= room:
            break
        count = int(count * room / hidden.sum() * 0.9)
    tiles, axes = tiles[hidden], axes[hidden]
    if not len(tiles) or len(tiles) > room:
        return scene.subset(np.zeros(0, np.int64))
    lum = colours @ (luminance_weights() if y_weights is None
                     else np.asarray(y_weights, np.float32))
    donor = lum <= LAMP_RATIO * max(float(np.median(lum)), 1e-12)
    centres, colours = centres[donor], colours[donor]
    k = min(DONORS, len(centres))
    _, near = cKDTree(centres).query(tiles, k=k)
    tile_colours = np.median(colours[near.reshape(len(tiles), k)], axis=1)
    n = len(tiles)
    log_scales = np.full((n, 3), np.log(TILE_OVERLAP * spacing), np.float32)
    log_scales[np.arange(n), axes] = np.log(0.02 * spacing)
    sh = np.zeros((n, scene.sh.shape[1], 3), np.float32)
    sh[:, 0] = rgb_to_sh_dc(tile_colours)
    return SplatScene(positions=tiles.astype(scene.positions.dtype),
                      rotations=np.tile(np.array([1.0, 0, 0, 0], np.float32), (n, 1)),
                      log_scales=log_scales,
                      opacity_logits=np.full(n, logit(np.array(0.99)), np.float32), sh=sh)


def concatenate(a: SplatScene, b: SplatScene) -> SplatScene:
    """The splats of ``a`` then ``b`` (same SH degree), ``a``'s metadata."""
    return SplatScene(
        positions=np.concatenate([a.positions, b.positions]),
        rotations=np.concatenate([a.rotations, b.rotations]),
        log_scales=np.concatenate([a.log_scales, b.log_scales]),
        opacity_logits=np.concatenate([a.opacity_logits, b.opacity_logits]),
        sh=np.concatenate([a.sh, b.sh]), metadata=dict(a.metadata))
