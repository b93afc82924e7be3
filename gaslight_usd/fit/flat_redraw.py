"""Windows and panels redrawn as what they are: a flat, even emitter on their rectangle.

A fit draws a window with a few hundred translucent blobs a few centimetres thick, each
brighter than the window, plus a dim veil of floaters in front of it; seen from where
the photos were taken they add up to the window, seen from half a metre they do not:
even from true HDR views a probe 0.5 m from a window saw a good part of a stop too much
of its light, though the renderer draws a flat window of splats right from any distance.

Where the views outlined the light's rectangle on a wall or ceiling
(:mod:`gaslight_usd.flat_outlines`, :func:`gaslight_usd.light_shapes.panel_of`), its
splats, every splat in the rectangle within :data:`SLAB_SHARE` of the plane, and the
bright ones round its edge, are replaced by a grid of flat, opaque splats on the
rectangle, one colour, at the level that keeps what the training views draw (their sums
over the views that frame it, solved in closed form: the grid is opaque, so a view's sum
is linear in its level), or the level the views that measured it read inside it where
that is lower or where those views set every side of the rectangle (it is then the
light's, not a clipped halo: the fit's sums drew the hall's window 0.2 stops dim), in
their colour (:func:`rectangle_reading`; a view too near its black to read it is left
out). Each overshoots in its way: the
fit's blobs draw a window 0.1-0.3 stops over what the views read (true HDR views), and
the views' reading over a rectangle the clipped photos outlined too large (their halo
round a ceiling panel, +40 % in area) puts too much light in it (``docs/measurements.md``,
session 50). A rectangle one view alone outlined takes that view's reading, above the
sums or below: one view cannot place the fit's splats of the light (they spread along its
rays, and of ``panels:7``'s second panel half fell outside its rectangle: its sums said
half its level; ``docs/measurements.md``, session 51). Then the splats over the white
floating in front of the rectangle, within its prism (up to :data:`OFF_SHARE` of the
median depth off it, and farther out where every view that frames them sees the rectangle
behind them: :func:`seen_over`), that are not another light many times brighter
(:data:`LAMP_RATIO`), join it and the level is solved again: a fit leaves window-bright
floaters there that every view sees over the window, and a probe beside it sees a fog.
So do bright splats behind its plane, round its edge or farther back where every view
that frames them sees them through the rectangle: a light one view framed smears along
that view's rays both ways, past the wall or ceiling, where a probe at a grazing angle
sees it through the surface beside the light.
The fit redraws only lights a view measured (a true HDR view, merged brackets, a darker
frame: :func:`gaslight_usd.fit.power.light_sighting`): where every photo clipped a window
its power is the uplift's fill, a lower bound, and drawn flat it lost more of it near by.

``gaslight2usd bench --suite chain`` measures it at the probes 0.5 m from the windows
(``irradiance_psnr``, ``power_err_window``; ``docs/measurements.md``, sessions 49-50).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..cameras import PinholeCamera, matrix_to_quaternion
from ..light_shapes import OUTLINED_OFF_SHARE, Panel
from ..splats import SplatScene
from .backdrop import concatenate

CELL_SHARE = 0.02
"""The grid's spacing, as a share of the captured space's median depth (5 cm in a 2.5 m
room: a 1.8 x 1.2 m window is some 900 splats; neighbours overlap to an even sheet, and
its edge blurs by 3 cm)."""
SLAB_SHARE = 0.06
"""Splats inside the rectangle within this share of the median depth of its plane (in
front or behind) are the light's, or the wall's around it, and are replaced."""
EDGE_SHARE = 0.08
"""Bright splats (over the white) this far past the rectangle's edge, as a share of the
median depth, are its halo and are replaced too."""
HALO_SHARE = 0.25
"""Splats round the rectangle's edge are its halo where over this share of the light's
median radiance: a ceiling panel lights the ceiling round it over the views' white."""
OFF_SHARE = OUTLINED_OFF_SHARE
"""The light's own splats are replaced up to this share of the median depth off the
plane (as far as :func:`gaslight_usd.light_shapes.panel_of` takes a light for the
panel)."""
REACH_SIGMAS = 2.0
"""A dim splat in front of the rectangle reaches over it within this many of its largest
scales (past that a Gaussian hides under 14 % of what is behind it)."""
THIN_SHARE = 0.001
"""The grid's splats' thickness, as a share of the median depth."""
OPACITY = 0.99
SAMPLES = 24
"""Points along each side of the rectangle where the views' reading of it is taken."""
INSET = 0.2
"""...kept this share of its half-size in from each edge: its blurred border, and the
outline's few per cent of slack, are the wall's."""
DARK_MARGIN = 16.0
"""A view reads the rectangle only where it is over this many times the luminance the
view's photo crushed to black (its dark ceiling's top: code 3 of 255), about code 32,
where 8-bit steps are a few per cent: a frame exposed 12.7 stops down for a bulb saw its
room's window at codes 3-4 and read it 0.25 stops over."""
LAMP_RATIO = 4.0
"""Another light in front of the rectangle is a lamp, and stays, where its splats' median
is over this many times the redrawn level (a lamp is hundreds of times a window; the
fit's window-bright floaters a few)."""


@dataclass
class Redrawn:
    """What was redrawn: per panel its splats replaced, grid splats and level."""

    panels: list[dict[str, Any]] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return {"panels": self.panels}


def _grid(panel: Panel, cell: float, thin: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (K, 3), rotations (K, 4) and scales (K, 3) of a grid of flat splats
    covering ``panel``."""
    nu = max(1, int(np.ceil(2.0 * panel.half_size[0] / cell)))
    nv = max(1, int(np.ceil(2.0 * panel.half_size[1] / cell)))
    su, sv = 2.0 * panel.half_size[0] / nu, 2.0 * panel.half_size[1] / nv
    a = -panel.half_size[0] + (np.arange(nu) + 0.5) * su
    b = -panel.half_size[1] + (np.arange(nv) + 0.5) * sv
    aa, bb = np.meshgrid(a, b, indexing="ij")
    pos = panel.centre + aa.reshape(-1, 1) * panel.u + bb.reshape(-1, 1) * panel.v
    frame = np.stack([panel.u, np.cross(panel.normal, panel.u), panel.normal], axis=1)
    rot = np.tile(matrix_to_quaternion(frame), (len(pos), 1))
    # a Gaussian of sigma 0.6 spacing: neighbours overlap to an even, opaque sheet
    scales = np.tile([0.6 * su, 0.6 * sv, thin], (len(pos), 1))
    return pos, rot, scales


def _with_grid(head: SplatScene, pos: np.ndarray, rot: np.ndarray, scales: np.ndarray,
               colour: np.ndarray, back: SplatScene) -> SplatScene:
    """``head``, a grid of opaque splats of linear ``colour`` (3,), then ``back``."""
    grid = SplatScene.from_activated(pos, np.tile(np.asarray(colour, np.float64), (len(pos), 1)),
                                     scales, np.full(len(pos), OPACITY), rotations=rot,
                                     sh_degree=head.sh_degree)
    return concatenate(concatenate(head, grid), back)


def _view_sums(scene: SplatScene, cameras: Sequence[PinholeCamera], weights: np.ndarray
               ) -> np.ndarray:
    from ..render import render

    return np.array([float(render(scene, cam).image.detach().cpu().numpy()
                           .reshape(-1, 3).astype(np.float64).sum(0) @ weights)
                     for cam in cameras])


def rectangle_reading(panel: Panel, cameras: Sequence[PinholeCamera],
                      images: Sequence[np.ndarray], floors: Sequence[np.ndarray | None],
                      weights: np.ndarray, white: float,
                      ceilings: Sequence[np.ndarray | None] | None = None
                      ) -> tuple[float, np.ndarray] | None:
    """(luminance, chroma (3,)) the views read inside ``panel`` (its middle, :data:`INSET`
    in from each edge, off its blurred border): per view that frames it whole, clipped
    nothing there and read it over twice the ``white`` and :data:`DARK_MARGIN` times its
    photo's black (the top of its dark ``ceilings``, None: it crushed nothing), the mean
    of those pixels; the median over such views (one a lamp or a plant stood in front of
    is outvoted). None where no view measured it whole."""
    n = SAMPLES
    a = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    aa, bb = np.meshgrid(a, a, indexing="ij")
    scale = 1.0 - INSET
    points = (panel.centre + (aa.reshape(-1, 1) * panel.half_size[0] * scale) * panel.u
              + (bb.reshape(-1, 1) * panel.half_size[1] * scale) * panel.v)
    means = []
    blacks = [0.0 if c is None else float(np.max(c))
              for c in (ceilings if ceilings is not None else [None] * len(images))]
    for cam, image, floor, black in zip(cameras, images, floors, blacks, strict=True):
        if float((cam.center - panel.centre) @ panel.normal) <= 0:
            continue
        x, y, inside = cam.pixels_of(points, image.shape)
        if not inside.all():
            continue
        if floor is not None and bool((np.asarray(floor)[y, x] > 0).any()):
            continue
        rgb = np.asarray(image, np.float64)[y, x].mean(axis=0)
        if float(rgb @ weights) > max(2.0 * white, DARK_MARGIN * black):
            means.append(rgb)
    if not means:
        return None
    rgb = np.median(np.asarray(means), axis=0)
    level = float(rgb @ weights)
    return level, rgb / level


def _solve(scene: SplatScene, panel: Panel, replace: np.ndarray, colours: np.ndarray,
           radiance: np.ndarray, white: float, median_depth: float,
           views: Sequence[PinholeCamera], weights: np.ndarray, tail: int,
           measured: tuple[float, np.ndarray] | None = None):
    """(level, the scene at a level, the kept splats, the grid's size, which level:
    "splats" or "views") for ``replace`` redrawn as a grid on ``panel`` at the level
    keeping the ``views``' sums, or the ``measured`` (level, chroma) where that is lower
    or one view alone outlined the panel (in its chroma either way); None where nothing
    bright is replaced or no level fits."""
    lit = replace & (radiance > white)
    if not lit.any():
        return None
    power = (colours[lit] * scene.opacities[lit, None]).sum(0)
    chroma = (measured[1] if measured is not None
              else power / max(float(power @ weights), 1e-30))
    grid = _grid(panel, CELL_SHARE * median_depth, THIN_SHARE * median_depth)
    keep = np.flatnonzero(~replace)
    head = scene.subset(keep[keep < len(replace) - tail])
    back = scene.subset(keep[keep >= len(replace) - tail])

    def with_level(level: float) -> SplatScene:
        return _with_grid(head, *grid, chroma * level, back)

    before = _view_sums(scene, views, weights)
    dark = _view_sums(with_level(0.0), views, weights)
    unit = _view_sums(with_level(1.0), views, weights) - dark
    level = float((before - dark).sum() / unit.sum()) if float(unit.sum()) > 0 else np.nan
    # the lower of the two: the views' reading over a rectangle the clipped photos
    # outlined too large (their halo) overshoots, and so do the fit's blobs where the
    # rectangle is right (module docstring); the reading where the measuring views set
    # every side
    source = "splats"
    if measured is not None and (panel.single_view or panel.measured_sides >= 4
                                 or not (np.isfinite(level) and 0 < level < measured[0])):
        level, source = measured[0], "views"
    if not np.isfinite(level) or level <= 0:
        return None
    return level, with_level, keep, len(grid[0]), source


def seen_over(panel: Panel, points: np.ndarray, cameras: Sequence[PinholeCamera],
              margin: float = 0.0) -> np.ndarray:
    """Per point (N, 3): at least one of ``cameras`` frames it, and every one that does
    sees it over ``panel`` (its rectangle grown by ``margin``): a point in front of the
    panel with the rectangle behind it, a point behind the panel's plane through the
    rectangle."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    framed = np.zeros(len(points), np.int64)
    backed = np.ones(len(points), bool)
    if not len(points):
        return backed
    plane = float(panel.centre @ panel.normal)
    for cam in cameras:
        uv, z = cam.project(points)
        inside = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & (uv[:, 1] >= 0) \
            & (uv[:, 1] < cam.height)
        ray = points - cam.center
        along = ray @ panel.normal
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (plane - float(cam.center @ panel.normal)) / along
        hit = cam.center + s[:, None] * ray
        rel = hit - panel.centre
        crosses = np.where(points @ panel.normal >= plane, s > 1.0, (s > 0.0) & (s < 1.0))
        on = (crosses & (np.abs(rel @ panel.u) <= panel.half_size[0] + margin)
              & (np.abs(rel @ panel.v) <= panel.half_size[1] + margin))
        framed += inside
        backed &= ~inside | on
    return backed & (framed > 0)


def _framing(panel: Panel, cameras: Sequence[PinholeCamera]) -> list[PinholeCamera]:
    """The cameras in front of ``panel`` whose frame holds its centre."""
    out = []
    for cam in cameras:
        if float((cam.center - panel.centre) @ panel.normal) <= 0:
            continue
        uv, z = cam.project(panel.centre[None])
        if z[0] > 0 and 0 <= uv[0, 0] < cam.width and 0 <= uv[0, 1] < cam.height:
            out.append(cam)
    return out


def redraw_flat_lights(scene: SplatScene, panels: Sequence[Panel],
                       light_splats: Sequence[np.ndarray], cameras: Sequence[PinholeCamera],
                       white: float, median_depth: float, weights: np.ndarray,
                       tail: int = 0, other_lights: Sequence[np.ndarray] = (),
                       images: Sequence[np.ndarray] | None = None,
                       floors: Sequence[np.ndarray | None] | None = None,
                       ceilings: Sequence[np.ndarray | None] | None = None
                       ) -> tuple[SplatScene, Redrawn]:
    """``scene`` with each of ``panels`` (the rectangle of the light whose splats are
    ``light_splats``) redrawn as a flat, even emitter (module docstring), at the level
    that keeps the sums of the ``cameras`` that frame it; ``white``: the views' white
    (what is over it is bright); ``weights``: luminance weights; ``tail``: the last
    splats (the fit's backdrop) are never replaced and stay last; ``images`` and
    ``floors``: the ``cameras``' HDR views and clip floors, whose reading inside the
    rectangle sets its level where one measured it (:func:`rectangle_reading`; their
    dark ``ceilings`` say where a view is too dark to read)."""
    report = Redrawn()
    weights = np.asarray(weights, np.float64)
    owns = [np.asarray(own, np.int64) for own in light_splats]
    others = [np.asarray(extra, np.int64) for extra in other_lights]
    done: list[np.ndarray] = []
    for k, panel in enumerate(panels):
        if any(np.allclose(panel.centre, c) for c in done):
            continue  # two lights the same outline holds: one rectangle
        own = owns[k]
        views = _framing(panel, cameras)
        if not views:
            continue
        pos = scene.positions.astype(np.float64)
        rel = pos - panel.centre
        d, a, b = rel @ panel.normal, np.abs(rel @ panel.u), np.abs(rel @ panel.v)
        colours = scene.base_colours.astype(np.float64)
        radiance = colours.max(axis=1)
        slab = np.abs(d) <= SLAB_SHARE * median_depth
        edge = EDGE_SHARE * median_depth
        inside = (a <= panel.half_size[0]) & (b <= panel.half_size[1])
        halo = (a <= panel.half_size[0] + edge) & (b <= panel.half_size[1] + edge)
        # the halo is the light's blur, not the wall or ceiling it lights round it
        level = np.median(radiance[own]) if len(own) else white
        bright = radiance > max(white, HALO_SHARE * float(level))
        replace = slab & (inside | (halo & bright))
        # the light's own splats, where they lie over the rectangle (a fit can leave a
        # window's light in front of it); not those of another light grouped with it
        over = own[halo[own] & (np.abs(d[own]) <= OFF_SHARE * median_depth)]
        replace[over] = True
        if tail:
            replace[len(replace) - tail:] = False
        # the wall's or ceiling's own splats a few centimetres in front of the plane, past
        # the rectangle but wide enough to reach over it, hide a corner of the light from
        # a probe (``gaslight2usd bench --suite chain --scene panels:7``;
        # docs/measurements.md, session 66); set just behind the grid, they still show
        # round it
        reach = REACH_SIGMAS * scene.scales.max(axis=1)
        behind = (slab & ~replace & ~bright & (d > 0) & (a <= panel.half_size[0] + reach)
                  & (b <= panel.half_size[1] + reach))
        behind[own] = False
        if tail:
            behind[len(replace) - tail:] = False
        if behind.any():
            scene = scene.subset(np.arange(scene.count))
            back = (d[behind] + 2.0 * THIN_SHARE * median_depth)[:, None] * panel.normal
            scene.positions[behind] = (pos[behind] - back).astype(scene.positions.dtype)
        measured = (None if images is None else
                    rectangle_reading(panel, cameras, images,
                                      floors if floors is not None else [None] * len(images),
                                      weights, white, ceilings))
        solved = _solve(scene, panel, replace, colours, radiance, white, median_depth, views,
                        weights, tail, measured)
        if solved is None:
            continue
        # window-bright splats floating in front of it are its light too: the clipped
        # photos bound them only from below, every view sees them over the window, and
        # a probe beside it sees a fog; a lamp there (another light, many times brighter)
        # is not
        lit = halo & (d > 0) & (radiance > max(white, HALO_SHARE * solved[0])) & ~replace
        ahead = lit & (d <= OFF_SHARE * median_depth)
        # farther out, those every view that frames them sees over the light: what the
        # photos say of them is the light's, and a probe by the window saw them as a fog
        # (window-bright floaters 0.6-1.2 m in front of the bulb and shaded rooms' windows)
        far = np.flatnonzero(lit & ~ahead)
        ahead[far[seen_over(panel, pos[far], cameras, edge)]] = True
        # and those the fit left behind its plane, outside the room: a light one view
        # framed smears along that view's rays both ways, and a probe at a grazing angle
        # sees them past the ceiling round the light (``--scene panels:2``, session 66)
        past = ~replace & (d < 0) & (radiance > max(white, HALO_SHARE * solved[0]))
        ahead |= past & halo & (d >= -OFF_SHARE * median_depth)
        # farther behind, those every view that frames them sees through the rectangle:
        # the same smear, deeper (a view that framed a ceiling panel left its light up
        # to a metre past the ceiling, which a probe saw through the ceiling beside it:
        # ``--scene panels:2``, session 67)
        deep = np.flatnonzero(past & ~ahead)
        ahead[deep[seen_over(panel, pos[deep], cameras, edge)]] = True
        for extra in others:
            if len(extra) and np.median(radiance[extra]) > LAMP_RATIO * solved[0]:
                ahead[extra] = False
        if tail:
            ahead[len(replace) - tail:] = False
        if ahead.any():
            wider = _solve(scene, panel, replace | ahead, colours, radiance, white,
                           median_depth, views, weights, tail, measured)
            if wider is not None:
                replace, solved = replace | ahead, wider
        level, with_level, keep, grid_splats, source = solved
        scene = with_level(level)
        done.append(panel.centre)
        remap = np.full(len(replace), -1, np.int64)
        front = keep[keep < len(replace) - tail]
        remap[front] = np.arange(len(front))  # the grid follows them, then the tail
        owns = [remap[o][remap[o] >= 0] for o in owns]
        others = [remap[o][remap[o] >= 0] for o in others]
        report.panels.append({"centre": [round(float(x), 4) for x in panel.centre],
                              "width": round(float(2 * panel.half_size[0]), 4),
                              "height": round(float(2 * panel.half_size[1]), 4),
                              "replaced_splats": int(replace.sum()),
                              "grid_splats": int(grid_splats),
                              "set_behind": int(behind.sum()),
                              "radiance": round(level, 5), "views": len(views),
                              "level_from": source})
    return scene, report
