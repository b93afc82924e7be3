"""Time-against-accuracy chart: one point per (method, setting), Pareto front marked.

Drawn with matplotlib's Agg canvas directly (no pyplot, no global backend).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ..atomic import atomic_path
from ..evaluation.metrics import PSNR_CAP_DB


def pareto_front(points: list[dict[str, Any]], x_key: str, y_key: str,
                 higher_is_better: bool) -> list[bool]:
    """Which points no other point beats: less or equal X and better or equal Y, one strictly.

    Points missing X or Y (or NaN) are never on the front.
    """
    def value(p: dict[str, Any], key: str) -> float:
        v = p.get(key)
        return float(v) if isinstance(v, (int, float)) and not math.isnan(float(v)) else math.nan

    xs = [value(p, x_key) for p in points]
    ys = [value(p, y_key) if higher_is_better else -value(p, y_key) for p in points]
    front = []
    for i, (x, y) in enumerate(zip(xs, ys, strict=True)):
        if math.isnan(x) or math.isnan(y):
            front.append(False)
            continue
        beaten = any(
            j != i and not math.isnan(xj) and not math.isnan(yj)
            and xj <= x and yj >= y and (xj < x or yj > y)
            for j, (xj, yj) in enumerate(zip(xs, ys, strict=True))
        )
        front.append(not beaten)
    return front


def pareto_chart(points: list[dict[str, Any]], x_key: str, x_label: str, y_key: str,
                 y_label: str, higher_is_better: bool, title: str, path: Path,
                 references: set[str] | frozenset[str] = frozenset()) -> Path:
    """Write a PNG: labelled points at their medians, Pareto front joined and marked.

    Methods named in ``references`` (e.g. an oracle that reads the truth) are
    drawn grey and take no part in the front.

    X uses a log scale when every X is positive and they span more than 20x;
    a non-positive X (an instant method) is drawn at a tenth of the smallest
    positive one and labelled "~0".
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    usable = [p for p in points if _finite(p.get(x_key)) and _finite(p.get(y_key))]
    is_ref = [p["method"] in references for p in usable]
    contenders = [p for p, r in zip(usable, is_ref, strict=True) if not r]
    contender_front = iter(pareto_front(contenders, x_key, y_key, higher_is_better))
    front = [False if r else next(contender_front) for r in is_ref]
    xs = [float(p[x_key]) for p in usable]
    ys = [float(p[y_key]) for p in usable]
    positive = [x for x in xs if x > 0]
    log_x = bool(positive) and (max(positive) / min(positive) > 20 or len(positive) < len(xs))
    floor = min(positive) / 10 if positive else 1e-6
    shown = [x if x > 0 or not log_x else floor for x in xs]
    # A PSNR at its cap (identical images, e.g. the oracle) would squash every
    # other point: draw it at the top edge, marked "off scale".
    capped = [("dB" in y_label and y >= PSNR_CAP_DB) for y in ys]
    rest = [y for y, c in zip(ys, capped, strict=True) if not c]
    if any(capped) and rest:
        span = (max(rest) - min(rest)) or 1.0
        top = max(rest) + 0.3 * span
        ys = [top if c else y for y, c in zip(ys, capped, strict=True)]

    fig = Figure(figsize=(8, 5.5), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    others = [i for i, f in enumerate(front) if not f and not is_ref[i]]
    ax.scatter([shown[i] for i in others], [ys[i] for i in others], s=40, color="tab:blue",
               zorder=3, label="method / setting (median)")
    refs = [i for i, r in enumerate(is_ref) if r]
    if refs:
        ax.scatter([shown[i] for i in refs], [ys[i] for i in refs], s=40, color="tab:gray",
                   marker="s", zorder=3, label="reference (reads the truth; not on the front)")
    on = sorted((i for i, f in enumerate(front) if f), key=lambda i: shown[i])
    if on:
        ax.scatter([shown[i] for i in on], [ys[i] for i in on], s=60, color="tab:red",
                   zorder=4, label="Pareto front")
        ax.plot([shown[i] for i in on], [ys[i] for i in on], "--", color="tab:red",
                lw=1, zorder=2, drawstyle="steps-post")
    below = _crowded(shown, ys, log_x)
    for i, p in enumerate(usable):
        label = p["method"] + (f" ({p['setting']})" if p.get("setting") not in ("", "default")
                               else "")
        if log_x and xs[i] <= 0:
            label += "  [time ~0]"
        if capped[i] and rest:
            label += f"  [{PSNR_CAP_DB:g} dB cap, off scale]"
        ax.annotate(label, (shown[i], ys[i]), textcoords="offset points",
                    xytext=(6, -14 if below[i] else 6), fontsize=9)
    if log_x:
        ax.set_xscale("log")
    ax.set_xlabel(x_label + (" (log scale)" if log_x else ""))
    better = "higher" if higher_is_better else "lower"
    ax.set_ylabel(f"{y_label}, {better} is better")
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    if usable:
        ax.legend(loc="best", fontsize=8)
        ax.margins(x=0.15, y=0.12)
    else:
        ax.text(0.5, 0.5, "no points with both values", ha="center", transform=ax.transAxes)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    return path


def _finite(value: Any) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(float(value))


def _crowded(xs: list[float], ys: list[float], log_x: bool) -> list[bool]:
    """Label below the point when an earlier point sits close by (labels would overlap)."""
    def spread(values: list[float]) -> float:
        return (max(values) - min(values)) or 1.0 if values else 1.0

    px = [math.log10(x) for x in xs] if log_x else list(xs)
    sx, sy = spread(px), spread(ys)
    below = []
    for i in range(len(px)):
        near = any(abs(px[i] - px[j]) < 0.25 * sx and abs(ys[i] - ys[j]) < 0.05 * sy
                   and not below[j] for j in range(i))
        below.append(near)
    return below
