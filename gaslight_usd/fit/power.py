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
identifiable from its surfaces and keeps its fill too. A clipped "light" that a matte
surface lit by the rest of the room and the other weighed lights could be (it reads no
brighter than albedo 1 would there: :mod:`.lamp_or_surface`) is taken for a lit surface
the photos clipped: it is not weighed, and the others are weighed again without it.

Measured by ``gaslight2usd bench --suite chain`` (power errors per light).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from scipy import ndimage
from scipy.spatial import cKDTree
from scipy.special import expit, log_ndtr

from ..cameras import PinholeCamera
from ..render import SplatParams, render
from ..render.envmap import cube_face_cameras
from ..render.many import render_many
from ..splats import SplatScene, rgb_to_sh_dc, sh_dc_to_rgb
from .data import scale_camera_to
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
left it 5-7 stops short: ``docs/measurements.md``, session 19.)"""
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
CUBE_SIZE = 12
LIGHT_VIEW_SIZE = 24
"""The least size (pixels across) of the view aimed at a light (:func:`light_view_size`)."""
MAX_LIGHT_VIEW_SIZE = 192
LIGHT_PIXELS_PER_GRAIN = 3.0
"""How many pixels a light's typical splat (its median largest scale) spans at least in
the view aimed at it. Coarser, a cluster of tiny nearly opaque splats turns translucent
(even in the antialiased mode each splat is widened to about a pixel and its opacity
cut), the splats behind shine through and the light gains power, and its factor comes
out low (a ``balanced`` fit's small bulb splats at a fixed 24 pixels:
``docs/measurements.md``, session 22)."""
POINTS_PER_BATCH = 64
"""Surface points whose cube maps are drawn in one pass (:mod:`gaslight_usd.render.many`)."""
SAMPLE_POINTS = 1000
"""Surface splats drawn as candidates (cheap: the photos are looked up at each)."""
GATHERED_POINTS = 320
"""At most this many of the candidates the photos measured are gathered (their
irradiance costs a cube map and an aimed view each); where fewer qualify (a room whose
photos clip or see few flat surfaces) all are used. Drawing a fixed 400 candidates
left the shaded-lamp room 55-61 usable points and its factor's spread over the 1.5-stop
limit in one draw of four (``docs/measurements.md``, session 17)."""
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
LOG2_K_RANGE = (-2.0, 16.0)
"""The factors searched (log2 over the fill). A bare bulb can be 15 stops over the
room's median, its fill a few over the white: the chain bench's ``bulb`` room needed
11-13, and a search that ran off its end at 12 left the lamp at its fill, 8 stops
short (``docs/measurements.md``, session 19)."""
ALBEDO_QUANTILE = 0.75
"""This share of the sampled albedos must stay at or under 1 for a factor to be possible
(a matte surface reflects at most what reaches it)."""
ALBEDO_PRIOR_MEDIAN = 0.3
"""What a room's surfaces reflect, before the photos say: a median albedo of 0.3
(interiors run from dark floors and wood near 0.1-0.2 to painted walls and ceilings near
0.5-0.8; 18 % is the photographer's average scene). It decides only where the albedos'
uniformity cannot: a bare bulb that lights every surface alike leaves the uniformity
flat over several stops, and its factor wandered with each draw of surface points
(``docs/measurements.md``, session 21)."""
ALBEDO_PRIOR_STOPS = 1.0
"""...within this many stops either way (1 sigma)."""
LEVEL_MEASURED_SHARE = 0.5
"""The albedos' level is weighed in only where the photos measured at least this share of
the surface points (the rest are bounds: clipped in every view). Around a shaded lamp
the photos clip most of them; the level a censored fit puts on the rest is then an
extrapolation, and on a held-out room it pulled an accurate uniformity stops over
(``docs/measurements.md``, session 21)."""
ALIKE_TOLERANCE = 0.05
"""Lights weighed together get one factor (over their own fills) where that scores within
this much (negative log-likelihood per point) of the best separate factors. Where the
surfaces see several lights alike they pin the sum of their light, not its split, and
the score is flat along the split: on the chain bench's ``panels`` room (seed 1) the
best split, (+3.5, -2.0) stops for two ceiling panels that each needed about +4, beat
one factor for both (+2.4) by 0.026; the coordinate search had given the first panel
all of it (``docs/measurements.md``, session 19). A tolerance, not calibrated further."""
MIN_SAMPLES = 20
MIN_SIGMA = 0.02
"""Least spread of the log2-albedos a fit may claim (stops)."""
FALSE_BOUND_SHARE = 0.05
"""Prior share of the clipped surface points whose bound is false (the pixel clipped
for a light in front of the surface): :func:`censored_fit`."""
GENUINE_LOGIT = math.log1p(-FALSE_BOUND_SHARE) - math.log(FALSE_BOUND_SHARE)
"""The prior log-odds that a bound is genuine."""


def _normal_logsf(a: np.ndarray) -> np.ndarray:
    """log P(Z > a) for a standard normal (``scipy.stats`` costs a second to import)."""
    return log_ndtr(-a)


def _normal_logpdf(a: np.ndarray) -> np.ndarray:
    return -0.5 * a * a - 0.5 * math.log(2.0 * math.pi)


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


def depth_map(scene: SplatScene, camera: PinholeCamera) -> np.ndarray:
    """``(H, W)`` alpha-weighted depth of the splats seen by ``camera`` (inf where none)."""
    z = (scene.positions.astype(np.float64) @ camera.R.T + camera.t)[:, 2]
    params = channel_scene(scene, np.repeat(np.maximum(z, 0.0)[:, None], 3, 1))
    with torch.no_grad():
        out = render(params, camera, background=0.0)
    alpha = out.alpha.cpu().numpy()
    return np.where(alpha > 0.5, out.image[..., 0].cpu().numpy() / np.maximum(alpha, 1e-6),
                    np.inf)


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


def pixel_directions(cams: list[PinholeCamera]) -> tuple[np.ndarray, np.ndarray]:
    """World directions ``(B, H W, 3)`` and solid angles ``(B, H W)`` of the pixels of
    ``B`` cameras of one size."""
    x, y = np.meshgrid(np.arange(cams[0].width) + 0.5, np.arange(cams[0].height) + 0.5)
    intr = np.array([[c.fx, c.fy, c.cx, c.cy] for c in cams], np.float64)[:, None]
    u = (x.ravel()[None] - intr[..., 2]) / intr[..., 0]
    v = (y.ravel()[None] - intr[..., 3]) / intr[..., 1]
    rays = np.stack([u, v, np.ones_like(u)], -1)  # (B, HW, 3) camera frame
    d = np.einsum("bpi,bij->bpj", rays, np.stack([c.R for c in cams]))  # camera -> world
    norm = np.linalg.norm(d, axis=-1)
    return d / norm[..., None], 1.0 / (intr[..., 0] * intr[..., 1]) / norm ** 3


def aimed_camera(position: np.ndarray, target: np.ndarray, half_angle: float, size: int
                 ) -> PinholeCamera:
    """A square pinhole at ``position`` looking at ``target``, ``2 half_angle`` wide."""
    fwd = (target - position) / np.linalg.norm(target - position)
    up = np.array([0.0, 1.0, 0.0]) if abs(fwd[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    rot = np.stack([right, np.cross(fwd, right), fwd])
    f = (size / 2.0) / math.tan(half_angle)
    return PinholeCamera(size, size, f, f, size / 2.0, size / 2.0, rot, -rot @ position)


def light_view_size(half_angles: np.ndarray, distances: np.ndarray, grain: float) -> int:
    """Pixels across the views aimed at a light from ``distances`` with ``half_angles``,
    so that its typical splat (``grain`` across, scene units) spans
    :data:`LIGHT_PIXELS_PER_GRAIN` pixels in each, within [:data:`LIGHT_VIEW_SIZE`,
    :data:`MAX_LIGHT_VIEW_SIZE`]."""
    if len(distances) == 0 or grain <= 0:
        return LIGHT_VIEW_SIZE
    needed = 2.0 * np.tan(half_angles) * distances * LIGHT_PIXELS_PER_GRAIN / grain
    return int(np.clip(math.ceil(float(needed.max())), LIGHT_VIEW_SIZE, MAX_LIGHT_VIEW_SIZE))


def channel_scene(scene: SplatScene, channels: np.ndarray) -> SplatParams:
    """The scene's geometry with view-independent colours ``channels`` (N, 3), drawn in the
    antialiased mode (a splat's footprint keeps its integral at any pixel size)."""
    sh = np.zeros((scene.count, 1, 3), np.float32)
    sh[:, 0] = rgb_to_sh_dc(channels.astype(np.float32))
    return SplatParams.from_scene(SplatScene(scene.positions, scene.rotations, scene.log_scales,
                                             scene.opacity_logits, sh,
                                             metadata={"antialiased": True}))


def gather_irradiance(scene: SplatScene, groups: list[np.ndarray], points: np.ndarray,
                      normals: np.ndarray, offsets: np.ndarray, weights: np.ndarray
                      ) -> np.ndarray:
    """``(P, 1 + L)`` irradiance luminance at each point: from everything but the
    clipped lights (a coarse cube map: it is smooth), then from each light as fitted
    (a narrow view aimed at the light, fine enough that its small splats keep their
    power); every splat occludes. NaN where a point is too close to a light."""
    lum = scene.base_colours @ weights
    is_light = np.zeros(scene.count, bool)
    for g in groups:
        is_light[g] = True
    chans = np.zeros((scene.count, 3), np.float32)
    chans[~is_light, 0] = lum[~is_light]
    for j, g in enumerate(groups[:2]):
        chans[g, 1 + j] = lum[g]
    rest = channel_scene(scene, chans)
    extra = []
    for start in range(2, len(groups), 3):
        more = np.zeros((scene.count, 3), np.float32)
        for c, g in enumerate(groups[start:start + 3]):
            more[g, c] = lum[g]
        extra.append(channel_scene(scene, more))
    centres = [scene.positions[g].astype(np.float64).mean(0) for g in groups]
    radii = [float(np.linalg.norm(scene.positions[g] - c, axis=1).max()
                   + 3.0 * scene.scales[g].max()) for g, c in zip(groups, centres, strict=True)]
    grains = [float(np.median(scene.scales[g].max(1))) for g in groups]
    cube_dirs, cube_omega = pixel_directions(cube_face_cameras(np.zeros(3), CUBE_SIZE))
    cube_dirs, cube_omega = cube_dirs.reshape(-1, 3), cube_omega.ravel()
    out = np.full((len(points), 1 + len(groups)), np.nan)
    eyes = points + normals * offsets[:, None]
    nears = 0.5 * offsets
    for lo in range(0, len(points), POINTS_PER_BATCH):
        part = slice(lo, min(lo + POINTS_PER_BATCH, len(points)))
        faces = [cam for eye in eyes[part] for cam in cube_face_cameras(eye, CUBE_SIZE)]
        cubes = render_many(rest, faces, near=np.repeat(nears[part], 6))
        cubes = cubes[..., 0].reshape(-1, 6 * CUBE_SIZE * CUBE_SIZE)
        cosine = np.clip(normals[part] @ cube_dirs.T, 0, None)
        out[part, 0] = np.sum(cosine * cube_omega * cubes, axis=1)
    for j, (c, r, grain) in enumerate(zip(centres, radii, grains, strict=True)):
        dist = np.linalg.norm(c - eyes, axis=1)
        aimed = np.flatnonzero(dist >= 2.0 * r)
        halves = np.arcsin(np.minimum(0.99, r / dist[aimed])) * 1.2
        size = light_view_size(halves, dist[aimed], grain)
        cams = [aimed_camera(eyes[p], c, float(h), size)
                for p, h in zip(aimed, halves, strict=True)]
        params = rest if j < 2 else extra[(j - 2) // 3]
        channel = 1 + j if j < 2 else (j - 2) % 3
        if not cams:
            continue
        images = render_many(params, cams, near=nears[aimed])
        d, o = pixel_directions(cams)
        cosine = np.clip(np.einsum("bpi,bi->bp", d, normals[aimed]), 0, None)
        out[aimed, 1 + j] = np.sum(cosine * o * images[..., channel].reshape(len(cams), -1),
                                   axis=1)
    return out


def censored_fit(y: np.ndarray, c: np.ndarray, iterations: int = 25
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A normal fitted to each row of ``(G, P)`` samples, some of them only known to be
    at least ``c`` (right-censored; ``y`` NaN there, ``c`` NaN where ``y`` is known).

    Expectation-maximisation with the truncated normal's moments. A bound may be false
    (a surface seen through a clipped light in front of it): each is genuine with prior
    ``1 -`` :data:`FALSE_BOUND_SHARE`, else it says nothing, so no one bound can outweigh
    the measured points. Returns ``(mu, sigma, nll)`` with ``nll`` the mean negative
    log-likelihood over the points."""
    known = np.isfinite(y)
    cens = np.isfinite(c)
    yk = np.where(known, y, 0.0)
    cc = np.where(cens, c, 0.0)
    n_known = np.maximum(known.sum(1), 1)
    mu = yk.sum(1) / n_known
    sigma = np.sqrt(np.maximum((((yk - mu[:, None]) ** 2) * known).sum(1) / n_known,
                               MIN_SIGMA ** 2))
    for _ in range(iterations if cens.any() else 1):
        a = (cc - mu[:, None]) / sigma[:, None]
        log_sf = _normal_logsf(a)
        genuine = np.where(cens, expit(log_sf + GENUINE_LOGIT), 0.0)
        lam = np.exp(_normal_logpdf(a) - log_sf)
        e1 = mu[:, None] + sigma[:, None] * lam
        e2 = sigma[:, None] ** 2 * np.maximum(1.0 + a * lam - lam ** 2, 0.0) + e1 ** 2
        n = known.sum(1) + genuine.sum(1)
        mu = (yk.sum(1) + (genuine * e1).sum(1)) / n
        second = ((yk ** 2) * known).sum(1) + (genuine * e2).sum(1)
        sigma = np.sqrt(np.maximum(second / n - mu ** 2, MIN_SIGMA ** 2))
    z = (yk - mu[:, None]) / sigma[:, None]
    nll = (np.where(known, np.log(sigma[:, None]) + 0.5 * z ** 2, 0.0).sum(1)
           - np.where(cens, np.logaddexp(
               math.log1p(-FALSE_BOUND_SHARE) + _normal_logsf((cc - mu[:, None]) / sigma[:, None]),
               math.log(FALSE_BOUND_SHARE)), 0.0).sum(1))
    return mu, sigma, nll / np.maximum((known | cens).sum(1), 1)


def albedo_scores(totals: np.ndarray, radiance: np.ndarray, bound: np.ndarray,
                  trim: float = 0.1) -> np.ndarray:
    """How unlikely the log-albedos are, per row of irradiance ``totals`` ``(G, P)`` (one
    row per trial factor): the negative log-likelihood per point of a normal fitted to
    them, points the photos only clipped (``bound``) counting as at least their bound
    (:func:`censored_fit`), the ``trim`` share of the measured points farthest from
    their median left out (bounds are not trimmed: a false one is weighed down by
    :data:`FALSE_BOUND_SHARE` instead).
    With no clipped point it is the log of the spread (least variance, as before).
    Infinite where over a quarter of the albedos would exceed 1 (:data:`ALBEDO_QUANTILE`).

    Leaving clipped points out would select on brightness: near a clipped lamp, the
    surfaces it lights brightest clip, the darker ones stay, and the factor that makes
    them look like the rest falls short (1.2 stops on a ``balanced`` fit of ``room:11``,
    ``docs/measurements.md``)."""
    _, nll, over = albedo_fit(totals, radiance, bound, trim)
    return np.where(over, np.inf, nll)


def albedo_fit(totals: np.ndarray, radiance: np.ndarray, bound: np.ndarray,
               trim: float = 0.1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row of irradiance ``totals`` ``(G, P)``: the log2-albedos' fitted mean (their
    level), the negative log-likelihood per point (:func:`albedo_scores`) and whether
    over a quarter of the albedos exceed 1."""
    totals = np.maximum(np.atleast_2d(totals), 1e-12)
    known = np.isfinite(radiance)
    y = np.where(known, np.log2(math.pi * np.where(known, radiance, 1.0) / totals), np.nan)
    cens = np.isfinite(bound)
    c = np.where(cens, np.log2(math.pi * np.where(cens, bound, 1.0) / totals), np.nan)
    over = ((y > 0) | (c > 0)).sum(1) > (1.0 - ALBEDO_QUANTILE) * (known | cens).sum()
    ref = np.nanmedian(y, axis=1, keepdims=True)
    dev = np.abs(y - ref)
    keep = cens | (dev <= np.nanquantile(dev, 1.0 - trim, axis=1, keepdims=True))
    y, c = np.where(keep, y, np.nan), np.where(keep, c, np.nan)
    mu, _, nll = censored_fit(y, c)
    return mu, nll, over


def factor_grid(step: float) -> np.ndarray:
    """The ``log2 k`` searched: :data:`LOG2_K_RANGE`, ``step`` apart."""
    return np.arange(LOG2_K_RANGE[0], LOG2_K_RANGE[1] + 1e-9, step)


def totals_over(irr: np.ndarray, log2_k: np.ndarray, j: int, grid: np.ndarray) -> np.ndarray:
    """``(G, P)`` irradiance at each point with light ``j`` at each factor of ``grid``
    (log2) and the other lights at ``log2_k``."""
    others = irr[:, 0] + irr[:, 1:] @ (2.0 ** log2_k) - irr[:, 1 + j] * 2.0 ** log2_k[j]
    return others[None] + (2.0 ** grid)[:, None] * irr[None, :, 1 + j]


def solve_factors(radiance: np.ndarray, bound: np.ndarray, irr: np.ndarray,
                  grid_step: float = 0.125) -> np.ndarray:
    """``log2 k`` per light minimising :func:`albedo_scores` (coordinate grid search);
    for several lights, one factor for all of them where it scores within
    :data:`ALIKE_TOLERANCE` of that."""
    lights = irr.shape[1] - 1
    k = np.zeros(lights)
    grid = factor_grid(grid_step)
    for _ in range(3 if lights > 1 else 1):
        for j in range(lights):
            scores = albedo_scores(totals_over(irr, k, j, grid), radiance, bound)
            if np.isfinite(scores).any():
                k[j] = grid[int(np.argmin(scores))]
    if lights > 1:
        best = albedo_scores((irr[:, 0] + irr[:, 1:] @ (2.0 ** k))[None], radiance, bound)[0]
        shared = albedo_scores(irr[:, 0][None] + (2.0 ** grid)[:, None]
                               * irr[:, 1:].sum(1)[None], radiance, bound)
        if np.isfinite(shared).any() and shared.min() <= best + ALIKE_TOLERANCE:
            k[:] = grid[int(np.argmin(shared))]
    return k


def feasible(log2_k: np.ndarray, radiance: np.ndarray, bound: np.ndarray, irr: np.ndarray
             ) -> bool:
    """Whether factors ``2**log2_k`` keep the albedos under the cap (:func:`albedo_scores`)."""
    totals = irr[:, 0] + irr[:, 1:] @ (2.0 ** log2_k)
    return bool(np.isfinite(albedo_scores(totals[None], radiance, bound))[0])


def evenness_floor(log2_k: np.ndarray, radiance: np.ndarray, bound: np.ndarray,
                   irr: np.ndarray, grid_step: float = 0.125) -> np.ndarray:
    """Per light, where the uniformity's best factor ``log2_k`` is the search's top: the
    least factor that scores within :data:`ALIKE_TOLERANCE` of it, the others held at
    theirs (NaN for the other lights).

    A uniformity that keeps improving to the end of the search says "a light at least
    this bright", not a centre: there the rest of the room's gathered irradiance adds
    spread instead of explaining it, and the brighter the light the more it drowns that
    spread. Taken as a centre at the search's top it pulled the level's posterior stops
    over (``bulb`` seed 0 on the chain bench; ``docs/measurements.md``, session 22)."""
    grid = factor_grid(grid_step)
    out = np.full(len(log2_k), np.nan)
    for j in np.flatnonzero(log2_k >= LOG2_K_RANGE[1] - 1e-9):
        scores = albedo_scores(totals_over(irr, log2_k, j, grid), radiance, bound)
        finite = np.isfinite(scores)
        if finite.any():
            out[j] = grid[int(np.argmax(scores <= scores[finite].min() + ALIKE_TOLERANCE))]
    return out


def with_albedo_prior(log2_k: np.ndarray, sigma: np.ndarray, radiance: np.ndarray,
                      bound: np.ndarray, irr: np.ndarray, grid_step: float = 0.125,
                      at_least: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The factors (log2) and their spread (stops) once the albedos' *level* is weighed
    in beside their uniformity (module docstring): per light, the posterior over a grid
    of ``log2 k`` of a normal around the uniformity's estimate ``log2_k`` (``sigma``)
    and the prior that the surfaces' median albedo is near
    :data:`ALBEDO_PRIOR_MEDIAN` (:data:`ALBEDO_PRIOR_STOPS`); factors that push over a
    quarter of the albedos over 1 are impossible. Lights the uniformity weighed as one
    (:data:`ALIKE_TOLERANCE`) stay one. Coordinate-wise for several lights. Where the
    photos only bounded most of the points (:data:`LEVEL_MEASURED_SHARE`) the level is
    not measured and the uniformity's estimate is returned as it is.

    ``at_least``: per light, where the uniformity ran off the search's top
    (:func:`evenness_floor`; NaN elsewhere): there it only says "at least this", and
    only factors under it are penalised (with ``sigma``)."""
    lights = len(log2_k)
    floors = np.full(lights, np.nan) if at_least is None else np.asarray(at_least, float)
    grid = factor_grid(grid_step)
    k, spread = log2_k.astype(np.float64).copy(), sigma.astype(np.float64).copy()
    measured = int(np.isfinite(radiance).sum())
    if measured < LEVEL_MEASURED_SHARE * (measured + int(np.isfinite(bound).sum())):
        return k, spread
    groups = ([np.arange(lights)] if lights > 1 and np.ptp(log2_k) == 0
              else [np.array([j]) for j in range(lights)])
    level = math.log2(ALBEDO_PRIOR_MEDIAN)
    for _ in range(3 if len(groups) > 1 else 1):
        for g in groups:
            trial = np.repeat(k[None], len(grid), 0)
            trial[:, g] = grid[:, None]
            mu, _, over = albedo_fit(irr[:, 0][None] + (2.0 ** trial) @ irr[:, 1:].T,
                                     radiance, bound)
            centre, width = float(log2_k[g[0]]), float(sigma[g].max())
            off = (grid - centre if not np.isfinite(floors[g]).any()
                   else np.minimum(grid - float(np.nanmax(floors[g])), 0.0))
            log_post = (-0.5 * (off / width) ** 2
                        - 0.5 * ((mu - level) / ALBEDO_PRIOR_STOPS) ** 2)
            log_post[over] = -np.inf
            if not np.isfinite(log_post).any():
                continue
            weight = np.exp(log_post - log_post.max())
            mean = float(np.sum(weight * grid) / weight.sum())
            k[g] = grid[int(np.argmax(log_post))]
            spread[g] = math.sqrt(max(float(np.sum(weight * (grid - mean) ** 2)
                                            / weight.sum()), grid_step ** 2 / 12.0))
    return k, spread


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
    """Whether the surfaces pin a factor: inside the search and sure enough."""
    return bool(LOG2_K_RANGE[0] < log2_k < LOG2_K_RANGE[1]) and sigma <= MAX_INFERRED_SIGMA_STOPS


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
                              "surface_points": int(np.isfinite(radiance).sum()),
                              "clipped_surface_points": int(np.isfinite(bound).sum()),
                              # the albedo cap, not the albedos' spread, decided: little
                              # light but this one's reaches the surfaces, so the factor
                              # is the least that keeps them matte (a lower bound)
                              "lower_bound": not feasible(lower, radiance, bound, columns)})
        if not _accepted(best[i], sigma_inf):
            light.details["note"] = ("its surfaces do not pin its power (the search ran off "
                                     "its range, or it is uncertain by over "
                                     f"{MAX_INFERRED_SIGMA_STOPS:g} stops): the uplift's "
                                     "power stands")
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
        else:
            weigh.append(entry)
    opaque = ~search.backdrop & (scene.opacities > 0.5)
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
