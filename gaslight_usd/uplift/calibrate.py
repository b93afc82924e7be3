"""Calibrate (train) the fast predictor on real HDR panoramas, reproducibly.

    python -m gaslight_usd.uplift.calibrate [--hdri DIR] [--holdout sunset]
        [--crops 300] [--seed 1000] [-o PARAMS.json]

Pairs come from the evaluation's reference builder
(:func:`gaslight_usd.evaluation.reference.make_pair`: 256 x 192 perspective
crops of the shared panoramas, half aimed at the light, metered exposures,
sRGB / gamma 2.2 / filmic camera curves, 8 bits), with a seed the benchmark
does not use (the bench uses seed 0). ``studio`` is never used (its lamps are
clamped flat); the held-out panoramas are only used to report generalisation.

Loss: the relighting error itself. The relight render
(:mod:`gaslight_usd.evaluation.relight`, here at 64 x 64, 16 spp) is linear in
the light, so for every crop we render the truth, the photo as it is (the
baseline) and, for its largest clipped regions (the three largest, then the
rest together), the region's true excess over white normalised to unit
energy. A prediction of region means ``m_r`` then renders as
``baseline + sum_g E_g unit_g`` with ``E_g = sum_{r in g} area_r (m_r - 1)``,
and the protocol's comparison (normalise by the truth's 99th percentile,
align exposure on truth pixels in [0.2, 0.8], clip to [0, 1], MSE, PSNR) is
differentiable in the prediction. The model (:class:`.fast_predictor.Mlp`,
15-8-8-1, tanh, softplus) is first fitted to the regions' true ``log2``
means (squared error, weighted by sqrt area), then to the mean relight PSNR
over the crops (plus a log-error term of equal weight that keeps every region's
estimate honest when several share one render). Seeded, CPU, a few minutes
on 2 busy cores; it prints train and held-out relight PSNR against the
baseline.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..evaluation import curves as camera_curves
from ..evaluation.reference import make_pair, shared_sources
from ..evaluation.relight import RelightRenderer
from .curves import Curve, lut_curve
from .fast_predictor import FEATURES, PARAMS_FILE, region_features

EXCLUDED = ("studio",)
GROUPS = 4
"""Regions rendered separately: the three largest, then all others together."""
RENDER = {"resolution": 64, "spp": 16, "env_height": 128}


@lru_cache(maxsize=8)
def evaluation_curve(name: str) -> Curve:
    """One of the evaluation's camera curves (srgb, gamma2.2, filmic) as a fast table."""
    levels = np.linspace(0.0, 1.0, 4097, dtype=np.float32)
    return lut_curve(name, levels, camera_curves.decode(levels, name))


@dataclass
class CropSet:
    """Everything the relight loss needs, for many crops."""

    features: np.ndarray
    """(R, F) features of every region of every crop"""
    log_mean: np.ndarray
    """(R,) true log2 mean brightest channel of every region"""
    area: np.ndarray
    """(R,) pixel count of every region"""
    slot: np.ndarray
    """(R,) crop index * GROUPS + group of every region"""
    truth: np.ndarray
    """(C, P) truth render, normalised by its 99th-percentile luminance"""
    base: np.ndarray
    """(C, P) baseline render, same normalisation"""
    units: np.ndarray
    """(C, GROUPS, P) render of unit excess energy of each group, same normalisation"""
    align: np.ndarray
    """(C, P / 3) bool: truth pixels used for exposure alignment"""
    names: list[str]


def _relight_inputs(renderer: RelightRenderer, truth: np.ndarray, base: np.ndarray,
                    units: list[np.ndarray]) -> tuple[np.ndarray, ...]:
    from ..evaluation.metrics import luminance

    rt = renderer.render(truth, "perspective")
    yt = luminance(rt)
    white = float(np.percentile(yt, 99.0)) or float(yt.max()) or 1.0
    mask = (yt >= 0.2 * white) & (yt <= 0.8 * white)
    if np.count_nonzero(mask) < 16:
        mask = yt > 0
    rb = renderer.render(base, "perspective")
    ru = np.zeros((GROUPS, *rt.shape), np.float32)
    for g, unit in enumerate(units):
        if unit is not None:
            ru[g] = renderer.render(unit, "perspective")
    return (rt.reshape(-1) / white, rb.reshape(-1) / white,
            ru.reshape(GROUPS, -1) / white, mask.reshape(-1))


def collect(sources: list, crops: int, seed: int) -> CropSet:
    """Regions, their truths and the relight renders of ``crops`` pairs (skipping unclipped)."""
    renderer = RelightRenderer(seed=seed, **RENDER)
    feats, ys, areas, slots, renders, names = [], [], [], [], [], []
    for i in range(crops):
        source = sources[i % len(sources)]
        pair = make_pair(source, i, seed)
        curve = evaluation_curve(pair.curve)
        linear = curve.to_linear(pair.ldr)
        regions = region_features(linear, pair.ldr)
        if regions is None or regions.mask.all():
            continue
        count = len(regions.area)
        labels = regions.labels
        truth_max = pair.truth.max(axis=-1)
        mean_truth = np.bincount(labels.ravel(), weights=truth_max.ravel(),
                                 minlength=count + 1)[1:] / regions.area
        rank = np.empty(count, np.int64)
        rank[np.argsort(-regions.area, kind="stable")] = np.arange(count)
        group = np.minimum(rank, GROUPS - 1)
        excess = np.where(regions.mask[..., None], np.maximum(pair.truth - linear, 0.0), 0.0)
        units = []
        pixel_group = np.where(regions.mask, group[np.maximum(labels - 1, 0)], -1)
        for g in range(GROUPS):
            sel = pixel_group == g
            if not sel.any():
                units.append(None)
                continue
            energy = float(excess.max(axis=-1)[sel].sum())
            if energy > 1e-3 * sel.sum():
                unit = np.where(sel[..., None], excess, 0.0) / energy
            else:  # no true excess: a uniform white unit
                unit = np.where(sel[..., None], 1.0, 0.0) / sel.sum()
            units.append(unit.astype(np.float32))
        c = len(names)
        renders.append(_relight_inputs(renderer, pair.truth, linear, units))
        feats.append(regions.features)
        ys.append(np.log2(np.maximum(mean_truth, 1.0)))
        areas.append(regions.area)
        slots.append(c * GROUPS + group)
        names.append(pair.name)
    rt, rb, ru, mask = (np.stack(a) for a in zip(*renders, strict=True))
    return CropSet(np.concatenate(feats), np.concatenate(ys).astype(np.float32),
                   np.concatenate(areas).astype(np.float32), np.concatenate(slots), rt, rb,
                   ru, mask, names)


def relight_psnr(data: CropSet, log_mean):
    """Per-crop relight PSNR (dB) of region predictions ``log_mean`` (numpy or torch)."""
    import torch

    t = {k: torch.as_tensor(getattr(data, k)) for k in ("area", "truth", "base", "units",
                                                       "align")}
    slot = torch.as_tensor(data.slot)
    log_mean = torch.as_tensor(log_mean, dtype=torch.float32)
    crops = t["truth"].shape[0]
    energy = torch.zeros(crops * GROUPS).index_add(
        0, slot, t["area"] * (torch.exp2(log_mean) - 1.0)).view(crops, GROUPS)
    pred = t["base"] + torch.einsum("cg,cgp->cp", energy, t["units"])
    lum = torch.tensor([0.2126, 0.7152, 0.0722])
    yt = (t["truth"].view(crops, -1, 3) * lum).sum(-1)
    yp = (pred.view(crops, -1, 3) * lum).sum(-1)
    m = t["align"].float()
    scale = (yt * m).sum(1) / (yp * m).sum(1).clamp_min(1e-12)
    p = (pred * scale[:, None]).clamp(0.0, 1.0)
    mse = ((p - t["truth"].clamp(0.0, 1.0)) ** 2).mean(1)
    return -10.0 * torch.log10(mse.clamp_min(1e-10))


def fit(data: CropSet, seed: int, hidden: int = 8, pre_iters: int = 300,
        iters: int = 300, log_weight: float = 1.0) -> dict:
    import torch

    torch.manual_seed(seed)
    x = data.features
    mean, std = x.mean(0), x.std(0) + 1e-6
    mean[-1], std[-1] = 0.0, 1.0  # the constant feature stays 1
    xt = torch.tensor((x - mean) / std, dtype=torch.float32)
    yt = torch.tensor(data.log_mean)
    wt = torch.sqrt(torch.tensor(data.area))
    wt = wt / wt.mean()
    net = torch.nn.Sequential(torch.nn.Linear(x.shape[1], hidden), torch.nn.Tanh(),
                              torch.nn.Linear(hidden, hidden), torch.nn.Tanh(),
                              torch.nn.Linear(hidden, 1))

    def predict():
        return torch.nn.functional.softplus(net(xt)[:, 0])

    opt = torch.optim.Adam(net.parameters(), lr=1e-2, weight_decay=1e-4)
    for _ in range(pre_iters):
        opt.zero_grad()
        loss = torch.mean(wt * (predict() - yt) ** 2)
        loss.backward()
        opt.step()
    opt = torch.optim.Adam(net.parameters(), lr=3e-3, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, iters)
    for _ in range(iters):
        opt.zero_grad()
        pred = predict()
        loss = -relight_psnr(data, pred).mean() + log_weight * torch.mean(wt * (pred - yt) ** 2)
        loss.backward()
        opt.step()
        sched.step()
    with torch.no_grad():
        rmse = float(torch.sqrt(torch.mean((predict() - yt) ** 2)))
    linears = [m for m in net if isinstance(m, torch.nn.Linear)]
    return {"mean": mean.tolist(), "std": std.tolist(),
            "layers": [[m.weight.detach().numpy().T.round(6).tolist(),
                        m.bias.detach().numpy().round(6).tolist()] for m in linears],
            "train_rmse_stops": rmse}


def report(label: str, data: CropSet, model_params: dict) -> dict:
    """Mean/median relight PSNR of the model, the baseline and the true means on ``data``."""
    from .fast_predictor import Mlp

    pred = Mlp(model_params)(data.features)
    scores = {name: relight_psnr(data, values).numpy() for name, values in (
        ("fast", pred), ("baseline", np.zeros_like(pred)), ("true_means", data.log_mean))}
    out = {name: {"mean": round(float(s.mean()), 2), "median": round(float(np.median(s)), 2)}
           for name, s in scores.items()}
    gain = scores["fast"] - scores["baseline"]
    out["gain"] = {"mean": round(float(gain.mean()), 2), "median": round(float(np.median(gain)),
                                                                        2),
                   "worst": round(float(gain.min()), 2)}
    out["crops"] = len(data.names)
    print(f"{label}: {len(data.names)} clipped crops, relight PSNR (64 px) " + ", ".join(
        f"{k} {v['mean']:.2f}/{v['median']:.2f}" for k, v in out.items() if k != "crops")
          + " (mean/median dB)")
    return out


def _collect_cached(cache: Path | None, train_src: list, held_src: list,
                    args: argparse.Namespace) -> tuple[CropSet, CropSet | None]:
    """Collect both sets, or load them from ``cache`` (written after collecting)."""
    if cache is not None and cache.exists():
        with np.load(cache, allow_pickle=False) as z:
            sets = [CropSet(**{k: z[f"{p}{k}"] for k in CropSet.__dataclass_fields__
                               if k != "names"}, names=list(z[f"{p}names"]))
                    if f"{p}truth" in z else None for p in ("train_", "held_")]
        return sets[0], sets[1]
    train = collect(train_src, args.crops, args.seed)
    held = collect(held_src, args.holdout_crops, args.seed) if held_src else None
    if cache is not None:
        arrays = {}
        for p, data in (("train_", train), ("held_", held)):
            if data is not None:
                arrays.update({f"{p}{k}": np.asarray(getattr(data, k))
                               for k in CropSet.__dataclass_fields__})
        np.savez(cache, **arrays)
    return train, held


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hdri", type=Path, default=None,
                    help="folder of HDR panoramas (default: the shared data set)")
    ap.add_argument("--holdout", nargs="*", default=["sunset"])
    ap.add_argument("--crops", type=int, default=300)
    ap.add_argument("--holdout-crops", type=int, default=60)
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("-o", "--output", type=Path, default=PARAMS_FILE)
    ap.add_argument("--cache", type=Path, default=None,
                    help="keep the collected crops in this .npz (reused when it exists)")
    args = ap.parse_args(argv)
    if args.seed == 0:
        ap.error("seed 0 makes the benchmark's crops: calibrate on another seed")
    t0 = time.perf_counter()
    sources = shared_sources(args.hdri)
    train_src = [s for s in sources if s.name not in EXCLUDED + tuple(args.holdout)]
    held_src = [s for s in sources if s.name in args.holdout]
    train, held = _collect_cached(args.cache, train_src, held_src, args)
    print(f"collected {len(train.names)} crops ({len(train.log_mean)} regions) "
          f"in {time.perf_counter() - t0:.0f} s")
    model = fit(train, args.seed)
    scores = {"train": report("train", train, model)}
    if held is not None:
        scores["holdout"] = report("held out " + "+".join(args.holdout), held, model)
    params = {"features": list(FEATURES), "model": model,
              "calibration": {"command": "python -m gaslight_usd.uplift.calibrate "
                              f"--crops {args.crops} --seed {args.seed} --holdout "
                              + " ".join(args.holdout),
                              "panoramas": [s.name for s in train_src],
                              "holdout": args.holdout, "regions": int(len(train.log_mean)),
                              "relight_psnr_64px": scores,
                              "seconds": round(time.perf_counter() - t0)}}
    args.output.write_text(json.dumps(params, separators=(",", ":")))
    print(f"-> {args.output} ({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
