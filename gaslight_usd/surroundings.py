"""What one point sees of the splats: coarse direction bins composited front to back.

A full panorama render (:mod:`gaslight_usd.render.envmap`) is more than some
questions need: how far the visible surface is in each direction (the captured
space, the free space around a probe) and how much light arrives at a point
(the irradiance bound of :mod:`gaslight_usd.lights`). Those want many points,
cheaply, so here every splat falls into the lat-long bin of its centre's
direction and covers a share of that bin equal to its integrated alpha
(``opacity x 2 pi sigma^2``, the area under its Gaussian footprint) over the
bin's area at the splat's distance, capped at its opacity; each bin is then
composited front to back as the renderer composites a pixel. A splat wider
than its bin covers that bin only, so light leaks past near, large splats:
good enough for depths and bounds, not for images.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cameras import latlong_directions, latlong_solid_angles
from .splats import SplatScene

BINS = (24, 48)
"""Lat-long bins (rows, columns): 7.5 degrees, a 33 cm wall patch at 2.5 m."""
SURFACE_TRANSMITTANCE = 0.5
"""A bin's visible surface is where less than this much light gets through."""
HALF_ALPHA = 0.5
"""...or, where more gets through, where this share of the bin's summed alpha lies nearer."""


@dataclass
class Surroundings:
    """A point's coarse view of the splats (all arrays per bin, row-major)."""

    point: np.ndarray
    directions: np.ndarray
    """(B, 3) unit direction of each bin's centre."""
    solid_angles: np.ndarray
    """(B,) steradians."""
    radiance: np.ndarray
    """(B, 3) composited radiance arriving from each bin (black behind the last splat)."""
    depth: np.ndarray
    """(B,) distance to the visible surface (``inf`` where light still gets through),
    the least of each bin's 3 x 3 neighbourhood (:func:`nearest_around`)."""
    bins: tuple[int, int]
    own_depth: np.ndarray | None = None
    """(B,) each bin's own surface distance, before the neighbourhood's least."""

    def irradiance(self, normals: np.ndarray) -> np.ndarray:
        """(M, 3) RGB irradiance on surfaces at the point facing each of ``normals`` (M, 3)."""
        cos = np.clip(self.directions @ np.asarray(normals, np.float64).T, 0.0, None)
        return (cos * self.solid_angles[:, None]).T @ self.radiance

    def bin_of(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bin index (N,) and distance (N,) of ``points`` (N, 3) as seen from the point."""
        d = np.asarray(points, np.float64) - self.point
        r = np.linalg.norm(d, axis=1)
        return _bin_index(d, r, self.bins), r


def normals_26() -> np.ndarray:
    """Unit normals: the 6 faces, 12 edges and 8 corners of a cube."""
    g = np.stack(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1], indexing="ij"), -1)
    g = g.reshape(-1, 3).astype(np.float64)
    g = g[np.abs(g).sum(1) > 0]
    return g / np.linalg.norm(g, axis=1, keepdims=True)


def _bin_index(d: np.ndarray, r: np.ndarray, bins: tuple[int, int]) -> np.ndarray:
    rows, cols = bins
    safe = np.maximum(r, 1e-30)
    lat = np.arcsin(np.clip(d[:, 1] / safe, -1.0, 1.0))
    lon = np.arctan2(d[:, 0], d[:, 2])
    # the lat-long convention of gaslight_usd.cameras: column 0 at lon = +pi, row 0 at +Y
    col = np.clip(((0.5 - lon / (2 * np.pi)) * cols).astype(np.int64), 0, cols - 1)
    row = np.clip(((0.5 - lat / np.pi) * rows).astype(np.int64), 0, rows - 1)
    return row * cols + col


def splat_sigma(scene: SplatScene) -> np.ndarray:
    """(N,) one std-dev per splat: the geometric mean of its two largest axes."""
    s = np.sort(scene.scales.astype(np.float64), axis=1)
    return np.sqrt(s[:, 1] * s[:, 2])


def _binned_alpha(point: np.ndarray, positions: np.ndarray, sigma: np.ndarray,
                  opacity: np.ndarray, bins: tuple[int, int]
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The splats away from ``point`` (mask), their bins, distances and the share of
    their bin each covers (integrated alpha over the bin's area there, capped at the
    opacity)."""
    rows, cols = bins
    omega = np.broadcast_to(latlong_solid_angles(cols, rows), (rows, cols)).reshape(-1)
    d = np.asarray(positions, np.float64) - point
    r = np.linalg.norm(d, axis=1)
    keep = r > 1e-9
    d, r = d[keep], r[keep]
    b = _bin_index(d, r, bins)
    sig = np.asarray(sigma, np.float64)[keep]
    op = np.clip(np.asarray(opacity, np.float64)[keep], 0.0, 0.999)
    return keep, b, r, op * np.minimum(1.0, 2 * np.pi * sig**2 / (r**2 * omega[b]))


def bin_cover(point, positions: np.ndarray, sigma: np.ndarray, opacity: np.ndarray,
              bins: tuple[int, int] = BINS) -> np.ndarray:
    """(B,) the splats' summed cover of each direction bin seen from ``point`` (the
    alpha :func:`look_from` composites, not composited)."""
    point = np.asarray(point, np.float64).reshape(3)
    _, b, _, alpha = _binned_alpha(point, positions, sigma, opacity, bins)
    return np.bincount(b, alpha, minlength=bins[0] * bins[1])


def look_from(point, positions: np.ndarray, colours: np.ndarray, sigma: np.ndarray,
              opacity: np.ndarray, bins: tuple[int, int] = BINS) -> Surroundings:
    """Composite the splats (N,) as seen from ``point`` into direction bins.

    ``colours`` (N, 3) linear radiance, ``sigma`` (N,) footprint std-dev,
    ``opacity`` (N,) in [0, 1]. Splats at the point itself are left out.
    """
    point = np.asarray(point, np.float64).reshape(3)
    rows, cols = bins
    n_bins = rows * cols
    directions = latlong_directions(cols, rows).reshape(-1, 3)
    omega = np.broadcast_to(latlong_solid_angles(cols, rows), (rows, cols)).reshape(-1)
    keep, b, r, alpha = _binned_alpha(point, positions, sigma, opacity, bins)
    order = np.lexsort((r, b))
    b, r, alpha = b[order], r[order], alpha[order]
    col = np.asarray(colours, np.float64)[keep][order]
    log_t = np.log1p(-alpha)
    before = np.cumsum(log_t) - log_t  # exclusive running sum over all splats
    start = np.flatnonzero(np.r_[True, b[1:] != b[:-1]])
    group = np.cumsum(np.r_[True, b[1:] != b[:-1]]) - 1
    t_before = np.exp(before - before[start][group])
    weight = alpha * t_before
    radiance = np.stack([np.bincount(b, weight * col[:, c], minlength=n_bins)
                         for c in range(3)], axis=1)
    t_after = t_before * (1.0 - alpha)
    cross = (t_after < SURFACE_TRANSMITTANCE) & (t_before >= SURFACE_TRANSMITTANCE)
    depth = np.full(n_bins, np.inf)
    # Where light still gets through (splats too small or too faint for their bin), the
    # surface is where half the bin's summed alpha lies nearer: its splats' middle.
    total = np.bincount(b, alpha, minlength=n_bins)
    run = np.cumsum(alpha)
    share = (run - (run - alpha)[start][group]) / np.maximum(total[b], 1e-30)
    half = (share >= HALF_ALPHA) & (share - alpha / np.maximum(total[b], 1e-30) < HALF_ALPHA)
    depth[b[half]] = r[half]
    depth[b[cross]] = r[cross]  # at most one crossing per bin: transmittance only falls
    return Surroundings(point, directions, omega, radiance, nearest_around(depth, bins), bins,
                        depth)


def nearest_around(depth: np.ndarray, bins: tuple[int, int]) -> np.ndarray:
    """Each bin's depth as the least of its 3 x 3 neighbourhood (longitude wraps).

    A bin holding a lone stray splat (a floater behind the floor) would take that
    splat as its surface; its neighbours' surfaces say where the set ends.
    """
    grid = depth.reshape(bins)
    padded = np.pad(grid, ((1, 1), (0, 0)), constant_values=np.inf)
    padded = np.concatenate([padded[:, -1:], padded, padded[:, :1]], axis=1)
    rows, cols = bins
    stack = [padded[i:i + rows, j:j + cols] for i in range(3) for j in range(3)]
    return np.min(stack, axis=0).reshape(-1)


def planar_fill(depth: np.ndarray, directions: np.ndarray, ring: np.ndarray,
                radius_deg: float, max_spread: float = np.inf) -> np.ndarray:
    """(B,) each bin's distance were the surfaces of the ``ring`` bins within
    ``radius_deg`` of it (their finite ``depth``) one plane; ``inf`` where too few
    surround it, spread along one line only, or off the plane by more than
    ``max_spread`` of their depth (RMS).

    Seen from a point, a plane ``n . x = h`` lies at ``h / (n . d)`` along a unit
    direction ``d``: its inverse depth is *linear* in ``d``. Fitting ``1 / depth =
    a . d`` over the ring therefore carries a wall straight across a window in it (a
    hole the ring leaves out) and evens out the fit's depth noise along it; where the
    ring spans two surfaces (a corner, a desk under a window) ``max_spread`` says no.
    """
    depth = np.asarray(depth, np.float64)
    dirs = np.asarray(directions, np.float64)
    fill = np.full(len(depth), np.inf)
    ring = np.flatnonzero(np.asarray(ring) & np.isfinite(depth) & (depth > 0))
    if len(ring) < 4:
        return fill
    w = ((dirs @ dirs[ring].T) >= np.cos(np.radians(radius_deg))).astype(np.float64)
    a_mat = np.einsum("br,ri,rj->bij", w, dirs[ring], dirs[ring])
    b_vec = w @ (dirs[ring] / depth[ring][:, None])
    # a plane needs ring bins spread both ways across the view
    ok = (w.sum(1) >= 4) & (np.linalg.eigvalsh(a_mat)[:, 0] > 1e-3 * w.sum(1))
    if not ok.any():
        return fill
    coef = np.linalg.solve(a_mat[ok], b_vec[ok][..., None])[..., 0]
    # the ring's own depths off that plane (relative): a ring round two surfaces at
    # different depths (a desk under a window) has no one plane
    off = (coef @ dirs[ring].T) * depth[ring][None] - 1.0
    spread = np.sqrt((w[ok] * off**2).sum(1) / w[ok].sum(1))
    inv = np.einsum("bi,bi->b", coef, dirs[ok])
    fill[ok] = np.where((inv > 0) & (spread <= max_spread), 1.0 / np.maximum(inv, 1e-12),
                        np.inf)
    return fill


def scene_view(scene: SplatScene, point, mask: np.ndarray | None = None,
               colours: np.ndarray | None = None, bins: tuple[int, int] = BINS
               ) -> Surroundings:
    """:func:`look_from` for a scene's splats (``mask`` picks some; ``colours`` override)."""
    pick = np.ones(scene.count, bool) if mask is None else np.asarray(mask)
    rgb = scene.base_colours if colours is None else colours
    return look_from(point, scene.positions[pick], rgb[pick], splat_sigma(scene)[pick],
                     scene.opacities[pick], bins)
