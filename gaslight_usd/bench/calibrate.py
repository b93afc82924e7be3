"""Calibrate (train) the fast predictor on real HDR panoramas, reproducibly.

    python -m gaslight_usd.bench.calibrate [--hdri DIR | --panoramas NAME ...]
        [--crops 600] [--seed 1000] [--clamped-weight 0] [--no-light-weight 1]
        [--exclude NAME ...] [--cache CROPS.npz] [--no-lopo] [-o PARAMS.json]

Panoramas: both shared folders, named, trusted or not and weighted as
:data:`gaslight_usd.evaluation.shared_panoramas.PANORAMAS` says (crops that
hold a clamped source pixel have too dark a truth: weight ``--clamped-weight``;
panoramas with no light source: ``--no-light-weight``). The reported number is
leave-one-panorama-out (LOPO): every panorama's trusted crops scored by a
model fitted without that panorama, pooled per folder and over all; the
shipped model is fitted on all of them, and the LOPO models are written beside
it (:data:`.fast_predictor.LOPO_FILE`) for the bench's ``recursive-fast-lopo``.

Pairs come from the evaluation's reference builder
(:func:`gaslight_usd.evaluation.reference.make_pair`: 256 x 192 perspective
crops of the shared panoramas, half aimed at the light, metered exposures,
sRGB / gamma 2.2 / filmic camera curves, 8 bits), with a seed the benchmark
does not use (the bench uses seed 0).

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
honest when several share one render), each crop weighted as above. Seeded,
CPU; it prints the relight PSNR against the baseline on the fitted crops and
leave-one-panorama-out.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..atomic import atomic_path, write_text
from ..colour import CLIP_LEVEL, REC709_Y
from ..evaluation import curves as camera_curves
from ..evaluation.reference import make_pair, shared_sources
from ..evaluation.relight import RelightRenderer
from ..evaluation.shared_panoramas import BY_NAME, NO_LIGHT, TRUSTED, folder_of, load_shared
from ..uplift.curves import Curve, lut_curve
from ..uplift.fast_predictor import (
    FEATURES,
    LEGACY_FEATURES,
    LOPO_FILE,
    PARAMS_FILE,
    PROFILES,
    SHRINK,
    fill_clipped,
    peak_cap,
    profile_weights,
    region_features,
    spread,
)

DEFAULT_CROPS = 600
DEFAULT_FEATURES: tuple[str, ...] = LEGACY_FEATURES
"""The features the shipped model uses. The four later ones of
:data:`.fast_predictor.FEATURES` (``--features`` with all of them) did not raise the
leave-one-panorama-out gain over these, so the model keeps the fifteen."""
DEFAULT_EXCLUDE: tuple[str, ...] = ()
"""Panoramas never fitted on by default (clamped crops are weighted instead)."""
DEFAULT_WEIGHTS = {"clamped": 0.0, "no_light": 1.0}
"""Crop weights by the panorama table (:func:`crop_weights`), chosen by the
leave-one-panorama-out score."""
GROUPS = 3
"""Regions rendered separately: the two largest, then all others together."""
SHRINKS = (0.4, 0.55, 0.7, 0.85, 1.0)
"""Shrink factors scored beside the shipped one (:data:`.fast_predictor.SHRINK`)."""
RENDER = {"resolution": 64, "spp": 16, "env_height": 128}
FIT_PIXELS = 512
"""Relight pixels per crop in the fitting loss (of 64 x 64); scores use them all."""


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
    trusted: np.ndarray
    """(C,) bool: the crop holds no clamped source pixel (its light truth is good)"""
    names: list[str]

    @property
    def panoramas(self) -> np.ndarray:
        """(C,) the panorama of every crop (its name without the index)."""
        return np.array([n.rsplit("-", 1)[0] for n in self.names])


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
    all_clipped = regions.mask & (pair.ldr.min(axis=-1) >= CLIP_LEVEL)
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
    per_crop, names, trusted = [], [], []
    for i in range(crops):
        pair = make_pair(sources[i % len(sources)], i, seed)
        inputs = _crop_inputs(pair, renderer)
        if inputs is not None:
            per_crop.append(inputs)
            names.append(pair.name)
            trusted.append(pair.light_truth)
    feats, ys, areas, caps, groups, rt, rb, ru, ring, align = zip(*per_crop, strict=True)
    slots = [c * GROUPS + g for c, g in enumerate(groups)]
    return CropSet(np.concatenate(feats), np.concatenate(ys).astype(np.float32),
                   np.concatenate(areas).astype(np.float32),
                   np.concatenate(caps).astype(np.float32), np.concatenate(slots),
                   np.stack(rt), np.stack(rb), np.stack(ru), np.stack(ring), np.stack(align),
                   np.asarray(trusted, bool), names)


def refresh_features(data: CropSet, sources: list, seed: int) -> CropSet:
    """``data`` with every region's features recomputed (all of :data:`FEATURES`) from
    its crop, rebuilt from ``sources`` by name: a cache made before a feature was
    added stays usable without its renders being made again."""
    by_name = {s.name: s for s in sources}
    feats = []
    for name in data.names:
        panorama, index = name.rsplit("-", 1)
        pair = make_pair(by_name[panorama], int(index), seed)
        curve = evaluation_curve(pair.curve)
        feats.append(region_features(curve.to_linear(pair.ldr), pair.ldr).features)
    features = np.concatenate(feats)
    if len(features) != len(data.log_mean):
        raise ValueError("the cached crops do not match their sources (region count differs)")
    return CropSet(features, *(getattr(data, k) for k in list(CropSet.__dataclass_fields__)[1:]))


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
                   data.trusted[crops], [n for n, c in zip(data.names, crops, strict=True) if c])


def pixel_subset(data: CropSet, count: int, seed: int) -> CropSet:
    """``data`` with its relight renders cut to ``count`` pixels (the same, seeded, in
    every crop): the loss's sample mean; fitting takes P / count times less time."""
    pixels = data.truth.shape[1]
    if count <= 0 or count >= pixels:
        return data
    keep = np.sort(np.random.default_rng(seed).choice(pixels, count, replace=False))
    return CropSet(data.features, data.log_mean, data.area, data.log_cap, data.slot,
                   data.truth[:, keep], data.base[:, keep], data.units[..., keep], data.ring,
                   data.align[:, keep], data.trusted, data.names)


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
    lum = torch.tensor(REC709_Y)
    yt = (t["truth"] * lum).sum(-1)
    yp = (pred * lum).sum(-1)
    m = t["align"].float()
    scale = (yt * m).sum(1) / (yp * m).sum(1).clamp_min(1e-12)
    p = (pred * scale[:, None, None]).clamp(0.0, 1.0)
    mse = ((p - t["truth"].clamp(0.0, 1.0)) ** 2).mean((1, 2))
    return -10.0 * torch.log10(mse.clamp_min(1e-10))


def fit(data: CropSet, seed: int, hidden: int = 12, pre_iters: int = 300,
        iters: int = 400, log_weight: float = 0.3, shape_heads: bool = True,
        weights: np.ndarray | None = None, pixels: int = FIT_PIXELS,
        features: tuple[str, ...] = FEATURES) -> dict:
    """Fit the perceptron to ``data``; see the module doc.

    ``shape_heads`` False: the mean alone (cones in the ring's colour).
    ``weights`` (C,): each crop's weight in both losses (default 1; 0 drops it).
    ``pixels``: relight pixels per crop in the loss (:func:`pixel_subset`; 0: all).
    ``features``: the names of the columns of ``data.features`` (:data:`FEATURES`) used.
    """
    import torch

    if weights is not None and np.any(np.asarray(weights) <= 0):
        data, weights = subset(data, np.asarray(weights) > 0), np.asarray(weights)[
            np.asarray(weights) > 0]
    data = pixel_subset(data, pixels, seed)
    torch.manual_seed(seed)
    torch.set_num_threads(1)  # small tensors: one thread is 2-3x faster than two here
    x = data.features[:, [FEATURES.index(f) for f in features]]
    mean, std = x.mean(0), x.std(0) + 1e-6
    mean[-1], std[-1] = 0.0, 1.0  # the constant feature stays 1
    xt = torch.tensor((x - mean) / std, dtype=torch.float32)
    yt = torch.tensor(data.log_mean)
    crop_w = torch.ones(len(data.names)) if weights is None else torch.tensor(
        np.asarray(weights, np.float32))
    crop_w = crop_w / crop_w.mean()
    wt = torch.sqrt(torch.tensor(data.area)) * crop_w[torch.as_tensor(data.slot // GROUPS)]
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
        loss = (-(crop_w * relight_psnr(data, log_mean, mix, share)).mean()
                + log_weight * torch.mean(wt * (log_mean - yt) ** 2))
        loss.backward()
        opt.step()
        sched.step()
    with torch.no_grad():
        rmse = float(torch.sqrt(torch.mean((heads()[0] - yt) ** 2)))
    linears = [m for m in net if isinstance(m, torch.nn.Linear)]
    return {"features": list(features), "mean": mean.tolist(), "std": std.tolist(),
            "layers": [[m.weight.detach().numpy().T.round(6).tolist(),
                        m.bias.detach().numpy().round(6).tolist()] for m in linears],
            "profiles": list(PROFILES), "train_rmse_stops": rmse}


def scores(data: CropSet, model_params: dict) -> dict[str, np.ndarray]:
    """Per-crop relight PSNR of the model as shipped (``fast``: its log2 means times
    :data:`.fast_predictor.SHRINK`), with each factor of :data:`SHRINKS` (``fast xA``),
    the baseline and the true means."""
    from ..uplift.fast_predictor import Mlp

    log_mean, mix, share = Mlp(model_params).heads(data.features)
    shrunk = {f"fast x{a}": relight_psnr(data, a * log_mean, mix, share).numpy()
              for a in SHRINKS}
    return {"fast": relight_psnr(data, SHRINK * log_mean, mix, share).numpy(), **shrunk,
            "baseline": relight_psnr(data, np.zeros_like(log_mean)).numpy(),
            "true_means": relight_psnr(data, data.log_mean, mix, share).numpy(),
            "true_means_cone_ring": relight_psnr(data, data.log_mean).numpy()}


def summary(label: str, per_crop: dict[str, np.ndarray]) -> dict:
    """Mean/median of per-crop scores and of the gains over the baseline, printed.

    ``gain``: the shipped model's (``fast``); ``gains``: the mean gain of every score.
    """
    out = {name: {"mean": round(float(s.mean()), 2), "median": round(float(np.median(s)), 2)}
           for name, s in per_crop.items()}
    gain = per_crop["fast"] - per_crop["baseline"]
    out["gain"] = {"mean": round(float(gain.mean()), 2),
                   "median": round(float(np.median(gain)), 2),
                   "worst": round(float(gain.min()), 2)}
    out["gains"] = {name: round(float((s - per_crop["baseline"]).mean()), 2)
                    for name, s in per_crop.items() if name != "baseline"}
    out["crops"] = len(gain)
    print(f"{label}: {len(gain)} clipped crops, relight PSNR (64 px) mean/median: "
          + ", ".join(f"{k} {v['mean']:.2f}/{v['median']:.2f}" for k, v in out.items()
                      if k not in ("crops", "gains"))
          + "; mean gains: " + ", ".join(f"{k} {v:+.2f}" for k, v in out["gains"].items()))
    return out


def report(label: str, data: CropSet, model_params: dict) -> dict:
    """Mean/median relight PSNR of the model, the baseline and the true means on ``data``."""
    return summary(label, scores(data, model_params))


def crop_weights(data: CropSet, clamped: float = 0.0, no_light: float = 1.0,
                 exclude: tuple[str, ...] = ()) -> np.ndarray:
    """(C,) calibration weight of every crop, from :data:`.shared_panoramas.PANORAMAS`.

    A crop that holds a clamped source pixel gets ``clamped`` (its regions' truth
    is too dark), a crop of a panorama with no light source ``no_light``, a
    panorama in ``exclude`` 0, the rest 1. Panoramas not in the table (a user
    folder) count as trusted.
    """
    kind = np.array([BY_NAME[n].kind if n in BY_NAME else TRUSTED for n in data.panoramas])
    w = np.ones(len(data.names))
    w[kind == NO_LIGHT] = no_light
    w[~data.trusted] = clamped
    w[np.isin(data.panoramas, list(exclude))] = 0.0
    return w


def _pooled(label: str, parts: dict[str, dict[str, np.ndarray]]) -> dict:
    return summary(label, {k: np.concatenate([p[k] for p in parts.values()])
                           for k in next(iter(parts.values()))})


def leave_one_out(data: CropSet, weights: np.ndarray, seed: int, full_model: dict,
                  shape_heads: bool = True, **fit_options: int
                  ) -> tuple[dict, dict[str, dict]]:
    """Every panorama's trusted crops scored by a model fitted without that panorama.

    A panorama that carries no calibration weight is scored by ``full_model``
    (which never saw it). Returns the scores (per panorama, per folder of
    :mod:`.shared_panoramas`, pooled) and the models fitted, by panorama.
    """
    panorama = data.panoramas
    per_pano: dict[str, dict[str, np.ndarray]] = {}
    models: dict[str, dict] = {}
    out: dict = {}
    for name in sorted(set(panorama)):
        judged = (panorama == name) & data.trusted
        if not judged.any():
            continue
        left = panorama == name
        if np.any(weights[left] > 0):
            models[name] = fit(data, seed, shape_heads=shape_heads,
                               weights=np.where(left, 0.0, weights), **fit_options)
        per_pano[name] = scores(subset(data, judged), models.get(name, full_model))
        out[name] = summary(f"  left out {name}", per_pano[name])
    for folder in sorted({folder_of(n) for n in per_pano}):
        members = {n: v for n, v in per_pano.items() if folder_of(n) == folder}
        out[f"folder:{folder}"] = _pooled(f"leave-one-panorama-out, {folder}", members)
    out["all"] = _pooled("leave-one-panorama-out, pooled", per_pano)
    return out, models


def _rounded(model: dict, digits: int = 4) -> dict:
    """A LOPO model with its weights rounded (the bench's file stays small)."""
    def r(v):
        return [r(x) for x in v] if isinstance(v, list) else (
            round(v, digits) if isinstance(v, float) else v)
    return {k: r(v) if k in ("layers", "mean", "std") else v for k, v in model.items()}


def _collect_cached(cache: Path | None, sources: list, crops: int, seed: int) -> CropSet:
    """Collect the crops, or load them from ``cache`` (written after collecting)."""
    if cache is not None and cache.exists():
        with np.load(cache, allow_pickle=False) as z:
            return CropSet(**{k: z[k] for k in CropSet.__dataclass_fields__ if k != "names"},
                           names=[str(n) for n in z["names"]])
    data = collect(sources, crops, seed)
    if cache is not None:
        with atomic_path(cache) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, **{k: np.asarray(getattr(data, k))
                            for k in CropSet.__dataclass_fields__})
    return data


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hdri", type=Path, default=None,
                    help="folder of HDR panoramas (default: both shared folders, "
                         "see gaslight_usd.evaluation.shared_panoramas)")
    ap.add_argument("--panoramas", nargs="*", default=None, metavar="NAME",
                    help="only these shared panoramas (names as in shared_panoramas)")
    ap.add_argument("--crops", type=int, default=DEFAULT_CROPS,
                    help="crops cut, cycling over the panoramas (unclipped ones are skipped)")
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--exclude", nargs="*", default=list(DEFAULT_EXCLUDE),
                    help="panoramas never fitted on (still scored, by a model that never "
                         "saw them)")
    ap.add_argument("--clamped-weight", type=float, default=DEFAULT_WEIGHTS["clamped"],
                    help="weight of crops holding a clamped source pixel")
    ap.add_argument("--no-light-weight", type=float, default=DEFAULT_WEIGHTS["no_light"],
                    help="weight of crops of panoramas with no light source")
    ap.add_argument("-o", "--output", type=Path, default=PARAMS_FILE)
    ap.add_argument("--lopo-output", type=Path, default=LOPO_FILE,
                    help="where the leave-one-panorama-out models go (the bench's "
                         "recursive-fast-lopo reads them)")
    ap.add_argument("--cache", type=Path, default=None,
                    help="keep the collected crops in this .npz (reused when it exists)")
    ap.add_argument("--iters", type=int, nargs=2, default=[300, 400], metavar=("PRE", "RELIGHT"),
                    help="optimiser steps on the log means, then on the relight loss")
    ap.add_argument("--features", nargs="*", default=list(DEFAULT_FEATURES), metavar="NAME",
                    help="region features the model uses (of fast_predictor.FEATURES; "
                         "'legacy' for the first model's fifteen)")
    ap.add_argument("--mean-only", action="store_true",
                    help="fit the mean alone (cones in the ring's colour, no shape heads)")
    ap.add_argument("--no-lopo", action="store_true",
                    help="skip the leave-one-panorama-out scores (one fit per panorama)")
    args = ap.parse_args(argv)
    if args.seed == 0:
        ap.error("seed 0 makes the benchmark's crops: calibrate on another seed")
    t0 = time.perf_counter()
    sources = shared_sources(args.hdri) if args.hdri else load_shared(args.panoramas)
    data = _collect_cached(args.cache, sources, args.crops, args.seed)
    if data.features.shape[1] != len(FEATURES):
        data = refresh_features(data, sources, args.seed)
    features = LEGACY_FEATURES if args.features == ["legacy"] else tuple(args.features)
    unknown = [f for f in features if f not in FEATURES]
    if unknown or features[-1:] != ("one",):
        ap.error(f"--features: unknown {unknown} (the list ends with 'one'); "
                 f"known: {' '.join(FEATURES)}")
    weights = crop_weights(data, args.clamped_weight, args.no_light_weight,
                           tuple(args.exclude))
    print(f"collected {len(data.names)} clipped crops ({len(data.log_mean)} regions) of "
          f"{len(set(data.panoramas))} panoramas, {int(np.count_nonzero(weights))} fitted on, "
          f"in {time.perf_counter() - t0:.0f} s")
    shape_heads = not args.mean_only
    steps = {"pre_iters": args.iters[0], "iters": args.iters[1], "features": features}
    model = fit(data, args.seed, shape_heads=shape_heads, weights=weights, **steps)
    results = {"fitted": report("fitted crops", subset(data, weights > 0), model)}
    given = list(sys.argv[1:] if argv is None else argv)
    if "--cache" in given:  # a cache only saves time: the numbers do not depend on it
        at = given.index("--cache")
        del given[at:at + 2]
    command = " ".join(["python -m gaslight_usd.bench.calibrate", *given])
    if not args.no_lopo:
        lopo, models = leave_one_out(data, weights, args.seed, model, shape_heads, **steps)
        models = {name: _rounded(m) for name, m in models.items()}
        results["leave_one_panorama_out"] = lopo
        write_text(args.lopo_output, json.dumps(
            {"command": command, "features": list(features), "models": models},
            separators=(",", ":")))
    fitted = sorted(set(data.panoramas[weights > 0]))
    params = {"features": list(features), "model": model,
              "calibration": {"command": command, "crops": args.crops, "seed": args.seed,
                              "panoramas": fitted,
                              "weights": {"clamped": args.clamped_weight,
                                          "no_light": args.no_light_weight,
                                          "excluded": list(args.exclude)},
                              "regions": int(len(data.log_mean[
                                  (weights > 0)[data.slot // GROUPS]])),
                              "relight_psnr_64px": results,
                              "seconds": round(time.perf_counter() - t0)}}
    write_text(args.output, json.dumps(params, separators=(",", ":")))
    print(f"-> {args.output} ({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
