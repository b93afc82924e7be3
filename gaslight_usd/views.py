"""Photo sets in and HDR view sets out: the ingest step every uplift shares.

A photo is decoded, its clipped pixels are found on the encoded values, and it
is linearised into the working space. Exposures from EXIF are normalised to
the set's median, so HDR values are *relative radiance*: 1.0 is the radiance
that reads as linear 1.0 at the reference exposure. That scale is recorded in
every output (``gaslight:exposure_scale`` and ``gaslight:reference_ev``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import colour
from .imageio import IMAGE_EXTENSIONS, LDR_EXTENSIONS, Image, list_images, read_image, write_exr

logger = logging.getLogger(__name__)

CLIP_LEVEL = 0.99
"""An encoded value at or above this (of full scale) counts as clipped."""

CLIP_FLOOR_CHANNEL = "clip_floor"
"""The HDR views' extra EXR channel: in pixels the photo clipped, the luminance the photo
recorded there (relative radiance, working space), a lower bound on the true luminance;
0 where the photo measured the pixel. The fit treats those pixels as bounds, not targets
(:mod:`gaslight_usd.fit.losses`)."""


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

    def clip_floor(self, weights: np.ndarray) -> np.ndarray:
        """``(H, W)``: the recorded luminance (``weights``: the working space's Y weights)
        where the photo clipped, 0 elsewhere; see :data:`CLIP_FLOOR_CHANNEL`."""
        recorded = np.maximum(self.relative_radiance, 0.0) @ weights.astype(np.float32)
        return np.where(self.clipped_mask, np.maximum(recorded, 1e-6), 0.0).astype(np.float32)


def load_views(paths: list[Path] | Path, input_space: str, working_space: str,
               config_uri: str | None = None) -> list[View]:
    """Read photos (a folder or a list), linearise them, normalise exposure."""
    if isinstance(paths, Path):
        paths = list_images(paths, LDR_EXTENSIONS)
    images: list[Image] = [read_image(p, colour_space=input_space, config_uri=config_uri)
                           for p in paths]
    evs = [im.exposure.ev if im.exposure.known else None for im in images]
    known = [e for e in evs if e is not None]
    warn_missing_exposure([im.path.name for im, ev in zip(images, evs, strict=True)
                           if ev is None], len(images))
    reference = float(np.median(known)) if known else 0.0
    views = []
    for im, ev in zip(images, evs, strict=True):
        linear = colour.convert(im.pixels, im.colour_space, working_space, config_uri)
        ratio = 2.0 ** (ev - reference) if ev is not None else 1.0
        views.append(View(name=im.path.stem, path=im.path, encoded=im.pixels, linear=linear,
                          exposure_ratio=ratio, ev=ev,
                          metadata={"reference_ev": reference, "source_space": im.colour_space}))
    return views


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
    attrs.update(extra or {})
    return attrs


def write_hdr_view(folder: Path, view: View, radiance: np.ndarray, working_space: str,
                   method: str, extra: dict[str, Any] | None = None,
                   config_uri: str | None = None, clipped_by: View | None = None) -> Path:
    """Write one HDR view as ``<folder>/<photo stem>.exr`` (atomic), with its clip floor.

    ``clipped_by``: the photo whose clipping bounds this radiance (default ``view``;
    for a merged bracket, its darkest frame: only what that frame clipped is unmeasured).
    """
    source = clipped_by or view
    floor = source.clip_floor(colour.luminance_weights(working_space, config_uri))
    if floor.shape != radiance.shape[:2]:
        floor = np.zeros(radiance.shape[:2], np.float32)
    return write_exr(folder / f"{view.name}.exr", radiance, working_space,
                     hdr_attributes(view, method, extra), config_uri=config_uri,
                     extra_channels={CLIP_FLOOR_CHANNEL: floor})


def hdr_view_paths(folder: Path) -> list[Path]:
    return [p for p in list_images(folder, IMAGE_EXTENSIONS) if p.suffix.lower() == ".exr"]
