"""Telling a clipped lamp from a surface the lamps lit (gaslight_usd.fit.lamp_or_surface)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaslight_usd.cameras import PinholeCamera
from gaslight_usd.colour import REC709_Y
from gaslight_usd.fit.lamp_or_surface import light_reading, lit_surface_albedos

Y709 = np.array(REC709_Y, np.float32)


def test_the_albedo_a_lit_surface_needs_counts_the_others_at_their_factors_not_itself():
    """Light 0 reads 2 and gets 0.5 from the room and 1 (fill) x 4 from light 1: pi 2 / 4.5.
    Its own column (and NaN: too close to aim at) adds nothing."""
    irr = np.array([[0.5, 100.0, 1.0],
                    [0.2, 0.3, np.nan]])
    albedo = lit_surface_albedos(np.array([2.0, 50.0]), irr, np.array([8.0, 4.0]))
    assert albedo[0] == pytest.approx(math.pi * 2.0 / 4.5)
    assert albedo[1] == pytest.approx(math.pi * 50.0 / (0.2 + 0.3 * 8.0))
    assert np.isinf(lit_surface_albedos(np.array([1.0]), np.array([[0.0, 5.0]]),
                                        np.array([2.0]))[0])


def test_the_reading_is_the_clip_floor_where_clipped_and_faces_the_views():
    cams = [PinholeCamera(40, 30, 30.0, 30.0, 20.0, 15.0, np.eye(3), np.array([x, 0.0, 2.0]))
            for x in (-0.5, 0.5)]
    images = [np.full((30, 40, 3), 0.2, np.float32) for _ in cams]
    floors = [np.zeros((30, 40), np.float32), None]
    point = np.zeros(3)
    uv, _ = cams[0].project(point[None])
    u, v = int(uv[0, 0]), int(uv[0, 1])
    images[0][v, u] = 0.9  # the photo's clipped value...
    floors[0][v, u] = 3.0  # ...says at least this
    reading, facing = light_reading(point, cams, images, floors, Y709)
    assert reading == pytest.approx(3.0)
    centres = np.array([c.center for c in cams])
    expected = (centres / np.linalg.norm(centres, axis=1, keepdims=True)).mean(0)
    np.testing.assert_allclose(facing, expected / np.linalg.norm(expected), atol=1e-9)
    assert light_reading(np.array([0.0, 0.0, -5.0]), cams, images, floors, Y709) == (0.0, None)
