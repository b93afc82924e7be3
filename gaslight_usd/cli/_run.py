"""``gaslight2usd run INPUT... -o OUT``: the whole chain, resumable."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..errors import InputError, NotBuiltYet
from ..kinds import Kind, detect_kind
from ..pipeline import DEFAULT_TARGETS, Job, run_job, step_options
from ..registry import default_registry
from ._common import add_common, emit, progress_from
from ._export import _forms
from ._fit import PLANE_MODES
from ._points import parse_point, positive_int

HELP = "the whole chain: photos -> HDR views -> poses -> splats -> USD/EXR/PLY"
DESCRIPTION = """\
Run the whole chain into one folder, resumable. INPUT is any stage's files, so a
run can start anywhere: a folder of photos, an EXR folder of HDR views, a COLMAP
model or transforms.json (poses), or a 3DGS PLY. What is missing is made; what
you give is used as is.

Photos are uplifted at the size the fit works at (the preset's working size,
at least 512 pixels on the long side), so a 12 MP photo costs what a small one
does; --keep-hdr full keeps full-resolution HDR views in OUT/hdr instead (the
fit still shrinks them as it reads them).

OUT holds: hdr/ (one EXR per photo), sparse/ (COLMAP model + frame.json),
splats.ply, scene.usda (+ .usdc layers), hdri/ (lat-long EXRs; with --cube also
cube maps), contact-sheet.png (the inputs, HDR views and HDRIs to look at) and
report.json (stages, seconds, counts, metrics, versions). Re-running the same
command skips the stages that finished with the same inputs and options.

examples:
  gaslight2usd run examples/room/photos -o out
  gaslight2usd run photos -o out --camera-height 1.6
  gaslight2usd run examples/room/photos --poses examples/room/sparse -o out --preset balanced
  gaslight2usd run splats.ply -o out --to usd,hdri --at 0,1.5,0
"""

KIND_NAMES = {"hdr": Kind.HDR_VIEWS, "poses": Kind.POSES, "splats": Kind.SPLATS,
              "usd": Kind.USD, "hdri": Kind.HDRI}


def _targets(text: str) -> tuple[Kind, ...]:
    try:
        return tuple(KIND_NAMES[t.strip()] for t in text.split(",") if t.strip())
    except KeyError as exc:
        raise argparse.ArgumentTypeError(
            f"unknown output {exc.args[0]!r}; choose from {', '.join(KIND_NAMES)}") from exc


def _non_negative(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value >= 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number of stops >= 0, got {text!r}")
    return value


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("inputs", nargs="+", type=Path, metavar="INPUT",
                   help="photos folder, HDR EXR folder, COLMAP model / transforms.json, or PLY")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="OUT",
                   help="output folder (made if missing; a re-run resumes in it)")
    p.add_argument("--to", type=_targets, default=DEFAULT_TARGETS, metavar="LIST",
                   help="what to make: any of hdr,poses,splats,usd,hdri (default: "
                        "splats,usd,hdri)")
    p.add_argument("--poses", type=Path, metavar="SPARSE_DIR|transforms.json",
                   help="poses to use instead of solving them (the same as giving them as "
                        "an INPUT; must be a COLMAP model or transforms.json)")
    scale = p.add_mutually_exclusive_group()
    scale.add_argument("--camera-height", type=float, metavar="METRES",
                       help="SfM poses: the photos' median height above the floor, for "
                            "metres (without a scale the unit is unknown)")
    scale.add_argument("--scale", type=float, metavar="FACTOR",
                       help="SfM poses: metres per SfM unit")
    scale.add_argument("--scale-from", metavar="IMG_A,IMG_B,METRES",
                       help="SfM poses: known distance between two photos' camera centres")
    p.add_argument("--default-variant", choices=["particlefield", "instancer", "rig"],
                   metavar="FORM", help="the lighting variant scene.usda selects (default rig)")
    p.add_argument("--method", choices=["bracket", "recursive", "linear"],
                   help="HDR uplift method (default: bracket when brackets are present, "
                        "else recursive)")
    p.add_argument("--predictor", help="exposure predictor for --method recursive")
    p.add_argument("--preset", choices=["fast", "balanced", "best"], default="fast",
                   help="fitting effort (default: fast)")
    p.add_argument("--keep-hdr", choices=["work", "full"], default="work",
                   help="size of the HDR views in OUT/hdr: work (the fit's working size, "
                        "default) or full (the photos' own; slower, more memory)")
    p.add_argument("--budget", type=positive_int, metavar="N", help="maximum splat count")
    p.add_argument("--iterations", type=positive_int, metavar="N",
                   help="fit optimisation steps (default: the preset's)")
    p.add_argument("--tolerance-stops", type=_non_negative, metavar="X",
                   help="keep the smallest model (fewer splats, lower SH degree) whose "
                        "error on the fit's held-out views stays within X stops of the full "
                        "fit's; the choice and its cost are printed and in report.json")
    p.add_argument("--refine-poses", action="store_true",
                   help="optimise small corrections to the training views' poses while "
                        "fitting (worth it with SfM poses; written to OUT/splats.refined-poses/)")
    p.add_argument("--uplift-power", action="store_true",
                   help="leave lights every photo clipped at the uplift's guess of their "
                        "power (by default a compact one, a bulb or a small panel, is weighed "
                        "by the surfaces it lights, as the photos measured them)")
    p.add_argument("--planes", choices=PLANE_MODES, metavar="auto|on|off",
                   help="keep the splats to the walls' and ceiling's planes (found in "
                        "the initial points), a window's floating light back on its wall: "
                        "auto (default: on where no view clipped, as merged brackets "
                        "give; off for clipped photos), on, off")
    p.add_argument("--at", type=parse_point, action="append", metavar="X,Y,Z",
                   help="probe point for HDRIs, in the poses' world frame (repeatable; "
                        "default: where the cameras stood, at their median height, moved "
                        "to free space)")
    p.add_argument("--as", dest="export_as", type=_forms, metavar="LIST",
                   help="USD forms: particlefield,instancer,rig (default: all three)")
    p.add_argument("--device", default="cpu", metavar="cpu|cuda[:N]",
                   help="where fitting and HDRI rendering run: cpu (default) or cuda")
    p.add_argument("--cube", action="store_true",
                   help="also write each HDRI as an OpenEXR cube map (NAME.cube.exr)")
    p.add_argument("--seed", type=int, default=0,
                   help="random seed of the fit (default 0; a run repeats exactly for a seed)")
    p.add_argument("--fresh", action="store_true",
                   help="ignore finished stages in OUT and redo everything")
    add_common(p, colour=True)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from ..devices import resolve_device  # imports torch: not at --help time

    resolve_device(args.device)
    inputs = list(args.inputs)
    if args.poses is not None:
        if detect_kind(args.poses) is not Kind.POSES:
            raise InputError("--poses: not a COLMAP model or transforms.json", args.poses)
        inputs.append(args.poses)
    choose = {"uplift": f"uplift.{args.method}"} if args.method else {}
    registry = default_registry()
    for step, name in choose.items():
        if name not in registry:
            raise NotBuiltYet(f"{step} method {name!r} is not built yet")
    job = Job(
        inputs=inputs,
        out_dir=args.output,
        targets=args.to,
        choose=choose,
        options=step_options({
            "uplift": {"predictor": args.predictor,
                       "max_size": 0 if args.keep_hdr == "full" else None},
            "poses": {"camera_height": args.camera_height, "scale": args.scale,
                      "scale_from": args.scale_from},
            "fit": {"preset": args.preset, "budget": args.budget, "device": args.device,
                    "iterations": args.iterations,
                    "seed": args.seed, "refine_poses": args.refine_poses or None,
                    "uplift_power": args.uplift_power or None,
                    "planes": args.planes,
                    "tolerance_stops": args.tolerance_stops},
            "export": {"as": list(args.export_as) if args.export_as else None,
                       "default_variant": args.default_variant},
            "hdri": {"at": args.at, "device": args.device, "cube": args.cube or None},
        }),
        settings={"ocio_config": args.ocio_config, "input_space": args.input_space,
                  "working_space": args.working_space, "device": args.device,
                  "seed": args.seed},
        resume=not args.fresh,
    )
    artifacts = run_job(job, registry, progress_from(args), command=["gaslight2usd", *sys.argv[1:]])
    report = json.loads((args.output / "report.json").read_text())
    lines = [f"{a.kind.value:10s} {a.path}" for a in artifacts.values()]
    from ..preview import CONTACT_SHEET

    sheet = args.output / CONTACT_SHEET
    if sheet.exists():
        lines.append(f"pictures   {sheet}")
    choice = _model_choice(report)
    if choice:
        lines.append(f"model      {choice['splats']} splats, SH degree {choice['sh_degree']} "
                     f"({choice['bytes'] / max(choice['full_bytes'], 1):.0%} of the full fit's "
                     f"bytes), {choice['cost_stops']:+.3f} stops held-out error for "
                     f"--tolerance-stops {choice['tolerance_stops']:g}")
    lines.append(f"report     {args.output / 'report.json'} "
                 f"({report['total_seconds']:.1f} s)")
    emit(args, {"outputs": {k.value: str(a.path) for k, a in artifacts.items()},
                "pictures": str(sheet) if sheet.exists() else None,
                "report": report}, "\n".join(lines))
    return 0


def _model_choice(report: dict) -> dict | None:
    """What ``--tolerance-stops`` chose, from the fit stage of ``report.json``."""
    for stage in report.get("stages", []):
        meta = stage.get("metadata") or {}
        if isinstance(meta, dict) and "model_choice" in meta:
            return meta["model_choice"]
    return None
