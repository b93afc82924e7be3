"""Photo sets in and HDR view sets out: the ingest step every uplift shares.

A photo is decoded, its clipped pixels are found on the encoded values, and it
is linearised into the working space. Exposures from EXIF are normalised to
the set's median, so HDR values are *relative radiance*: 1.0 is the radiance
that reads as linear 1.0 at the reference exposure. That scale is recorded in
every output (``gaslight:exposure_scale`` and ``gaslight:reference_ev``).

Photos are read one at a time (:func:`iter_views`): the set's reference
exposure comes from the files' headers, so no stage holds every decoded photo
at once. ``long_side`` shrinks each photo as it is read (area average of the
encoded values, as an image editor's resize gives; pixels inside a clipped
lamp stay clipped), so a 12 MP photo costs one decode, then its working size.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import colour
from ..colour import CLIP_LEVEL, DARK_LEVEL
from ..imageio import (
    IMAGE_EXTENSIONS,
    LDR_EXTENSIONS,
    exposure_from_spec,
    list_images,
    read_header,
    read_image,
    write_exr,
)
from ..resize import area_resize, fit_within

logger = logging.getLogger(__name__)

CLIP_FLOOR_CHANNEL = "clip_floor"
"""The HDR views' extra EXR channel: in pixels the photo clipped, the luminance the photo
recorded there (relative radiance, working space), a lower bound on the true luminance;
0 where the photo measured the pixel. The fit treats those pixels as bounds, not targets
(:mod:`gaslight_usd.fit.losses`)."""
DARK_CEILING_CHANNEL = "dark_ceiling"
"""The HDR views' second extra channel: in pixels the photo crushed to black (every
channel at or under :data:`gaslight_usd.colour.DARK_LEVEL`), the luminance of that level
(relative radiance, working space), an upper bound on the true luminance; 0 where the
photo measured the pixel. A frame exposed for a light (the README's "shooting the
lights") is black but for the light: its black says "at most this", not "nothing
there" (``gaslight2usd bench --suite chain --method "recursive + dark frames"``
measures such frames)."""


@dataclass
class View:
    """One photo: encoded pixels (as shot), linear working-space pixels, exposure."""

    name: str
    path: Path
    encoded: np.ndarray
    linear: np.ndarray
    exposure_ratio: float
    """This photo's exposure / the set's reference exposure."""
    ev: float | None
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def clipped_mask(self) -> np.ndarray:
        return np.any(self.encoded >= CLIP_LEVEL, axis=-1)

    @property
    def clipped_fraction(self) -> float:
        return float(np.mean(self.clipped_mask))

    @property
    def relative_radiance(self) -> np.ndarray:
        return self.linear / np.float32(self.exposure_ratio)

    @property
    def crushed_mask(self) -> np.ndarray:
        return np.all(self.encoded <= DARK_LEVEL, axis=-1)

    def dark_ceiling(self, weights: np.ndarray, working_space: str,
                     config_uri: str | None = None) -> np.ndarray:
        """``(H, W)``: the luminance of an encoded :data:`~gaslight_usd.colour.DARK_LEVEL`
        in every channel (relative radiance, ``weights`` the working space's Y weights)
        where the photo crushed to black, 0 elsewhere; see :data:`DARK_CEILING_CHANNEL`."""
        crushed = self.crushed_mask
        if not crushed.any():
            return np.zeros(crushed.shape, np.float32)
        level = colour.convert(np.full((1, 1, 3), DARK_LEVEL, np.float32),
                               self.metadata.get("source_space", colour.DEFAULT_INPUT_SPACE),
                               working_space, config_uri)
        value = float(np.maximum(level.reshape(3), 0.0) @ weights.astype(np.float32))
        value = max(value, 1e-9) / float(self.exposure_ratio)
        return np.where(crushed, value, 0.0).astype(np.float32)

    def clip_floor(self, weights: np.ndarray) -> np.ndarray:
        """``(H, W)``: the recorded luminance (``weights``: the working space's Y weights)
        where the photo clipped, 0 elsewhere; see :data:`CLIP_FLOOR_CHANNEL`."""
        recorded = np.maximum(self.relative_radiance, 0.0) @ weights.astype(np.float32)
        return np.where(self.clipped_mask, np.maximum(recorded, 1e-6), 0.0).astype(np.float32)


def reference_ev(paths: list[Path]) -> float:
    """The set's reference EV: the median EXIF EV of the photos that carry one (0 if none),
    read from the headers alone."""
    evs = [e.ev for e in (exposure_from_spec(read_header(p)) for p in paths) if e.known]
    return float(np.median(evs)) if evs else 0.0


def iter_views(paths: list[Path] | Path, input_space: str, working_space: str,
               config_uri: str | None = None, long_side: int = 0) -> Iterator[View]:
    """Photos (a folder or a list) one at a time: linearised, exposure-normalised, and
    shrunk so the long side is at most ``long_side`` (0: as shot)."""
    if isinstance(paths, Path):
        paths = list_images(paths, LDR_EXTENSIONS)
    missing = [p.name for p in paths if not exposure_from_spec(read_header(p)).known]
    warn_missing_exposure(missing, len(paths))
    reference = reference_ev(paths)
    for path in paths:
        im = read_image(path, colour_space=input_space, config_uri=config_uri)
        h, w = im.pixels.shape[:2]
        encoded = area_resize(im.pixels, *fit_within(w, h, long_side))
        ev = im.exposure.ev if im.exposure.known else None
        linear = colour.convert(encoded, im.colour_space, working_space, config_uri)
        ratio = 2.0 ** (ev - reference) if ev is not None else 1.0
        yield View(name=im.path.stem, path=im.path, encoded=encoded, linear=linear,
                   exposure_ratio=ratio, ev=ev,
                   metadata={"reference_ev": reference, "source_space": im.colour_space,
                             "photo_size": [w, h]})


def load_views(paths: list[Path] | Path, input_space: str, working_space: str,
               config_uri: str | None = None, long_side: int = 0) -> list[View]:
    """Every photo at once (bracket grouping needs them together); see :func:`iter_views`."""
    return list(iter_views(paths, input_space, working_space, config_uri, long_side))


def warn_missing_exposure(names: list[str], total: int) -> None:
    """Say which photos have no EXIF exposure: their relative radiance is a guess.

    Such a photo is taken as exposed like the set's median; a bracket or an
    exposure change between shots then shows up as a wrong brightness, silently.
    """
    if not names:
        return
    listed = ", ".join(names[:5]) + (" ..." if len(names) > 5 else "")
    what = "no photo carries" if len(names) == total else f"{len(names)} of {total} photos carry no"
    logger.warning("%s EXIF exposure (ExposureTime): %s; taken as exposed like the "
                   "set's median, so their relative radiance may be off", what, listed)


def hdr_attributes(view: View, method: str, extra: dict[str, Any] | None = None) -> dict:
    attrs = {
        "gaslight:method": method,
        "gaslight:source": view.path.name,
        "gaslight:exposure_scale": 1.0,
        "gaslight:exposure_ratio": float(view.exposure_ratio),
        "gaslight:reference_ev": float(view.metadata.get("reference_ev", 0.0)),
        "gaslight:clipped_fraction_before": view.clipped_fraction,
    }
    if view.ev is not None:
        attrs["gaslight:ev"] = float(view.ev)
    if "photo_size" in view.metadata:
        attrs["gaslight:photo_size"] = [int(v) for v in view.metadata["photo_size"]]
    attrs.update(extra or {})
    return attrs


def write_hdr_view(folder: Path, view: View, radiance: np.ndarray, working_space: str,
                   method: str, extra: dict[str, Any] | None = None,
                   config_uri: str | None = None, clipped_by: View | None = None,
                   crushed_by: View | None = None) -> Path:
    """Write one HDR view as ``<folder>/<photo stem>.exr`` (atomic), with its clip floor
    and its dark ceiling.

    ``clipped_by``: the photo whose clipping bounds this radiance (default ``view``;
    for a merged bracket, its darkest frame: only what that frame clipped is unmeasured);
    ``crushed_by``: the photo whose black bounds it (default ``view``; for a bracket,
    its brightest frame).
    """
    weights = colour.luminance_weights(working_space, config_uri)
    floor = (clipped_by or view).clip_floor(weights)
    if floor.shape != radiance.shape[:2]:
        floor = np.zeros(radiance.shape[:2], np.float32)
    ceiling = (crushed_by or view).dark_ceiling(weights, working_space, config_uri)
    if ceiling.shape != radiance.shape[:2]:
        ceiling = np.zeros(radiance.shape[:2], np.float32)
    return write_exr(folder / f"{view.name}.exr", radiance, working_space,
                     hdr_attributes(view, method, extra), config_uri=config_uri,
                     extra_channels={CLIP_FLOOR_CHANNEL: floor,
                                     DARK_CEILING_CHANNEL: ceiling})


def hdr_view_paths(folder: Path) -> list[Path]:
    return [p for p in list_images(folder, IMAGE_EXTENSIONS) if p.suffix.lower() == ".exr"]
