"""Subcommands the project has not built yet: they say so and exit 2."""

from __future__ import annotations

import argparse

from ..errors import NotBuiltYet
from ._common import add_common

PENDING = {
    "poses": "camera poses by structure from motion (pycolmap) or imported",
    "fit": "fit HDR Gaussian splats to posed HDR views",
    "export": "export splats as OpenUSD (ParticleField, instancer, UsdLux rig)",
    "hdri": "render lat-long / cube-map EXR HDRIs from splats at any point",
    "bench": "measure time and accuracy of methods; Pareto chart",
}


def register_pending(sub: argparse._SubParsersAction, name: str) -> None:
    what = PENDING.get(name, name)
    p = sub.add_parser(name, help=f"{what} (not built yet)",
                       description=f"{what}.\n\nNot built yet: exits with status 2.")
    p.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    add_common(p)
    p.set_defaults(handler=lambda args: _not_built(name))


def _not_built(name: str) -> int:
    raise NotBuiltYet(f"'gaslight2usd {name}' is not built yet ({PENDING.get(name, name)})")
