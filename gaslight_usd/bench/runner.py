"""Run one bench suite: collect its rows, take medians, write CSV, JSON and the chart."""

from __future__ import annotations

import csv
import io
import json
import math
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from ..atomic import write_text
from ..provenance import versions
from .chart import pareto_chart, pareto_front

GROUP_KEYS = ("method", "setting")


@dataclass
class SuiteResult:
    name: str
    rows: list[dict[str, Any]] = field(default_factory=list)
    medians: list[dict[str, Any]] = field(default_factory=list)
    summaries: list[dict[str, Any]] = field(default_factory=list)
    """The suite's own grouped figures (optional ``summaries(rows)``), e.g. means per group."""
    seconds: float = 0.0
    error: str | None = None
    files: list[Path] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.error is None


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_))


def aggregate(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One dict per (method, setting): ``cases`` and the median of every numeric column.

    NaN values are left out of a median (a metric that does not apply to a
    case); a column that is NaN everywhere has median NaN.
    """
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in rows:
        key = (str(row.get("method", "?")), str(row.get("setting", "")))
        groups.setdefault(key, []).append(row)
    out = []
    for (method, setting), members in groups.items():
        columns = list(dict.fromkeys(k for r in members for k in r if k not in GROUP_KEYS))
        entry: dict[str, Any] = {"method": method, "setting": setting, "cases": len(members)}
        for col in columns:
            values = [float(r[col]) for r in members if col in r and _is_number(r[col])]
            if not values:
                continue
            finite = [v for v in values if not math.isnan(v)]
            entry[col] = float(np.median(finite)) if finite else math.nan
        out.append(entry)
    return out


def jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if _is_number(value):
        v = float(value) if isinstance(value, (float, np.floating)) else int(value)
        return None if isinstance(v, float) and not math.isfinite(v) else v
    if isinstance(value, Path):
        return str(value)
    return value


def _csv_text(rows: list[dict[str, Any]]) -> str:
    columns = list(dict.fromkeys(k for r in rows for k in r))
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if v is None else v) for k, v in row.items()})
    return buf.getvalue()


def suite_notes(module: ModuleType, options: dict[str, Any]) -> list[str]:
    """A suite's optional ``notes(options) -> list[str]`` (settings worth stating)."""
    fn = getattr(module, "notes", None)
    return list(fn(options)) if callable(fn) else []


def run_suite(module: ModuleType, options: dict[str, Any], out: Path) -> SuiteResult:
    """Run ``module.run(options)`` and write ``<name>.csv``, ``.json`` and ``.png`` in ``out``.

    A suite that raises is reported in the result (``error``), not re-raised.
    """
    name = module.NAME
    result = SuiteResult(name=name)
    start = time.perf_counter()
    try:
        result.notes = suite_notes(module, options)
        result.rows = [dict(r) for r in module.run(dict(options))]
    except Exception as exc:  # noqa: BLE001 - a failing suite must not stop the others
        result.error = f"{type(exc).__name__}: {exc}"
        if options.get("verbose"):
            traceback.print_exc()
    result.seconds = time.perf_counter() - start
    if not result.rows:
        result.error = result.error or "the suite returned no rows"
        return result
    result.medians = aggregate(result.rows)
    summarise = getattr(module, "summaries", None)
    if callable(summarise):
        result.summaries = [dict(s) for s in summarise(result.rows)]
    x_key, x_label = module.X
    y_key, y_label = module.Y
    higher = bool(getattr(module, "HIGHER_IS_BETTER", True))
    references = set(getattr(module, "REFERENCES", ()))
    for entry in result.medians:
        entry["pareto"] = False
    front_by = getattr(module, "FRONT_BY", None)
    contenders = [m for m in result.medians if m["method"] not in references]
    families = ({} if front_by is None else
                {m.get(front_by): [c for c in contenders if c.get(front_by) == m.get(front_by)]
                 for m in contenders})
    for members in (families.values() if front_by else [contenders]):
        for entry, on_front in zip(members, pareto_front(members, x_key, y_key, higher),
                                   strict=True):
            entry["pareto"] = on_front
    out.mkdir(parents=True, exist_ok=True)
    csv_path = write_text(out / f"{name}.csv", _csv_text(result.rows))
    report = {
        "suite": name, "description": module.DESCRIPTION,
        "x": {"key": x_key, "label": x_label}, "y": {"key": y_key, "label": y_label},
        "higher_is_better": higher, "references": sorted(references), "front_by": front_by,
        "seconds": result.seconds, "notes": result.notes,
        "options": {k: v for k, v in options.items() if k != "progress"},
        "versions": versions(), "error": result.error,
        "medians": result.medians, "summaries": result.summaries, "rows": result.rows,
    }
    json_path = write_text(out / f"{name}.json", json.dumps(jsonable(report), indent=2))
    png_path = pareto_chart(result.medians, x_key, x_label, y_key, y_label, higher,
                            f"{name}: {module.DESCRIPTION}", out / f"{name}.png", references)
    result.files = [csv_path, json_path, png_path]
    return result
