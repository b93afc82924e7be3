"""A measured compact light keeps, drawn finer, the power its views measured at fitting size."""

from __future__ import annotations

import numpy as np

from gaslight_usd.fit.data import scale_camera_to
from gaslight_usd.fit.fine_power import (
    TOLERANCE_STOPS,
    FinePower,
    matched_light,
    rows_after,
    with_fine_power,
)
from gaslight_usd.fit.gather import aimed_camera
from gaslight_usd.render import render
from gaslight_usd.resize import area_resize
from gaslight_usd.splats import SplatScene

Y709 = np.array([0.2126, 0.7152, 0.0722], np.float32)
BULB = np.array([0.0, 1.0, 0.0])
SIZE = 48


def _wall_and_bulb(cluster: int, seed: int = 0) -> tuple[SplatScene, np.ndarray]:
    """A dim wall 2 m behind a bulb of ``cluster`` overlapping splats (1 cm, opacity 0.6,
    luminance about 5,000, 8 mm apart: sub-pixel at the fitting size, 6 cm a pixel)."""
    rng = np.random.default_rng(seed)
    g = np.linspace(-1.5, 1.5, 25)
    wu, wv = np.meshgrid(g, g)
    wall = np.column_stack([wu.ravel(), 1.0 + wv.ravel(), np.full(wu.size, 2.0)])
    bulb = BULB + rng.normal(0.0, 0.008, (cluster, 3))
    pos = np.concatenate([wall, bulb])
    rgb = np.concatenate([np.full((len(wall), 3), 0.3), np.full((cluster, 3), 5000.0)])
    scales = np.concatenate([np.full((len(wall), 3), 0.12), np.full((cluster, 3), 0.01)])
    opac = np.concatenate([np.full(len(wall), 0.99), np.full(cluster, 0.6)])
    scene = SplatScene.from_activated(pos, rgb, scales, opac, metadata={"antialiased": True})
    return scene, np.arange(len(wall), len(pos))


def factor_and_views(*args, **kwargs) -> tuple[float, int]:
    """(factor, views) of :func:`matched_light`."""
    return matched_light(*args, **kwargs)[:2]


def _cameras() -> list:
    eyes = [np.array([x, 1.1, -2.5]) for x in (-0.8, -0.3, 0.3, 0.8)]
    return [aimed_camera(e, BULB, 0.5, SIZE) for e in eyes]


def _window_light(scene: SplatScene, cam, fine: int) -> float:
    """The bulb's window's light (luminance summed, in fitting pixels) drawn ``fine``x."""
    image = render(scene, scale_camera_to(cam, cam.width * fine, cam.height * fine)).image
    u, v = (int(c) for c in cam.project(BULB[None])[0][0])
    lum = image.numpy() @ Y709
    return float(lum[(v - 4) * fine:(v + 5) * fine, (u - 4) * fine:(u + 5) * fine].sum()) / fine**2


def test_a_cluster_that_dims_drawn_finer_is_brightened_to_what_its_views_measured():
    """Drawn at the fitting size the cluster matches its views (they are its own
    renders); drawn four times finer its splats hide each other and it shows less.
    Brightened by the factor, the fine drawing holds what the views measured, within 5 %."""
    scene, rows = _wall_and_bulb(8)
    cams = _cameras()
    views = [render(scene, cam).image.numpy() for cam in cams]
    coarse = [_window_light(scene, cam, 1) for cam in cams]
    fine = [_window_light(scene, cam, 4) for cam in cams]
    assert max(f / c for f, c in zip(fine, coarse, strict=True)) < 0.9  # it dims
    factor, used = factor_and_views(scene, rows, BULB, 0.02, cams, views, Y709,
                                     tolerance=0.0)
    assert used == len(cams) and factor > 1.1
    # by default the first TOLERANCE_STOPS of it are not applied
    shrunk, _ = factor_and_views(scene, rows, BULB, 0.02, cams, views, Y709)
    np.testing.assert_allclose(np.log2(shrunk), np.log2(factor) - TOLERANCE_STOPS, atol=1e-6)
    fixed = with_fine_power(scene, [FinePower(BULB, rows, factor, used)])
    after = [_window_light(fixed, cam, 4) for cam in cams]
    np.testing.assert_allclose(np.median(after), np.median(coarse), rtol=0.05)
    # only the light's splats changed
    np.testing.assert_array_equal(fixed.sh[: rows[0]], scene.sh[: rows[0]])


def test_one_splat_keeps_its_power_at_any_size_and_is_left_alone():
    """A lone small splat keeps its power drawn finer (the antialiased dilation's
    opacity compensation): views that measured it as it is (drawn fine, area-averaged
    to the fitting size) give it no factor."""
    scene, rows = _wall_and_bulb(1)
    cams = _cameras()
    views = [area_resize(render(scene, scale_camera_to(cam, SIZE * 4, SIZE * 4)).image.numpy(),
                         SIZE, SIZE) for cam in cams]
    factor, used = factor_and_views(scene, rows, BULB, 0.02, cams, views, Y709)
    assert used == len(cams)
    assert abs(np.log2(factor)) < 0.05


def test_a_light_fewer_than_two_views_frame_whole_keeps_its_power():
    scene, rows = _wall_and_bulb(40)
    cams = [aimed_camera(np.array([0.0, 1.1, -2.5]), BULB + np.array([1.2, 0.0, 0.0]), 0.5,
                         SIZE)]
    views = [render(scene, cam).image.numpy() for cam in cams]
    assert factor_and_views(scene, rows, BULB, 0.02, cams, views, Y709) == (1.0, 0)
    one = _cameras()[:1]  # it dims in this view too, but one window is one sample
    seen = [render(scene, cam).image.numpy() for cam in one]
    assert factor_and_views(scene, rows, BULB, 0.02, one, seen, Y709) == (1.0, 0)


def test_a_floater_in_front_of_a_bulb_no_longer_brightens_it(monkeypatch):
    """A dim floater 1.2 m in front of a lone bulb, across the views' rays to it (the
    views saw no floater): matched through it, the bulb was brightened by what the
    floater hid, and a probe off those rays would see it that much too bright. Drawn
    without what lies in front of it, the fit's bulb is brought back to what its views
    measured; through the floater (nothing cleared) it would be left as it is."""
    from gaslight_usd.fit import fine_power
    from gaslight_usd.fit.backdrop import concatenate

    scene, rows = _wall_and_bulb(1)
    cams = _cameras()
    views = [area_resize(render(scene, scale_camera_to(cam, SIZE * 4, SIZE * 4)).image.numpy(),
                         SIZE, SIZE) for cam in cams]
    floater = SplatScene.from_activated(np.array([[0.0, 1.05, -1.2]]), np.full((1, 3), 0.3),
                                        np.full((1, 3), 0.3), np.array([0.3]),
                                        metadata={"antialiased": True})
    fogged = concatenate(scene, floater)
    monkeypatch.setattr(fine_power, "FRONT_CLEAR_SIZES", 1e6)  # clear nothing
    hidden, used = factor_and_views(fogged, rows, BULB, 0.02, cams, views, Y709,
                                     tolerance=0.0)
    assert used == len(cams) and np.log2(hidden) > 0.15  # the floater hides some of it
    fitted = with_fine_power(fogged, [FinePower(BULB, rows, hidden, used)])
    through, _ = factor_and_views(fitted, rows, BULB, 0.02, cams, views, Y709, tolerance=0.0)
    assert abs(np.log2(through)) < 0.03
    monkeypatch.undo()
    back, used = factor_and_views(fitted, rows, BULB, 0.02, cams, views, Y709, tolerance=0.0)
    assert used == len(cams)
    np.testing.assert_allclose(np.log2(back), -np.log2(hidden), atol=0.05)
    # the wall behind, farther than the light, is never cleared; the floater is, and the
    # fit leaves it out with the factor (kept, it would hide the matched bulb)
    front = fine_power.in_front(fogged, cams[0].center, BULB, 0.02, 0.04)
    assert front[-1] and not front[: rows[0]].any()
    _, _, cleared = fine_power.matched_light(fitted, rows, BULB, 0.02, cams, views, Y709)
    assert cleared.tolist() == [fitted.count - 1]
    # splats the caller keeps (a wall the light is flush with) are matched through
    kept, _, none = fine_power.matched_light(fitted, rows, BULB, 0.02, cams, views, Y709,
                                             tolerance=0.0, keep=np.ones(fitted.count, bool))
    assert len(none) == 0 and abs(np.log2(kept)) < 0.03
    light = FinePower(BULB, rows, back, used, cleared)
    assert light.as_dict()["floaters_cleared"] == 1
    clean = with_fine_power(fitted, [light])
    assert clean.count == fitted.count - 1
    np.testing.assert_allclose(np.median([_window_light(clean, cam, 4) for cam in cams]),
                               np.median([_window_light(scene, cam, 4) for cam in cams]),
                               rtol=0.05)


def test_a_clipped_bulb_a_darker_frame_measured_is_matched_to_that_frame():
    """Three photos clip the bulb (their fitting-size floors mark it), a fourth, darker
    frame measured it. Only that frame measures it (:func:`measuring_views`); a fit that
    drew the bulb 1.4 x over it (the clipped views bound it only from below) is brought
    back to it from that one frame, which the default two-view rule would not count."""
    from gaslight_usd.fit.fine_power import MIN_VIEWS, matched_light, measuring_views

    truth, rows = _wall_and_bulb(1)
    cams = _cameras()
    measured = [area_resize(render(truth, scale_camera_to(cam, SIZE * 4, SIZE * 4)).image
                            .numpy(), SIZE, SIZE) for cam in cams]
    white = 10.0
    images, floors = [], []
    for k, image in enumerate(measured):
        if k == 3:  # the darker frame: nothing clipped
            images.append(image)
            floors.append(None)
            continue
        over = (image @ Y709) > white
        assert over.any()  # the bright photos clip the bulb
        images.append(np.where(over[..., None], white, image))
        floors.append(np.where(over, white, 0.0).astype(np.float32))
    assert measuring_views(BULB, 0.02, cams, images, floors, Y709, white) == [3]
    # a view that clipped nothing round the bulb but reads it under twice the white
    # does not measure it
    assert measuring_views(BULB, 0.02, cams[3:], [images[3] * 1e-4], [None], Y709,
                           white) == []
    fit = with_fine_power(truth, [FinePower(BULB, rows, 1.4, 1)])
    dark = [cams[3]], [images[3]]
    assert matched_light(fit, rows, BULB, 0.02, *dark, Y709)[:2] == (1.0, 0)
    assert MIN_VIEWS > 1
    factor, used, _ = matched_light(fit, rows, BULB, 0.02, *dark, Y709, tolerance=0.0,
                                    min_views=1)
    assert used == 1
    np.testing.assert_allclose(np.log2(factor), -np.log2(1.4), atol=0.05)


def test_a_lights_rows_follow_it_past_the_splats_cleared_in_front_of_it():
    pos = np.column_stack([np.arange(10.0), np.zeros(10), np.zeros(10)])
    scene = SplatScene.from_activated(pos, np.ones((10, 3)), np.full((10, 3), 0.1),
                                      np.full(10, 0.9))
    light = FinePower(np.zeros(3), np.array([5, 6, 7]), 2.0, 1, np.array([1, 2, 8]))
    idle = FinePower(np.zeros(3), np.array([9]), 1.0, 0, np.array([0]))  # no views: kept
    out = with_fine_power(scene, [light, idle])
    rows = rows_after([light, idle], scene.count)
    np.testing.assert_array_equal(rows[0], [3, 4, 5])
    np.testing.assert_array_equal(out.positions[rows[0]], scene.positions[[5, 6, 7]])
    np.testing.assert_array_equal(out.positions[rows[1]], scene.positions[[9]])
