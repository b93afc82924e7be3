"""Flat lights in the room's planes (windows, ceiling panels) as RectLights in the rig."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdLux
from test_lights import ROOM_HI, ROOM_LO, WINDOW, room_scene

from gaslight_usd.light_shapes import NUDGE_SHARE, panel_of, room_planes, solid_angle
from gaslight_usd.lights import search_lights
from gaslight_usd.splats import SplatScene
from gaslight_usd.usd.rig import Rig, build_rig, rig_irradiance
from gaslight_usd.usd.scene import ExportOptions, export_usd

# The room of tests/test_lights.py as a fit's room box reports it: normals towards the
# cameras (into the room), offset = normal . x on the plane.
ROOM_BOX = [{"normal": n, "offset": float(np.dot(n, p))} for n, p in (
    ([1.0, 0.0, 0.0], ROOM_LO), ([-1.0, 0.0, 0.0], ROOM_HI), ([0.0, 1.0, 0.0], ROOM_LO),
    ([0.0, -1.0, 0.0], ROOM_HI), ([0.0, 0.0, 1.0], ROOM_LO), ([0.0, 0.0, -1.0], ROOM_HI))]


def boxed_room() -> tuple[SplatScene, dict]:
    scene, parts = room_scene()
    scene.metadata["fit_metrics"] = {**scene.metadata["fit_metrics"], "room_box": ROOM_BOX}
    return scene, parts


def test_solid_angle_of_a_square_near_and_far():
    # a 2 x 2 square 1 away, seen from its axis: 4 asin(ab / sqrt((a^2+4d^2)(b^2+4d^2)))
    square = np.array([[-1, -1, 1], [-1, 1, 1], [1, 1, 1], [1, -1, 1]], np.float64)
    assert solid_angle(square, np.zeros(3)) == pytest.approx(2 * math.pi / 3, rel=1e-9)
    far = solid_angle(square, np.array([0.0, 0.0, -99.0]))
    assert far == pytest.approx(4.0 / 100.0**2, rel=1e-3)  # area / distance^2


def test_room_planes_read_the_fits_room_box():
    scene, _ = boxed_room()
    planes = room_planes(scene.metadata)
    assert len(planes) == 6
    normal, offset = planes[1]
    np.testing.assert_allclose(normal, [-1, 0, 0])
    assert offset == pytest.approx(-2.5)
    assert room_planes({}) == [] and room_planes({"fit_metrics": {"room_box": [{}]}}) == []


def test_the_window_is_a_rectangle_in_its_wall_the_lamp_is_not():
    scene, _ = boxed_room()
    search = search_lights(scene)
    window, lamp = search.lights
    planes, depth = room_planes(scene.metadata), search.space.median_depth()
    panel = panel_of(window.position, window.extent, window.axes, planes, depth)
    assert panel is not None
    np.testing.assert_allclose(panel.normal, [-1, 0, 0], atol=1e-9)
    assert panel.centre[0] == pytest.approx(2.5 - NUDGE_SHARE * depth, abs=1e-6)
    np.testing.assert_allclose(panel.centre[1:], WINDOW[1:], atol=0.1)
    # sides along the room's other planes (y and z), sizes the window's (1.1 x 1.4 m)
    axis = np.abs(np.stack([panel.u, panel.v])).argmax(1)
    sides = sorted(zip(axis, panel.half_size, strict=True))
    assert [axis for axis, _ in sides] == [1, 2]
    assert sides[0][1] == pytest.approx(0.6, abs=0.12) and sides[1][1] == pytest.approx(
        0.75, abs=0.12)
    np.testing.assert_allclose(np.cross(panel.u, panel.v), -panel.normal, atol=1e-9)
    assert panel_of(lamp.position, lamp.extent, lamp.axes, planes, depth) is None
    assert panel_of(window.position, window.extent, window.axes, [], depth) is None


def test_a_round_light_by_a_wall_stays_round():
    planes = room_planes({"fit_metrics": {"room_box": ROOM_BOX}})
    bulb_by_wall = np.array([2.45, 1.5, 0.0])  # 5 cm from the x = 2.5 wall
    assert panel_of(bulb_by_wall, np.full(3, 0.08), np.eye(3), planes, 2.0) is None
    flat = np.array([0.5, 0.4, 0.02])  # the same place, flat along the wall
    axes = np.array([[0, 0, 1], [0, 1, 0], [1, 0, 0]], np.float64)
    assert panel_of(bulb_by_wall, flat, axes, planes, 2.0) is not None


def rect_rig(radiance: float, half: tuple[float, float], distance: float) -> Rig:
    """A rig of one rectangle (normal -z) ``distance`` above the origin, a black dome."""
    from gaslight_usd.light_shapes import Panel

    panel = Panel(centre=np.array([0.0, 0.0, distance]), normal=np.array([0.0, 0.0, -1.0]),
                  u=np.array([1.0, 0.0, 0.0]), v=np.array([0.0, 1.0, 0.0]),
                  half_size=np.array(half), plane_offset=0.0)
    lights = {"position": panel.centre[None], "radius": np.array([0.1]),
              "radiance": np.array([[radiance] * 3]), "panel": [panel]}
    return Rig(probe=np.zeros(3), dome=np.zeros((8, 16, 3), np.float32), lights=lights)


def corner_factor(a: float, b: float) -> float:
    """View factor from a point to a parallel a x b rectangle over it, one corner above it
    (the textbook closed form)."""
    x, y = a / math.sqrt(1 + a * a), b / math.sqrt(1 + b * b)
    return (x * math.atan(b / math.sqrt(1 + a * a)) + y * math.atan(a / math.sqrt(1 + b * b))
            ) / (2 * math.pi)


def test_rig_irradiance_of_a_rectangle_matches_the_closed_form():
    rig = rect_rig(radiance=5.0, half=(0.6, 0.4), distance=0.5)
    up, down = np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, -1.0]])
    e = rig_irradiance(rig, np.zeros(3), up, cells=64)[0, 0]
    factor = 4 * corner_factor(0.6 / 0.5, 0.4 / 0.5)  # four corner rectangles
    assert e == pytest.approx(math.pi * 5.0 * factor, rel=0.01)
    assert rig_irradiance(rig, np.zeros(3), down)[0, 0] == 0.0  # faces away
    # behind the rectangle: it emits from its front only
    assert rig_irradiance(rig, np.array([0.0, 0.0, 1.0]), down)[0, 0] == 0.0


def _world_axes(prim: Usd.Prim) -> tuple[np.ndarray, np.ndarray]:
    m = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(0))
    return m[3, :3], -m[2, :3] / np.linalg.norm(m[2, :3])  # origin, emitting direction


@pytest.mark.slow
def test_the_rig_writes_the_window_as_a_rect_light(tmp_path):
    scene, _ = boxed_room()
    probe = np.array([0.0, 1.5, 0.0])
    report = export_usd(scene, tmp_path / "scene.usda",
                        ExportOptions(variants=("rig",), dome_width=64, probe=tuple(probe)))
    assert report.errors == []
    metrics = report.metrics["rig"]
    assert len(metrics["rect_lights"]) == 1 and len(metrics["sphere_lights"]) == 1
    stage = Usd.Stage.Open(str(tmp_path / "scene.rig.usdc"))
    rects = [p for p in stage.Traverse() if p.IsA(UsdLux.RectLight)]
    spheres = [p for p in stage.Traverse() if p.IsA(UsdLux.SphereLight)]
    assert len(rects) == 1 and len(spheres) == 1
    origin, emits = _world_axes(rects[0])
    np.testing.assert_allclose(emits, [-1, 0, 0], atol=1e-6)  # into the room
    assert 2.45 < origin[0] < 2.5 and np.linalg.norm(origin[1:] - WINDOW[1:]) < 0.1
    rect = UsdLux.RectLight(rects[0])
    sides = sorted([rect.GetWidthAttr().Get(), rect.GetHeightAttr().Get()])
    assert sides[0] == pytest.approx(1.2, abs=0.25) and sides[1] == pytest.approx(1.5, abs=0.25)
    assert not rect.GetNormalizeAttr().Get()
    # The window's light at the probe is what the splats send there (their radiance ~19).
    rig = build_rig(scene, probe=probe, width=64)
    intensity = rect.GetIntensityAttr().Get() * np.asarray(rect.GetColorAttr().Get())
    np.testing.assert_allclose(intensity, rig.lights["radiance"][0], rtol=1e-5)
    assert 10.0 < float(intensity.max()) < 40.0
    facing_window = np.array([[1.0, 0.0, 0.0]])
    lit = rig_irradiance(rig, probe, facing_window)[0]
    assert metrics["irradiance_error"] <= metrics["tolerance"]
    from gaslight_usd.render.envmap import render_latlong
    from gaslight_usd.usd.rig import irradiance

    full_pano = render_latlong(scene, probe, 128)
    full = irradiance(full_pano, facing_window)[0]
    np.testing.assert_allclose(lit, full, rtol=0.15)
    # the chain bench's score of the rig: at its own probe it is the splats' light there
    from gaslight_usd.bench.suite_chain import TRUTH_SPACE, rig_irradiance_psnr

    at_probe = rig_irradiance_psnr(rig, full_pano, probe, TRUTH_SPACE, 1.0)
    assert at_probe > 30.0
    by_window = np.array([2.0, 1.6, 0.2])  # 0.5 m from it: the dome's parallax shows
    truth = render_latlong(scene, by_window, 128)
    rig_there = rig_irradiance_psnr(rig, truth, by_window, TRUTH_SPACE, 1.0)
    assert 5.0 < rig_there < at_probe
