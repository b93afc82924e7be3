"""Working sizes and the area (box) resample every stage shrinks images with.

Phones and DSLRs give 12-24 MP photos while the uplift and the fit need far
fewer pixels; shrinking them first makes time and memory grow with the working
size, not with the camera. The resample is an area average: each output pixel
is the mean of the input area it covers (fractional pixels weighted by their
share), so a light's total power is kept and an integer ratio gives exactly
the plain box filter. It runs on prefix sums, one axis at a time and in row
blocks, so a 12 MP float image is shrunk without a full-size float64 copy.

Pixel-centre convention: pixel ``i`` covers ``[i, i + 1)``, its centre at
``i + 0.5``. Shrinking ``W`` to ``w`` maps ``x`` to ``x * w / W``, so a pinhole
camera's ``fx`` and ``cx`` scale by ``w / W`` (and ``fy``, ``cy`` by ``h / H``).
"""

from __future__ import annotations

import numpy as np

ROW_BLOCK = 256
"""Rows resampled at once (bounds the float64 scratch to a few tens of MB)."""


def fit_within(width: int, height: int, long_side: int) -> tuple[int, int]:
    """The size of a ``width`` x ``height`` image shrunk so its long side is ``long_side``.

    Never enlarges: an image already within ``long_side`` (or ``long_side`` <= 0,
    "the image's own size") keeps its size. Sides are rounded, at least 1.
    """
    longest = max(width, height)
    if long_side <= 0 or longest <= long_side:
        return width, height
    s = long_side / longest
    return max(1, round(width * s)), max(1, round(height * s))


def _area_axis(a: np.ndarray, n_out: int, axis: int) -> np.ndarray:
    """Area-average ``a`` along ``axis`` to ``n_out`` samples (float64 out)."""
    n_in = a.shape[axis]
    a = np.moveaxis(np.asarray(a, np.float64), axis, 0)
    prefix = np.concatenate([np.zeros((1, *a.shape[1:])), np.cumsum(a, axis=0)])
    edges = np.arange(n_out + 1) * (n_in / n_out)
    whole = np.minimum(np.floor(edges).astype(np.int64), n_in)
    frac = (edges - whole)[(...,) + (None,) * (a.ndim - 1)]
    inside = np.minimum(whole, n_in - 1)
    at_edge = prefix[whole] + frac * a[inside]
    out = (at_edge[1:] - at_edge[:-1]) * (n_out / n_in)
    return np.moveaxis(out, 0, axis)


def area_resize(image: np.ndarray, width: int, height: int) -> np.ndarray:
    """``(H, W, C)`` (or ``(H, W)``) shrunk to ``(height, width, ...)`` by area averaging.

    The output keeps the input's dtype. Exact (to float rounding) for integer
    ratios; enlarging is refused (ValueError): nothing here needs it.
    """
    h, w = image.shape[:2]
    if (width, height) == (w, h):
        return image
    if width > w or height > h or width < 1 or height < 1:
        raise ValueError(f"area_resize shrinks only: {w}x{h} -> {width}x{height}")
    if w % width == 0 and h % height == 0 and w // width == h // height:
        f = w // width  # an integer ratio: the plain box filter (what fits always used)
        return image.reshape(height, f, width, f, *image.shape[2:]).mean(
            axis=(1, 3)).astype(image.dtype)
    narrow = np.empty((h, width, *image.shape[2:]), np.float64)
    for r in range(0, h, ROW_BLOCK):  # row blocks bound the float64 scratch
        narrow[r:r + ROW_BLOCK] = _area_axis(image[r:r + ROW_BLOCK], width, axis=1)
    return _area_axis(narrow, height, axis=0).astype(image.dtype)
