"""The options of the two export steps, ``export`` (OpenUSD) and ``hdri`` (EXR HDRIs).

One typed dataclass per step, and the defaults in one place: the CLI reads them
from here, the converters build these dataclasses from a step's options
(:func:`gaslight_usd.registry.options_from`), and the USD writer and the HDRI
renderer default to the same constants. This module imports nothing heavy (no
USD, no renderer), so argument parsing stays fast.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

PALETTE_TOLERANCE = 0.10
"""95th-percentile relative colour error allowed for the instancer's palette."""
RIG_TOLERANCE = 0.05
"""Irradiance error at the probe allowed for the light rig, relative to its largest."""
DOME_WIDTH = 1024
"""Width (pixels) of the rig's dome lat-long."""
HDRI_WIDTH = 2048
"""Width (pixels) of a rendered lat-long HDRI (height half, cube faces a quarter)."""


@dataclass
class UsdExportOptions:
    """The ``export`` step: which USD forms, and how each is made."""

    forms: list[str] | None = field(default=None, metadata={"key": "as"})
    """particlefield, instancer, rig (None: all three); the options key is ``as``."""
    half: bool = False
    """Half-precision ParticleField attributes (positions stay float)."""
    usdz: bool = False
    """Also package everything as ``<stem>.usdz``."""
    emit_threshold: float | None = None
    """A splat emits when its base colour's max channel is above this; None: the
    splats of the set's lights."""
    palette_tolerance: float = PALETTE_TOLERANCE
    non_emitters: str = "drop"
    """What the instancer does with splats below the threshold: drop | diffuse."""
    rig_tolerance: float = RIG_TOLERANCE
    at: Any = None
    """The rig's probe point (x, y, z); None: :func:`gaslight_usd.probe.default_probe`."""
    dome_width: int = DOME_WIDTH
    max_layer_bytes: int | None = None
    """Split ParticleField layers above this size (None: the writer's 3 GiB)."""
    display_ply: Any = None
    """Also write a display-referred PLY here."""
    display_exposure: float | None = None
    """Its exposure in EV (None: automatic)."""
    default_variant: str | None = None
    """The ``lighting`` variant the root layer selects (None: rig when written)."""


@dataclass
class HdriOptions:
    """The ``hdri`` step: where probes are rendered and what is written for each."""

    at: Any = None
    """One (x, y, z) or a list of them; None: the default probe inside the set."""
    size: int = HDRI_WIDTH
    """Lat-long width in pixels."""
    cube: bool = False
    faces: bool = False
    tx: bool = False
    output_space: str | None = None
    """OCIO colour space of the files (None: the working space)."""
    paths: list[Any] | None = None
    """The lat-long file of each probe (None: numbered beside the output)."""
    device: str | None = None
    """Where to render (None: the run's device)."""
