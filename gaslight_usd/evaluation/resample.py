"""Area resampling shared by the reference builder and the relighting protocol
(bilinear and lat-long lookups live in :mod:`gaslight_usd.cameras`)."""

from __future__ import annotations

import numpy as np


def _box_weights(n_in: int, n_out: int) -> np.ndarray:
    """(n_out, n_in) weights: the fraction of each output cell covered by each input cell."""
    edges_out = np.arange(n_out + 1) * (n_in / n_out)
    lo = np.maximum(edges_out[:-1, None], np.arange(n_in)[None, :])
    hi = np.minimum(edges_out[1:, None], np.arange(n_in)[None, :] + 1)
    w = np.clip(hi - lo, 0.0, None)
    return w / w.sum(axis=1, keepdims=True)


def area_resize(image: np.ndarray, height: int, width: int) -> np.ndarray:
    """Resize ``(H, W, C)`` to ``(height, width, C)`` by exact area averaging.

    Each output pixel is the mean of the input area it covers, so the image
    mean (and a light's total power) is kept when downsampling.
    """
    img = np.asarray(image, np.float64)
    rows = _box_weights(img.shape[0], height)
    cols = _box_weights(img.shape[1], width)
    h, w, c = img.shape
    tall = (rows @ img.reshape(h, w * c)).reshape(height, w, c)  # two separable matmuls
    out = cols @ tall.transpose(1, 0, 2).reshape(w, height * c)
    return np.ascontiguousarray(out.reshape(width, height, c).transpose(1, 0, 2), np.float32)
