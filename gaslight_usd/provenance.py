"""Versions and provenance that every output and report carries."""

from __future__ import annotations

import os
import platform
import re
import sys
from functools import lru_cache

DISTRIBUTIONS = ("gaslight-usd", "numpy", "torch", "usd-core", "OpenImageIO", "OpenEXR",
                 "opencolorio", "pycolmap", "plyfile", "trimesh", "mitsuba")


def _normalise(name: str) -> str:
    return re.sub(r"[-_.]+", "_", name).lower()


@lru_cache(maxsize=1)
def _installed() -> dict[str, str]:
    """Installed distributions -> version, from the ``*.dist-info`` folder names.

    A directory listing per ``sys.path`` entry instead of ``importlib.metadata``
    (whose import and look-ups cost a command-line run about 0.15 s); the first
    entry of a name wins, as for imports.
    """
    found: dict[str, str] = {}
    for entry in sys.path:
        try:
            names = os.listdir(entry or ".")
        except OSError:
            continue
        for folder in names:
            if folder.endswith(".dist-info"):
                name, _, ver = folder[: -len(".dist-info")].partition("-")
                found.setdefault(_normalise(name), ver)
    return found


def distribution_version(name: str) -> str | None:
    """Installed version of distribution ``name``, or None."""
    ver = _installed().get(_normalise(name))
    if ver is None:  # an unusual install (an egg, a zip): ask the slow, thorough way
        from importlib.metadata import PackageNotFoundError, version
        try:
            ver = version(name)
        except PackageNotFoundError:
            return None
    return ver


@lru_cache(maxsize=1)
def versions() -> dict[str, str]:
    found = {"python": platform.python_version()}
    for dist in DISTRIBUTIONS:
        ver = distribution_version(dist)
        if ver is not None:
            found[dist] = ver
    return found


def tool_version() -> str:
    return versions().get("gaslight-usd", "unknown")
