"""Options and output helpers shared by every subcommand."""

from __future__ import annotations

import argparse
import json
from typing import Any

from ..progress import Progress
from ..registry import Settings


def add_common(parser: argparse.ArgumentParser, colour: bool = False,
               photos: bool = True) -> None:
    """--json/-v/-q; with ``colour`` the OCIO options (--input-space only for
    commands that read photos: ``photos``)."""
    g = parser.add_argument_group("common options")
    g.add_argument("--json", action="store_true",
                   help="print the result as JSON on stdout (progress stays on stderr)")
    g.add_argument("-v", "--verbose", action="store_true",
                   help="more detail; show tracebacks of internal errors")
    g.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    if colour:
        c = parser.add_argument_group("colour (OpenColorIO)")
        c.add_argument("--ocio-config", metavar="URI",
                       help="OCIO config file or URI (default: $OCIO, else "
                            "ocio://cg-config-latest)")
        if photos:
            c.add_argument("--input-space", metavar="NAME",
                           help="colour space of the photos (default: "
                                "'sRGB Encoded Rec.709 (sRGB)')")
        c.add_argument("--working-space", metavar="NAME",
                       help="scene-linear working and output space (default: ACEScg)")


def settings_from(args: argparse.Namespace, **kw: Any) -> Settings:
    return Settings.resolved(
        ocio_config=getattr(args, "ocio_config", None),
        input_space=getattr(args, "input_space", None),
        working_space=getattr(args, "working_space", None),
        **kw,
    )


def progress_from(args: argparse.Namespace) -> Progress:
    return Progress(quiet=bool(getattr(args, "quiet", False)))


def emit(args: argparse.Namespace, data: Any, text: str) -> None:
    """Print ``data`` as JSON with --json, else ``text`` (unless quiet and empty)."""
    if getattr(args, "json", False):
        print(json.dumps(data, indent=2, default=str))
    elif text:
        print(text)
