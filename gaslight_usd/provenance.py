"""Versions and provenance that every output and report carries."""

from __future__ import annotations

import platform
from functools import lru_cache
from importlib.metadata import PackageNotFoundError, version

DISTRIBUTIONS = ("gaslight-usd", "numpy", "torch", "usd-core", "OpenImageIO", "OpenEXR",
                 "opencolorio", "pycolmap", "plyfile", "trimesh", "mitsuba")


@lru_cache(maxsize=1)
def versions() -> dict[str, str]:
    found = {"python": platform.python_version()}
    for dist in DISTRIBUTIONS:
        try:
            found[dist] = version(dist)
        except PackageNotFoundError:
            continue
    return found


def tool_version() -> str:
    return versions().get("gaslight-usd", "unknown")
