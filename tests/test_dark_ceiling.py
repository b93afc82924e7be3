"""Pixels a photo crushed to black are upper bounds, not zeros: the dark ceiling from
photo to fit (a frame exposed for a light is black everywhere else)."""

from __future__ import annotations

import numpy as np
import torch
from conftest import write_jpeg

from gaslight_usd.cli.main import main
from gaslight_usd.colour import DARK_LEVEL, REC709_Y, convert, luminance_weights
from gaslight_usd.fit.data import fit_ceiling
from gaslight_usd.fit.losses import bounded_l1, fit_loss
from gaslight_usd.imageio import read_channel, read_image
from gaslight_usd.poses.views import CLIP_FLOOR_CHANNEL, DARK_CEILING_CHANNEL

Y = torch.tensor(REC709_Y)


def test_bounded_l1_penalises_only_radiance_above_the_ceiling_in_crushed_pixels():
    target = torch.zeros((1, 3, 3))  # what the photo recorded: black
    ceiling = torch.tensor([[0.5, 0.5, 0.0]])  # pixels 0, 1 crushed (at most 0.5); 2 measured
    pred = torch.zeros((1, 3, 3))
    pred[0, 0] = 0.3  # under the ceiling: free
    pred[0, 1] = 2.0  # 1.5 over it: penalised by the excess
    pred[0, 2] = 0.2  # measured black: plain L1
    expected = (0.0 + 3 * 1.5 + 3 * 0.2) / 9
    assert abs(float(bounded_l1(pred, target, None, Y, ceiling=ceiling)) - expected) < 1e-5
    # the gradient under the ceiling is nil: nothing pulls a wall the dark frame saw to black
    x = torch.full((1, 1, 3), 0.3, requires_grad=True)
    bounded_l1(x, torch.zeros((1, 1, 3)), None, Y, ceiling=torch.tensor([[0.5]])).backward()
    assert float(x.grad.abs().max()) == 0.0
    # without a ceiling the same pixel is pulled to black
    x.grad = None
    bounded_l1(x, torch.zeros((1, 1, 3)), None, Y).backward()
    assert float(x.grad.abs().max()) > 0.0


def test_the_ssim_term_asks_nothing_under_the_ceiling():
    """A dark frame's black is no structure to match: with the ceiling, a lit room drawn
    under it costs nothing; without, SSIM and L1 both pull it to black."""
    rng = np.random.default_rng(0)
    room = torch.as_tensor(rng.uniform(0.02, 0.05, (16, 16, 3)).astype(np.float32))
    black = torch.zeros_like(room)
    ceiling = torch.full((16, 16), 0.2)
    assert float(fit_loss(room, black, 0.2, 0.0, None, Y, 0.1, ceiling)) < 1e-6
    assert float(fit_loss(room, black, 0.2, 0.0, None, Y, 0.1, None)) > 0.02


def test_fit_ceiling_bounds_a_downscaled_pixel_only_where_most_was_crushed():
    image = np.full((2, 4, 3), 0.01, np.float32)
    ceiling = np.zeros((2, 4), np.float32)
    ceiling[:, :2] = 0.004  # the left block all crushed
    ceiling[0, 2] = 0.004  # one pixel of four in the right block
    w = np.array(REC709_Y, np.float32)
    out = fit_ceiling(ceiling, image, w, (4, 2), 2)
    assert out is not None and out.shape == (1, 2)
    assert abs(out[0, 0] - 0.004) < 1e-7  # a bound on its mean
    assert out[0, 1] == 0.0  # a quarter crushed, under half: a measurement
    assert fit_ceiling(np.zeros((2, 4), np.float32), image, w, (4, 2), 2) is None


def test_hdr_views_carry_the_black_level_where_the_photo_crushed(tmp_path):
    """A frame 6 stops darker than the set, black but for its lamp: its HDR view says "at
    most the black level" there, in the set's relative radiance; the bright frame has no
    crushed pixel and no ceiling."""
    photos = tmp_path / "photos"
    photos.mkdir()
    rng = np.random.default_rng(0)
    room = rng.uniform(0.1, 0.6, (48, 64, 3)).astype(np.float32)
    write_jpeg(photos / "a.jpg", np.round(room * 255).astype(np.uint8), exposure_time=1 / 30)
    dark = np.zeros((48, 64, 3), np.uint8)
    dark[20:24, 30:34] = 200  # the lamp, measured
    dark[0:4, 0:4] = 10  # a dim patch over the black level: measured
    write_jpeg(photos / "b.jpg", dark, exposure_time=1 / 1920)  # 6 stops darker
    assert main(["hdr", str(photos), "--method", "linear", "-o", str(tmp_path / "hdr")]) == 0
    assert read_channel(tmp_path / "hdr" / "a.exr", DARK_CEILING_CHANNEL).max() == 0.0
    view = tmp_path / "hdr" / "b.exr"
    ceiling = read_channel(view, DARK_CEILING_CHANNEL)
    space = read_image(view).colour_space
    assert ceiling is not None and ceiling.shape == (48, 64)
    crushed = ceiling > 0
    assert not crushed[20:24, 30:34].any() and not crushed[1:3, 1:3].any()
    assert crushed.mean() > 0.98 - (16 + 16) / (48 * 64)
    # the black level's luminance in relative radiance: the dark frame's over its exposure
    # ratio (1/8: the set's reference EV is the median of the two photos')
    level = convert(np.full((1, 1, 3), DARK_LEVEL, np.float32), "srgb_rec709_scene", space)
    ratio = float(read_image(view).metadata["gaslight:exposure_ratio"])
    reference = float(level.reshape(3) @ luminance_weights(space)) / ratio
    np.testing.assert_allclose(ceiling[crushed], reference, rtol=2e-3)
    assert ratio < 1.0 / 2 ** 2.5  # the darker frame of the two
    assert read_channel(view, CLIP_FLOOR_CHANNEL).max() == 0.0  # nothing clipped

