"""``gaslight2usd info FILE...``: what an EXR, PLY or USD file holds."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import InputError
from ..inspect import describe, format_facts
from ._common import add_common, emit
from ._preview import add_preview, check_preview, write_preview_for

HELP = "print what an EXR/HDR image, 3DGS PLY or USD stage holds (--preview: a PNG)"
DESCRIPTION = """\
Print what a file holds: for images (EXR, HDR, JPEG, PNG, TIFF, and the .tx
textures 'hdri --tx' writes) the size, channels, colour space, value range,
dynamic range in stops and envmap (latlong or cube); a truncated or corrupt
image is an error (exit 3). For 3DGS PLYs the splat count, SH degree,
bounds and brightest colour; for USD stages the up axis, metersPerUnit, prims
by type, ParticleField splat counts and variant sets. --preview writes the
image(s) as a PNG through an OCIO display/view transform.

examples:
  gaslight2usd info out/hdr/view_00.exr
  gaslight2usd info out/splats.ply --json | jq .splats
  gaslight2usd info out/hdri/probe_000.exr --preview probe.png
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("info", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("files", nargs="+", metavar="FILE", help="EXR, HDR, PLY or USD files")
    add_preview(p, "the image(s)")
    add_common(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    check_preview(args)
    facts = [describe(f) for f in args.files]
    if args.preview is not None:
        not_images = [f["file"] for f in facts if f["type"] != "image"]
        if not_images:
            raise InputError("--preview draws images only (EXR, HDR, JPEG, PNG, TIFF, .tx)",
                             not_images[0])
        write_preview_for(args, [Path(f) for f in args.files], None)
    text = "\n\n".join(format_facts(f) for f in facts)
    if args.preview is not None:
        text += f"\n\npreview: {args.preview}"
    emit(args, facts if len(facts) > 1 else facts[0], text)
    return 0
