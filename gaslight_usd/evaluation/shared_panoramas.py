"""The shared CC0 panoramas as calibration and benchmark data: which to trust, and why.

Two folders (see ``../shared/data/README.md``): ``hdri`` (eight 1024 x 512
panoramas from Blender's studio lights) and ``hdri-polyhaven-512`` (seventeen
512 x 256 Poly Haven panoramas). Their flaws are written down here, once, as
data: a clamped panorama's brightest pixels are not the truth (a crop that
holds one has ``light_truth = False``: benches leave it out of their means,
calibration leaves it out or down-weights it), and a panorama with no real
light source in view only teaches the predictor what "just clipped" looks
like. Names of the second folder get the prefix ``ph-`` (both folders hold a
``city``, ``forest``, ``night``, ``studio`` and ``sunset``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..locate import find_data, shared_hdri_dir
from .reference import HDRSource, load_source

CLAMPED = "clamped"
"""Kind: the file's brightest pixels were clamped (crops holding them are untrusted)."""
NO_LIGHT = "no-light"
"""Kind: no real light source in view (peak a few times the median)."""
TRUSTED = "trusted"
"""Kind: unclipped, with a light source."""


@dataclass(frozen=True)
class SharedPanorama:
    """One shared panorama: where it lives, how far its truth goes, and why."""

    folder: str
    """``hdri`` or ``hdri-polyhaven-512`` (a folder of ``shared/data``)"""
    stem: str
    kind: str
    """:data:`TRUSTED`, :data:`CLAMPED` or :data:`NO_LIGHT`"""
    reason: str
    clamp_level: float | None = None
    """Pixels at or above half this level are untrusted (:class:`.reference.HDRSource`)."""

    @property
    def name(self) -> str:
        """Unique name: the stem, prefixed ``ph-`` in the Poly Haven folder."""
        return self.stem if self.folder == HDRI else f"ph-{self.stem}"


HDRI = "hdri"
POLYHAVEN = "hdri-polyhaven-512"
FOLDERS = (HDRI, POLYHAVEN)

PANORAMAS: tuple[SharedPanorama, ...] = (
    SharedPanorama(HDRI, "city", CLAMPED, "sun core clamped at 32000 (a handful of pixels)",
                   32000.0),
    SharedPanorama(HDRI, "courtyard", TRUSTED, "unclipped"),
    SharedPanorama(HDRI, "forest", TRUSTED, "unclipped (scaled by 0.7)"),
    SharedPanorama(HDRI, "interior", CLAMPED, "sun core clamped at 32000", 32000.0),
    SharedPanorama(HDRI, "night", TRUSTED, "unclipped"),
    SharedPanorama(HDRI, "studio", CLAMPED, "lamps clamped flat at 100", 100.0),
    SharedPanorama(HDRI, "sunrise", CLAMPED, "sun core clamped at 32000", 32000.0),
    SharedPanorama(HDRI, "sunset", TRUSTED, "unclipped"),
    SharedPanorama(POLYHAVEN, "apartment", NO_LIGHT, "peak 21, no light source in view"),
    SharedPanorama(POLYHAVEN, "bridge", CLAMPED, "sun clamped: flat top near 105", 105.0),
    SharedPanorama(POLYHAVEN, "city", NO_LIGHT, "peak 11, no light source in view"),
    SharedPanorama(POLYHAVEN, "dawn", TRUSTED, "unclipped"),
    SharedPanorama(POLYHAVEN, "esplanade", TRUSTED, "unclipped"),
    SharedPanorama(POLYHAVEN, "forest", TRUSTED, "unclipped"),
    SharedPanorama(POLYHAVEN, "hall", TRUSTED, "unclipped"),
    SharedPanorama(POLYHAVEN, "lab", CLAMPED, "7 px at the maximum: possibly clamped at 56",
                   56.0),
    SharedPanorama(POLYHAVEN, "lobby", TRUSTED, "unclipped"),
    SharedPanorama(POLYHAVEN, "night", TRUSTED, "unclipped"),
    SharedPanorama(POLYHAVEN, "park", TRUSTED, "unclipped"),
    SharedPanorama(POLYHAVEN, "sky", TRUSTED, "unclipped"),
    SharedPanorama(POLYHAVEN, "studio", TRUSTED, "unclipped"),
    SharedPanorama(POLYHAVEN, "sunset", TRUSTED, "unclipped"),
    SharedPanorama(POLYHAVEN, "venice", NO_LIGHT, "peak 9, no light source in view"),
    SharedPanorama(POLYHAVEN, "warehouse", CLAMPED,
                   "7 px at the maximum: possibly clamped at 214", 214.0),
    SharedPanorama(POLYHAVEN, "workshop", TRUSTED, "unclipped"),
)
"""Every shared panorama, by folder then name (the ``README.md`` tables)."""

BY_NAME = {p.name: p for p in PANORAMAS}


def folder_path(folder: str) -> Path:
    """Where a shared folder is (``$GASLIGHT_HDRI_DIR`` moves ``hdri``; the other is its
    sibling)."""
    if folder == HDRI:
        return shared_hdri_dir()
    sibling = shared_hdri_dir().parent / folder
    return sibling if sibling.exists() else find_data(f"shared/data/{folder}")


def folder_of(name: str) -> str:
    """The folder of a panorama named as :attr:`SharedPanorama.name` (``?`` if unknown)."""
    entry = BY_NAME.get(name)
    return entry.folder if entry else "?"


def load_shared(names: list[str] | None = None, folders: tuple[str, ...] = FOLDERS
                ) -> list[HDRSource]:
    """The shared panoramas present on disk (``names`` to pick), named and clamp-tagged
    as :data:`PANORAMAS` says, in table order; then any other EXR / HDR file of the
    ``hdri`` folder (``$GASLIGHT_HDRI_DIR`` may point at the user's own), by stem."""
    out = []
    for entry in PANORAMAS:
        if entry.folder not in folders or (names is not None and entry.name not in names):
            continue
        path = folder_path(entry.folder) / f"{entry.stem}.exr"
        if not path.exists():
            continue
        source = load_source(path, clamp_level=entry.clamp_level, panorama=True)
        source.name = entry.name
        out.append(source)
    listed = {p.stem for p in PANORAMAS if p.folder == HDRI}
    hdri = folder_path(HDRI)
    if HDRI in folders and hdri.is_dir():
        extra = sorted(p for p in hdri.iterdir() if p.suffix.lower() in (".exr", ".hdr")
                       and p.stem not in listed and (names is None or p.stem in names))
        out += [load_source(p) for p in extra]
    return out
