"""The fast predictor: a small calibrated model of what lies under clipped regions.

No downloaded weights, numpy only, well under a second per megapixel.

Model. The photo is linearised through its curve; a pixel is clipped when its
brightest channel reaches ``CLIP``. For every clipped pixel the model predicts
``log2`` of its brightest linear channel (relative to the photo's white) from
features of the pixel and of its clipped region (8-connected component):

* depth: distance to the nearest unclipped pixel, and the region's largest depth
  and area (size and shape: a thin streak is shallow, a disc is deep);
* glow: the mean luminance of two rings around the region (near, far) and their
  ratio (a light source bright enough to clip far beyond white lights up its
  surroundings, a window or a white wall does not);
* context: the photo's median luminance and clipped fraction (how far the
  photo is over-exposed).

Lengths are measured in units of ``sqrt(H W) / 512`` pixels so the model does
not depend on resolution. A two-layer perceptron (:data:`PARAMS_FILE`, a few
KB, trained by ``python -m gaslight_usd.uplift.calibrate``) maps the features
to the log excess. Colour: channels that are not clipped keep their measured
value; clipped channels take the predicted peak times the ring's chromaticity,
never below white. Output values are clamped to at least the clip level, so a
clipped pixel never comes out darker than the sensor saw it.

Applied to its own output (the recursion), the predictor recognises the image
it rendered and re-exposes the same estimate 2 EV lower, so every step of the
stack agrees with the first estimate instead of re-guessing from its own
guesses.
"""

from __future__ import annotations

import hashlib
import json
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from .curves import Curve
from .predictors import register_predictor

CLIP = 0.99
PARAMS_FILE = Path(__file__).with_name("fast_predictor_params.json")
FEATURES = ("log_depth", "depth_frac", "log_max_depth", "log_area", "log_ring_near",
            "log_ring_far", "glow_ratio", "log_median", "clipped_frac", "one")
LUM = np.array([0.2126, 0.7152, 0.0722], np.float32)


@dataclass
class ClipFeatures:
    """Per-clipped-pixel features and what the renderer needs besides."""

    mask: np.ndarray
    """(H, W) bool: clipped pixels"""
    features: np.ndarray
    """(N, F) float32, rows in ``np.nonzero(mask)`` order"""
    chroma: np.ndarray
    """(N, 3) float32: colour of the pixel's region ring, max channel 1"""


def _scale(shape: tuple[int, ...]) -> float:
    return max(float(np.sqrt(shape[0] * shape[1])) / 512.0, 1e-3)


def clip_features(linear: np.ndarray, encoded: np.ndarray, clip: float = CLIP
                  ) -> ClipFeatures | None:
    """Features of every clipped pixel of one photo, or None if nothing is clipped."""
    mask = encoded.max(axis=-1) >= clip
    if not mask.any():
        return None
    scale = _scale(mask.shape)
    lum = np.clip(linear, 0.0, 1.0) @ LUM
    labels, count = ndimage.label(mask, structure=np.ones((3, 3), bool))
    depth = ndimage.distance_transform_edt(mask).astype(np.float32) / scale
    index = np.arange(1, count + 1)
    area = ndimage.sum_labels(np.ones_like(depth), labels, index) / scale ** 2
    max_depth = ndimage.maximum(depth, labels, index).astype(np.float32)
    # Rings: unclipped pixels within r of a region, labelled by their nearest region.
    dist_out, (iy, ix) = ndimage.distance_transform_edt(~mask, return_indices=True)
    dist_out = dist_out / scale
    nearest = labels[iy, ix]
    rings = []
    for lo, hi in ((0.0, 3.0), (3.0, 12.0)):
        sel = (~mask) & (dist_out > lo) & (dist_out <= hi)
        n = ndimage.sum_labels(sel, nearest, index)
        s = ndimage.sum_labels(np.where(sel, lum, 0.0), nearest, index)
        rings.append(np.where(n > 0, s / np.maximum(n, 1), 1.0).astype(np.float32))
    near = np.clip(rings[0], 1e-4, 1.0)
    far = np.clip(np.minimum(rings[1], near), 1e-4, 1.0)
    sel = (~mask) & (dist_out <= 3.0)
    chroma = np.stack([ndimage.sum_labels(np.where(sel, linear[..., c], 0.0), nearest, index)
                       for c in range(3)], axis=-1)
    chroma = np.clip(chroma, 0.0, None) + 1e-6
    chroma = (chroma / chroma.max(axis=-1, keepdims=True)).astype(np.float32)

    lab = labels[mask] - 1
    d = depth[mask]
    median = float(np.median(lum))
    columns = [
        np.log2(1.0 + d),
        d / np.maximum(max_depth[lab], 1e-3),
        np.log2(1.0 + max_depth[lab]),
        np.log2(1.0 + area[lab]),
        np.log2(near[lab]),
        np.log2(far[lab]),
        np.log2(near[lab] / far[lab]),
        np.full(d.shape, np.log2(max(median, 1e-4))),
        np.full(d.shape, float(mask.mean())),
        np.ones(d.shape),
    ]
    feats = np.stack(columns, axis=-1).astype(np.float32)
    return ClipFeatures(mask=mask, features=feats, chroma=chroma[lab])


class Mlp:
    """A tiny perceptron evaluated in numpy: standardise, tanh layers, softplus out."""

    def __init__(self, params: dict):
        self.mean = np.asarray(params["mean"], np.float32)
        self.std = np.asarray(params["std"], np.float32)
        self.layers = [(np.asarray(w, np.float32), np.asarray(b, np.float32))
                       for w, b in params["layers"]]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        h = (x - self.mean) / self.std
        for i, (w, b) in enumerate(self.layers):
            h = h @ w + b
            if i < len(self.layers) - 1:
                h = np.tanh(h)
        return np.logaddexp(0.0, h[:, 0]).astype(np.float32)  # softplus: excess >= 0


def load_params(path: Path = PARAMS_FILE) -> dict:
    return json.loads(Path(path).read_text())


def _digest(a: np.ndarray) -> str:
    return hashlib.blake2b(np.ascontiguousarray(a).tobytes(), digest_size=16).hexdigest()


class FastPredictor:
    """Calibrated highlight model; see the module docstring."""

    name = "fast"

    def __init__(self, params: dict | str | Path | None = None, cache_size: int = 8):
        if params is None or isinstance(params, (str, Path)):
            params = load_params(Path(params) if params else PARAMS_FILE)
        self.params = params
        self.model = Mlp(params["model"])
        self._cache: OrderedDict[str, np.ndarray] = OrderedDict()
        self._cache_size = cache_size

    def estimate(self, encoded: np.ndarray, curve: Curve) -> np.ndarray:
        """Linear radiance of the photo with clipped pixels filled (1.0 = white)."""
        enc = np.clip(np.asarray(encoded, np.float32), 0.0, 1.0)
        linear = curve.to_linear(enc)
        feats = clip_features(linear, enc)
        if feats is None or feats.mask.all():
            # nothing clipped, or nothing but clipped: no border to extrapolate from,
            # so a fully white photo stays at white (documented, sensible)
            return linear
        excess = self.model(feats.features)
        peak = np.exp2(excess)[:, None]
        filled = linear[feats.mask]
        clipped_ch = enc[feats.mask] >= CLIP
        guess = np.maximum(peak * feats.chroma, 1.0)
        filled = np.where(clipped_ch, guess, filled)
        out = linear.copy()
        out[feats.mask] = filled
        return out

    def _remember(self, rendered: np.ndarray, radiance: np.ndarray) -> None:
        self._cache[_digest(rendered)] = radiance
        while len(self._cache) > self._cache_size:
            self._cache.popitem(last=False)

    def darker(self, encoded: np.ndarray, curve: Curve, ev: float) -> np.ndarray:
        radiance = self._cache.get(_digest(np.asarray(encoded, np.float32)))
        if radiance is None:
            radiance = self.estimate(encoded, curve)
        radiance = radiance * np.float32(0.25)
        rendered = np.clip(curve.to_encoded(np.clip(radiance, 0.0, 1.0)), 0.0, 1.0).astype(
            np.float32)
        self._remember(rendered, radiance)
        return rendered

    def brighter(self, encoded: np.ndarray, curve: Curve, ev: float) -> np.ndarray:
        return curve.reexpose(encoded, 2.0)


def _factory(params: str | Path | None = None, **_: object) -> FastPredictor:
    return FastPredictor(params)


register_predictor("fast", _factory,
                   "calibrated highlight model on the CPU, no downloaded weights (default)")
