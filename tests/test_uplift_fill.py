"""The uplift's own error per light, view by view (gaslight_usd.bench.uplift_fill)."""

from __future__ import annotations

import numpy as np

from gaslight_usd.bench.uplift_fill import light_footprint, view_fill_errors
from gaslight_usd.cameras import PinholeCamera


def test_a_fill_twice_the_truth_where_the_light_shows_is_one_stop_over():
    truth = np.full((8, 8), 0.5)
    truth[2:4, 2:4] = 40.0  # the light
    truth[5, 5] = 30.0  # its blurred edge: 3/4 of it, still shown
    floor = np.zeros((8, 8))
    floor[1:6, 1:6] = 1.0  # the photo clipped it and a lit patch around it
    fill = truth * 2.0
    fill[1, 1] = 1000.0  # a clipped pixel that does not show the light: not counted
    everywhere = np.ones((8, 8), bool)
    levels = {"lamp": 40.0, "window": 5000.0}
    errors = view_fill_errors(fill, floor, truth, levels, {"lamp": everywhere,
                                                           "window": everywhere})
    assert errors == {"lamp": 1.0}
    off = {"lamp": np.zeros((8, 8), bool), "window": everywhere}
    assert view_fill_errors(fill, floor, truth, levels, off) == {}  # not in its footprint
    assert view_fill_errors(fill, np.zeros((8, 8)), truth, levels,
                            {"lamp": everywhere, "window": everywhere}) == {}


def test_a_lights_footprint_is_where_the_camera_sees_it():
    camera = PinholeCamera(64, 48, 50.0, 50.0, 32.0, 24.0, np.eye(3), np.zeros(3))
    window = {"kind": "rectangle", "corners": [[-0.2, -0.2, 2.0], [0.2, -0.2, 2.0],
                                               [0.2, 0.2, 2.0], [-0.2, 0.2, 2.0]]}
    ys, xs = np.nonzero(light_footprint(window, camera, (48, 64)))
    assert (xs.min(), xs.max(), ys.min(), ys.max()) == (27, 37, 19, 29)
    assert len(xs) == 11 * 11  # filled, not just its edge
    bulb = {"kind": "sphere", "center": [0.4, 0.0, 2.0], "radius": 0.02}
    ys, xs = np.nonzero(light_footprint(bulb, camera, (96, 128)))  # a finer image
    assert abs(xs.mean() - 84.0) <= 1.0 and abs(ys.mean() - 48.0) <= 1.0
    assert not light_footprint({"kind": "disk"}, camera, (48, 64)).any()
    behind = {"kind": "sphere", "center": [0.0, 0.0, -2.0], "radius": 0.5}
    assert not light_footprint(behind, camera, (48, 64)).any()
