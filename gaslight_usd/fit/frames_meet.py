"""A compact light two darker frames measured, put where their sight lines to it meet.

The photos that clip a shaded lamp see the inside of its shade lit at the opening, and
the light seeded from their clipped outlines (:mod:`.light_seeds`) sits there, under the
bulb. The darker frames shot from below it (the README's capture: two, from either side)
see the bulb itself through the opening, but each frame alone cannot tell how far along
its line of sight the bulb is, and the fit explains each frame with a lobe at the seeded
depth: on ``shade:7`` one lobe per frame, 10 cm under the bulb and 13 cm apart. Drawn
there, the bulb hangs below its shade: a probe from the side sees what the shade hides,
and one under the lamp sees it off where it is.

Two frames' lines of sight to the bulb's blob cross at the bulb. So where two or more
training views measured a light (it reads over twice the white round it and they
clipped nothing there: :func:`measuring_sightings`) from directions at least
:data:`MIN_ANGLE_DEG` apart, and their lines pass within :data:`MAX_GAP_SIZES` of the
light's measured radius of the point nearest them all (:func:`frames_meeting`), the
light's bright splats (at least :data:`BULB_SHARE` of the frames' reading: the bulb, not
the opening's glow) are moved there, drawn together to the radius the frames measured
(:func:`moved_to_meeting`). The fit does it at the end of its densify window, so that
its remaining steps fit the room round the bulb where it is (moved only at the end, the
shade's glow at the opening hid it from below: the fit had made a lid of it), and again
at the end; :mod:`.fine_power` then matches the bulb alone to those frames, and clears
what hid it from them. Measured by ``gaslight2usd bench --suite chain --scene shade:7
--method "recursive + extra dark frames"`` (``docs/measurements.md``, session 59).

Where no view clipped (true HDR views, merged brackets), every view that framed a shaded
lamp measured it, most of them only the glow at its opening, and the fit drew the bulb
there, under it, short of its power below it (``gaslight2usd bench --suite chain --scene
shade:7 --method "truth HDR"``; ``docs/measurements.md``, session 65). So there the views
that read the light at least :data:`GLOW_SHARE` of the brightest reading place it
likewise, where some read it dimmer (:func:`bulb_sightings`); where all read it alike (a
bare bulb) the fit's own placement from its many views stands.
A bare bulb one darker frame measured is placed likewise where that frame's line passes
the light the clipped photos seeded from places apart (:func:`frame_and_seed`): left
where the fit put it, its splats lay along the frame's line, one bulb to the frame and a
streak 10-25 cm long to a probe beside it (session 62).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy import ndimage

from ..cameras import PinholeCamera
from ..sightings import MIN_BASELINE_DEG
from ..splats import SplatScene
from .frame_edge import pixel_rays

MIN_ANGLE_DEG = MIN_BASELINE_DEG
"""The widest angle between two frames' sight lines must be at least this: nearer
parallel, a pixel of error moves their meeting point along them by more than a bulb."""
REACH_SIZES = 3.0
"""Each frame looks for the light's blob this many of its seeded sizes round the seed
(the seed sits at the opening, 0.18 m from the bulb on ``shade:7``)."""
PEAK_SHARE = 0.5
"""The blob: the connected pixels at or over this share of the brightest in reach."""
MAX_GAP_SIZES = 2.0
"""Every frame's sight line passes within this many of the measured radius of the
meeting point (else the frames saw different things, and nothing moves)."""
BULB_SHARE = 0.25
"""The light's splats at least this share of the frames' brightest reading are the bulb
and move; dimmer ones (the glow the photos saw at the opening) stay."""
WHITE_MULTIPLE = 2.0
"""A view measured the light where it reads over this many whites round it (as
:func:`.fine_power.measuring_views` says)."""


GLOW_SHARE = 0.25
"""Where no view clipped (true HDR views, merged brackets), a view that read the light at
under this share of the brightest view's reading saw only the glow round it (a shade's
inside lit at its opening), not the bulb (:func:`bulb_sightings`)."""


@dataclass
class Sighting:
    """One view's measurement of the light: its line of sight and the blob's size."""

    view: int
    origin: np.ndarray
    direction: np.ndarray
    radius_rad: float
    """The blob's radius as an angle (its area's equivalent disc)."""
    peak: float
    """The brightest luminance in it."""


@dataclass
class Meeting:
    """Where the frames' sight lines meet, and what moved there."""

    position: np.ndarray
    radius: float
    """The light's radius as the frames measured it (m)."""
    views: list[int]
    peak: float
    moved: int = 0
    shift: float = 0.0
    """How far the moved splats' centre went (m)."""

    def as_dict(self) -> dict[str, Any]:
        return {"position": [round(float(v), 4) for v in self.position],
                "radius": round(self.radius, 4), "views": self.views,
                "splats_moved": self.moved, "shift_m": round(self.shift, 4)}


def _reach_box(cam: PinholeCamera, centre: np.ndarray, reach: float
               ) -> tuple[int, int, int, int] | None:
    uv, z = cam.project(centre[None])
    if not (z[0] > 0 and np.isfinite(uv).all()):
        return None
    r = int(math.ceil(cam.fx * reach / z[0]))
    u, v = int(uv[0, 0]), int(uv[0, 1])
    u0, v0 = max(u - r, 0), max(v - r, 0)
    u1, v1 = min(u + r + 1, cam.width), min(v + r + 1, cam.height)
    return None if u0 >= u1 or v0 >= v1 else (u0, v0, u1, v1)


def measuring_sightings(centre: np.ndarray, size: float, cameras: list[PinholeCamera],
                        images: list[np.ndarray], floors: list[np.ndarray | None],
                        y_weights: np.ndarray, white: float) -> list[Sighting]:
    """The views that measured a clipped light seeded at ``centre`` (``size`` its
    radius): within :data:`REACH_SIZES` of it they clipped nothing and read over
    :data:`WHITE_MULTIPLE` whites. Each gives the sight line to its blob's
    luminance-weighted centre (:data:`PEAK_SHARE`)."""
    y = np.asarray(y_weights, np.float32)
    out = []
    for i, (cam, image, floor) in enumerate(zip(cameras, images, floors, strict=True)):
        box = _reach_box(cam, np.asarray(centre, np.float64), REACH_SIZES * size)
        if box is None:
            continue
        u0, v0, u1, v1 = box
        if floor is not None and bool((floor[v0:v1, u0:u1] > 0).any()):
            continue
        lum = image[v0:v1, u0:u1] @ y
        peak = float(lum.max())
        if peak <= WHITE_MULTIPLE * white:
            continue
        labels, _ = ndimage.label(lum >= PEAK_SHARE * peak)
        blob = labels == labels[np.unravel_index(int(np.argmax(lum)), lum.shape)]
        rows, cols = np.nonzero(blob)
        w = lum[blob].astype(np.float64)
        uv = np.array([[u0 + 0.5 + float(cols @ w) / w.sum(),
                        v0 + 0.5 + float(rows @ w) / w.sum()]])
        radius_px = math.sqrt(len(w) / math.pi)
        out.append(Sighting(i, cam.center.astype(np.float64), pixel_rays(cam, uv)[0],
                            math.atan(radius_px / cam.fx), peak))
    return out


def bulb_sightings(sightings: list[Sighting]) -> list[Sighting]:
    """Of ``sightings`` of one light, those that read it at least :data:`GLOW_SHARE` of
    the brightest: the views that saw the bulb itself. Where nothing clipped, every view
    that framed a shaded lamp measured it, most of them only the glow of the shade's
    inside at its opening, far dimmer than the bulb seen through it from below, and their
    lines of sight meet at the opening."""
    top = max((s.peak for s in sightings), default=0.0)
    return [s for s in sightings if s.peak >= GLOW_SHARE * top]


def meeting_point(origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """(3,) the point nearest, in the least-squares sense, to the lines through
    ``origins`` along unit ``directions`` (both (N, 3), N >= 2, not all parallel)."""
    d = np.asarray(directions, np.float64)
    project = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
    return np.linalg.solve(project.sum(axis=0),
                           np.einsum("nij,nj->i", project, np.asarray(origins, np.float64)))


def frames_meeting(sightings: list[Sighting]) -> Meeting | None:
    """Where ``sightings`` (two or more) meet, or None when their lines are nearer
    parallel than :data:`MIN_ANGLE_DEG` or miss the meeting point by more than
    :data:`MAX_GAP_SIZES` of the light's measured radius."""
    if len(sightings) < 2:
        return None
    d = np.array([s.direction for s in sightings])
    cos = np.clip(d @ d.T, -1.0, 1.0)
    if math.degrees(math.acos(float(cos.min()))) < MIN_ANGLE_DEG:
        return None
    o = np.array([s.origin for s in sightings])
    point = meeting_point(o, d)
    rel = point - o
    along = np.sum(rel * d, axis=1)
    if (along <= 0).any():
        return None
    gaps = np.linalg.norm(rel - along[:, None] * d, axis=1)
    radii = along * np.tan([s.radius_rad for s in sightings])
    radius = float(np.median(radii))
    if float(gaps.max()) > MAX_GAP_SIZES * max(radius, 1e-6):
        return None
    return Meeting(point, radius, [s.view for s in sightings],
                   float(max(s.peak for s in sightings)))


def frame_and_seed(sightings: list[Sighting], seed: np.ndarray, seed_size: float
                   ) -> Meeting | None:
    """Where one frame's sight line passes the light seeded at ``seed`` (``seed_size``
    its radius; placed from the photos' clipped outlines, :mod:`.light_seeds`): the
    point on the line nearest the seed, at the radius the frame measured. Of several
    ``sightings`` (that did not meet: :func:`frames_meeting`), the line nearest the
    seed; None where it misses the seed by more than its size.

    One frame cannot say how far along its line the bulb is, and the fit spreads the
    bulb's splats along it: the frame sees them as one, a probe 0.5 m from the bulb as a
    streak round it, a third to two thirds more light than the bulb (``hall:9``,
    ``bulb:11``: ``gaslight2usd bench --suite chain``). The photos that clipped it placed the seed
    from places apart."""
    if not sightings:
        return None
    seed = np.asarray(seed, np.float64)

    def gap(s: Sighting) -> float:
        rel = seed - s.origin
        return float(np.linalg.norm(rel - (rel @ s.direction) * s.direction))

    best = min(sightings, key=gap)
    along = float((seed - best.origin) @ best.direction)
    if along <= 0 or gap(best) > seed_size:
        return None
    point = best.origin + along * best.direction
    return Meeting(point, along * math.tan(best.radius_rad), [best.view], best.peak)


def moved_to_meeting(scene: SplatScene, rows: np.ndarray, meeting: Meeting,
                     y_weights: np.ndarray) -> tuple[SplatScene, Meeting, np.ndarray]:
    """``scene`` with the splats of ``rows`` that read at least :data:`BULB_SHARE` of the
    frames' peak (the bulb) moved to ``meeting``: their weighted centre onto it, drawn
    together along each of their principal axes to no more than a ball of the radius the
    frames measured (RMS); and the indices of the bulb's splats."""
    rows = np.asarray(rows, np.int64)
    lum = scene.base_colours[rows] @ np.asarray(y_weights, np.float64)
    bulb = rows[lum >= BULB_SHARE * meeting.peak]
    if not len(bulb):
        return scene, meeting, bulb
    weight = (scene.base_colours[bulb] @ np.asarray(y_weights, np.float64)) * \
        scene.opacities[bulb] * np.prod(scene.scales[bulb], axis=1) ** (2.0 / 3.0)
    pos = scene.positions[bulb].astype(np.float64)
    total = max(float(weight.sum()), 1e-30)
    centre = weight @ pos / total
    rel = pos - centre
    # each principal axis drawn in to the radius's share (a ball of that RMS radius): a
    # cluster only scaled down keeps its shape, and one along a frame's line hides itself
    # from that frame, which it is matched to, more than from a probe beside it
    variance, axes = np.linalg.eigh((rel * weight[:, None]).T @ rel / total)
    share = meeting.radius / math.sqrt(3.0)
    shrink = np.minimum(1.0, share / np.sqrt(np.maximum(variance, 1e-30)))
    positions = scene.positions.copy()
    positions[bulb] = (meeting.position + ((rel @ axes) * shrink) @ axes.T
                       ).astype(positions.dtype)
    moved = replace(meeting, moved=int(len(bulb)),
                    shift=float(np.linalg.norm(meeting.position - centre)))
    return replace(scene, positions=positions, metadata=dict(scene.metadata)), moved, bulb
