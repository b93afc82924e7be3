"""Exposure brackets: group the photos of one view, recover the response, align, merge.

Grouping: an explicit grouping file, or EXIF. Photos are taken in name order;
a bracket is a run of consecutive photos of the same size whose exposures all
differ (a repeated exposure, a size change or, when EXIF capture times exist,
a gap of more than ``MAX_GAP_S`` seconds starts the next view).

Grouping file: JSON ``{"view": ["a.jpg", "b.jpg"], ...}`` or text lines
``view: a.jpg b.jpg`` (file names relative to the photo folder).

Response: the photo's OCIO input transform (default) or the Debevec-Malik
least-squares recovery from the bracket itself. Alignment: a translation per
photo from phase correlation of exposure-normalised log luminance on a
downsampled copy, chained from the middle exposure outwards. Merge:
:func:`.merge.merge_stack` with its weights (the darkest photo keeps the
highlights, the brightest the shadows).
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np
from scipy import ndimage

from ..errors import InputError
from ..views import View
from .curves import Curve, lut_curve
from .merge import merge_stack

MAX_GAP_S = 2.0
MIN_EV_STEP = 0.3


@dataclass
class Bracket:
    name: str
    views: list[View]

    @property
    def evs(self) -> list[float]:
        return [float(v.ev) if v.ev is not None else 0.0 for v in self.views]

    @property
    def is_bracket(self) -> bool:
        evs = self.evs
        return len(self.views) >= 2 and (max(evs) - min(evs)) >= MIN_EV_STEP


def _capture_time(view: View) -> datetime | None:
    from ..imageio import read_header

    try:
        spec = read_header(view.path)
    except InputError:
        return None
    raw = spec.getattribute("Exif:DateTimeOriginal") or spec.getattribute("DateTime")
    if not isinstance(raw, str):
        return None
    try:
        return datetime.strptime(raw.strip()[:19], "%Y:%m:%d %H:%M:%S")
    except ValueError:
        return None


@dataclass
class PhotoInfo:
    """What grouping needs of a photo, read from its header alone."""

    name: str
    path: Path
    ev: float | None
    shape: tuple[int, ...]


def photo_infos(paths: Sequence[Path]) -> list[PhotoInfo]:
    from ..imageio import exposure_from_spec, read_header

    infos = []
    for p in paths:
        spec = read_header(p)
        exp = exposure_from_spec(spec)
        infos.append(PhotoInfo(Path(p).stem, Path(p), exp.ev if exp.known else None,
                               (spec.height, spec.width, 3)))
    return infos


def _shape(photo: View | PhotoInfo) -> tuple[int, ...]:
    """The photo's size as shot (a View read shrunk remembers it)."""
    if isinstance(photo, PhotoInfo):
        return photo.shape
    if "photo_size" in photo.metadata:
        w, h = photo.metadata["photo_size"]
        return (h, w, photo.encoded.shape[2])
    return photo.encoded.shape


def _small_log_luminance(view: View, side: int = 48) -> tuple[np.ndarray, np.ndarray]:
    enc = view.encoded
    step = max(1, max(enc.shape[:2]) // side)
    enc = enc[::step, ::step]
    lin = view.linear[::step, ::step].mean(axis=-1) / view.exposure_ratio
    valid = (enc.max(axis=-1) < 0.95) & (enc.max(axis=-1) > 0.05)
    return np.log2(np.maximum(lin, 1e-6)), valid


SAME_VIEW_CORRELATION = 0.85
"""Least correlation of two photos' exposure-normalised log luminance (48 px) for "one view".
Brackets (hand-held shifts included) measure 0.97-0.99 in the tests; neighbouring views of
a smooth ceiling, 1/3 EV apart by auto-exposure, up to 0.70 (the example's view_16/17)."""


def same_view(a: View, b: View, min_correlation: float = SAME_VIEW_CORRELATION) -> bool:
    """Do two photos show the same view? Exposure-normalised luminance must correlate."""
    la, va = _small_log_luminance(a)
    lb, vb = _small_log_luminance(b)
    if la.shape != lb.shape:
        return False
    both = va & vb
    if both.sum() < 16:
        return True  # nothing comparable (e.g. 4+ stops apart): trust EXIF and sizes
    x, y = la[both], lb[both]
    if x.std() < 1e-3 or y.std() < 1e-3:
        return bool(abs(np.median(x - y)) < 0.5)
    return bool(np.corrcoef(x, y)[0, 1] >= min_correlation)


def group_by_exif(views: Sequence[View]) -> list[Bracket]:
    """Runs of same-size photos with distinct EXIF exposures (see module doc).

    Accepts :class:`View` or :class:`PhotoInfo` items; with Views (pixels at
    hand) a photo also has to show the same view as the group's first photo.
    """
    groups: list[list[View]] = []
    last_time: datetime | None = None
    for view in sorted(views, key=lambda v: v.name):
        when = _capture_time(view)
        current = groups[-1] if groups else None
        starts_new = (
            current is None or view.ev is None or any(v.ev is None for v in current)
            or _shape(current[0]) != _shape(view)
            or any(abs(v.ev - view.ev) < MIN_EV_STEP for v in current)
            or (when is not None and last_time is not None
                and abs((when - last_time).total_seconds()) > MAX_GAP_S)
            or (isinstance(view, View) and not same_view(current[0], view))
        )
        if starts_new:
            groups.append([view])
        else:
            current.append(view)
        last_time = when
    return [Bracket(g[len(g) // 2].name if len(g) > 2 else g[0].name, g) for g in groups]


def read_group_file(path: Path) -> dict[str, list[str]]:
    """Parse a grouping file (JSON object or ``view: a.jpg b.jpg`` lines)."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no such grouping file", path)
    text = path.read_text()
    try:
        data = json.loads(text)
    except json.JSONDecodeError:
        data = None
    if data is None:
        data = {}
        for n, line in enumerate(text.splitlines(), start=1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            if ":" not in line:
                raise InputError(f"line {n}: expected 'view: photo photo ...'", path)
            name, files = line.split(":", 1)
            data[name.strip()] = re.split(r"[\s,]+", files.strip())
    if not isinstance(data, dict) or not all(isinstance(v, list) for v in data.values()):
        raise InputError("expected an object mapping view names to lists of photos", path)
    return {str(k): [str(f) for f in v if f] for k, v in data.items()}


def group_from_file(views: Sequence[View], path: Path) -> list[Bracket]:
    by_name = {v.path.name: v for v in views} | {v.name: v for v in views}
    brackets = []
    for name, files in read_group_file(path).items():
        missing = [f for f in files if f not in by_name]
        if missing:
            raise InputError(f"view {name!r} names photos that are not in the input: "
                             + ", ".join(missing), path)
        brackets.append(Bracket(name, [by_name[f] for f in files]))
    return brackets


def group_brackets(views: Sequence[View], group_file: Path | None = None) -> list[Bracket]:
    return group_from_file(views, group_file) if group_file else group_by_exif(views)


def has_brackets(views: Sequence[View | PhotoInfo], group_file: Path | None = None) -> bool:
    """True when some view was shot as a bracket.

    With :class:`PhotoInfo` items (headers only) this is the EXIF test alone;
    :func:`find_brackets` also compares the pixels.
    """
    if group_file:
        return True
    return any(b.is_bracket for b in group_by_exif(views))


CONFIRM_SIZE = 512
"""Long side the candidate photos are read at to confirm a bracket by its pixels."""


def find_brackets(paths: Sequence[Path], input_space: str, working_space: str,
                  config_uri: str | None = None) -> list[Bracket]:
    """Brackets among photo files: EXIF candidates from headers, confirmed by pixels.

    The pixels are read shrunk to :data:`CONFIRM_SIZE` (the check compares 48-pixel
    thumbnails): every candidate of a 12 MP set at full size would hold gigabytes.
    """
    from ..views import load_views

    candidates = [b for b in group_by_exif(photo_infos(paths)) if b.is_bracket]
    if not candidates:
        return []
    views = load_views([p.path for b in candidates for p in b.views], input_space,
                       working_space, config_uri, long_side=CONFIRM_SIZE)
    return [b for b in group_by_exif(views) if b.is_bracket]


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
