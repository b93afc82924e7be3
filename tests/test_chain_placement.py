"""The chain bench's light placement: distances to true emitters, and the share of
light power the export would place away from every true emitter."""

from __future__ import annotations

import numpy as np
import pytest
from test_lights import LAMP, room_scene

from gaslight_usd.bench.suite_chain import emitter_distance, light_placement

WINDOW_LIGHT = {"name": "window", "kind": "rectangle", "center": [2.5, 1.6, 0.2],
                "corners": [[2.5, 1.05, -0.5], [2.5, 1.05, 0.9], [2.5, 2.15, 0.9],
                            [2.5, 2.15, -0.5]], "normal": [-1.0, 0.0, 0.0]}
LAMP_LIGHT = {"name": "lamp", "kind": "sphere", "center": LAMP.tolist(), "radius": 0.05}


def test_emitter_distance_to_a_sphere_and_a_rectangle():
    pts = np.array([[-0.6, 2.0, 0.7], [2.0, 1.6, 0.2], [2.5, 3.15, 0.2], [2.5, 1.2, 0.0]])
    assert np.allclose(emitter_distance(LAMP_LIGHT, pts[:1]), [0.25])
    # in front of the window's middle, 1 m above its top edge, and on it
    assert np.allclose(emitter_distance(WINDOW_LIGHT, pts[1:]), [0.5, 1.0, 0.0])


def test_placement_finds_the_lamp_and_the_window_and_no_stray_power():
    scene, _ = room_scene()
    row = light_placement(scene, [LAMP_LIGHT, WINDOW_LIGHT])
    assert row["lights_found"] == 2
    assert row["light_dist_lamp"] == pytest.approx(0.0, abs=0.05)
    assert row["light_dist_window"] == pytest.approx(0.0, abs=0.05)
    assert row["stray_light_share"] == 0.0
    # the same scene scored against a lamp 1 m away: it is missed, its power is stray
    moved = {**LAMP_LIGHT, "center": (LAMP + [1.0, 0.0, 0.0]).tolist()}
    row = light_placement(scene, [moved, WINDOW_LIGHT])
    assert row["light_dist_lamp"] > 0.8 and row["stray_light_share"] > 0.0
