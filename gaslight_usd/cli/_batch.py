"""``gaslight2usd batch MANIFEST -o OUT``: many scenes, resumable."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from ..batch import load_manifest, run_batch
from ..errors import EXIT_FAILED
from ._common import add_common, emit

HELP = "run many scenes from a JSON manifest (process pool or Dask), resumable"
DESCRIPTION = """\
Run every scene of a manifest through the chain, each into OUT/<name>/ with its
own report.json; a summary goes to OUT/batch-report.json. One scene's failure
does not stop the others; the exit status is 1 if any failed. Run the same
command again to resume: finished stages are skipped.

manifest (JSON; schema: gaslight_usd/schemas/manifest.schema.json):
  {"defaults": {"targets": ["splats", "usd", "hdri"],
                "options": {"fit": {"preset": "fast"}}},
   "scenes": [{"name": "room", "inputs": ["examples/room/photos"]}]}

examples:
  gaslight2usd batch shots.json -o /jobs/lighting --jobs 2
  gaslight2usd batch shots.json -o /jobs/lighting --dask tcp://scheduler:8786
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("batch", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("manifest", type=Path)
    p.add_argument("-o", "--output", type=Path, required=True, metavar="OUT")
    p.add_argument("--jobs", type=int, default=1, metavar="N",
                   help="scenes run at once in a process pool (default 1)")
    p.add_argument("--dask", metavar="ADDRESS",
                   help="submit scenes to a Dask distributed scheduler instead")
    add_common(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    jobs = load_manifest(args.manifest, args.output)
    workers = max(1, min(args.jobs, len(jobs), os.cpu_count() or 1))
    report = run_batch(jobs, args.output, workers, args.dask, quiet=args.quiet)
    lines = [f"{s['name']:20s} {s['status']:7s} {s['seconds']:8.1f} s"
             + (f"  {s['error']}" if s["error"] else "") for s in report["scenes"]]
    lines.append(f"{report['done']} done, {report['failed']} failed "
                 f"-> {args.output / 'batch-report.json'}")
    emit(args, report, "\n".join(lines))
    return EXIT_FAILED if report["failed"] else 0
