"""Display-referred PLY copy: hand-computed tone map, exposure in the header."""

from __future__ import annotations

import numpy as np

from gaslight_usd.ply import read_ply
from gaslight_usd.ply_display import DISPLAY_SPACE, display_scene, write_display_ply
from gaslight_usd.splats import SplatScene, sh_dc_to_rgb

LINEAR = "Linear Rec.709 (sRGB)"


def srgb_encode(x: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB transfer function."""
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def test_tone_map_matches_hand_computation(tmp_path):
    colours = np.array([[0.18, 0.18, 0.18], [4.0, 1.0, 0.25], [100.0, 50.0, 0.0]])
    scene = SplatScene.from_activated(np.zeros((3, 3)), colours, np.full((3, 3), 0.1),
                                      np.full(3, 0.9), sh_degree=1)
    scene.sh[:, 1:] = 0.2
    shown = display_scene(scene, exposure_ev=1.0, working_space=LINEAR)
    exposed = colours * 2.0
    want = srgb_encode(exposed / (1 + exposed))
    np.testing.assert_allclose(sh_dc_to_rgb(shown.sh[:, 0]), want, atol=2e-3)
    got = sh_dc_to_rgb(shown.sh[:, 0])
    assert got.max() < 1.0 and got.min() >= 0.0  # nothing a viewer would clip
    # Higher bands scaled by the same per-channel display/linear ratio.
    np.testing.assert_allclose(shown.sh[1, 1:, 0], 0.2 * want[1, 0] / 4.0, rtol=2e-3)
    ev = write_display_ply(tmp_path / "d.ply", scene, 1.0, working_space=LINEAR)
    back = read_ply(tmp_path / "d.ply")
    assert ev == 1.0
    assert back.metadata["display_exposure_ev"] == 1.0
    assert back.metadata["colour_space"] == DISPLAY_SPACE
    assert "Reinhard" in back.metadata["display_tone_map"]


def test_auto_exposure_puts_median_at_middle_grey():
    colours = np.full((5, 3), 0.72)  # two stops above middle grey
    scene = SplatScene.from_activated(np.zeros((5, 3)), colours, np.full((5, 3), 0.1),
                                      np.full(5, 0.5))
    shown = display_scene(scene, working_space=LINEAR)
    assert abs(shown.metadata["display_exposure_ev"] + 2.0) < 1e-3
    grey = 0.18 / 1.18
    np.testing.assert_allclose(sh_dc_to_rgb(shown.sh[:, 0]), srgb_encode(np.full((5, 3), grey)),
                               atol=2e-3)
