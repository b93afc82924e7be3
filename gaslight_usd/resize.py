"""Working sizes and the area (box) resample every stage shrinks images with.

Phones and DSLRs give 12-24 MP photos while the uplift and the fit need far
fewer pixels; shrinking them first makes time and memory grow with the working
size, not with the camera. The resample is an area average: each output pixel
is the mean of the input area it covers (fractional pixels weighted by their
share), so a light's total power is kept and an integer ratio gives exactly
the plain box filter. It is two sparse matrix products (rows, then columns;
each output pixel reads only the few input pixels it covers), so a 12 MP
float image is shrunk without any full-size scratch copy.

Pixel-centre convention: pixel ``i`` covers ``[i, i + 1)``, its centre at
``i + 0.5``. Shrinking ``W`` to ``w`` maps ``x`` to ``x * w / W``, so a pinhole
camera's ``fx`` and ``cx`` scale by ``w / W`` (and ``fy``, ``cy`` by ``h / H``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import sparse


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


def area_weights(n_in: int, n_out: int) -> sparse.csr_matrix:
    """(n_out, n_in) sparse float32 weights: the share of output cell ``o`` (covering
    ``[o, o + 1) * n_in / n_out``) that each input cell covers; rows sum to 1."""
    ratio = n_in / n_out
    lo = np.arange(n_out) * ratio
    hi = lo + ratio
    cells = np.floor(lo).astype(np.int64)[:, None] + np.arange(math.ceil(ratio) + 1)[None]
    cover = np.minimum(hi[:, None], cells + 1) - np.maximum(lo[:, None], cells)
    keep = (cover > 0) & (cells < n_in)
    rows = np.broadcast_to(np.arange(n_out)[:, None], cells.shape)
    return sparse.csr_matrix(((cover / ratio)[keep].astype(np.float32),
                              (rows[keep], cells[keep])), shape=(n_out, n_in))


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
    rest = image.shape[2:]
    flat = np.asarray(image, np.float32).reshape(h, -1)
    low = area_weights(h, height) @ flat  # rows first: (height, W * C), a few MB
    low = low.reshape(height, w, -1).transpose(1, 0, 2).reshape(w, -1)
    out = (area_weights(w, width) @ low).reshape(width, height, -1).transpose(1, 0, 2)
    return np.ascontiguousarray(out.reshape(height, width, *rest)).astype(image.dtype)
