"""A small synthetic closed scene with known splats, for tests and the bench.

Objects (with three 30x "lamps") in the middle of a dim shell of large splats,
seen by a ring of cameras looking at the centre: every pixel sees something,
as in a room.
"""

from __future__ import annotations

import numpy as np

from ..cameras import PinholeCamera
from ..poses.colmap import ColmapModel
from ..render import render
from ..splats import SplatScene
from .data import FitData


def look_at(centre, target=(0, 0, 0), up=(0, 1, 0)) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera (R, t) of a camera at ``centre`` looking at ``target`` (COLMAP)."""
    centre = np.asarray(centre, float)
    f = np.asarray(target, float) - centre
    f /= np.linalg.norm(f)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    rot = np.stack([r, np.cross(f, r), f])
    return rot, -rot @ centre


def closed_scene(seed: int = 0) -> SplatScene:
    rng = np.random.default_rng(seed)
    n_obj, n_shell = 120, 300
    d = rng.normal(size=(n_shell, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    pos = np.concatenate([rng.uniform(-0.6, 0.6, (n_obj, 3)), 4.0 * d])
    col = np.concatenate([np.exp(rng.normal(-0.5, 0.7, (n_obj, 3))),
                          rng.uniform(0.1, 0.4, (n_shell, 3))])
    col[:3] *= 30.0
    scales = np.concatenate([rng.uniform(0.05, 0.12, (n_obj, 3)), np.full((n_shell, 3), 0.6)])
    opac = np.concatenate([rng.uniform(0.6, 0.95, n_obj), np.full(n_shell, 0.99)])
    return SplatScene.from_activated(pos, col, scales, opac,
                                     rotations=rng.normal(size=(len(pos), 4)))


def ring_cameras(n: int = 9, size: int = 48) -> list[PinholeCamera]:
    cams = []
    for k in range(n):
        a = 2 * np.pi * k / n
        rot, t = look_at([2.5 * np.sin(a), 0.4 * np.cos(2 * a), 2.5 * np.cos(a)])
        cams.append(PinholeCamera(size, size, 0.8 * size, 0.8 * size, size / 2, size / 2,
                                  rot, t, name=f"view_{k:02d}.jpg"))
    return cams


def synthetic_data(views: int = 9, size: int = 48, seed: int = 0
                   ) -> tuple[SplatScene, FitData]:
    truth, cams = closed_scene(seed), ring_cameras(views, size)
    images = [render(truth, c).image.numpy() for c in cams]
    data = FitData(names=[c.name.rsplit(".", 1)[0] for c in cams], cameras=cams,
                   images=images, model=ColmapModel(cameras=cams),
                   colour_space="lin_rec709")
    return truth, data
