"""The chain bench's generated rooms (``examples/make_room.py --variant``): every camera
and probe stands in free space, and every light and the sun patch where it can be seen.

A camera inside a cabinet renders a black photo (the hall's first draw did: its auto-
exposure divided by a zero median); a probe inside furniture scores a panorama of its
inside. Checked without rendering, from the script's own geometry."""

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "examples" / "make_room.py"
CLEARANCE_M = 0.1


def load_variant(name: str):
    """A fresh copy of the script's module with variant ``name`` applied (the variants
    rewrite module constants, so each gets its own module)."""
    spec = importlib.util.spec_from_file_location(f"make_room_{name}", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.apply_variant(name)
    return module


def inside_box(points: np.ndarray, centre, half, yaw_deg: float, margin: float) -> np.ndarray:
    """Which points lie within ``margin`` of a box turned by ``yaw_deg`` about +Y."""
    a = math.radians(yaw_deg)
    rot = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    local = (points - np.asarray(centre)) @ rot  # rows: rot.T @ (p - c)
    return (np.abs(local) <= np.asarray(half) + margin).all(axis=1)


def standing_points(m) -> dict[str, np.ndarray]:
    points = {"cameras": np.array([c.centre for c in m.camera_rig()]),
              "probes": np.asarray(m.PROBE_POSITIONS, np.float64)}
    if m.SHADE is not None:  # the frames from below the shaded lamp
        points["below"] = np.array([c.centre for c in m.below_cameras()])
    return points


@pytest.mark.parametrize("variant", ["room", "bulb", "panels", "shade", "sun", "hall"])
def test_cameras_and_probes_stand_in_free_space(variant):
    m = load_variant(variant)
    lo, hi = np.asarray(m.ROOM_MIN), np.asarray(m.ROOM_MAX)
    for what, pts in standing_points(m).items():
        assert ((pts > lo + CLEARANCE_M) & (pts < hi - CLEARANCE_M)).all(), (variant, what)
        for name, (centre, half, yaw, _) in m.object_boxes().items():
            hit = inside_box(pts, centre, half, yaw, CLEARANCE_M)
            assert not hit.any(), f"{variant}: {what} {np.flatnonzero(hit)} inside the {name}"
        for name, (centre, radius) in m.balls().items():
            dist = np.linalg.norm(pts - np.asarray(centre), axis=1)
            assert (dist > radius + CLEARANCE_M).all(), f"{variant}: {what} in the {name}"
        if m.LAMP_ON:
            dist = np.linalg.norm(pts - m.LAMP_CENTER, axis=1)
            assert (dist > 0.3).all(), f"{variant}: {what} at the lamp"


@pytest.mark.parametrize("variant", ["room", "bulb", "panels", "shade", "sun", "hall"])
def test_lights_sit_on_the_room(variant):
    """The window in the +x wall, panels in the ceiling, the lamp inside the room, and
    the sun patch on free floor (no furniture stands on it)."""
    m = load_variant(variant)
    lo, hi = np.asarray(m.ROOM_MIN), np.asarray(m.ROOM_MAX)
    lights = {li["name"]: li for li in m.light_list()}
    corners = np.asarray(lights["window"]["corners"])
    assert np.allclose(corners[:, 0], hi[0], atol=0.01)
    assert ((corners[:, 1:] > lo[1:]) & (corners[:, 1:] < hi[1:])).all()
    for name, li in lights.items():
        if name.startswith("panel_"):
            assert np.allclose(np.asarray(li["corners"])[:, 1], hi[1], atol=0.01)
        if li["kind"] == "sphere":
            c = np.asarray(li["center"])
            assert ((c - li["radius"] > lo) & (c + li["radius"] < hi)).all()
    if m.SUN is None:
        return
    (x0, z0), (x1, z1) = m.SUN["min"], m.SUN["max"]
    grid = np.stack(np.meshgrid(np.linspace(x0, x1, 9), [0.01], np.linspace(z0, z1, 9)),
                    axis=-1).reshape(-1, 3)
    assert ((grid[:, [0, 2]] > lo[[0, 2]]) & (grid[:, [0, 2]] < hi[[0, 2]])).all()
    for name, (centre, half, yaw, _) in m.object_boxes().items():
        assert not inside_box(grid, centre, half, yaw, 0.0).any(), f"sun patch under the {name}"
    for name, (centre, radius) in m.balls().items():
        dist = np.linalg.norm(grid[:, [0, 2]] - np.asarray(centre)[[0, 2]], axis=1)
        assert (dist > radius).all(), f"sun patch under the {name}"


def test_the_frames_from_below_a_shade_see_its_bulb_through_the_opening():
    """The shaded room's extra views (the README's two frames from below): the bulb lies
    in their frames, the sight lines to the bulb's near half pass the shade's open bottom,
    not its wall, and the two look at it from 30 degrees apart or more; of the photos that
    frame the bulb none sees more than a sliver of it (why the frames are needed)."""
    m = load_variant("shade")
    fx, fy, cx, cy = m.intrinsics()

    def frames_bulb(cam, margin: float) -> bool:
        local = cam.w2c @ (m.LAMP_CENTER - cam.centre)
        u, v = fx * local[0] / local[2] + cx, fy * local[1] / local[2] + cy
        return bool(local[2] > 0 and margin * m.WIDTH < u < (1 - margin) * m.WIDTH
                    and margin * m.HEIGHT < v < (1 - margin) * m.HEIGHT)

    below = m.below_cameras()
    assert len(below) == 2 and all(frames_bulb(cam, 0.25) for cam in below)
    rays = [(cam.centre - m.LAMP_CENTER) / np.linalg.norm(cam.centre - m.LAMP_CENTER)
            for cam in below]
    assert math.degrees(math.acos(float(rays[0] @ rays[1]))) > 30
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(400, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)

    def through_opening(eye: np.ndarray) -> np.ndarray:
        """Per bulb point facing ``eye``: its sight line crosses the opening's plane
        inside the shade's radius."""
        points = m.LAMP_CENTER + m.LAMP_RADIUS * dirs
        points = points[np.einsum("ij,ij->i", eye - points, dirs) > 0]
        y0 = m.SHADE["y0"]
        s = (y0 - points[:, 1]) / (eye[1] - points[:, 1])
        cross = points + s[:, None] * (eye - points)
        off = np.linalg.norm((cross - m.LAMP_CENTER)[:, [0, 2]], axis=1)
        return (s > 0) & (off < m.SHADE["radius"])

    assert all(through_opening(cam.centre).all() for cam in below)
    framing = [c for c in m.camera_rig() if frames_bulb(c, 0.0)]
    assert framing and all(through_opening(c.centre).mean() < 0.05 for c in framing)
