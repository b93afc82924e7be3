"""The chain bench's light placement: distances to true emitters, and the share of
light power the export would place away from every true emitter."""

from __future__ import annotations

import numpy as np
import pytest
from test_lights import LAMP, room_scene

from gaslight_usd.bench.suite_chain import (
    emitter_distance,
    light_placement,
    summaries,
    weighing_summary,
)

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
    assert (row["power_source_lamp"], row["claimed_stops_lamp"]) == ("inferred", 1.2)
    assert (row["power_source_window"], row["claimed_stops_window"]) == ("predicted", 3.0)
    empty = weighing_summary([], [LAMP_LIGHT])
    assert (empty["weighing_lamp"], empty["power_source_lamp"]) == ("", "")
    assert np.isnan(empty["claimed_stops_lamp"]) and empty["false_lights_weighed"] == 0


def _row(method, scene, probe, psnr, lamp_err, window_err, lamp_source="inferred",
         lamp_claim=1.0):
    """A chain row as :func:`run` makes it (the columns :func:`summaries` reads)."""
    return {"method": method, "setting": "fast", "scene": scene, "probe": probe,
            "irradiance_psnr": psnr, "power_err_lamp": lamp_err, "power_err_window": window_err,
            "power_err_sun_patch": -3.0, "weighing_lamp": "x", "weighing_window": "x",
            "power_source_lamp": lamp_source, "claimed_stops_lamp": lamp_claim,
            "power_source_window": "predicted", "claimed_stops_window": 3.0}


def test_the_chain_summary_scores_the_goals_and_the_claimed_uncertainty():
    """Two scenes of two probes: the photos' fit within 3 dB of the true HDR fit's at
    three probes of four; lights within half a stop at 4 of 8 pairs (the sunlit patch,
    a lit surface, not counted); the lamp's claimed stop covers two of its four errors."""
    truth = [_row("truth HDR", s, k, 30.0, 0.0, 0.0, "measured", float("nan"))
             for s in ("a", "b") for k in (0, 1)]
    photos = [_row("recursive", "a", 0, 28.0, 0.2, -0.4),
              _row("recursive", "a", 1, 26.5, -1.5, 0.3),
              _row("recursive", "b", 0, 29.0, 0.9, 2.0, lamp_claim=2.0),
              _row("recursive", "b", 1, 31.0, 3.0, 0.1, lamp_claim=2.0)]
    by_method = {s["method"]: s for s in summaries(truth + photos)}
    got = by_method["recursive"]
    assert got["probes"] == 4 and got["irradiance_psnr_median"] == pytest.approx(28.5)
    assert got["within_3db_of_truth"] == pytest.approx(0.75)
    assert got["light_probe_pairs"] == 8
    assert got["lights_within_half_stop"] == pytest.approx(4 / 8)
    assert got["weighed_pairs"] == 4
    assert got["weighed_within_claim"] == pytest.approx(0.5)  # 0.2 <= 1, 0.9 <= 2
    z = np.sqrt(np.mean(np.square([0.2, 1.5, 0.45, 1.5])))
    assert got["weighed_z_rms"] == pytest.approx(z, abs=0.01)
    assert got["predicted_pairs"] == 4 and got["predicted_within_claim"] == pytest.approx(1.0)
    ceiling = by_method["truth HDR"]
    assert np.isnan(ceiling["within_3db_of_truth"]) and ceiling["weighed_pairs"] == 0
    assert ceiling["lights_within_half_stop"] == 1.0


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
