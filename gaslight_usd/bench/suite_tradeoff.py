"""Bench suite "tradeoff": one HTML page of time against accuracy over every suite's results.

Reads the ``<suite>.json`` reports the runner wrote (in the ``--from`` folders, else in
the output folder, so ``--suite budget --suite tradeoff`` in one command works) and
writes ``index.html`` (:mod:`.tradeoff_page`): per suite, its methods, presets, budgets
and export forms as labelled points with the Pareto front marked, and the tables under
the charts. Its rows are every charted point (``suite``, ``x``, ``y``, ``front``)::

    gaslight2usd bench --suite tradeoff --from DIR -o OUT
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..atomic import write_text
from ..errors import GaslightError
from .tradeoff_page import build_page, load_reports, points_of

NAME = "tradeoff"
DESCRIPTION = "one HTML page: time against accuracy over every suite's JSON, Pareto fronts"
X = ("x", "the suite's X (time or size)")
Y = ("y", "the suite's Y (accuracy)")
HIGHER_IS_BETTER = True
TABLE = ("suite", "x", "y", "front")
PAGE = "index.html"


def command_for(sources: list[Path], out: Path) -> str:
    """The command line that rebuilds the page (relative paths as given)."""
    given = "".join(f" --from {s}" for s in sources)
    return f"gaslight2usd bench --suite tradeoff{given} -o {out}"


def run(options: dict[str, Any]) -> list[dict[str, Any]]:
    out = Path(options.get("out") or ".")
    sources = [Path(s) for s in options.get("sources") or ()]
    reports = load_reports(sources or [out])
    if not reports:
        where = ", ".join(str(s) for s in sources or [out])
        raise GaslightError(f"no bench results (<suite>.json) in {where}: run e.g. "
                            f"'gaslight2usd bench --suite budget -o {out}' first, or give "
                            "--from DIR")
    page = build_page(reports, command_for(sources, out))
    write_text(out / PAGE, page)
    rows = []
    for report in reports:
        for p in points_of(report):
            method, _, setting = p["label"].partition(" · ")
            rows.append({"method": f"{report['suite']}: {method}", "setting": setting,
                         "suite": report["suite"], "x": p["x"], "y": p["y"],
                         "front": int(p["front"]), "reference": int(p["reference"])})
    return rows
