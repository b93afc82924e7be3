"""The set's lights: splats no diffuse surface lit by this scene could explain.

GaSLight's splats are all light, but a TD wants *lights*: the lamp and the
window, not the wall the lamp lights. The rule, in the paper's own use
(emitters light the scene, everything else is a diffuse surface it lights):

1. **Candidates** are splats brighter than the photos' white (radiance 1 in
   the HDR views' relative units, times the scene's ``exposure_scale``): only
   those were clipped at the reference exposure, which is where GaSLight's
   "radiance above 1" rule comes from. Backdrop splats (outside the captured
   space, :mod:`gaslight_usd.capture`, or the fit's unseen-surface backdrop)
   are never candidates.
2. Candidates that touch (within :data:`LINK_SIGMAS` footprints of each other)
   form **clusters**; the brightest (mean radiance) :data:`MAX_CLUSTERS` are
   tested, fainter ones and those under :data:`MIN_POWER_SHARE` of the
   strongest's power are not lights.
3. A cluster is an **emitter** when its mean radiance exceeds what the
   brightest plausible diffuse surface could reflect at its place:
   ``L > RHO_MAX * E_max / pi``, where ``E_max`` is the largest irradiance
   (over 26 surface orientations) that the rest of the scene sends to the
   cluster's centre (:mod:`gaslight_usd.surroundings`). A diffuse surface of
   albedo rho under irradiance E has radiance rho E / pi, so no surface of
   albedo <= RHO_MAX lit by this scene can be brighter. The cluster's own
   splats, and dimmer splats around it (the surface it lies on only hides the
   light that lights it), are left out of ``E_max``. Light from sources brighter
   than the photos' white (and than the cluster) was predicted, not measured,
   so it counts ``2 ** power_uncertainty_stops`` times (it may be that much
   brighter): a wall lit by an underestimated lamp is still explained by it.
4. Emitter clusters closer than their own sizes plus :data:`GROUP_SHARE` of
   the captured space's median depth are **grouped into lights**:
   position (power-weighted centre), size (principal half-extents), power
   (radiance x projected area, summed), colour, and where the power came from.

``gaslight2usd bench --suite usd`` times the export that runs this;
``tests/test_lights.py`` checks it on a room with a lamp, a window, lit walls
and backdrop.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .capture import CaptureSpace, backdrop_mask, capture_space
from .splats import SplatScene
from .surroundings import look_from, normals_26, splat_sigma

RHO_MAX = 0.9
"""Brightest plausible diffuse albedo (fresh snow, the whitest paints: 0.8-0.9)."""
LINK_SIGMAS = 1.0
"""Candidates whose centres are closer than this many (summed) footprints touch."""
MAX_CLUSTERS = 96
"""Clusters tested, highest mean radiance first (a lamp is small but bright: ordered by
power, the example's lamp ranked below 48 window and wall fragments); the rest are not
lights."""
MIN_POWER_SHARE = 1e-3
"""Clusters with less than this share of the brightest cluster's power are not lights."""
POWER_UNCERTAINTY_STOPS = {"measured": 0.25, "predicted": 3.0, "inferred": 4.0}
"""How far a light's power may be off, by where it came from: merged brackets measure it
(a quarter stop covers the fit's error); the fast exposure predictor's median error
before its shrink is about 2 stops (README), and on the example the ``fast`` fit's lamp
lights the ceiling as a lamp about 3 stops brighter would; a clipped photo taken as is
only gives a lower bound."""
GROUP_SHARE = 0.15
"""Emitter clusters closer than this share of the captured space's median depth (plus
their own sizes) are one light (a window fitted as many patches)."""


@dataclass
class Light:
    """One light of the set, found from its splats."""

    position: np.ndarray
    """(3,) power-weighted centre, world frame."""
    extent: np.ndarray
    """(3,) half-sizes along ``axes`` (largest first): a uniform box of the splats' spread."""
    axes: np.ndarray
    """(3, 3) rows: the principal directions of ``extent``."""
    power: np.ndarray
    """(3,) RGB radiance x projected area summed over the splats (an isotropic emitter's
    radiant intensity), in the splats' radiance units x length unit squared."""
    radiance: np.ndarray
    """(3,) mean RGB radiance over the light's area (power / area)."""
    area: float
    splats: np.ndarray
    """Indices of the light's splats in the scene."""
    power_source: str = "predicted"
    """"measured" (merged brackets), "predicted" (exposure predictor), "inferred"."""
    power_uncertainty_stops: float = POWER_UNCERTAINTY_STOPS["predicted"]
    test: dict[str, float] = field(default_factory=dict)
    """The emitter test's numbers: mean radiance, E_max, the diffuse limit."""

    @property
    def radius(self) -> float:
        """Radius of a sphere as large as the light's spread."""
        return float(np.sqrt((self.extent**2).sum() / 3.0))

    @property
    def colour(self) -> np.ndarray:
        """(3,) power normalised to its largest channel."""
        return self.power / max(float(self.power.max()), 1e-30)

    def as_dict(self) -> dict[str, Any]:
        return {
            "position": [round(float(v), 5) for v in self.position],
            "extent": [round(float(v), 5) for v in self.extent],
            "radius": round(self.radius, 5),
            "power": [float(f"{v:.6g}") for v in self.power],
            "colour": [round(float(v), 5) for v in self.colour],
            "radiance": [float(f"{v:.6g}") for v in self.radiance],
            "area": float(f"{self.area:.6g}"),
            "splats": int(len(self.splats)),
            "power_source": self.power_source,
            "power_uncertainty_stops": self.power_uncertainty_stops,
            "test": {k: float(f"{v:.6g}") for k, v in self.test.items()},
        }


@dataclass
class LightSearch:
    """What :func:`search_lights` found and why (for reports)."""

    lights: list[Light]
    emitters: np.ndarray
    """(N,) bool: splats of the lights."""
    backdrop: np.ndarray
    """(N,) bool: splats outside the captured space (never emitters)."""
    space: CaptureSpace
    white: float
    power_source: str
    counts: dict[str, int] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        return {
            "rule": ("emitter: cluster of splats above the photos' white whose mean radiance "
                     f"exceeds {RHO_MAX} x E_max / pi, E_max the largest irradiance the rest "
                     "of the scene sends it (sources above white x 2^uncertainty)"),
            "white": self.white,
            "rho_max": RHO_MAX,
            "captured_space": self.space.source,
            "power_source": self.power_source,
            **self.counts,
            "lights": [light.as_dict() for light in self.lights],
        }


def power_source(metadata: Mapping[str, Any]) -> str:
    """Where splat radiance above the photos' white came from, by the HDR method."""
    prov = metadata.get("provenance")
    method = str((prov.get("hdr_method") if isinstance(prov, Mapping) else None)
                 or metadata.get("hdr_method") or "").lower()
    if "bracket" in method:
        return "measured"
    if "recursive" in method or "diffusion" in method or "predict" in method:
        return "predicted"
    return "inferred"


def white_level(metadata: Mapping[str, Any]) -> float:
    """Radiance of the photos' white in the splats' units (1 x exposure_scale)."""
    try:
        scale = float(metadata.get("exposure_scale", 1.0) or 1.0)
    except (TypeError, ValueError):
        scale = 1.0
    return scale if scale > 0 else 1.0


def _components(points: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """Connected-component label (N,) of points linked when closer than reach_i + reach_j."""
    n = len(points)
    if n == 0:
        return np.zeros(0, np.int64)
    pairs = cKDTree(points).query_pairs(2.0 * float(reach.max()), output_type="ndarray")
    if len(pairs):
        d = np.linalg.norm(points[pairs[:, 0]] - points[pairs[:, 1]], axis=1)
        pairs = pairs[d <= reach[pairs[:, 0]] + reach[pairs[:, 1]]]
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)) \
        if len(pairs) else coo_matrix((n, n))
    return connected_components(graph, directed=False)[1]


def _max_irradiance(scene: SplatScene, sources: np.ndarray, point: np.ndarray,
                    colours: np.ndarray, sigma: np.ndarray) -> float:
    view = look_from(point, scene.positions[sources], colours[sources], sigma[sources],
                     scene.opacities[sources])
    return float(view.irradiance(normals_26()).max(axis=1).max())


def _light(scene: SplatScene, idx: np.ndarray, area: np.ndarray, colours: np.ndarray,
           source: str) -> Light:
    pos = scene.positions[idx].astype(np.float64)
    power_rgb = (colours[idx] * area[idx, None]).sum(0)
    w = (colours[idx].max(1) * area[idx]) + 1e-30
    centre = (pos * w[:, None]).sum(0) / w.sum()
    cov = ((pos - centre).T * w) @ (pos - centre) / w.sum()
    vals, vecs = np.linalg.eigh(cov)
    order = np.argsort(vals)[::-1]
    sig = splat_sigma(scene)[idx]
    own = float(np.sqrt((w * sig**2).sum() / w.sum()))
    extent = np.sqrt(3.0 * np.maximum(vals[order], 0.0)) + own
    total_area = float(area[idx].sum())
    return Light(position=centre, extent=extent, axes=vecs[:, order].T, power=power_rgb,
                 radiance=power_rgb / max(total_area, 1e-30), area=total_area, splats=idx,
                 power_source=source, power_uncertainty_stops=POWER_UNCERTAINTY_STOPS[source])


def search_lights(scene: SplatScene, space: CaptureSpace | None = None,
                  source: str | None = None) -> LightSearch:
    """Find the lights of ``scene`` (module docstring) and say how."""
    space = space or capture_space(scene)
    source = source or power_source(scene.metadata)
    white = white_level(scene.metadata)
    uncertainty = POWER_UNCERTAINTY_STOPS[source]
    colours = scene.base_colours.astype(np.float64)
    radiance = colours.max(axis=1)
    sigma = splat_sigma(scene)
    opacity = scene.opacities.astype(np.float64)
    area = 2.0 * np.pi * sigma**2 * opacity  # integrated alpha: the projected area
    backdrop = backdrop_mask(scene, space)
    candidates = np.flatnonzero((radiance > white) & ~backdrop)
    counts = {"splats": scene.count, "backdrop": int(backdrop.sum()),
              "candidates": int(len(candidates))}
    emitters = np.zeros(scene.count, bool)
    if len(candidates) == 0:
        return LightSearch([], emitters, backdrop, space, white, source,
                           {**counts, "clusters": 0, "clusters_tested": 0, "emitters": 0})
    labels = _components(scene.positions[candidates].astype(np.float64),
                         LINK_SIGMAS * sigma[candidates])
    n_clusters = int(labels.max()) + 1
    power = np.bincount(labels, radiance[candidates] * area[candidates], minlength=n_clusters)
    areas = np.bincount(labels, area[candidates], minlength=n_clusters)
    level_of = power / np.maximum(areas, 1e-30)
    order = np.argsort(-level_of)
    order = order[power[order] >= MIN_POWER_SHARE * power.max()][:MAX_CLUSTERS]
    boost = 2.0**uncertainty
    not_backdrop = ~backdrop
    emitting: list[np.ndarray] = []
    tests: list[dict[str, float]] = []
    for c in order:
        idx = candidates[labels == c]
        a = area[idx]
        level = float((radiance[idx] * a).sum() / max(a.sum(), 1e-30))
        w = radiance[idx] * a + 1e-30
        centre = (scene.positions[idx] * w[:, None]).sum(0) / w.sum()
        size = float(np.sqrt((w * ((scene.positions[idx] - centre) ** 2).sum(1)).sum()
                             / w.sum())) + float(np.median(LINK_SIGMAS * sigma[idx]))
        near = np.linalg.norm(scene.positions - centre, axis=1) <= size
        sources = not_backdrop & ~(near & (radiance <= level))
        sources[idx] = False
        # only sources brighter than the cluster may be that much brighter: its peers
        # (the rest of the same lamp) do not explain it by their own uncertainty
        gain = np.where(radiance > max(white, level), boost, 1.0)
        e_max = _max_irradiance(scene, sources, centre, colours * gain[:, None], sigma)
        limit = RHO_MAX * e_max / np.pi
        if level > limit:
            emitting.append(idx)
            tests.append({"mean_radiance": level, "irradiance_max": e_max,
                          "diffuse_limit": limit})
    counts.update(clusters=n_clusters, clusters_tested=int(len(order)))
    if not emitting:
        return LightSearch([], emitters, backdrop, space, white, source,
                           {**counts, "emitters": 0})
    # Group emitter clusters that lie within each other's reach into lights.
    centres = np.array([scene.positions[i].astype(np.float64).mean(0) for i in emitting])
    gap = GROUP_SHARE * space.median_depth() / 2.0
    reach = np.array([np.linalg.norm(scene.positions[i] - c, axis=1).max() + gap
                      for i, c in zip(emitting, centres, strict=True)])
    groups = _components(centres, reach)
    lights = []
    for g in range(int(groups.max()) + 1):
        members = [k for k in range(len(emitting)) if groups[k] == g]
        idx = np.concatenate([emitting[k] for k in members])
        light = _light(scene, idx, area, colours, source)
        first = max(members, key=lambda k: tests[k]["mean_radiance"])
        light.test = tests[first]
        lights.append(light)
        emitters[idx] = True
    lights.sort(key=lambda li: -float(li.power.max()))
    counts["emitters"] = int(emitters.sum())
    return LightSearch(lights, emitters, backdrop, space, white, source, counts)


def find_lights(scene: SplatScene, space: CaptureSpace | None = None) -> list[Light]:
    """The set's lights, brightest first (see :func:`search_lights`)."""
    return search_lights(scene, space).lights
