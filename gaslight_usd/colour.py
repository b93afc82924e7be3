"""Colour management through OpenColorIO.

Every pixel inside the engine is float32 scene-linear in ONE working space
(default ACEScg). Config resolution order: an explicit ``--ocio-config`` over
``$OCIO`` over the built-in ``ocio://cg-config-latest``. Conversions go through
``PackedImageDesc`` (whole images at once), and processors are cached.
"""

from __future__ import annotations

import difflib
import os
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import PyOpenColorIO as OCIO

from .errors import InputError

BUILTIN_CONFIG = "ocio://cg-config-latest"
DEFAULT_INPUT_SPACE = "sRGB Encoded Rec.709 (sRGB)"
DEFAULT_WORKING_SPACE = "ACEScg"
DEFAULT_LINEAR_FILE_SPACE = "Linear Rec.709 (sRGB)"
"""What an EXR/HDR file with no colour-space tag is assumed to hold."""

# CIE xy chromaticities (R, G, B, white) of the scene-linear spaces, keyed by
# the OCIO interop id (which is also the USD colour-space token).
# Sources: ITU-R BT.709-6, ITU-R BT.2020-2, SMPTE ST 2065-1 (AP0),
# SMPTE S-2014-004 (AP1), SMPTE EG 432-1 (P3-D65), Adobe RGB (1998).
_D65 = (0.3127, 0.3290)
_ACES_WHITE = (0.32168, 0.33767)
CHROMATICITIES: dict[str, tuple[float, ...]] = {
    "lin_rec709_scene": (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, *_D65),
    "lin_ap1_scene": (0.713, 0.293, 0.165, 0.830, 0.128, 0.044, *_ACES_WHITE),
    "lin_ap0_scene": (0.7347, 0.2653, 0.0, 1.0, 0.0001, -0.077, *_ACES_WHITE),
    "lin_rec2020_scene": (0.708, 0.292, 0.170, 0.797, 0.131, 0.046, *_D65),
    "lin_p3d65_scene": (0.680, 0.320, 0.265, 0.690, 0.150, 0.060, *_D65),
    "lin_adobergb_scene": (0.64, 0.33, 0.21, 0.71, 0.15, 0.06, *_D65),
}


def resolve_config_uri(explicit: str | None = None) -> str:
    """``--ocio-config`` over ``$OCIO`` over the built-in CG config."""
    if explicit:
        return explicit
    return os.environ.get("OCIO") or BUILTIN_CONFIG


@lru_cache(maxsize=8)
def load_config(uri: str) -> OCIO.Config:
    try:
        return OCIO.Config.CreateFromFile(uri)
    except Exception as exc:  # OCIO raises its own Exception type
        raise InputError(f"cannot load OCIO config: {exc}", uri) from exc


def _all_names(config: OCIO.Config) -> dict[str, str]:
    """Every name and alias (lower-cased) -> canonical colour-space name."""
    names: dict[str, str] = {}
    for cs in config.getColorSpaces():
        names[cs.getName().lower()] = cs.getName()
        for alias in cs.getAliases():
            names[alias.lower()] = cs.getName()
    return names


def resolve_space(name: str, config_uri: str | None = None) -> str:
    """Canonical colour-space name for ``name`` (a name, alias or role).

    An unknown name raises :class:`InputError` listing the closest valid names.
    """
    uri = resolve_config_uri(config_uri)
    config = load_config(uri)
    cs = config.getColorSpace(name)
    if cs is not None:
        return cs.getName()
    names = _all_names(config)
    if name.lower() in names:
        return names[name.lower()]
    canonical = sorted({cs.getName() for cs in config.getColorSpaces()})
    close = difflib.get_close_matches(name.lower(), list(names), n=4, cutoff=0.4)
    suggestions = list(dict.fromkeys(names[c] for c in close)) or canonical[:6]
    raise InputError(
        f"unknown colour space {name!r} in OCIO config {uri}; closest: "
        + ", ".join(repr(s) for s in suggestions)
    )


@dataclass(frozen=True)
class SpaceInfo:
    name: str
    interop_id: str | None
    encoding: str
    is_scene_linear: bool
    chromaticities: tuple[float, ...] | None

    @property
    def usd_token(self) -> str | None:
        """The USD ColorSpaceAPI token (``lin_ap1_scene``...) if it is one."""
        token = self.interop_id
        if token and ":" not in token and token.endswith("_scene"):
            return token
        return None


def space_info(name: str, config_uri: str | None = None) -> SpaceInfo:
    uri = resolve_config_uri(config_uri)
    canonical = resolve_space(name, uri)
    cs = load_config(uri).getColorSpace(canonical)
    interop = cs.getInteropID() if hasattr(cs, "getInteropID") else None
    interop = interop or None
    encoding = cs.getEncoding() if hasattr(cs, "getEncoding") else ""
    return SpaceInfo(
        name=canonical,
        interop_id=interop,
        encoding=encoding,
        is_scene_linear=encoding == "scene-linear",
        chromaticities=CHROMATICITIES.get(interop or ""),
    )


@lru_cache(maxsize=64)
def _processor(uri: str, src: str, dst: str) -> OCIO.CPUProcessor:
    config = load_config(uri)
    proc = config.getProcessor(src, dst)
    return proc.getOptimizedCPUProcessor(OCIO.OPTIMIZATION_DEFAULT)


def convert(
    pixels: np.ndarray, src: str, dst: str, config_uri: str | None = None
) -> np.ndarray:
    """Convert an ``(..., 3)`` or ``(..., 4)`` float array from ``src`` to ``dst``.

    Returns a new float32 array; alpha (a 4th channel) passes through untouched.
    """
    uri = resolve_config_uri(config_uri)
    src_name, dst_name = resolve_space(src, uri), resolve_space(dst, uri)
    out = np.ascontiguousarray(pixels, dtype=np.float32).copy()
    if src_name == dst_name or out.size == 0:
        return out
    channels = out.shape[-1]
    if channels not in (3, 4):
        raise ValueError(f"convert expects 3 or 4 channels, got shape {pixels.shape}")
    flat = out.reshape(-1, channels)
    desc = OCIO.PackedImageDesc(flat, flat.shape[0], 1, channels)
    _processor(uri, src_name, dst_name).apply(desc)
    return out


REC709_Y = (0.2126, 0.7152, 0.0722)
"""ITU-R BT.709 luminance weights (CIE Y of the linear Rec.709/sRGB primaries): what
sRGB-encoded photos and Rec.709 files are weighed with. Pixels in the working space
take :func:`luminance_weights` of that space instead."""

CLIP_LEVEL = 0.99
"""Encoded value (0-1) at or above which a photo's channel counts as clipped; 8-bit
JPEGs land a little under 1.0 at saturation, so 1.0 itself would miss them."""
AT_WHITE = 1.0 - 1e-4
"""A luminance at or over this share of a white counts as at the white. A pixel a photo
recorded at its white reads a float32 ulp or two under it once its channels are weighed
into luminance, by the machine's summation order (0.9 x (0.2126 + 0.7152 + 0.0722) is
0.8999999 on one CPU and 0.9 on another), and a test against the white itself then
found a lamp on one machine and not on the next; 1e-4 is a fortieth of an 8-bit code."""
DARK_LEVEL = 3.0 / 255.0
"""Encoded value (0-1) at or under which a photo's channel counts as crushed to black:
an 8-bit photo's codes 0-3, where the sensor's floor, noise and JPEG's rounding leave
no measurement, only "at most this dark"."""


def luminance_weights(space: str | None = None, config_uri: str | None = None, *,
                      fallback: bool = False) -> np.ndarray:
    """Y weights (float32) of the space's RGB primaries (CIE Y of R, G and B).

    ``space`` None means linear Rec.709 (:data:`REC709_Y`). With ``fallback`` a
    space the config does not know also gives Rec.709's weights instead of an
    :class:`InputError` (in-memory data with a made-up space name, untagged files).
    """
    rec709_y = np.array(REC709_Y, dtype=np.float32)  # ITU-R BT.709
    if space is None:
        return rec709_y
    uri = resolve_config_uri(config_uri)
    try:
        basis = convert(np.eye(3, dtype=np.float32), space, DEFAULT_LINEAR_FILE_SPACE, uri)
    except InputError:
        if fallback:
            return rec709_y
        raise
    return (basis @ rec709_y).astype(np.float32)


def srgb_encode(x: np.ndarray) -> np.ndarray:
    """The IEC 61966-2-1 sRGB transfer function, linear [0, 1] -> encoded.

    Piecewise: ``12.92 x`` below 0.0031308, else ``1.055 x^(1/2.4) - 0.055``.
    """
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def srgb_decode(v: np.ndarray) -> np.ndarray:
    """The inverse of :func:`srgb_encode` (IEC 61966-2-1), encoded [0, 1] -> linear."""
    return np.where(v <= 0.04045, v / 12.92, np.power((v + 0.055) / 1.055, 2.4))
