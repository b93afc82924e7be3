"""Calibrate (train) the fast predictor on real HDR panoramas, reproducibly.

    python -m gaslight_usd.uplift.calibrate [--hdri DIR] [--holdout sunset]
        [--crops 400] [--seed 1000] [-o PARAMS.json]

Pairs come from the evaluation's reference builder
(:func:`gaslight_usd.evaluation.reference.make_pair`: perspective crops of
the shared panoramas, half aimed at the light, metered exposures, sRGB /
gamma 2.2 / filmic camera curves, 8 bits), with a seed the benchmark does not
use (the bench uses seed 0). ``studio`` is never used (its lamps are clamped
flat) and the held-out panoramas are kept for measuring generalisation.
Targets: ``log2`` of the brightest true linear channel of every clipped pixel
(pixels whose truth is unreliable, clamped in the source, are skipped). The
model (:class:`.fast_predictor.Mlp`, 10-16-16-1, tanh, softplus) is fitted with
Adam on the mean squared log error, each pixel weighted by 1/sqrt of its
region's area so small lamps count as much as big windows; seeded, CPU, about
two minutes on 2 busy cores.
"""

from __future__ import annotations

import argparse
import json
import time
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..evaluation import curves as camera_curves
from ..evaluation.reference import make_pair, shared_sources
from .curves import Curve, lut_curve
from .fast_predictor import FEATURES, PARAMS_FILE, clip_features

EXCLUDED = ("studio",)


@lru_cache(maxsize=8)
def evaluation_curve(name: str) -> Curve:
    """One of the evaluation's camera curves (srgb, gamma2.2, filmic) as a fast table."""
    levels = np.linspace(0.0, 1.0, 4097, dtype=np.float32)
    return lut_curve(name, levels, camera_curves.decode(levels, name))


def collect(hdri: Path | None, holdout: list[str], crops: int, seed: int, per_crop: int = 500
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    sources = [s for s in shared_sources(hdri) if s.name not in EXCLUDED + tuple(holdout)]
    rng = np.random.default_rng(seed)
    xs, ys, ws = [], [], []
    for i in range(crops):
        source = sources[i % len(sources)]
        pair = make_pair(source, i, seed)
        curve = evaluation_curve(pair.curve)
        feats = clip_features(curve.to_linear(pair.ldr), pair.ldr)
        if feats is None:
            continue
        truth = pair.truth[feats.mask].max(axis=-1)
        reliable = np.ones(len(truth), bool)
        if source.clamp_level is not None:
            reliable = truth < 0.5 * source.clamp_level * pair.exposure
        target = np.log2(np.maximum(truth, 1e-3))
        pick = rng.permutation(np.flatnonzero(reliable))[:per_crop]
        xs.append(feats.features[pick])
        ys.append(target[pick])
        area = np.exp2(feats.features[pick, FEATURES.index("log_area")])
        ws.append(1.0 / np.sqrt(area))
    w = np.concatenate(ws)
    return np.concatenate(xs), np.concatenate(ys), w / w.mean(), [s.name for s in sources]


def fit(x: np.ndarray, y: np.ndarray, w: np.ndarray, seed: int, hidden: int = 16,
        iters: int = 1500, batch: int = 4096) -> dict:
    import torch

    torch.manual_seed(seed)
    mean, std = x.mean(0), x.std(0) + 1e-6
    mean[-1], std[-1] = 0.0, 1.0  # the constant feature stays 1
    xt = torch.tensor((x - mean) / std, dtype=torch.float32)
    yt = torch.tensor(y, dtype=torch.float32)
    wt = torch.tensor(w, dtype=torch.float32)
    net = torch.nn.Sequential(torch.nn.Linear(x.shape[1], hidden), torch.nn.Tanh(),
                              torch.nn.Linear(hidden, hidden), torch.nn.Tanh(),
                              torch.nn.Linear(hidden, 1))
    opt = torch.optim.Adam(net.parameters(), lr=1e-2)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, iters)
    gen = torch.Generator().manual_seed(seed)
    for _ in range(iters):
        idx = torch.randint(0, len(yt), (batch,), generator=gen)
        opt.zero_grad()
        pred = torch.nn.functional.softplus(net(xt[idx])[:, 0])
        loss = torch.mean(wt[idx] * (pred - yt[idx]) ** 2)
        loss.backward()
        opt.step()
        sched.step()
    with torch.no_grad():
        rmse = float(torch.sqrt(torch.mean(
            (torch.nn.functional.softplus(net(xt)[:, 0]) - yt) ** 2)))
    linears = [m for m in net if isinstance(m, torch.nn.Linear)]
    return {"mean": mean.tolist(), "std": std.tolist(),
            "layers": [[m.weight.detach().numpy().T.round(6).tolist(),
                        m.bias.detach().numpy().round(6).tolist()] for m in linears],
            "train_rmse_stops": rmse}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hdri", type=Path, default=None,
                    help="folder of HDR panoramas (default: the shared data set)")
    ap.add_argument("--holdout", nargs="*", default=["sunset"])
    ap.add_argument("--crops", type=int, default=400)
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("-o", "--output", type=Path, default=PARAMS_FILE)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    x, y, w, names = collect(args.hdri, args.holdout, args.crops, args.seed)
    print(f"collected {len(y)} clipped pixels in {time.perf_counter() - t0:.0f} s")
    model = fit(x, y, w, args.seed)
    params = {"features": list(FEATURES), "model": model,
              "calibration": {"command": "python -m gaslight_usd.uplift.calibrate "
                              f"--crops {args.crops} --seed {args.seed} --holdout "
                              + " ".join(args.holdout),
                              "panoramas": names, "holdout": args.holdout,
                              "pixels": int(len(y)), "seconds": round(time.perf_counter() - t0)}}
    args.output.write_text(json.dumps(params, separators=(",", ":")))
    print(f"trained on {len(y)} clipped pixels from {names}: "
          f"rmse {model['train_rmse_stops']:.2f} stops -> {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
