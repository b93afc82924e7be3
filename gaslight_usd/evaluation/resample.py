"""Resampling shared by the reference builder and the relighting protocol."""

from __future__ import annotations

import numpy as np

from ..cameras import direction_to_latlong


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


def sample_latlong(panorama: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Bilinear lookup of a lat-long panorama (OpenEXR convention) in unit directions.

    ``directions`` ``(..., 3)`` -> ``(..., C)``; longitude wraps, latitude clamps.
    """
    pano = np.asarray(panorama, np.float32)
    h, w = pano.shape[:2]
    xy = direction_to_latlong(directions, w, h) - 0.5  # pixel centres at integers
    x, y = xy[..., 0], np.clip(xy[..., 1], 0.0, h - 1.0)
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    x0 = x0.astype(np.int64) % w
    x1 = (x0 + 1) % w
    y0 = y0.astype(np.int64)
    y1 = np.minimum(y0 + 1, h - 1)
    top = pano[y0, x0] * (1 - fx) + pano[y0, x1] * fx
    bottom = pano[y1, x0] * (1 - fx) + pano[y1, x1] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32)
