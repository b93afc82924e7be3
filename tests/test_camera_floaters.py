"""Faint splats floating at a camera are dropped; surfaces, lights, walls and the open
air away from the cameras are not."""

from __future__ import annotations

import numpy as np
import torch
from test_fog import EXTENT, _box

from gaslight_usd.fit.camera_floaters import NEAR_SHARE, OPACITY, camera_floaters
from gaslight_usd.render.envmap import render_latlong
from gaslight_usd.splats import SplatScene

WEIGHTS = np.array([0.2126, 0.7152, 0.0722])
CAMERA = np.array([0.8, 1.5, 0.9])  # a photo taken under a lamp, looking up at it
LADDER = np.array([0.0, 2.7, 0.0])  # one taken from a ladder, just under the ceiling


def _scene(rows) -> SplatScene:
    pos = np.array([r[0] for r in rows], float)
    colour = np.array([r[1] for r in rows], float)
    opac = np.array([r[2] for r in rows], float)
    return SplatScene.from_activated(pos, colour, np.full((len(rows), 3), 0.03), opac)


def test_faint_dim_splats_at_a_camera_go_surfaces_lights_walls_and_far_ones_stay():
    near = 0.5 * NEAR_SHARE * EXTENT
    grey = [0.3, 0.3, 0.3]
    rows = [
        (CAMERA + [0.0, near, 0.0], grey, 0.2),           # floater above the camera
        (CAMERA + [near, 0.1, 0.0], grey, 0.5),           # a fainter-than-surface one
        (CAMERA + [0.0, near, near], grey, 0.95),         # a surface seen close up
        (CAMERA + [0.0, near, -0.1], [40.0, 40.0, 40.0], 0.2),  # a light's glow
        ([0.0, 1.4, -1.0], grey, 0.2),                    # open air, far from the cameras
        (LADDER + [0.0, 0.15, 0.0], grey, 0.2),           # on the ceiling by a camera
    ] + [([x, 1.0, -1.5], grey, 0.9) for x in np.linspace(-1.0, 1.0, 6)]  # the median
    scene = _scene(rows)
    got = camera_floaters(scene, np.stack([CAMERA, LADDER]), _box(), EXTENT, WEIGHTS)
    np.testing.assert_array_equal(got, [True, True] + [False] * 10)
    assert OPACITY > 0.5
    # the backdrop (the last splats) is never taken, nor is anything without a box
    assert not camera_floaters(scene, CAMERA[None], _box(), EXTENT, WEIGHTS, fitted=0).any()
    assert not camera_floaters(scene, CAMERA[None], [], EXTENT, WEIGHTS).any()


def test_a_probe_at_the_camera_sees_the_window_whole_once_its_floaters_are_gone():
    """A probe where the photo was taken looks through the floaters at a bright wall
    patch (the window): with them it reads it dimmed, without them as drawn."""
    rng = np.random.default_rng(3)
    gy, gz = np.meshgrid(np.linspace(1.2, 2.0, 9), np.linspace(0.0, 1.6, 17))
    window = np.column_stack([np.full(gy.size, 2.45), gy.ravel(), gz.ravel()])
    fog = CAMERA + rng.uniform(-0.12, 0.12, (30, 3)) + [0.15, 0.1, 0.0]
    pos = np.concatenate([window, fog])
    colour = np.concatenate([np.full((len(window), 3), 10.0), np.full((len(fog), 3), 0.3)])
    scales = np.concatenate([np.full((len(window), 3), 0.08) * [0.1, 1, 1],
                             np.full((len(fog), 3), 0.04)])
    opac = np.concatenate([np.full(len(window), 0.99), np.full(len(fog), 0.3)])
    scene = SplatScene.from_activated(pos, colour, scales, opac)
    drop = camera_floaters(scene, CAMERA[None], _box(), EXTENT, WEIGHTS)
    assert drop[len(window):].all() and not drop[:len(window)].any()

    with torch.no_grad():
        through = render_latlong(scene, CAMERA, 128) @ WEIGHTS
        cleared = render_latlong(scene.subset(np.flatnonzero(~drop)), CAMERA, 128) @ WEIGHTS
    inside = cleared > 5.0  # the window's pixels, as the probe sees it without them
    assert inside.sum() > 20
    assert abs(float(np.median(cleared[inside])) - 10.0) < 1.0
    assert float(through[inside].mean()) < 0.85 * float(cleared[inside].mean())
