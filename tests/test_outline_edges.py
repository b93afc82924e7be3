"""A lit rectangle's sides put where the views that measured it see its light end.

A 0.4 m ceiling panel at 300 in a ceiling at 1 (y = 3), seen by five views whose pixels
average the scene over their area (the panel's edge pixels partly light), as a true HDR
view or a darker frame records it.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from gaslight_usd.flat_outlines import Outline, lit_masks, plane_outlines
from gaslight_usd.outline_edges import luminances, refine_outlines, side_offsets

from .test_flat_outlines import PANEL_CENTRE, PANEL_HALF, PLANES, look_at, panel_mask

WEIGHTS = np.array([0.2126, 0.7152, 0.0722])
SUPER = 4
CEILING = [(np.array([0.0, -1.0, 0.0]), -3.0)] + PLANES[2:]
CENTRES = ([0.5, 1.4, 0.5], [1.0, 1.5, -1.0], [0.2, 1.3, -2.0], [1.5, 1.6, 0.0],
           [0.8, 1.2, -0.2])


def views() -> list:
    return [look_at(c, PANEL_CENTRE) for c in CENTRES]


def image_of(centre, level: float = 300.0) -> np.ndarray:
    """The view from ``centre``: each pixel the mean of SUPER x SUPER rays' radiance."""
    fine = look_at(centre, PANEL_CENTRE, width=160 * SUPER, height=120 * SUPER,
                   focal=120.0 * SUPER)
    cover = panel_mask(fine).astype(np.float64)
    cover = cover.reshape(120, SUPER, 160, SUPER).mean(axis=(1, 3))
    return np.repeat((1.0 + (level - 1.0) * cover)[..., None], 3, axis=2).astype(np.float32)


def panel_outline(outlines: list[Outline]) -> Outline:
    return max((o for o in outlines if o.normal[1] < -0.9), key=lambda o: o.cells)


def too_large() -> Outline:
    """The panel's outline a few centimetres too large and off to one side, as clipped
    photos' halo leaves it."""
    normal = np.array([0.0, -1.0, 0.0])
    return Outline(centre=PANEL_CENTRE + np.array([0.012, 0.0, -0.008]), normal=normal,
                   u=np.array([1.0, 0.0, 0.0]), v=np.array([0.0, 0.0, 1.0]),
                   half_size=np.array([0.235, 0.228]), cells=400)


def test_the_views_outline_of_a_small_panel_runs_past_it_and_its_sides_come_back():
    cams = views()
    images = [image_of(c) for c in CENTRES]
    floors = [None] * len(images)
    masks = lit_masks(images, floors, WEIGHTS)
    found = panel_outline(plane_outlines(CEILING, cams, masks))
    assert found.half_size.min() > PANEL_HALF + 0.004  # a pixel's worth past each side
    (refined,) = refine_outlines([found], cams, images, floors, WEIGHTS)
    np.testing.assert_allclose(refined.half_size, PANEL_HALF, atol=0.003)
    np.testing.assert_allclose(refined.centre[[0, 2]], PANEL_CENTRE[[0, 2]], atol=0.003)
    assert refined.cells == found.cells and refined.single_view == found.single_view
    assert found.measured_sides == 0 and refined.measured_sides == 4
    assert Outline.from_dict(refined.as_dict()).measured_sides == 4


def test_an_outline_too_large_and_off_centre_is_moved_onto_the_panel():
    cams = views()
    images = [image_of(c) for c in CENTRES]
    (refined,) = refine_outlines([too_large()], cams, images, [None] * len(images), WEIGHTS)
    np.testing.assert_allclose(refined.half_size, PANEL_HALF, atol=0.003)
    np.testing.assert_allclose(refined.centre, PANEL_CENTRE, atol=0.003)
    past = side_offsets(too_large(), cams, *luminances(images, [None] * len(images), WEIGHTS))
    # u: the - side 0.023 past (0.235 - 0.012 - 0.2), the + side 0.047 (0.235 + 0.012 - 0.2)
    np.testing.assert_allclose(past, [[0.023, 0.047], [0.036, 0.020]], atol=0.003)


def test_a_lamp_in_front_of_the_edge_in_one_view_is_outvoted():
    cams = views()
    images = [image_of(c) for c in CENTRES]
    h, w = images[0].shape[:2]
    images[0][:, : w // 2] = 2.0  # something dark over half of one view
    (refined,) = refine_outlines([too_large()], cams, images, [None] * len(images), WEIGHTS)
    np.testing.assert_allclose(refined.half_size, PANEL_HALF, atol=0.004)


def test_clipped_views_say_nothing_and_a_darker_frame_says_where_the_panel_ends():
    """Photos that clipped the panel (and its blur, over their white) cannot say where it
    ends: with only them the outline stays; one darker frame among them moves it."""
    cams = views()
    white = 4.0
    photos = [np.minimum(image_of(c), white) for c in CENTRES]
    floors = [np.where(p[..., 1] >= white, white, 0.0).astype(np.float32) for p in photos]
    outline = too_large()
    assert np.isnan(side_offsets(outline, cams, *luminances(photos, floors, WEIGHTS))).all()
    assert refine_outlines([outline], cams, photos, floors, WEIGHTS)[0] is outline
    dark = image_of(CENTRES[0]) / 100.0  # a darker frame from the first photo's place
    (refined,) = refine_outlines([outline], cams + [cams[0]], photos + [dark],
                                 floors + [None], WEIGHTS)
    np.testing.assert_allclose(refined.half_size, PANEL_HALF, atol=0.003)


@pytest.mark.parametrize("level", [1.0, 3.0])
def test_a_view_with_no_light_there_moves_nothing(level):
    """A ceiling with no panel (or one too dim to tell from it) has no edge to find."""
    cams = views()
    images = [image_of(c, level) for c in CENTRES]
    outline = too_large()
    assert refine_outlines([outline], cams, images, [None] * len(images), WEIGHTS)[0] is outline


def halo_photos(sigma: float = 3.0, white: float = 20.0) -> tuple[list, list]:
    """The five views as photos that clipped the panel and its blur: each clipped region
    the panel grown by a halo with round corners."""
    photos, floors = [], []
    for c in CENTRES:
        image = image_of(c)
        image = np.stack([ndimage.gaussian_filter(image[..., k], sigma) for k in range(3)], -1)
        floors.append(np.where(image[..., 1] >= white, white, 0.0).astype(np.float32))
        photos.append(np.minimum(image, white))
    return photos, floors


def test_a_clipped_panels_round_halo_is_its_rectangle_once_a_darker_frame_sets_its_sides():
    """The clipped photos' outline runs past the panel, round at its corners, and fills
    too little of the box bounding it to be a light's rectangle; cut to the sides a
    darker frame sees, its lit cells fill it."""
    cams = views()
    photos, floors = halo_photos()
    found = panel_outline(plane_outlines(CEILING, cams, lit_masks(photos, floors, WEIGHTS)))
    assert found.half_size.min() > PANEL_HALF + 0.05 and not found.clean
    dark = image_of(CENTRES[0]) / 100.0
    (refined,) = refine_outlines([found], cams + [cams[0]], photos + [dark], floors + [None],
                                 WEIGHTS)
    assert refined.measured_sides >= 3 and refined.clean and refined.fill > 0.9
    # the metadata keeps the fill, not the cells
    kept = Outline.from_dict(refined.as_dict())
    assert kept.fill == pytest.approx(refined.fill, abs=1e-4)
    assert kept.fill_within(kept.centre, kept.half_size / 2) == kept.fill


def test_a_panels_light_carried_past_the_ceiling_onto_a_walls_plane_is_not_outlined():
    """A photo and its darker frame, shot from one place, agree on the panel's light at any
    depth along their rays: carried past the ceiling onto the far wall's plane, it made a
    rectangle there, over the room (the chain bench's ``panels:7``)."""
    cam = views()[0]
    photos, floors = halo_photos(sigma=1.0)
    dark = image_of(CENTRES[0]) / 100.0
    far_wall = (np.array([1.0, 0.0, 0.0]), -2.5)  # x = -2.5, beyond the panel
    masks = lit_masks([photos[0], dark], [floors[0], None], WEIGHTS)
    outlines = plane_outlines([CEILING[0], far_wall], [cam, cam], masks)
    assert len(outlines) == 1 and outlines[0].normal[1] < -0.9
