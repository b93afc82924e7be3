"""Do two exposures show the same view? Compared only where both saw the scene.

A bracket's frames differ by stops, so most pixels are clipped in the bright
frame or sunk in the dark frame's quantisation noise; comparing whole images
(or a bracket's first frame with its last, 4 stops away) calls a real bracket
two views. Here two frames are compared on a small thumbnail, only on blocks
where *both* are unclipped (every pixel's brightest channel below
``CLIP_ENCODED``) and above the noise floor (every pixel's brightest channel
above ``NOISE_FLOOR_ENCODED``), by the rank correlation of their log
luminance: rank, so a camera tone curve that is not quite the assumed input
transform changes nothing; luminance normalised by EXIF exposure, so a flat
overlap can still be checked by its level. Too little overlap (a nearly black
frame against a mostly clipped one) measures nothing: ``None``, and the
caller decides from EXIF alone.

Measured by ``pytest tests/test_bracket.py -k similarity_separates -s`` (brackets and
neighbouring views of the bundled example and of real HDR crops).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..poses.views import View

THUMB_SIDE = 96
"""Longest thumbnail side in blocks."""
MAX_SHIFT_BLOCKS = 1
"""Hand-held frames are compared at every offset up to this many blocks (1 % of the
image) and the best is kept: a shift of half a block already decorrelates texture,
and larger searches make neighbouring views alike too."""
CLIP_ENCODED = 0.95
NOISE_FLOOR_ENCODED = 0.1
"""Encoded level (about 25 of 255) under which 8-bit quantisation and noise dominate."""
SMOOTH_BLOCKS = 3
"""Blocks per side of the window the log luminance is averaged over (usable where all are)."""
MIN_OVERLAP = 24
"""Fewest blocks both frames saw for a measured similarity."""
FLAT_STOPS = 0.05
"""Spread of log2 luminance (stops) under which an overlap is flat: no structure to rank."""
FLAT_MAX_OFFSET_STOPS = 0.75
"""A flat overlap whose exposure-normalised levels differ more than this is another view."""


@dataclass(frozen=True)
class Thumbnail:
    """Exposure-normalised log2 luminance per block, and which blocks are usable."""

    log_luminance: np.ndarray
    usable: np.ndarray


def _blocks(img: np.ndarray, factor: int) -> np.ndarray:
    h, w = (img.shape[0] // factor) * factor, (img.shape[1] // factor) * factor
    return img[:h, :w].reshape(h // factor, factor, w // factor, factor).swapaxes(1, 2)


def thumbnail(view: View, side: int = THUMB_SIDE) -> Thumbnail:
    """Block thumbnail of a photo: mean luminance, usable where no pixel clips or sinks."""
    factor = max(1, int(np.ceil(max(view.encoded.shape[:2]) / side)))
    brightest = _blocks(view.encoded.max(axis=-1), factor)
    usable = (brightest.max(axis=(2, 3)) < CLIP_ENCODED) & \
             (brightest.min(axis=(2, 3)) > NOISE_FLOOR_ENCODED)
    lum = _blocks(view.linear.mean(axis=-1), factor).mean(axis=(2, 3))
    lum = lum / np.float32(view.exposure_ratio)
    # a sliding window of SMOOTH_BLOCKS: texture finer than a window no longer
    # decorrelates when the frame moved by a fraction of a block
    log_lum = ndimage.uniform_filter(np.log2(np.maximum(lum, 1e-8)), SMOOTH_BLOCKS,
                                     mode="nearest")
    usable = ndimage.minimum_filter(usable, SMOOTH_BLOCKS, mode="constant", cval=False)
    return Thumbnail(log_lum, usable)


def _ranks(x: np.ndarray) -> np.ndarray:
    ranks = np.empty(len(x), np.float64)
    ranks[np.argsort(x, kind="stable")] = np.arange(len(x))
    return ranks


def _window(n: int, d: int) -> slice:
    return slice(max(0, d), n + min(0, d))


def _aligned_similarity(a: Thumbnail, b: Thumbnail, dy: int, dx: int) -> float | None:
    """Similarity with ``b`` displaced by (dy, dx) blocks."""
    h, w = a.usable.shape
    sa = (_window(h, dy), _window(w, dx))
    sb = (_window(h, -dy), _window(w, -dx))
    both = a.usable[sa] & b.usable[sb]
    if int(both.sum()) < MIN_OVERLAP:
        return None
    x, y = a.log_luminance[sa][both], b.log_luminance[sb][both]
    if x.std() < FLAT_STOPS or y.std() < FLAT_STOPS:
        return 0.0 if abs(float(np.median(x - y))) > FLAT_MAX_OFFSET_STOPS else None
    return float(np.corrcoef(_ranks(x), _ranks(y))[0, 1])


def similarity(a: Thumbnail, b: Thumbnail, max_shift: int = MAX_SHIFT_BLOCKS) -> float | None:
    """Rank correlation of two thumbnails where both are usable, at the best offset
    within ``max_shift`` blocks; None when too few blocks are usable in both as shot.

    A flat common region (no structure to rank) counts 0.0 when its
    exposure-normalised levels disagree by more than ``FLAT_MAX_OFFSET_STOPS``,
    else nothing.
    """
    if a.usable.shape != b.usable.shape:
        return 0.0
    if int((a.usable & b.usable).sum()) < MIN_OVERLAP:
        return None  # offsets would only compare regions the frames did not both see
    r = range(-max_shift, max_shift + 1)
    found = [s for s in (_aligned_similarity(a, b, dy, dx) for dy in r for dx in r)
             if s is not None]
    return max(found) if found else None
