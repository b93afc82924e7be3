"""Colour palettes: the fewest colours that keep every instance's colour error small.

Colours are clustered with k-means in log2 radiance (so a lamp and a dim
wall are told apart by ratio, as the eye and exposure do). The palette grows
until the 95th percentile of the per-colour relative error
``|palette - colour| / |colour|`` (Euclidean RGB norms) is within tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DEFAULT_THRESHOLD = 1.0
"""Radiance (max channel of the base colour) above which a splat is an emitter (GaSLight)."""

FIT_SAMPLE = 20_000
"""K-means fits on at most this many colours; every colour is then assigned."""


@dataclass
class Palette:
    colours: np.ndarray        # (K, 3) linear colours
    labels: np.ndarray         # (N,) palette index of each input colour
    relative_error: np.ndarray  # (N,) |p - c| / |c|
    stops_error: np.ndarray    # (N,) brightness error in stops: abs(log2(sum p / sum c))

    @property
    def size(self) -> int:
        return int(self.colours.shape[0])

    def summary(self) -> dict[str, float]:
        if self.relative_error.size == 0:
            return {"palette_size": self.size}
        rel, stops = self.relative_error, self.stops_error
        return {
            "palette_size": self.size,
            "relative_error_median": float(np.median(rel)),
            "relative_error_p95": float(np.percentile(rel, 95)),
            "relative_error_max": float(rel.max()),
            "stops_error_median": float(np.median(stops)),
            "stops_error_p95": float(np.percentile(stops, 95)),
        }


def _log(colours: np.ndarray) -> np.ndarray:
    floor = max(float(colours.max(initial=0.0)) * 1e-4, 1e-8)
    return np.log2(np.maximum(colours, floor))


def _assign(x: np.ndarray, centres: np.ndarray) -> np.ndarray:
    d = (x * x).sum(1)[:, None] - 2 * x @ centres.T + (centres * centres).sum(1)[None]
    return np.argmin(d, axis=1)


def kmeans(x: np.ndarray, k: int, seed: int = 0, iterations: int = 30) -> np.ndarray:
    """(k, D) centres of ``x`` (N, D): k-means++ seeding, Lloyd iterations."""
    rng = np.random.default_rng(seed)
    n = x.shape[0]
    k = min(k, n)
    centres = np.empty((k, x.shape[1]), x.dtype)
    centres[0] = x[rng.integers(n)]
    d2 = ((x - centres[0]) ** 2).sum(1)
    for i in range(1, k):  # k-means++: k is the palette size, not the splat count
        total = d2.sum()
        pick = rng.integers(n) if total <= 0 else rng.choice(n, p=d2 / total)
        centres[i] = x[pick]
        d2 = np.minimum(d2, ((x - centres[i]) ** 2).sum(1))
    for _ in range(iterations):
        labels = _assign(x, centres)
        counts = np.bincount(labels, minlength=k)
        sums = np.zeros_like(centres)
        np.add.at(sums, labels, x)
        moved = np.where(counts[:, None] > 0, sums / np.maximum(counts, 1)[:, None], centres)
        if np.allclose(moved, centres, atol=1e-6):
            break
        centres = moved
    return centres


def _palette_for(colours: np.ndarray, k: int, seed: int) -> Palette:
    x = _log(colours)
    rng = np.random.default_rng(seed)
    sample = x if len(x) <= FIT_SAMPLE else x[rng.choice(len(x), FIT_SAMPLE, replace=False)]
    centres = kmeans(sample, k, seed)
    labels = _assign(x, centres)
    # Each palette colour is the mean (in linear) of its members: keeps power.
    sums = np.zeros((centres.shape[0], 3))
    np.add.at(sums, labels, colours)
    counts = np.bincount(labels, minlength=centres.shape[0])
    used = counts > 0
    pal = (sums[used] / counts[used, None]).astype(np.float32)
    remap = np.cumsum(used) - 1
    labels = remap[labels]
    approx = pal[labels]
    norm = np.linalg.norm(colours, axis=1)
    rel = np.linalg.norm(approx - colours, axis=1) / np.maximum(norm, 1e-12)
    stops = np.abs(np.log2(np.maximum(approx.sum(1), 1e-12) / np.maximum(colours.sum(1), 1e-12)))
    return Palette(pal, labels.astype(np.int64), rel.astype(np.float32),
                   stops.astype(np.float32))


def fit_palette(colours: np.ndarray, tolerance: float = 0.1, max_size: int = 64,
                seed: int = 0) -> Palette:
    """Smallest palette (up to ``max_size``) whose p95 relative error <= ``tolerance``.

    Doubles the size until the tolerance holds, then bisects between the last
    two sizes. If ``max_size`` cannot reach it, the ``max_size`` palette is
    returned and its error says so.
    """
    colours = np.asarray(colours, np.float32).reshape(-1, 3)
    if len(colours) == 0:
        empty = np.zeros(0, np.float32)
        return Palette(np.zeros((0, 3), np.float32), np.zeros(0, np.int64), empty, empty)

    def ok(p: Palette) -> bool:
        return float(np.percentile(p.relative_error, 95)) <= tolerance

    limit = min(max_size, len(colours))
    k, best, low = 1, None, 0
    while True:
        pal = _palette_for(colours, k, seed)
        if ok(pal) or k >= limit:
            best = pal
            break
        low = k
        k = min(2 * k, limit)
    high = k
    while high - low > 1 and ok(best):
        mid = (low + high) // 2
        pal = _palette_for(colours, mid, seed)
        if ok(pal):
            best, high = pal, mid
        else:
            low = mid
    return best
