"""Exposure brackets: group the photos of one view, recover the response, align, merge.

Grouping (:mod:`.grouping`): capture order, EXIF exposures that step by a
constant ratio, confirmed by image similarity where both frames saw the scene
(:mod:`.similarity`); or an explicit grouping file.

Response: the photo's OCIO input transform (default) or the Debevec-Malik
least-squares recovery from the bracket itself. Alignment: a translation per
photo from phase correlation of exposure-normalised log luminance on a
downsampled copy, chained from the middle exposure outwards. Merge:
:func:`.merge.merge_stack` with its weights (the darkest photo keeps the
highlights, the brightest the shadows).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from ..errors import InputError
from ..poses.views import View
from .curves import Curve, lut_curve
from .grouping import (  # noqa: F401 (re-exported: the bracket API in one place)
    MAX_GAP_S,
    MIN_EV_STEP,
    SAME_VIEW_SIMILARITY,
    Bracket,
    Grouping,
    Photo,
    Similar,
    bracket_candidates,
    group_from_file,
    plan_groups,
    read_group_file,
    read_photo,
)
from .merge import merge_stack
from .similarity import THUMB_SIDE, Thumbnail, similarity, thumbnail


@dataclass
class BracketOptions:
    """The options of the bracket merge (converter ``uplift.bracket``); the CLI reads
    its defaults from here."""

    group_file: str | None = None
    """A grouping file (one view per line, or JSON) overriding the EXIF grouping."""
    max_size: int = 0
    """Long side (pixels) photos are shrunk to (0: as shot)."""
    response: str = "ocio"
    """ocio: the input space's curve; debevec: recovered from each bracket."""
    align: bool = True
    save_stacks: bool = False


def photo_of_view(view: View) -> Photo:
    """The grouping facts of a loaded photo (capture time from its header)."""
    from ..imageio import exposure_from_spec, read_header
    from .grouping import capture_time

    taken = exposure_time = None
    try:
        spec = read_header(view.path)
        taken, exposure_time = capture_time(spec), exposure_from_spec(spec).exposure_time
    except InputError:
        pass
    return Photo(view.name, view.path, view.ev, exposure_time, view.encoded.shape, taken)


def view_similarity(views: Sequence[View | None]) -> Similar:
    """``similar(i, j)`` for :func:`.grouping.plan_groups`: thumbnails and pairs computed
    once, on demand (the split search asks about a pair once per candidate bracket)."""
    thumbs: dict[int, Thumbnail] = {}
    pairs: dict[tuple[int, int], float | None] = {}

    def thumb(i: int) -> Thumbnail:
        if i not in thumbs:
            thumbs[i] = thumbnail(views[i])
        return thumbs[i]

    def similar(i: int, j: int) -> float | None:
        if views[i] is None or views[j] is None:
            return None
        key = (min(i, j), max(i, j))
        if key not in pairs:
            pairs[key] = similarity(thumb(key[0]), thumb(key[1]))
        return pairs[key]

    return similar


def group_views(views: Sequence[View], group_file: Path | None = None,
                threshold: float = SAME_VIEW_SIMILARITY) -> Grouping:
    """Brackets (and single photos) of loaded photos; each Bracket holds its Views."""
    photos = [photo_of_view(v) for v in views]
    if group_file:
        grouping = group_from_file(photos, group_file)
    else:
        grouping = plan_groups(photos, view_similarity(views), threshold)
    for b in grouping.brackets:
        b.views = [views[i] for i in b.views]
    return grouping


def group_by_exif(views: Sequence[View]) -> list[Bracket]:
    """Brackets and single photos of loaded photos, grouped as the camera shot them."""
    return group_views(views).brackets


def group_brackets(views: Sequence[View], group_file: Path | None = None) -> list[Bracket]:
    return group_views(views, group_file).brackets


def find_brackets(paths: Sequence[Path], input_space: str, working_space: str,
                  config_uri: str | None = None, long_side: int = 8 * THUMB_SIDE
                  ) -> list[Bracket]:
    """Brackets among photo files: EXIF candidates from headers, confirmed by pixels.

    Only photos that could be in a bracket by EXIF are decoded, each shrunk as read to
    ``long_side`` (the similarity compares thumbnails of :data:`THUMB_SIDE` blocks, so
    a 12 MP photo need not stay whole in memory: 8 of them are 1.1 GB as float32).
    """
    from ..poses.views import load_views

    photos = [read_photo(Path(p)) for p in paths]
    wanted = sorted(bracket_candidates(photos))
    if not wanted:
        return []
    loaded = load_views([photos[i].path for i in wanted], input_space, working_space,
                        config_uri, long_side)
    views: list[View | None] = [None] * len(photos)
    for i, v in zip(wanted, loaded, strict=True):
        views[i] = v
    grouping = plan_groups(photos, view_similarity(views))
    found = [b for b in grouping.brackets if len(b.views) > 1]
    for b in found:
        b.views = [views[i] for i in b.views]
    return [b for b in found if b.is_bracket]


def check_bracket(bracket: Bracket, where: Path | None = None) -> None:
    """Refuse what cannot be merged, with a one-line reason."""
    shapes = {v.encoded.shape for v in bracket.views}
    if len(shapes) > 1:
        sizes = ", ".join(f"{v.path.name} {v.encoded.shape[1]}x{v.encoded.shape[0]}"
                          for v in bracket.views)
        raise InputError(f"bracket {bracket.name!r} mixes image sizes ({sizes})", where)
    if any(v.ev is None for v in bracket.views):
        raise InputError(f"bracket {bracket.name!r}: a photo has no EXIF exposure time, "
                         "so its exposure is unknown", where)
    if not bracket.is_bracket:
        raise InputError(f"bracket {bracket.name!r} has a single exposure "
                         f"({len(bracket.views)} photo(s) at EV {bracket.evs[0]:.2f}); "
                         "a bracket needs at least two different exposures", where)


# -- camera response (Debevec & Malik 1997) ----------------------------------

def recover_response(stack: Sequence[np.ndarray], evs: Sequence[float], samples: int = 200,
                     smoothness: float = 50.0, levels: int = 256, seed: int = 0) -> Curve:
    """The camera response from a bracket, as a :class:`Curve` (white -> 1).

    Solves ``g(Z_ij) = ln E_i + ln t_j`` in least squares with a hat weight
    (0 at black and white: clipped samples say nothing) and a uniform
    second-difference smoothness term, which also extrapolates ``g`` to white
    (anchored at ``g(white) = 0``), per channel, on ``samples`` pixels
    spread over the brightness range; the channels' curves are averaged (most
    cameras share one tone curve across channels).
    """
    rng = np.random.default_rng(seed)
    enc = np.stack([np.clip(s, 0.0, 1.0) for s in stack])
    z = np.round(enc * (levels - 1)).astype(np.int64)
    ln_t = np.asarray(evs, np.float64) * np.log(2.0)
    mid = int(np.argsort(evs)[len(evs) // 2])
    flat = z[mid].reshape(-1, 3)
    hat = np.minimum(np.arange(levels), levels - 1 - np.arange(levels)).astype(np.float64)
    curves = []
    for c in range(3):
        # pixels spread over the middle exposure's levels
        order = np.argsort(flat[:, c], kind="stable")
        picks = order[np.linspace(0, len(order) - 1, samples).astype(int)]
        picks = np.unique(np.concatenate([picks, rng.integers(0, len(order), samples // 4)]))
        zc = z[..., c].reshape(len(stack), -1)[:, picks].T  # (N, P)
        n, p = zc.shape
        rows = n * p + 1 + (levels - 2)
        a = np.zeros((rows, levels + n))
        b = np.zeros(rows)
        w = hat[zc].ravel()
        r = np.arange(n * p)
        a[r, zc.ravel()] = w
        a[r, levels + np.repeat(np.arange(n), p)] = -w
        b[r] = w * np.tile(ln_t, n)
        a[n * p, levels - 1] = 1.0  # g(white) = 0: white reads as linear 1
        k = np.arange(1, levels - 1)
        s = n * p + 1 + np.arange(levels - 2)
        a[s, k - 1] = smoothness
        a[s, k] = -2 * smoothness
        a[s, k + 1] = smoothness
        g = np.linalg.lstsq(a, b, rcond=None)[0][:levels]
        curves.append(g)
    g = np.mean(curves, axis=0)
    lin = np.exp(g - g[-1])
    lin[0] = 0.0
    return lut_curve("debevec", np.linspace(0.0, 1.0, levels), lin)


# -- alignment ----------------------------------------------------------------

def _downsample(img: np.ndarray, max_side: int) -> tuple[np.ndarray, float]:
    factor = max(1, int(np.ceil(max(img.shape[:2]) / max_side)))
    h, w = (img.shape[0] // factor) * factor, (img.shape[1] // factor) * factor
    small = img[:h, :w].reshape(h // factor, factor, w // factor, factor).mean(axis=(1, 3))
    return small, float(factor)


def phase_correlation(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Sub-pixel (dy, dx) such that ``b`` shifted by it matches ``a``."""
    win = np.outer(np.hanning(a.shape[0]), np.hanning(a.shape[1]))
    fa = np.fft.rfft2((a - a.mean()) * win)
    fb = np.fft.rfft2((b - b.mean()) * win)
    cross = fa * np.conj(fb)
    corr = np.fft.irfft2(cross / np.maximum(np.abs(cross), 1e-12), s=a.shape)
    py, px = np.unravel_index(int(np.argmax(corr)), corr.shape)

    def refine(c_m: float, c_0: float, c_p: float) -> float:
        den = c_m - 2 * c_0 + c_p
        return 0.0 if abs(den) < 1e-12 else 0.5 * (c_m - c_p) / den

    h, w = corr.shape
    dy = py + refine(corr[(py - 1) % h, px], corr[py, px], corr[(py + 1) % h, px])
    dx = px + refine(corr[py, (px - 1) % w], corr[py, px], corr[py, (px + 1) % w])
    dy = dy - h if dy > h / 2 else dy
    dx = dx - w if dx > w / 2 else dx
    return float(dy), float(dx)


def _log_luminance(encoded: np.ndarray, ev: float, curve: Curve, low: float, high: float
                   ) -> np.ndarray:
    lin = curve.to_linear(np.clip(encoded, 0, 1)).mean(axis=-1) / 2.0 ** ev
    return np.log2(np.clip(lin, low, high))


def estimate_shifts(stack: Sequence[np.ndarray], evs: Sequence[float], curve: Curve,
                    max_side: int = 512) -> list[tuple[float, float]]:
    """Translation of each photo relative to the middle exposure, in pixels."""
    order = list(np.argsort(evs))
    mid = order[len(order) // 2]
    shifts: dict[int, tuple[float, float]] = {int(mid): (0.0, 0.0)}
    pos = order.index(mid)
    for direction in (-1, 1):
        i = pos
        while 0 <= i + direction < len(order):
            a, b = order[i], order[i + direction]
            low = max(0.03 / 2.0 ** evs[a], 0.03 / 2.0 ** evs[b])
            high = min(0.9 / 2.0 ** evs[a], 0.9 / 2.0 ** evs[b])
            if high <= low:  # no common range: fall back on edges of each
                low, high = 1e-4, 1e4
            sa, f = _downsample(_log_luminance(stack[a], evs[a], curve, low, high), max_side)
            sb, _ = _downsample(_log_luminance(stack[b], evs[b], curve, low, high), max_side)
            dy, dx = phase_correlation(sa, sb)
            base = shifts[int(a)]
            shifts[int(b)] = (base[0] + dy * f, base[1] + dx * f)
            i += direction
    return [shifts[i] for i in range(len(stack))]


def apply_shift(img: np.ndarray, shift: tuple[float, float]) -> np.ndarray:
    if abs(shift[0]) < 1e-3 and abs(shift[1]) < 1e-3:
        return img
    return ndimage.shift(img, (shift[0], shift[1], 0.0), order=1, mode="nearest")


@dataclass
class BracketResult:
    linear: np.ndarray
    """Merged radiance in the curve's primaries, relative to the bracket's reference."""
    reference: int
    evs: list[float]
    shifts: list[tuple[float, float]]
    curve: Curve


def merge_bracket(stack: Sequence[np.ndarray], evs: Sequence[float], curve: Curve,
                  align: bool = True, max_shift: float = 0.05) -> BracketResult:
    """Align and merge one bracket; radiance is relative to its middle exposure.

    Shifts larger than ``max_shift`` of the image size are treated as failed
    estimates and ignored (the tool compensates hand-held jitter, not motion).
    """
    evs = [float(e) for e in evs]
    ref = int(np.argsort(evs)[len(evs) // 2])
    rel = [e - evs[ref] for e in evs]
    shifts = estimate_shifts(stack, rel, curve) if align else [(0.0, 0.0)] * len(stack)
    limit = max_shift * max(stack[0].shape[:2])
    shifts = [s if max(abs(s[0]), abs(s[1])) <= limit else (0.0, 0.0) for s in shifts]
    aligned = [apply_shift(np.asarray(s, np.float32), sh) for s, sh in zip(stack, shifts,
                                                                           strict=True)]
    linear = merge_stack(aligned, rel, curve)
    return BracketResult(linear, ref, rel, shifts, curve)
