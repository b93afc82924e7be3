"""``gaslight2usd bench [--suite NAME ...] -o REPORT_DIR``: time against accuracy."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from ..atomic import write_text
from ..bench import Discovery, SuiteResult, discover_suites, run_bench, suite_summaries
from ..bench.runner import jsonable
from ..errors import EXIT_FAILED, InputError
from ._common import add_common, emit, progress_from
from ._fit import PRESET_NAMES

HELP = "measure time and accuracy of methods on ground truth; Pareto chart"
DESCRIPTION = """\
Run benchmark suites and write, per suite, NAME.csv (every case), NAME.json
(cases, medians, options, versions) and NAME.png (time against accuracy, one
point per method and setting at its medians, Pareto front marked) into
REPORT_DIR, plus bench.json (what ran, how long, what failed). Prints a table
of medians per suite.

suites:
{suites}
examples:
  gaslight2usd bench --suite uplift --quick -o out/bench
  gaslight2usd bench -o out/bench            # every suite, full size
  gaslight2usd bench --suite scale --photos 24 --megapixels 0.2,12 -o out/bench
  gaslight2usd bench --suite stability -o out/bench   # where methods break
  gaslight2usd bench --suite budget --suite tradeoff -o out/bench  # + out/bench/index.html
"""


def _suite_lines() -> str:
    lines = [f"  {name:<10} {text}" for name, text in suite_summaries().items()]
    return "\n".join(lines or ["  (none found)"]) + "\n"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help=HELP,
                       description=DESCRIPTION.format(suites=_suite_lines()),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--suite", action="append", metavar="NAME", default=[],
                   help="suite to run (repeatable; default: all)")
    p.add_argument("--quick", action="store_true",
                   help="small sizes and few cases (well under a minute per suite)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random choice (0)")
    p.add_argument("--count", type=int, metavar="N",
                   help="number of cases (default: the suite's, e.g. uplift 200, quick 8)")
    p.add_argument("--preset", action="append", choices=PRESET_NAMES, default=[],
                   help="fit suite: fit presets to measure (repeatable; default fast and "
                        "balanced; balanced takes about 50 min on 2 cores)")
    p.add_argument("--method", action="append", default=[], metavar="NAME",
                   help="uplift and chain suites: only these methods (repeatable; "
                        "default: all)")
    p.add_argument("--scene", action="append", default=[], metavar="NAME",
                   help="chain suite: only these scenes (repeatable; room, bulb, panels, "
                        "shade, sun (a sun patch on the floor, no lamp), hall (a 7 m hall, "
                        "its lamp in a far corner), each optionally :SEED for another draw "
                        "never tuned on, e.g. room:11; default: all)")
    p.add_argument("--perturb", action="append", default=[], metavar="NAME",
                   help="stability suite: only these perturbations (repeatable; photos, "
                        "noise, jpeg, white_balance, exposure, motion_blur, light_half_out, "
                        "light_one_view, no_clip, clipped_frames, pose_noise)")
    p.add_argument("--full", action="store_true",
                   help="stability suite: every strength of each perturbation, not the "
                        "default few; stability and budget suites: fits with the preset as "
                        "it is (not shortened)")
    p.add_argument("--refit", action="store_true",
                   help="budget suite: also fit each splat budget from scratch (one fit per "
                        "budget), besides cutting the one full fit down")
    p.add_argument("--from", dest="sources", action="append", type=Path, default=[],
                   metavar="DIR", help="tradeoff suite: folders of earlier bench results "
                                       "(<suite>.json) to chart (repeatable; default: "
                                       "REPORT_DIR)")
    p.add_argument("--photos", type=_numbers(int), metavar="N[,N...]",
                   help="scale suite: photo counts (e.g. 12,24,48,96)")
    p.add_argument("--megapixels", type=_numbers(float), metavar="MP[,MP...]",
                   help="scale suite: photo sizes in megapixels (e.g. 0.2,3,12)")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="REPORT_DIR",
                   help="folder for the reports (created)")
    add_common(p)
    p.set_defaults(handler=run)


def _numbers(kind: type) -> Any:
    """An argparse type: a comma-separated list of positive ``kind`` numbers."""
    def parse(text: str) -> tuple:
        try:
            values = tuple(kind(t) for t in text.split(",") if t.strip())
        except ValueError:
            values = ()
        if not values or any(v <= 0 for v in values):
            raise argparse.ArgumentTypeError(f"expected positive numbers like 12,24, got "
                                             f"{text!r}")
        return values
    return parse


def _format(value: Any) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if math.isnan(value):
            return "-"
        return f"{value:.3g}" if abs(value) < 0.01 or abs(value) >= 1000 else f"{value:.3f}"
    return str(value)


def median_table(result: SuiteResult, columns: list[str]) -> str:
    """A plain-text table: method, setting, cases, then ``columns`` (medians)."""
    header = ["method", "setting", "cases", *columns, "pareto"]
    body = [[_format(m.get(c, float("nan"))) for c in header] for m in result.medians]
    widths = [max(len(h), *(len(r[i]) for r in body)) for i, h in enumerate(header)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True))]
    lines += ["  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)) for r in body]
    return "\n".join(lines)


def summary_table(summaries: list[dict[str, Any]]) -> str:
    """A plain-text table of a suite's own summaries (columns in first-seen order)."""
    header = list(dict.fromkeys(k for s in summaries for k in s))
    body = [[_format(s.get(c, float("nan"))) for c in header] for s in summaries]
    widths = [max(len(h), *(len(r[i]) for r in body)) for i, h in enumerate(header)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True))]
    lines += ["  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)) for r in body]
    return "\n".join(lines)


def _columns(module: Any) -> list[str]:
    table = getattr(module, "TABLE", None)
    return list(table) if table else list(dict.fromkeys([module.X[0], module.Y[0]]))


def run(args: argparse.Namespace) -> int:
    discovery: Discovery = discover_suites()
    unknown = [n for n in args.suite if n not in discovery.suites]
    if unknown:
        raise InputError(f"unknown suite(s) {', '.join(unknown)}; available: "
                         f"{', '.join(discovery.suites) or 'none'}")
    progress = progress_from(args)
    for module, why in discovery.broken.items():
        progress.message(f"suite module {module} skipped: {why}")
    names = args.suite or list(discovery.suites)
    options = {"quick": args.quick, "seed": args.seed, "count": args.count,
               "verbose": args.verbose, "presets": tuple(args.preset) or None,
               "methods": list(args.method) or None, "scenes": tuple(args.scene) or None,
               "photos": args.photos, "megapixels": args.megapixels,
               "perturbations": list(args.perturb) or None, "full": args.full,
               "refit": args.refit,
               "sources": list(args.sources) or None}
    results = []
    for name in names:
        progress.message(f"suite {name}: {discovery.suites[name].DESCRIPTION}")
        results += run_bench([name], {**options, "progress": progress.child(name)},
                             args.output, discovery)
    text = []
    for result in results:
        module = discovery.suites[result.name]
        text.append(f"== {result.name} ({result.seconds:.1f} s) ==")
        text += [f"  note: {n}" for n in result.notes]
        if result.error:
            text.append(f"  FAILED: {result.error}")
        if result.medians:
            text.append(median_table(result, _columns(module)))
        if result.summaries:
            text.append(summary_table(result.summaries))
            text.append("  wrote " + ", ".join(str(f) for f in result.files))
    summary = {
        "output": str(args.output),
        "suites": [{"name": r.name, "ok": r.ok, "error": r.error, "seconds": r.seconds,
                    "cases": len(r.rows), "files": [str(f) for f in r.files],
                    "notes": r.notes} for r in results],
        "skipped_modules": discovery.broken,
    }
    write_text(Path(args.output) / "bench.json", json.dumps(summary, indent=2))
    emit(args, jsonable({**summary, "medians": {r.name: r.medians for r in results},
                         "summaries": {r.name: r.summaries for r in results if r.summaries}}),
         "\n".join(text))
    return 0 if all(r.ok for r in results) else EXIT_FAILED
