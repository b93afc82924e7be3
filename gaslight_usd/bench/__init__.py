"""``gaslight2usd bench``: time against accuracy for every method, on ground truth.

Suites are modules ``gaslight_usd/bench/suite_<name>.py`` found at run time.
Each defines (the bench contract)::

    NAME = "uplift"                     # --suite uplift
    DESCRIPTION = "one line"
    X = ("sec_per_mp", "seconds per megapixel")    # (row key, axis label with unit)
    Y = ("relight_psnr", "relight PSNR (dB)")      # (row key, axis label with unit)
    HIGHER_IS_BETTER = True                        # for Y
    def run(options: dict) -> list[dict]: ...

and optionally ``notes(options) -> list[str]`` (settings worth printing, e.g.
a reduced render size), ``summaries(rows) -> list[dict]`` (the suite's own
grouped figures, e.g. means per group of cases: written to ``<suite>.json``
and printed as a table), ``TABLE`` (the columns the CLI prints) and
``REFERENCES`` (methods such as an oracle: charted grey, kept off the front) and
``FRONT_BY`` (a row key, e.g. ``"method"``: a Pareto front per value of it, for a
suite whose methods measure different errors). Options:
``quick`` (bool: well under a minute), ``seed`` (int), ``out`` (Path, the
report folder), ``count`` (int or None: cases, suite default when None),
``progress`` (a :class:`~gaslight_usd.progress.Progress`), ``verbose``.

Rows are flat dicts with at least ``method``, ``setting`` and the X and Y
keys. The runner groups rows by (method, setting), takes the median of every
numeric column (NaN left out), and writes ``<suite>.csv`` (all rows),
``<suite>.json`` (rows, medians, options, versions) and ``<suite>.png`` (a
point per (method, setting) at its medians, Pareto front marked).

A suite module that fails to import is listed with its error, never fatal.
"""

from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

from .runner import SuiteResult, aggregate, run_suite

REQUIRED = ("NAME", "DESCRIPTION", "X", "Y", "run")


@dataclass(frozen=True)
class Discovery:
    suites: dict[str, ModuleType]
    """Suite name -> module, sorted by name."""
    broken: dict[str, str]
    """Module name -> why it could not be used (import error, missing attribute)."""


def suite_summaries() -> dict[str, str]:
    """``{name: description}`` of every suite, read from the files without importing
    them (suites import torch, Mitsuba...; ``--help`` must stay fast)."""
    import ast

    found: dict[str, str] = {}
    for info in pkgutil.iter_modules(__path__):
        if not info.name.startswith("suite_"):
            continue
        path = Path(__path__[0]) / f"{info.name}.py"
        try:
            tree = ast.parse(path.read_text())
        except (OSError, SyntaxError):
            continue
        consts = {t.id: n.value.value for n in tree.body if isinstance(n, ast.Assign)
                  for t in n.targets if isinstance(t, ast.Name)
                  and isinstance(n.value, ast.Constant) and isinstance(n.value.value, str)}
        if "NAME" in consts:
            found[consts["NAME"]] = consts.get("DESCRIPTION", "")
    return dict(sorted(found.items()))


def discover_suites() -> Discovery:
    """Import every ``suite_*`` module here; a broken one is recorded, not raised."""
    suites: dict[str, ModuleType] = {}
    broken: dict[str, str] = {}
    for info in pkgutil.iter_modules(__path__):
        if not info.name.startswith("suite_"):
            continue
        try:
            module = importlib.import_module(f"{__name__}.{info.name}")
        except Exception as exc:  # noqa: BLE001 - one bad suite must not hide the others
            broken[info.name] = f"failed to import: {type(exc).__name__}: {exc}"
            continue
        missing = [a for a in REQUIRED if not hasattr(module, a)]
        if missing:
            broken[info.name] = f"missing {', '.join(missing)}"
            continue
        if module.NAME in suites:
            broken[info.name] = f"duplicate suite name {module.NAME!r}"
            continue
        suites[module.NAME] = module
    return Discovery(dict(sorted(suites.items())), broken)


def run_bench(names: list[str] | None, options: dict[str, Any], out: Path,
              discovery: Discovery | None = None) -> list[SuiteResult]:
    """Run the named suites (all when ``names`` is empty) into ``out``; results in order."""
    discovery = discovery or discover_suites()
    chosen = names or list(discovery.suites)
    unknown = [n for n in chosen if n not in discovery.suites]
    if unknown:
        raise KeyError(", ".join(unknown))
    options = {**options, "out": Path(out)}
    return [run_suite(discovery.suites[n], options, Path(out)) for n in chosen]


__all__ = ["Discovery", "SuiteResult", "aggregate", "discover_suites", "run_bench", "run_suite"]
