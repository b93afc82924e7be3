"""gaslight2usd: a set's real light, from a handful of LDR photos, as assets.

Public API (see the README for a tour)::

    from gaslight_usd import ChainRun, Kind, Artifact, Settings
    from gaslight_usd import read_image, write_exr, read_ply, write_ply, SplatScene
"""

from .chain import ChainRun, Settings, StageContext, StageResult, plan
from .errors import GaslightError, InputError, NotBuiltYet
from .imageio import Image, read_image, write_exr
from .kinds import Artifact, Kind, detect_kind
from .ply import read_ply, write_ply
from .registry import Converter, Registry, default_registry
from .splats import SplatScene

__all__ = [
    "Artifact", "ChainRun", "Converter", "GaslightError", "Image", "InputError", "Kind",
    "NotBuiltYet", "Registry", "Settings", "SplatScene", "StageContext", "StageResult",
    "default_registry", "detect_kind", "plan", "read_image", "read_ply", "write_exr",
    "write_ply",
]
