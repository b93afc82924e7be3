"""Lights, not bright surfaces; a probe inside the set; backdrop never a light.

A room of diffuse wall splats (5 x 3 x 4 m, floor y = 0) with a lamp (a small
cluster of radiance 200) 1 m under the ceiling, a window on the +x wall
(radiance 20), the ceiling patch the lamp lights (radiance 1.4, what a wall of
albedo 0.7 reflects under that lamp), bright splats behind the window wall (a
fit's depth smear) and the fit's own unseen-surface backdrop tiles. The old
rule (radiance above 1) makes the lit ceiling, the backdrop and the smear
emitters; the lights finder must not.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from gaslight_usd import lights
from gaslight_usd.bench.suite_chain import TRUTH_HDR_METHOD
from gaslight_usd.capture import capture_space, room_half_spaces
from gaslight_usd.lights import find_lights, power_source, search_lights
from gaslight_usd.probe import clearance, default_probe
from gaslight_usd.splats import SplatScene
from gaslight_usd.usd.instancer import emitter_mask

ROOM_LO, ROOM_HI = np.array([-2.5, 0.0, -2.0]), np.array([2.5, 3.0, 2.0])
LAMP = np.array([-0.6, 2.0, 0.4])
WINDOW = np.array([2.49, 1.6, 0.2])
LIT = np.array([-0.6, 2.99, 0.4])
SPACING = 0.15


def _face_grid(axis: int, level: float, rng) -> np.ndarray:
    u, v = [a for a in range(3) if a != axis]
    gu = np.arange(ROOM_LO[u] + SPACING / 2, ROOM_HI[u], SPACING)
    gv = np.arange(ROOM_LO[v] + SPACING / 2, ROOM_HI[v], SPACING)
    uu, vv = np.meshgrid(gu, gv, indexing="ij")
    pts = np.empty((uu.size, 3))
    pts[:, u], pts[:, v], pts[:, axis] = uu.ravel(), vv.ravel(), level
    return pts + rng.normal(0, 0.005, pts.shape)


def room_scene(method: str = "recursive", with_cameras: bool = True) -> tuple[SplatScene, dict]:
    rng = np.random.default_rng(0)
    walls = np.concatenate([_face_grid(a, lv, rng) for a in range(3)
                            for lv in (ROOM_LO[a], ROOM_HI[a])])
    rgb = np.full((len(walls), 3), 0.3)
    sigma = np.full(len(walls), 0.1)
    window = (np.abs(walls[:, 0] - 2.5) < 0.01) & (np.abs(walls[:, 1] - WINDOW[1]) < 0.55) & \
        (np.abs(walls[:, 2] - WINDOW[2]) < 0.7)
    rgb[window] = [18.0, 19.0, 20.0]
    lit = (np.abs(walls[:, 1] - 3.0) < 0.01) & (np.linalg.norm(walls - LIT, axis=1) < 0.5)
    rgb[lit] = [1.4, 1.2, 1.0]  # albedo 0.7 under the lamp (6.3, as the splats render it)
    lamp = LAMP + rng.normal(0, 0.02, (30, 3))
    smear = np.column_stack([np.full(12, 3.2), rng.uniform(1.1, 2.1, 12),
                             rng.uniform(-0.4, 0.8, 12)])  # behind the window wall
    tiles = np.column_stack([rng.uniform(-2, 2, 15), np.full(15, 3.0), rng.uniform(-1.5, 1.5, 15)])
    pos = np.concatenate([walls, lamp, smear, tiles])
    rgb = np.concatenate([rgb, np.tile([200.0, 160.0, 100.0], (30, 1)),
                          np.full((12, 3), 30.0), np.full((15, 3), 2.5)])
    sigma = np.concatenate([sigma, np.full(30, 0.02), np.full(12, 0.08), np.full(15, 0.2)])
    angles = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    cams = np.column_stack([1.2 * np.cos(angles), 1.5 + 0.1 * np.sin(2 * angles),
                            1.0 * np.sin(angles)])
    meta = {"provenance": {"hdr_method": method},
            "fit_metrics": {"backdrop_splats": 15}}  # the tiles are the fit's last splats
    if with_cameras:
        meta["cameras"] = {"centres": cams.tolist()}
    scene = SplatScene.from_activated(pos, rgb, np.repeat(sigma[:, None], 3, 1),
                                      np.full(len(pos), 0.9), metadata=meta)
    parts = {"window": np.flatnonzero(window), "lit": np.flatnonzero(lit),
             "lamp": np.arange(len(walls), len(walls) + 30),
             "smear": np.arange(len(walls) + 30, len(walls) + 42),
             "tiles": np.arange(len(pos) - 15, len(pos))}
    return scene, parts


def outside_room(points: np.ndarray, tol: float = 0.05) -> np.ndarray:
    return np.any((points < ROOM_LO - tol) | (points > ROOM_HI + tol), axis=1)


def test_the_old_rule_takes_lit_walls_and_backdrop_for_lights():
    scene, parts = room_scene()
    old = emitter_mask(scene)
    assert old[parts["lit"]].all() and old[parts["smear"]].all() and old[parts["tiles"]].all()


@pytest.mark.parametrize("method", ["recursive", "bracket", TRUTH_HDR_METHOD])
def test_lights_are_the_lamp_and_the_window(method):
    scene, parts = room_scene(method)
    found = search_lights(scene)
    emitters = found.emitters
    assert emitters[parts["lamp"]].all() and emitters[parts["window"]].mean() > 0.9
    assert not emitters[parts["lit"]].any()  # a lit ceiling, explained by the lamp
    assert not emitters[parts["smear"]].any() and not emitters[parts["tiles"]].any()
    assert not outside_room(scene.positions[emitters]).any()
    lights = found.lights
    assert len(lights) == 2
    window, lamp = lights  # brightest power first: the window's area is larger
    assert np.linalg.norm(lamp.position - LAMP) < 0.05
    assert np.linalg.norm(window.position - WINDOW) < 0.1
    assert lamp.radius < 0.1 and 0.3 < window.radius < 1.0
    # power: radiance x projected area (2 pi sigma^2 opacity per splat), summed
    area = 2 * np.pi * 0.02**2 * 0.9
    np.testing.assert_allclose(lamp.power, 30 * area * np.array([200.0, 160.0, 100.0]),
                               rtol=1e-4)
    np.testing.assert_allclose(lamp.colour, [1.0, 0.8, 0.5], rtol=1e-4)
    assert lamp.power_source == ("predicted" if method == "recursive" else "measured")
    assert lamp.test["mean_radiance"] > lamp.test["diffuse_limit"]
    summary = found.summary()
    assert summary["lights"][1]["power_source"] == lamp.power_source
    assert "rho" in summary["rule"] or "0.9" in summary["rule"]


def test_power_source_follows_the_hdr_method():
    assert power_source({"provenance": {"hdr_method": "bracket"}}) == "measured"
    assert power_source({"hdr_method": TRUTH_HDR_METHOD}) == "measured"  # the chain bench
    assert power_source({"provenance": {"hdr_method": "recursive"}}) == "predicted"
    assert power_source({}) == "inferred"  # HDR views of unknown making: a lower bound


def with_far_backdrop(scene: SplatScene) -> SplatScene:
    """Plus a far cloud of dim splats 10 m off, as an SfM fit leaves beyond a window."""
    rng = np.random.default_rng(5)
    far = np.array([12.0, 1.5, 0.0]) + rng.normal(0, 1.0, (40, 3))
    return SplatScene.from_activated(
        np.concatenate([scene.positions, far]),
        np.concatenate([scene.base_colours, np.full((40, 3), 0.3)]),
        np.concatenate([scene.scales, np.full((40, 3), 0.3)]),
        np.concatenate([scene.opacities, np.full(40, 0.9)]), metadata=scene.metadata)


def test_default_probe_is_inside_the_room_in_free_space():
    scene = with_far_backdrop(room_scene()[0])
    lo, hi = scene.bounds()
    assert outside_room(((lo + hi) / 2)[None], tol=0.0).any()  # the old default: outside
    choice = default_probe(scene)
    assert not outside_room(choice.position[None], tol=-0.3).any()
    assert choice.position[1] == pytest.approx(1.5, abs=0.3)  # the cameras' height
    assert clearance(scene, choice.position[None])[0] > 0.2
    assert "camera" in choice.how
    # without camera centres: the splats' median, still inside
    bare = with_far_backdrop(room_scene(with_cameras=False)[0])
    assert not outside_room(default_probe(bare).position[None], tol=-0.3).any()


def test_a_probe_in_a_crowd_moves_to_free_space():
    scene, _ = room_scene()
    rng = np.random.default_rng(3)
    crowd = np.array([0.0, 1.5, 0.0]) + rng.normal(0, 0.05, (40, 3))  # a plant at the start
    cams = np.array(scene.metadata["cameras"]["centres"])
    cams[:] = [0.0, 1.5, 0.0]
    both = SplatScene.from_activated(
        np.concatenate([scene.positions, crowd]),
        np.concatenate([scene.base_colours, np.full((40, 3), 0.2)]),
        np.concatenate([scene.scales, np.full((40, 3), 0.03)]),
        np.concatenate([scene.opacities, np.full(40, 0.9)]),
        metadata={**scene.metadata, "cameras": {"centres": cams.tolist()}})
    choice = default_probe(both)
    assert choice.moved > 0.1 and "moved" in choice.how
    assert clearance(both, choice.position[None])[0] >= 0.1 * capture_space(both).median_depth()
    assert not outside_room(choice.position[None], tol=-0.1).any()


def test_no_candidates_no_lights():
    scene, _ = room_scene()
    dim = SplatScene.from_activated(scene.positions, np.minimum(scene.base_colours, 0.5),
                                    scene.scales, scene.opacities, metadata=scene.metadata)
    assert find_lights(dim) == []


def _recoloured(scene: SplatScene, rgb: np.ndarray) -> SplatScene:
    return SplatScene.from_activated(scene.positions, rgb, scene.scales, scene.opacities,
                                     metadata=scene.metadata)


def test_a_wall_lit_by_a_clipped_lamp_left_short_is_not_a_light():
    """The uplift's fill of a clipped lamp falls short (the chain bench's recursive rows):
    here 5 stops, while the ceiling it lights keeps the radiance the true lamp gives it.
    The lamp's fitted power is a lower bound, so the ceiling is still explained by it;
    the lamp and the window (dimmer than the lamp, nothing brighter near it) stay."""
    scene, parts = room_scene()
    rgb = scene.base_colours.copy()
    rgb[parts["lamp"]] /= 2.0**5  # 6.25: 2.6 stops above white, 5 short of the truth
    rgb[parts["window"]] *= 0.2  # 3.6-4
    found = search_lights(_recoloured(scene, rgb))
    assert not found.emitters[parts["lit"]].any()
    assert found.emitters[parts["lamp"]].all() and found.emitters[parts["window"]].all()
    assert len(found.lights) == 2
    assert found.summary()["clipped_headroom_stops"] == lights.CLIPPED_HEADROOM_STOPS


def test_clipped_sources_count_up_to_the_brightest_plausible_light():
    """A source the fit left near white may be up to the headroom brighter; one it put far
    above white only by its stated uncertainty; measured (bracketed) ones by theirs."""
    white = 2.0
    rad = np.array([2.5, 40.0, 400.0, 1e4])
    gain = lights.clipped_gain(rad, white, "predicted")
    aim = white * 2.0**lights.BRIGHTEST_LIGHT_STOPS / rad
    np.testing.assert_allclose(gain, np.clip(aim, 2.0**3, 2.0**lights.CLIPPED_HEADROOM_STOPS))
    assert gain[0] == 2.0**lights.CLIPPED_HEADROOM_STOPS and gain[-1] == 2.0**3
    assert 2.0**3 < gain[1] < 2.0**lights.CLIPPED_HEADROOM_STOPS
    np.testing.assert_allclose(lights.clipped_gain(rad, white, "measured"), 2.0**0.25)


PANEL = np.array([1.0, 3.0, -0.9])


def panel_scene() -> tuple[SplatScene, np.ndarray, np.ndarray]:
    """The room with a ceiling panel (radiance 60) as a fit from photos leaves it: the
    featureless ceiling round it fitted 0.6-1.2 m too high, and two of the panel's splats
    sunk 0.45 and 0.9 m behind it along the ray from the cameras' median point (as
    ``gaslight2usd run`` left ``panels``' panel_0, docs/measurements.md). Returns the
    scene, the panel's splats and the sunk splats."""
    scene, _ = room_scene()
    pos, rgb = scene.positions.astype(np.float64), scene.base_colours.copy()
    rng = np.random.default_rng(1)
    ceiling = np.abs(pos[:, 1] - 3.0) < 0.02
    panel = ceiling & np.all(np.abs(pos[:, [0, 2]] - PANEL[[0, 2]]) < 0.2, axis=1)
    rgb[panel] = [60.0, 56.0, 50.0]
    round_it = ceiling & ~panel & (np.hypot(*(pos[:, [0, 2]] - PANEL[[0, 2]]).T) < 0.9)
    pos[round_it, 1] += rng.uniform(0.6, 1.2, round_it.sum())
    viewpoint = np.median(np.array(scene.metadata["cameras"]["centres"]), axis=0)
    ray = (PANEL - viewpoint) / np.linalg.norm(PANEL - viewpoint)
    sunk = PANEL + ray[None] * np.array([[0.45], [0.9]])
    n = scene.count - 15  # the fit's backdrop tiles stay last
    out = SplatScene.from_activated(
        np.concatenate([pos[:n], sunk, pos[n:]]),
        np.concatenate([rgb[:n], np.tile([60.0, 56.0, 50.0], (2, 1)), rgb[n:]]),
        np.concatenate([scene.scales[:n], np.full((2, 3), 0.1), scene.scales[n:]]),
        np.concatenate([scene.opacities[:n], np.full(2, 0.9), scene.opacities[n:]]),
        metadata=scene.metadata)
    return out, np.flatnonzero(panel[:n]), np.array([n, n + 1])


def test_a_light_smeared_behind_the_ceiling_is_one_light_at_the_ceiling():
    scene, panel, sunk = panel_scene()
    found = search_lights(scene)
    assert found.emitters[sunk].all() and found.emitters[panel].mean() > 0.8
    assert len(found.lights) == 3  # the window, the lamp, the panel: not its smear
    light = min(found.lights, key=lambda li: np.linalg.norm(li.position - PANEL))
    assert set(sunk) <= set(light.splats)
    assert np.linalg.norm(light.position - PANEL) < 0.1
    assert light.position[1] < 3.0 + 0.02
    assert all(li.position[1] < 3.05 for li in found.lights)
    # the light is placed at its nearest strong part, but its sunk splats are not moved
    # there for the instancer: which part is right the photos do not say
    np.testing.assert_allclose(found.positions[sunk], scene.positions[sunk], atol=1e-6)


def test_an_emitter_behind_the_surface_it_is_seen_through_is_moved_onto_it():
    """From the origin: a wall of surface splats 2 m off along +z; a cluster 0.5 m behind
    it goes onto it, one in front and one where no surface lies stay."""
    rng = np.random.default_rng(0)
    wall = np.column_stack([rng.uniform(-1, 1, 400), rng.uniform(-1, 1, 400),
                            2.0 + rng.normal(0, 0.05, 400)])
    behind = np.array([[0.1, 0.0, 2.5], [0.12, 0.02, 2.52]])
    front = np.array([[-0.3, 0.2, 1.5]])
    aside = np.array([[3.0, 0.0, -2.0]])
    pos = np.concatenate([wall, behind, front, aside])
    clusters = [np.array([400, 401]), np.array([402]), np.array([403])]
    surface = np.zeros(len(pos), bool)
    surface[:400] = True
    moved, sunk = lights.onto_surfaces(pos, clusters, np.zeros(3), surface)
    assert sunk.tolist() == [True, False, False]
    depth = np.linalg.norm(moved[400:402], axis=1)
    np.testing.assert_allclose(depth, 2.0, atol=0.05)
    np.testing.assert_allclose(moved[400:402] / depth[:, None],
                               pos[400:402] / np.linalg.norm(pos[400:402], axis=1)[:, None])
    np.testing.assert_array_equal(moved[402:], pos[402:])
    np.testing.assert_array_equal(moved[:400], pos[:400])


def test_each_splat_a_little_behind_its_surface_is_moved_onto_it():
    """From the origin: a wall 2 m off along +z; splats 0.1 m behind it go onto it, one
    in front and one 1 m behind (seen through a gap, in another room) stay."""
    rng = np.random.default_rng(0)
    wall = np.column_stack([rng.uniform(-1, 1, 400), rng.uniform(-1, 1, 400),
                            2.0 + rng.normal(0, 0.01, 400)])
    lights_at = np.array([[0.1, 0.0, 2.1], [0.3, 0.1, 2.12], [-0.3, 0.2, 1.5], [0.0, 0.3, 3.0]])
    pos = np.concatenate([wall, lights_at])
    surface = np.zeros(len(pos), bool)
    surface[:400] = True
    idx = np.arange(400, 404)
    moved_to, moved = lights.onto_surfaces_each(pos, idx, np.zeros(3), surface)
    assert moved.tolist() == [True, True, False, False]
    np.testing.assert_allclose(moved_to[:2, 2], 2.0, atol=0.02)  # on the wall's plane
    np.testing.assert_allclose(moved_to[:2] / np.linalg.norm(moved_to[:2], axis=1)[:, None],
                               pos[400:402] / np.linalg.norm(pos[400:402], axis=1)[:, None])
    np.testing.assert_array_equal(moved_to[2:], pos[402:])


def test_a_windows_splats_sunk_behind_its_wall_are_written_on_it():
    """A fit that left a fifth of the window's splats 10 cm behind the wall (x = 2.5):
    the lights finder still finds the window, and writes none of them outside the room."""
    scene, parts = room_scene()
    pos = scene.positions.copy()
    sunk = parts["window"][::5]
    pos[sunk, 0] += 0.1
    scene = SplatScene.from_activated(pos, scene.base_colours, scene.scales,
                                      scene.opacities, metadata=scene.metadata)
    found = search_lights(scene)
    assert found.emitters[sunk].all()
    assert outside_room(scene.positions[sunk]).all()
    assert not outside_room(found.positions[found.emitters]).any()
    assert found.counts["sunk_splats_moved"] >= len(sunk)


def test_a_lights_bright_copy_is_no_surface_to_see_it_through():
    """A lit ceiling a little above white is a surface; a window-coloured sheet a fit left
    in front of its window (several times white) is the light's own smear, not a wall."""
    radiance = np.array([0.4, 1.5, 1.9, 6.0, 0.4, 0.4])
    opacity = np.array([0.9, 0.9, 0.9, 0.9, 0.05, 0.9])
    backdrop = np.array([False, False, False, False, False, True])
    np.testing.assert_array_equal(lights.surface_splats(radiance, opacity, backdrop, 1.0),
                                  [True, True, True, False, False, False])


def test_a_light_smeared_along_the_rays_sits_at_its_nearest_strong_part():
    """Along one ray from the origin: a lone weak floater at 2 m, the light at 3 m, a part
    of it sunk to 3.6 m. One light; the sunk part is seen at 3 m, the light is not pulled
    forward onto the floater."""
    ray = np.array([0.3, 0.1, 1.0]) / np.linalg.norm([0.3, 0.1, 1.0])
    pos = np.concatenate([ray * 2.0 + np.zeros((1, 3)), ray * 3.0 + np.array(
        [[0.02, 0, 0], [-0.02, 0, 0], [0, 0.02, 0]]), ray * 3.6 + np.zeros((1, 3))])
    clusters = [np.array([0]), np.array([1, 2, 3]), np.array([4])]
    sigma = np.full(len(pos), 0.03)
    power = np.array([0.05, 1.0, 0.4])
    labels, seen_at = lights.group_clusters(pos, clusters, sigma, power, np.zeros(3), 0.05)
    assert len(set(labels.tolist())) == 1
    np.testing.assert_allclose(seen_at, [2.0, 3.0, 3.0], atol=0.01)


def test_an_outlined_bulb_is_not_grouped_with_the_lit_patch_under_it():
    """A bare bulb at its fill (two clusters and a one-splat fragment 0.12 m off) 0.75 m
    over the broad floor patch it lights, the patch behind it as the cameras' middle sees
    it. The gap and the smear join them into one light; with the photos' outline of the
    bulb the bulb is one light of its own, its fragment with it, and the patch another."""
    rng = np.random.default_rng(3)
    bulb = np.array([1.2, 0.95, 1.1])
    viewpoint = np.array([0.0, 1.5, 0.0])
    patch = np.column_stack([rng.uniform(0.85, 1.75, 40), np.zeros(40),
                             rng.uniform(0.9, 1.7, 40)])
    pos = np.concatenate([bulb + rng.normal(0, 0.015, (8, 3)),
                          bulb + [0.03, -0.02, 0.0] + rng.normal(0, 0.01, (3, 3)),
                          (bulb + [0.0, -0.12, 0.0])[None], patch])
    clusters = [np.arange(8), np.arange(8, 11), np.array([11]), np.arange(12, 52)]
    sigma = np.concatenate([np.full(12, 0.01), np.full(40, 0.08)])
    power = np.array([0.02, 0.01, 0.001, 0.5])
    gap = 0.2
    labels, _ = lights.group_clusters(pos, clusters, sigma, power, viewpoint, gap)
    assert len(set(labels.tolist())) == 1
    outline = np.array([[*bulb, 0.05]])
    labels, _ = lights.group_clusters(pos, clusters, sigma, power, viewpoint, gap, outline)
    assert labels[0] == labels[1] == labels[2] != labels[3]
    # the patch's own fragments still join it across the gap
    pos2 = np.concatenate([pos, [[1.95, 0.0, 1.3]]])
    clusters2 = [*clusters, np.array([52])]
    labels, _ = lights.group_clusters(pos2, clusters2, np.append(sigma, 0.08),
                                      np.append(power, 0.01), viewpoint, gap, outline)
    assert labels[4] == labels[3] != labels[0]


def test_a_probe_within_a_lights_reach_is_warned_about(tmp_path, capsys):
    """0.4 m in front of the window (under one of its radii) the HDRI is not to be trusted:
    a fit leaves a flat light's splats floating there (issue 16); the room's middle and a
    point 0.4 m from the small lamp (many of its radii) are fine."""
    from gaslight_usd.cli.main import main
    from gaslight_usd.ply import write_ply
    from gaslight_usd.probe_check import NEAR_LIGHT_RADII, near_light_warning

    scene, _ = room_scene()
    lights = find_lights(scene)
    window = WINDOW - np.array([0.4, 0.0, 0.0])
    text = near_light_warning(window, lights)
    assert text is not None and text.startswith("probe point 2.09,1.6,0.2 lies 0.")
    assert "radii from a light (centre 2.5, 1.56, 0.183, radius 0.582)" in text
    assert near_light_warning([0.0, 1.5, 0.0], lights) is None
    assert near_light_warning(LAMP + [0.4, 0.0, 0.0], lights) is None
    lamp = min(lights, key=lambda light: light.radius)
    edge = lamp.position + [0.99 * NEAR_LIGHT_RADII * lamp.radius, 0.0, 0.0]
    assert near_light_warning(edge, lights) is not None
    ply = write_ply(tmp_path / "room.ply", scene)
    assert main(["hdri", str(ply), "--at", "2.09,1.6,0.2", "-o", str(tmp_path / "w.exr"),
                 "--size", "16", "--json"]) == 0
    captured = capsys.readouterr()
    assert "warning: probe point 2.09,1.6,0.2 lies 0." in captured.err
    assert json.loads(captured.out)["warnings"] == [text]
    assert main(["hdri", str(ply), "--at", "0,1.5,0", "-o", str(tmp_path / "m.exr"),
                 "--size", "16"]) == 0
    assert "warning" not in capsys.readouterr().err


def test_the_opacity_splats_lay_on_a_point_follows_their_shape():
    """One splat: its opacity at its centre, times exp(-1/2) one sigma out along its long
    axis (turned by its rotation), nothing past three sigmas; two multiply as layers."""
    from gaslight_usd.probe_check import inside_alpha

    turn = [np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)]  # 90 degrees about z: x -> y
    one = SplatScene.from_activated(np.zeros((1, 3)), np.ones((1, 3)),
                                    np.array([[0.3, 0.02, 0.02]]), np.array([0.6]),
                                    rotations=np.array([turn]))
    assert inside_alpha([0.0, 0.0, 0.0], one) == pytest.approx(0.6)
    assert inside_alpha([0.0, 0.3, 0.0], one) == pytest.approx(0.6 * np.exp(-0.5))
    assert inside_alpha([0.3, 0.0, 0.0], one) == 0.0  # 15 of its sigmas across
    assert inside_alpha([0.0, 0.95, 0.0], one) == 0.0
    two = SplatScene.from_activated(np.zeros((2, 3)), np.ones((2, 3)),
                                    np.full((2, 3), 0.1), np.array([0.6, 0.5]))
    assert inside_alpha([0.0, 0.0, 0.0], two) == pytest.approx(1.0 - 0.4 * 0.5)


def test_a_probe_among_splats_floating_in_the_room_is_warned_about(tmp_path, capsys):
    """Window-bright splats left floating 0.5 m in front of the window (as a fit from the
    shaded-lamp room's true HDR views leaves them, issue 16): a probe among them is warned
    about, by the stage as well; the room's middle, among no splats, is not."""
    from gaslight_usd.cli.main import main
    from gaslight_usd.ply import write_ply
    from gaslight_usd.probe_check import INSIDE_ALPHA, inside_alpha, inside_warning

    scene, _ = room_scene()
    among = WINDOW - np.array([0.5, 0.0, 0.0])
    fog = among + np.array([[0.03, -0.04, 0.05], [-0.06, 0.02, -0.01], [0.0, 0.06, 0.03]])
    floating = SplatScene.from_activated(fog, np.full((3, 3), 12.0), np.full((3, 3), 0.07),
                                         np.full(3, 0.4))
    joined = SplatScene.from_activated(
        np.concatenate([scene.positions, floating.positions]),
        np.concatenate([scene.base_colours, floating.base_colours]),
        np.concatenate([scene.scales, floating.scales]),
        np.concatenate([scene.opacities, floating.opacities]),
        metadata=scene.metadata)
    assert inside_alpha(among, joined) > 0.5
    assert inside_alpha(among, scene) < INSIDE_ALPHA
    text = inside_warning(among, joined)
    assert text is not None and text.startswith("probe point 1.99,1.6,0.2 lies inside the "
                                                 "fit's splats (they lay opacity 0.")
    assert inside_warning(among, scene) is None
    assert inside_warning([0.0, 1.5, 0.0], joined) is None
    ply = write_ply(tmp_path / "fog.ply", joined)
    assert main(["hdri", str(ply), "--at", "1.99,1.6,0.2", "-o", str(tmp_path / "f.exr"),
                 "--size", "16", "--json"]) == 0
    captured = capsys.readouterr()
    assert "warning: probe point 1.99,1.6,0.2 lies inside the fit's splats" in captured.err
    assert text in json.loads(captured.out)["warnings"]


def test_a_probe_that_sees_a_light_from_where_no_photo_did_is_warned_about(tmp_path, capsys):
    """Half the ring of cameras saw the lamp (light regions holding it); a probe on their
    side is fine, one beyond the lamp from all of them is warned about, with the angle
    the stage's metadata records; a light no photo's region holds gives no angle."""
    from gaslight_usd.cli.main import main
    from gaslight_usd.ply import write_ply
    from gaslight_usd.probe_check import UNSEEN_LIGHT_DEG, unseen_angles, unseen_light_warning
    from gaslight_usd.sightings import Sightings

    scene, _ = room_scene()
    cams = np.asarray(scene.metadata["cameras"]["centres"])
    saw = np.arange(6)  # the cameras at angles 0..150 degrees round the ring
    axes = LAMP[None] - cams[saw]
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    sightings = Sightings(cams, saw, axes, np.full(6, np.radians(3.0)), np.ones(6, bool),
                          np.ones(6), 1.0)
    scene.metadata = {**scene.metadata, "light_sightings": sightings.as_dict()}
    lights = find_lights(scene)

    def angle_by_hand(point, light):  # the smallest angle over the cameras that saw it
        u = (point - light) / np.linalg.norm(point - light)
        return min(np.degrees(np.arccos(np.clip(
            (c - light) @ u / np.linalg.norm(c - light), -1, 1))) for c in cams[saw])

    towards = LAMP + 0.5 * (cams[2] - LAMP) / np.linalg.norm(cams[2] - LAMP)
    side = cams[saw].mean(0) - LAMP
    side[1] = 0.0
    away = LAMP - side / np.linalg.norm(side) + [0.0, -0.3, 0.0]  # 1 m beyond, a little lower
    got = unseen_angles(away, np.array([LAMP, WINDOW]), sightings)
    assert got.shape == (2,) and np.isnan(got[1])  # no photo's region holds the window
    for point in (towards, away):
        np.testing.assert_allclose(unseen_angles(point, LAMP[None], sightings)[0],
                                   angle_by_hand(point, LAMP), atol=1e-6)
    assert unseen_angles(towards, LAMP[None], sightings)[0] < 1.0
    far = unseen_angles(away, LAMP[None], sightings)[0]
    assert far > UNSEEN_LIGHT_DEG
    assert unseen_light_warning(towards, lights, sightings) is None
    text = unseen_light_warning(away, lights, sightings)
    assert text is not None and f"from {far:.0f} degrees off every photo that saw it" in text
    assert unseen_light_warning(away, lights, None) is None  # nothing known of the photos

    ply = write_ply(tmp_path / "room.ply", scene)
    at = ",".join(f"{v:.4f}" for v in away)
    assert main(["hdri", str(ply), "--at", at, "-o", str(tmp_path / "w.exr"), "--size", "16",
                 "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert any("off every photo that saw it" in w for w in report["warnings"])
    lamp_index = int(np.argmin([np.linalg.norm(lt.position - LAMP) for lt in lights]))
    unseen = report["probes"][0]["lights_unseen_deg"]
    assert len(unseen) == len(lights)
    assert abs(unseen[lamp_index] - angle_by_hand(np.asarray(away.round(4)),
                                                  lights[lamp_index].position)) < 0.1


def test_a_light_the_fit_weighed_says_its_power_was_inferred():
    """The fit's ``clipped_lights`` (gaslight_usd.fit.power) name where each clipped light's
    power came from; the export's lights take it from there, not from the HDR method."""
    scene, _ = room_scene()
    assert {light.power_source for light in search_lights(scene).lights} == {"predicted"}
    scene.metadata = {**scene.metadata, "fit_metrics": {"clipped_lights": [
        {"position": (LAMP + 0.01).tolist(), "radius": 0.04, "factor": 96.0,
         "power_source": "inferred", "power_uncertainty_stops": 0.7},
        {"position": WINDOW.tolist(), "radius": 0.4, "factor": 1.0,
         "power_source": "predicted", "power_uncertainty_stops": 3.0}]}}
    window, lamp = search_lights(scene).lights
    assert (lamp.power_source, lamp.power_uncertainty_stops) == ("inferred", 0.7)
    assert lamp.test["inferred_factor"] == 96.0
    assert window.power_source == "predicted"


@pytest.mark.parametrize("source, stops", [("inferred", 0.9), ("measured", 0.25)])
def test_a_lamp_the_fit_weighed_does_not_explain_the_window_away(source, stops):
    """A bare bulb the fit weighed 10 stops over its fill (radiance 2000 here), or one a
    darker frame measured over the white (the README's capture), is known to the
    weighing's or the measurement's uncertainty, not a lower bound: counted at the
    clipped headroom (8x and more) it would light the window's wall as brightly as the
    window shines, and the rig would have no window."""
    scene, parts = room_scene()
    rgb = scene.base_colours.copy()
    rgb[parts["lamp"]] *= 10.0
    scene = _recoloured(scene, rgb)
    assert not search_lights(scene).emitters[parts["window"]].any()  # its fill: a lower bound
    weighed = {"position": LAMP.tolist(), "radius": 0.06, "factor": 1024.0,
               "power_source": source, "power_uncertainty_stops": stops}
    scene.metadata = {**scene.metadata, "fit_metrics": {
        **scene.metadata["fit_metrics"], "clipped_lights": [weighed]}}
    gain = lights.weighed_gain(scene.positions, scene.metadata)
    # its splats lie within WEIGHED_REACH of its radius (an RMS spread) of its centre
    near = np.linalg.norm(scene.positions - LAMP, axis=1) <= lights.WEIGHED_REACH * 0.06
    np.testing.assert_allclose(gain[near], 2.0**stops)
    assert np.isnan(gain[~near]).all()
    found = search_lights(scene)
    assert found.emitters[parts["window"]].all() and found.emitters[parts["lamp"]].mean() > 0.9
    assert not found.emitters[parts["lit"]].any()  # the ceiling it lights is still lit
    window, lamp = sorted(found.lights, key=lambda li: li.radius, reverse=True)
    assert np.linalg.norm(window.position - WINDOW) < 0.1
    assert (lamp.power_source, lamp.power_uncertainty_stops) == (source, stops)
    assert ("inferred_factor" in lamp.test) == (source == "inferred")


@pytest.mark.parametrize("views, framed", [([0, 1], 2), ([0], 1)])
def test_a_clipped_bulb_the_photos_outlined_is_a_light_however_faint_its_fill(views, framed):
    """A bare bulb's splats hold the uplift's fill, a lower bound that can be under a
    thousandth of a window's power: kept where the photos outlined a light there, by
    two photos' outlines or by the one photo that frames it (a sunk light the fit moved
    back along that photo's rays, :mod:`gaslight_usd.fit.sunk_lights`)."""
    scene, parts = room_scene()
    lamp = parts["lamp"]
    scene.log_scales[lamp] = np.log(0.005)
    scene.sh[lamp] = scene.sh[lamp] * (15.0 / 200.0)  # the fill, about 15x the white
    found = search_lights(scene)
    assert not found.emitters[lamp].any()  # too faint beside the window to be a light
    scene.metadata["light_seeds"] = [{"position": LAMP.tolist(), "size": 0.05,
                                      "views": views, "framed": framed}]
    found = search_lights(scene)
    assert found.emitters[lamp].all()
    lamp_light = min(found.lights, key=lambda li: np.linalg.norm(li.position - LAMP))
    assert np.linalg.norm(lamp_light.position - LAMP) < 0.05
    assert float(lamp_light.power.max()) < 1e-3 * max(float(li.power.max())
                                                      for li in found.lights)


ROOM_BOX = [{"normal": n, "offset": o} for n, o in (
    ([0.0, 1.0, 0.0], 0.0), ([0.0, -1.0, 0.0], -3.0), ([-1.0, 0.0, 0.0], -2.5),
    ([1.0, 0.0, 0.0], -2.5), ([0.0, 0.0, -1.0], -2.0), ([0.0, 0.0, 1.0], -2.0))]
HIDDEN_PANEL = np.array([1.2, 2.99, -1.0])


def panel_behind_a_floater(room_box: list[dict] | None) -> SplatScene:
    """``room_scene`` plus a clipped ceiling panel (0.4 m, radiance 300) that a few dim,
    opaque floaters 0.6 m under the ceiling hide from the cameras' median point, as a fit
    leaves them: seen from there, the room ends at the floaters in the panel's direction."""
    scene, _ = room_scene()
    rng = np.random.default_rng(3)
    panel = HIDDEN_PANEL + np.column_stack([rng.uniform(-0.2, 0.2, 40), np.zeros(40),
                                            rng.uniform(-0.2, 0.2, 40)])
    eye = np.median(np.asarray(scene.metadata["cameras"]["centres"]), axis=0)
    floaters = eye + (HIDDEN_PANEL - eye) * 0.6 + rng.normal(0, 0.03, (6, 3))
    meta = dict(scene.metadata)
    meta["fit_metrics"] = {**meta["fit_metrics"], **({"room_box": room_box} if room_box else {})}
    n = scene.count - 15  # the fit's backdrop tiles stay its last splats
    order = np.r_[np.arange(n), np.arange(scene.count, scene.count + 46), np.arange(n, scene.count)]
    return SplatScene.from_activated(
        np.concatenate([scene.positions, panel, floaters])[order],
        np.concatenate([scene.base_colours, np.full((40, 3), 300.0), np.full((6, 3), 0.3)])[order],
        np.concatenate([scene.scales, np.full((40, 3), 0.04), np.full((6, 3), 0.08)])[order],
        np.concatenate([scene.opacities, np.full(46, 0.9)])[order], metadata=meta)


def test_a_panel_a_floater_hides_from_the_viewpoint_is_inside_the_rooms_box():
    lights_at = [light.position for light in search_lights(panel_behind_a_floater(None)).lights]
    # seen from the cameras' median point alone, the room ends at the floaters
    assert all(np.linalg.norm(p - HIDDEN_PANEL) > 0.3 for p in lights_at)
    scene = panel_behind_a_floater(ROOM_BOX)
    found = search_lights(scene)
    near = [light for light in found.lights if np.linalg.norm(light.position - HIDDEN_PANEL) < 0.1]
    assert len(near) == 1 and near[0].radius < 0.3
    # the box holds the room, not the bright smear a fit left behind the window's wall
    assert not outside_room(scene.positions[found.emitters]).any()
    assert "room box (6 planes)" in found.space.source
    # ...but the surfaces a clipped light is weighed by stay those the viewpoint sees
    panel = np.linalg.norm(scene.positions - HIDDEN_PANEL, axis=1) < 0.3
    panel &= scene.base_colours.max(axis=1) > 100
    assert panel.sum() == 40 and found.unseen[panel].all() and not found.backdrop[panel].any()


def test_a_box_open_on_two_sides_is_no_room():
    eye = np.array([0.0, 1.5, 0.0])
    assert len(room_half_spaces({"fit_metrics": {"room_box": ROOM_BOX}}, eye)) == 6
    assert len(room_half_spaces({"fit_metrics": {"room_box": ROOM_BOX[:5]}}, eye)) == 5
    assert room_half_spaces({"fit_metrics": {"room_box": ROOM_BOX[:4]}}, eye) == []
    # two planes closing one side count as one side
    twice = ROOM_BOX[:4] + [{"normal": [0.9987, 0.05, 0.0], "offset": -2.4}]
    assert room_half_spaces({"fit_metrics": {"room_box": twice}}, eye) == []


def test_a_box_open_on_one_side_is_closed_where_the_viewpoint_sees_that_side():
    """A plain floor the sparse points miss leaves the fit's box five sides. Open, the
    sixth let in all the percentile box holds under the floor (the sun room's patch,
    left under its floor by a fit, was "inside" and moved down to the box's bottom); it
    is closed where the viewpoint sees the floor."""
    scene, _ = room_scene()
    scene.metadata = {**scene.metadata,
                      "fit_metrics": {**scene.metadata["fit_metrics"],
                                      "room_box": ROOM_BOX[1:]}}  # no floor
    space = capture_space(scene)
    assert len(space.room) == 6
    normal, offset = space.room[-1]
    np.testing.assert_allclose(normal, [0.0, 1.0, 0.0], atol=1e-9)
    assert abs(offset) < 0.1  # the floor, y = 0
    under, above = np.array([[0.3, -0.25, 0.2]]), np.array([[0.3, 0.25, 0.2]])
    assert space.box[0, 1] < -0.25  # the percentile box holds the point under the floor
    assert not space.inside(under)[0] and space.inside(above)[0]
    # all six given: nothing added
    scene.metadata["fit_metrics"]["room_box"] = ROOM_BOX
    assert len(capture_space(scene).room) == 6
