"""Calibrate (train) the fast predictor on real HDR panoramas, reproducibly.

    python -m gaslight_usd.uplift.calibrate [--hdri DIR] [--holdout sunset]
        [--crops 300] [--seed 1000] [-o PARAMS.json]

Pairs come from the evaluation's reference builder
(:func:`gaslight_usd.evaluation.reference.make_pair`: 256 x 192 perspective
crops of the shared panoramas, half aimed at the light, metered exposures,
sRGB / gamma 2.2 / filmic camera curves, 8 bits), with a seed the benchmark
does not use (the bench uses seed 0). ``studio`` is never used (its lamps are
clamped flat); the held-out panoramas are only used to report generalisation.

Loss: the relighting error of the predictor's own rendering rule. The
relight render (:mod:`gaslight_usd.evaluation.relight`, here at 64 x 64,
16 spp) is linear in the light, and the renderer is grey, so for every crop
we render the truth, the photo as it is (the baseline, with the pixels where
only some channels clip filled by the predictor's bounded rule at the true
mean), and, for its largest clipped regions (the two largest, then the rest
together) and every profile shape of :data:`.fast_predictor.PROFILES`, the
shape itself in grey at unit energy over the pixels whose channels all clip.
A prediction (region mean ``m_r``, profile mix ``a_rk``, ring colour share
``b_r``) then renders as ``baseline + sum_gk sum_{r in g} E_r a_rk
(b_r ring_g + 1 - b_r) unit_gk`` with ``E_r = area_r (min(m_r, cap) - 1)``,
and the protocol's comparison (normalise by the truth's 99th percentile,
align exposure on truth pixels in [0.2, 0.8], clip to [0, 1], MSE, PSNR) is
differentiable in the prediction. The model (:class:`.fast_predictor.Mlp`,
15-H-H-(1 + K + 1), tanh) is first fitted to the regions' true ``log2``
means (squared error, weighted by sqrt area), then to the mean relight PSNR
over the crops (plus a log-error term that keeps every region's estimate
honest when several share one render). Seeded, CPU; it prints train and
held-out relight PSNR against the baseline, and with ``--lopo`` the
leave-one-panorama-out PSNR (each training panorama predicted by a model
fitted without it).
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
from .fast_predictor import (
    CLIP,
    FEATURES,
    PARAMS_FILE,
    PROFILES,
    fill_clipped,
    peak_cap,
    profile_weights,
    region_features,
    spread,
)

EXCLUDED = ("studio",)
GROUPS = 3
"""Regions rendered separately: the two largest, then all others together."""
SHRINKS = (0.4, 0.55, 0.7, 0.85)
"""Shrink factors scored beside the raw model (the predictor uses
:data:`.fast_predictor.SHRINK`)."""
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
    log_cap: np.ndarray
    """(R,) log2 of the peak cap of the region's curve"""
    slot: np.ndarray
    """(R,) crop index * GROUPS + group of every region"""
    truth: np.ndarray
    """(C, P, 3) truth render, normalised by its 99th-percentile luminance"""
    base: np.ndarray
    """(C, P, 3) baseline render (partly clipped pixels filled), same normalisation"""
    units: np.ndarray
    """(C, GROUPS, K, P) grey render of unit energy of each group and profile"""
    ring: np.ndarray
    """(C, GROUPS, 3) ring chromaticity of each group (energy-weighted over its regions)"""
    align: np.ndarray
    """(C, P) bool: truth pixels used for exposure alignment"""
    names: list[str]


def _render(renderer: RelightRenderer, image: np.ndarray) -> np.ndarray:
    return renderer.render(image, "perspective").reshape(-1, 3)


def _crop_inputs(pair, renderer: RelightRenderer) -> tuple | None:
    """One crop's regions, truths and renders, or None when nothing (or everything) clips."""
    from ..evaluation.metrics import luminance

    curve = evaluation_curve(pair.curve)
    linear = curve.to_linear(pair.ldr)
    regions = region_features(linear, pair.ldr)
    if regions is None or regions.mask.all():
        return None
    count = len(regions.area)
    labels = regions.labels
    lab = labels[regions.mask] - 1
    truth_max = pair.truth.max(axis=-1)
    mean_truth = np.bincount(lab, weights=truth_max[regions.mask], minlength=count) / regions.area
    log_mean = np.log2(np.maximum(mean_truth, 1.0))
    rank = np.empty(count, np.int64)
    rank[np.argsort(-regions.area, kind="stable")] = np.arange(count)
    group = np.minimum(rank, GROUPS - 1)
    cap = peak_cap(curve)
    # the baseline as the predictor leaves it when the means are right: partly clipped
    # pixels get their bounded values (all-clipped pixels are the units' business)
    value = spread(regions, log_mean, cap)
    filled = fill_clipped(linear, pair.ldr, regions, value)
    all_clipped = regions.mask & (pair.ldr.min(axis=-1) >= CLIP)
    base = np.where(all_clipped[..., None], linear, filled)
    # true excess energy of every region: how the "rest" group shares its unit
    excess = np.bincount(lab, weights=np.maximum(truth_max[regions.mask] - 1.0, 0.0),
                         minlength=count)
    rt = _render(renderer, pair.truth)
    yt = luminance(rt)
    white = float(np.percentile(yt, 99.0)) or float(yt.max()) or 1.0
    align = (yt >= 0.2 * white) & (yt <= 0.8 * white)
    if np.count_nonzero(align) < 16:
        align = yt > 0
    units = np.zeros((GROUPS, len(PROFILES), len(yt)), np.float32)
    ring = np.ones((GROUPS, 3), np.float32)
    keep = all_clipped[regions.mask]
    for g in range(GROUPS):
        members = group == g
        if not members.any():
            continue
        share = np.where(members, np.maximum(excess, 1e-6 * regions.area), 0.0)
        share = share / share.sum()
        ring[g] = share @ regions.chroma
        for k in range(len(PROFILES)):
            mix = np.zeros((count, len(PROFILES)))
            mix[:, k] = 1.0
            w = profile_weights(regions, mix) / regions.area[lab]  # unit energy per region
            grey = np.zeros(regions.mask.shape, np.float32)
            grey[regions.mask] = np.where(keep, share[lab] * w, 0.0)
            if grey.any():
                units[g, k] = _render(renderer, np.repeat(grey[..., None], 3, axis=-1))[:, 0]
    return (regions.features, log_mean, regions.area, np.full(count, np.log2(cap)), group,
            rt / white, _render(renderer, base) / white, units / white, ring, align)


def collect(sources: list, crops: int, seed: int) -> CropSet:
    """Regions, their truths and the relight renders of ``crops`` pairs (skipping unclipped)."""
    renderer = RelightRenderer(seed=seed, **RENDER)
    per_crop, names = [], []
    for i in range(crops):
        pair = make_pair(sources[i % len(sources)], i, seed)
        inputs = _crop_inputs(pair, renderer)
        if inputs is not None:
            per_crop.append(inputs)
            names.append(pair.name)
    feats, ys, areas, caps, groups, rt, rb, ru, ring, align = zip(*per_crop, strict=True)
    slots = [c * GROUPS + g for c, g in enumerate(groups)]
    return CropSet(np.concatenate(feats), np.concatenate(ys).astype(np.float32),
                   np.concatenate(areas).astype(np.float32),
                   np.concatenate(caps).astype(np.float32), np.concatenate(slots),
                   np.stack(rt), np.stack(rb), np.stack(ru), np.stack(ring), np.stack(align),
                   names)


def subset(data: CropSet, crops: np.ndarray) -> CropSet:
    """The crops ``crops`` (bool per crop) of ``data``, regions renumbered."""
    crops = np.asarray(crops, bool)
    region_crop = data.slot // GROUPS
    keep = crops[region_crop]
    new_index = np.cumsum(crops) - 1
    slot = new_index[region_crop[keep]] * GROUPS + data.slot[keep] % GROUPS
    return CropSet(data.features[keep], data.log_mean[keep], data.area[keep],
                   data.log_cap[keep], slot, data.truth[crops], data.base[crops],
                   data.units[crops], data.ring[crops], data.align[crops],
                   [n for n, c in zip(data.names, crops, strict=True) if c])


def relight_psnr(data: CropSet, log_mean, mix=None, ring_share=None):
    """Per-crop relight PSNR (dB) of region predictions (numpy or torch).

    ``log_mean`` (R,); ``mix`` (R, K) profile weights (default: the cone);
    ``ring_share`` (R,) (default 1: the ring's colour).
    """
    import torch

    t = {k: torch.as_tensor(getattr(data, k)) for k in ("area", "truth", "base", "units",
                                                       "ring", "align", "log_cap")}
    slot = torch.as_tensor(data.slot)
    log_mean = torch.as_tensor(log_mean, dtype=torch.float32)
    regions, k_count = len(log_mean), len(PROFILES)
    if mix is None:
        mix = torch.zeros(regions, k_count)
        mix[:, PROFILES.index(1.0)] = 1.0
    mix = torch.as_tensor(mix, dtype=torch.float32)
    share = torch.ones(regions) if ring_share is None else torch.as_tensor(
        ring_share, dtype=torch.float32)
    crops = t["truth"].shape[0]
    energy = t["area"] * (torch.exp2(torch.minimum(log_mean, t["log_cap"])) - 1.0)
    coef = energy[:, None] * mix  # (R, K)
    ring_coef = torch.zeros(crops * GROUPS, k_count).index_add(0, slot, coef * share[:, None])
    white_coef = torch.zeros(crops * GROUPS, k_count).index_add(
        0, slot, coef * (1.0 - share[:, None]))
    ring_coef = ring_coef.view(crops, GROUPS, k_count)
    white_coef = white_coef.view(crops, GROUPS, k_count)
    ring_light = torch.einsum("cgk,cgkp->cgp", ring_coef, t["units"])
    white_light = torch.einsum("cgk,cgkp->cp", white_coef, t["units"])
    pred = (t["base"] + torch.einsum("cgp,cgd->cpd", ring_light, t["ring"])
            + white_light[..., None])
    lum = torch.tensor([0.2126, 0.7152, 0.0722])
    yt = (t["truth"] * lum).sum(-1)
    yp = (pred * lum).sum(-1)
    m = t["align"].float()
    scale = (yt * m).sum(1) / (yp * m).sum(1).clamp_min(1e-12)
    p = (pred * scale[:, None, None]).clamp(0.0, 1.0)
    mse = ((p - t["truth"].clamp(0.0, 1.0)) ** 2).mean((1, 2))
    return -10.0 * torch.log10(mse.clamp_min(1e-10))


def fit(data: CropSet, seed: int, hidden: int = 12, pre_iters: int = 300,
        iters: int = 400, log_weight: float = 0.3, shape_heads: bool = True) -> dict:
    """Fit the perceptron to ``data``; see the module doc.

    ``shape_heads`` False: the mean alone (cones in the ring's colour).
    """
    import torch

    torch.manual_seed(seed)
    torch.set_num_threads(1)  # small tensors: one thread is 2-3x faster than two here
    x = data.features
    mean, std = x.mean(0), x.std(0) + 1e-6
    mean[-1], std[-1] = 0.0, 1.0  # the constant feature stays 1
    xt = torch.tensor((x - mean) / std, dtype=torch.float32)
    yt = torch.tensor(data.log_mean)
    wt = torch.sqrt(torch.tensor(data.area))
    wt = wt / wt.mean()
    k_count = len(PROFILES)
    net = torch.nn.Sequential(torch.nn.Linear(x.shape[1], hidden), torch.nn.Tanh(),
                              torch.nn.Linear(hidden, hidden), torch.nn.Tanh(),
                              torch.nn.Linear(hidden, 2 + k_count if shape_heads else 1))
    cone = torch.zeros(len(xt), k_count)
    cone[:, PROFILES.index(1.0)] = 1.0

    def heads():
        h = net(xt)
        if not shape_heads:
            return torch.nn.functional.softplus(h[:, 0]), cone, torch.ones(len(xt))
        return (torch.nn.functional.softplus(h[:, 0]), torch.softmax(h[:, 1:1 + k_count], 1),
                torch.sigmoid(h[:, 1 + k_count]))

    opt = torch.optim.Adam(net.parameters(), lr=1e-2, weight_decay=1e-4)
    for _ in range(pre_iters):
        opt.zero_grad()
        loss = torch.mean(wt * (heads()[0] - yt) ** 2)
        loss.backward()
        opt.step()
    opt = torch.optim.Adam(net.parameters(), lr=3e-3, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, iters)
    for _ in range(iters):
        opt.zero_grad()
        log_mean, mix, share = heads()
        loss = (-relight_psnr(data, log_mean, mix, share).mean()
                + log_weight * torch.mean(wt * (log_mean - yt) ** 2))
        loss.backward()
        opt.step()
        sched.step()
    with torch.no_grad():
        rmse = float(torch.sqrt(torch.mean((heads()[0] - yt) ** 2)))
    linears = [m for m in net if isinstance(m, torch.nn.Linear)]
    return {"mean": mean.tolist(), "std": std.tolist(),
            "layers": [[m.weight.detach().numpy().T.round(6).tolist(),
                        m.bias.detach().numpy().round(6).tolist()] for m in linears],
            "profiles": list(PROFILES), "train_rmse_stops": rmse}


def scores(data: CropSet, model_params: dict) -> dict[str, np.ndarray]:
    """Per-crop relight PSNR of the model (also with its log2 means times each of
    :data:`SHRINKS`, see :data:`.fast_predictor.SHRINK`), the baseline and the true means."""
    from .fast_predictor import Mlp

    log_mean, mix, share = Mlp(model_params).heads(data.features)
    shrunk = {f"fast x{a}": relight_psnr(data, a * log_mean, mix, share).numpy()
              for a in SHRINKS}
    return {**shrunk, "fast": relight_psnr(data, log_mean, mix, share).numpy(),
            "baseline": relight_psnr(data, np.zeros_like(log_mean)).numpy(),
            "true_means": relight_psnr(data, data.log_mean, mix, share).numpy(),
            "true_means_cone_ring": relight_psnr(data, data.log_mean).numpy()}


def summary(label: str, per_crop: dict[str, np.ndarray]) -> dict:
    """Mean/median of per-crop scores and of the gain over the baseline, printed."""
    out = {name: {"mean": round(float(s.mean()), 2), "median": round(float(np.median(s)), 2)}
           for name, s in per_crop.items()}
    gain = per_crop["fast"] - per_crop["baseline"]
    out["gain"] = {"mean": round(float(gain.mean()), 2),
                   "median": round(float(np.median(gain)), 2),
                   "worst": round(float(gain.min()), 2)}
    out["crops"] = len(gain)
    print(f"{label}: {len(gain)} clipped crops, relight PSNR (64 px) " + ", ".join(
        f"{k} {v['mean']:.2f}/{v['median']:.2f}" for k, v in out.items() if k != "crops")
          + " (mean/median dB)")
    return out


def report(label: str, data: CropSet, model_params: dict) -> dict:
    """Mean/median relight PSNR of the model, the baseline and the true means on ``data``."""
    return summary(label, scores(data, model_params))


def leave_one_out(data: CropSet, seed: int, shape_heads: bool = True) -> dict:
    """Each panorama of ``data`` scored by a model fitted on the others."""
    panorama = np.array([n.rsplit("-", 1)[0] for n in data.names])
    pooled: dict[str, list[np.ndarray]] = {}
    out = {}
    for name in sorted(set(panorama)):
        model = fit(subset(data, panorama != name), seed, shape_heads=shape_heads)
        per_crop = scores(subset(data, panorama == name), model)
        out[name] = summary(f"  left out {name}", per_crop)
        for k, v in per_crop.items():
            pooled.setdefault(k, []).append(v)
    out["all"] = summary("leave-one-panorama-out, pooled",
                         {k: np.concatenate(v) for k, v in pooled.items()})
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
    ap.add_argument("--mean-only", action="store_true",
                    help="fit the mean alone (cones in the ring's colour, no shape heads)")
    ap.add_argument("--lopo", action="store_true",
                    help="also report leave-one-panorama-out scores (one fit per panorama)")
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
    model = fit(train, args.seed, shape_heads=not args.mean_only)
    results = {"train": report("train", train, model)}
    if held is not None:
        results["holdout"] = report("held out " + "+".join(args.holdout), held, model)
    if args.lopo:
        results["leave_one_panorama_out"] = leave_one_out(train, args.seed, not args.mean_only)
    params = {"features": list(FEATURES), "model": model,
              "calibration": {"command": "python -m gaslight_usd.uplift.calibrate "
                              f"--crops {args.crops} --seed {args.seed} --holdout "
                              + " ".join(args.holdout) + (" --mean-only" if args.mean_only else "")
                              + (" --lopo" if args.lopo else ""),
                              "panoramas": [s.name for s in train_src],
                              "holdout": args.holdout, "regions": int(len(train.log_mean)),
                              "relight_psnr_64px": results,
                              "seconds": round(time.perf_counter() - t0)}}
    args.output.write_text(json.dumps(params, separators=(",", ":")))
    print(f"-> {args.output} ({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
