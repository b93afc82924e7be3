"""The room's boundary carried across a bright hole (gaslight_usd.surroundings.planar_fill,
gaslight_usd.capture.capture_space sealed): where a window set in a wall belongs."""

from __future__ import annotations

import numpy as np

from gaslight_usd.cameras import latlong_directions
from gaslight_usd.capture import capture_space
from gaslight_usd.splats import SplatScene
from gaslight_usd.surroundings import BINS, planar_fill


def _plane_depth(dirs: np.ndarray, normal: np.ndarray, offset: float) -> np.ndarray:
    """Distance from the origin along ``dirs`` to the plane ``normal . x = offset``."""
    cos = dirs @ normal
    return np.where(cos > 1e-9, offset / np.maximum(cos, 1e-9), np.inf)


def test_a_plane_is_carried_across_a_hole_exactly():
    rows, cols = BINS
    dirs = latlong_directions(cols, rows).reshape(-1, 3)
    normal = np.array([0.8, 0.1, -0.59])
    normal /= np.linalg.norm(normal)
    depth = _plane_depth(dirs, normal, 2.5)
    hole = (dirs @ normal) > np.cos(np.radians(10.0))  # a window straight ahead
    assert hole.sum() >= 4
    seen = np.where(hole, np.inf, depth)  # the hole shows nothing (or what lies behind)
    fill = planar_fill(seen, dirs, ~hole, 22.5)
    np.testing.assert_allclose(fill[hole], depth[hole], rtol=1e-6)
    # and the ring's own bins keep their plane
    ring = ~hole & ((dirs @ normal) > np.cos(np.radians(20.0)))
    np.testing.assert_allclose(fill[ring], depth[ring], rtol=1e-6)


def test_no_plane_where_the_surroundings_are_two_surfaces():
    """A ring half on the wall, half on a desk 1.3 m in front of it: no one plane."""
    rows, cols = BINS
    dirs = latlong_directions(cols, rows).reshape(-1, 3)
    normal = np.array([1.0, 0.0, 0.0])
    wall = _plane_depth(dirs, normal, 2.5)
    desk = np.where(dirs[:, 1] < -0.05, _plane_depth(dirs, normal, 1.2), wall)  # lower half
    hole = (dirs @ normal) > np.cos(np.radians(10.0))
    for depth, planar in ((wall, True), (desk, False)):
        fill = planar_fill(np.where(hole, np.inf, depth), dirs, ~hole, 22.5, max_spread=0.15)
        assert np.isfinite(fill[hole]).all() == planar


def test_no_plane_where_too_few_surround():
    rows, cols = BINS
    dirs = latlong_directions(cols, rows).reshape(-1, 3)
    depth = np.full(len(dirs), np.inf)
    depth[0] = 2.0  # one lone bin
    fill = planar_fill(depth, dirs, np.ones(len(dirs), bool), 22.5)
    assert np.isinf(fill).all()


def _room_with_window() -> tuple[SplatScene, np.ndarray]:
    """A 5 x 3 x 4 m room of dim splats with a 1.8 x 1.8 m hole in its +x wall, and a
    bright window (radiance 20, white 1) the fit left 1 m behind the hole; and the
    window's splats."""
    step = 0.15
    ys, zs = np.arange(0.1, 2.91, step), np.arange(-1.9, 1.91, step)
    u, v = np.meshgrid(ys, zs)
    wall = np.stack([np.full(u.size, 2.5), u.ravel(), v.ravel()], 1)
    hole = (wall[:, 1] > 0.7) & (wall[:, 1] < 2.5) & (np.abs(wall[:, 2]) < 0.9)
    wall = wall[~hole]
    others = []
    for fixed, value in ((0, -2.5), (1, 0.0), (1, 3.0), (2, -2.0), (2, 2.0)):
        a = np.arange(-2.4, 2.41, step) if fixed != 0 else ys
        b = np.arange(-1.9, 1.91, step) if fixed == 1 else (
            np.arange(0.1, 2.91, step) if fixed == 2 else zs)
        aa, bb = np.meshgrid(a, b)
        pts = np.zeros((aa.size, 3))
        free = [i for i in range(3) if i != fixed]
        pts[:, free[0]], pts[:, free[1]], pts[:, fixed] = aa.ravel(), bb.ravel(), value
        others.append(pts)
    dim = np.concatenate([wall, *others])
    wy, wz = np.meshgrid(np.arange(0.8, 2.41, 0.1), np.arange(-0.8, 0.81, 0.1))
    window = np.stack([np.full(wy.size, 3.5), wy.ravel(), wz.ravel()], 1)
    pts = np.concatenate([dim, window])
    colours = np.concatenate([np.full((len(dim), 3), 0.3), np.full((len(window), 3), 20.0)])
    scene = SplatScene.from_activated(pts, colours, np.full((len(pts), 3), 0.1),
                                      np.full(len(pts), 0.95),
                                      metadata={"exposure_scale": 1.0})
    return scene, window


def test_the_sealed_space_closes_a_window_with_its_wall():
    scene, window = _room_with_window()
    eye = np.array([[0.0, 1.5, 0.0]])
    space = capture_space(scene, eye, planes=True)
    on_wall = window.copy()
    on_wall[:, 0] = 2.45
    beyond = window.copy()
    beyond[:, 0] = 2.9
    # open: where the window's bright splats are, the boundary falls through (part of
    # what lies 0.4 m behind the wall is inside); sealed: the wall's plane closes it
    assert space.inside(beyond).mean() > 0.1
    assert not space.inside(beyond, boundary="sealed").any()
    assert space.inside(on_wall, boundary="sealed").mean() > 0.9
    # the rest of the room is the same room
    probe = np.array([[0.0, 1.0, 1.0], [-2.0, 2.0, -1.5], [1.5, 0.5, 1.0]])
    for boundary in ("open", "sealed"):
        assert space.inside(probe, boundary=boundary).all()
