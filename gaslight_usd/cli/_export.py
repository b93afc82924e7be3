"""``gaslight2usd export SPLATS.ply -o scene.usda``: splats to OpenUSD (and PLY)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..chain import ChainRun
from ..errors import InputError
from ..export_options import UsdExportOptions as D
from ..kinds import Artifact, Kind
from ..outputs import check_output
from ..registry import default_registry
from ._common import add_common, emit, progress_from, settings_from
from ._points import parse_point

HELP = "write the splats as OpenUSD: ParticleField, emissive instancer, UsdLux rig"
FORMS = ("particlefield", "instancer", "rig")
USD_ROOT_SUFFIXES = (".usda", ".usd", ".usdc")
DESCRIPTION = """\
Write a 3DGS PLY (ours or any other tool's) as OpenUSD. The root layer
(scene.usda) has a variant set 'lighting' on its default prim /Scene with one
variant per form, each referencing .usdc layers written beside it:

  particlefield  UsdVol.ParticleField3DGaussianSplat (linear scales, opacities
                 0..1, SH in the schema's per-particle layout; --half for the
                 half-precision attributes); split over several layers above
                 3 GiB so no file reaches USDZ's 4 GiB limit
  instancer      a PointInstancer of emissive icosphere prototypes for the splats
                 of the set's lights (or, with --emit-threshold R, every splat whose
                 radiance, the max channel of its base colour, is above R);
                 colours share a palette as small as keeps the 95th percentile
                 relative colour error <= --palette-tolerance
  rig            a DomeLight (lat-long EXR of the other splats at --at) plus one
                 light per light of the set: a RectLight in its wall or ceiling
                 for a window or panel there, else a SphereLight; powers
                 measured at that point
                 (the error against --rig-tolerance is reported)

Lights: clusters of splats brighter than the photos' white that no diffuse
surface lit by the rest of the scene could explain (radiance above 0.9 x the
irradiance reaching them / pi); splats outside the captured space never are.
Each light (position, size, power, colour, where its power came from) is listed
in the output and in scene.usda's customLayerData (gaslight:lights).
The root layer selects the rig variant unless --default-variant says otherwise.

Stage metadata: upAxis and metersPerUnit from the PLY's metadata (defaults Y
and 1.0, stated in customLayerData when assumed); colour space via
ColorSpaceAPI (lin_ap1_scene for ACEScg); provenance via GaslightProvenanceAPI.
Every layer is checked with UsdValidation; errors fail the command.

examples:
  gaslight2usd export out/splats.ply -o out/usd/scene.usda
  gaslight2usd export other_tool.ply -o scene.usda --as particlefield --half --usdz
"""


def _forms(text: str) -> tuple[str, ...]:
    forms = tuple(f.strip() for f in text.split(",") if f.strip())
    bad = [f for f in forms if f not in FORMS]
    if bad or not forms:
        raise argparse.ArgumentTypeError(f"choose from {', '.join(FORMS)} (got {text!r})")
    return forms


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("export", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("splats", type=Path, help="3DGS PLY (linear HDR colours)")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="SCENE.usda",
                   help="root layer to write (.usda/.usd); layers go beside it")
    p.add_argument("--as", dest="forms", type=_forms, default=FORMS,
                   metavar="FORMS", help="comma-separated: particlefield,instancer,rig "
                   "(default: all three)")
    p.add_argument("--half", action="store_true",
                   help="half-precision ParticleField attributes (positions stay float)")
    p.add_argument("--usdz", action="store_true",
                   help="also package everything as SCENE.usdz (validated)")
    p.add_argument("--emit-threshold", type=float, metavar="R",
                   help="a splat emits when the max channel of its base colour > R (the "
                        "GaSLight rule; default: the splats of the set's lights, those no "
                        "diffuse surface lit by the scene could explain)")
    p.add_argument("--default-variant", choices=FORMS, metavar="FORM",
                   help="the 'lighting' variant scene.usda selects (default: rig, which "
                        "Blender, usdview and Karma all import; Blender drops "
                        "particlefield)")
    p.add_argument("--palette-tolerance", type=float, default=D.palette_tolerance,
                   metavar="REL", help="95th-percentile relative colour error allowed for "
                   f"the instancer palette (default {D.palette_tolerance:.2f})")
    p.add_argument("--non-emitters", choices=["drop", "diffuse"], default=D.non_emitters,
                   help="what the instancer does with splats below the threshold")
    p.add_argument("--rig-tolerance", type=float, default=D.rig_tolerance, metavar="REL",
                   help="irradiance error at the probe allowed for the rig, relative "
                        f"to its largest irradiance (default {D.rig_tolerance})")
    p.add_argument("--at", type=parse_point, metavar="X,Y,Z",
                   help="rig probe point (default: where the cameras stood, at their "
                        "median height, moved to free space; a PLY without camera "
                        "centres: the opaque splats' median)")
    p.add_argument("--dome-size", type=int, default=D.dome_width, metavar="N",
                   help=f"dome lat-long width in pixels (default {D.dome_width})")
    p.add_argument("--display-ply", type=Path, metavar="PATH",
                   help="also write a display-referred (tone-mapped) PLY for viewers "
                        "that clip HDR; its exposure is in the header comments")
    add_common(p, colour=True, photos=False)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    if not args.splats.is_file():
        raise InputError("no such file", args.splats)
    check_output(args.output, folder=args.output.suffix.lower() not in USD_ROOT_SUFFIXES)
    if args.display_ply is not None:
        check_output(args.display_ply, folder=False)
    settings = settings_from(args)
    options = {"as": list(args.forms), "half": args.half, "usdz": args.usdz,
               "emit_threshold": args.emit_threshold,
               "palette_tolerance": args.palette_tolerance,
               "non_emitters": args.non_emitters, "rig_tolerance": args.rig_tolerance,
               "at": args.at, "dome_width": args.dome_size,
               "display_ply": args.display_ply, "default_variant": args.default_variant}
    # Through the registry like every stage: report.json beside the root layer, and a
    # plug-in export converter of higher priority is honoured.
    root = args.output
    if root.suffix.lower() not in USD_ROOT_SUFFIXES:  # a folder: the root layer goes in it
        root = root / Kind.USD.default_name
    folder = root.parent
    runner = ChainRun(folder if str(folder) else Path("."), settings, default_registry(),
                      progress_from(args))
    runner.run([Artifact(Kind.SPLATS, args.splats)], [Kind.USD],
               options={"export": options}, outputs={Kind.USD: root}, resume=False)
    result = runner.records[-1]
    lines = [f"wrote {args.output} ({', '.join(args.forms)})"]
    m = result.metrics
    if "instancer" in m:
        i = m["instancer"]
        lines.append(f"  instancer: {i['emitters']} emitters, palette {i['palette_size']}, "
                     f"p95 colour error {i.get('relative_error_p95', 0):.3f}")
    for light in m.get("lights", {}).get("lights", []):
        lines.append("  light at " + ", ".join(f"{v:.3g}" for v in light["position"])
                     + f": radius {light['radius']:.3g}, power "
                     + ", ".join(f"{v:.3g}" for v in light["power"])
                     + f" ({light['power_source']})")
    if "instancer" in m and m["instancer"].get("warning"):
        lines.append(f"  warning: {m['instancer']['warning']}")
    if "rig" in m:
        r = m["rig"]
        lines.append(f"  rig: {r['lights']} sphere lights + dome, irradiance error "
                     f"{r['irradiance_error']:.3f} (tolerance {r['tolerance']})")
    emit(args, {**result.metadata, **result.counts, "metrics": result.metrics},
         "\n".join(lines))
    return 0
