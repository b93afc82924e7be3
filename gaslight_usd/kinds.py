"""The data kinds of the chain and their on-disk forms.

Every stage's output is an ordinary file or folder that other tools read, so a
chain can start or stop at any stage. :func:`detect_kind` tells what a path
holds from its form alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any

from .errors import InputError
from .poses.colmap import find_colmap_model


class Kind(StrEnum):
    LDR_VIEWS = "ldr-views"
    HDR_VIEWS = "hdr-views"
    POSES = "poses"
    SPLATS = "splats"
    USD = "usd"
    HDRI = "hdri"

    @property
    def on_disk(self) -> str:
        return ON_DISK[self]

    @property
    def default_name(self) -> str:
        """Where a chain run puts this kind inside its output folder."""
        return DEFAULT_NAMES[self]


ON_DISK = {
    Kind.LDR_VIEWS: "folder of JPEG/PNG/TIFF photos (EXIF exposure when present)",
    Kind.HDR_VIEWS: "folder of scene-linear EXR views, one per photo",
    Kind.POSES: "COLMAP model folder (cameras, images, points3D; text or binary) "
                "or a transforms.json",
    Kind.SPLATS: "3DGS PLY (linear HDR colours)",
    Kind.USD: "OpenUSD stage (.usda/.usdc/.usdz)",
    Kind.HDRI: "folder of EXR environment maps (lat-long and/or cube)",
}

DEFAULT_NAMES = {
    Kind.LDR_VIEWS: "photos",
    Kind.HDR_VIEWS: "hdr",
    Kind.POSES: "sparse",
    Kind.SPLATS: "splats.ply",
    Kind.USD: "scene.usda",
    Kind.HDRI: "hdri",
}

USD_EXTENSIONS = (".usd", ".usda", ".usdc", ".usdz")
LDR_EXTENSIONS = (".jpg", ".jpeg", ".png", ".tif", ".tiff")
HDR_EXTENSIONS = (".exr", ".hdr")
IMAGE_EXTENSIONS = LDR_EXTENSIONS + HDR_EXTENSIONS


@dataclass
class Artifact:
    """A path holding one kind of data, plus what is known about it."""

    kind: Kind
    path: Path
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # Pipeline code passes plain strings as often as Paths (the README does).
        self.path = Path(self.path)
        self.kind = Kind(self.kind)


def detect_kind(path: str | Path) -> Kind:
    """What ``path`` holds, judged from its form. Raises InputError if unknown."""
    path = Path(path)
    if not path.exists():
        raise InputError("no such file or folder", path)
    suffix = path.suffix.lower()
    if path.is_file():
        if suffix == ".ply":
            return Kind.SPLATS
        if suffix in USD_EXTENSIONS:
            return Kind.USD
        if path.name == "transforms.json":
            return Kind.POSES
        if suffix in HDR_EXTENSIONS:
            return Kind.HDRI
        raise InputError("cannot tell what this file holds (expected .ply, .usd*, .exr, "
                         "transforms.json or a folder of photos)", path)
    if find_colmap_model(path) is not None or (path / "transforms.json").exists():
        return Kind.POSES
    files = [p for p in path.iterdir() if p.is_file() and not p.name.startswith(".")]
    ldr = [p for p in files if p.suffix.lower() in LDR_EXTENSIONS]
    hdr = [p for p in files if p.suffix.lower() in HDR_EXTENSIONS]
    if not ldr and not hdr:
        raise InputError("folder holds no photos, EXR views or COLMAP model", path)
    return Kind.HDR_VIEWS if len(hdr) >= len(ldr) else Kind.LDR_VIEWS
