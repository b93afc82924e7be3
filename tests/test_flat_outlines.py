"""The rectangles the views saw lit on the room's planes, and the rig's panels from them.

A room 5 x 3 x 4 m (floor y = 0) with a 1.2 x 1.0 m window in its +x wall; four
cameras look at it from inside. Each view's lit mask is exactly where its rays meet
the window, as a photo that clipped the window shows it.
"""

from __future__ import annotations

import numpy as np
import pytest

from gaslight_usd.cameras import PinholeCamera
from gaslight_usd.flat_outlines import (
    Outline,
    lit_masks,
    outlines_from_metadata,
    plane_outlines,
)
from gaslight_usd.light_shapes import panel_of

WINDOW_CENTRE = np.array([2.5, 1.6, 0.2])
HALF = np.array([0.6, 0.5])  # along z, along y
# unit normal towards the cameras, offset: the +x wall, the floor, the side walls
PLANES = [(np.array([-1.0, 0.0, 0.0]), -2.5), (np.array([0.0, 1.0, 0.0]), 0.0),
          (np.array([0.0, 0.0, 1.0]), -2.0), (np.array([0.0, 0.0, -1.0]), -2.0)]


def look_at(centre, target, width=160, height=120, focal=120.0) -> PinholeCamera:
    centre = np.asarray(centre, float)
    z = np.asarray(target, float) - centre
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, -1.0, 0.0])
    x /= np.linalg.norm(x)
    rot = np.stack([x, np.cross(z, x), z])
    return PinholeCamera(width, height, focal, focal, width / 2, height / 2, R=rot,
                         t=-rot @ centre)


def window_mask(cam: PinholeCamera) -> np.ndarray:
    """Where ``cam``'s pixel rays meet the window."""
    dirs = cam.ray_directions()
    t = (2.5 - cam.center[0]) / np.where(dirs[..., 0] > 1e-6, dirs[..., 0], np.nan)
    hit = cam.center + dirs * t[..., None]
    with np.errstate(invalid="ignore"):
        return ((np.abs(hit[..., 2] - WINDOW_CENTRE[2]) <= HALF[0])
                & (np.abs(hit[..., 1] - WINDOW_CENTRE[1]) <= HALF[1]))


def cameras() -> list[PinholeCamera]:
    return [look_at(c, WINDOW_CENTRE) for c in
            ([-1.0, 1.5, 0.0], [-0.5, 1.2, 1.2], [0.0, 1.8, -1.0], [-1.8, 1.4, -0.4])]


def window_outline(outlines: list[Outline]) -> Outline:
    return max((o for o in outlines if o.normal[0] < -0.9), key=lambda o: o.cells)


def half_along_z_y(outline: Outline) -> np.ndarray:
    """The outline's half-sizes along z and y, whichever of its sides runs along which."""
    return outline.half_size if abs(outline.u[2]) > 0.5 else outline.half_size[::-1]


def test_the_views_lit_rectangle_on_the_wall_is_the_window():
    cams = cameras()
    outlines = plane_outlines(PLANES, cams, [window_mask(c) for c in cams])
    window = window_outline(outlines)
    np.testing.assert_allclose(window.centre, WINDOW_CENTRE, atol=0.04)
    # sides along the room's planes square to the wall (the side walls, the floor)
    assert max(abs(window.u[1]), abs(window.u[2])) > 1.0 - 1e-6
    np.testing.assert_allclose(half_along_z_y(window), HALF, atol=0.05)
    assert not [o for o in outlines if o.normal[0] > -0.9]  # nothing lit elsewhere


def test_an_object_in_front_of_the_window_in_one_view_leaves_it_whole():
    cams = cameras()
    masks = [window_mask(c) for c in cams]
    masks[0] = masks[0].copy()
    rows, cols = np.nonzero(masks[0])
    masks[0][rows.min():(rows.min() + rows.max()) // 2, :] = False  # its top half hidden
    window = window_outline(plane_outlines(PLANES, cams, masks))
    np.testing.assert_allclose(half_along_z_y(window), HALF, atol=0.05)


def test_views_that_clipped_nothing_see_a_light_over_many_times_their_median():
    """True HDR views: the window 10 times the walls, a lit wall patch 3 times; the
    window is outlined, the patch is not. Photos: their clipped pixels."""
    cams = cameras()
    weights = np.array([0.2126, 0.7152, 0.0722])
    images = []
    for cam in cams:
        lum = np.where(window_mask(cam), 10.0, 1.0)
        lum[:, :20] = 3.0  # a lit patch of wall at each view's left edge
        images.append(np.repeat(lum[..., None], 3, axis=2).astype(np.float32))
    masks = lit_masks(images, [None] * len(cams), weights)
    assert all(np.array_equal(m, window_mask(c)) for m, c in zip(masks, cams, strict=True))
    window = window_outline(plane_outlines(PLANES, cams, masks))
    np.testing.assert_allclose(half_along_z_y(window), HALF, atol=0.05)
    floors = [np.where(window_mask(c), 1.0, 0.0) for c in cams]
    clipped = lit_masks(images, floors, weights)
    assert all(np.array_equal(m, f > 0) for m, f in zip(clipped, floors, strict=True))


def test_a_darker_frame_that_clipped_a_lamp_still_sees_the_window_it_measured():
    """Two photos clipped the window; two darker frames exposed for it measured it (one
    JPEG-rung pixel of it clipped) and clipped a lamp's glow elsewhere, a bright ring round
    it. The frames see the window lit and the glow's clipped pixels, not its ring; with
    only their clipped pixels counted they voted the window dark, and it had no outline."""
    cams = cameras()
    weights = np.array([0.2126, 0.7152, 0.0722])
    images, floors = [], []
    for k, cam in enumerate(cams):
        window = window_mask(cam)
        if k < 2:  # a photo: the window clipped at its white
            lum = np.where(window, 1.0, 0.2)
            floors.append(np.where(window, 1.0, 0.0))
        else:  # a darker frame: the window measured at 10, the walls at 0.3
            lum = np.where(window, 10.0, 0.3)
            lum[2:14, 2:14] = 6.0  # the glow's ring, over 8 x the median
            lum[4:12, 4:12] = 12.0  # the glow, clipped
            rows, cols = np.nonzero(window)
            lum[rows[0], cols[0]] = 12.0  # a clipped pixel of the window
            floor = np.where(lum >= 12.0, 12.0, 0.0)
            floors.append(floor)
        images.append(np.repeat(lum[..., None], 3, axis=2).astype(np.float32))
    masks = lit_masks(images, floors, weights)
    for k in (2, 3):
        assert masks[k][window_mask(cams[k])].all()
        assert masks[k][4:12, 4:12].all() and not masks[k][2:4, 2:14].any()
    window = window_outline(plane_outlines(PLANES, cams, masks))
    np.testing.assert_allclose(half_along_z_y(window), HALF, atol=0.05)
    only_clipped = [f > 0 for f in floors]
    assert not [o for o in plane_outlines(PLANES, cams, only_clipped) if o.normal[0] < -0.9]


def test_a_light_the_outline_holds_takes_its_rectangle():
    cams = cameras()
    outlines = plane_outlines(PLANES, cams, [window_mask(c) for c in cams])
    # a fit's window: a clump of splats 0.3 m across and round, not a flat panel
    position, extent, axes = WINDOW_CENTRE + [-0.02, 0.05, 0.1], np.full(3, 0.15), np.eye(3)
    assert panel_of(position, extent, axes, PLANES, 2.5) is None
    panel = panel_of(position, extent, axes, PLANES, 2.5, outlines)
    assert panel is not None
    np.testing.assert_allclose(sorted(panel.half_size), sorted(HALF), atol=0.05)
    np.testing.assert_allclose(np.cross(panel.u, panel.v), -panel.normal, atol=1e-9)
    assert panel.centre[0] < 2.5  # nudged into the room
    # a light elsewhere on the wall keeps its own shape
    assert panel_of(position + [0.0, 0.0, 1.5], extent, axes, PLANES, 2.5, outlines) is None


def test_a_window_light_floating_in_front_of_it_is_the_window_but_a_lamp_there_is_not():
    """The fit left the window's light 0.6 m into the room, in front of the window: the
    outline puts it back on the wall; a light the photos outlined as a compact lamp at
    that place stays a lamp, and so does one twice as far out."""
    cams = cameras()
    outlines = plane_outlines(PLANES, cams, [window_mask(c) for c in cams])
    floating, extent, axes = WINDOW_CENTRE + [-0.6, 0.0, 0.0], np.full(3, 0.15), np.eye(3)
    panel = panel_of(floating, extent, axes, PLANES, 2.5, outlines)
    assert panel is not None and abs(panel.centre[0] - 2.5) < 0.05
    lamp = np.array([[*floating, 0.05]])
    assert panel_of(floating, extent, axes, PLANES, 2.5, outlines, lamp) is None
    assert panel_of(WINDOW_CENTRE + [-1.2, 0.0, 0.0], extent, axes, PLANES, 2.5,
                    outlines) is None


def test_outlines_round_trip_through_metadata():
    cams = cameras()
    outlines = plane_outlines(PLANES, cams, [window_mask(c) for c in cams])
    meta = {"flat_outlines": [o.as_dict() for o in outlines] + [{"centre": [1, 2]}, "x"]}
    back = outlines_from_metadata(meta)
    assert len(back) == len(outlines)
    np.testing.assert_allclose(back[0].centre, outlines[0].centre, atol=1e-4)
    assert outlines_from_metadata({}) == []


def test_a_ragged_lit_region_is_no_lights_rectangle():
    """The window and a lit strip of wall along its bottom and down one side, clipped
    in every view: one L-shaped region that fills under MIN_FILL of its rectangle,
    which no light takes for its own."""
    cams = cameras()
    masks = []
    for cam in cams:
        dirs = cam.ray_directions()
        t = (2.5 - cam.center[0]) / np.where(dirs[..., 0] > 1e-6, dirs[..., 0], np.nan)
        hit = cam.center + dirs * t[..., None]
        with np.errstate(invalid="ignore"):
            strip = ((np.abs(hit[..., 2] - WINDOW_CENTRE[2]) <= HALF[0] + 0.8)
                     & (hit[..., 1] < WINDOW_CENTRE[1] - HALF[1])
                     & (hit[..., 1] > WINDOW_CENTRE[1] - HALF[1] - 0.2))
            side = ((hit[..., 2] > WINDOW_CENTRE[2] + HALF[0])
                    & (hit[..., 2] < WINDOW_CENTRE[2] + HALF[0] + 0.8)
                    & (np.abs(hit[..., 1] - WINDOW_CENTRE[1]) <= HALF[1] + 0.6))
        masks.append(window_mask(cam) | strip | side)
    ragged = window_outline(plane_outlines(PLANES, cams, masks))
    assert not ragged.clean
    position, extent, axes = WINDOW_CENTRE, np.full(3, 0.15), np.eye(3)
    assert panel_of(position, extent, axes, PLANES, 2.5, [ragged]) is None
    clean = window_outline(plane_outlines(PLANES, cams, [window_mask(c) for c in cams]))
    assert clean.clean and clean.fill > 0.95


PANEL_CENTRE = np.array([-1.2, 3.0, -0.6])
PANEL_HALF = 0.2


def panel_mask(cam: PinholeCamera, centre: np.ndarray = PANEL_CENTRE) -> np.ndarray:
    """Where ``cam``'s pixel rays meet a 0.4 m ceiling panel at y = 3."""
    dirs = cam.ray_directions()
    t = (3.0 - cam.center[1]) / np.where(dirs[..., 1] > 1e-6, dirs[..., 1], np.nan)
    hit = cam.center + dirs * t[..., None]
    with np.errstate(invalid="ignore"):
        return ((np.abs(hit[..., 0] - centre[0]) <= PANEL_HALF)
                & (np.abs(hit[..., 2] - centre[2]) <= PANEL_HALF))


@pytest.mark.parametrize("low", [0.05, 0.14])
def test_a_ceiling_panel_is_outlined_where_it_is_though_the_ceiling_plane_is_off(low):
    """The room box's ceiling, fitted to the whole ceiling, ``low`` under the panel (5 cm;
    14 cm where its points were smeared, as ``panels:2``'s from photos): seen from one
    side, each view's outline lands elsewhere on that plane; the plane's depth where the
    views agree puts the panel back."""
    from gaslight_usd import flat_outlines

    cams = [look_at(c, PANEL_CENTRE) for c in
            ([0.5, 1.4, 0.5], [1.0, 1.5, -1.0], [0.2, 1.3, -2.0], [1.5, 1.6, 0.0],
             [0.8, 1.2, -0.2])]
    masks = [panel_mask(c) for c in cams]
    assert all(m.any() for m in masks)
    planes = [(np.array([0.0, -1.0, 0.0]), low - 3.0)] + PLANES[2:]

    def ceiling(outlines):
        return max((o for o in outlines if o.normal[1] < -0.9), key=lambda o: o.cells)

    found = ceiling(plane_outlines(planes, cams, masks))
    np.testing.assert_allclose(found.centre[[0, 2]], PANEL_CENTRE[[0, 2]], atol=0.015)
    assert abs(found.centre[1] - 3.0) < 0.015
    np.testing.assert_allclose(found.half_size, PANEL_HALF, atol=0.02)
    # on the room box's plane as it is, the outline slides off the panel
    was = flat_outlines.DEPTH_SWEEP
    try:
        flat_outlines.DEPTH_SWEEP = 0.0
        off = ceiling(plane_outlines(planes, cams, masks))
    finally:
        flat_outlines.DEPTH_SWEEP = was
    assert np.linalg.norm(off.centre[[0, 2]] - PANEL_CENTRE[[0, 2]]) > 0.03


def test_a_view_that_clipped_nothing_outlines_a_panel_not_the_ceiling_it_lights():
    """A true HDR view: a panel at 300 in a ceiling lit round it at 20 (both far over 8x
    the view's median of 1) and a window at 30 with a blurred edge: each region cut at
    0.35 of its level keeps the panel, and the window without the foot of its edge."""
    image = np.ones((60, 80, 3), np.float32)
    image[5:25, 5:35] = 20.0  # the ceiling round the panel
    image[10:20, 12:28] = 300.0  # the panel
    ramp = np.linspace(9.0, 30.0, 6, dtype=np.float32)  # the window's blurred edge
    image[35:55, 40:70] = 30.0
    image[35:55, 34:40] = ramp[:, None].T[..., None] * np.ones((20, 1, 3), np.float32)
    (mask,) = lit_masks([image], [None], np.array([0.2126, 0.7152, 0.0722]))
    rows, cols = np.nonzero(mask[:30])
    assert (rows.min(), rows.max(), cols.min(), cols.max()) == (10, 19, 12, 27)
    window_cols = np.nonzero(mask[45])[0]
    assert window_cols.max() == 69 and window_cols.min() == 35  # its ramp's 9 is out


def test_a_panel_one_view_frames_is_outlined_from_it_and_held_only_on_its_plane():
    """A ceiling panel only one photo frames (the others look past it): that view's lit
    region on the ceiling is the panel's rectangle, marked as one view's; it holds a
    light the fit drew on the ceiling, not one hanging half a metre under it, where one
    view would have outlined a lamp's shadow on the ceiling all the same."""
    cam = look_at([0.3, 1.5, 0.4], PANEL_CENTRE)
    others = [look_at(c, [2.5, 1.2, 0.5]) for c in ([-1.0, 1.4, 1.0], [0.0, 1.6, -1.5])]
    cams = [cam, *others]
    masks = [panel_mask(c) for c in cams]
    assert masks[0].any() and not masks[1].any() and not masks[2].any()
    planes = [(np.array([0.0, -1.0, 0.0]), -3.0)] + PLANES[2:]
    (found,) = [o for o in plane_outlines(planes, cams, masks) if o.normal[1] < -0.9]
    assert found.single_view and found.clean
    np.testing.assert_allclose(found.centre, PANEL_CENTRE, atol=0.03)
    np.testing.assert_allclose(found.half_size, PANEL_HALF, atol=0.03)
    back = outlines_from_metadata({"flat_outlines": [found.as_dict()]})
    assert back[0].single_view
    extent, axes = np.full(3, 0.1), np.eye(3)
    panel = panel_of(PANEL_CENTRE + [0.03, -0.03, 0.0], extent, axes, planes, 2.5, [found])
    assert panel is not None and panel.single_view and panel.outlined
    np.testing.assert_allclose(panel.half_size, PANEL_HALF, atol=0.03)
    hanging = PANEL_CENTRE + [0.0, -0.5, 0.0]
    assert panel_of(hanging, extent, axes, planes, 2.5, [found]) is None
    # two views framing it make the usual outline, not one view's
    both = [cam, look_at([-0.2, 1.3, 1.0], PANEL_CENTRE)]
    (two,) = [o for o in plane_outlines(planes, both, [panel_mask(c) for c in both])
              if o.normal[1] < -0.9]
    assert not two.single_view


def test_one_views_panel_lies_at_the_depth_two_views_agreed_on_for_the_ceiling():
    """The room box's ceiling 5 cm under the panels: five views sweep it up to the panel
    they share; a second panel one view frames, seen from the side, is outlined at that
    depth too, where it is, not slid along that view's rays."""
    second = np.array([1.6, 3.0, 1.6])
    shared = [look_at(c, PANEL_CENTRE) for c in
              ([0.5, 1.4, 0.5], [1.0, 1.5, -1.0], [0.2, 1.3, -2.0], [1.5, 1.6, 0.0],
               [0.8, 1.2, -0.2])]
    alone = look_at([0.2, 1.4, 0.2], second)
    cams = [*shared, alone]
    assert not any(panel_mask(c, second).any() for c in shared)
    masks = [panel_mask(c) | panel_mask(c, second) for c in cams]
    planes = [(np.array([0.0, -1.0, 0.0]), -2.95)] + PLANES[2:]
    found = [o for o in plane_outlines(planes, cams, masks)
             if o.normal[1] < -0.9 and o.single_view]
    assert len(found) == 1
    np.testing.assert_allclose(found[0].centre, second, atol=0.02)
    np.testing.assert_allclose(found[0].half_size, PANEL_HALF, atol=0.03)


def test_a_panel_seen_from_one_place_lies_at_the_depth_views_from_two_agreed_on():
    """A second panel framed by a photo and its darker frame, shot from one place: their
    outlines of it (the photo's clipped halo, the frame's panel) coincide at no depth and
    every depth alike, so it takes the depth the five views sharing the first panel
    swept the ceiling to, not one the pair's differing outlines pick by chance."""
    from scipy import ndimage

    second = np.array([1.6, 3.0, 1.6])
    shared = [look_at(c, PANEL_CENTRE) for c in
              ([0.5, 1.4, 0.5], [1.0, 1.5, -1.0], [0.2, 1.3, -2.0], [1.5, 1.6, 0.0],
               [0.8, 1.2, -0.2])]
    alone = look_at([0.2, 1.4, 0.2], second)
    cams = [*shared, alone, alone]
    halo = ndimage.binary_dilation(panel_mask(alone, second), iterations=3)
    masks = [panel_mask(c) for c in shared] + [halo, panel_mask(alone, second)]
    planes = [(np.array([0.0, -1.0, 0.0]), -2.9)] + PLANES[2:]
    outlines = [o for o in plane_outlines(planes, cams, masks) if o.normal[1] < -0.9]
    first = [o for o in outlines if o.holds(PANEL_CENTRE, 0.1)]
    found = [o for o in outlines if o.holds(second, 0.1)]
    assert len(first) == 1 and len(found) == 1
    assert abs(first[0].centre[1] - 3.0) < 0.03
    assert found[0].centre[1] == pytest.approx(first[0].centre[1], abs=1e-9)
    np.testing.assert_allclose(found[0].centre[[0, 2]], second[[0, 2]], atol=0.05)


def test_one_views_outline_is_a_light_where_the_fit_drew_its_light_on_the_plane():
    """The fit's light over a one-view outline, on the ceiling (a few centimetres under
    it, as fits leave it), is the outline's; a lamp hanging half a metre under it, or
    nothing bright there at all, is not."""
    from gaslight_usd.light_shapes import drawn_on_outline

    cam = look_at([0.3, 1.5, 0.4], PANEL_CENTRE)
    others = [look_at(c, [2.5, 1.2, 0.5]) for c in ([-1.0, 1.4, 1.0], [0.0, 1.6, -1.5])]
    cams = [cam, *others]
    planes = [(np.array([0.0, -1.0, 0.0]), -3.0)] + PLANES[2:]
    (found,) = [o for o in plane_outlines(planes, cams, [panel_mask(c) for c in cams])
                if o.normal[1] < -0.9]
    rng = np.random.default_rng(0)
    spot = PANEL_CENTRE + rng.uniform(-0.15, 0.15, (40, 3)) * [1.0, 0.1, 1.0]
    wall = np.column_stack([rng.uniform(-2, 2, 60), rng.uniform(0, 3, 60), np.full(60, -2.0)])
    power = np.concatenate([np.full(40, 300.0), np.zeros(60)])
    on = np.concatenate([spot - [0.0, 0.04, 0.0], wall])
    hanging = np.concatenate([spot - [0.0, 0.5, 0.0], wall])
    assert drawn_on_outline(on, power, found, 2.5)
    assert not drawn_on_outline(hanging, power, found, 2.5)
    assert not drawn_on_outline(on, np.zeros(100), found, 2.5)


def test_one_views_light_cut_by_its_frame_or_past_a_wall_is_not_outlined():
    """Half the panel in the only view that frames it: its edge there is the frame's,
    not the light's. A light past the side wall, put on the ceiling's stretch beyond
    the wall, is none of the room's. (Two more views look elsewhere.)"""
    others = [look_at(c, [2.5, 1.2, 0.5]) for c in ([-1.0, 1.4, 1.0], [0.0, 1.6, -1.5])]
    cam = look_at([0.3, 1.5, 0.4], PANEL_CENTRE)
    cols = np.nonzero(panel_mask(cam).any(axis=0))[0]
    cut = look_at([0.3, 1.5, 0.4], PANEL_CENTRE)
    cut.cx -= (cols.min() + cols.max()) / 2  # the panel's middle on the frame's left edge
    assert panel_mask(cut)[:, 0].any()
    planes = [(np.array([0.0, -1.0, 0.0]), -3.0)] + PLANES[2:]

    def on_ceiling(first, walls=planes):
        cams = [first, *others]
        return [o for o in plane_outlines(walls, cams, [panel_mask(c) for c in cams])
                if o.normal[1] < -0.9]

    assert len(on_ceiling(cam)) == 1
    assert not on_ceiling(cut)
    # a side wall at z = -0.4 (its normal towards the cameras): the panel lies past it
    walled = [planes[0], (np.array([0.0, 0.0, 1.0]), -0.4)]
    assert not on_ceiling(cam, walled)


def test_a_camera_finds_points_in_an_image_of_any_size():
    """``PinholeCamera.pixels_of``: the view's frame at half size halves the indices;
    a point behind the camera or off the frame is in no pixel."""
    cam = look_at([0.0, 1.5, 0.0], [0.0, 1.5, 2.0])  # 160 x 120, looking along +z
    points = np.array([[0.0, 1.5, 2.0], [0.0, 1.5, -2.0], [50.0, 1.5, 2.0]])
    x, y, inside = cam.pixels_of(points, (60, 80, 3))
    assert inside.tolist() == [True, False, False]
    assert (x[0], y[0]) == (40, 30) and x[1] == -1 and y[2] == -1


def test_a_planes_grid_lands_on_the_pixels_its_points_do():
    """The outlines' sweep projects a plane's grid as one affine map; it must pick the
    same pixels as projecting each point, behind the camera and off the frame included."""
    rng = np.random.default_rng(3)
    for _ in range(12):
        q = rng.normal(size=4)
        w, x, y, z = q / np.linalg.norm(q)
        r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                      [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                      [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        cam = PinholeCamera(320, 240, 250.0, 250.0, 160.0, 120.0, r, rng.normal(0, 1, 3))
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        u = np.cross(normal, [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(normal, u)
        centre, ahead = -r.T @ cam.t, r.T @ np.array([0.0, 0.0, 1.0])
        base = centre + 2.0 * ahead + rng.normal(0, 0.3, 3)  # the plane crosses the view
        gu, gv = np.linspace(-3, 3, 90), np.linspace(-2, 2, 70)
        uu, vv = np.meshgrid(gu, gv, indexing="ij")
        points = base + uu.reshape(-1, 1) * u + vv.reshape(-1, 1) * v
        each = cam.pixels_of(points, (60, 80))
        grid = cam.pixels_of_grid(base, u, v, gu, gv, (60, 80))
        assert each[2].any() and not each[2].all()  # some framed, some not
        for a, b in zip(each, grid, strict=True):
            np.testing.assert_array_equal(a, b)


def test_a_frame_that_cuts_only_the_margin_round_a_light_still_places_it():
    """The depth sweep reads each view's lit cells round a region; a view whose frame's
    edge cuts the grid's margin but not the light still sees the light whole and counts,
    one whose edge touches the light does not (its centre moved by the cut)."""
    from gaslight_usd.flat_outlines import _uncut

    inside = np.ones((10, 10), bool)
    inside[:, :2] = False  # the frame's edge cuts the two first columns
    lit = np.zeros((10, 10), bool)
    lit[4:7, 5:8] = True
    np.testing.assert_array_equal(_uncut(inside.ravel(), lit.ravel(), 10, 10), lit.ravel())
    lit[4:7, 2:4] = True  # now the light runs to the frame's edge
    assert _uncut(inside.ravel(), lit.ravel(), 10, 10) is None
    np.testing.assert_array_equal(_uncut(np.ones(100, bool), lit.ravel(), 10, 10), lit.ravel())
