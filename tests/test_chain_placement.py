"""The chain bench's light placement: distances to true emitters, and the share of
light power the export would place away from every true emitter."""

from __future__ import annotations

import numpy as np
import pytest
from test_lights import LAMP, room_scene

from gaslight_usd.bench.suite_chain import emitter_distance, light_placement, weighing_summary

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


def test_emitter_spread_sees_floaters_in_front_of_the_window():
    """A window's splats on its wall spread 0; the same window with bright splats
    floating 0.3 m in front of it (what a fit leaves: the probe near it sees them close
    up) spreads 0.3 m and shows their power as floating."""
    from gaslight_usd.bench.suite_chain import emitter_spread
    from gaslight_usd.splats import SplatScene

    scene, parts = room_scene()
    emitters = np.zeros(scene.count, bool)
    emitters[parts["window"]] = emitters[parts["lamp"]] = True
    row = emitter_spread(scene, emitters, [LAMP_LIGHT, WINDOW_LIGHT])
    assert row["light_spread_window"] == pytest.approx(0.0, abs=0.01)
    assert row["light_spread_lamp"] < 0.1 and row["floating_share"] == 0.0

    window = parts["window"]
    floaters = scene.positions[window] - np.array([0.3, 0.0, 0.0], np.float32)
    both = SplatScene.from_activated(
        np.concatenate([scene.positions[window], floaters]),
        np.concatenate([scene.base_colours[window]] * 2),
        np.concatenate([scene.scales[window]] * 2), np.concatenate([scene.opacities[window]] * 2))
    row = emitter_spread(both, np.ones(both.count, bool), [LAMP_LIGHT, WINDOW_LIGHT])
    assert row["light_spread_window"] == pytest.approx(0.3, abs=0.01)
    assert row["floating_share"] == pytest.approx(0.5, abs=0.01)
    assert np.isnan(row["light_spread_lamp"])


def test_the_weighing_summary_names_each_emitters_clipped_light_and_false_ones():
    """The fit's clipped lights, as its metrics list them: the lamp's (inferred), one by
    the window that kept its fill as a lit surface, and a floater 1 m from both whose
    power was raised."""
    clipped = [
        {"position": (LAMP + [0.0, 0.03, 0.0]).tolist(), "factor": 2.0 ** 6.5,
         "power_source": "inferred", "power_uncertainty_stops": 1.2,
         "lit_surface_albedo": 12.5},
        {"position": [2.45, 1.6, 0.2], "factor": 1.0, "power_source": "predicted",
         "power_uncertainty_stops": 3.0, "lit_surface_albedo": 0.6},
        {"position": [0.5, 0.5, -1.5], "factor": 8.0, "power_source": "inferred",
         "power_uncertainty_stops": 1.0},
    ]
    row = weighing_summary(clipped, [LAMP_LIGHT, WINDOW_LIGHT])
    assert row["weighing_lamp"] == "inferred +6.50 (1.2) lit-surface albedo 12.50"
    assert row["weighing_window"] == "predicted +0.00 (3.0) lit-surface albedo 0.60"
    assert row["false_lights_weighed"] == 1
    assert weighing_summary([], [LAMP_LIGHT]) == {"weighing_lamp": "",
                                                  "false_lights_weighed": 0}


def test_the_rigs_rectangle_is_scored_against_the_true_window():
    """The room's window, drawn by its splats, is a panel in the fit's +x wall; its
    rectangle against the true one, and against one moved off it."""
    scene, _ = room_scene()
    scene.metadata["fit_metrics"]["room_box"] = [{"normal": [-1.0, 0.0, 0.0], "offset": -2.5},
                                                 {"normal": [0.0, 1.0, 0.0], "offset": 0.0}]
    row = light_placement(scene, [LAMP_LIGHT, WINDOW_LIGHT])
    assert "rect_iou_lamp" not in row
    assert row["rect_iou_window"] > 0.5
    far = {**WINDOW_LIGHT, "corners": (np.array(WINDOW_LIGHT["corners"]) + [0, 0, 3.0]).tolist()}
    assert light_placement(scene, [LAMP_LIGHT, far])["rect_iou_window"] == 0.0
