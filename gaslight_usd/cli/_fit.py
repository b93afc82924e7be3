"""``gaslight2usd fit HDR_DIR --poses SPARSE_DIR -o splats.ply``: fit HDR splats."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..chain import ChainRun
from ..kinds import Artifact, Kind
from ..registry import default_registry
from ._common import add_common, emit, progress_from, settings_from
from ._points import positive_int

# The names of gaslight_usd.fit.PRESETS, kept here so --help does not import torch.
PRESET_NAMES = ("fast", "balanced", "best")
PLANE_MODES = ("auto", "on", "off")
"""``--planes`` (``FitConfig.plane_prior``; not imported from it: ``--help`` loads no torch)."""

HELP = "fit HDR Gaussian splats to posed HDR views (writes a 3DGS PLY)"
DESCRIPTION = """\
Fit 3D Gaussian splats to scene-linear HDR views (one <photo stem>.exr per
posed image) in linear HDR: colours are relative radiance, clamped at 0 only.
Every 8th view is held out to measure the fit; splats are added only while
the held-out views improve, never past --budget; idle splats are pruned. The
PLY carries the colour space, exposure scale, frame and provenance in its
header, and the held-out error; report.json sits beside it.

presets (the bundled example has 24 views of 480x360):
  fast      views at 1/4 size, 300 steps, <= 12k splats, SH degree <= 1
  balanced  views at 1/2 size, 2500 steps, SH degree <= 2
  best      full size, 6000 steps, SH degree <= 3

A checkpoint is kept beside the output while fitting; --resume continues an
interrupted fit with the same settings.

examples:
  gaslight2usd fit out/hdr --poses examples/room/sparse/0 -o out/splats.ply
  gaslight2usd fit out/hdr --poses out/sparse -o splats.ply --preset balanced --budget 50000
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("fit", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("hdr", type=Path, metavar="HDR_DIR", help="folder of HDR EXR views")
    p.add_argument("--poses", type=Path, required=True, metavar="SPARSE_DIR",
                   help="COLMAP model folder (or transforms.json) posing the views")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="SPLATS_PLY",
                   help="3DGS PLY to write")
    p.add_argument("--preset", choices=PRESET_NAMES, default="fast",
                   help="fitting effort: fast (default), balanced or best (see above)")
    p.add_argument("--budget", type=positive_int, metavar="N", help="most splats to keep")
    p.add_argument("--iterations", type=positive_int, metavar="N", help="optimisation steps")
    p.add_argument("--device", default="cpu", metavar="cpu|cuda[:N]",
                   help="cpu (default; compiled kernels, deterministic for a seed) or cuda "
                        "(the torch renderer on a GPU torch can see)")
    p.add_argument("--seed", type=int, default=0, help="random seed (the fit is deterministic)")
    p.add_argument("--refine-poses", action="store_true",
                   help="also optimise small corrections to the training views' poses "
                        "(for SfM poses; the refined poses are written beside the PLY as "
                        "SPLATS.refined-poses/, a COLMAP text model)")
    p.add_argument("--uplift-power", action="store_true",
                   help="leave lights every photo clipped at the uplift's guess of their "
                        "power (by default a compact one, a bulb or a small panel, is weighed "
                        "by the surfaces it lights, as the photos measured them)")
    p.add_argument("--planes", choices=PLANE_MODES, metavar="auto|on|off",
                   help="keep the splats to the walls' and ceiling's planes (found in "
                        "the initial points), a window's floating light back on its wall: "
                        "auto (default: on where no view clipped, as merged brackets "
                        "give; off for clipped photos), on, off")
    p.add_argument("--resume", action="store_true",
                   help="continue from the checkpoint an interrupted fit left")
    add_common(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from ..devices import resolve_device  # imports torch: not at --help time

    resolve_device(args.device)
    out = args.output
    options = {"preset": args.preset, "budget": args.budget, "iterations": args.iterations,
               "device": args.device, "seed": args.seed, "resume": args.resume,
               "refine_poses": args.refine_poses, "uplift_power": args.uplift_power,
               "planes": args.planes}
    runner = ChainRun(out.parent if str(out.parent) else Path("."),
                      settings_from(args, device=args.device, seed=args.seed),
                      default_registry(), progress_from(args))
    runner.run([Artifact(Kind.HDR_VIEWS, args.hdr), Artifact(Kind.POSES, args.poses)],
               [Kind.SPLATS], choose={"fit": "fit.splats"}, options={"fit": options},
               outputs={Kind.SPLATS: out}, resume=False)
    record = runner.records[-1]
    m, c = record.metrics, record.counts
    text = (f"fitted {c['splats']} splats to {c['views']} views in {record.seconds:.1f} s; "
            f"held-out log-luminance RMSE {m['held_out_log_lum_rmse_stops']:.3f} stops, "
            f"PU21-PSNR {m['held_out_pu21_psnr']:.2f} dB; wrote {out}")
    emit(args, {"output": str(out), **c, **m, "seconds": record.seconds}, text)
    return 0
