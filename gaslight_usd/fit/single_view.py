"""Lights seen from one photo only: where they are is a guess.

A light's depth comes from parallax between photos; a lamp framed by one photo alone
can sit anywhere along that photo's rays (the fit puts it where the loss happened to
leave it), so its place, size and the light it throws at a probe are unknown. The fit
names it: the bright splats (over ``ratio`` x the views' median) that no more than one
training camera frames, when they hold at least :data:`MIN_SHARE` of the bright
splats' power. Measured by ``gaslight2usd bench --suite stability --perturb
light_one_view``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cameras import PinholeCamera

BRIGHT_RATIO = 8.0
"""Splats this many times brighter than the views' median count as light."""
MIN_SHARE = 0.1
"""Share of the bright splats' power, framed by one camera at most, that is reported."""


@dataclass
class SingleViewLight:
    view: str | None
    """The one camera that frames it (None: none does)."""
    position: np.ndarray
    share: float
    """Its share of the bright splats' power."""

    def as_dict(self) -> dict:
        return {"view": self.view, "position": [round(float(v), 4) for v in self.position],
                "power_share": round(self.share, 3)}


def single_view_lights(positions: np.ndarray, luminance: np.ndarray, area: np.ndarray,
                       cameras: list[PinholeCamera], names: list[str], level: float,
                       ratio: float = BRIGHT_RATIO, min_share: float = MIN_SHARE
                       ) -> list[SingleViewLight]:
    """Bright splats framed by at most one of ``cameras``, grouped by that camera, each
    group reported when its power (luminance x ``area``) is ``min_share`` of all bright
    splats' or more. ``level``: the views' median luminance."""
    bright = np.flatnonzero(luminance >= ratio * level)
    if not len(bright) or len(cameras) < 2:
        return []
    pts = positions[bright].astype(np.float64)
    framed = np.zeros(len(bright), np.int64)
    which = np.full(len(bright), -1)
    for v, cam in enumerate(cameras):
        uv, z = cam.project(pts)
        inside = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & \
                 (uv[:, 1] >= 0) & (uv[:, 1] < cam.height)
        framed += inside
        which[inside] = v
    power = luminance[bright] * area[bright]
    total = float(power.sum()) or 1.0
    lonely = framed <= 1
    out = []
    for v in np.unique(which[lonely]):
        group = lonely & (which == v)
        share = float(power[group].sum()) / total
        if share >= min_share:
            centre = (pts[group] * power[group, None]).sum(0) / max(power[group].sum(), 1e-30)
            out.append(SingleViewLight(names[v] if v >= 0 else None, centre, share))
    return sorted(out, key=lambda light: -light.share)
