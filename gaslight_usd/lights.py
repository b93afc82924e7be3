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
   light that lights it), are left out of ``E_max``. Sources brighter than the
   photos' white (and than the cluster) were clipped in the photos, so their
   fitted radiance is a *lower bound* unless brackets measured it: each counts
   as bright as :data:`BRIGHTEST_LIGHT_STOPS` above white, but at least
   ``2 ** power_uncertainty_stops`` and at most ``2 ** headroom`` times its fit
   (:func:`clipped_gain`; the headroom is :data:`CLIPPED_HEADROOM_STOPS` for
   predicted or inferred power). A wall lit by a lamp the uplift left short is
   still explained by that lamp, while a lamp fitted far above white (its fill
   not short) does not explain a window as bright as a tenth of it. A source the
   fit weighed by the surfaces it lights (its ``fit_metrics.clipped_lights``) is no
   lower bound: its power is known to the weighing's uncertainty, and it counts only
   ``2 **`` that much brighter (:func:`weighed_gain`, which covers the splats within
   :data:`WEIGHED_REACH` of its radius); nor is one a view measured over the white (a
   darker frame aimed at it: the fit's ``measured`` entries). At the headroom, a bare
   bulb weighed 10-11 stops over its fill explained the window of its room away, and
   the rig written from the photos had no window (``gaslight2usd bench --suite chain``,
   ``light_dist_window``; ``docs/measurements.md``, sessions 36 and 46).
   A cluster within :data:`OUTLINE_REACH` sizes of a light the photos' outlines
   placed clipped in every view that frames it (the fit's ``light_seeds``,
   :mod:`gaslight_usd.fit.light_seeds`) is an emitter without this test: a bare bulb
   the uplift left a few times the white is "explained" by the clipped walls it
   lights, whose own power the test must leave open, while the photos saw a small
   light over the white wherever they framed that place.
4. **Sunk emitters are moved onto the surface they are seen through.** A flat,
   featureless light fits at any depth along the rays that see it, so a fit
   leaves some of its splats behind the wall or ceiling it is set in. Seen from
   the captured space's viewpoint, a cluster farther than the median distance
   of the opaque splats no brighter than :data:`SURFACE_STOPS` above white (and
   not emitters) within :data:`SURFACE_CONE_DEG` of its direction
   (plus its own size) is placed onto that surface along the rays and tested
   again there (:func:`onto_surfaces`; a patch of ceiling sunk over a lamp is
   nearer the lamp on it; the splats themselves are not moved), and clusters
   whose outlines overlap as seen from there, within :data:`SMEAR_DEG`, are
   one light smeared in depth, each part placed at the nearest strong part's
   distance (:data:`SMEAR_POWER_SHARE`, :func:`group_clusters`).
5. Emitter clusters closer than their own sizes plus :data:`GROUP_SHARE` of
   the captured space's median depth are **grouped into lights**, except that the
   clusters of a light the photos outlined (step 3) join others only where they
   touch (:func:`group_clusters`: a bare bulb at its fill, grouped with the floor it
   lights, was a broad light off the bulb):
   position (power-weighted centre), size (principal half-extents), power
   (radiance x projected area, summed), colour, and where the power came from.
6. **The photos have the last word** when the fit recorded where they saw light over
   the white (:mod:`gaslight_usd.sightings`, the splats' ``light_sightings``): a light
   less than :data:`SEEN_SHARE` of whose power lies where some photo saw light is not
   a light (a bright patch the fit made where every photo saw a plain wall), and a
   light two photos frame whole from far enough apart is moved, as a whole, to where
   its outlines' rays meet (a flat light's depth is what its splats cannot fix).
7. **Where its power came from**: by the HDR method (merged brackets measure it, an
   uplift predicts it), unless the fit weighed the light by the surfaces it lights
   (:mod:`gaslight_usd.fit.power`, the splats' ``fit_metrics.clipped_lights``): then
   "inferred" or "fused", with the fit's uncertainty.

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

from .capture import OPAQUE, CaptureSpace, backdrop_mask, capture_space, fit_backdrop_mask
from .sightings import Sightings
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
"""Clusters with less than this share of the brightest cluster's power are not lights,
unless the photos outlined a light there (:func:`outlined_lights`): a clipped bare
bulb's splats hold its fill, a lower bound that on the chain bench's ``bulb`` room is
6e-4 of its window's (docs/measurements.md, session 19)."""
POWER_UNCERTAINTY_STOPS = {"measured": 0.25, "predicted": 3.0, "inferred": 4.0}
"""How far a light's power may be off, by where it came from: merged brackets measure it
(a quarter stop covers the fit's error); the fast exposure predictor's median error
before its shrink is about 2 stops (README), and on the example the ``fast`` fit's lamp
lights the ceiling as a lamp about 3 stops brighter would; a clipped photo taken as is
only gives a lower bound."""
CLIPPED_HEADROOM_STOPS = 7.0
"""How much brighter than its fitted radiance a clipped source may be when it explains a
surface it lights (power not measured by brackets). The photos clipped it, so what they
give is a lower bound, and the uplift's fill is a guess that falls short: a lit wall that
such a source could explain were it this much brighter is not an emitter. The shortfall
is what ``gaslight2usd bench --suite chain`` reports per light (``power_err_<light>``,
recursive and clipped-photos rows, docs/measurements.md); the headroom covers the
largest there. It only lets sources brighter than the tested cluster explain it, so a
true emitter brighter than everything around it stays one; what it costs (an emitter
dimmer than a nearby clipped light it faces can be taken for a lit surface) is measured
by ``tests/test_lights.py`` and the panels/example check in docs/measurements.md."""
BRIGHTEST_LIGHT_STOPS = 9.0
"""How far above the photos' white a clipped light plausibly lies: a set is exposed for
its walls (their median near a fifth of white), and a bare bulb, the brightest light a set
holds, is some thousand times its walls. A clipped source counts as this bright when it
explains a lit surface, within
:data:`CLIPPED_HEADROOM_STOPS` of its fit: the fit of a source already far above white
was not left short, and is not raised further (:func:`clipped_gain`)."""
SURFACE_CONE_DEG = 8.0
"""Half-angle of the cone round an emitter's direction (from the captured space's
viewpoint) whose opaque non-emitting splats give the surface it is seen through: their
median distance, robust to the fit's depth smear of that surface. About two direction
bins of :mod:`gaslight_usd.surroundings` across: a ``fast`` fit's ceiling is sparse where
a lamp lights it (``gaslight2usd run examples/room/photos``: the patch sunk over the
lamp finds too few splats in one bin's cone)."""
SURFACE_STOPS = 1.0
"""Splats at most this many stops above the photos' white can be the surface a light is
seen through: a lit ceiling over a lamp is a little above white (the set is exposed for
its walls), while a flat light's own depth-smeared copies lie far above it and are no
surface (``gaslight2usd run`` on a ``make_room.py --variant bulb`` room: a ``fast`` fit
leaves a window-coloured sheet well in front of the window)."""
SURFACE_MIN_SPLATS = 5
"""Fewer surface splats in the cone than this: no surface there, the cluster stays."""
PLANE_NEIGHBOURS = 12
"""Surface splats nearest a light splat's direction that make the plane behind it."""
PLANE_MAX_DEG = 30.0
"""Those neighbours all lie within this angle of its direction (else: no plane)."""
PLANE_FLATNESS = 0.05
"""Their least spread (eigenvalue) is at most this share of the next: a plane, not a
corner."""
SUNK_MIN_SHARE = 0.01
"""A light's splat less than this share of its surface's distance behind it is on it."""
SUNK_MAX_SHARE = 0.15
"""A light's splat farther behind the surface it is seen through than this share of
that surface's distance is not sunk into it but seen through a gap (another room)."""
SMEAR_DEG = 2.0
"""Emitter clusters whose directions from the viewpoint are closer than their angular
radii plus this are one light smeared along the viewing rays: the photos see them
through the same pixels, so they cannot tell their depths apart (a ceiling panel fitted
partly above the ceiling: ``gaslight2usd run`` on the chain bench's ``panels`` photos
without poses, docs/measurements.md)."""
SMEAR_POWER_SHARE = 0.25
"""A light smeared along the rays is placed at its nearest part holding at least this
share of a farther part's power: the photos put a light on the first surface along the
ray, but a lone floater the fit left in front of a window does not carry the window
forward (``make_room.py --variant bulb`` photos, ``gaslight2usd run``)."""
SEEN_SHARE = 0.25
"""A light needs at least this share of its power where a photo saw light over the
white (step 6): the fit's depth smear keeps a true light's splats inside the cones of the
views that see it (all of its power on the chain bench's panels, the example's lamp and
window), while a lit wall patch the fit pushed over the white lies where the photos saw
under half the white (none of its power)."""
OUTLINE_REACH = 2.0
"""A cluster whose centre lies within this many of an outlined light's sizes is that
light (step 3)."""
WEIGHED_REACH = 3.0
"""A weighed or measured light's splats lie within this many of its radius (an RMS
spread) of its centre. Within one radius, most of a bare bulb's bright splats fell
outside, counted up to the clipped headroom instead of the weighing's uncertainty, and
explained its room's window away (``gaslight2usd bench --suite chain --scene bulb:7``,
``light_dist_window``; figures in docs/measurements.md, session 46)."""
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
    positions: np.ndarray | None = None
    """(N, 3) where the evidence puts the splats: the lights' ones moved onto the surface
    they are seen through or to where their outlines meet (steps 4 and 6), the rest as
    fitted (a light smeared along the rays is *placed* at its nearest strong part, but
    its splats are not moved there: which part is right the photos do not say; the
    chain bench's `bulb` window fitted as a sheet 1 m in front of its wall lost every
    emitter near the window that way); None when no light was found."""
    unseen: np.ndarray | None = None
    """(N,) bool: ``backdrop`` and the splats in the room's box that the captured space's
    viewpoint does not see (:meth:`gaslight_usd.capture.CaptureSpace.inside` without
    the room): no surface a clipped light is weighed by
    (:func:`gaslight_usd.fit.power.lights_to_weigh`; with them every weighing came out
    lower and the bare bulbs short: ``gaslight2usd bench --suite chain``,
    ``docs/measurements.md``); ``None``: as ``backdrop``."""

    def summary(self) -> dict[str, Any]:
        return {
            "rule": ("emitter: cluster of splats above the photos' white whose mean radiance "
                     f"exceeds {RHO_MAX} x E_max / pi, E_max the largest irradiance the rest "
                     "of the scene sends it (clipped sources, those above white, count as "
                     f"{BRIGHTEST_LIGHT_STOPS:g} stops above white, within "
                     f"2^{POWER_UNCERTAINTY_STOPS[self.power_source]:g}-"
                     f"2^{explain_headroom_stops(self.power_source):g} x their fit: "
                     "their fitted power is a lower bound); a light must lie where a photo "
                     f"saw light over the white ({SEEN_SHARE:g} of its power at least) and is "
                     "placed where two photos' whole outlines of it meet, when the fit "
                     "recorded the photos' light regions"),
            "white": self.white,
            "rho_max": RHO_MAX,
            "clipped_headroom_stops": explain_headroom_stops(self.power_source),
            "brightest_light_stops": BRIGHTEST_LIGHT_STOPS,
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
    if "bracket" in method or "measured" in method:
        return "measured"
    if "recursive" in method or "diffusion" in method or "predict" in method:
        return "predicted"
    return "inferred"


def explain_headroom_stops(source: str) -> float:
    """Stops a clipped source may be brighter when it explains a lit surface (step 3).

    Merged brackets measured the lights: their quarter-stop uncertainty. Otherwise the
    fitted radiance is a lower bound: at least :data:`CLIPPED_HEADROOM_STOPS`.
    """
    stops = POWER_UNCERTAINTY_STOPS[source]
    return stops if source == "measured" else max(stops, CLIPPED_HEADROOM_STOPS)


def clipped_gain(radiance: np.ndarray, white: float, source: str) -> np.ndarray:
    """(N,) factor by which clipped sources of fitted ``radiance`` (N,) may be brighter.

    Between ``2 ** POWER_UNCERTAINTY_STOPS[source]`` and ``2 ** headroom``
    (:func:`explain_headroom_stops`), aiming at :data:`BRIGHTEST_LIGHT_STOPS` above
    ``white``: a source the fit left near white may be far brighter, one it put far
    above white only by its stated uncertainty.
    """
    low = 2.0 ** POWER_UNCERTAINTY_STOPS[source]
    high = max(2.0 ** explain_headroom_stops(source), low)
    aim = white * 2.0**BRIGHTEST_LIGHT_STOPS / np.maximum(np.asarray(radiance, np.float64), 1e-30)
    return np.clip(aim, low, high)


def white_level(metadata: Mapping[str, Any]) -> float:
    """Radiance of the photos' white in the splats' units (1 x exposure_scale)."""
    try:
        scale = float(metadata.get("exposure_scale", 1.0) or 1.0)
    except (TypeError, ValueError):
        scale = 1.0
    return scale if scale > 0 else 1.0


def outlined_lights(metadata: Mapping[str, Any]) -> np.ndarray:
    """(K, 4) position and size of the lights the fit's outlines placed clipped in every
    view that frames them (``light_seeds`` whose views are all their framing views;
    empty for older files)."""
    rows = []
    for seed in metadata.get("light_seeds") or []:
        try:
            pos = [float(v) for v in seed["position"]]
            size, views, framed = float(seed["size"]), len(seed["views"]), int(seed["framed"])
        except (KeyError, TypeError, ValueError):
            continue
        if len(pos) == 3 and size > 0 and views >= framed:
            rows.append([*pos, size])
    return np.asarray(rows, np.float64).reshape(-1, 4)


def _near_outlined(points: np.ndarray, power: np.ndarray, labels: np.ndarray,
                   outlined: np.ndarray) -> np.ndarray:
    """(C,) bool: cluster ``labels``' power-weighted centres (of ``points`` (N, 3) by
    ``power`` (N,)) lie within :data:`OUTLINE_REACH` sizes of an ``outlined`` light."""
    n = int(labels.max()) + 1 if len(labels) else 0
    if not len(outlined) or not n:
        return np.zeros(n, bool)
    w = np.bincount(labels, power, minlength=n) + 1e-30
    centre = np.stack([np.bincount(labels, power * points[:, k], minlength=n)
                       for k in range(3)], 1) / w[:, None]
    gap = np.linalg.norm(centre[:, None] - outlined[None, :, :3], axis=2) / outlined[None, :, 3]
    return gap.min(axis=1) <= OUTLINE_REACH


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
           source: str, positions: np.ndarray | None = None) -> Light:
    pos = (scene.positions if positions is None else positions)[idx].astype(np.float64)
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


def surface_splats(radiance: np.ndarray, opacity: np.ndarray, backdrop: np.ndarray,
                   white: float) -> np.ndarray:
    """(N,) splats that can be the surface a light is seen through: opaque (above the
    captured space's ``OPAQUE``), not ``backdrop``, at most :data:`SURFACE_STOPS` above
    ``white`` (``radiance`` (N,) the splats' largest channel)."""
    return (~np.asarray(backdrop, bool) & (np.asarray(opacity) > OPAQUE)
            & (np.asarray(radiance) <= white * 2.0**SURFACE_STOPS))


def onto_surfaces(positions: np.ndarray, clusters: list[np.ndarray], viewpoint: np.ndarray,
                  surface: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Emitter clusters sunk behind the surface they are seen through, moved onto it.

    ``positions`` (N, 3) all splats; ``clusters`` index arrays into them; ``surface``
    (N,) bool, the splats that make surfaces (:func:`surface_splats`, emitters left
    out). From ``viewpoint`` (3,), a cluster's surface is the median distance of the
    surface splats within :data:`SURFACE_CONE_DEG` of its centre's direction (at least
    :data:`SURFACE_MIN_SPLATS` of them); a cluster whose centre lies farther than that
    plus its own radial spread is scaled along the rays onto it. Returns the moved
    positions (N, 3; only the sunk clusters' rows change) and (K,) bool, which moved.
    """
    out = np.asarray(positions, np.float64).copy()
    sunk = np.zeros(len(clusters), bool)
    if not clusters or not surface.any():
        return out, sunk
    vp = np.asarray(viewpoint, np.float64).reshape(3)
    d = out[surface] - vp
    r = np.linalg.norm(d, axis=1)
    keep = r > 1e-9
    u, r = d[keep] / r[keep, None], r[keep]
    centres = np.array([out[i].mean(0) for i in clusters]) - vp
    dist = np.linalg.norm(centres, axis=1)
    dirs = centres / np.maximum(dist, 1e-30)[:, None]
    inside = dirs @ u.T > np.cos(np.radians(SURFACE_CONE_DEG))  # (K, M)
    count = inside.sum(1)
    ranked = np.sort(np.where(inside, r[None], np.inf), axis=1)  # members first, by distance
    lo = np.take_along_axis(ranked, np.maximum(count - 1, 0)[:, None] // 2, axis=1)[:, 0]
    hi = np.take_along_axis(ranked, np.minimum(count // 2, len(r) - 1)[:, None], axis=1)[:, 0]
    depth = np.where(count > 0, 0.5 * (lo + hi), np.inf)  # the members' median distance
    spread = np.array([np.linalg.norm(out[i] - vp, axis=1).std() for i in clusters])
    sunk = (count >= SURFACE_MIN_SPLATS) & (dist > depth + spread)
    for k in np.flatnonzero(sunk):
        out[clusters[k]] = vp + (out[clusters[k]] - vp) * (depth[k] / dist[k])
    return out, sunk


def onto_surfaces_each(positions: np.ndarray, idx: np.ndarray, viewpoint: np.ndarray,
                       surface: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each of the splats ``idx`` that lies a little behind the surface it is seen
    through, moved onto it.

    :func:`onto_surfaces` moves whole clusters by their centres; a window's cluster
    centred on its wall can still leave a few splats a hand's width behind it (SfM
    runs of the example: 3-5 splats 7-19 cm outside the room). A window has no surface
    splats in front of its own middle, so per splat the surface is a plane: the one
    through the :data:`PLANE_NEIGHBOURS` ``surface`` splats nearest its direction from
    ``viewpoint`` (all within :data:`PLANE_MAX_DEG`, and flat: their least spread under
    :data:`PLANE_FLATNESS` of the next), met along the splat's ray. A splat behind it by
    more than :data:`SUNK_MIN_SHARE` and less than :data:`SUNK_MAX_SHARE` of its distance
    is put on it (one farther still is a light seen through a gap, in another room).
    Returns the (K, 3) new positions of ``idx`` and (K,) which moved.
    """
    out = np.asarray(positions, np.float64)[idx].copy()
    moved = np.zeros(len(idx), bool)
    if not len(idx) or int(surface.sum()) < PLANE_NEIGHBOURS:
        return out, moved
    vp = np.asarray(viewpoint, np.float64).reshape(3)
    pts = np.asarray(positions, np.float64)[surface]
    d = pts - vp
    r = np.linalg.norm(d, axis=1)
    keep = r > 1e-9
    pts, u = pts[keep], d[keep] / r[keep, None]
    if len(pts) < PLANE_NEIGHBOURS:
        return out, moved
    rel = out - vp
    dist = np.linalg.norm(rel, axis=1)
    dirs = rel / np.maximum(dist, 1e-30)[:, None]
    chord, near = cKDTree(u).query(dirs, k=PLANE_NEIGHBOURS)
    local = chord.max(1) <= 2.0 * np.sin(np.radians(PLANE_MAX_DEG) / 2.0)
    nb = pts[near]  # (K, n, 3)
    centre = nb.mean(1)
    dev = nb - centre[:, None]
    evals, evecs = np.linalg.eigh(np.einsum("kni,knj->kij", dev, dev))
    normal = evecs[:, :, 0]
    flat = evals[:, 0] <= PLANE_FLATNESS * np.maximum(evals[:, 1], 1e-30)
    facing = np.einsum("ki,ki->k", normal, dirs)
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.einsum("ki,ki->k", normal, centre - vp) / facing
    ok = local & flat & (np.abs(facing) > 0.1) & np.isfinite(depth) & (depth > 0)
    beyond = dist - depth
    moved = ok & (beyond > SUNK_MIN_SHARE * depth) & (beyond < SUNK_MAX_SHARE * depth)
    out[moved] = vp + dirs[moved] * depth[moved, None]
    return out, moved


def group_clusters(positions: np.ndarray, clusters: list[np.ndarray], sigma: np.ndarray,
                   power: np.ndarray, viewpoint: np.ndarray, gap: float,
                   outlined: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Light label (K,) of each emitter cluster and the distance (K,) each is seen at.

    Clusters are linked when their reaches (spread plus ``gap``) touch, or when their
    outlines (splats' spread plus footprints ``sigma`` (N,)) overlap within
    :data:`SMEAR_DEG` as seen from ``viewpoint`` (one light smeared along the rays): a
    cluster lying behind such one by more than its own reach, one holding at least
    :data:`SMEAR_POWER_SHARE` of its ``power`` (K,), is seen at the nearest such one's
    distance.

    A cluster within :data:`OUTLINE_REACH` sizes of a light the photos outlined
    (``outlined`` (L, 4), :func:`outlined_lights`) is that light's, and so is a cluster
    within the gap of one of those and no broader than that light; the clusters of one
    outlined light are one light, and they join any other cluster only where their
    reaches touch, without the gap and the smear. A bare bulb at the uplift's fill is
    no brighter than the floor it lights, and the gap or the smear from the cameras'
    middle joined the two into one broad light half a metre off the bulb, too wide to
    weigh (``gaslight2usd bench --suite chain --scene bulb:11``; docs/measurements.md,
    sessions 48-49); the photos' outlines say where the bulb ends.
    """
    centres = np.array([positions[i].mean(0) for i in clusters])
    reach = np.array([(np.linalg.norm(positions[i] - c, axis=1) + LINK_SIGMAS * sigma[i]).max()
                      for i, c in zip(clusters, centres, strict=True)])
    rel = centres - np.asarray(viewpoint, np.float64).reshape(3)
    dist = np.maximum(np.linalg.norm(rel, axis=1), 1e-30)
    dirs = rel / dist[:, None]
    ang = np.arctan2(reach, dist)  # angular radius as seen from the viewpoint
    between = np.arccos(np.clip(dirs @ dirs.T, -1.0, 1.0))
    apart = np.linalg.norm(centres[:, None] - centres[None], axis=2)
    touch = apart <= reach[:, None] + reach[None]
    near = apart <= reach[:, None] + reach[None] + 2.0 * gap
    smear = between <= ang[:, None] + ang[None] + np.radians(SMEAR_DEG)
    owner = _outlined_owner(centres, outlined)
    if (owner >= 0).any():
        # a cluster near an outlined light's and no broader than that light is a fragment
        # of it (a bulb's splat a little off its outline)
        size = np.where(owner >= 0, OUTLINE_REACH * outlined[np.maximum(owner, 0), 3], 0.0)
        part = near & (owner[:, None] < 0) & (owner[None] >= 0) & (reach[:, None] <= size[None])
        of = np.where(part, apart, np.inf).argmin(axis=1)
        owner = np.where(part.any(axis=1), owner[of], owner)
    same = (owner[:, None] == owner[None]) & (owner[:, None] >= 0)
    other = owner[:, None] != owner[None]
    near = np.where(other, touch, near | same)
    smear &= ~other
    behind = smear & (dist[None] < dist[:, None] - reach[:, None]) & (
        power[None] >= SMEAR_POWER_SHARE * power[:, None])
    seen_at = np.where(behind, dist[None], dist[:, None]).min(axis=1)
    return connected_components(coo_matrix(near | smear), directed=False)[1], seen_at


def _outlined_owner(centres: np.ndarray, outlined: np.ndarray | None) -> np.ndarray:
    """(K,) index of the outlined light (``outlined`` (L, 4)) whose :data:`OUTLINE_REACH`
    sizes hold each of ``centres`` (K, 3) (the nearest in sizes), -1 for none."""
    if outlined is None or not len(outlined):
        return np.full(len(centres), -1)
    sizes = np.linalg.norm(centres[:, None] - outlined[None, :, :3], axis=2) / outlined[None, :, 3]
    return np.where(sizes.min(axis=1) <= OUTLINE_REACH, sizes.argmin(axis=1), -1)


def _weighed_lights(metadata: Mapping[str, Any]) -> list[tuple[np.ndarray, float, Mapping]]:
    """``(position, radius, entry)`` of each light whose power the fit knows: weighed by
    the surfaces it lights (its ``fit_metrics.clipped_lights`` whose power was
    ``inferred`` or ``fused``, :mod:`gaslight_usd.fit.power`) or ``measured`` over the
    white by a view; malformed entries are skipped."""
    fit = metadata.get("fit_metrics")
    weighed = fit.get("clipped_lights") if isinstance(fit, Mapping) else None
    out = []
    for entry in weighed or []:
        if not isinstance(entry, Mapping) or entry.get("power_source") not in (
                "inferred", "fused", "measured"):
            continue
        try:
            where = np.asarray(entry["position"], np.float64).reshape(3)
            reach = float(entry.get("radius") or 0.0)
            float(entry["power_uncertainty_stops"])
        except (KeyError, TypeError, ValueError):
            continue
        out.append((where, reach, entry))
    return out


def weighed_gain(positions: np.ndarray, metadata: Mapping[str, Any]) -> np.ndarray:
    """(N,) how much brighter each splat of a light the fit weighed may be
    (:func:`_weighed_lights`): ``2 **`` the weighing's uncertainty (stops) within
    :data:`WEIGHED_REACH` of that light's radius; NaN elsewhere (:func:`clipped_gain`
    holds there)."""
    out = np.full(len(positions), np.nan)
    pos = np.asarray(positions, np.float64)
    for where, reach, entry in _weighed_lights(metadata):
        near = np.linalg.norm(pos - where, axis=1) <= WEIGHED_REACH * reach
        out[near] = np.fmax(out[near], 2.0 ** float(entry["power_uncertainty_stops"]))
    return out


def _weighed_by_the_fit(light: Light, metadata: Mapping[str, Any]) -> None:
    """Where the fit weighed this light by the surfaces it lights, or a view measured it
    (:func:`_weighed_lights`), the light's power came from there: its splats already
    carry the factor, and the fit's uncertainty replaces the uplift's."""
    for where, reach, entry in _weighed_lights(metadata):
        if np.linalg.norm(where - light.position) <= max(reach + light.radius, 1e-6):
            light.power_source = str(entry["power_source"])
            light.power_uncertainty_stops = round(float(entry["power_uncertainty_stops"]), 3)
            if entry["power_source"] != "measured":
                light.test["inferred_factor"] = float(entry.get("factor", 1.0))
            return


def search_lights(scene: SplatScene, space: CaptureSpace | None = None,
                  source: str | None = None) -> LightSearch:
    """Find the lights of ``scene`` (module docstring) and say how."""
    space = space or capture_space(scene)
    source = source or power_source(scene.metadata)
    white = white_level(scene.metadata)
    headroom = explain_headroom_stops(source)
    colours = scene.base_colours.astype(np.float64)
    radiance = colours.max(axis=1)
    sigma = splat_sigma(scene)
    opacity = scene.opacities.astype(np.float64)
    area = 2.0 * np.pi * sigma**2 * opacity  # integrated alpha: the projected area
    backdrop = backdrop_mask(scene, space)
    unseen = backdrop_mask(scene, space, room=False) if space.room else backdrop
    candidates = np.flatnonzero((radiance > white) & ~backdrop)
    counts = {"splats": scene.count, "backdrop": int(backdrop.sum()),
              "candidates": int(len(candidates))}
    emitters = np.zeros(scene.count, bool)
    if len(candidates) == 0:
        return LightSearch([], emitters, backdrop, space, white, source,
                           {**counts, "clusters": 0, "clusters_tested": 0, "emitters": 0},
                           unseen=unseen)
    labels = _components(scene.positions[candidates].astype(np.float64),
                         LINK_SIGMAS * sigma[candidates])
    n_clusters = int(labels.max()) + 1
    power = np.bincount(labels, radiance[candidates] * area[candidates], minlength=n_clusters)
    areas = np.bincount(labels, area[candidates], minlength=n_clusters)
    level_of = power / np.maximum(areas, 1e-30)
    order = np.argsort(-level_of)
    outlined = outlined_lights(scene.metadata)
    order = order[(power[order] >= MIN_POWER_SHARE * power.max())
                  | _near_outlined(scene.positions[candidates], radiance[candidates]
                                   * area[candidates], labels, outlined)[order]][:MAX_CLUSTERS]
    not_backdrop = ~backdrop
    headroom_gain = clipped_gain(radiance, white, source)
    known = weighed_gain(scene.positions, scene.metadata)
    headroom_gain = np.where(np.isfinite(known), known, headroom_gain)
    emitting: list[np.ndarray] = []
    tests: list[dict[str, float]] = []
    positions = scene.positions.astype(np.float64)

    def emitter_test(idx: np.ndarray, at: np.ndarray) -> dict[str, float] | None:
        """The step-3 test of cluster ``idx`` with its splats at ``at`` (K, 3)."""
        a = area[idx]
        level = float((radiance[idx] * a).sum() / max(a.sum(), 1e-30))
        w = radiance[idx] * a + 1e-30
        centre = (at * w[:, None]).sum(0) / w.sum()
        size = float(np.sqrt((w * ((at - centre) ** 2).sum(1)).sum() / w.sum())) + \
            float(np.median(LINK_SIGMAS * sigma[idx]))
        near = np.linalg.norm(positions - centre, axis=1) <= size
        sources = not_backdrop & ~(near & (radiance <= level))
        sources[idx] = False
        # only sources brighter than the cluster may be that much brighter: its peers
        # (the rest of the same lamp) do not explain it by their own shortfall
        gain = np.where(radiance > max(white, level), headroom_gain, 1.0)
        e_max = _max_irradiance(scene, sources, centre, colours * gain[:, None], sigma)
        limit = RHO_MAX * e_max / np.pi
        if level <= limit:
            return None
        return {"mean_radiance": level, "irradiance_max": e_max, "diffuse_limit": limit,
                "headroom_stops": headroom}

    for c in order:
        idx = candidates[labels == c]
        test = emitter_test(idx, positions[idx])
        if test is None and len(outlined):
            w = radiance[idx] * area[idx] + 1e-30
            centre = (positions[idx] * w[:, None]).sum(0) / w.sum()
            gap = np.linalg.norm(outlined[:, :3] - centre, axis=1) / outlined[:, 3]
            if float(gap.min()) <= OUTLINE_REACH:
                test = {"mean_radiance": float((radiance[idx] * area[idx]).sum()
                                               / max(area[idx].sum(), 1e-30)),
                        "outlined": 1.0, "headroom_stops": headroom}
        if test is not None:
            emitting.append(idx)
            tests.append(test)
    counts.update(clusters=n_clusters, clusters_tested=int(len(order)))
    if not emitting:
        return LightSearch([], emitters, backdrop, space, white, source,
                           {**counts, "emitters": 0}, unseen=unseen)
    # Sunk clusters onto the surface they are seen through; then group into lights the
    # clusters within each other's reach or overlapping along the viewing rays, each
    # group at its nearest member's distance from the viewpoint.
    viewpoint = space.viewpoints.mean(0)
    surface = surface_splats(radiance, opacity, backdrop, white)
    surface[np.concatenate(emitting)] = False
    placed, sunk = onto_surfaces(positions, emitting, viewpoint, surface)
    # a sunk cluster is tested again where it belongs: on the surface, a patch of ceiling
    # over a lamp is nearer the lamp than the fit put it, and may be lit by it
    retest = {int(k): emitter_test(emitting[k], placed[emitting[k]]) for k in np.flatnonzero(sunk)}
    keep = [k for k in range(len(emitting)) if retest.get(k, tests[k]) is not None]
    counts.update(sunk_moved=int(sunk.sum()), sunk_lit_surfaces=len(emitting) - len(keep))
    emitting, tests = [emitting[k] for k in keep], [retest.get(k) or tests[k] for k in keep]
    if not emitting:
        return LightSearch([], emitters, backdrop, space, white, source,
                           {**counts, "emitters": 0}, unseen=unseen)
    cluster_power = np.array([(radiance[i] * area[i]).sum() for i in emitting])
    groups, seen_at = group_clusters(placed, emitting, sigma, cluster_power, viewpoint,
                                     GROUP_SHARE * space.median_depth() / 2.0, outlined)
    evidence = placed.copy()  # moves the surfaces and outlines support, not the smear's
    for k, idx in enumerate(emitting):
        dist = float(np.linalg.norm(placed[idx].mean(0) - viewpoint))
        if seen_at[k] < dist:
            placed[idx] = viewpoint + (placed[idx] - viewpoint) * (seen_at[k] / dist)
    sightings = Sightings.from_metadata(scene.metadata)
    if sightings is not None:
        counts.update(unseen_not_lights=0, placed_by_outlines=0)
    lights = []
    for g in range(int(groups.max()) + 1):
        members = [k for k in range(len(emitting)) if groups[k] == g]
        idx = np.concatenate([emitting[k] for k in members])
        first = max(members, key=lambda k: tests[k]["mean_radiance"])
        test = dict(tests[first])
        if sightings is not None:
            power_of = radiance[idx] * area[idx]
            seen = float(power_of @ sightings.seen(positions[idx]) / max(power_of.sum(), 1e-30))
            test["seen_share"] = seen
            if seen < SEEN_SHARE:
                counts["unseen_not_lights"] += 1
                continue
            met = sightings.locate(positions[idx], power_of)
            if met is not None:
                w = power_of / max(power_of.sum(), 1e-30)
                placed[idx] += met["position"] - w @ placed[idx]
                evidence[idx] = placed[idx]
                test["outline_baseline_deg"] = met["baseline_deg"]
                counts["placed_by_outlines"] += 1
        light = _light(scene, idx, area, colours, source, placed)
        light.test = test
        _weighed_by_the_fit(light, scene.metadata)
        lights.append(light)
        emitters[idx] = True
    lights.sort(key=lambda li: -float(li.power.max()))
    counts["emitters"] = int(emitters.sum())
    em = np.flatnonzero(emitters)
    # the walls a window is set in lie on the captured space's edge, half of their
    # splats "outside": here every opaque, unlit splat the fit made counts
    walls = surface_splats(radiance, opacity, fit_backdrop_mask(scene), white) & ~emitters
    evidence[em], moved = onto_surfaces_each(evidence, em, viewpoint, walls)
    counts["sunk_splats_moved"] = int(moved.sum())
    return LightSearch(lights, emitters, backdrop, space, white, source, counts,
                       evidence.astype(np.float32), unseen)


def find_lights(scene: SplatScene, space: CaptureSpace | None = None) -> list[Light]:
    """The set's lights, brightest first (see :func:`search_lights`)."""
    return search_lights(scene, space).lights
