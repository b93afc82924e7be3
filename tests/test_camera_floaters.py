"""Faint splats floating at a camera are dropped; surfaces, lights, walls and the open
air away from the cameras are not."""

from __future__ import annotations

import numpy as np
import torch
from test_fog import EXTENT, _box

from gaslight_usd.fit.camera_floaters import NEAR_SHARE, camera_floaters
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


def _sheet_and_haze(ys, zs, level: float, cell: float, haze: np.ndarray
                    ) -> tuple[SplatScene, int]:
    """An opaque sheet of splats at x = 2.45 (a wall or window, ``level`` bright) over
    the grid ``ys`` x ``zs``, then ``haze`` (K, 3) faint grey splats; and the sheet's
    size."""
    gy, gz = np.meshgrid(ys, zs)
    sheet = np.column_stack([np.full(gy.size, 2.45), gy.ravel(), gz.ravel()])
    n = len(sheet)
    scene = SplatScene.from_activated(
        np.concatenate([sheet, haze]),
        np.concatenate([np.full((n, 3), level), np.full((len(haze), 3), 0.3)]),
        np.concatenate([np.full((n, 3), cell) * [0.1, 1, 1], np.full((len(haze), 3), 0.04)]),
        np.concatenate([np.full(n, 0.99), np.full(len(haze), 0.3)]))
    return scene, n


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
    # the backdrop (the last splats) is never taken, nor is anything without a box
    assert not camera_floaters(scene, CAMERA[None], _box(), EXTENT, WEIGHTS, fitted=0).any()
    assert not camera_floaters(scene, CAMERA[None], [], EXTENT, WEIGHTS).any()


def test_a_probe_at_the_camera_sees_the_window_whole_once_its_floaters_are_gone():
    """A probe where the photo was taken looks through the floaters at a bright wall
    patch (the window): with them it reads it dimmed, without them as drawn."""
    rng = np.random.default_rng(3)
    fog = CAMERA + rng.uniform(-0.12, 0.12, (30, 3)) + [0.15, 0.1, 0.0]
    scene, window = _sheet_and_haze(np.linspace(1.2, 2.0, 9), np.linspace(0.0, 1.6, 17),
                                    10.0, 0.08, fog)
    drop = camera_floaters(scene, CAMERA[None], _box(), EXTENT, WEIGHTS)
    assert drop[window:].all() and not drop[:window].any()

    with torch.no_grad():
        through = render_latlong(scene, CAMERA, 128) @ WEIGHTS
        cleared = render_latlong(scene.subset(np.flatnonzero(~drop)), CAMERA, 128) @ WEIGHTS
    inside = cleared > 5.0  # the window's pixels, as the probe sees it without them
    assert inside.sum() > 20
    assert abs(float(np.median(cleared[inside])) - 10.0) < 1.0
    assert float(through[inside].mean()) < 0.85 * float(cleared[inside].mean())


def test_floaters_a_held_out_photo_saw_are_kept_those_it_did_not_are_dropped():
    """The fit drops a camera's floaters only where the held-out views do not read worse
    without them: a held-out photo beside that camera that saw them (something there after
    all) keeps them; one that saw the wall clear behind them lets them go."""
    from types import SimpleNamespace

    from test_flat_outlines import look_at

    from gaslight_usd.fit.trainer import Trainer
    from gaslight_usd.render import render

    rng = np.random.default_rng(7)
    haze = CAMERA + [0.25, 0.0, 0.0] + rng.uniform(-0.08, 0.08, (20, 3))
    scene, wall = _sheet_and_haze(np.linspace(0.6, 2.6, 21), np.linspace(-0.2, 2.0, 23),
                                  1.0, 0.1, haze)
    clear = scene.subset(np.arange(wall))
    target = np.array([2.45, 1.5, 0.9])
    trained = look_at(CAMERA, target, width=64, height=48, focal=50.0)
    held = look_at(CAMERA + [-0.05, 0.03, 0.0], target, width=64, height=48, focal=50.0)
    with torch.no_grad():
        photos = {"saw them": render(scene, held).image.numpy(),
                  "saw the wall": render(clear, held).image.numpy()}
        train_photo = render(scene, trained).image.numpy()
    kept = {}
    for name, photo in photos.items():
        trainer = Trainer.__new__(Trainer)  # the fit's finishing step, on a made-up fit
        trainer.data = SimpleNamespace(cameras=[trained, held], images=[train_photo, photo])
        trainer.refiner, trainer.train, trainer.held = None, [0], [1]
        trainer.room_planes, trainer.extent = _box(), EXTENT
        trainer.y_weights = torch.tensor(WEIGHTS, dtype=torch.float32)
        trainer.cfg, trainer.device = SimpleNamespace(background=0.0), "cpu"
        out, report = trainer._drop_camera_floaters(scene, 0)
        kept[name] = (out.count, report)
    assert kept["saw them"][0] == scene.count
    assert kept["saw them"][1]["refused"] == len(haze)
    assert kept["saw them"][1]["held_out_stops_after"] > kept["saw them"][1][
        "held_out_stops_before"] + 0.02
    assert kept["saw the wall"][0] == wall
    assert kept["saw the wall"][1]["splats"] == len(haze)
