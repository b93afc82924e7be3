"""The power of clipped lights, inferred from the surfaces they light.

A photo that clips a lamp says only that the lamp is brighter than white; the
uplift's fill is a guess, and for a small bright bulb it falls many stops short.
The diffuse surfaces around it were measured, and they carry the lamp's power: a
matte surface point ``s`` with albedo ``rho_s`` has radiance

    L_s = rho_s / pi * (E_s + sum_j k_j D_js)

where ``E_s`` is the irradiance from every splat that is not a weighed light,
``D_js`` the irradiance from light ``j`` as fitted and ``k_j`` the factor its
fitted power is off by. ``E_s`` comes from a small cube map rendered at the point,
``D_js`` from a narrow view aimed at the light (fine enough that its small splats
keep their power); every splat occludes.

``L_s`` is what the *photos* measured there, not a splat's colour: a fit's splats
overlap, and any one of them may be far brighter or darker than the surface the
composite shows (on the example's ``fast`` fit, neighbouring ceiling splats read
0.01 and 0.4). Each sample is looked up in the training views that see it face on
and unoccluded (the fit's depth there agrees with the sample's), on pixels no
photo clipped; the median over those views is ``L_s``. A point fewer than
:data:`MIN_VIEWS` views see is not used: one view cannot tell a surface from a floater
in front of it. A point every such view clipped
is kept as a bound (``L_s`` at least its clip floors): near a clipped lamp the photos
clip the surfaces it lights most, and leaving those out keeps the darker ones, whose
albedos look even at too low a factor.

Albedo varies with the surface's texture, but it does not know where the lamp is:
with the right ``k`` the albedos ``pi L_s / (E_s + sum_j k_j D_js)`` do not depend
on how much of a point's light comes from the lamp. So ``k`` is chosen to make the
log-albedos as uniform as possible (the most likely normal spread of them, the bounds
censored, trimmed of the 10 % worst measured points; with no bound, the least
variance), subject to most albedos (three quarters) staying at or under 1. Where
almost all the surfaces' light is this light's, the spread no longer depends on
``k`` and that cap decides: the factor is then a lower bound, and says so. The
uniformity's uncertainty (stops) is the spread of ``log2 k`` over bootstrap resamples
of the points and :data:`SYSTEMATIC_STOPS` for what resampling cannot show.

Uniformity alone is weak where the light reaches every surface in much the same share
(a bare bulb in the middle of a room gives every surface much the same share of its
light), and then it is biased as well: noise in the gathered irradiance from the rest
of the room makes a brighter lamp, which drowns that noise, look more uniform (a
regression-dilution effect; noise in the light's own irradiance pulls the other way).
The albedos' *level* is the other half of what the surfaces say: a brighter lamp means
darker surfaces, and rooms are not built of soot. So the uniformity's estimate is
weighed with a prior on the surfaces' median albedo (:data:`ALBEDO_PRIOR_MEDIAN`,
:func:`with_albedo_prior`); where the uniformity is sharp the prior hardly moves it.

The estimate is fused with the uplift's fill (``k = 1``) as what the fill is for a
clipped light: a lower bound, not a guess with errors both ways. The fit holds every
clipped pixel at or above its clip level and the recursive uplift only raises a clipped
region until its predicted exposure stops clipping, so the fill says "at least this"
and nothing above it. The posterior of a normal estimate under a flat prior above the
fill is the estimate where it is over the fill (``inferred``, its own uncertainty) and
the fill where it is under (``fused``: the two meet at the bound). A two-sided fusion
with :data:`PREDICTOR_SIGMA_STOPS` pulled every light towards its fill, which the
chain bench's compact lights sat 6-10 stops over (``docs/measurements.md``, session 17).

Which lights: only a light that is **clipped** (no training view measured it over
the white) and **compact** (at most :data:`COMPACT_SHARE` of the captured space's
median depth across): a compact light's direct light falls off fast and unevenly
across the room, which the indirect light does not, so the surfaces tell the two
apart; a window's or a large panel's broad, smooth light looks like more indirect
light and trades off against the albedos instead (a window came out 2-4 stops too
bright that way, ``docs/measurements.md``). Those keep the uplift's power, and say
so. A light whose bootstrap spread exceeds :data:`MAX_INFERRED_SIGMA_STOPS` is not
identifiable from its surfaces and keeps its fill too, unless they put it surely over
the fill all the same (:data:`SURE_OVER_FILL_SIGMAS`). A clipped "light" that a matte
surface lit by the rest of the room and the other weighed lights could be (it reads no
brighter than albedo 1 would there: :mod:`.lamp_or_surface`) is taken for a lit surface
the photos clipped: it is not weighed, and the others are weighed again without it.

The irradiance is gathered by :mod:`.gather`; the albedos' evenness and level, and the
factors they say, are :mod:`.albedos`; a lamp is told from a lit surface by
:mod:`.lamp_or_surface`. Measured by ``gaslight2usd bench --suite chain`` (power errors
per light, and what the fit decided about each).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from ..cameras import PinholeCamera
from ..splats import SplatScene, rgb_to_sh_dc, sh_dc_to_rgb
from .albedos import (
    LOG2_K_RANGE,
    evenness_floor,
    feasible,
    solve_factors,
    with_albedo_prior,
)
from .data import scale_camera_to
from .gather import depth_map, gather_irradiance
from .lamp_or_surface import LIT_SURFACE_ALBEDO, light_reading, lit_surface_albedos

PREDICTOR_SIGMA_STOPS = 3.0
"""How far the uplift's fill of a clipped light may be off (stops, 1 sigma): the fast
predictor leaves small bright bulbs 6-8 stops short on the chain bench's rooms and is
within about 2 stops on real panoramas (``gaslight2usd bench --suite uplift``); the same
figure as :data:`gaslight_usd.lights.POWER_UNCERTAINTY_STOPS` ``["predicted"]``."""
MAX_INFERRED_SIGMA_STOPS = PREDICTOR_SIGMA_STOPS
"""A light whose inferred factor is more uncertain than this (its spread over bootstrap
resamples of the surface points, and :data:`SYSTEMATIC_STOPS`) is no surer from them
than from the fill: it keeps the uplift's fill. (At 1.5 stops the shaded lamp's weighing
fell through on some fits, sigma 1.95-2.3 about +5.6 where +6.9 was needed, and its fill
left it 5-7 stops short: ``docs/measurements.md``, session 19.)..."""
SURE_OVER_FILL_SIGMAS = 1.645
"""...unless, less sure, it still puts the light over its fill by this many of its own
sigmas (a one-sided 95 % test). The fill is a lower bound: surfaces that say "many stops
brighter, give or take more than the fill's own uncertainty" still rule the bound out.
A shaded lamp, whose surroundings the photos clip, is weighed so (``gaslight2usd bench
--suite chain --scene shade:7``; kept at its fill it was left stops short:
``docs/measurements.md``, session 42)."""
SYSTEMATIC_STOPS = 1.0
"""Error of the inference that resampling the points does not show (the gathered
irradiance's sensitivity to how far off the surface it is taken, the fitted light's
shape, the photos' blur across neighbouring albedos), added in quadrature to the
bootstrap spread. Set so that the claimed uncertainty covers the errors measured on the
chain bench's fits against each light's true power (``gaslight2usd bench --suite
chain``; ``docs/measurements.md``, session 21)."""
COMPACT_SHARE = 0.15
"""A light is weighed only when its radius, and that of the clipped region the photos saw
it in (:func:`clipped_extent`), is at most this share of the captured space's median
depth (a bulb, a shade, a 0.4 m panel in a 2.5 m room; not a window)."""
SAMPLE_POINTS = 3000
"""Surface splats drawn as candidates (cheap: the photos are looked up at each)."""
GATHERED_POINTS = 960
"""At most this many of the candidates the photos measured are gathered (their
irradiance costs a cube map and an aimed view each); where fewer qualify (a room whose
photos clip or see few flat surfaces) all are used. Drawing a fixed 400 candidates
left the shaded-lamp room 55-61 usable points and its factor's spread over the 1.5-stop
limit in one draw of four (``docs/measurements.md``, session 17). Where a fit has more
usable surface, more points steady a bare bulb's factor from fit to fit: the old caps
(1000 and 320) let it swing by most of a stop (``gaslight2usd bench --suite chain``;
``docs/measurements.md``, session 35)."""
NEIGHBOURS = 32
"""Opaque splats a sample's normal is fitted to (the smallest principal axis). 16 was too
few on a ``balanced`` fit, whose splats are small: the neighbourhood spans less than the
fit's scatter off the wall, and the samples' normals leaned off their walls
(``docs/measurements.md``, session 22)."""
FLATNESS = 0.3
"""A sample's neighbourhood is a surface when its smallest principal variance is at most
this share of the middle one."""
DEPTH_AGREEMENT = 0.05
"""A view sees a sample when the fit's depth at its pixel is within this share of the
sample's own depth (nothing in front of it)."""
FACING = 0.3
"""...and looks at it no more obliquely than this cosine."""
MIN_VIEWS = 2
"""A sample is weighed only where at least this many training views see it (measured or
clipped). A point only one view sees has no second view to place it: on the chain
bench's fits most such points were floaters off the room's shell, and their irradiance,
gathered at the wrong place, misleads the weighing (``docs/measurements.md``, session
22)."""
MAX_LIGHTS = 6
MIN_SAMPLES = 20
JUST_CLIPPED_FILL = 1.5
"""A clipped light whose brightest splat the uplift filled under this many times the
photos' white is not weighed: the uplift read its clipped region as a surface that just
clipped (a flat near-white surround), not a source, and the fill stands. Weighed, such
specks take the light of whatever else the photos clipped (a sunlit floor the uplift
left short made a patch of ceiling over it a false lamp) or share a real lamp's factor;
real bulbs and panels are filled well over the white. Measured by ``gaslight2usd bench
--suite chain`` (``false_lights_weighed``; figures in ``docs/measurements.md``)."""



@dataclass
class LightPower:
    """One clipped light and where its power came from."""

    position: np.ndarray
    splats: np.ndarray
    """Indices into the scene."""
    radius: float = 0.0
    factor: float = 1.0
    """What its splats' radiance was multiplied by."""
    source: str = "predicted"
    """``predicted`` (the uplift's fill), ``inferred`` (the lit surfaces), or ``fused``
    (the surfaces said less than the fill, a lower bound: the fill stands)."""
    uncertainty_stops: float = PREDICTOR_SIGMA_STOPS
    details: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {"position": [round(float(v), 4) for v in self.position],
                "radius": round(float(self.radius), 4),
                "splats": int(len(self.splats)), "factor": round(self.factor, 4),
                "power_source": self.source,
                "power_uncertainty_stops": round(self.uncertainty_stops, 3), **self.details}


def light_sighting(position: np.ndarray, cameras: list[PinholeCamera],
                   images: list[np.ndarray], floors: list[np.ndarray | None],
                   weights: np.ndarray, white: float) -> str:
    """How the training views saw the light at ``position``: ``"measured"`` where one
    read it over ``white`` unclipped (a darker frame shot for the light, or an
    auto-exposure that dropped), ``"clipped"`` where every view that frames it clipped
    there or read no more than white, ``"unseen"`` where none frames it.

    An unseen light is not weighed: nothing says its photos clipped, and a fit's stray
    bright splats outside every view, far from any emitter, were weighed many stops up
    to light the corner they sit in (``docs/measurements.md``, session 21)."""
    framed = False
    for cam, img, floor in zip(cameras, images, floors, strict=True):
        uv, z = cam.project(np.asarray(position, np.float64)[None])
        h, w = img.shape[:2]
        x, y = int(uv[0, 0] * w / cam.width), int(uv[0, 1] * h / cam.height)
        if not (z[0] > 0 and 0 <= x < w and 0 <= y < h):
            continue
        framed = True
        block = (slice(max(0, y - 1), y + 2), slice(max(0, x - 1), x + 2))
        clipped = floor is not None and bool((floor[block] > 0).any())
        if not clipped and float((img[block] @ weights).max()) > 2.0 * white:
            return "measured"
    return "clipped" if framed else "unseen"


def light_is_clipped(position: np.ndarray, cameras: list[PinholeCamera],
                     images: list[np.ndarray], floors: list[np.ndarray | None],
                     weights: np.ndarray, white: float) -> bool:
    """Whether views frame the light at ``position`` and none measured it over ``white``
    (:func:`light_sighting`)."""
    return light_sighting(position, cameras, images, floors, weights, white) == "clipped"


def clipped_extent(position: np.ndarray, cameras: list[PinholeCamera],
                   floors: list[np.ndarray | None]) -> float:
    """Radius (scene units) of the clipped region a light at ``position`` lies in, as the
    views that frame it see it: the region's pixel area at the light's distance, as a disc.

    A fit may cut one bright region into several lights (a window's corner fitted as a
    light of its own, 0.17 m across in a 1.2 m window); the photos' clipped region says
    how large the source it belongs to is. One view may merge the light with another
    clipped source behind it (a shaded lamp seen against the window: 0.7 m where two other
    views saw 0.12), another may foreshorten or crop it, so the second smallest reading
    counts (the only one when one view frames it). 0 where no view has it on a clipped
    pixel.
    """
    readings = []
    for cam, floor in zip(cameras, floors, strict=True):
        if floor is None:
            continue
        h, w = floor.shape
        uv, z = cam.project(np.asarray(position, np.float64)[None])
        x, y = int(uv[0, 0] * w / cam.width), int(uv[0, 1] * h / cam.height)
        if not (z[0] > 0 and 0 <= x < w and 0 <= y < h):
            continue
        labels, _ = ndimage.label(floor > 0, structure=np.ones((3, 3)))
        near = labels[max(0, y - 1):y + 2, max(0, x - 1):x + 2]
        if not near.any():
            continue
        area_px = int(np.isin(labels, near[near > 0]).sum())
        pixel = z[0] * cam.width / (w * cam.fx)  # one fitting pixel's width at the light
        readings.append(math.sqrt(area_px / math.pi) * pixel)
    readings.sort()
    return readings[1] if len(readings) > 1 else (readings[0] if readings else 0.0)


def surface_samples(scene: SplatScene, candidates: np.ndarray, opaque: np.ndarray, count: int,
                    rng: np.random.Generator, eye: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Indices (of ``candidates``, a bool mask) and unit normals of splats on flat surfaces.

    The normal is the smallest principal axis of the :data:`NEIGHBOURS` nearest ``opaque``
    splats (a fit's single splats are not flat enough to say), turned towards ``eye``;
    samples whose neighbourhood is not flat (:data:`FLATNESS`) are dropped.
    """
    cand = np.flatnonzero(candidates)
    others = np.flatnonzero(opaque)
    if len(cand) == 0 or len(others) < NEIGHBOURS:
        return np.zeros(0, np.int64), np.zeros((0, 3))
    if len(cand) > count:
        cand = np.sort(rng.choice(cand, count, replace=False))
    pos = scene.positions.astype(np.float64)
    _, nb = cKDTree(pos[others]).query(pos[cand], k=NEIGHBOURS)
    local = pos[others][nb]
    local = local - local.mean(1, keepdims=True)
    vals, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local))
    flat = vals[:, 0] <= FLATNESS * np.maximum(vals[:, 1], 1e-30)
    normals = vecs[:, :, 0]
    normals *= np.sign(np.sum(normals * (eye - pos[cand]), 1, keepdims=True) + 1e-12)
    return cand[flat], normals[flat]


def measured_radiance(scene: SplatScene, points: np.ndarray, normals: np.ndarray,
                      cameras: list[PinholeCamera], images: list[np.ndarray],
                      floors: list[np.ndarray | None], weights: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """``(P,)`` luminance the photos measured at each surface point (module docstring),
    and ``(P,)`` a lower bound where they only clipped it.

    A view reads a point it sees face on and unoccluded: the mean of its 3x3 pixel block
    where no pixel of the block clipped (a measurement), else a bound on that mean (its
    clipped pixels at their clip floors, the rest as measured). The measurement is the
    median over the views that measured the point; the bound, for points no view
    measured, the median of the views' bounds. NaN where fewer than :data:`MIN_VIEWS`
    views qualify (or, for the bound, where a view measured the point)."""
    readings = np.full((len(cameras), len(points)), np.nan)
    bounds = np.full((len(cameras), len(points)), np.nan)
    for v, (cam, img, floor) in enumerate(zip(cameras, images, floors, strict=True)):
        h, w = img.shape[:2]
        cam_px = scale_camera_to(cam, w, h)
        uv, z = cam_px.project(points)
        x, y = np.floor(uv[:, 0]).astype(int), np.floor(uv[:, 1]).astype(int)
        to_cam = cam.center[None] - points
        facing = np.sum(normals * to_cam, 1) / np.linalg.norm(to_cam, axis=1)
        ok = (z > 0) & (x >= 1) & (x < w - 1) & (y >= 1) & (y < h - 1) & (facing >= FACING)
        if not ok.any():
            continue
        x, y = np.where(ok, x, 1), np.where(ok, y, 1)
        depth = depth_map(scene, cam_px)
        ok &= np.abs(depth[y, x] - z) <= DEPTH_AGREEMENT * z
        lum = (img @ weights).astype(np.float64)
        measured = ok
        if floor is not None:
            clipped = ok & ndimage.maximum_filter(floor > 0, size=3)[y, x]
            # the block's mean is at least its measured pixels' and its clip floors' mean
            recorded = ndimage.uniform_filter(np.where(floor > 0, floor, lum), size=3)
            bounds[v, clipped] = recorded[y[clipped], x[clipped]]
            measured = ok & ~clipped
        block_mean = ndimage.uniform_filter(lum, size=3)
        readings[v, measured] = block_mean[y[measured], x[measured]]
    placed = (np.isfinite(readings) | np.isfinite(bounds)).sum(axis=0) >= MIN_VIEWS
    readings[:, ~placed] = np.nan
    bounds[:, ~placed] = np.nan
    out = np.full(len(points), np.nan)
    seen = np.isfinite(readings).any(axis=0)
    out[seen] = np.nanmedian(readings[:, seen], axis=0)
    bound = np.full(len(points), np.nan)
    only_clipped = ~seen & np.isfinite(bounds).any(axis=0)
    bound[only_clipped] = np.nanmedian(bounds[:, only_clipped], axis=0)
    return out, bound



@dataclass
class Weighing:
    """The factors (log2 over the fills) the surfaces say, per weighed light."""

    uniform: np.ndarray
    """The albedos' uniformity's best factor."""
    uniform_sigma: np.ndarray
    """...its spread over bootstrap resamples and :data:`SYSTEMATIC_STOPS` (stops)."""
    at_least: np.ndarray
    """Where the uniformity ran off the search's top, the floor it says (NaN elsewhere)."""
    best: np.ndarray
    """The uniformity weighed with the albedos' level (:func:`with_albedo_prior`)."""
    sigma: np.ndarray
    """...and its spread (stops)."""


def weigh_factors(radiance: np.ndarray, bound: np.ndarray, irr: np.ndarray,
                  rng: np.random.Generator, bootstrap: int = 32) -> Weighing:
    """The surfaces' factors for the lights of ``irr`` ``(P, 1 + L)`` (module docstring)."""
    uniform = solve_factors(radiance, bound, irr)
    boots = [solve_factors(radiance[pick], bound[pick], irr[pick], grid_step=0.25)
             for pick in (rng.integers(0, len(radiance), len(radiance))
                          for _ in range(bootstrap))]
    # half the central 68 % of the resamples' factors: a few resamples that run off to the
    # search's ends inflate a standard deviation (docs/measurements.md, session 14)
    spread = np.diff(np.quantile(np.asarray(boots), [0.16, 0.84], axis=0), axis=0)[0] / 2.0
    uniform_sigma = np.hypot(spread, SYSTEMATIC_STOPS)
    at_least = evenness_floor(uniform, radiance, bound, irr)
    best, sigma = with_albedo_prior(uniform, uniform_sigma, radiance, bound, irr,
                                    at_least=at_least)
    return Weighing(uniform, uniform_sigma, at_least, best, sigma)


def _columns(irr: np.ndarray, active: list[int]) -> np.ndarray:
    """``irr`` with only the ``active`` lights apart; the others' light (at their fills)
    joins the rest of the room's."""
    others = [1 + j for j in range(irr.shape[1] - 1) if j not in active]
    rest = irr[:, 0] + irr[:, others].sum(1)
    return np.column_stack([rest, irr[:, [1 + j for j in active]]])


def _accepted(log2_k: float, sigma: float) -> bool:
    """Whether the surfaces pin a factor: inside the search, and sure enough or surely
    over the fill (:data:`SURE_OVER_FILL_SIGMAS`)."""
    return bool(LOG2_K_RANGE[0] < log2_k < LOG2_K_RANGE[1]) and (
        sigma <= MAX_INFERRED_SIGMA_STOPS or log2_k >= SURE_OVER_FILL_SIGMAS * sigma)


def infer_light_power(scene: SplatScene, lights: list[LightPower],
                      cameras: list[PinholeCamera], images: list[np.ndarray],
                      floors: list[np.ndarray | None], weights: np.ndarray,
                      surfaces: np.ndarray, opaque: np.ndarray, extent: float,
                      seed: int = 0, bootstrap: int = 32) -> SplatScene:
    """Weigh ``lights`` (clipped, compact: :func:`lights_to_weigh`) by the surfaces they
    light and rescale their splats by the factor fused with the fill's bound (module
    docstring).

    ``cameras``/``images``/``floors``: the training views (HDR, their clip floors);
    ``surfaces``: (N,) splats that may be sampled as lit surfaces (measured, inside the
    captured space, no light's); ``opaque``: (N,) splats a sample's
    normal is fitted to; ``extent``: the scene's size (the gathering's offset off the
    surface). Each light's ``factor``, ``source``, ``uncertainty_stops`` and ``details``
    are set in place; returns the rescaled scene.
    """
    lights = lights[:MAX_LIGHTS]
    if not lights:
        return scene
    rng = np.random.default_rng(seed)
    eye = np.mean([c.center for c in cameras], axis=0)
    cand, normals = surface_samples(scene, surfaces, opaque, SAMPLE_POINTS, rng, eye)
    points = scene.positions[cand].astype(np.float64)
    radiance, bound = measured_radiance(scene, points, normals, cameras, images, floors,
                                        weights)
    seen = (np.isfinite(radiance) & (radiance > 0)) | (np.isfinite(bound) & (bound > 0))
    keep = np.flatnonzero(seen)
    if len(keep) > GATHERED_POINTS:
        keep = np.sort(rng.choice(keep, GATHERED_POINTS, replace=False))
    cand, normals, points = cand[keep], normals[keep], points[keep]
    radiance, bound = radiance[keep], bound[keep]
    if len(cand) < MIN_SAMPLES:
        for light in lights:
            light.details["note"] = (f"too few measured surfaces ({len(cand)}) to weigh it: "
                                     "the uplift's power stands")
        return scene
    offsets = 2.0 * scene.scales[cand].max(1) + 0.01 * extent
    irr = gather_irradiance(scene, [light.splats for light in lights], points, normals,
                            offsets, weights)
    useful = np.all(np.isfinite(irr), axis=1) & (irr[:, 0] + irr[:, 1:].sum(1) > 0)
    radiance, bound, irr = radiance[useful], bound[useful], irr[useful]
    if np.isfinite(radiance).sum() < MIN_SAMPLES:
        for light in lights:
            light.details["note"] = (f"too few measured surfaces "
                                     f"({int(np.isfinite(radiance).sum())}) to weigh "
                                     "it: the uplift's power stands")
        return scene
    # what lights each light's own place, to tell a lamp from a surface the lamps lit
    seen_at = [light_reading(light.position, cameras, images, floors, weights)
               for light in lights]
    readings = np.array([r for r, _ in seen_at])
    faces = np.array([np.zeros(3) if f is None else f for _, f in seen_at])
    radii = np.array([light.radius for light in lights])
    at_lights = gather_irradiance(scene, [light.splats for light in lights],
                                  np.array([light.position for light in lights], np.float64),
                                  faces, radii + 0.01 * extent, weights)
    at_lights[[f is None for _, f in seen_at]] = np.nan
    active = list(range(len(lights)))
    while True:
        weighed = weigh_factors(radiance, bound, _columns(irr, active), rng, bootstrap)
        factors = np.ones(len(lights))
        for i, j in enumerate(active):
            if _accepted(weighed.best[i], weighed.sigma[i]):
                factors[j] = 2.0 ** max(0.0, float(weighed.best[i]))
        albedos = lit_surface_albedos(readings, at_lights, factors)
        for j in active:
            lights[j].details["lit_surface_albedo"] = (round(float(albedos[j]), 3)
                                                       if np.isfinite(albedos[j]) else None)
        lit = [j for j in active if albedos[j] <= LIT_SURFACE_ALBEDO]
        if not lit:
            break
        # the likeliest surface goes first: the others' weighing changes without it
        surface = min(lit, key=lambda j: albedos[j])
        lights[surface].details["note"] = (
            "a matte surface lit by the rest of the room and the other lights would read "
            f"as bright as the photos read it (albedo {albedos[surface]:.2f}): taken for a "
            "lit surface the photos clipped, not weighed; the uplift's power stands")
        active.remove(surface)
        if not active:
            return scene
    out = scene.subset(np.arange(scene.count))
    uniform, best, columns = weighed.uniform, weighed.best, _columns(irr, active)
    for i, j in enumerate(active):
        light = lights[j]
        sigma_inf = float(weighed.sigma[i])
        lower = uniform.copy()  # did the albedo cap, not their spread, decide?
        lower[i] -= 0.25
        light.details.update({"inferred_log2_factor": round(float(best[i]), 3),
                              "inferred_sigma_stops": round(sigma_inf, 3),
                              "uniformity_log2_factor": round(float(uniform[i]), 3),
                              "uniformity_sigma_stops": round(float(weighed.uniform_sigma[i]),
                                                              3),
                              "uniformity_ran_off": bool(np.isfinite(weighed.at_least[i])),
                              "uniformity_at_least": (round(float(weighed.at_least[i]), 3)
                                                      if np.isfinite(weighed.at_least[i])
                                                      else None),
                              "surface_points": int(np.isfinite(radiance).sum()),
                              "clipped_surface_points": int(np.isfinite(bound).sum()),
                              # the albedo cap, not the albedos' spread, decided: little
                              # light but this one's reaches the surfaces, so the factor
                              # is the least that keeps them matte (a lower bound); or
                              # the uniformity ran off and nothing weighed above its floor
                              "lower_bound": (bool(best[i] == weighed.at_least[i])
                                              or not feasible(lower, radiance, bound,
                                                              columns))})
        if not _accepted(best[i], sigma_inf):
            light.details["note"] = ("its surfaces do not pin its power (the search ran off "
                                     "its range, or it is uncertain by over "
                                     f"{MAX_INFERRED_SIGMA_STOPS:g} stops and not surely "
                                     "over its fill): the uplift's power stands")
            continue
        # the fill is a lower bound (module docstring): the surfaces' word above it, the
        # fill where they say less
        log2_k = max(0.0, float(best[i]))
        light.factor = float(2.0 ** log2_k)
        light.uncertainty_stops = sigma_inf
        light.source = "inferred" if best[i] > 0.0 else "fused"
        out.sh[light.splats] = scaled_sh(scene.sh[light.splats], light.factor)
    return out


def lights_to_weigh(scene: SplatScene, cameras: list[PinholeCamera], images: list[np.ndarray],
                    floors: list[np.ndarray | None], weights: np.ndarray
                    ) -> tuple[list[LightPower], list[LightPower], np.ndarray, np.ndarray]:
    """The lights finder's lights (:func:`gaslight_usd.lights.search_lights`, so ``scene``
    carries the fit's camera centres and sightings), split into those to weigh (clipped
    in every view that frames them, compact) and the rest (each with a note saying why
    not); plus the splats that may be sampled as surfaces and the opaque ones."""
    from ..lights import search_lights

    search = search_lights(scene)
    white = search.white
    size = COMPACT_SHARE * search.space.median_depth()
    radiance = scene.base_colours.max(axis=1)
    weigh, keep = [], []
    for light in search.lights:
        entry = LightPower(position=light.position, splats=light.splats, radius=light.radius)
        sighting = light_sighting(light.position, cameras, images, floors, weights, white)
        if sighting == "measured":
            entry.source, entry.uncertainty_stops = "measured", 0.25
            entry.details["note"] = "a view measured it over the white"
            keep.append(entry)
        elif sighting == "unseen":
            entry.details["note"] = ("no training view frames it, so none says it clipped: "
                                     "not weighed; the uplift's power stands")
            keep.append(entry)
        elif not max(light.radius, clipped_extent(light.position, cameras, floors)) <= size:
            entry.details["note"] = (f"wider than {COMPACT_SHARE:g} of the room's depth, or "
                                     "part of a clipped region that is (a window, a large "
                                     "panel): its broad light is not told from the "
                                     "indirect light; the uplift's power stands")
            keep.append(entry)
        elif float(radiance[light.splats].max()) < JUST_CLIPPED_FILL * white:
            entry.details["note"] = (
                f"the uplift filled it under {JUST_CLIPPED_FILL:g} x the white, as a "
                "surface that just clipped, not a source: not weighed; the uplift's power "
                "stands")
            keep.append(entry)
        else:
            weigh.append(entry)
    # the surfaces the captured space's viewpoint sees, not all of the room's box
    # (LightSearch.unseen)
    unseen = search.backdrop if search.unseen is None else search.unseen
    opaque = ~unseen & (scene.opacities > 0.5)
    # bright surfaces too: the photos clipped the ones a lamp lights most, and they count
    # as bounds (:func:`albedo_scores`); leaving them out biases the factor low
    surfaces = opaque & ~search.emitters
    return weigh, keep, surfaces, opaque


def scaled_sh(sh: np.ndarray, factor: float) -> np.ndarray:
    """SH coefficients ``(N, K, 3)`` whose radiance is ``factor`` x theirs (3DGS's DC
    carries a +0.5 offset, so the DC term is rescaled through the colour)."""
    out = sh * np.float32(factor)
    out[:, 0] = rgb_to_sh_dc(sh_dc_to_rgb(sh[:, 0]) * np.float32(factor))
    return out.astype(np.float32)
