"""Where the views saw light on the room's planes: the rectangles of windows and panels.

A window's splats say little about its edges: a fit draws it with a few dozen blobs whose
spread is not its size (often a third smaller, or not flat enough to be a panel at all).
The views say it exactly: every photo that frames the window clipped the same rectangle
of the wall. So each room plane (the fit's room box, :func:`gaslight_usd.fit.planes.room_box`)
is cut into cells, each cell is looked up in every view that frames it from the plane's
front, and a cell is **lit** where at least :data:`MIN_VIEWS` views frame it and at least
:data:`LIT_SHARE` of them saw a light there (a clipped pixel; in a view that clipped
nothing, one many times its median: :func:`lit_masks`). An object in front of the window
in one view only takes its cells out where that view is most of those that frame them.
The lit cells' connected regions, of at least :data:`MIN_CELLS` cells, are the plane's
**outlines**: rectangles with sides along the room's other planes where one is square to
this one (windows and panels are set square to their walls), bounding the region.

The room box's plane is fitted to the whole wall or ceiling, and a ceiling seen at
grazing angles can sit a few centimetres off the panel in it; seen from one side, each
view's outline then lands elsewhere on the plane. So a region the views see obliquely is
looked up again at depths around the plane (:data:`DEPTH_SWEEP`), and kept where the
centres of the views' outlines of it coincide (:func:`_agreeing_offset`).

A light only one view frames (a ceiling panel the other photos look past) has no second
view to vote with: where that view saw it whole (framed round it, not cut by its frame)
and the other views judge none of it, its lit cells on the plane are outlined all the
same, smoothed of the ragged edge one view's coarse pixels leave, and marked
``single_view``: one view puts a lamp hanging in front of a wall on the wall just as
well, so such an outline holds only a light the fit drew on the plane
(:func:`gaslight_usd.light_shapes.panel_of`), and only inside the room's other planes.

The fit stores them in the splats' metadata (``flat_outlines``); the rig's panels take a
light's rectangle from the outline that holds it (:func:`gaslight_usd.light_shapes.panel_of`).
Measured by ``gaslight2usd bench --suite chain`` (``rect_iou_<light>``,
``rig_irradiance_psnr``; figures in ``docs/measurements.md``, session 49).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import ndimage

from .cameras import PinholeCamera

CELL_SHARE = 0.01
"""A cell's side, as a share of the cameras' median distance to the plane."""
MAX_CELLS = 400
"""At most this many cells along a side of a plane's grid (the cell grows instead)."""
SPAN_SHARE = 2.0
"""The grid reaches this many median camera distances past the cameras' own span."""
MIN_VIEWS = 2
"""A cell is judged only where at least this many views frame it from the front."""
LIT_SHARE = 0.75
"""...and lit where at least this share of them saw light there."""
MIN_CELLS = 12
"""Lit regions of fewer cells are no outline (a speck, a lit edge)."""
UNCLIPPED_RATIO = 8.0
"""In a view that clipped nothing (a true HDR view, merged brackets, a darker frame) a
light is what is over this many times the view's median luminance: the chain bench's
windows are 15-50 times their rooms' walls, the light those windows and lamps throw on
the walls a few times."""
EDGE_LEVEL = 0.35
"""...and, within each such region, only what is over this share of the region's level
(its brightest tenth's floor): a blurred edge crosses half its light's level where the
light ends, and a ceiling panel lights the ceiling round it over the median many times
(its outline from true HDR views ran a quarter larger than the panel, 5-20 % for windows;
``docs/measurements.md``, session 50)."""
EDGE_QUANTILE = 0.9
CLIPPED_SHARE = 0.1
"""In a view that clipped something, a bright region with under this share of its pixels
clipped is a light it measured (:func:`lit_masks`); over it, a clipped light and the ring
its blur lays round it (the shaded lamp's glow in a window's darker frame: 93 % clipped;
its window: one pixel of 6900)."""
MIN_FILL = 0.8
"""An outline is a light's rectangle only where its lit cells fill this share of it."""
MAX_OUTLINES = 32
"""Kept, the most lit cells first: a speckled set's photos clip hundreds of specks, and
the splats' metadata carries them."""
DEPTH_SWEEP = 0.1
"""Each region's plane is swept this share of the cameras' distance either way: the room
box's plane, fitted to the whole wall or ceiling, sat 5 cm under a ceiling panel, and
seen from the side the views' outlines of it slid 7 cm apart (``docs/measurements.md``,
session 50); a ceiling few photos see, its points smeared from 2.4 to 3.2 m, was found
9-14 cm under its panels (``panels:2``; session 62)."""
DEPTH_STEPS = 20
"""...in this many steps each way: steps of a two-hundredth of the distance (0.8 cm in a
room's middle). In coarser steps the depth a clipped panel's halo picked, by chance, made
its round outline fill its box like a panel's rectangle."""
DEPTH_GAIN = 0.5
"""...and moved only where the views' outlines' centres spread less than this share of
their spread on the room box's plane."""
FACE_ON_COS = 0.8
"""...but not where the views see the region face on (the median |cos| of their rays to it
over this): there the outlines hardly slide with the plane's depth, and their spread says
nothing of it (windows seen across a room, |cos| 0.97-0.99, were moved up to 12 cm off
their walls)."""
PLACES_APART = 0.05
"""...and only by views at least this share of the cameras' distance apart: a photo and its
darker frame shot from one place see the light's outline at one place at any depth, and
their outlines' spread (one clipped, one measured) moved a ceiling panel by chance
(``panels:7``: 12 cm under it, or onto it); such a region takes the depth views from two
places agreed on for the plane's other lights."""
SINGLE_VIEW_MARGIN = 2
"""A region only one view frames, lit there, is outlined too (a ceiling panel the other
photos pass by: ``panels:7``'s second panel, which one of its photos frames), where the
cells this many round it are framed as well (its edge is the light's, not the frame's)
and dark in every view that frames them (the region is the whole light)."""
SQUARE_COS = 0.2
"""Another plane whose normal is within this |cos| of square to this one sets the sides."""


@dataclass
class Outline:
    """A lit rectangle on a room plane: ``centre + s * half_size[0] * u + t * half_size[1]
    * v`` for s, t in [-1, 1]; ``normal`` towards the cameras."""

    centre: np.ndarray
    normal: np.ndarray
    u: np.ndarray
    v: np.ndarray
    half_size: np.ndarray
    cells: int
    """Lit cells in the region (the rectangle may hold unlit corners)."""
    fill: float = 1.0
    """The share of the rectangle's cells that are lit: a window's or panel's clipped
    region fills its rectangle; specks and lit walls merged into one region do not."""
    single_view: bool = False
    """Only one view frames the region (:data:`SINGLE_VIEW_MARGIN`): it lies on the plane
    only if the light the fit drew there does, which one view cannot show."""
    measured_sides: int = 0
    """How many of its four sides were put where a view that measured the light sees it
    end (:mod:`gaslight_usd.outline_edges`); the rest are where the lit cells end."""
    lit_uv: np.ndarray | None = field(default=None, repr=False, compare=False)
    """(K, 2) the lit cells' centres' coordinates along ``u`` and ``v`` (not kept in the
    metadata): :meth:`fill_within` reads them."""
    cell: float = 0.0
    """The side of those cells."""

    def fill_within(self, centre: np.ndarray, half_size: np.ndarray) -> float:
        """The share of the rectangle (``centre``, ``half_size``, on this outline's plane
        and axes) that the lit cells fill; the outline's own :attr:`fill` where it keeps
        no cells. A clipped light's lit cells run past it (the photos' halo, pixels only
        partly on it), so the cells bounding it leave its corners empty: a 0.4 m ceiling
        panel's 0.46 x 0.50 m outline was 0.78 full, its 0.39 m sides where the measuring
        views see it end all but full (``docs/measurements.md``, session 57)."""
        if self.lit_uv is None or self.cell <= 0:
            return self.fill
        middle = np.array([np.asarray(centre) @ self.u, np.asarray(centre) @ self.v])
        rel = np.abs(self.lit_uv - middle)
        half = np.asarray(half_size, np.float64)
        inside = int(np.all(rel <= half, axis=1).sum())
        return float(min(1.0, inside * self.cell ** 2 / max(float(np.prod(2 * half)), 1e-12)))

    @property
    def clean(self) -> bool:
        """Whether the region fills its rectangle (:data:`MIN_FILL`): a light's rectangle."""
        return self.fill >= MIN_FILL

    def holds(self, point: np.ndarray, margin: float = 0.0) -> bool:
        """Whether ``point``, put on the outline's plane, lies within the rectangle
        grown by ``margin``."""
        rel = np.asarray(point, np.float64) - self.centre
        return bool(abs(rel @ self.u) <= self.half_size[0] + margin
                    and abs(rel @ self.v) <= self.half_size[1] + margin)

    def as_dict(self) -> dict[str, Any]:
        return {"centre": [round(float(x), 5) for x in self.centre],
                "normal": [round(float(x), 5) for x in self.normal],
                "u": [round(float(x), 5) for x in self.u],
                "v": [round(float(x), 5) for x in self.v],
                "half_size": [round(float(x), 5) for x in self.half_size],
                "cells": int(self.cells), "fill": round(float(self.fill), 4),
                "single_view": bool(self.single_view),
                "measured_sides": int(self.measured_sides)}

    @classmethod
    def from_dict(cls, entry: Mapping[str, Any]) -> Outline | None:
        """The outline an :meth:`as_dict` wrote; None for a malformed entry."""
        try:
            vecs = [np.asarray(entry[k], np.float64).reshape(3)
                    for k in ("centre", "normal", "u", "v")]
            half = np.asarray(entry["half_size"], np.float64).reshape(2)
            cells = int(entry.get("cells", 0))
            fill = float(entry.get("fill", 1.0))
            single = bool(entry.get("single_view", False))
            measured = int(entry.get("measured_sides", 0))
        except (KeyError, TypeError, ValueError):
            return None
        if not all(np.all(np.isfinite(x)) for x in (*vecs, half)) or half.min() <= 0:
            return None
        return cls(*vecs, half_size=half, cells=cells, fill=fill, single_view=single,
                   measured_sides=measured)


def outlines_from_metadata(metadata: Mapping[str, Any]) -> list[Outline]:
    """The outlines the fit stored (``flat_outlines``; none for older files)."""
    out = [Outline.from_dict(e) for e in metadata.get("flat_outlines") or []
           if isinstance(e, Mapping)]
    return [o for o in out if o is not None]


def side_axis(normal: np.ndarray, others: Sequence[np.ndarray],
              fallback: np.ndarray | None = None) -> np.ndarray:
    """A unit direction in the plane of ``normal``: along the plane square to it in
    ``others`` (normals; ``normal`` itself among them is ignored) that is most nearly so
    (windows and panels are set square to their walls), else ``fallback`` put in the
    plane, else the in-plane direction nearest the world's x axis, then z."""
    normal = np.asarray(normal, np.float64)
    across = [np.asarray(m, np.float64) for m in others if abs(np.asarray(m) @ normal) < SQUARE_COS]
    candidates = [min(across, key=lambda m: abs(m @ normal))] if across else []
    if fallback is not None:
        candidates.append(np.asarray(fallback, np.float64))
    candidates += [np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])]
    for side in candidates:
        u = side - (side @ normal) * normal
        if np.linalg.norm(u) > 1e-3:
            return u / np.linalg.norm(u)
    return np.array([0.0, 1.0, 0.0])


def plane_outlines(planes: Sequence[tuple[np.ndarray, float]], cameras: Sequence[PinholeCamera],
                   lit: Sequence[np.ndarray | None]) -> list[Outline]:
    """The lit rectangles (module docstring) on each of ``planes`` (unit normal towards
    the cameras, offset), from ``cameras`` and their ``lit`` masks (H, W) bool at any
    size (None: the view does not count)."""
    if not planes or not cameras:
        return []
    centres = np.array([c.center for c in cameras], np.float64)
    out: list[Outline] = []
    normals = [np.asarray(n, np.float64) for n, _ in planes]
    for k, (normal, offset) in enumerate(planes):
        normal = np.asarray(normal, np.float64)
        dist = centres @ normal - offset
        front = dist > 0
        if front.sum() < MIN_VIEWS:
            continue
        u = side_axis(normal, normals[:k] + normals[k + 1:])
        v = np.cross(normal, u)
        reach = SPAN_SHARE * float(np.median(dist[front]))
        cu, cv = centres[front] @ u, centres[front] @ v
        lo = np.array([cu.min() - reach, cv.min() - reach])
        hi = np.array([cu.max() + reach, cv.max() + reach])
        cell = max(CELL_SHARE * float(np.median(dist[front])), float((hi - lo).max()) / MAX_CELLS)
        nu, nv = (np.ceil((hi - lo) / cell)).astype(int)
        gu = lo[0] + (np.arange(nu) + 0.5) * cell
        gv = lo[1] + (np.arange(nv) + 0.5) * cell
        good = _votes(offset, normal, u, v, gu, gv, cameras, lit, front)
        labels, count = ndimage.label(good, structure=np.ones((3, 3)))
        sizes = np.bincount(labels.ravel(), minlength=count + 1)
        boxes = ndimage.find_objects(labels)
        largest = [lab for lab in np.argsort(-sizes[1:]) + 1 if sizes[lab] >= MIN_CELLS]
        swept = []  # the depths the views agreed on where they moved a region's plane
        one_place = []  # regions only views from one place frame: they cannot sweep it
        regions = []
        for lab in largest[:MAX_OUTLINES]:
            su, sv = boxes[lab - 1]
            # the plane's depth there, as the views agree on it (module docstring)
            margin = max(3, int(np.ceil(0.25 * max(su.stop - su.start, sv.stop - sv.start))))
            bu = slice(max(0, su.start - margin), min(nu, su.stop + margin))
            bv = slice(max(0, sv.start - margin), min(nv, sv.stop + margin))
            depth = _agreeing_offset(offset, normal, u, v, gu[bu], gv[bv], cameras, lit,
                                     front, float(np.median(dist[front])))
            if depth is None:
                one_place.append((lab, bu, bv))
                continue
            if depth != offset:
                swept.append(depth)
            regions.append((depth, lab, bu, bv))
        # one place cannot sweep the plane: where views from two moved it under their
        # lights, the plane (a flat ceiling) is there under this light too
        at = float(np.median(swept)) if swept else offset
        regions += [(at, lab, bu, bv) for lab, bu, bv in one_place]
        for depth, lab, bu, bv in regions:
            if depth == offset:
                region = labels[bu, bv] == lab
            else:
                moved = _moved_region(depth, normal, u, v, gu, gv, bu, bv, cameras, lit,
                                      front)
                if moved is None:
                    continue
                region, bu, bv = moved
            outline = _outline_of(region, gu[bu], gv[bv], cell, depth, normal, u, v)
            if outline is not None and _in_room(outline, planes, k):
                out.append(outline)
        framed, seen, which = _counts(at, normal, u, v, gu, gv, cameras, lit, front)
        good = (framed >= MIN_VIEWS) & (seen >= LIT_SHARE * np.maximum(framed, 1))
        for region in _single_view_regions(framed, seen, which, good):
            outline = _outline_of(region, gu, gv, cell, at, normal, u, v)
            if outline is not None and _in_room(outline, planes, k):
                outline.single_view = True
                out.append(outline)
    return sorted(out, key=lambda o: -o.cells)[:MAX_OUTLINES]


def look_up(cam: PinholeCamera, mask: np.ndarray, points: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """Per point (N, 3): whether ``cam`` frames it, and ``mask`` (H, W, at any size)
    there (False where it does not frame it)."""
    x, y, inside = cam.pixels_of(points, mask.shape)
    value = np.zeros(len(points), bool)
    value[inside] = mask[y[inside], x[inside]]
    return inside, value


def grid_look_up(cam: PinholeCamera, mask: np.ndarray, base: np.ndarray, u: np.ndarray,
                 v: np.ndarray, gu: np.ndarray, gv: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`look_up` for the grid ``base + gu[i] u + gv[j] v`` (``meshgrid(gu, gv,
    indexing="ij")`` raveled)."""
    x, y, inside = cam.pixels_of_grid(base, u, v, gu, gv, mask.shape)
    value = np.zeros(len(inside), bool)
    value[inside] = mask[y[inside], x[inside]]
    return inside, value


def _counts(offset: float, normal: np.ndarray, u: np.ndarray, v: np.ndarray, gu: np.ndarray,
            gv: np.ndarray, cameras: Sequence[PinholeCamera], lit: Sequence[np.ndarray | None],
            front: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per cell of the plane (``normal``, ``offset``), ``(len(gu), len(gv))`` each: how
    many views frame it, how many saw light there, and the last view that framed it."""
    n = len(gu) * len(gv)
    framed = np.zeros(n, np.int32)
    seen = np.zeros(n, np.int32)
    which = np.full(n, -1, np.int32)
    for k, (cam, mask, ahead) in enumerate(zip(cameras, lit, front, strict=True)):
        if ahead and mask is not None:
            inside, value = grid_look_up(cam, mask, offset * normal, u, v, gu, gv)
            framed += inside
            seen += value
            which[inside] = k
    shape = (len(gu), len(gv))
    return framed.reshape(shape), seen.reshape(shape), which.reshape(shape)


def _votes(offset: float, normal: np.ndarray, u: np.ndarray, v: np.ndarray, gu: np.ndarray,
           gv: np.ndarray, cameras: Sequence[PinholeCamera], lit: Sequence[np.ndarray | None],
           front: np.ndarray) -> np.ndarray:
    """(len(gu), len(gv)) cells of the plane (``normal``, ``offset``) lit in the views
    (:data:`MIN_VIEWS`, :data:`LIT_SHARE`)."""
    framed, seen, _ = _counts(offset, normal, u, v, gu, gv, cameras, lit, front)
    return (framed >= MIN_VIEWS) & (seen >= LIT_SHARE * np.maximum(framed, 1))


GROW_TIMES = 4
"""A region looked up on a moved plane has its window grown (doubled) at most this many
times where the lit cells reach its side (:func:`_moved_region`)."""


def _moved_region(depth: float, normal: np.ndarray, u: np.ndarray, v: np.ndarray,
                  gu: np.ndarray, gv: np.ndarray, bu: slice, bv: slice,
                  cameras: Sequence[PinholeCamera], lit: Sequence[np.ndarray | None],
                  front: np.ndarray) -> tuple[np.ndarray, slice, slice] | None:
    """The largest lit region (:func:`_votes`) on the plane moved to ``depth``, within
    the window ``bu``, ``bv`` of the grid (cell centres ``gu``, ``gv``), grown where the
    region reaches its side: the window was drawn round what the views agreed on at the
    room box's depth, and on a plane 14 cm off, the views' outlines slid apart, that was
    a third of the panel (session 62). (region mask, window) or None where nothing is lit."""
    nu, nv = len(gu), len(gv)
    for attempt in range(GROW_TIMES + 1):
        moved = _votes(depth, normal, u, v, gu[bu], gv[bv], cameras, lit, front)
        near, n_near = ndimage.label(moved, structure=np.ones((3, 3)))
        if not n_near:
            return None
        counts = np.bincount(near.ravel(), minlength=n_near + 1)
        counts[0] = 0
        region = near == int(np.argmax(counts))
        rows, cols = np.nonzero(region)
        grow_u, grow_v = bu.stop - bu.start, bv.stop - bv.start
        wider = (slice(max(0, bu.start - grow_u * (rows.min() == 0)),
                       min(nu, bu.stop + grow_u * (rows.max() == region.shape[0] - 1))),
                 slice(max(0, bv.start - grow_v * (cols.min() == 0)),
                       min(nv, bv.stop + grow_v * (cols.max() == region.shape[1] - 1))))
        if wider == (bu, bv) or attempt == GROW_TIMES:
            break
        bu, bv = wider
    return region, bu, bv


def _single_view_regions(framed: np.ndarray, seen: np.ndarray, which: np.ndarray,
                         good: np.ndarray) -> list[np.ndarray]:
    """Masks of the lit regions one view alone frames (module docstring,
    :data:`SINGLE_VIEW_MARGIN`): the cells lit in some view that frames them, joined,
    where the cells only one view frames (at least :data:`MIN_CELLS`) are all that view's,
    those two views judged lit are too few for an outline of their own, and every cell
    round the region is framed and dark (the region is the whole light)."""
    alone = (framed == 1) & (seen == 1)
    labels, count = ndimage.label((seen > 0) & (alone | (framed > 1)),
                                  structure=np.ones((3, 3)))
    ring = np.ones((2 * SINGLE_VIEW_MARGIN + 1,) * 2, bool)
    alone_cells = np.bincount(labels[alone], minlength=count + 1)  # specks skipped unbuilt
    out = []
    for lab in np.flatnonzero(alone_cells >= MIN_CELLS):
        region = labels == lab
        mine = region & alone
        if mine.sum() < MIN_CELLS or good[region].sum() >= MIN_CELLS \
                or len(np.unique(which[mine])) != 1:
            continue
        around = ndimage.binary_dilation(region, ring) & ~region
        if (framed[around] == 0).any() or (seen[around] > 0).any():
            continue  # cut by the frame, or part of more light
        # one view's pixels, coarser than the cells, leave its edge ragged a cell deep
        # where views' votes smooth it: smoothed so, its rectangle is the light's
        smooth = ndimage.binary_opening(ndimage.binary_closing(region, np.ones((3, 3))),
                                        np.ones((3, 3)))
        out.append(smooth if smooth.sum() >= MIN_CELLS else region)
    return out


def _agreeing_offset(offset: float, normal: np.ndarray, u: np.ndarray, v: np.ndarray,
                     gu: np.ndarray, gv: np.ndarray, cameras: Sequence[PinholeCamera],
                     lit: Sequence[np.ndarray | None], front: np.ndarray,
                     distance: float) -> float | None:
    """The plane offset within :data:`DEPTH_SWEEP` of the cameras' ``distance`` where the
    views' lit regions on the grid (cell centres ``gu``, ``gv``) coincide: the least spread
    of their centres, over the views that see the light whole at every depth (their frame
    not touching it: :func:`_uncut`; seen from apart, the views' outlines on a plane at
    the wrong depth slide apart). ``offset`` unless that
    spread is under :data:`DEPTH_GAIN` of the spread there; None where those views stand
    in one place (:data:`PLACES_APART`)."""
    uu, vv = np.meshgrid(gu, gv, indexing="ij")
    flat = np.stack([uu.ravel(), vv.ravel()], axis=1)
    steps = np.linspace(-DEPTH_SWEEP, DEPTH_SWEEP, 2 * DEPTH_STEPS + 1) * distance
    lit_cells = []  # per step, per view: its lit cells; None where its frame cuts them
    for step in steps:
        base = (offset + step) * normal
        row: list[np.ndarray | None] = []
        for cam, mask, ahead in zip(cameras, lit, front, strict=True):
            inside, value = (grid_look_up(cam, mask, base, u, v, gu, gv)
                             if ahead and mask is not None else (None, None))
            row.append(None if inside is None else _uncut(inside, value, len(gu), len(gv)))
        lit_cells.append(row)
    # one set of views at every depth, each seeing the light whole
    chosen = [k for k in range(len(cameras))
              if all(row[k] is not None and row[k].sum() >= MIN_CELLS for row in lit_cells)]
    if len(chosen) < MIN_VIEWS:
        return offset
    places = np.array([cameras[k].center for k in chosen])
    if float(np.linalg.norm(places - places[0], axis=1).max()) < PLACES_APART * distance:
        return None
    middle = offset * normal + float(np.mean(gu)) * u + float(np.mean(gv)) * v
    rays = np.array([middle - cameras[k].center for k in chosen])
    facing = np.abs(rays @ normal) / np.linalg.norm(rays, axis=1)
    if float(np.median(facing)) > FACE_ON_COS:
        return offset  # seen face on, the outline hardly moves with the plane's depth
    spreads = []
    for row in lit_cells:
        centres = np.array([flat[row[k]].mean(axis=0) for k in chosen])
        spreads.append(float(np.sqrt(((centres - centres.mean(0)) ** 2).sum(1).mean())))
    best = int(np.argmin(spreads))
    if spreads[best] > DEPTH_GAIN * spreads[DEPTH_STEPS]:
        return offset
    return float(offset + steps[best])


def _uncut(inside: np.ndarray, value: np.ndarray, nu: int, nv: int) -> np.ndarray | None:
    """A view's lit cells of a grid (``inside``: the cells it frames, raveled ``(nu,
    nv)``), or None where its frame's edge touches them: a light the frame cuts has its
    centre moved by the cut, not by the plane's depth. Framing the whole grid was asked
    once, and a sweep wide enough for a ceiling 14 cm off lost a view whose frame only
    cut the grid's margin at the far depths (``panels:7``)."""
    if inside.all():
        return value
    outside = ndimage.binary_dilation(~inside.reshape(nu, nv), np.ones((3, 3), bool))
    return None if bool((outside.ravel() & value).any()) else value


def _in_room(outline: Outline, planes: Sequence[tuple[np.ndarray, float]], k: int) -> bool:
    """Whether ``outline``, on plane ``k`` of ``planes``, lies on the room's side of the
    others: a light seen past a wall or the ceiling, put on this plane's stretch beyond
    them (a ceiling panel's pixels carried on to a wall's plane over the ceiling), is none
    of this room's."""
    return all(float(np.asarray(m) @ outline.centre) - d > 0
               for j, (m, d) in enumerate(planes) if j != k)


def _outline_of(region: np.ndarray, gu: np.ndarray, gv: np.ndarray, cell: float,
                offset: float, normal: np.ndarray, u: np.ndarray, v: np.ndarray
                ) -> Outline | None:
    """The outline bounding the lit cells ``region`` of a grid (cell centres ``gu``,
    ``gv``) on the plane (``normal``, ``offset``)."""
    cells = int(region.sum())
    if cells < MIN_CELLS:
        return None
    rows, cols = np.nonzero(region)
    a0, a1 = gu[rows.min()] - cell / 2, gu[rows.max()] + cell / 2
    b0, b1 = gv[cols.min()] - cell / 2, gv[cols.max()] + cell / 2
    box = (rows.max() - rows.min() + 1) * (cols.max() - cols.min() + 1)
    centre = offset * normal + (a0 + a1) / 2 * u + (b0 + b1) / 2 * v
    lit_uv = np.stack([gu[rows], gv[cols]], axis=1)
    return Outline(centre=centre, normal=normal.copy(), u=u.copy(), v=v.copy(),
                   half_size=np.array([(a1 - a0) / 2, (b1 - b0) / 2]), cells=cells,
                   fill=float(cells / box), lit_uv=lit_uv, cell=float(cell))


def lit_masks(images: Sequence[np.ndarray], floors: Sequence[np.ndarray | None],
              weights: np.ndarray) -> list[np.ndarray]:
    """Per view where it saw a light: its clipped pixels (a clip floor over 0), or, in a
    view that clipped nothing, its pixels over :data:`UNCLIPPED_RATIO` times its median
    luminance (``weights``), cut to its regions' edges (:data:`EDGE_LEVEL`).

    Not over the view's white, as the sightings read an unclipped view: a true HDR view's
    white is any level, and over it the outlines took whole lit ceilings with the panels
    (``docs/measurements.md``, session 49).

    A view that clipped something also saw, unclipped, the lights dimmer than what it
    clipped: a darker frame exposed for a window clips a lamp's glow and measures the
    window. Its regions over the ratio (clipped pixels included) that it measured (under
    :data:`CLIPPED_SHARE` of their pixels clipped: a firefly or JPEG ringing can clip a
    pixel of a window) are lit too; in one more clipped, a clipped light and its halo,
    only the clipped pixels are. Counting only the clipped pixels, such a frame
    voted "dark" over the window it measured, and a shaded room's window came out half its
    width (``docs/measurements.md``, session 61)."""
    out = []
    for image, floor in zip(images, floors, strict=True):
        lum = np.asarray(image, np.float64) @ np.asarray(weights, np.float64)
        bright = lum > UNCLIPPED_RATIO * max(float(np.median(lum)), 1e-30)
        clipped = None if floor is None else np.asarray(floor) > 0
        if clipped is None or not clipped.any():
            out.append(_to_edges(lum, bright))
            continue
        labels, count = ndimage.label(bright | clipped)
        pixels = np.bincount(labels.ravel(), minlength=count + 1)
        share = np.bincount(labels.ravel(), weights=clipped.ravel(), minlength=count + 1)
        measured = share < CLIPPED_SHARE * pixels
        measured[0] = False
        out.append(clipped | _to_edges(np.where(clipped, np.maximum(lum, floor), lum),
                                       measured[labels]))
    return out


def _to_edges(lum: np.ndarray, lit: np.ndarray) -> np.ndarray:
    """``lit`` (H, W) with each connected region cut to what is over :data:`EDGE_LEVEL`
    of the region's level (:data:`EDGE_QUANTILE` of its luminance)."""
    labels, count = ndimage.label(lit)
    if not count:
        return lit
    level = ndimage.labeled_comprehension(lum, labels, np.arange(1, count + 1),
                                          lambda x: np.quantile(x, EDGE_QUANTILE), float, 0.0)
    floor = np.concatenate([[np.inf], EDGE_LEVEL * np.asarray(level)])[labels]
    return lit & (lum >= floor)
