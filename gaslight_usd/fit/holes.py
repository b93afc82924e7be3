"""Seed splats where a training view's compact clipped light is still drawn by nothing.

A splat fit grows only where it has splats: densification copies and splits the splats
that the loss pulls hardest, so a patch of a view that no splat covers gets no gradient
and stays empty, however far its pixels are from their targets. The initial points miss
such patches where nothing could be triangulated and no sparse neighbour says how deep
they lie: a ceiling panel only one photo frames (the chain bench's ``panels:7``: no splat
near it, and the panel missing from every probe).

So once, at the end of the densify window, every training view is drawn, and the
patches of its clipped pixels (``masks``) that its splats leave mostly uncovered
(accumulated opacity under :data:`EMPTY_ALPHA`) get a splat each on a grid of
:data:`STRIDE` pixels, in the target's colour (the uplift's fill; the loss holds it as a
bound), where they pass three tests that tell a missed light from the rest:

* **Compact and over the white.** A patch no wider than a compact light's outline
  (:data:`gaslight_usd.fit.light_seeds.MAX_CONE_DEG` from its middle) whose median target
  is over the photos' white: a wide clipped patch is a lit surface (the ceiling over a
  shaded lamp), whose neighbours are its own depth smear; a patch under the white is no
  light's (the lights finder starts from splats over it, :mod:`gaslight_usd.lights`),
  only a surface a view shot brighter clipped.
* **At a depth inside the room.** The depth the covered pixels round it say (an affine
  fit of inverse depth over their nearest :data:`NEIGHBOURS`,
  :func:`gaslight_usd.fit.init.fill_depths`: the surface the patch is part of), but
  never beyond the room's box (:func:`gaslight_usd.fit.planes.room_box`): round a hole
  the covered splats' depth is their smear, which runs past the ceiling a panel is set
  in.
* **Seen by no other view.** A new splat another view would show in front of the
  surface it draws there (:func:`drawn_behind`) marks a hole the fit made by putting a
  light too deep, not a light it missed; filled, it floated in front of a window.

The rest of the fit then shapes them as any other splat. Unclipped pixels are left alone:
the fit's own loss reaches them once densification covers them. Measured by
``gaslight2usd bench --suite chain`` (its ``holes_filled`` column; the tries behind the
tests in ``docs/measurements.md``, sessions 43-45).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from ..cameras import PinholeCamera
from ..splats import SplatScene
from .gather import depth_map
from .init import depth_rays, fill_depths
from .light_seeds import MAX_CONE_DEG
from .planes import Plane

EMPTY_ALPHA = 0.5
"""A pixel its splats cover less than this is empty."""
COVERED_ALPHA = 0.9
"""Pixels covered at least this much say how deep the surface round a hole lies."""
DARK_SHARE = 0.05
"""A pixel whose target is under this share of the views' mean level is left alone (a
black background is no surface to cover)."""
STRIDE = 2
"""One new splat per this many pixels each way."""
NEIGHBOURS = 6
"""Covered pixels the depth of a hole's pixel is fitted to (as the initial surface fill)."""
MIN_PIXELS = 4
"""A view with fewer empty pixels is left alone (the edges of the fit's coverage)."""
NEARER_SHARE = 0.9
"""Another view's fitted surface nearer than this share of a new splat's depth hides it
there."""


@dataclass
class Holes:
    """The splats to add: positions ``(n, 3)``, colours ``(n, 3)`` and sizes ``(n,)``, and
    per view how many pixels its compact, bright, empty patches hold (before the depth
    and the other views have their say)."""

    positions: np.ndarray
    colours: np.ndarray
    sizes: np.ndarray
    empty_pixels: dict[str, int]

    @property
    def count(self) -> int:
        return len(self.positions)


def box_depths(cam: PinholeCamera, rays: np.ndarray, planes: list[Plane]) -> np.ndarray:
    """``(n,)`` the depth along each of ``cam``'s ``rays`` (``(n, 3)``, unit depth) at which it
    meets the first of ``planes``' patches from their front; ``inf`` where it meets none."""
    eye = np.broadcast_to(cam.center, rays.shape)
    depth = np.full(len(rays), np.inf)
    for plane in planes:
        depth = np.minimum(depth, plane.crossing(eye, eye + rays))
    return depth


def drawn_behind(points: np.ndarray, cameras: list[PinholeCamera], depths: list[np.ndarray],
                 own: int) -> np.ndarray:
    """``(n,)`` bool: which ``points`` a view other than ``own`` frames with a fitted surface
    drawn behind them (its ``depths``, inf where it draws nothing): that view would show
    the point, and draws its light farther away; the hole is a depth the fit got wrong,
    not a light it missed. A view that draws nothing there either says nothing."""
    out = np.zeros(len(points), bool)
    for j, (cam, depth) in enumerate(zip(cameras, depths, strict=True)):
        if j == own:
            continue
        uv, z = cam.project(points)
        col, row = np.floor(uv[:, 0]).astype(int), np.floor(uv[:, 1]).astype(int)
        inside = np.flatnonzero((z > 0) & (col >= 0) & (col < cam.width) & (row >= 0)
                                & (row < cam.height))
        behind = depth[row[inside], col[inside]]
        out[inside] |= np.isfinite(behind) & (behind >= NEARER_SHARE * z[inside])
    return out


def bright_patches(pixels: np.ndarray, target_lum: np.ndarray, white: float) -> np.ndarray:
    """``pixels`` ``(H, W)`` bool with only the patches (8-connected) whose median target is
    over ``white`` kept."""
    labels, count = ndimage.label(pixels, structure=np.ones((3, 3), bool))
    if not count:
        return pixels
    median = ndimage.median(target_lum, labels, np.arange(1, count + 1))
    return pixels & (np.asarray(median) > white)[np.maximum(labels - 1, 0)] & (labels > 0)


def empty_pixels(alpha: np.ndarray, target_lum: np.ndarray, level: float) -> np.ndarray:
    """``(H, W)`` bool: pixels covered under :data:`EMPTY_ALPHA` whose target is not black."""
    return (alpha < EMPTY_ALPHA) & (target_lum > DARK_SHARE * level)


def compact_patches(pixels: np.ndarray, focal: float) -> np.ndarray:
    """``pixels`` ``(H, W)`` bool with only its compact patches kept (8-connected): those
    whose pixels all lie within :data:`gaslight_usd.fit.light_seeds.MAX_CONE_DEG` of the
    patch's middle, seen through a lens of ``focal`` pixels."""
    labels, count = ndimage.label(pixels, structure=np.ones((3, 3), bool))
    if not count:
        return pixels
    yx = np.argwhere(labels > 0)
    patch = labels[yx[:, 0], yx[:, 1]] - 1
    middle = np.zeros((count, 2))
    np.add.at(middle, patch, yx.astype(np.float64))
    middle /= np.bincount(patch, minlength=count)[:, None]
    reach = np.zeros(count)
    np.maximum.at(reach, patch, np.linalg.norm(yx - middle[patch], axis=1) + 0.5)
    compact = np.degrees(np.arctan(reach / focal)) <= MAX_CONE_DEG
    return pixels & compact[np.maximum(labels - 1, 0)] & (labels > 0)


def fill_holes(scene: SplatScene, cameras: list[PinholeCamera], alphas: list[np.ndarray],
               targets: list[np.ndarray], names: list[str], weights: np.ndarray,
               level: float, rng: np.random.Generator,
               masks: list[np.ndarray | None] | None = None, white: float = 0.0,
               planes: list[Plane] | None = None) -> Holes:
    """Splats for the compact empty patches of each view (module docstring).

    ``cameras``: the views at their image size; ``alphas``: each view's accumulated
    opacity as the fit draws it; ``targets``: ``(H, W, 3)`` what each view should show;
    ``weights``: the luminance weights; ``level``: the views' mean luminance; ``masks``:
    per view the pixels that may be filled (None: all of them); ``white``: a patch whose
    median target is not over it is left alone; ``planes``: the room's box, which no new
    splat lies beyond."""
    positions, colours, sizes, counts = [], [], [], {}
    masks = masks or [None] * len(cameras)
    depths: list[np.ndarray] = []  # every view's, drawn once a view has a patch to seed
    for own, (cam, alpha, target, name, mask) in enumerate(zip(cameras, alphas, targets,
                                                               names, masks, strict=True)):
        lum = target @ weights
        empty = empty_pixels(alpha, lum, level)
        if mask is not None:
            empty &= mask
        empty = bright_patches(compact_patches(empty, cam.fx), lum, white)
        if int(empty.sum()) < MIN_PIXELS:
            continue
        depths = depths or [depth_map(scene, view) for view in cameras]
        depth = depths[own]
        covered = (alpha >= COVERED_ALPHA) & np.isfinite(depth)
        if int(covered.sum()) < NEIGHBOURS:
            continue
        counts[name] = int(empty.sum())
        grid = np.zeros_like(empty)
        offset = rng.integers(0, STRIDE, 2)
        grid[offset[0]::STRIDE, offset[1]::STRIDE] = True
        yx = np.argwhere(empty & grid)
        if not len(yx):
            continue
        px = yx[:, ::-1] + 0.5
        cover_yx = np.argwhere(covered)
        _, near = cKDTree(cover_yx[:, ::-1] + 0.5).query(px, k=NEIGHBOURS)
        near_yx = cover_yx[near]
        at = fill_depths(px, near_yx[..., ::-1] + 0.5, depth[near_yx[..., 0], near_yx[..., 1]])
        rays = depth_rays(cam, px)
        at = np.minimum(at, box_depths(cam, rays, planes or []))
        ok = np.isfinite(at) & (at > 0)
        px, yx, at, rays = px[ok], yx[ok], at[ok], rays[ok]
        points = cam.center + rays * at[:, None]
        alone = ~drawn_behind(points, cameras, depths, own)
        yx, at, points = yx[alone], at[alone], points[alone]
        positions.append(points)
        colours.append(target[yx[:, 0], yx[:, 1]])
        # a splat as wide as the stride's footprint at its depth covers its pixels
        sizes.append(STRIDE * at / cam.fx)
    if not positions:
        return Holes(np.zeros((0, 3)), np.zeros((0, 3), np.float32), np.zeros(0), counts)
    return Holes(np.concatenate(positions), np.concatenate(colours).astype(np.float32),
                 np.concatenate(sizes), counts)
