"""One self-contained HTML page of time against accuracy, from the benches' JSON reports.

Each ``<suite>.json`` the bench runner writes (:mod:`.runner`) becomes a section: an
inline SVG scatter of its medians (its own X against its own Y, since suites measure
different things), every point labelled ``method · setting``, the Pareto front ringed
and joined, then the medians as a table and the suite's own summaries (e.g. the
stability suite's break points) as a second. No scripts, no fonts or images from
elsewhere: the page opens offline. The output is a pure function of the reports (no
clock, no paths), so a committed page can be checked against a fresh build::

    gaslight2usd bench --suite tradeoff --from DIR -o OUT
"""

from __future__ import annotations

import html
import json
import math
from pathlib import Path
from typing import Any

from .chart import pareto_front

WIDTH, HEIGHT = 760, 440
MARGIN = {"left": 70, "right": 20, "top": 20, "bottom": 50}
FRONT_COLOUR = "#c0392b"
POINT_COLOUR = "#2c6fbb"
REFERENCE_COLOUR = "#999999"


def load_reports(folders: list[Path]) -> list[dict[str, Any]]:
    """Every bench report (a JSON with ``suite`` and ``medians``) in ``folders``, not the
    tradeoff page's own, sorted by suite name. Reports of one suite (runs of other methods
    or presets, e.g. ``stability.json`` and ``stability-linear.json``) are charted
    together: their medians, summaries and notes joined in file order."""
    reports: dict[str, dict[str, Any]] = {}
    for folder in folders:
        for path in sorted(Path(folder).glob("*.json")):
            try:
                data = json.loads(path.read_text())
            except (OSError, json.JSONDecodeError):
                continue
            if not (isinstance(data, dict) and "suite" in data and "medians" in data) \
                    or data["suite"] == "tradeoff":
                continue
            seen = reports.get(data["suite"])
            if seen is None:
                reports[data["suite"]] = dict(data)
                continue
            seen["medians"] = [*seen["medians"], *data["medians"]]
            seen["summaries"] = [*(seen.get("summaries") or []), *(data.get("summaries") or [])]
            seen["notes"] = list(dict.fromkeys([*seen.get("notes", []), *data.get("notes", [])]))
    return [reports[k] for k in sorted(reports)]


def _num(value: Any) -> float:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(float(value)) else math.nan


def fmt(value: Any) -> str:
    """A table cell: 4 significant digits for numbers, '-' for missing."""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, float)):
        v = float(value)
        if not math.isfinite(v):
            return "-"
        return str(int(v)) if v == int(v) and abs(v) < 1e9 else f"{v:.4g}"
    return "-" if value is None else str(value)


def _ticks(lo: float, hi: float, log: bool) -> list[float]:
    if log:
        return [10.0 ** e for e in range(math.floor(math.log10(lo)), math.ceil(math.log10(hi)) + 1)]
    step = 10 ** math.floor(math.log10(max(hi - lo, 1e-12) / 4))
    for mult in (1, 2, 5, 10):
        if (hi - lo) / (step * mult) <= 6:
            step *= mult
            break
    first = math.ceil(lo / step) * step
    return [first + i * step for i in range(int((hi - first) / step) + 1)]


def points_of(report: dict[str, Any]) -> list[dict[str, Any]]:
    """The medians with finite X and Y, each with ``label``, ``x``, ``y``, ``reference``
    (a method the suite lists as a reference) and ``front`` (on the Pareto front of the
    other points)."""
    xk, yk = report["x"]["key"], report["y"]["key"]
    refs = set(report.get("references") or ())
    pts = [{"label": " · ".join(t for t in (str(m.get("method", "?")),
                                             str(m.get("setting", ""))) if t),
            "x": _num(m.get(xk)), "y": _num(m.get(yk)), "reference": m.get("method") in refs}
           for m in report["medians"]]
    pts = [p for p in pts if not (math.isnan(p["x"]) or math.isnan(p["y"]))]
    higher = bool(report.get("higher_is_better", True))
    for p in pts:
        p["front"] = False
    by_family = report.get("front_by") == "method"
    families: dict[str, list[dict[str, Any]]] = {}
    for p in pts:
        if not p["reference"]:
            families.setdefault(p["label"].split(" · ")[0] if by_family else "", []).append(p)
    for members in families.values():
        for p, on in zip(members, pareto_front(members, "x", "y", higher), strict=True):
            p["front"] = on
    return pts


def svg_chart(report: dict[str, Any]) -> str:
    """An inline SVG scatter of a report's medians, labelled, front ringed and joined."""
    pts = points_of(report)
    w, h = WIDTH - MARGIN["left"] - MARGIN["right"], HEIGHT - MARGIN["top"] - MARGIN["bottom"]
    title = html.escape(f"{report['suite']}: {report['y']['label']} against "
                        f"{report['x']['label']}")
    head = (f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" '
            f'viewBox="0 0 {WIDTH} {HEIGHT}" role="img" aria-label="{title}">'
            f'<rect width="{WIDTH}" height="{HEIGHT}" fill="#ffffff"/>')
    if not pts:
        return head + (f'<text x="{WIDTH / 2}" y="{HEIGHT / 2}" text-anchor="middle">no point '
                       "with both values</text></svg>")
    xs, ys = [p["x"] for p in pts], [p["y"] for p in pts]
    log = min(xs) > 0 and max(xs) / min(xs) > 20
    tx = (lambda v: math.log10(v)) if log else (lambda v: v)
    x0, x1 = tx(min(xs)), tx(max(xs))
    y0, y1 = min(ys), max(ys)
    padx, pady = (x1 - x0) * 0.08 or 1.0, (y1 - y0) * 0.1 or 1.0
    x0, x1, y0, y1 = x0 - padx, x1 + padx, y0 - pady, y1 + pady

    def px(v: float) -> float:
        return MARGIN["left"] + (tx(v) - x0) / (x1 - x0) * w

    def py(v: float) -> float:
        return MARGIN["top"] + (1 - (v - y0) / (y1 - y0)) * h

    parts = [head, f'<rect x="{MARGIN["left"]}" y="{MARGIN["top"]}" width="{w}" height="{h}" '
             'fill="#fafafa" stroke="#333"/>']
    lo_x, hi_x = (10 ** x0, 10 ** x1) if log else (x0, x1)
    for t in _ticks(lo_x, hi_x, log):
        if lo_x <= t <= hi_x:
            parts.append(f'<line x1="{px(t):.1f}" x2="{px(t):.1f}" y1="{MARGIN["top"]}" '
                         f'y2="{MARGIN["top"] + h}" stroke="#ddd"/><text x="{px(t):.1f}" '
                         f'y="{MARGIN["top"] + h + 16}" font-size="11" text-anchor="middle">'
                         f"{fmt(t)}</text>")
    for t in _ticks(y0, y1, False):
        if y0 <= t <= y1:
            parts.append(f'<line x1="{MARGIN["left"]}" x2="{MARGIN["left"] + w}" '
                         f'y1="{py(t):.1f}" y2="{py(t):.1f}" stroke="#ddd"/><text '
                         f'x="{MARGIN["left"] - 6}" y="{py(t) + 4:.1f}" font-size="11" '
                         f'text-anchor="end">{fmt(round(t, 10))}</text>')
    parts.append(f'<text x="{MARGIN["left"] + w / 2}" y="{HEIGHT - 12}" font-size="13" '
                 f'text-anchor="middle">{html.escape(report["x"]["label"])}'
                 f'{" (log scale)" if log else ""}</text>')
    parts.append(f'<text transform="translate(16 {MARGIN["top"] + h / 2}) rotate(-90)" '
                 f'font-size="13" text-anchor="middle">{html.escape(report["y"]["label"])}'
                 "</text>")
    families: dict[str, list[dict[str, Any]]] = {}
    for p in pts:
        if p["front"]:
            key = p["label"].split(" · ")[0] if report.get("front_by") == "method" else ""
            families.setdefault(key, []).append(p)
    for front in families.values():
        if len(front) > 1:
            path = " ".join(f"{px(p['x']):.1f},{py(p['y']):.1f}"
                            for p in sorted(front, key=lambda p: p["x"]))
            parts.append(f'<polyline points="{path}" fill="none" stroke="{FRONT_COLOUR}" '
                         'stroke-width="1.5" stroke-dasharray="5 3"/>')
    for p in pts:
        colour = REFERENCE_COLOUR if p["reference"] else POINT_COLOUR
        cx, cy = px(p["x"]), py(p["y"])
        parts.append(f'<circle cx="{cx:.1f}" cy="{cy:.1f}" r="4.5" fill="{colour}"/>')
        if p["front"]:
            parts.append(f'<circle cx="{cx:.1f}" cy="{cy:.1f}" r="8" fill="none" '
                         f'stroke="{FRONT_COLOUR}" stroke-width="2"/>')
        anchor = "end" if cx > MARGIN["left"] + w * 0.7 else "start"
        dx = -10 if anchor == "end" else 10
        parts.append(f'<text x="{cx + dx:.1f}" y="{cy - 6:.1f}" font-size="10" '
                     f'text-anchor="{anchor}" fill="#222">{html.escape(p["label"])}</text>')
    parts.append("</svg>")
    return "".join(parts)


def table(rows: list[dict[str, Any]], columns: list[str]) -> str:
    """An HTML table of ``rows`` over ``columns``."""
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(fmt(r.get(c)))}</td>" for c in columns)
                   + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def section(report: dict[str, Any]) -> str:
    """A suite's chart, its medians table and its summaries table."""
    xk, yk = report["x"]["key"], report["y"]["key"]
    columns = ["method", "setting", "cases", xk, yk, "pareto"]
    extra = [c for c in ("seconds", "size_bytes", "error_stops", "cost_stops", "drop_db",
                         "irradiance_psnr", "relight_psnr") if c not in columns
             and any(c in m for m in report["medians"])]
    parts = [f'<section id="{html.escape(report["suite"])}"><h2>{html.escape(report["suite"])}'
             f"</h2><p>{html.escape(report.get('description', ''))}</p>"]
    parts += [f"<p class='note'>{html.escape(n)}</p>" for n in report.get("notes", [])]
    parts.append(svg_chart(report))
    better = "higher" if report.get("higher_is_better", True) else "lower"
    parts.append("<p class='key'>Blue: a method and setting at its medians; grey: a "
                 "reference (oracle or floor); ringed red and joined: the Pareto front (no "
                 f"other point has both less X and {better} Y).</p>")
    parts.append("<h3>Medians</h3>" + table(report["medians"], columns[:5] + extra + ["pareto"]))
    summaries = report.get("summaries") or []
    if summaries:
        cols = list(dict.fromkeys(k for s in summaries for k in s))
        parts.append("<h3>Summaries</h3>" + table(summaries, cols))
    parts.append("</section>")
    return "".join(parts)


STYLE = ("body{font-family:sans-serif;margin:24px;color:#222;max-width:1100px}"
         "table{border-collapse:collapse;font-size:12px;margin:8px 0 24px}"
         "td,th{border:1px solid #ccc;padding:3px 6px;text-align:left}"
         "th{background:#eee}code{background:#f3f3f3;padding:2px 4px}"
         ".note{color:#555;font-size:13px}.key{font-size:12px;color:#555}")


def build_page(reports: list[dict[str, Any]], command: str) -> str:
    """The whole page: the regenerating ``command`` at the top, then a section per report."""
    toc = " · ".join(f'<a href="#{html.escape(r["suite"])}">{html.escape(r["suite"])}</a>'
                     for r in reports)
    body = "".join(section(r) for r in reports)
    return ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            "<title>gaslight2usd: time against accuracy</title>"
            f"<style>{STYLE}</style></head><body>"
            "<h1>gaslight2usd: time against accuracy</h1>"
            f"<p>Regenerate this page with: <code>{html.escape(command)}</code></p>"
            f"<p>Suites: {toc}</p>{body}</body></html>\n")
