"""``gaslight2usd batch MANIFEST -o OUT``: many scenes, resumable, local or on Dask."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..errors import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_INTERRUPTED
from ._common import add_common, emit

HELP = "run many scenes from a TOML/JSON manifest (processes or Dask), resumable"
DESCRIPTION = """\
Run every scene of a manifest through the chain, each into OUT/<name>/ (its
outputs, report.json and batch.log), and sum it up in OUT/batch.json and a
table. The whole manifest is checked first (schema: gaslight_usd/schemas/
manifest.schema.json); every problem is named with its scene and key, and
nothing runs. A scene that fails does not stop the others (exit status 1).

Resuming: run the same command again. A scene whose outputs all match its
inputs and options is skipped; a changed option reruns the stages it affects
and those after them (new probes rerun only the HDRIs). A batch killed even
with SIGKILL resumes: outputs are written whole or not at all. Ctrl-C or
SIGTERM stop it cleanly (exit status 130), finished scenes kept.

manifest (TOML; JSON with the same keys works too). Paths are relative to it;
`defaults` holds any scene key, a scene's own keys win (tables merge):

  [defaults]
  targets = ["splats", "usd", "hdri"]   # any of hdr, poses, splats, usd, hdri
  preset = "fast"                       # fast | balanced | best
  colour = { working_space = "ACEScg" } # also config, input_space, output_space

  [[scenes]]
  name = "kitchen"
  photos = "kitchen/photos"
  poses = "kitchen/sparse"              # omit to solve them (SfM)
  probes = [[0, 1.5, 0], [1.2, 1.5, -0.8]]

  [[scenes]]
  name = "hall"
  photos = "hall/photos"
  camera_height = 1.6                   # SfM scale; or scale, or scale_from
  preset = "balanced"
  [scenes.options.hdri]                 # any converter option, per step
  size = 1024

  other keys: inputs (list of any stage's files), method (bracket | recursive
  | linear), device, seed, choose, options.{uplift,poses,fit,export,hdri}

examples:
  gaslight2usd batch shots.toml -o /jobs/lighting --dry-run
  gaslight2usd batch shots.toml -o /jobs/lighting --jobs 2
  gaslight2usd batch shots.toml -o /shared/lighting --dask tcp://scheduler:8786
  gaslight2usd batch shots.toml -o /jobs/lighting --dask local:4
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("batch", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("manifest", type=Path, help="the manifest (.toml or .json)")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="OUT",
                   help="output folder: OUT/<scene>/ per scene, OUT/batch.json")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--jobs", type=int, default=1, metavar="N",
                       help="scenes run at once, each in its own process (default 1: "
                            "one after another in this process)")
    where.add_argument("--dask", metavar="ADDRESS",
                       help="run the scenes on a Dask cluster: a scheduler address "
                            "(tcp://host:8786; OUT must be storage the workers share) or "
                            "local:N for a LocalCluster of N worker processes")
    p.add_argument("--dry-run", action="store_true",
                   help="print each scene's stages and what would run or be skipped; "
                        "write nothing")
    add_common(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from ..batch import plan_batch, plan_text, run_batch, summary_table
    from ..manifest import ManifestError, load_manifest
    from ..outputs import check_output

    if args.jobs < 1:
        print("gaslight2usd: error: --jobs must be 1 or more", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        scenes = load_manifest(args.manifest, args.output)
    except ManifestError as exc:
        for line in exc.lines():
            print(f"gaslight2usd: error: {line}", file=sys.stderr)
        print(f"gaslight2usd: {len(exc.problems)} problem(s) in the manifest; nothing was run",
              file=sys.stderr)
        return exc.exit_code
    check_output(args.output, folder=True)  # before any work, not after the planning
    plans = plan_batch(scenes)
    if args.dry_run:
        emit(args, {"dry_run": True, "scenes": [{"name": s.name, "out_dir": str(s.job.out_dir),
                                                  **plans[s.name]} for s in scenes]},
             plan_text(scenes, plans))
        return 0
    report = run_batch(scenes, args.output, jobs=args.jobs, dask=args.dask, quiet=args.quiet,
                       manifest=args.manifest, plans=plans)
    emit(args, report, summary_table(report))
    if report["status"] == "interrupted":
        return EXIT_INTERRUPTED
    return EXIT_FAILED if report["counts"]["failed"] else 0
