"""Light the fit left off the room's surfaces, put back on them along the photos' rays.

A light's depth comes from parallax, and a fit gets it wrong two ways.

- **Sunk compact lights.** A light only one photo frames can sit anywhere along that
  photo's rays; where the room around it is well fitted, the fit often leaves it behind
  the ceiling or wall: the chain bench's ``panels`` room, fitted from its photos, had
  the ceiling panel one photo frames 0.3-0.8 m above the ceiling, where the lights
  finder calls it backdrop (``docs/measurements.md``, session 17).
- **Broad lights off their wall.** Clipped pixels only bound the fit from below, so a
  window's light may lie at any depth along the rays that see it clipped: the ``bulb``
  room's fit left clumps of its window 0.6-1.1 m in front of it, beside the probe 0.5 m
  from the window, and more behind the wall (session 19).

The photos still say where such light can be. A bright splat (over the white) lying in
the cone of a light region of some photo (:mod:`gaslight_usd.sightings`) is on that
photo's rays, and it is moved along them, its scales in proportion so that the photo
draws it on the same pixels:

- a light held by a **compact** outline (whole, at most
  :data:`gaslight_usd.fit.light_seeds.MAX_CONE_DEG` across) with splats outside the
  captured space (:mod:`gaslight_usd.capture`: the free space the cameras' median point
  sees, bounded by the fit's dim opaque surfaces), whole: all the splats that outline
  holds, by one ratio, until their power-weighted centre is where the ray leaves the
  space, or crosses one of the room's planes first (a ceiling few photos see is
  smeared deep, and the space's boundary with it); whole, because per splat the
  boundary's bin-to-bin depth noise broke a panel into fragments the lights finder no
  longer took for a light. Refused where another training photo
  frames the new place: there parallax placed the light, and a bright splat outside
  the space on a compact light's rays is something else (the lit ceiling behind a lamp;
  what a lampshade hides from the space's one viewpoint). The light moved is recorded
  where its outline places it (:attr:`SurfacedLights.placed`, the splats'
  ``light_seeds``): its clipped radiance says only "at least the white", and without
  that the lights finder took the chain bench's ``panels:7`` ceiling panel, which one
  photo frames, for a lit patch, so it was never weighed.
- held only by **broad** outlines (windows, skylights, large panels), more than
  :data:`OFF_SURFACE_SHARE` of its distance in front of or behind the room's boundary,
  onto it: the captured space's *sealed* boundary, the local planes of the surfaces,
  carried across the bright holes a window leaves in them (the open boundary falls
  through there). Refused where some photo framing the new place shows
  no light there, and a whole light (the splats of outlines holding splats in common)
  stays where it is when most of its splats are refused: a lit shade hanging in front
  of a wall is seen against the wall from the side. With ``broad_on_planes`` (the fit's
  second pass, after the lamps are weighed), where one of the room's planes is that
  boundary, onto the plane instead, from :data:`PLANE_OFF_SHARE` off it: the sealed
  boundary is the wall's first splats, a few centimetres in front of the wall.

- a bright splat of a **compact** outline at under :data:`NEAR_SHARE` of the way from
  its photo's camera to the boundary, onto the boundary along its own ray, where every
  photo framing the new place shows light there: a light one photo sees can be drawn by
  small splats just in front of that camera, which no other viewpoint sees at its
  power. This is the one rule for views that clipped nothing (merged brackets, true
  HDR views: ``near_only``), where a light is what
  :data:`gaslight_usd.fit.single_view.BRIGHT_RATIO` calls bright.

``gaslight2usd bench --suite chain --scene panels --scene bulb`` measures what it buys
(the lights' power at the probes, ``light_dist_*``, ``floating_share``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from ..cameras import PinholeCamera
from ..capture import CaptureSpace, capture_space
from ..colour import AT_WHITE
from ..sightings import PeakMap, Sightings, peak_map
from ..splats import SplatScene
from ..surroundings import splat_sigma
from .light_seeds import MAX_CONE_DEG, LightSeed, framing
from .planes import Plane

RAY_STEPS = 128
"""Samples along a light splat's ray where it is tested against the captured space."""
BISECTIONS = 6
"""Halvings of the step where the ray leaves the space (a room's diagonal over
:data:`RAY_STEPS`, 5 cm, to under a millimetre)."""
OFF_SURFACE_SHARE = 0.1
"""A broad light's splat farther than this share of its distance from the room's
boundary (in front or behind, along its photo's ray) is moved onto it."""
PLANE_AGREEMENT_SHARE = 0.1
"""Where the room's plane (:func:`gaslight_usd.fit.planes.room_box`) that a broad light's
ray crosses first lies within this share of the splat's distance of the sealed boundary
along it, that plane is the wall the light is on: the sealed boundary is the wall's first
visible splats, 5-8 cm in front of it (session 30), no place for a window to the
centimetre."""
PLANE_OFF_SHARE = 0.02
"""...and a broad light's splat farther than this share of its distance off that plane
is moved onto it. A window's splats left 5-20 cm in front of their wall (under
:data:`OFF_SURFACE_SHARE` at 2-3 m) are seen from a probe 0.5 m away over a wider angle
than the window, which the ``bench --suite chain`` probe by the window measures."""
MIN_LIT_SHARE = 1.0
"""...only where this share of the photos framing the new place show light there: all
of them (a light moved where some photo saw none contradicts that photo; this also
refuses a window that something in front hides from some photo)."""


@dataclass
class SurfacedLights:
    """What :func:`surface_sunk_lights` moved."""

    moved: int
    """Splats moved."""
    power_share: float
    """Their share of the bright splats' power (radiance x area x opacity)."""
    mean_move: float
    """Mean distance moved (scene units)."""
    refused: int
    """Splats left where they were: a sunk light's new place more than one photo frames,
    or a broad light's some photo framing it shows no light at."""
    placed: list[LightSeed] = field(default_factory=list)
    """The sunk compact lights moved, each where it now is, as the one photo whose whole
    outline holds it places it (``views``: that photo's index among the views given,
    ``size``: the outline's radius there): the lights finder takes such a light for a
    light without testing its clipped radiance (:func:`gaslight_usd.lights.outlined_lights`),
    which only says "at least the white"; the fit then weighs it by the surfaces it
    lights, which tell a light from a lit patch (:mod:`.lamp_or_surface`)."""

    def as_dict(self) -> dict:
        return {"moved": self.moved, "power_share": round(self.power_share, 4),
                "mean_move": round(self.mean_move, 4), "refused": self.refused,
                "placed_lights": len(self.placed)}


def _exit_along(space: CaptureSpace, eye: np.ndarray, pos: np.ndarray, span: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """Where the rays from ``eye`` (K, 3) through ``pos`` (K, 3), followed to ``span``
    (K,) times the splat's distance, leave ``space``'s sealed boundary (the surfaces'
    planes): the distance ratio there (K,), and whether the ray starts inside and leaves
    it (K,). :data:`RAY_STEPS` samples find the first one outside, then
    :data:`BISECTIONS` halvings the crossing before it."""
    rows = np.arange(len(pos))
    t = span[:, None] * np.linspace(0.0, 1.0, RAY_STEPS + 1)[None, 1:]  # (K, S)
    along = eye[:, None] + (pos - eye)[:, None, :] * t[..., None]  # (K, S, 3)
    inside = space.inside(along.reshape(-1, 3), boundary="sealed").reshape(len(pos), -1)
    first_out = np.argmin(inside, axis=1)
    leaves = inside[:, 0] & ~inside.all(axis=1)
    lo = t[rows, np.maximum(first_out - 1, 0)]
    hi = t[rows, first_out]
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        ins = space.inside(eye + (pos - eye) * mid[:, None], boundary="sealed")
        lo, hi = np.where(ins, mid, lo), np.where(ins, hi, mid)
    return lo, leaves


def _boundary_along(space: CaptureSpace, eye: np.ndarray, pos: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_exit_along` with the rays followed as far as the room's box reaches, so a
    splat in front of the boundary or behind it finds it."""
    dist = np.linalg.norm(pos - eye, axis=1)
    far = float(np.linalg.norm(space.box[1] - space.box[0]))
    return _exit_along(space, eye, pos, np.maximum(far / np.maximum(dist, 1e-9), 1.0))


def _seen_lit(points: np.ndarray, cameras: list[PinholeCamera],
              views: Sequence[np.ndarray | PeakMap], whites: np.ndarray, weights: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """(K, V) bool each: which photos frame each point, and which of those show light at
    or over their white there (the brightest of the 3 x 3 blocks of the full-size peaks
    round its pixel: a splat has a size, and an outline's edge is a pixel uncertain)."""
    framed = framing(points, cameras, margin=0.0)
    lit = np.zeros_like(framed)
    for v, (cam, view) in enumerate(zip(cameras, views, strict=True)):
        if not framed[:, v].any():
            continue
        peaks = view if isinstance(view, PeakMap) else peak_map(view, weights, None)
        near = ndimage.maximum_filter(peaks.peaks, size=3, mode="nearest")
        uv, _ = cam.project(points[framed[:, v]])
        col = np.clip((uv[:, 0] * peaks.size[0] / cam.width / peaks.block).astype(int), 0,
                      near.shape[1] - 1)
        row = np.clip((uv[:, 1] * peaks.size[1] / cam.height / peaks.block).astype(int), 0,
                      near.shape[0] - 1)
        lit[framed[:, v], v] = near[row, col] >= AT_WHITE * whites[v]
    return framed, lit


@dataclass
class _Moves:
    """Splats to move along rays from their eyes: ``pos' = eye + (pos - eye) * ratio``."""

    idx: np.ndarray
    eye: np.ndarray
    ratio: np.ndarray
    refused: int
    placed: list[LightSeed] = field(default_factory=list)

    @classmethod
    def none(cls) -> _Moves:
        return cls(np.zeros(0, int), np.zeros((0, 3)), np.zeros(0), 0)


def _sunk_compact(pos: np.ndarray, power: np.ndarray, idx: np.ndarray, region: np.ndarray,
                  outside: np.ndarray, eyes: np.ndarray, space: CaptureSpace,
                  cameras: list[PinholeCamera], sightings: Sightings,
                  planes: Sequence[Plane] = ()) -> _Moves:
    """Compact lights (the bright splats ``idx`` one compact ``region`` holds) with a
    splat ``outside`` the space, moved whole along their photo's rays (from ``eyes``,
    per region) until their power-weighted centre is on the boundary: the photo draws
    them on the same pixels, their shape kept; each moved light is also returned as
    that photo's outline places it (:attr:`SurfacedLights.placed`)."""
    sunk = np.unique(region[outside])
    if not len(sunk):
        return _Moves.none()
    members = np.isin(region, sunk)
    idx, region = idx[members], region[members]
    _, group = np.unique(region, return_inverse=True)
    w = np.bincount(group, power[idx])
    centre = np.stack([np.bincount(group, power[idx] * pos[idx, k]) for k in range(3)], 1)
    centre /= np.maximum(w, 1e-30)[:, None]
    eye = eyes[sunk]
    ratio, ok = _exit_along(space, eye, centre, np.ones(len(sunk)))
    # a ceiling few photos see is smeared deep, and the boundary with it (0.4 m over
    # panels:7's, from photos): the room's planes, where the ray crosses one first
    for plane in planes:
        ratio = np.minimum(ratio, plane.crossing(eye, centre))
    ok &= ratio < 1.0
    # only where the one photo it is moved along frames the new place (elsewhere the
    # photos' parallax placed the light, and a bright splat outside the space on its
    # rays is something else: the lit ceiling behind a lamp, or what a shade hides from
    # the space's one viewpoint)
    refused = ok & (framing(eye + (centre - eye) * ratio[:, None], cameras,
                            margin=0.0).sum(axis=1) > 1)
    go = (ok & ~refused)[group]
    at = eye + (centre - eye) * ratio[:, None]
    far = np.linalg.norm(at - eye, axis=1)
    placed = [LightSeed(position=at[k], size=float(far[k] * np.tan(sightings.radii[r])),
                        views=[int(sightings.view[r])], framed=1)
              for k, r in enumerate(sunk) if ok[k] and not refused[k]]
    return _Moves(idx[go], eye[group[go]], ratio[group[go]], int(refused[group].sum()),
                  placed)


NEAR_SHARE = 0.5
"""A bright splat a compact outline holds at under this share of the distance from its
photo's camera to the room's boundary along its ray is moved onto the boundary
(:func:`_near_floaters`)."""


SCAN_STEPS = 8
"""Depths tried, from the sealed boundary out to the splats' box, for a floater whose
place on the boundary some photo saw dark (:func:`_first_lit_along`)."""


def _box_exit(box: np.ndarray, eye: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """(K,) the ratio along ``eye + (pos - eye) * r`` where each ray leaves ``box``
    ((2, 3) corners), at least 1."""
    step = pos - eye
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (box[0] - eye) / step
        b = (box[1] - eye) / step
    far = np.where(np.abs(step) > 1e-12, np.maximum(a, b), np.inf)
    return np.maximum(far.min(axis=1), 1.0)


def _first_lit_along(eye: np.ndarray, pos: np.ndarray, start: np.ndarray, stop: np.ndarray,
                     cameras: list[PinholeCamera], views: Sequence[np.ndarray | PeakMap],
                     whites: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The first of :data:`SCAN_STEPS` + 1 ratios from ``start`` to ``stop`` (K,) along
    ``eye + (pos - eye) * r`` where every photo framing the place shows light there, and
    whether there is one (K,): where the fit's surfaces hang short of the true ceiling
    (few photos see it), the sealed boundary lies in front of a light, and photos from
    the side see that place dark."""
    k = len(pos)
    ratios = start[:, None] + (stop - start)[:, None] * np.linspace(0.0, 1.0, SCAN_STEPS + 1)
    points = eye[:, None] + (pos - eye)[:, None] * ratios[..., None]
    frames, lit = _seen_lit(points.reshape(-1, 3), cameras, views, whites, weights)
    good = (lit.sum(axis=1) >= MIN_LIT_SHARE * frames.sum(axis=1)).reshape(k, -1)
    first = np.argmax(good, axis=1)
    return ratios[np.arange(k), first], good.any(axis=1)


def _near_floaters(pos: np.ndarray, idx: np.ndarray, region: np.ndarray, eyes: np.ndarray,
                   space: CaptureSpace, cameras: list[PinholeCamera],
                   views: Sequence[np.ndarray | PeakMap], whites: np.ndarray,
                   weights: np.ndarray, planes: Sequence[Plane] = ()) -> _Moves:
    """Bright splats ``idx`` of compact outlines (``region``) lying in front of their
    photo's camera at under :data:`NEAR_SHARE` of the way to the room's boundary, moved
    onto it along their own rays, scales in proportion, where every photo framing the
    new place shows light there; where some photo saw it dark, to the first place
    farther along the ray, up to the splats' box, that no photo contradicts
    (:func:`_first_lit_along`). Never past the first of the room's ``planes`` the ray
    crosses: the captured space's boundary at a ceiling few photos see is smeared deep,
    and past the ceiling no other photo frames the place to contradict it (``panels:7``'s
    ceiling panel from true HDR views, one fit: moved above the ceiling, where the probes
    saw the ceiling instead; ``docs/measurements.md``, session 66).

    A light one photo sees keeps that photo's pixels at any depth, and the fit's cheapest
    way to draw it can be a few small splats just in front of the camera (``panels:7``'s
    ceiling panel fitted from its true HDR views: its brightest splats 0.13 m from the
    camera, 2.85 m short of the panel), which no probe sees at the light's power. A lamp
    hanging in the room, more than half way to the boundary, stays; one nearer the camera
    is moved only where no photo that frames the boundary there saw it dark.
    """
    if not len(idx):
        return _Moves.none()
    eye = eyes[region]
    ratio, ok = _boundary_along(space, eye, pos[idx])
    wall = _first_plane_along(planes, eye, pos[idx])
    ratio = np.minimum(ratio, wall)
    ok &= ratio * NEAR_SHARE > 1.0
    stop = np.minimum(np.maximum(_box_exit(space.box, eye, pos[idx]), ratio),
                      np.maximum(wall, ratio))
    ratio, go = _first_lit_along(eye, pos[idx], ratio, stop, cameras, views, whites, weights)
    go &= ok
    return _Moves(idx[go], eye[go], ratio[go], int((ok & ~go).sum()))


def _first_plane_along(planes: Sequence[Plane], eye: np.ndarray, pos: np.ndarray
                       ) -> np.ndarray:
    """(K,) the distance ratio along ``eye -> pos`` where each ray first crosses one of
    ``planes`` from its front, ``inf`` where it crosses none."""
    if not planes:
        return np.full(len(pos), np.inf)
    return np.min([plane.crossing(eye, pos) for plane in planes], axis=0)


def _off_surface_broad(pos: np.ndarray, idx: np.ndarray, region: np.ndarray,
                       eyes: np.ndarray, space: CaptureSpace, sightings: Sightings,
                       cameras: list[PinholeCamera], views: Sequence[np.ndarray | PeakMap],
                       whites: np.ndarray, weights: np.ndarray,
                       planes: Sequence[Plane] = ()) -> _Moves:
    """Bright splats ``idx`` held only by broad outlines (nearest: ``region``) more than
    :data:`OFF_SURFACE_SHARE` off the sealed boundary along their photo's ray (from
    ``eyes``, per region), moved onto it where the photos agree; where one of the room's
    ``planes`` is the boundary there (:data:`PLANE_AGREEMENT_SHARE`), onto that plane,
    from :data:`PLANE_OFF_SHARE` off it."""
    if not len(idx):
        return _Moves.none()
    eye = eyes[region]
    ratio, ok = _boundary_along(space, eye, pos[idx])
    wall = _first_plane_along(planes, eye, pos[idx])
    on_wall = ok & np.isfinite(wall) & (np.abs(wall - ratio) <= PLANE_AGREEMENT_SHARE * ratio)
    ratio = np.where(on_wall, wall, ratio)
    ok &= np.abs(ratio - 1.0) > np.where(on_wall, PLANE_OFF_SHARE, OFF_SURFACE_SHARE) * ratio
    target = eye + (pos[idx] - eye) * ratio[:, None]
    # only where the photos that frame the new place show light there (a lit shade
    # hanging in front of a wall stays: photos from the side see the wall behind it)
    frames, lit = _seen_lit(target, cameras, views, whites, weights)
    alone = ok & (lit.sum(axis=1) < MIN_LIT_SHARE * frames.sum(axis=1))
    # and a light moves whole or not at all: where most of its splats would contradict a
    # photo, none of them moves (a shade's middle, behind it from every photo, is no
    # wall light). A light: the splats of outlines that hold some splat in common.
    held = sightings.holding(pos[idx]).astype(np.int32)
    _, component = connected_components(csr_matrix(held.T @ held), directed=False)
    light = component[region]
    count = light.max() + 1
    share = (np.bincount(light, alone, minlength=count)
             / np.maximum(np.bincount(light, ok, minlength=count), 1))
    refused = ok & (alone | (share[light] > 0.5))
    go = ok & ~refused
    return _Moves(idx[go], eye[go], ratio[go], int(refused.sum()))


RULES = frozenset({"sunk", "broad", "near"})
"""The rules :func:`surface_sunk_lights` applies: sunk compact lights, broad lights off
their wall, floaters just in front of a camera (the module docstring)."""


def surface_sunk_lights(scene: SplatScene, cameras: list[PinholeCamera],
                        views: Sequence[np.ndarray | PeakMap], whites: np.ndarray,
                        weights: np.ndarray, sightings: Sightings,
                        rules: frozenset[str] = RULES, planes: Sequence[Plane] = (),
                        broad_on_planes: bool = False) -> tuple[SplatScene, SurfacedLights]:
    """``scene`` with its sunk compact lights and its off-surface broad lights moved
    onto the room's boundary along the photos' rays (module docstring), and what
    moved. ``cameras``: the training views; ``views``: their photos (linear HDR, or
    their :class:`gaslight_usd.sightings.PeakMap`); ``whites`` (V,): each view's white,
    in the scene's units; ``weights``: luminance weights; ``sightings``: the views' light
    regions (:func:`gaslight_usd.sightings.sight_lights`, same views); ``rules``: which
    of :data:`RULES` to apply; ``planes``: the room's box
    (:func:`gaslight_usd.fit.planes.room_box`), which bounds a sunk light's move;
    ``broad_on_planes``: broad lights go onto those planes where they are the boundary
    (:data:`PLANE_AGREEMENT_SHARE`, :data:`PLANE_OFF_SHARE`), else onto the sealed
    boundary alone."""
    if not rules <= RULES:
        raise ValueError(f"unknown rules {sorted(rules - RULES)}; known: {sorted(RULES)}")
    lum = scene.base_colours @ np.asarray(weights, np.float32)
    nothing = SurfacedLights(0, 0.0, 0.0, 0)
    bright = np.flatnonzero((lum > float(np.median(whites))) & (scene.opacities > 0.05))
    if not len(bright) or not sightings.count or len(cameras) < 2:
        return scene, nothing
    pos = scene.positions.astype(np.float64)
    compact = sightings.whole & (sightings.radii <= np.radians(MAX_CONE_DEG))
    # the region holding each bright splat (nearest its axis), a compact one first
    angle = sightings.angles(pos[bright]) / np.maximum(sightings.radii, 1e-9)[None]
    row = np.arange(len(bright))
    near_c = np.argmin(np.where(compact[None], angle, np.inf), axis=1)
    near_b = np.argmin(np.where(compact[None], np.inf, angle), axis=1)
    held_c = compact[near_c] & (angle[row, near_c] <= 1.0)
    held_b = ~held_c & ~compact[near_b] & (angle[row, near_b] <= 1.0)
    centres = np.array([cam.center for cam in cameras])
    eyes = centres[sightings.view]  # per region
    probe = scene.subset(np.arange(scene.count))
    # the captured space holds the room's box (gaslight_usd.capture), closed on a side it
    # lacks where the viewpoint sees that side: open, a box without its floor let the
    # sun room's sunlit patch sink to the box's bottom (docs/measurements.md, session 56)
    probe.metadata = {**scene.metadata, "exposure_scale": float(np.median(whites)),
                      "fit_metrics": {**(scene.metadata.get("fit_metrics") or {}),
                                      "room_box": [plane.as_dict() for plane in planes]}}
    space = capture_space(probe, centres, planes=True)
    sigma = splat_sigma(scene)
    area = scene.opacities * np.prod(np.sort(scene.scales, axis=1)[:, 1:], axis=1)
    power = (lum * area).astype(np.float64)
    # outside as the lights finder tells backdrop (gaslight_usd.capture.backdrop_mask)
    outside = ~space.inside(pos[bright], reach=2.0 * sigma[bright])
    whites = np.asarray(whites, np.float64)
    moves = [_sunk_compact(pos, power, bright[held_c], near_c[held_c], outside[held_c],
                           eyes, space, cameras, sightings, planes)
             if "sunk" in rules else _Moves.none(),
             _off_surface_broad(pos, bright[held_b], near_b[held_b], eyes, space, sightings,
                                cameras, views, whites, weights,
                                planes if broad_on_planes else ())
             if "broad" in rules else _Moves.none()]
    taken = np.concatenate([m.idx for m in moves])
    rest = held_c & ~np.isin(bright, taken)
    moves.append(_near_floaters(pos, bright[rest], near_c[rest], eyes, space, cameras, views,
                                whites, weights, planes) if "near" in rules else _Moves.none())
    idx = np.concatenate([m.idx for m in moves])
    if not len(idx):
        return scene, SurfacedLights(0, 0.0, 0.0, sum(m.refused for m in moves))
    eye = np.concatenate([m.eye for m in moves])
    ratio = np.concatenate([m.ratio for m in moves])
    target = eye + (pos[idx] - eye) * ratio[:, None]
    out = scene.subset(np.arange(scene.count))
    out.positions[idx] = target.astype(out.positions.dtype)
    out.log_scales[idx] = (scene.log_scales[idx]
                           + np.log(ratio)[:, None]).astype(out.log_scales.dtype)
    return out, SurfacedLights(
        moved=int(len(idx)),
        power_share=float(power[idx].sum() / max(power[bright].sum(), 1e-30)),
        mean_move=float(np.linalg.norm(target - pos[idx], axis=1).mean()),
        refused=sum(m.refused for m in moves), placed=moves[0].placed)
