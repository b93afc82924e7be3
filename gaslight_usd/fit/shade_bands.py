"""A shaded lamp's sides that no photo saw, closed where the photos saw its bulb hidden.

Frames of a bulb in a shade taken from one side read it hidden at some elevations (the
shade) and seen at others (through its openings). The sides no photo looked from are
free in the fit, and its shade there lets a few per cent of a bulb thousands of times
the walls through: a probe on such a side read the lamp over a stop too bright
(``gaslight2usd bench --suite chain``; ``docs/measurements.md``, session 64).

Lamps are round about the vertical. An elevation (seen from the bulb, about the room's
vertical) within :data:`BAND_DEG` of a frame that read the bulb hidden by something near
it, and of none that read it seen, is closed all round on the sides no frame looked
from (:data:`UNSEEN_DEG`): shells of opaque discs :data:`SHELL_RADII` bulb radii out, in
the colour those frames saw there. Discs the training views would fit better without
(:func:`.contribution.removal_gains`) are taken out, round after round. A bare bulb,
seen from every elevation its frames had, is left as it is, and so is a light no
unclipped frame measured (no darker frame): then nothing says what is hidden.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from ..cameras import PinholeCamera, matrix_to_quaternion
from ..render.params import SplatParams
from ..splats import SplatScene
from .backdrop import concatenate
from .contribution import removal_gains

HIDDEN_SHARE = 0.01
"""A frame reads the bulb hidden where its pixel at the bulb is under this share of the
brightest unclipped reading of it..."""
SEEN_SHARE = 0.125
"""...and seen where it is over this share."""
BAND_DEG = 10.0
"""Elevations this near a hidden reading (and no nearer a seen one) are closed."""
SHELL_RADII = (3.0, 4.0, 5.0, 6.0, 7.0, 8.0)
"""The shells' radii in bulb radii, from outside the bulb's own splats to the reach of
what hid it: the views see the inner ones through the shade's openings (taken out), the
outer ones outside the shade's far side are hidden behind it."""
REACH_RADII = 8.0
"""A hidden reading counts where an opaque splat that is not a light lies this near the
bulb (in bulb radii) on the frame's line (a shade, not a far piece of furniture), or
where none lies anywhere on it: the fit shows that frame the bulb it saw hidden (the
true HDR views' fits drew a shade's outside too thin to hide it, session 65)."""
OPAQUE = 0.3
UNSEEN_DEG = 45.0
"""Directions this far from every frame that had the bulb in it are the unseen sides
(at 30 degrees the discs also took light from a probe on the frames' side, where the
bulb shows under the shade's rim)."""
FLAT_COS = 0.8
"""A plane of the room's box whose normal is within this |cos| of the cameras' mean up
is a floor or ceiling..."""
WALL_COS = 0.6
"""...under this, a wall."""
SHELL_DIRECTIONS = 2000
"""Directions the shell is laid on (a Fibonacci sphere, about 4.5 degrees apart)."""
DISC_RADII = 0.5
"""Each disc's std-dev across, in bulb radii (at least its share of the shell): discs
only as wide as their share hid a strip of the bulb from a probe and let the rest shine
past; a bulb radius wide, they also dimmed it from a probe just under the band."""
WORSE = 0.5
"""A disc the views would fit better without, by this much (their log2-luminance squared
error summed over pixels, :func:`.contribution.removal_gains`), is left out: the discs
kept are ones the photos do not object to (some the photos' own side sees, where the fit
let a hidden bulb through, they fit better).
"""
MAX_ROUNDS = 24
"""Rounds of taking out the discs the views object to (a disc behind one shows once
that one is out)."""


@dataclass
class ClosedBand:
    """One light's closed elevations and the discs that close them."""

    position: np.ndarray
    lowest_deg: float
    highest_deg: float
    bulb_radius: float
    hidden_views: int
    seen_views: int
    discs: int = 0

    def as_dict(self) -> dict[str, Any]:
        return {"position": [round(float(v), 4) for v in self.position],
                "elevations_deg": [round(self.lowest_deg, 1), round(self.highest_deg, 1)],
                "bulb_radius": round(self.bulb_radius, 4), "hidden_views": self.hidden_views,
                "seen_views": self.seen_views, "discs": self.discs}


def box_vertical(planes: list, up: np.ndarray) -> np.ndarray | None:
    """The room's vertical from its box's planes (:class:`.planes.Plane`): a floor's or
    ceiling's normal, else square to two walls; None without either. ``up`` (the
    cameras' mean up: frames aimed up at a lamp lean it by tens of degrees) only tells
    floors from walls and picks the sign."""
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    normals = np.array([np.asarray(p.normal, np.float64) for p in planes]).reshape(-1, 3)
    if not len(normals):
        return None
    lean = np.abs(normals @ up)
    if lean.max() >= FLAT_COS:
        best = normals[int(np.argmax(lean))]
        return best * np.sign(best @ up)
    walls = normals[lean < WALL_COS]
    across = np.cross(walls[:, None], walls[None]).reshape(-1, 3)
    if not len(across):
        return None
    k = int(np.argmax(np.linalg.norm(across, axis=1)))
    if np.linalg.norm(across[k]) < 0.5:  # only parallel walls
        return None
    best = across[k] / np.linalg.norm(across[k])
    return best * np.sign(best @ up)


def fibonacci_directions(n: int) -> np.ndarray:
    """(n, 3) unit directions spread evenly over the sphere, +Y the pole."""
    k = np.arange(n) + 0.5
    polar = np.arccos(1.0 - 2.0 * k / n)
    azimuth = np.pi * (1.0 + 5.0 ** 0.5) * k
    return np.stack([np.cos(azimuth) * np.sin(polar), np.cos(polar),
                     np.sin(azimuth) * np.sin(polar)], axis=1)


def _frame_to_up(up: np.ndarray) -> np.ndarray:
    """A rotation taking +Y to ``up`` (its columns: the frame's x, up and z in the
    world)."""
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    a = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(up, a)
    x /= np.linalg.norm(x)
    return np.stack([x, up, np.cross(x, up)], axis=1)


def _discs_facing(centre: np.ndarray, directions: np.ndarray, radius: float, bulb: float,
                  colour: np.ndarray, sh_degree: int) -> SplatScene:
    """Opaque discs at ``centre + radius * direction``, each facing the centre, wide
    enough to tile the sphere their directions cover and to cover a bulb ``bulb`` in
    radius behind them (a disc only as wide as its tile, seen from a probe, hides a
    strip of the bulb: the rest of it shines past)."""
    n = len(directions)
    helper = np.where(np.abs(directions[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    ex = np.cross(helper, directions)
    ex /= np.linalg.norm(ex, axis=1, keepdims=True)
    ey = np.cross(directions, ex)
    quats = matrix_to_quaternion(np.stack([ex, ey, directions], axis=2)).astype(np.float32)
    width = max(0.6 * radius * np.sqrt(4.0 * np.pi / SHELL_DIRECTIONS), DISC_RADII * bulb)
    return SplatScene.from_activated(centre + radius * directions, np.tile(colour, (n, 1)),
                                     np.tile([width, width, 0.1 * width], (n, 1)),
                                     np.full(n, 0.99), rotations=quats, sh_degree=sh_degree)


def bulb_centre_and_radius(scene: SplatScene, rows: np.ndarray, y_weights: np.ndarray
                           ) -> tuple[np.ndarray, float]:
    """Where a light's splats throw their light from, and the radius holding 90 % of it
    (each splat's light: luminance x opacity x its footprint), so a faint halo of wide
    splats round a drawn-in bulb does not widen it."""
    light = (np.maximum(scene.base_colours[rows] @ np.asarray(y_weights, np.float64), 0.0)
             * scene.opacities[rows] * np.prod(scene.scales[rows], axis=1) ** (2.0 / 3.0))
    light = np.maximum(light, 1e-30)
    centre = (scene.positions[rows] * light[:, None]).sum(0) / light.sum()
    distance = np.linalg.norm(scene.positions[rows] - centre, axis=1)
    order = np.argsort(distance)
    held = np.cumsum(light[order]) / light.sum()
    return centre, float(distance[order][min(np.searchsorted(held, 0.9), len(order) - 1)])


def band_shell(scene: SplatScene, rows: np.ndarray, light_mask: np.ndarray,
               cameras: list[PinholeCamera], images: list[np.ndarray],
               floors: list[np.ndarray | None], y_weights: np.ndarray, up: np.ndarray,
               ) -> tuple[SplatScene | None, ClosedBand | None]:
    """The discs that close one light's hidden elevations (not yet checked against the
    views), and what they close; (None, None) where nothing is closed.

    ``rows``: the light's own splats; ``light_mask``: (N,) every light's splats (never
    taken for what hid one); ``floors``: each view's clip floor (None: nothing clipped)."""
    y = np.asarray(y_weights, np.float64)
    if not len(rows):
        return None, None
    centre, radius = bulb_centre_and_radius(scene, rows, y)
    if radius <= 0.0:
        return None, None
    reach = REACH_RADII * radius
    readings, clipped, towards, hid_near, there = [], [], [], [], []
    offsets = scene.positions.astype(np.float64) - centre
    opaque = (scene.opacities > OPAQUE) & ~light_mask
    size = 1.5 * scene.scales.max(axis=1)
    for cam, image, floor in zip(cameras, images, floors, strict=True):
        px, depth = cam.project(centre[None])
        x, yy = px[0]
        if depth[0] <= 0 or not (0 <= x < cam.width and 0 <= yy < cam.height):
            continue
        i, j = int(yy), int(x)
        readings.append(float(image[i, j] @ y))
        clipped.append(floor is not None and bool(floor[i, j] > 0))
        u = cam.center - centre
        u /= np.linalg.norm(u)
        towards.append(u)
        t = offsets @ u
        across = np.linalg.norm(offsets - t[:, None] * u, axis=1)
        on = opaque & (t > 0) & (across < size)
        near = on & (t < reach)
        # a frame's reading is the bulb hidden by something near it (True), by something
        # far (False), or by nothing the fit drew (True)
        hid_near.append(bool(near.any()) or not bool((on & (t < np.linalg.norm(
            cam.center - centre))).any()))
        there.append(np.asarray(image[i, j], np.float64))
    if not readings:
        return None, None
    readings_a, clipped_a = np.array(readings), np.array(clipped)
    if clipped_a.all():
        return None, None
    top = readings_a[~clipped_a].max()
    seen = ~clipped_a & (readings_a >= SEEN_SHARE * top)
    hidden = ~clipped_a & (readings_a < HIDDEN_SHARE * top) & np.array(hid_near)
    if not hidden.any():
        return None, None
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    view_elevation = np.degrees(np.arcsin(np.clip(np.array(towards) @ up, -1.0, 1.0)))
    directions = fibonacci_directions(SHELL_DIRECTIONS) @ _frame_to_up(up).T
    elevation = np.degrees(np.arcsin(np.clip(directions @ up, -1.0, 1.0)))
    near = np.abs(elevation[:, None] - view_elevation[None]) < BAND_DEG
    closed = (near & hidden[None]).any(1) & ~(near & seen[None]).any(1)
    # only the sides no frame looked from: the frames' own side is the fit's to draw
    closed &= (directions @ np.array(towards).T).max(axis=1) < np.cos(np.radians(UNSEEN_DEG))
    if not closed.any():
        return None, None
    # the colour those frames saw where the bulb hid (a splat on their line may be the
    # shade's glow, seen from inside)
    colour = np.median(np.array(there)[hidden], axis=0).astype(np.float32)
    shells = [_discs_facing(centre, directions[closed], k * radius, radius, colour,
                            scene.sh_degree) for k in SHELL_RADII]
    discs = shells[0]
    for shell in shells[1:]:
        discs = concatenate(discs, shell)
    return discs, ClosedBand(centre, float(elevation[closed].min()),
                             float(elevation[closed].max()), radius, int(hidden.sum()),
                             int(seen.sum()))


def close_hidden_bands(scene: SplatScene, lights: list[np.ndarray], light_mask: np.ndarray,
                       cameras: list[PinholeCamera], images: list[np.ndarray],
                       floors: list[np.ndarray | None], y_weights: np.ndarray,
                       up: np.ndarray) -> tuple[SplatScene, list[ClosedBand]]:
    """``scene`` with each light's hidden elevations closed on its unseen sides
    (:func:`band_shell`) by the discs ``cameras`` (the training views) would not fit
    better without, appended after its splats; and the bands closed (those with discs
    kept)."""
    shells, bands = [], []
    for rows in lights:
        discs, band = band_shell(scene, rows, light_mask, cameras, images, floors,
                                 y_weights, up)
        if discs is not None and band is not None:
            shells.append(discs)
            bands.append(band)
    if not shells:
        return scene, []
    added = shells[0]
    for discs in shells[1:]:
        added = concatenate(added, discs)
    kept_ok = np.ones(added.count, bool)
    y = torch.as_tensor(np.asarray(y_weights, np.float32))
    # discs behind discs each change little on their own: those the views fit better
    # without are taken out and the rest weighed again, until the views object to none
    for _ in range(MAX_ROUNDS):
        kept = np.flatnonzero(kept_ok)
        both = concatenate(scene, added.subset(kept))
        gain = removal_gains(SplatParams.from_scene(both), cameras, images, floors,
                             scene.sh_degree, y)
        worse = gain.cpu().numpy()[scene.count:] > WORSE
        if not worse.any():
            break
        kept_ok[kept[worse]] = False
    else:
        kept_ok[:] = False  # the views still object after the last round: nothing added
    start = 0
    for discs, band in zip(shells, bands, strict=True):
        band.discs = int(kept_ok[start:start + discs.count].sum())
        start += discs.count
    kept = [band for band in bands if band.discs]
    if not kept:
        return scene, []
    return concatenate(scene, added.subset(np.flatnonzero(kept_ok))), kept
