"""The fast predictor: a small calibrated model of what lies under clipped regions.

No downloaded weights, numpy only, well under a second per megapixel.

Model. The photo is linearised through its curve; a pixel is clipped when its
brightest channel reaches ``CLIP_LEVEL``. Clipped pixels are grouped into regions
(8-connected components) and a two-layer perceptron (:data:`PARAMS_FILE`, a
few KB, trained by ``python -m gaslight_usd.bench.calibrate``) predicts, for
every region, ``log2`` of its mean brightest linear channel (relative to the
photo's white, so 0 means "just white") from region features:

* size and shape: area, largest depth (distance to the border), compactness
  (a thin streak is shallow, a disc is deep);
* glow: the mean luminance of four rings around the region (1.5 to 30 units
  out), the slope between the nearest and farthest ring, and how much of the
  nearest rings is itself near white (a sky or a white wall that only just
  clips has a flat near-white surround; a lamp or the sun lights a halo that
  falls off);
* colour: the ring's saturation and how many of the region's pixels clip in
  all three channels;
* context: the photo's median luminance and clipped fraction (how far the
  photo is over-exposed), the 99th percentile of its unclipped luminance and
  the share of unclipped pixels above half white (a photo metered for a dark
  room shows its bright surroundings near white), the region's share of all
  clipped pixels and its height in the frame.

A model names the features it was fitted on (its parameters' ``features``;
the first model's fifteen, :data:`LEGACY_FEATURES`, when it does not), so a
feature added later never breaks an older parameter file.

Lengths are in units of ``sqrt(H W) / 256`` pixels, so the model does not
depend on resolution. The calibration fits the relighting error itself (an
overestimated "sun" in a near-white sky costs far more than an underestimate),
so where the evidence is weak the prediction stays near white.

Rendering. Besides the mean, the perceptron gives every region a profile
and a colour. The profile mixes peaked shapes ``d ** p`` (``d`` the pixel's
distance to the region's border, ``p`` in :data:`PROFILES`: a cone, a steeper
peak, a near-point "sun"), each scaled to keep the mean, so the measured
white is at the edge and the energy sits where the region is deepest. Every
pixel is capped at :func:`peak_cap` (what EV -12, the recursion's last step,
still sees below the threshold), flattening the profile first so that the
energy is kept where it can be; so the recursion's darkest exposure never
clips. Colour: a pixel whose channels all clip takes the value times a mix of
the ring's chromaticity and white (a sun is whiter than the sky around it);
where only some channels clip, the unclipped ones keep their measured value
and bound the clipped ones: at most :data:`PARTIAL_LIMIT` times what the
ring's hue and the unclipped channels imply (a clear sky where only blue clips
stays a sky, not a 20x blue lamp), never below white.

The calibration fits this rendering rule (mean, profile mix, colour mix,
cap; linearised, see :mod:`.calibrate`) to the relighting error, so it
optimises what the benchmark measures rather than the region's true excess.

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

from ..colour import CLIP_LEVEL, REC709_Y
from ..errors import InputError
from .curves import Curve

"""Encoded level from which a channel counts as clipped."""
WHITE = 0.9
"""Encoded level counted as "near white" in the glow rings (the recursion's threshold)."""
MAX_STEPS = 6
"""The recursion's depth (EV -12): the estimate never exceeds what that step can show."""
CAP_LEVEL = 0.85
"""Encoded level the brightest pixel may reach at EV -12 (below the 0.9 threshold)."""
PROFILES = (1.0, 3.0, 12.0)
"""Powers of the border distance mixed into a region's profile (1: the cone)."""
SHRINK = 0.7
"""Factor on every region's predicted ``log2`` mean (towards "just white") at use.

On a panorama it never saw, the perceptron's full estimate overshoots often
enough to cost more than it gains (an overestimated "sun" in a near-white sky
costs far more relight PSNR than an underestimate). The factor is chosen by the
leave-one-panorama-out gain over all the calibration panoramas
(``python -m gaslight_usd.bench.calibrate`` scores every factor of
``calibrate.SHRINKS``), and checked on the uplift bench, where
``recursive-fast-unshrunk`` is charted beside it and ``recursive-fast-lopo``
scores each panorama with the model fitted without it
(``gaslight2usd bench --suite uplift --count 200``)."""
PARTIAL_LIMIT = 1.1
"""A clipped channel beside unclipped ones is at most this times what they imply
(the median truth on calibration crops, seed 1000, is 1.06-1.16 times that)."""
PARAMS_FILE = Path(__file__).with_name("fast_predictor_params.json")
LOPO_FILE = Path(__file__).with_name("fast_predictor_lopo.json")
"""The calibration's leave-one-panorama-out models (the bench scores each panorama's
crops with the model fitted without it: ``recursive-fast-lopo``)."""
RING_EDGES = (1.5, 4.0, 10.0, 30.0)
"""Outer radii of the glow rings in units of ``sqrt(H W) / 256`` pixels."""
RING_MIN_PX = (1.5, 3.0, 6.0, 12.0)
"""Smallest outer radii in pixels (small photos still get one pixel per ring)."""
LEGACY_FEATURES = ("log_area", "log_max_depth", "log_compact", "log_ring0", "log_ring1",
                   "log_ring2", "log_ring3", "glow_slope", "white0", "white1", "ring_sat",
                   "all_clipped", "log_median", "clipped_frac", "one")
"""The features of a model whose parameters do not name theirs."""
FEATURES = LEGACY_FEATURES[:-1] + ("area_share", "row", "log_p99", "bright_frac", "one")
"""Every feature :func:`region_features` computes; a model uses those it names."""
LUM = np.array(REC709_Y, np.float32)
"""Photos are sRGB-encoded: Rec.709 primaries."""


@dataclass
class RegionFeatures:
    """Clipped regions of one photo, their features and what the renderer needs."""

    mask: np.ndarray
    """(H, W) bool: clipped pixels"""
    labels: np.ndarray
    """(H, W) int32: region of every pixel, 0 outside"""
    features: np.ndarray
    """(R, F) float32, region ``r`` is label ``r + 1``"""
    chroma: np.ndarray
    """(R, 3) float32: colour of the region's near ring, max channel 1"""
    depth: np.ndarray
    """(H, W) float32: distance in pixels to the nearest unclipped pixel (0 outside)"""
    area: np.ndarray
    """(R,) pixel count of every region"""


def _unit(shape: tuple[int, ...]) -> float:
    return max(float(np.sqrt(shape[0] * shape[1])) / 256.0, 1e-3)


def channel_max(image: np.ndarray) -> np.ndarray:
    """Brightest channel of an ``(..., 3)`` array (much faster than ``max(axis=-1)``)."""
    return np.maximum(np.maximum(image[..., 0], image[..., 1]), image[..., 2])


def _window(mask: np.ndarray, margin: int) -> tuple[slice, slice]:
    """The bounding box of ``mask`` grown by ``margin`` pixels, clipped to the image."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    h, w = mask.shape
    return (slice(max(rows[0] - margin, 0), min(rows[-1] + margin + 1, h)),
            slice(max(cols[0] - margin, 0), min(cols[-1] + margin + 1, w)))


def region_features(linear: np.ndarray, encoded: np.ndarray, clip: float = CLIP_LEVEL
                    ) -> RegionFeatures | None:
    """Features of every clipped region of one photo, or None if nothing is clipped."""
    full_peak = channel_max(encoded)
    full_mask = full_peak >= clip
    if not full_mask.any():
        return None
    unit = _unit(full_mask.shape)
    full_lum = np.clip(linear, 0.0, 1.0) @ LUM
    median = float(np.median(full_lum))
    unclipped_lum = full_lum[~full_mask]
    p99 = float(np.percentile(unclipped_lum, 99.0)) if unclipped_lum.size else 1.0
    bright = float(np.mean(unclipped_lum >= 0.5)) if unclipped_lum.size else 0.0
    radii = [max(edge * unit, min_px) for edge, min_px in zip(RING_EDGES, RING_MIN_PX,
                                                              strict=True)]
    # Everything below happens in the window around the clipped pixels (the rings
    # reach at most the largest radius); the labels and depth are pasted back.
    win = _window(full_mask, int(np.ceil(radii[-1])) + 1)
    mask, peak, linear_w = full_mask[win], full_peak[win], linear[win]
    labels, count = ndimage.label(mask, structure=np.ones((3, 3), bool))
    depth = ndimage.distance_transform_edt(mask).astype(np.float32)
    lab = labels[mask]
    area = np.bincount(lab, minlength=count + 1)[1:].astype(np.float64)
    rows_mean = np.bincount(lab, weights=np.nonzero(mask)[0],
                            minlength=count + 1)[1:] / area
    max_depth = np.zeros(count + 1)
    np.maximum.at(max_depth, lab, depth[mask])
    max_depth = max_depth[1:]
    all_clipped = np.bincount(lab, weights=channel_max(-encoded[win][mask]) <= -clip,
                              minlength=count + 1)[1:] / area
    # Rings: unclipped pixels within a radius of a region, labelled by their nearest region.
    dist_out, (iy, ix) = ndimage.distance_transform_edt(~mask, return_indices=True)
    near_sel = (dist_out > 0) & (dist_out <= radii[-1])
    dist = dist_out[near_sel]
    nearest = labels[iy[near_sel], ix[near_sel]]
    ring_lin = linear_w[near_sel]
    lum = np.clip(ring_lin, 0.0, 1.0) @ LUM
    white = peak[near_sel] >= WHITE
    band = np.searchsorted(np.asarray(radii), dist, side="left")  # 0..3
    slot = nearest * len(radii) + band
    size = (count + 1) * len(radii)
    n = np.bincount(slot, minlength=size).reshape(count + 1, -1)[1:]
    ring_sum = np.bincount(slot, weights=lum, minlength=size).reshape(count + 1, -1)[1:]
    white_sum = np.bincount(slot, weights=white, minlength=size).reshape(count + 1, -1)[1:]
    rings, whites = ring_sum / np.maximum(n, 1), white_sum / np.maximum(n, 1)
    # an empty ring (the region fills the photo there) repeats the ring inside it
    for k in range(len(radii)):
        prev_r = rings[:, k - 1] if k else 1.0
        prev_w = whites[:, k - 1] if k else 1.0
        rings[:, k] = np.where(n[:, k] > 0, rings[:, k], prev_r)
        whites[:, k] = np.where(n[:, k] > 0, whites[:, k], prev_w)
    ring = np.log2(np.clip(rings, 1e-4, 1.0))
    close = band <= 1
    chroma = np.stack([np.bincount(nearest[close], weights=ring_lin[close, c],
                                   minlength=count + 1)[1:] for c in range(3)], axis=-1)
    chroma = np.clip(chroma, 0.0, None) + 1e-6
    chroma = chroma / chroma.max(axis=-1, keepdims=True)
    area_u = area / unit ** 2
    depth_u = max_depth / unit
    columns = [
        np.log2(1.0 + area_u),
        np.log2(1.0 + depth_u),
        np.log2(area_u / (np.pi * depth_u ** 2 + 1e-3) + 1e-3),
        *ring.T,
        ring[:, 0] - ring[:, 3],
        whites[:, 0],
        whites[:, 1],
        1.0 - chroma.min(axis=-1),
        all_clipped,
        np.full(count, np.log2(max(median, 1e-4))),
        np.full(count, float(full_mask.mean())),
        area / area.sum(),
        (rows_mean + win[0].start) / full_mask.shape[0] - 0.5,
        np.full(count, np.log2(max(p99, 1e-4))),
        np.full(count, bright),
        np.ones(count),
    ]
    feats = np.stack(columns, axis=-1).astype(np.float32)
    full_labels = np.zeros(full_mask.shape, np.int32)
    full_labels[win] = labels
    full_depth = np.zeros(full_mask.shape, np.float32)
    full_depth[win] = depth
    return RegionFeatures(mask=full_mask, labels=full_labels, features=feats,
                          chroma=chroma.astype(np.float32), depth=full_depth, area=area)


class Mlp:
    """A tiny perceptron evaluated in numpy: standardise, tanh layers, softplus out."""

    def __init__(self, params: dict):
        self.features = tuple(params.get("features", LEGACY_FEATURES))
        self.columns = np.array([FEATURES.index(f) for f in self.features])
        self.mean = np.asarray(params["mean"], np.float32)
        self.std = np.asarray(params["std"], np.float32)
        self.layers = [(np.asarray(w, np.float32), np.asarray(b, np.float32))
                       for w, b in params["layers"]]

    def raw(self, x: np.ndarray) -> np.ndarray:
        """The last layer's outputs ``(R, n_out)`` from every feature ``(R, len(FEATURES))``
        (or from the model's own columns ``(R, len(self.features))``)."""
        if x.shape[1] != len(self.features):
            x = x[:, self.columns]
        h = (x - self.mean) / self.std
        for i, (w, b) in enumerate(self.layers):
            h = h @ w + b
            if i < len(self.layers) - 1:
                h = np.tanh(h)
        return h

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """``log2`` of the region means (softplus of the first output: mean >= white)."""
        return np.logaddexp(0.0, self.raw(x)[:, 0]).astype(np.float32)

    def heads(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(log_mean (R,), profile weights (R, len(PROFILES)), ring colour share (R,))``.

        A one-output model (no profile or colour head) renders cones in the ring's colour.
        """
        h = self.raw(x)
        log_mean = np.logaddexp(0.0, h[:, 0]).astype(np.float32)
        k = len(PROFILES)
        if h.shape[1] >= 2 + k:
            logits = h[:, 1:1 + k] - h[:, 1:1 + k].max(axis=1, keepdims=True)
            weights = np.exp(logits)
            weights /= weights.sum(axis=1, keepdims=True)
            ring = 1.0 / (1.0 + np.exp(-h[:, 1 + k]))
        else:
            weights = np.zeros((len(h), k))
            weights[:, PROFILES.index(1.0)] = 1.0
            ring = np.ones(len(h))
        return log_mean, weights.astype(np.float32), ring.astype(np.float32)


def load_params(path: Path = PARAMS_FILE) -> dict:
    return json.loads(Path(path).read_text())


def peak_cap(curve: Curve, steps: int = MAX_STEPS, level: float = CAP_LEVEL) -> float:
    """The brightest linear value the recursion's darkest step still shows below ``level``."""
    return float(curve.to_linear(np.float32(level))) * 4.0 ** steps


def profile_weights(regions: RegionFeatures, mix: np.ndarray | None = None) -> np.ndarray:
    """Per-pixel profile ``w`` (clipped pixels in ``np.nonzero(mask)`` order), mean 1 per region.

    ``w = sum_k mix[r, k] d ** p_k / mean_r(d ** p_k)`` with ``p_k`` in
    :data:`PROFILES` and ``d`` the distance to the region's border; ``mix``
    ``(R, K)`` defaults to the cone alone.
    """
    lab = regions.labels[regions.mask] - 1
    d = regions.depth[regions.mask].astype(np.float64)
    count = len(regions.area)
    if mix is None:
        mix = np.zeros((count, len(PROFILES)))
        mix[:, PROFILES.index(1.0)] = 1.0
    w = np.zeros_like(d)
    for k, power in enumerate(PROFILES):  # a loop over a few shapes, never pixels
        if not np.any(mix[:, k] > 0):
            continue
        dk = d ** power
        mean_k = np.bincount(lab, weights=dk, minlength=count) / np.maximum(regions.area, 1)
        w += mix[lab, k] * dk / np.maximum(mean_k[lab], 1e-12)
    return w


def spread(regions: RegionFeatures, log_mean: np.ndarray, cap: float,
           mix: np.ndarray | None = None) -> np.ndarray:
    """Brightest-channel radiance of every clipped pixel (``np.nonzero(mask)`` order).

    Region ``r`` gets mean ``2 ** log_mean[r]`` (at least 1, white), spread as
    ``1 + (m - 1) w`` with ``w`` the :func:`profile_weights` (the cone
    ``d / mean(d)`` by default); where that peak would pass ``cap`` the profile
    is flattened towards uniform until it fits, and where even uniform does
    not fit the mean itself is capped.
    """
    lab = regions.labels[regions.mask] - 1
    count = len(regions.area)
    w_px = profile_weights(regions, mix)
    w_peak = np.zeros(count)
    np.maximum.at(w_peak, lab, w_px)
    excess = np.exp2(np.maximum(log_mean.astype(np.float64), 0.0)) - 1.0
    excess = np.minimum(excess, cap - 1.0)
    room = (cap - 1.0) / np.maximum(excess, 1e-12)  # the largest weight allowed
    flat = np.clip((w_peak - room) / np.maximum(w_peak - 1.0, 1e-12), 0.0, 1.0)
    w = (1.0 - flat[lab]) * w_px + flat[lab]
    return np.minimum(1.0 + excess[lab] * w, cap).astype(np.float32)


def fill_clipped(linear: np.ndarray, encoded: np.ndarray, regions: RegionFeatures,
                 value: np.ndarray, ring_share: np.ndarray | None = None) -> np.ndarray:
    """Linear image with the clipped channels of clipped pixels filled (see the module doc).

    ``value``: brightest-channel radiance of every clipped pixel (:func:`spread`);
    ``ring_share`` ``(R,)``: how much of the ring's chromaticity (against white)
    the pixels whose channels all clip take (default 1).
    """
    lab = regions.labels[regions.mask] - 1
    enc = encoded[regions.mask]
    lin = linear[regions.mask]
    clipped_ch = enc >= CLIP_LEVEL
    ring = regions.chroma[lab]
    share = np.ones(len(regions.area), np.float32) if ring_share is None else ring_share
    colour = share[lab, None] * ring + (1.0 - share[lab, None])
    guess = np.maximum(value[:, None] * colour, 1.0)
    # where some channels are measured, they bound the clipped ones through the ring's hue
    partial = ~clipped_ch.all(axis=-1)
    implied = channel_max(np.where(clipped_ch, 0.0, lin / np.maximum(ring, 0.05)))
    bound = np.maximum(PARTIAL_LIMIT * implied[:, None] * ring, 1.0)
    guess = np.where(partial[:, None], np.minimum(guess, bound), guess)
    out = linear.copy()
    out[regions.mask] = np.where(clipped_ch, guess, lin)
    return out


def _digest(a: np.ndarray) -> str:
    """A cheap key (shape and a sparse sample); the cache checks the full image on a hit."""
    sample = np.ascontiguousarray(a.reshape(-1)[::61])
    return f"{a.shape}:" + hashlib.blake2b(sample.tobytes(), digest_size=16).hexdigest()


class FastPredictor:
    """Calibrated highlight model; see the module docstring."""

    name = "fast"

    def __init__(self, params: dict | str | Path | None = None, cache_size: int = 8,
                 shrink: float = SHRINK):
        if params is None or isinstance(params, (str, Path)):
            params = load_params(Path(params) if params else PARAMS_FILE)
        self.params = params
        self.model = Mlp(params["model"])
        self.shrink = float(shrink)
        self._cache: OrderedDict[str, tuple[np.ndarray, np.ndarray]] = OrderedDict()
        self._cache_size = cache_size

    def region_log_means(self, regions: RegionFeatures) -> np.ndarray:
        """Predicted ``log2`` mean brightest channel of every region (>= 0)."""
        return self.shrink * self.model(regions.features)

    def estimate(self, encoded: np.ndarray, curve: Curve) -> np.ndarray:
        """Linear radiance of the photo with clipped pixels filled (1.0 = white)."""
        enc = np.clip(np.asarray(encoded, np.float32), 0.0, 1.0)
        linear = curve.to_linear(enc)
        regions = region_features(linear, enc)
        if regions is None or regions.mask.all():
            # nothing clipped, or nothing but clipped: no border to extrapolate from,
            # so a fully white photo stays at white (documented, sensible)
            return linear
        log_mean, mix, ring_share = self.model.heads(regions.features)
        log_mean = self.shrink * log_mean
        value = spread(regions, log_mean, peak_cap(curve), mix)
        return fill_clipped(linear, enc, regions, value, ring_share)

    def _remember(self, rendered: np.ndarray, radiance: np.ndarray) -> None:
        self._cache[_digest(rendered)] = (rendered, radiance)
        while len(self._cache) > self._cache_size:
            self._cache.popitem(last=False)

    def darker(self, encoded: np.ndarray, curve: Curve, ev: float) -> np.ndarray:
        encoded = np.asarray(encoded, np.float32)
        hit = self._cache.get(_digest(encoded))
        if hit is not None and np.array_equal(hit[0], encoded):
            radiance = hit[1]
        else:
            radiance = self.estimate(encoded, curve)
        radiance = radiance * np.float32(0.25)
        rendered = np.clip(curve.to_encoded(np.clip(radiance, 0.0, 1.0)), 0.0, 1.0).astype(
            np.float32)
        self._remember(rendered, radiance)
        return rendered

    def brighter(self, encoded: np.ndarray, curve: Curve, ev: float) -> np.ndarray:
        return curve.reexpose(encoded, 2.0)


def _factory(params: str | Path | None = None, **unknown: object) -> FastPredictor:
    """The ``fast`` predictor; an option it does not take is an error, not ignored."""
    if unknown:
        raise InputError(f"the fast predictor takes no {', '.join(sorted(unknown))} option "
                         "(it needs no downloaded weights; 'params' names another "
                         "calibration JSON)")
    return FastPredictor(params)


PREDICTORS = {
    "fast": (_factory, "calibrated highlight model on the CPU, no downloaded weights (default)"),
}
"""The predictors this module offers: name -> (factory, description); see
:mod:`.predictors`."""
