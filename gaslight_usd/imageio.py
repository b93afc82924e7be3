"""Image reading and EXR writing through OpenImageIO.

Reads JPEG, PNG, TIFF (8/16-bit), EXR and Radiance HDR; honours EXIF
orientation; returns float32 pixels with the colour space they are in. Writes
EXR (half by default, float when values exceed the half range) carrying
chromaticities, the colour-space name and provenance attributes, atomically.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import OpenImageIO as oiio

from . import colour
from .atomic import atomic_path
from .errors import InputError
from .kinds import HDR_EXTENSIONS, IMAGE_EXTENSIONS, LDR_EXTENSIONS  # noqa: F401 (re-exported)

HALF_MAX = 65504.0


@dataclass(frozen=True)
class Exposure:
    """A photo's exposure from EXIF, and its EV relative to ISO 100, f/1, 1 s.

    ``relative = t * (iso / 100) / N**2`` is proportional to the pixel value a
    given scene radiance produces; ``ev = log2(relative)``.
    """

    exposure_time: float | None
    f_number: float | None
    iso: float | None

    @property
    def known(self) -> bool:
        return self.exposure_time is not None

    @property
    def relative(self) -> float:
        t = self.exposure_time if self.exposure_time else 1.0
        n = self.f_number if self.f_number else 1.0
        iso = self.iso if self.iso else 100.0
        return t * (iso / 100.0) / (n * n)

    @property
    def ev(self) -> float:
        return math.log2(self.relative)


@dataclass
class Image:
    """Float32 pixels ``(H, W, 3)`` and what they hold."""

    pixels: np.ndarray
    colour_space: str
    path: Path | None = None
    exposure: Exposure = field(default_factory=lambda: Exposure(None, None, None))
    bit_depth: str = "float"
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def height(self) -> int:
        return int(self.pixels.shape[0])

    @property
    def width(self) -> int:
        return int(self.pixels.shape[1])


def _float_attr(spec: oiio.ImageSpec, *names: str) -> float | None:
    for name in names:
        value = spec.getattribute(name)
        if value is None:
            continue
        try:
            value = float(value[0] if isinstance(value, (tuple, list)) else value)
        except (TypeError, ValueError):
            continue
        if math.isfinite(value) and value > 0:
            return value
    return None


def exposure_from_spec(spec: oiio.ImageSpec) -> Exposure:
    return Exposure(
        exposure_time=_float_attr(spec, "ExposureTime", "Exif:ExposureTime"),
        f_number=_float_attr(spec, "FNumber", "Exif:FNumber"),
        iso=_float_attr(spec, "Exif:ISOSpeedRatings", "Exif:PhotographicSensitivity", "ISO"),
    )


def _default_space(path: Path, spec: oiio.ImageSpec, ldr_space: str) -> str:
    tagged = spec.getattribute("oiio:ColorSpace") or spec.getattribute("colorSpace")
    is_float = spec.format.basetype in (oiio.FLOAT, oiio.HALF, oiio.DOUBLE)
    if tagged and isinstance(tagged, str):
        try:
            return colour.resolve_space(tagged)
        except InputError:
            pass  # an unknown tag: fall back on what the file type implies
    return colour.DEFAULT_LINEAR_FILE_SPACE if is_float else ldr_space


def read_image(
    path: str | Path,
    colour_space: str | None = None,
    to_space: str | None = None,
    ldr_space: str = colour.DEFAULT_INPUT_SPACE,
    config_uri: str | None = None,
) -> Image:
    """Read an image as float32 RGB, EXIF orientation applied.

    ``colour_space`` names what the file holds (default: its tag, else
    ``ldr_space`` for 8/16-bit files and linear Rec.709 for float files);
    ``to_space`` converts on the way in. Raises :class:`InputError` naming the
    file for a missing or unreadable file and for NaN or infinite pixels.
    """
    path = Path(path)
    spec, pixels = read_pixels(path)
    orientation = int(spec.get_int_attribute("Orientation", 1))
    if orientation != 1:
        pixels = _reoriented(pixels, orientation)
    pixels = np.asarray(pixels, dtype=np.float32)
    if pixels.ndim == 2:
        pixels = pixels[..., None]
    channels = pixels.shape[2]
    if channels == 1 or channels == 2:
        pixels = np.repeat(pixels[..., :1], 3, axis=2)
    else:
        pixels = pixels[..., :3]
    pixels = np.ascontiguousarray(pixels)
    bad = int(np.count_nonzero(~np.isfinite(pixels)))
    if bad:
        raise InputError(f"contains {bad} NaN or infinite sample(s)", path)
    space = colour.resolve_space(colour_space, config_uri) if colour_space else (
        _default_space(path, spec, ldr_space)
    )
    if to_space:
        pixels = colour.convert(pixels, space, to_space, config_uri)
        space = colour.resolve_space(to_space, config_uri)
    metadata = {a.name: a.value for a in spec.extra_attribs}
    return Image(
        pixels=pixels,
        colour_space=space,
        path=path,
        exposure=exposure_from_spec(spec),
        bit_depth=str(spec.format),
        metadata=metadata,
    )


def read_pixels(path: str | Path, pixel_type: Any = None) -> tuple[oiio.ImageSpec, np.ndarray]:
    """The file's spec and all its pixels ``(H, W, C)``, read whole or not at all.

    Every read checks OpenImageIO's error state after decoding: a truncated or
    corrupt file (an EXR with missing chunks, a JPEG that ends early) would
    otherwise come back as an image padded with black or grey, silently. Such a
    file raises :class:`InputError` naming it. ``pixel_type`` defaults to float.
    """
    path = Path(path)
    inp = _open(path)
    try:
        spec = oiio.ImageSpec(inp.spec())
        pixels = inp.read_image(oiio.FLOAT if pixel_type is None else pixel_type)
        if pixels is None or inp.has_error:
            reason = inp.geterror().strip() or oiio.geterror().strip() or "no pixels"
            raise InputError(f"truncated or corrupt image: {_one_line(reason)}", path)
    finally:
        inp.close()
    pixels = np.asarray(pixels)
    if pixels.ndim == 2:
        pixels = pixels[..., None]
    return spec, pixels


def _open(path: Path) -> oiio.ImageInput:
    """An open OpenImageIO input for ``path``, or :class:`InputError` naming it."""
    if not path.exists():
        raise InputError("no such file", path)
    if path.is_dir():
        raise InputError("is a folder, expected an image file", path)
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        reason = oiio.geterror().strip() or "unknown format"
        raise InputError(f"cannot read image: {_one_line(reason)}", path)
    return inp


_IJG_LUMINANCE = np.array([
    16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55,
    14, 13, 16, 24, 40, 57, 69, 56, 14, 17, 22, 29, 51, 87, 80, 62,
    18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113, 92,
    49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99], np.float64)
"""The JPEG standard's example luminance quantisation table (Annex K), row by row."""
_ZIGZAG = np.array([
    0, 1, 8, 16, 9, 2, 3, 10, 17, 24, 32, 25, 18, 11, 4, 5, 12, 19, 26, 33, 40, 48, 41, 34,
    27, 20, 13, 6, 7, 14, 21, 28, 35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37,
    44, 51, 58, 59, 52, 45, 38, 31, 39, 46, 53, 60, 61, 54, 47, 55, 62, 63])
"""Where each coefficient of a DQT segment (stored in zigzag order) sits in the block."""


def jpeg_quality(path: str | Path) -> int | None:
    """The IJG quality (1-100) a JPEG's luminance table was scaled for, or None (not a
    JPEG, or no table 0). Encoders that follow libjpeg scale the standard table by
    ``5000 / q`` % under quality 50 and ``200 - 2 q`` % above; the median ratio of the
    file's table to the standard one inverts that."""
    data = Path(path).read_bytes()
    if data[:2] != b"\xff\xd8":
        return None
    pos = 2
    while pos + 4 <= len(data) and data[pos] == 0xFF:
        marker = data[pos + 1]
        length = int.from_bytes(data[pos + 2:pos + 4], "big")
        if marker == 0xDA:  # start of scan: no tables after it
            return None
        if marker == 0xDB:
            seg, i = data[pos + 4:pos + 2 + length], 0
            while i < len(seg):
                wide, table = seg[i] >> 4, seg[i] & 0x0F
                size = 128 if wide else 64
                chunk = seg[i + 1:i + 1 + size]
                if len(chunk) < size:  # a damaged segment: no estimate
                    return None
                raw = np.frombuffer(chunk, ">u2" if wide else "u1")
                if table == 0:
                    values = np.empty(64)
                    values[_ZIGZAG] = raw
                    scale = float(np.median(100.0 * values / _IJG_LUMINANCE))
                    quality = (200.0 - scale) / 2.0 if scale <= 100.0 else 5000.0 / scale
                    return int(np.clip(round(quality), 1, 100))
                i += 1 + size
        pos += 2 + length
    return None


def _one_line(text: str) -> str:
    """OpenImageIO repeats its message once per failed chunk: keep each line once."""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return "; ".join(dict.fromkeys(lines))


def _reoriented(pixels: np.ndarray, orientation: int) -> np.ndarray:
    """Pixels turned upright as the EXIF ``Orientation`` tag asks."""
    h, w, c = pixels.shape
    buf = oiio.ImageBuf(oiio.ImageSpec(w, h, c, oiio.FLOAT))
    buf.set_pixels(oiio.ROI(0, w, 0, h, 0, 1, 0, c), np.ascontiguousarray(pixels, np.float32))
    buf.specmod().attribute("Orientation", int(orientation))
    return np.asarray(oiio.ImageBufAlgo.reorient(buf).get_pixels(oiio.FLOAT), np.float32)


def read_header(path: str | Path) -> oiio.ImageSpec:
    """The image's spec (size, channels, attributes) without reading pixels."""
    inp = _open(Path(path))
    try:
        return oiio.ImageSpec(inp.spec())
    finally:
        inp.close()


def write_exr(
    path: str | Path,
    pixels: np.ndarray,
    colour_space: str,
    attributes: Mapping[str, Any] | None = None,
    half: bool | None = None,
    compression: str = "zip",
    config_uri: str | None = None,
    extra_channels: Mapping[str, np.ndarray] | None = None,
) -> Path:
    """Write float pixels ``(H, W, C)`` as an EXR, atomically.

    ``extra_channels``: named ``(H, W)`` planes stored after R, G, B (such as
    the HDR views' ``clip_floor``); readers that know only RGB ignore them.

    ``half=None`` picks half unless a value exceeds the half range (65504).
    The file carries ``chromaticities`` (when the space has known primaries),
    ``oiio:ColorSpace`` and ``colorSpace`` (the OCIO name), plus
    ``attributes`` (str, int, float or float sequences).
    """
    path = Path(path)
    data = np.ascontiguousarray(pixels, dtype=np.float32)
    if data.ndim == 2:
        data = data[..., None]
    names = None
    if extra_channels:
        if data.shape[2] != 3:
            raise ValueError("extra channels follow an RGB image")
        planes = [np.asarray(v, np.float32)[..., None] for v in extra_channels.values()]
        data = np.ascontiguousarray(np.concatenate([data, *planes], axis=2))
        names = ("R", "G", "B", *extra_channels)
    if not np.all(np.isfinite(data)):
        raise ValueError(f"refusing to write NaN/Inf pixels to {path}")
    if half is None:
        half = float(np.max(np.abs(data), initial=0.0)) <= HALF_MAX
    h, w, c = data.shape
    spec = oiio.ImageSpec(w, h, c, oiio.HALF if half else oiio.FLOAT)
    if names:
        spec.channelnames = names
    elif c >= 3:
        spec.channelnames = ("R", "G", "B", "A")[:c] if c <= 4 else spec.channelnames
    spec.attribute("compression", compression)
    info = colour.space_info(colour_space, config_uri)
    spec.attribute("oiio:ColorSpace", info.name)
    spec.attribute("colorSpace", info.name)
    if info.chromaticities:
        spec.attribute("chromaticities", "float[8]", tuple(info.chromaticities))
    for key, value in (attributes or {}).items():
        _set_attribute(spec, key, value)
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            raise OSError(f"cannot write {path}: {oiio.geterror()}")
        try:
            if not out.write_image(data):
                raise OSError(f"cannot write {path}: {out.geterror()}")
        finally:
            out.close()
        del out  # environment-map EXRs are only flushed once the output is gone
    return path


def read_channel(path: str | Path, name: str) -> np.ndarray | None:
    """One named channel of an image as float32 ``(H, W)``; None when it has none."""
    path = Path(path)
    buf = oiio.ImageBuf(str(path))
    if buf.has_error or not buf.initialized:
        raise InputError(f"cannot read image: {buf.geterror().strip() or 'unknown format'}", path)
    index = buf.spec().channelindex(name)
    if index < 0:
        return None
    plane = buf.get_pixels(oiio.FLOAT, roi=oiio.ROI(buf.roi.xbegin, buf.roi.xend,
                                                     buf.roi.ybegin, buf.roi.yend, 0, 1,
                                                     index, index + 1))
    if plane is None or buf.has_error:
        raise InputError(f"cannot decode channel {name!r}: {buf.geterror().strip()}", path)
    plane = np.asarray(plane, np.float32).reshape(buf.spec().height, buf.spec().width)
    if not np.all(np.isfinite(plane)):
        raise InputError(f"channel {name!r} holds NaN or infinite samples", path)
    return plane


def _set_attribute(spec: oiio.ImageSpec, key: str, value: Any) -> None:
    if isinstance(value, bool):
        spec.attribute(key, int(value))
    elif isinstance(value, (int, np.integer)):
        spec.attribute(key, int(value))
    elif isinstance(value, (float, np.floating)):
        spec.attribute(key, float(value))
    elif isinstance(value, str):
        spec.attribute(key, value)
    elif isinstance(value, (tuple, list, np.ndarray)):
        values = tuple(float(v) for v in np.asarray(value).ravel())
        spec.attribute(key, f"float[{len(values)}]", values)
    else:
        spec.attribute(key, str(value))


def list_images(folder: str | Path, extensions: tuple[str, ...] = IMAGE_EXTENSIONS) -> list[Path]:
    """Image files in ``folder`` (not recursive), sorted by name.

    An empty folder, or one with no image of the given types, is an InputError.
    """
    folder = Path(folder)
    if not folder.exists():
        raise InputError("no such folder", folder)
    if not folder.is_dir():
        raise InputError("expected a folder of images", folder)
    files = sorted(
        p for p in folder.iterdir()
        if p.is_file() and p.suffix.lower() in extensions and not p.name.startswith(".")
    )
    if not files:
        kinds = ", ".join(sorted({e.lstrip(".") for e in extensions}))
        raise InputError(f"folder holds no images ({kinds})", folder)
    return files
