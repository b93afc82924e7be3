"""Find the project's data folders from an installed package or a checkout.

An installed package does not sit inside the checkout, so data such as the
bundled example (``examples/room``) and the shared HDR panoramas
(``../shared/data/hdri``) are looked up from an environment variable, then
from the working directory and its parents, then beside the source tree.
"""

from __future__ import annotations

import os
from pathlib import Path

_SOURCE_ROOT = Path(__file__).resolve().parents[1]


def find_data(relative: str, env: str | None = None) -> Path:
    """The first existing ``<base>/<relative>``; the last candidate if none exists."""
    if env and os.environ.get(env):
        return Path(os.environ[env])
    cwd = Path.cwd().resolve()
    candidates = [base / relative for base in (cwd, *cwd.parents, _SOURCE_ROOT,
                                               _SOURCE_ROOT.parent)]
    for path in candidates:
        if path.exists():
            return path
    return _SOURCE_ROOT / relative


def example_room() -> Path:
    """The bundled example scene (``$GASLIGHT_EXAMPLE`` overrides)."""
    return find_data("examples/room", "GASLIGHT_EXAMPLE")


def shared_hdri_dir() -> Path:
    """The shared CC0 panoramas (``$GASLIGHT_HDRI_DIR`` overrides)."""
    return find_data("shared/data/hdri", "GASLIGHT_HDRI_DIR")
