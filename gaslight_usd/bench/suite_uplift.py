"""Suite "uplift": single-photo LDR -> HDR methods on real-HDR reference pairs.

Cases are :mod:`~gaslight_usd.evaluation.reference` pairs cut from the
shared CC0 panoramas of both shared folders, named and clamp-tagged by
:mod:`~gaslight_usd.evaluation.shared_panoramas` (200 in the full run, cycling
over the panoramas, 8 with ``quick``; ``count`` overrides; option ``hdri_dir``:
one folder of the user's instead). Per case and method:

- ``sec_per_mp``: wall time of the method's call per megapixel of photo;
- ``relight_mse`` / ``relight_psnr`` / ``relight_angle_deg``: the relighting
  protocol (:mod:`~gaslight_usd.evaluation.relight`) at a reduced render size
  for speed (stated in the notes and in every row);
- ``pu21_psnr``, ``log_lum_rmse_stops``, ``relative_l1``: HDR errors after
  exposure alignment on truth pixels in [0.2, 0.8];
- ``light_power_err_stops`` / ``light_peak_err_stops``: light-source errors
  (after the same alignment, pixels weighted by solid angle), only on cases
  whose light truth is trustworthy and whose brightest region is clipped in
  the photo; NaN elsewhere (left out of medians).

Beside the runner's medians over every case, :func:`summaries` gives per
method the mean and median relight PSNR, and the gain over ``ldr-baseline``
on the same cases, in groups: ``clipped`` (crops with a clipped pixel whose
light truth is good: the uplift's job, the headline), the same per shared
folder, ``nothing-clipped`` (reported apart: every method should equal the
baseline there) and ``clamped`` (crops holding a clamped source pixel: their
truth is wrong, so they are left out of every other group and only counted).

Built-in methods: ``ldr-baseline`` (the photo through the inverse camera
curve, no uplift), ``oracle`` (the truth itself: the ceiling) and
``region-mean-oracle`` (every clipped region filled flat with the truth's
mean over it: the right energy in the right place, no shape; what a
predictor that only ever gets each region's power right can score) and the
same with every region's power half a stop under and over the truth
(``region-mean-oracle-0.5-stop-under`` / ``-over``: how exactly a predictor
must know the power; the photo's own value stays the floor). Other
modules add theirs with :func:`register_uplift_method`, and ceilings that
read the truth with :func:`register_reference_method`; the suite imports
the optional module ``gaslight_usd.bench.uplift_methods`` and the entry
points of group ``gaslight_usd.bench_uplift`` (each a callable taking
``register_uplift_method``) before it runs, so methods living there join
without this file changing. A plug-in that fails to load is reported as a
row-less warning on stderr, never fatal.
"""

from __future__ import annotations

import importlib
import math
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ..colour import CLIP_LEVEL
from ..evaluation import curves
from ..evaluation.metrics import hdr_errors, light_source_errors
from ..evaluation.reference import ReferencePair, make_pair, shared_sources
from ..evaluation.relight import RelightRenderer, compare_renders
from ..evaluation.shared_panoramas import folder_of, load_shared

NAME = "uplift"
DESCRIPTION = "LDR -> HDR uplift on real-HDR reference pairs (relighting, PU21, light power)"
X = ("sec_per_mp", "uplift time (seconds per megapixel)")
Y = ("relight_psnr", "relight PSNR (dB)")
HIGHER_IS_BETTER = True
REFERENCES = ["oracle"]
"""Methods that read the truth: charted as references, kept off the Pareto front."""
TABLE = ("sec_per_mp", "relight_psnr", "relight_mse", "relight_angle_deg", "pu21_psnr",
         "log_lum_rmse_stops", "light_power_err_stops")

FULL_COUNT = 200
QUICK_COUNT = 8
SIZES = {"quick": {"photo": (128, 96), "render": 64, "spp": 8, "env": 128},
         "full": {"photo": (256, 192), "render": 128, "spp": 16, "env": 256}}

UpliftFn = Callable[[np.ndarray, str], np.ndarray]
_METHODS: dict[str, Callable[[ReferencePair], np.ndarray]] = {}


def register_uplift_method(name: str, fn: UpliftFn) -> None:
    """Add a method to the suite: ``fn(ldr_encoded, curve) -> HDR``.

    ``ldr_encoded`` is ``(H, W, 3)`` float in [0, 1] (8-bit levels) encoded
    with ``curve`` (one of ``srgb``, ``gamma2.2``, ``filmic``; see
    :mod:`~gaslight_usd.evaluation.curves`); the result is ``(H, W, 3)``
    linear HDR in the baseline's scale (1.0 = the photo's white). Registering
    a name again replaces it.
    """
    _METHODS[name] = lambda pair: fn(pair.ldr, pair.curve)


def register_pair_method(name: str, fn: Callable[[ReferencePair], np.ndarray]) -> None:
    """Add a method that needs to know which panorama a case comes from (``pair.spec``)
    but must not read ``pair.truth``: e.g. a model fitted without that panorama."""
    _METHODS[name] = fn


def ldr_baseline(ldr_encoded: np.ndarray, curve: str) -> np.ndarray:
    """No uplift: the photo linearised through its inverse camera curve."""
    return curves.decode(ldr_encoded, curve)


def register_reference_method(name: str, fn: Callable[[ReferencePair], np.ndarray]) -> None:
    """Add a ceiling: ``fn(pair) -> HDR`` may read ``pair.truth`` (charted as a reference)."""
    _METHODS[name] = fn
    if name not in REFERENCES:
        REFERENCES.append(name)


def clipped_regions(ldr_encoded: np.ndarray, level: float = CLIP_LEVEL) -> tuple[np.ndarray, int]:
    """8-connected regions of pixels whose brightest encoded channel reaches ``level``."""
    from scipy import ndimage

    return ndimage.label(ldr_encoded.max(axis=-1) >= level, structure=np.ones((3, 3)))


def region_means(image: np.ndarray, labels: np.ndarray, count: int) -> np.ndarray:
    """``(count, 3)`` mean of ``image`` over each labelled region (labels 1..count)."""
    from scipy import ndimage

    index = np.arange(1, count + 1)
    return np.stack([np.asarray(ndimage.mean(image[..., c], labels, index))
                     for c in range(image.shape[-1])], axis=1)


def region_mean_oracle(pair: ReferencePair, stops: float = 0.0) -> np.ndarray:
    """The baseline with each clipped region set to the truth's mean over it (per channel),
    times ``2**stops`` but never below the photo's own value there."""
    out = ldr_baseline(pair.ldr, pair.curve).astype(np.float32)
    labels, count = clipped_regions(pair.ldr)
    if count:
        inside = labels > 0
        fill = region_means(pair.truth, labels, count)[labels[inside] - 1]
        if stops:
            fill = np.maximum(fill * 2.0 ** stops, out[inside])
        out[inside] = fill
    return out


register_uplift_method("ldr-baseline", ldr_baseline)
register_reference_method("oracle", lambda pair: pair.truth)
register_reference_method("region-mean-oracle", region_mean_oracle)
register_reference_method("region-mean-oracle-0.5-stop-under",
                          lambda pair: region_mean_oracle(pair, -0.5))
register_reference_method("region-mean-oracle-0.5-stop-over",
                          lambda pair: region_mean_oracle(pair, 0.5))


PLUGIN_MODULE = "gaslight_usd.bench.uplift_methods"
ENTRY_POINT_GROUP = "gaslight_usd.bench_uplift"


def load_plugins() -> None:
    """Import the optional plug-in module and entry points that register methods."""
    try:
        importlib.import_module(PLUGIN_MODULE)
    except ModuleNotFoundError as exc:
        if exc.name not in (PLUGIN_MODULE, PLUGIN_MODULE.rpartition(".")[0]):
            print(f"bench uplift: cannot load {PLUGIN_MODULE}: {exc}", file=sys.stderr)
    except Exception as exc:  # noqa: BLE001 - a broken plug-in must not stop the bench
        print(f"bench uplift: cannot load {PLUGIN_MODULE}: {exc}", file=sys.stderr)
    from importlib.metadata import entry_points

    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            ep.load()(register_uplift_method)
        except Exception as exc:  # noqa: BLE001
            print(f"bench uplift: entry point {ep.name} failed: {exc}", file=sys.stderr)


def methods() -> list[str]:
    """Names of the registered methods (plug-ins loaded first)."""
    load_plugins()
    return list(_METHODS)


def _sizes(options: dict[str, Any]) -> dict[str, Any]:
    return SIZES["quick" if options.get("quick") else "full"]


def notes(options: dict[str, Any]) -> list[str]:
    s = _sizes(options)
    count = options.get("count") or (QUICK_COUNT if options.get("quick") else FULL_COUNT)
    return [f"{count} reference pairs of {s['photo'][0]}x{s['photo'][1]} from the shared "
            f"panoramas, seed {options.get('seed', 0)}",
            f"relight renders at {s['render']}x{s['render']}, {s['spp']} spp, environment "
            f"{2 * s['env']}x{s['env']} (protocol default 256x256, 64 spp)",
            "light-source errors only on cases with trustworthy light truth and a clipped "
            "brightest region"]


def _nan_metrics() -> dict[str, float]:
    keys = ("relight_mse", "relight_psnr", "relight_angle_deg", "pu21_psnr",
            "log_lum_rmse_stops", "relative_l1", "light_power_err_stops",
            "light_peak_err_stops", "exposure_scale")
    return dict.fromkeys(keys, math.nan)


def _evaluate(pair: ReferencePair, pred: np.ndarray, renderer: RelightRenderer,
              truth_render: np.ndarray) -> dict[str, float]:
    if pred.shape != pair.truth.shape:
        raise ValueError(f"returned shape {pred.shape}, expected {pair.truth.shape}")
    if not np.all(np.isfinite(pred)):
        raise ValueError("returned NaN or infinite values")
    start = time.perf_counter()
    render = truth_render if pred is pair.truth else renderer.render(pred, "perspective")
    render_seconds = time.perf_counter() - start
    relit = compare_renders(render, truth_render)
    errors = hdr_errors(pred, pair.truth, align=True)
    light = {"power_err_stops": math.nan, "peak_err_stops": math.nan}
    if pair.light_truth and pair.light_clipped:
        light = light_source_errors(pred * errors["exposure_scale"], pair.truth,
                                    pixel_weights=pair.solid_angles)
    return {
        "relight_mse": relit.mse, "relight_psnr": relit.psnr,
        "relight_angle_deg": relit.angular_error_deg,
        "pu21_psnr": errors["pu21_psnr"], "log_lum_rmse_stops": errors["log_lum_rmse_stops"],
        "relative_l1": errors["relative_l1"],
        "light_power_err_stops": light["power_err_stops"],
        "light_peak_err_stops": light["peak_err_stops"],
        "exposure_scale": errors["exposure_scale"], "render_seconds": render_seconds,
    }


def run(options: dict[str, Any]) -> list[dict[str, Any]]:
    quick = bool(options.get("quick"))
    seed = int(options.get("seed", 0))
    count = int(options.get("count") or (QUICK_COUNT if quick else FULL_COUNT))
    s = _sizes(options)
    width, height = s["photo"]
    progress = options.get("progress")
    hdri_dir = options.get("hdri_dir")
    sources = shared_sources(hdri_dir) if hdri_dir else load_shared()
    if not sources:
        sources = shared_sources()  # no shared folder found: its clear error
    renderer = RelightRenderer(resolution=s["render"], spp=s["spp"], env_height=s["env"],
                               seed=seed)
    available = methods()
    wanted = options.get("methods") or available
    unknown = [m for m in wanted if m not in available]
    if unknown:
        raise ValueError(f"unknown uplift method(s) {', '.join(unknown)}; "
                         f"known: {', '.join(available)}")
    rows: list[dict[str, Any]] = []
    for i in range(count):
        start = time.perf_counter()
        pair = make_pair(sources[i % len(sources)], i, seed, width=width, height=height)
        pair_seconds = time.perf_counter() - start
        start = time.perf_counter()
        truth_render = renderer.render(pair.truth, "perspective")
        truth_render_seconds = time.perf_counter() - start
        base = {
            "case": pair.name, "source": pair.spec.source,
            "folder": str(hdri_dir) if hdri_dir else folder_of(pair.spec.source),
            "ldr_clipped": bool(np.any(pair.ldr.max(axis=-1) >= CLIP_LEVEL)),
            "curve": pair.curve,
            "fov": pair.spec.fov, "aimed_at_light": pair.spec.aimed_at_light,
            "clipped_fraction": pair.clipped_fraction, "light_truth": pair.light_truth,
            "light_clipped": pair.light_clipped, "pair_seconds": pair_seconds,
            "truth_render_seconds": truth_render_seconds,
            "render_resolution": s["render"], "render_spp": s["spp"],
        }
        megapixels = width * height / 1e6
        for name in wanted:
            row = {"method": name, "setting": "default", **base}
            try:
                start = time.perf_counter()
                pred = np.asarray(_METHODS[name](pair), dtype=np.float32)
                seconds = time.perf_counter() - start
                if name == "oracle":
                    pred = pair.truth  # the same object: its render is the truth's
                row.update(seconds=seconds, sec_per_mp=seconds / megapixels)
                row.update(_evaluate(pair, pred, renderer, truth_render))
            except Exception as exc:  # noqa: BLE001 - one failing method must not stop the run
                row.update(seconds=math.nan, sec_per_mp=math.nan, **_nan_metrics(),
                           error=f"{type(exc).__name__}: {exc}")
            rows.append(row)
        if progress is not None:
            progress.update(i + 1, count, case=pair.name)
    return rows


BASELINE = "ldr-baseline"


def case_group(row: dict[str, Any]) -> str:
    """``clamped`` (the truth is wrong: left out), ``nothing-clipped`` or ``clipped``."""
    if not row.get("light_truth", True):
        return "clamped"
    return "clipped" if row.get("ldr_clipped", True) else "nothing-clipped"


def _stats(values: list[float]) -> tuple[float, float]:
    finite = [v for v in values if math.isfinite(v)]
    if not finite:
        return math.nan, math.nan
    return float(np.mean(finite)), float(np.median(finite))


def summaries(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Relight PSNR mean / median and gain over ``ldr-baseline`` per method and group.

    Groups (:func:`case_group`): ``clipped`` (the headline), ``clipped:FOLDER``
    per shared folder, ``nothing-clipped``; clamped cases are only counted (one
    row, ``clamped (left out)``).
    A gain pairs a method's case with the baseline's same case.
    """
    base = {r["case"]: r["relight_psnr"] for r in rows if r["method"] == BASELINE}
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    clamped: set[str] = set()
    for row in rows:
        group = case_group(row)
        if group == "clamped":
            clamped.add(row["case"])
            continue
        keys = [group] + ([f"clipped:{row.get('folder', '?')}"] if group == "clipped" else [])
        for key in keys:
            groups.setdefault((key, row["method"]), []).append(row)
    order = {"clipped": 0, "nothing-clipped": 2}
    out = []
    for (group, method), members in sorted(
            groups.items(), key=lambda kv: (order.get(kv[0][0], 1), kv[0][0])):
        psnr = [float(r["relight_psnr"]) for r in members]
        gain = [float(r["relight_psnr"]) - float(base.get(r["case"], math.nan))
                for r in members]
        entry: dict[str, Any] = {"group": group, "method": method, "cases": len(members)}
        entry["relight_psnr_mean"], entry["relight_psnr_median"] = _stats(psnr)
        entry["gain_mean"], entry["gain_median"] = _stats(gain)
        out.append(entry)
    if clamped:
        out.append({"group": "clamped (left out)", "method": "-", "cases": len(clamped)})
    return out
