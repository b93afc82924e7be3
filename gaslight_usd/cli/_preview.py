"""The ``--preview PNG`` option that ``info`` and ``hdri`` share."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_preview(parser: argparse.ArgumentParser, what: str) -> None:
    g = parser.add_argument_group("preview (a PNG to look at)")
    g.add_argument("--preview", type=Path, metavar="PNG",
                   help=f"also write {what} as an 8-bit PNG through an OCIO display/view "
                        "transform (several images: a contact sheet)")
    g.add_argument("--display", metavar="NAME",
                   help="OCIO display of the preview (default: the config's, "
                        "'sRGB - Display' in the built-in config)")
    g.add_argument("--view", metavar="NAME",
                   help="OCIO view of the preview (default: the display's default, "
                        "'ACES 2.0 - SDR 100 nits (Rec.709)' in the built-in config)")


def check_preview(args: argparse.Namespace) -> None:
    """Before any work: a .png name in a writable place, a known display and view."""
    if args.preview is None:
        return
    from ..errors import InputError
    from ..outputs import check_output

    if args.preview.suffix.lower() != ".png":
        raise InputError("--preview takes a .png file name", args.preview)
    check_output(args.preview, folder=False)
    from ..colour import resolve_config_uri
    from ..preview import DisplayView

    DisplayView(args.display, args.view).resolved(
        resolve_config_uri(getattr(args, "ocio_config", None)))


def write_preview_for(args: argparse.Namespace, images: list[Path], working_space: str | None,
                      input_space: str | None = None) -> Path | None:
    if args.preview is None:
        return None
    from ..colour import DEFAULT_INPUT_SPACE, DEFAULT_WORKING_SPACE, resolve_config_uri
    from ..preview import DisplayView, write_preview

    return write_preview(args.preview, images,
                         resolve_config_uri(getattr(args, "ocio_config", None)),
                         working_space or DEFAULT_WORKING_SPACE,
                         input_space or DEFAULT_INPUT_SPACE,
                         DisplayView(args.display, args.view))
