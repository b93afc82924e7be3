"""``gaslight2usd hdri SPLATS --at X,Y,Z -o probe.exr``: HDRIs rendered from splats."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..chain import ChainRun
from ..errors import InputError
from ..export_options import HdriOptions
from ..kinds import Artifact, Kind
from ..outputs import check_output
from ..registry import default_registry
from ._common import add_common, emit, progress_from, settings_from
from ._points import parse_point
from ._preview import add_preview, check_preview, write_preview_for

HELP = "render lat-long / cube-map EXR HDRIs from the splats at probe points"
DESCRIPTION = """\
Render the splats' light as seen from one or more points and write EXRs.

conventions (also written in every EXR header):
  lat-long  OpenEXR envmap=latlong: the image centre looks along +Z, a quarter
            width from the left along +X, the top row is +Y; width = 2 x height
  cube      OpenEXR envmap=cube: six square faces stacked vertically in the
            order +X, -X, +Y, -Y, +Z, -Z (OpenEXR face orientation); --faces
            also writes them as NAME.px.exr, .nx, .py, .ny, .pz, .nz
  frame     positions (--at) and directions are in the world frame of the
            splats: the poses the user gave, or the frame the project chose and
            recorded when poses came from SfM (+Y up, origin at the scene centre)
  radiance  scene-linear and unclamped (float EXR when above the half range),
            in --output-space (an OCIO name; default the working space, ACEScg)

outputs: with one --at, -o NAME.exr is the lat-long; NAME.cube.exr the cube
map; NAME.tx the tiled mip-mapped texture (OpenImageIO maketx). With several
--at, NAME.000.exr, NAME.001.exr... in the order given.

warnings (printed, and in report.json beside the EXRs): a point far outside the
splats, within 1.5 radii of a light, or seeing a light from more than 30 degrees
off every photo that saw it (its power there is the fit's guess; report.json
gives the angle per probe and light, lights_unseen_deg)

examples:
  gaslight2usd hdri out/splats.ply --at 0,1.5,0 -o out/probe.exr --cube
  gaslight2usd hdri out/splats.ply --at 0,1,0 --at 2,1,0 -o probes/p.exr --size 1024
  gaslight2usd hdri out/splats.ply --at -1.2,1.35,-0.58 -o probe.exr --preview probe.png
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("hdri", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("splats", type=Path, help="3DGS PLY (linear HDR colours)")
    p.add_argument("--at", type=parse_point, action="append", metavar="X,Y,Z",
                   help="probe point in the splats' world frame (repeat for several; "
                        "default: where the cameras stood, at their median height, moved "
                        "to free space)")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="PROBE.exr",
                   help="lat-long EXR to write (numbered when several --at)")
    p.add_argument("--size", type=int, default=HdriOptions.size, metavar="N",
                   help="lat-long width in pixels (height N/2; cube faces N/4); "
                        f"default {HdriOptions.size}")
    p.add_argument("--cube", action="store_true", help="also write the cube map")
    p.add_argument("--faces", action="store_true", help="also write six face files")
    p.add_argument("--tx", action="store_true",
                   help="also write a tiled mip-mapped lat-long .tx (maketx)")
    p.add_argument("--output-space", metavar="NAME",
                   help="OCIO colour space of the files (default: the working space)")
    p.add_argument("--device", default="cpu", metavar="cpu|cuda[:N]",
                   help="where the panoramas are rendered: cpu (default) or cuda")
    add_preview(p, "the lat-long HDRI(s)")
    add_common(p, colour=True, photos=False)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from ..devices import resolve_device

    resolve_device(args.device)
    if not args.splats.is_file():
        raise InputError("no such file", args.splats)
    if args.size < 8 or args.size % 2:
        raise InputError(f"--size must be an even number >= 8, got {args.size}")
    if args.output.suffix.lower() != ".exr":
        raise InputError("the output must be an .exr file name", args.output)
    check_output(args.output, folder=False)
    check_preview(args)
    settings = settings_from(args, device=args.device)
    options = {"at": args.at, "size": args.size, "cube": args.cube, "faces": args.faces,
               "tx": args.tx, "output_space": args.output_space}
    # Through the registry like every stage: report.json beside the EXRs, and a plug-in
    # HDRI converter of higher priority is honoured.
    folder = args.output.parent
    runner = ChainRun(folder if str(folder) else Path("."), settings, default_registry(),
                      progress_from(args))
    runner.run([Artifact(Kind.SPLATS, args.splats)], [Kind.HDRI],
               options={"hdri": options}, outputs={Kind.HDRI: args.output}, resume=False)
    result = runner.records[-1]
    probes = result.metadata["probes"]
    text = "\n".join(f"probe at {tuple(p['position'])} ({p['chosen']}): "
                     + ", ".join(p["files"]) for p in probes)
    preview = write_preview_for(args, [Path(p["files"][0]) for p in probes],
                                settings.working_space)
    if preview is not None:
        result.metadata["preview"] = str(preview)
        text += f"\npreview: {preview}"
    emit(args, {**result.counts, **result.metadata}, text)  # the probe list, not its count
    return 0
