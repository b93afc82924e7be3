"""USDZ packaging: every layer and texture a root layer uses, in one archive.

``UsdUtils.CreateNewUsdzPackage`` gathers the root layer's dependencies,
stores them uncompressed and 64-byte aligned, and fails when a referenced
asset is missing. USDZ has no ZIP64: no single file may reach 4 GiB, which
the particle-field layer splitting (``particlefield.MAX_LAYER_BYTES``) keeps.
"""

from __future__ import annotations

from pathlib import Path

from pxr import Sdf, UsdUtils

from ..atomic import atomic_path
from ..errors import GaslightError
from .validate import Finding, validate

ZIP_LIMIT = 2**32 - 1


def package_usdz(root_layer: str | Path, usdz_path: str | Path) -> Path:
    """Package ``root_layer`` and its dependencies as ``usdz_path`` (atomically)."""
    root_layer, usdz_path = Path(root_layer), Path(usdz_path)
    with atomic_path(usdz_path) as tmp:
        ok = UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(root_layer)), str(tmp))
        if not ok or not tmp.exists():
            raise GaslightError("USDZ packaging failed (a referenced asset is missing?)",
                                usdz_path)
        if tmp.stat().st_size >= ZIP_LIMIT:
            raise GaslightError("USDZ archive reached 4 GiB (no ZIP64 in USDZ)", usdz_path)
    return usdz_path


def validate_usdz(usdz_path: str | Path) -> list[Finding]:
    """Findings of the USDZ validators plus every other registered validator."""
    return validate(usdz_path)
