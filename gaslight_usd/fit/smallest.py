"""The smallest model within a tolerance: fewer splats and a lower SH degree, measured.

A fit keeps what its budget allows; many scenes need less. Here the fitted scene is
cut down without refitting: splats are ranked by what they add to the views
(:func:`.contribution.contributions`: blend weight x brightness) and only the top
share kept, and the SH coefficients above a degree dropped. Each candidate is
rendered on the run's own held-out views (training views when none are held out,
never bench truth) and scored as the fit scores itself (log-luminance RMSE in stops);
the smallest in bytes whose error is within ``tolerance`` stops of the full model's
wins. ``gaslight2usd run --tolerance-stops X`` uses it; the sizes and errors on the
bench's room are charted by ``gaslight2usd bench --suite budget``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from ..cameras import PinholeCamera
from ..render import SplatParams, render
from ..splats import SplatScene, sh_coefficient_count
from .contribution import contributions
from .losses import held_out_errors

SHARES = (1.0, 0.5, 0.25, 0.125, 0.0625)
"""Shares of the splats (ranked by contribution) tried as candidates."""
FLOATS_PER_SPLAT = 3 + 4 + 3 + 1
"""Position, rotation, scale, opacity: the float32 values besides the SH coefficients."""


def model_bytes(count: int, degree: int) -> int:
    """float32 bytes of ``count`` splats with SH ``degree`` (what a 3DGS PLY stores)."""
    return int(count) * 4 * (FLOATS_PER_SPLAT + 3 * sh_coefficient_count(degree))


def truncate_sh(scene: SplatScene, degree: int) -> SplatScene:
    """``scene`` with the SH coefficients above ``degree`` dropped."""
    out = scene.subset(np.arange(scene.count))
    out.sh = np.ascontiguousarray(scene.sh[:, :sh_coefficient_count(degree)])
    return out


def contribution_rank(scene: SplatScene, cameras: Sequence[PinholeCamera]) -> np.ndarray:
    """Splat indices, most contributing first (weight x max(brightness / mean, 1))."""
    params = SplatParams.from_scene(scene, device="cpu")
    weight, radiance = contributions(params, list(cameras), scene.sh_degree)
    mean = float(radiance.sum() / weight.sum().clamp_min(1e-12)) or 1.0
    score = weight * torch.clamp(radiance / weight.clamp_min(1e-12) / mean, min=1.0)
    return np.argsort(-score.cpu().numpy(), kind="stable")


@dataclass
class ModelChoice:
    splats: int
    sh_degree: int
    bytes: int
    error_stops: float
    """The chosen model's log-luminance RMSE (stops) on the scoring views."""
    full_splats: int
    full_sh_degree: int
    full_bytes: int
    full_error_stops: float
    tolerance_stops: float
    views: list[str]
    candidates: list[dict[str, Any]] = field(default_factory=list)

    @property
    def cost_stops(self) -> float:
        """What the smaller model costs: its error minus the full model's (stops)."""
        return self.error_stops - self.full_error_stops

    def as_dict(self) -> dict[str, Any]:
        return {"splats": self.splats, "sh_degree": self.sh_degree, "bytes": self.bytes,
                "error_stops": round(self.error_stops, 4),
                "cost_stops": round(self.cost_stops, 4),
                "full_splats": self.full_splats, "full_sh_degree": self.full_sh_degree,
                "full_bytes": self.full_bytes,
                "full_error_stops": round(self.full_error_stops, 4),
                "tolerance_stops": self.tolerance_stops, "scored_on": self.views,
                "scored_on_held_out": self.held_out,
                "candidates": self.candidates}

    held_out: bool = True
    """Whether ``views`` are held-out views (False: the fit held none out; training views)."""

    def sentence(self) -> str:
        where = "" if self.held_out else " (training views: the fit held none out)"
        return (f"tolerance {self.tolerance_stops:g} stops{where}: kept {self.splats} of "
                f"{self.full_splats} splats at SH degree {self.sh_degree} (of "
                f"{self.full_sh_degree}), {self.bytes / max(self.full_bytes, 1):.0%} of the "
                f"bytes; error {self.error_stops:.3f} stops on {len(self.views)} view(s), "
                f"{self.cost_stops:+.3f} against the full model")


def score(scene: SplatScene, cameras: Sequence[PinholeCamera], images: Sequence[np.ndarray],
          background: float = 0.0) -> float:
    """Mean log-luminance RMSE (stops) of ``scene`` rendered in ``cameras``."""
    with torch.no_grad():
        errs = [held_out_errors(render(scene, cam, background=background).image.cpu().numpy(),
                                img)["log_lum_rmse_stops"]
                for cam, img in zip(cameras, images, strict=True)]
    return float(np.mean(errs))


def candidates(scene: SplatScene, rank: np.ndarray,
               keep: Sequence[int] = ()) -> list[tuple[int, int, SplatScene]]:
    """(splats, degree, scene) for every share of :data:`SHARES` and SH degree, smallest
    first. ``keep``: indices always kept (e.g. the backdrop, which no view ranks)."""
    keep = np.asarray(keep, np.int64)
    ranked = rank[~np.isin(rank, keep)]
    out = []
    for share in SHARES:
        n = max(1, int(round(len(ranked) * share)))
        picked = scene.subset(np.sort(np.concatenate([ranked[:n], keep])))
        for degree in range(scene.sh_degree + 1):
            out.append((picked.count, degree, truncate_sh(picked, degree)))
    return sorted(out, key=lambda c: model_bytes(c[0], c[1]))


def choose_smallest(scene: SplatScene, rank_cameras: Sequence[PinholeCamera],
                    cameras: Sequence[PinholeCamera], images: Sequence[np.ndarray],
                    tolerance_stops: float, view_names: Sequence[str] = (),
                    background: float = 0.0, keep: Sequence[int] = ()
                    ) -> tuple[ModelChoice, SplatScene]:
    """The smallest candidate whose error on ``cameras``/``images`` is within
    ``tolerance_stops`` of the full ``scene``'s (the full scene when none is), and what
    it is."""
    if tolerance_stops < 0:
        raise ValueError("the tolerance must be >= 0 stops")
    full_err = score(scene, cameras, images, background)
    rank = contribution_rank(scene, rank_cameras)
    chosen = (scene.count, scene.sh_degree, scene, full_err)
    tried = []
    for count, degree, cand in candidates(scene, rank, keep):
        err = score(cand, cameras, images, background)
        tried.append({"splats": count, "sh_degree": degree,
                      "bytes": model_bytes(count, degree), "error_stops": round(err, 4)})
        if err <= full_err + tolerance_stops:
            chosen = (count, degree, cand, err)
            break
    count, degree, picked, err = chosen
    picked.metadata = dict(scene.metadata)
    return ModelChoice(count, degree, model_bytes(count, degree), err, scene.count,
                       scene.sh_degree, model_bytes(scene.count, scene.sh_degree), full_err,
                       float(tolerance_stops), list(view_names), tried), picked


def choose_for_fit(data, result, tolerance_stops: float, background: float = 0.0
                   ) -> tuple[ModelChoice, SplatScene]:
    """:func:`choose_smallest` on a finished fit (``data``: its :class:`.data.FitData`,
    ``result``: its :class:`.trainer.FitResult`): scored on the fit's held-out views (a
    quarter of its views, spread, when it held none out), ranked on the others; the
    backdrop splats the fit added last are always kept."""
    names = list(data.names)
    held = [names.index(n) for n in result.metrics.get("held_out_views", []) if n in names]
    views = held or list(range(0, len(names), 4))
    rank_views = [i for i in range(len(names)) if i not in held] or views
    cams = result.cameras
    backdrop = int(result.metrics.get("backdrop_splats", 0))
    keep = np.arange(result.scene.count - backdrop, result.scene.count)
    choice, scene = choose_smallest(result.scene, [cams[i] for i in rank_views],
                                    [cams[i] for i in views], [data.images[i] for i in views],
                                    tolerance_stops, [names[i] for i in views], background, keep)
    choice.held_out = bool(held)
    return choice, scene
