"""gaslight2usd: a set's real light, from a handful of LDR photos, as assets.

Public API (see the README for a tour)::

    from gaslight_usd import ChainRun, Kind, Artifact, Settings
    from gaslight_usd import read_image, write_exr, read_ply, write_ply, SplatScene

The names are resolved on first use (PEP 562), so importing one submodule
(``gaslight_usd.ply``, say) does not pull in OCIO, USD or OpenImageIO through
this package's ``__init__``; a command-line run starts faster for it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

_EXPORTS = {
    "chain": ("ChainRun", "plan"),
    "errors": ("GaslightError", "InputError", "NotBuiltYet"),
    "imageio": ("Image", "read_image", "write_exr"),
    "kinds": ("Artifact", "Kind", "detect_kind"),
    "ply": ("read_ply", "write_ply"),
    "registry": ("Converter", "Registry", "Settings", "StageContext", "StageResult",
                 "default_registry"),
    "splats": ("SplatScene",),
}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = [
    "Artifact", "ChainRun", "Converter", "GaslightError", "Image", "InputError", "Kind",
    "NotBuiltYet", "Registry", "Settings", "SplatScene", "StageContext", "StageResult",
    "default_registry", "detect_kind", "plan", "read_image", "read_ply", "write_exr",
    "write_ply",
]
assert sorted(__all__) == sorted(_WHERE)


def __getattr__(name: str) -> Any:
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'gaslight_usd' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:  # for type checkers and IDEs: the same names, imported eagerly
    from .chain import ChainRun, plan
    from .errors import GaslightError, InputError, NotBuiltYet
    from .imageio import Image, read_image, write_exr
    from .kinds import Artifact, Kind, detect_kind
    from .ply import read_ply, write_ply
    from .registry import (
        Converter,
        Registry,
        Settings,
        StageContext,
        StageResult,
        default_registry,
    )
    from .splats import SplatScene
