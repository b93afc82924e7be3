"""The uplift methods of this package, registered into ``bench --suite uplift``.

Imported by :mod:`gaslight_usd.bench.suite_uplift` (its plug-in module).
Methods: ``recursive-fast`` (the paper's recursion with the fast predictor),
``recursive-fast-unshrunk`` (the same with its estimates not shrunk towards
white, :data:`.fast_predictor.SHRINK`: better on the panoramas it was fitted on,
worse on others),
``recursive-fast-lopo`` (every case predicted by the calibration's model fitted
without that case's panorama, :data:`.fast_predictor.LOPO_FILE`; the shipped
model where none was fitted: the honest score of a model on panoramas it never
saw, not a method to ship), and the reference ``recursive-fast+true-energy``
(its output with every
clipped region rescaled, per channel, to the truth's mean over it: the fast
predictor's shapes with perfect energy, so the gap between the two is what
its energy estimates cost).
The recursion with the ``reexpose`` predictor equals ``ldr-baseline`` (tested
in tests/test_uplift.py), so it is not benchmarked.

Where it fails, in pictures::

    python -m gaslight_usd.bench.uplift_methods BENCH_DIR/uplift.json -o worst.png [-n 8]

rebuilds the worst crops of ``recursive-fast`` (largest relight PSNR loss
against ``ldr-baseline``, then lowest PSNR) from the bench's seed and draws, per
crop, the photo, the truth, the prediction (both tone-mapped with the same
exposure, log scale) and the predicted / true ratio in stops.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from ..evaluation.reference import ReferencePair
from ..uplift.fast_predictor import LOPO_FILE, FastPredictor
from ..uplift.recursive import uplift_recursive
from .calibrate import evaluation_curve
from .suite_uplift import (
    clipped_regions,
    region_means,
    register_pair_method,
    register_reference_method,
    register_uplift_method,
)

_FAST = FastPredictor()
METHOD = "recursive-fast"


def recursive_fast(ldr: np.ndarray, curve: str) -> np.ndarray:
    return uplift_recursive(ldr, _FAST, evaluation_curve(curve)).linear


register_uplift_method(METHOD, recursive_fast)

_RAW = FastPredictor(shrink=1.0)


def recursive_fast_unshrunk(ldr: np.ndarray, curve: str) -> np.ndarray:
    return uplift_recursive(ldr, _RAW, evaluation_curve(curve)).linear


register_uplift_method(METHOD + "-unshrunk", recursive_fast_unshrunk)


class LeaveOnePanoramaOut:
    """Per panorama, the calibration's model fitted without it (else the shipped one)."""

    def __init__(self, path: Path = LOPO_FILE):
        models = json.loads(Path(path).read_text())["models"] if Path(path).exists() else {}
        self.predictors = {name: FastPredictor({"model": model})
                           for name, model in models.items()}

    def __call__(self, pair: ReferencePair) -> np.ndarray:
        predictor = self.predictors.get(pair.spec.source, _FAST)
        return uplift_recursive(pair.ldr, predictor, evaluation_curve(pair.curve)).linear


register_pair_method(METHOD + "-lopo", LeaveOnePanoramaOut())


def with_true_energy(pred: np.ndarray, pair: ReferencePair) -> np.ndarray:
    """``pred`` with each clipped region scaled (per channel) to the truth's mean over it."""
    out = np.array(pred, dtype=np.float32)
    labels, count = clipped_regions(pair.ldr)
    if count:
        inside = labels > 0
        ratio = (region_means(pair.truth, labels, count)
                 / np.maximum(region_means(out, labels, count), 1e-12)).astype(np.float32)
        out[inside] *= ratio[labels[inside] - 1]
    return out


register_reference_method(METHOD + "+true-energy",
                          lambda pair: with_true_energy(recursive_fast(pair.ldr, pair.curve), pair))


def worst_cases(rows: list[dict], count: int) -> list[tuple[str, float, float]]:
    """``(case, method PSNR, baseline PSNR)`` of the ``count`` largest losses (then lowest)."""
    base = {r["case"]: r["relight_psnr"] for r in rows if r["method"] == "ldr-baseline"}
    mine = [(r["case"], r["relight_psnr"], base.get(r["case"], np.nan)) for r in rows
            if r["method"] == METHOD]
    mine.sort(key=lambda c: (c[1] - c[2], c[1]))
    return mine[:count]


def _tonemap(hdr: np.ndarray, scale: float) -> np.ndarray:
    """Log tone map: 2^-6 .. 2^10 of ``scale`` onto [0, 1], gamma-free."""
    y = np.log2(np.maximum(hdr * scale, 2.0 ** -6))
    return np.clip((y + 6.0) / 16.0, 0.0, 1.0)


def contact_sheet(bench_json: Path, output: Path, count: int = 8, seed: int = 0) -> Path:
    """Draw the worst crops of a bench run (see the module doc); returns ``output``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..evaluation.reference import make_pair
    from ..evaluation.shared_panoramas import load_shared

    rows = json.loads(Path(bench_json).read_text())["rows"]
    sources = {s.name: s for s in load_shared()}
    cases = worst_cases(rows, count)
    fig, axes = plt.subplots(len(cases), 4, figsize=(12, 2.4 * len(cases)), squeeze=False)
    for ax_row, (case, psnr, base) in zip(axes, cases, strict=True):
        name, index = case.rsplit("-", 1)
        pair = make_pair(sources[name], int(index), seed)
        pred = recursive_fast(pair.ldr, pair.curve)
        ratio = np.log2(np.maximum(pred.max(axis=-1), 1e-6)
                        / np.maximum(pair.truth.max(axis=-1), 1e-6))
        panels = [(pair.ldr, f"{case} ({pair.curve})"),
                  (_tonemap(pair.truth, 1.0), f"truth, peak {pair.truth.max():.0f}x"),
                  (_tonemap(pred, 1.0), f"fast, peak {pred.max():.0f}x"),
                  (None, f"PSNR {psnr:.1f} vs base {base:.1f} dB")]
        for ax, (img, title) in zip(ax_row, panels, strict=True):
            if img is None:
                shown = ax.imshow(ratio, cmap="RdBu_r", vmin=-6, vmax=6)
                fig.colorbar(shown, ax=ax, fraction=0.04, label="pred/true stops")
            else:
                ax.imshow(img)
            ax.set_title(title, fontsize=8)
            ax.axis("off")
    fig.tight_layout()
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=80)
    plt.close(fig)
    return output


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="contact sheet of the fast predictor's worst "
                                 "bench crops")
    ap.add_argument("bench_json", type=Path, help="uplift.json of a bench run")
    ap.add_argument("-o", "--output", type=Path, required=True)
    ap.add_argument("-n", "--count", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0, help="the bench's seed")
    args = ap.parse_args(argv)
    print(contact_sheet(args.bench_json, args.output, args.count, args.seed))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
