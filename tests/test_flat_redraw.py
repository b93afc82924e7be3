"""A window's fitted blobs redrawn as a flat, even emitter on its rectangle.

A wall (x = 2.5, dim diffuse splats) holds a 1.2 x 1.0 m window drawn as a fit draws
one: translucent blobs 1.6 times its radiance, a few centimetres thick, some a little in
front of the wall, and a halo round its edge; the fit's backdrop is the last splats.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from test_flat_outlines import look_at as outlines_look_at
from test_flat_outlines import window_mask

from gaslight_usd.cameras import PinholeCamera
from gaslight_usd.fit.flat_redraw import redraw_flat_lights
from gaslight_usd.light_shapes import Panel
from gaslight_usd.render import render
from gaslight_usd.splats import SplatScene

WEIGHTS = np.array([0.2126, 0.7152, 0.0722])
CENTRE = np.array([2.5, 1.6, 0.2])
HALF = np.array([0.6, 0.5])  # along z, along y


def look_at(centre, target) -> PinholeCamera:
    return outlines_look_at(centre, target, width=96, height=72, focal=80.0)


def scene_with_window() -> tuple[SplatScene, np.ndarray, int]:
    rng = np.random.default_rng(5)
    gy, gz = np.meshgrid(np.arange(0.3, 3.0, 0.08), np.arange(-1.8, 2.0, 0.08))
    wall = np.column_stack([np.full(gy.size, 2.5), gy.ravel(), gz.ravel()])
    on_window = (np.abs(wall[:, 2] - CENTRE[2]) <= HALF[0]) & (np.abs(wall[:, 1] - CENTRE[1])
                                                               <= HALF[1])
    wall = wall[~on_window]
    k = 400
    blobs = np.column_stack([2.5 - np.abs(rng.normal(0, 0.04, k)),
                             CENTRE[1] + rng.uniform(-HALF[1], HALF[1], k),
                             CENTRE[2] + rng.uniform(-HALF[0], HALF[0], k)])
    halo = np.column_stack([np.full(20, 2.49), CENTRE[1] + HALF[1] + rng.uniform(0.01, 0.1, 20),
                            CENTRE[2] + rng.uniform(-HALF[0], HALF[0], 20)])
    backdrop = np.column_stack([np.full(10, 3.5), rng.uniform(1.2, 2.0, 10),
                                rng.uniform(-0.3, 0.7, 10)])
    pos = np.concatenate([wall, blobs, halo, backdrop])
    rgb = np.concatenate([np.full((len(wall), 3), 0.3), np.full((k, 3), 16.0),
                          np.full((20, 3), 6.0), np.full((10, 3), 2.0)])
    scales = np.concatenate([np.full((len(wall), 3), 0.05), np.full((k, 3), 0.05) *
                             [1.0, 1.0, 0.6], np.full((20, 3), 0.03), np.full((10, 3), 0.2)])
    opac = np.concatenate([np.full(len(wall), 0.95), np.full(k, 0.35), np.full(20, 0.5),
                           np.full(10, 0.9)])
    scene = SplatScene.from_activated(pos, rgb, scales, opac)
    window = np.arange(len(wall), len(wall) + k)
    return scene, window, 10


def panel() -> Panel:
    normal = np.array([-1.0, 0.0, 0.0])
    u = np.array([0.0, 0.0, 1.0])
    return Panel(centre=CENTRE + 0.005 * normal, normal=normal, u=u, v=np.cross(u, normal),
                 half_size=HALF.copy(), plane_offset=0.0, outlined=True)


def sums(scene, cams) -> np.ndarray:
    with torch.no_grad():
        return np.array([float(render(scene, c).image.numpy().reshape(-1, 3).sum(0) @ WEIGHTS)
                         for c in cams])


def test_a_window_of_blobs_is_redrawn_flat_and_even_at_the_power_the_views_drew():
    scene, window, tail = scene_with_window()
    cams = [look_at(c, CENTRE) for c in ([-1.0, 1.5, 0.0], [-0.8, 1.2, 1.3],
                                         [-0.5, 1.8, -1.1], [-1.5, 1.4, 0.6])]
    # a light grouped with it elsewhere on the wall (its splats in the window's light)
    elsewhere = np.flatnonzero(np.abs(scene.positions[:, 2] + 1.5) < 0.05)[:5]
    out, report = redraw_flat_lights(scene, [panel()], [np.concatenate([window, elsewhere])],
                                     cams, white=1.0, median_depth=2.5, weights=WEIGHTS,
                                     tail=tail)
    assert len(report.panels) == 1
    kept = {tuple(p) for p in out.positions.round(5).tolist()}
    assert all(tuple(p) in kept for p in scene.positions[elsewhere].round(5).tolist())
    entry = report.panels[0]
    assert entry["replaced_splats"] >= len(window) + 20  # the blobs and the halo
    before, after = sums(scene, cams), sums(out, cams)
    assert abs(after.sum() / before.sum() - 1.0) < 0.01  # one level keeps the views' total
    np.testing.assert_allclose(after, before, rtol=0.06)  # the blobs were not even
    # the backdrop stays last, untouched
    np.testing.assert_array_equal(out.positions[-tail:], scene.positions[-tail:])
    # the grid lies on the panel's plane, inside its rectangle, opaque
    grid = out.base_colours.max(axis=1) > 1.0
    grid[-tail:] = False
    assert np.allclose(out.positions[grid, 0], panel().centre[0], atol=1e-4)
    assert np.all(np.abs(out.positions[grid, 2] - CENTRE[2]) <= HALF[0])
    # seen from 0.4 m, face on: an even emitter at the level it was given
    near = look_at(CENTRE + [-0.4, 0.0, 0.0], CENTRE)
    with torch.no_grad():
        lum = render(out, near).image.numpy()[24:48, 32:64] @ WEIGHTS
    assert float(lum.std() / lum.mean()) < 0.05
    assert abs(float(lum.mean()) / entry["radiance"] - 1.0) < 0.05


def test_nothing_is_redrawn_where_no_camera_frames_the_panel():
    scene, window, tail = scene_with_window()
    behind = [look_at([4.0, 1.5, 0.0], [5.0, 1.5, 0.0])]
    out, report = redraw_flat_lights(scene, [panel()], [window], behind, white=1.0,
                                     median_depth=2.5, weights=WEIGHTS, tail=tail)
    assert report.panels == [] and out is scene


def test_bright_floaters_in_front_of_the_window_join_it_a_lamp_and_a_plant_stay():
    """A fit leaves window-bright splats floating in front of a window (clipped photos
    bound them only from below); every view sees them over the window, one 0.3 m off it
    is a fog to a probe beside it. They are the window's light and are redrawn with it;
    another light in front of it (a lamp) and dim things (a plant) are not."""
    scene, window, tail = scene_with_window()
    rng = np.random.default_rng(9)
    n = 12
    floaters = np.column_stack([2.5 - rng.uniform(0.2, 0.5, n),
                                CENTRE[1] + rng.uniform(-0.3, 0.3, n),
                                CENTRE[2] + rng.uniform(-0.4, 0.4, n)])
    lamp = CENTRE + [-0.4, -0.3, 0.3] + rng.normal(0, 0.01, (4, 3))
    plant = CENTRE + [-0.3, -0.4, -0.3] + rng.normal(0, 0.03, (6, 3))
    extra = SplatScene.from_activated(
        np.concatenate([floaters, lamp, plant]),
        np.concatenate([np.full((n, 3), 16.0), np.full((4, 3), 500.0), np.full((6, 3), 0.2)]),
        np.full((n + 10, 3), 0.03), np.concatenate([np.full(n, 0.2), np.full(10, 0.9)]))
    head = scene.subset(np.arange(scene.count - tail))
    back = scene.subset(np.arange(scene.count - tail, scene.count))
    from gaslight_usd.fit.backdrop import concatenate

    full = concatenate(concatenate(head, extra), back)
    lamp_idx = np.arange(head.count + n, head.count + n + 4)
    cams = [look_at(c, CENTRE) for c in ([-1.0, 1.5, 0.0], [-0.8, 1.2, 1.3],
                                         [-0.5, 1.8, -1.1], [-1.5, 1.4, 0.6])]
    out, report = redraw_flat_lights(full, [panel()], [window], cams, white=1.0,
                                     median_depth=2.5, weights=WEIGHTS, tail=tail,
                                     other_lights=[lamp_idx])
    assert len(report.panels) == 1
    kept = {tuple(p) for p in out.positions.round(5).tolist()}
    first = head.count  # the floaters, the lamp, the plant, as the scene stores them
    stored = full.positions.round(5).tolist()
    assert not any(tuple(p) in kept for p in stored[first:first + n])
    assert all(tuple(p) in kept for p in stored[first + n:first + n + 10])
    before, after = sums(full, cams), sums(out, cams)
    assert abs(after.sum() / before.sum() - 1.0) < 0.01
    # nothing window-bright is left floating in front of it but the lamp
    d = 2.5 - out.positions[:, 0]
    lum = out.base_colours @ WEIGHTS
    front = (d > 0.1) & (lum > 1.0)
    assert front.sum() == 4 and np.all(lum[front] > 100.0)


def test_a_window_no_light_holds_is_redrawn_from_its_outline_alone():
    """The fit's light for a window can sit off in the room, or be missing; the outline
    the views drew (and one view measured) is the window all the same: with no splats of
    its own, what lies in its rectangle on the wall is redrawn."""
    scene, window, tail = scene_with_window()
    cams = [look_at(c, CENTRE) for c in ([-1.0, 1.5, 0.0], [-0.8, 1.2, 1.3],
                                         [-0.5, 1.8, -1.1], [-1.5, 1.4, 0.6])]
    out, report = redraw_flat_lights(scene, [panel()], [np.zeros(0, np.int64)], cams,
                                     white=1.0, median_depth=2.5, weights=WEIGHTS, tail=tail)
    assert len(report.panels) == 1 and report.panels[0]["replaced_splats"] >= len(window)
    before, after = sums(scene, cams), sums(out, cams)
    assert abs(after.sum() / before.sum() - 1.0) < 0.01
    near = look_at(CENTRE + [-0.4, 0.0, 0.0], CENTRE)
    with torch.no_grad():
        lum = render(out, near).image.numpy()[24:48, 32:64] @ WEIGHTS
    assert float(lum.std() / lum.mean()) < 0.05


def test_a_window_a_view_measured_takes_the_level_the_views_read_inside_it():
    """The fit's blobs draw the window brighter than it is (what the training views sum
    over it overshoots); the views that measured it read its level: the grid takes that
    (and its colour), not the sums' level. A view that clipped there does not count."""
    scene, window, tail = scene_with_window()
    cams = [look_at(c, CENTRE) for c in ([-1.0, 1.5, 0.0], [-0.8, 1.2, 1.3],
                                         [-0.5, 1.8, -1.1], [-1.5, 1.4, 0.6])]
    true_rgb = np.array([9.0, 10.0, 11.0])
    images, floors = [], []
    for cam in cams:
        lit = window_mask(cam)
        images.append(np.where(lit[..., None], true_rgb, 0.3).astype(np.float32))
        floors.append(None)
    images[0] = np.where(window_mask(cams[0])[..., None], 1.0, 0.3).astype(np.float32)
    floors[0] = window_mask(cams[0]).astype(np.float32)  # this photo clipped the window
    out, report = redraw_flat_lights(scene, [panel()], [window], cams, white=1.0,
                                     median_depth=2.5, weights=WEIGHTS, tail=tail,
                                     images=images, floors=floors)
    entry = report.panels[0]
    assert entry["level_from"] == "views"
    assert abs(entry["radiance"] / float(true_rgb @ WEIGHTS) - 1.0) < 0.01
    grid = out.base_colours.max(axis=1) > 1.0
    grid[-tail:] = False
    colour = out.base_colours[grid].mean(axis=0)
    np.testing.assert_allclose(colour / colour[1], true_rgb / true_rgb[1], rtol=0.01)
    # without the views' reading it keeps the sums' level, which the blobs overdraw
    _, plain = redraw_flat_lights(scene, [panel()], [window], cams, white=1.0,
                                  median_depth=2.5, weights=WEIGHTS, tail=tail)
    assert plain.panels[0]["level_from"] == "splats"
    assert plain.panels[0]["radiance"] > 1.1 * entry["radiance"]
    # a reading over the sums' level (a rectangle outlined larger than the light) keeps
    # the sums' level, in the views' colour, and says so
    _, brighter = redraw_flat_lights(scene, [panel()], [window], cams, white=1.0,
                                     median_depth=2.5, weights=WEIGHTS, tail=tail,
                                     images=[4.0 * im for im in images], floors=floors)
    assert brighter.panels[0]["level_from"] == "splats"
    assert abs(brighter.panels[0]["radiance"] / plain.panels[0]["radiance"] - 1.0) < 0.01


def test_a_light_one_view_outlined_takes_its_reading_though_the_sums_say_less():
    """One view frames the light: the fit's splats of it spread along that view's rays,
    and what of them falls in the rectangle sums to less than the light; its reading
    inside the rectangle is the light's level, above or below the sums'."""
    from dataclasses import replace

    scene, window, tail = scene_with_window()
    cams = [look_at([-1.0, 1.5, 0.0], CENTRE)]
    true_rgb = np.array([9.0, 10.0, 11.0])
    lit = window_mask(cams[0])
    bright = [4.0 * np.where(lit[..., None], true_rgb, 0.3).astype(np.float32)]
    one = replace(panel(), single_view=True)
    _, plain = redraw_flat_lights(scene, [panel()], [window], cams, white=1.0,
                                  median_depth=2.5, weights=WEIGHTS, tail=tail,
                                  images=bright, floors=[None])
    _, single = redraw_flat_lights(scene, [one], [window], cams, white=1.0,
                                   median_depth=2.5, weights=WEIGHTS, tail=tail,
                                   images=bright, floors=[None])
    assert plain.panels[0]["level_from"] == "splats"
    assert single.panels[0]["level_from"] == "views"
    assert abs(single.panels[0]["radiance"] / float(4.0 * true_rgb @ WEIGHTS) - 1.0) < 0.01


def test_a_rectangle_the_measuring_views_set_every_side_of_takes_their_reading():
    """Where the views that measured the light set all four sides of its rectangle, the
    rectangle is the light's, not a clipped halo: their reading is its level though the
    fit's blobs sum to less (the hall's window, drawn 0.2 stops dim by its splats)."""
    from dataclasses import replace

    scene, window, tail = scene_with_window()
    cams = [look_at(c, CENTRE) for c in ([-1.0, 1.5, 0.0], [-0.8, 1.2, 1.3],
                                         [-0.5, 1.8, -1.1], [-1.5, 1.4, 0.6])]
    true_rgb = np.array([9.0, 10.0, 11.0])
    bright = [4.0 * np.where(window_mask(c)[..., None], true_rgb, 0.3).astype(np.float32)
              for c in cams]
    kwargs = dict(white=1.0, median_depth=2.5, weights=WEIGHTS, tail=tail, images=bright,
                  floors=[None] * len(cams))
    _, sides = redraw_flat_lights(scene, [replace(panel(), measured_sides=4)], [window], cams,
                                  **kwargs)
    _, three = redraw_flat_lights(scene, [replace(panel(), measured_sides=3)], [window], cams,
                                  **kwargs)
    assert sides.panels[0]["level_from"] == "views"
    assert abs(sides.panels[0]["radiance"] / float(4.0 * true_rgb @ WEIGHTS) - 1.0) < 0.01
    assert three.panels[0]["level_from"] == "splats"


def test_a_view_that_saw_the_window_near_its_black_does_not_read_it():
    """A frame exposed far down for a bulb sees the room's window at a few codes over its
    black, where 8-bit steps are tens of per cent (it read the window 0.25 stops over);
    with its dark ceiling known (its photo's code 3), its reading is left out and the
    window's own frame reads it."""
    from gaslight_usd.fit.flat_redraw import DARK_MARGIN, rectangle_reading

    cams = [look_at(c, CENTRE) for c in ([-1.0, 1.5, 0.0], [-0.8, 1.2, 1.3])]
    true_rgb = np.array([9.0, 10.0, 11.0])
    level = float(true_rgb @ WEIGHTS)
    images = [np.where(window_mask(c)[..., None], scale * true_rgb, 0.3).astype(np.float32)
              for c, scale in zip(cams, (1.0, 1.19), strict=True)]
    black = level / (DARK_MARGIN / 2)  # the bulb's frame: the window 3 stops over its black
    ceilings = [None, np.where(window_mask(cams[1]), 0.0, black).astype(np.float32)]
    args = (panel(), cams, images, [None, None], WEIGHTS, 1.0)
    both = rectangle_reading(*args)
    assert both is not None and both[0] == pytest.approx(1.095 * level, rel=1e-3)
    alone = rectangle_reading(*args, ceilings)
    assert alone is not None and alone[0] == pytest.approx(level, rel=1e-3)


def test_floaters_farther_out_join_the_window_where_every_view_sees_them_over_it():
    """Window-bright floaters 1.0-1.1 m in front of the window, past the prism the fit's
    window may stray into: every view that frames them sees the window behind them, so
    they are its light too (a probe beside a shaded room's window saw them as a fog). A
    bright thing as far out to the side, which the views see against the wall, stays."""
    scene, window, tail = scene_with_window()
    rng = np.random.default_rng(11)
    n = 8
    floaters = np.column_stack([2.5 - rng.uniform(1.0, 1.1, n),
                                CENTRE[1] + rng.uniform(-0.1, 0.1, n),
                                CENTRE[2] - 0.15 + rng.uniform(-0.03, 0.03, n)])
    aside = np.array([[1.2, 1.6, 0.9]])
    extra = SplatScene.from_activated(
        np.concatenate([floaters, aside]), np.full((n + 1, 3), 16.0),
        np.full((n + 1, 3), 0.03), np.full(n + 1, 0.2))
    head = scene.subset(np.arange(scene.count - tail))
    back = scene.subset(np.arange(scene.count - tail, scene.count))
    from gaslight_usd.fit.backdrop import concatenate
    from gaslight_usd.fit.flat_redraw import seen_over

    full = concatenate(concatenate(head, extra), back)
    cams = [look_at(c, CENTRE) for c in ([-1.0, 1.5, 0.0], [-0.8, 1.2, 1.3],
                                         [-0.5, 1.8, -1.1], [-1.5, 1.4, 0.6])]
    np.testing.assert_array_equal(seen_over(panel(), np.concatenate([floaters, aside]),
                                            cams, 0.2), [True] * n + [False])
    out, report = redraw_flat_lights(full, [panel()], [window], cams, white=1.0,
                                     median_depth=2.5, weights=WEIGHTS, tail=tail)
    assert len(report.panels) == 1
    kept = {tuple(p) for p in out.positions.round(5).tolist()}
    stored = full.positions.round(5).tolist()
    assert not any(tuple(p) in kept for p in stored[head.count:head.count + n])
    assert tuple(stored[head.count + n]) in kept
    before, after = sums(full, cams), sums(out, cams)
    assert abs(after.sum() / before.sum() - 1.0) < 0.01


def test_a_wall_splat_in_front_of_the_windows_edge_is_set_behind_it():
    """The wall's own splat 4 cm in front of it, centred 8 cm past the window's side but
    wide enough to reach over it, hid a strip of the light from close by; after the
    redraw it lies just behind the window's plane, in place across it, and the window
    shows whole."""
    from gaslight_usd.fit.backdrop import concatenate

    scene, window, tail = scene_with_window()
    edge = CENTRE + [-0.04, 0.0, HALF[0] + 0.08]
    veil = SplatScene.from_activated(edge[None], np.full((1, 3), 0.3), np.full((1, 3), 0.15),
                                     np.full(1, 0.95))
    head = scene.subset(np.arange(scene.count - tail))
    scene = concatenate(concatenate(head, veil), scene.subset(np.arange(scene.count - tail,
                                                                         scene.count)))
    cams = [look_at(c, CENTRE) for c in ([-1.0, 1.5, 0.0], [-0.8, 1.2, 1.3],
                                         [-0.5, 1.8, -1.1], [-1.5, 1.4, 0.6])]
    out, report = redraw_flat_lights(scene, [panel()], [window], cams, white=1.0,
                                     median_depth=2.5, weights=WEIGHTS, tail=tail)
    entry = report.panels[0]
    assert entry["set_behind"] == 1
    moved = np.flatnonzero(np.all(np.isclose(out.positions[:, 1:], edge[1:]), axis=1)
                           & (out.base_colours.max(axis=1) < 1.0))
    assert len(moved) == 1
    assert out.positions[moved[0], 0] > panel().centre[0]  # behind the window's plane
    # seen from 0.5 m in front of the window's side: the light runs to its edge
    near = look_at(CENTRE + [-0.5, 0.0, HALF[0] - 0.15], CENTRE + [0.0, 0.0, HALF[0] - 0.15])
    left = out.subset(np.arange(out.count))
    left.positions[moved[0]] = edge  # where the fit had it
    with torch.no_grad():
        lum = render(out, near).image.numpy()[30:42, 40:56] @ WEIGHTS
        hid = render(left, near).image.numpy()[30:42, 40:56] @ WEIGHTS
    # the last 15 cm of the window before its side
    assert float(lum.min()) > 0.9 * entry["radiance"]
    assert float(hid.min()) < 0.7 * entry["radiance"]


def test_bright_splats_behind_the_window_join_it():
    """A light one view framed smears along that view's rays both ways: window-bright
    splats left 0.3 m behind the wall, round the window's edge, are its light and are
    redrawn with it (a probe at a grazing angle saw them past the wall), and so is a
    bright one 1.5 m behind it that every view framing it sees through the window. A dim
    one round the edge stays, and so does a bright one as deep off to the side, which
    some views see through the wall beside the window."""
    from gaslight_usd.fit.backdrop import concatenate
    from gaslight_usd.fit.flat_redraw import seen_over

    scene, window, tail = scene_with_window()
    rng = np.random.default_rng(4)
    n = 8
    smeared = np.column_stack([2.5 + rng.uniform(0.2, 0.4, n),
                               CENTRE[1] + rng.uniform(-0.3, 0.3, n),
                               CENTRE[2] + HALF[0] + rng.uniform(0.02, 0.12, n)])
    dim = CENTRE + [0.3, 0.2, HALF[0] + 0.05]
    deep = CENTRE + [1.5, 0.0, 0.0]  # past the prism the redraw takes (0.35 x 2.5 m)
    aside = CENTRE + [1.5, 0.0, 1.5]
    extra = SplatScene.from_activated(
        np.concatenate([smeared, dim[None], deep[None], aside[None]]),
        np.concatenate([np.full((n, 3), 16.0), np.full((1, 3), 0.2), np.full((2, 3), 16.0)]),
        np.full((n + 3, 3), 0.03), np.full(n + 3, 0.5))
    head = scene.subset(np.arange(scene.count - tail))
    full = concatenate(concatenate(head, extra),
                       scene.subset(np.arange(scene.count - tail, scene.count)))
    cams = [look_at(c, CENTRE) for c in ([-1.0, 1.5, 0.0], [-0.8, 1.2, 1.3],
                                         [-0.5, 1.8, -1.1], [-1.5, 1.4, 0.6])]
    np.testing.assert_array_equal(seen_over(panel(), np.stack([deep, aside]), cams, 0.2),
                                  [True, False])
    out, report = redraw_flat_lights(full, [panel()], [window], cams, white=1.0,
                                     median_depth=2.5, weights=WEIGHTS, tail=tail)
    assert len(report.panels) == 1
    kept = {tuple(p) for p in out.positions.round(5).tolist()}
    stored = full.positions.round(5).tolist()
    first = head.count
    assert not any(tuple(p) in kept for p in stored[first:first + n])
    assert tuple(stored[first + n]) in kept
    assert tuple(stored[first + n + 1]) not in kept
    assert tuple(stored[first + n + 2]) in kept
    before, after = sums(full, cams), sums(out, cams)
    assert abs(after.sum() / before.sum() - 1.0) < 0.01
