"""Broad faint splats in a room's open air are fog; walls, lights and detail are not."""

from __future__ import annotations

import numpy as np

from gaslight_usd.fit.fog import FOG_CLEAR_SHARE, FOG_OPACITY, FOG_WIDTH_SHARE, fog_splats
from gaslight_usd.fit.planes import Plane
from gaslight_usd.splats import SplatScene

EXTENT = 1.7  # the cameras' spread in a 5 x 3 x 4 m room


def _box() -> list[Plane]:
    """The room's box: walls at x = +-2.5, z = +-2, floor y = 0, ceiling y = 3."""
    out = []
    for axis, lo, hi in ((0, -2.5, 2.5), (1, 0.0, 3.0), (2, -2.0, 2.0)):
        n = np.zeros(3)
        n[axis] = 1.0
        for normal, offset in ((n, lo), (-n, -hi)):
            out.append(Plane(normal, offset, np.array([-3.0, -3.0]), np.array([3.0, 3.0]),
                             np.eye(3)[[(axis + 1) % 3, (axis + 2) % 3]], 500))
    return out


def test_a_broad_faint_splat_in_the_open_air_is_fog_and_walls_lights_and_detail_are_not():
    wide = 2.0 * FOG_WIDTH_SHARE * EXTENT
    rows = [
        ([1.8, 1.5, 0.3], wide, 0.2),   # fog: by the window's probe, on its line to a bulb
        ([0.0, 1.4, 0.0], wide, 0.1),   # fog in the room's middle
        ([1.2, 0.95, 1.1], wide, 0.9),  # the bulb: opaque
        ([0.5, 1.2, 0.5], 0.01, 0.2),   # faint but small: detail
        ([2.45, 1.5, 0.0], wide, 0.2),  # faint and broad, but on the wall
        ([0.5, 2.9, 0.5], wide, 0.2),   # ... on the ceiling
    ]
    pos = np.array([r[0] for r in rows], float)
    scales = np.repeat(np.array([r[1] for r in rows], float)[:, None], 3, axis=1)
    opac = np.array([r[2] for r in rows], float)
    scene = SplatScene.from_activated(pos, np.ones((len(rows), 3)), scales, opac)
    np.testing.assert_array_equal(fog_splats(scene, _box(), EXTENT),
                                  [True, True, False, False, False, False])
    # the thresholds: at the opacity, or as near the wall as the clearance, it stays
    edge = SplatScene.from_activated(
        np.array([[0.0, 1.4, 0.0], [2.5 - 0.9 * FOG_CLEAR_SHARE * EXTENT, 1.5, 0.0]]),
        np.ones((2, 3)), np.full((2, 3), wide), np.array([FOG_OPACITY, 0.2]))
    assert not fog_splats(edge, _box(), EXTENT).any()
    # no room box (a set SfM gave no two facing walls): nothing is judged fog
    assert not fog_splats(scene, [], EXTENT).any()
