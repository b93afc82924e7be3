"""Debevec merge of an exposure stack in the log domain, with the paper's weights.

Each exposure ``k`` (encoded values ``v_k``, EV offset ``ev_k`` from the
reference image, so its exposure time is ``2 ** ev_k``) votes for the log
radiance ``ln f^-1(v_k) - ev_k ln 2`` with weight ``w_k(v_k)``:

* the reference (EV 0) image: 1 below 0.8, ramping to 0 at 1 (and, when
  brighter images exist, ramping from 0 at 0 to 1 at 0.2);
* middle exposures: the hat ``1 - 2 |v - 0.5|``;
* the darkest image: 1 from 0.5 up (the only one that sees the lamp; the paper
  asks for 1 above 0.9), the hat below;
* the brightest image (when brighter predictions exist): 1 up to 0.5, hat above.

Weights are taken per pixel from the brightest channel, not per channel: where
one channel clips before the others, all three then come from the same
exposure, which keeps the hue (a deviation from the paper's per-channel
weights, which mix exposures within one pixel). NaN votes weigh 0.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .curves import Curve

LOG_FLOOR = 1e-7
"""Linear values below this are floored before taking logs."""


def trapezoid(v: np.ndarray, low: float, high: float) -> np.ndarray:
    """1 on [low, high], ramping linearly to 0 at 0 and at 1 (no ramp if low=0/high=1)."""
    v = np.clip(v, 0.0, 1.0)
    up = np.ones_like(v) if low <= 0 else np.clip(v / low, 0.0, 1.0)
    down = np.ones_like(v) if high >= 1 else np.clip((1.0 - v) / (1.0 - high), 0.0, 1.0)
    return np.minimum(up, down)


def stack_weights(values: np.ndarray, evs: Sequence[float]) -> np.ndarray:
    """Weights ``(K, H, W)`` for the per-pixel max-channel ``values`` ``(K, H, W)``."""
    evs = np.asarray(evs, np.float64)
    k_count = len(evs)
    if k_count == 1:
        return np.ones_like(values)
    darkest, brightest = int(np.argmin(evs)), int(np.argmax(evs))
    has_brighter = bool(np.any(evs > 0))
    weights = np.empty_like(values)
    for k in range(k_count):  # a loop over exposures (at most ~9), never pixels
        v = values[k]
        if k == darkest:
            w = trapezoid(v, 0.5, 1.0)
        elif has_brighter and k == brightest:
            w = trapezoid(v, 0.0, 0.5)
        elif evs[k] == 0:
            w = trapezoid(v, 0.2 if has_brighter else 0.0, 0.8)
        else:
            w = trapezoid(v, 0.5, 0.5)
        weights[k] = w
    return np.nan_to_num(weights, nan=0.0)


def merge_stack(stack: Sequence[np.ndarray], evs: Sequence[float], curve: Curve,
                weights: np.ndarray | None = None) -> np.ndarray:
    """Merge encoded exposures into linear radiance relative to the EV-0 exposure.

    ``stack``: encoded images ``(H, W, 3)`` in [0, 1]; ``evs``: their EV offsets
    (``-2`` is two stops darker). Returns float32 ``(H, W, 3)`` linear values in
    the curve's primaries. Where every weight is 0 the darkest exposure wins.
    """
    if len(stack) != len(evs):
        raise ValueError("one EV per image is needed")
    shape = stack[0].shape
    if any(s.shape != shape for s in stack):
        raise ValueError("all images of a stack must have the same size")
    enc = np.stack([np.clip(np.nan_to_num(s, nan=0.0), 0.0, 1.0) for s in stack]).astype(
        np.float32)
    if weights is None:
        # the channel maximum, written out: 7x faster than max(axis=-1) on (..., 3)
        weights = stack_weights(np.maximum(np.maximum(enc[..., 0], enc[..., 1]), enc[..., 2]),
                                evs)
    weights = weights.astype(np.float32)
    lin = np.maximum(curve.to_linear(enc), LOG_FLOOR)
    scale = np.asarray(evs, np.float32)[:, None, None, None] * np.float32(np.log(2.0))
    votes = np.log(lin) - scale
    total = weights.sum(axis=0)[..., None]
    merged = (weights[..., None] * votes).sum(axis=0)
    darkest = int(np.argmin(evs))
    log_e = np.where(total > 1e-6, merged / np.maximum(total, 1e-6), votes[darkest])
    out = np.exp(log_e)
    out[out <= LOG_FLOOR * 1.0001] = 0.0
    return out.astype(np.float32)
