"""Clipped pixels are bounds, not targets: the clip floor from photo to fit."""

from __future__ import annotations

import math

import numpy as np
import torch
from conftest import write_jpeg

from gaslight_usd.cameras import PinholeCamera
from gaslight_usd.cli.main import main
from gaslight_usd.colour import REC709_Y, luminance_weights
from gaslight_usd.fit.data import FitData, fit_floor
from gaslight_usd.fit.losses import bounded_l1
from gaslight_usd.imageio import read_channel, read_image
from gaslight_usd.poses.colmap import ColmapModel
from gaslight_usd.poses.views import CLIP_FLOOR_CHANNEL

Y = torch.tensor(REC709_Y)


def test_bounded_l1_penalises_only_radiance_below_the_floor_in_clipped_pixels():
    target = torch.full((1, 2, 3), 8.0)  # the uplift's fill: 8
    floor = torch.tensor([[1.0, 0.0]])  # pixel 0 clipped at 1, pixel 1 measured
    above = torch.full((1, 2, 3), 8.0)
    above[0, 0] = 20.0  # far above the fill, but above the floor: only the weak pull
    pull = math.log(21.0 / 9.0)  # |log(1 + x) - log(1 + fill)|: in stops, not radiance
    assert abs(float(bounded_l1(above, target, floor, Y, 0.1)) - 0.1 * pull / 2) < 1e-5
    below = torch.full((1, 2, 3), 8.0)
    below[0, 0] = 0.5  # under what the photo recorded: the bound bites
    expected = (0.1 * math.log(9.0 / 1.5) + 0.5) / 2
    assert abs(float(bounded_l1(below, target, floor, Y, 0.1)) - expected) < 1e-5
    # no floor: plain L1
    assert abs(float(bounded_l1(above, target, None)) - 12.0 / 2) < 1e-5


def test_a_view_that_measured_the_light_pins_it_against_another_views_fill():
    """Two views of one light: one clipped at 1 with a fill of 8 (a guess), one that saw
    it unclipped at 3. With bounds the light fits 3; fitted as targets it settles between."""
    def fit(bounds: bool) -> float:
        x = torch.tensor(1.0, requires_grad=True)
        opt = torch.optim.Adam([x], lr=0.05)
        clipped_floor = torch.tensor([[1.0]]) if bounds else None
        for _ in range(600):
            opt.zero_grad()
            pred = x.expand(1, 1, 3)
            loss = bounded_l1(pred, torch.full((1, 1, 3), 8.0), clipped_floor, Y, 0.1) + \
                bounded_l1(pred, torch.full((1, 1, 3), 3.0), None)
            loss.backward()
            opt.step()
        return float(x.detach())

    assert abs(fit(True) - 3.0) < 0.1
    assert fit(False) > 3.5


def test_one_measured_frame_outweighs_many_clipped_guesses():
    """15 views clipped a lamp at 1 and the uplift guessed 3; one dark frame measured
    400. The fit must take the measurement (a linear pull from each guess, 15 x 0.1,
    outweighed it, and the lamp stayed at the guess)."""
    x = torch.tensor(1.0, requires_grad=True)  # log radiance, as the splats' colours
    opt = torch.optim.Adam([x], lr=0.05)
    floor = torch.tensor([[1.0]])
    for _ in range(800):
        opt.zero_grad()
        pred = x.exp().expand(1, 1, 3)
        guesses = sum(bounded_l1(pred, torch.full((1, 1, 3), 3.0), floor, Y, 0.1)
                      for _ in range(15))
        loss = guesses + bounded_l1(pred, torch.full((1, 1, 3), 400.0), None)
        loss.backward()
        opt.step()
    assert abs(math.log2(float(x.detach().exp()) / 400.0)) < 0.1


def test_fit_floor_bounds_the_mean_of_a_downscaled_pixel():
    image = np.ones((2, 4, 3), np.float32)
    floor = np.zeros((2, 4), np.float32)
    floor[0, 0] = 5.0  # one clipped photo pixel, recorded luminance 5
    w = np.array(REC709_Y, np.float32)
    out = fit_floor(floor, image, w, (4, 2), 2)
    assert out.shape == (1, 2)
    assert abs(out[0, 0] - (5.0 + 3 * 1.0) / 4) < 1e-5  # its block: a bound on the mean
    assert out[0, 1] == 0.0  # nothing clipped there: measured


def test_hdr_views_carry_the_recorded_luminance_where_the_photo_clipped(tmp_path):
    photos = tmp_path / "photos"
    photos.mkdir()
    rng = np.random.default_rng(0)
    pixels = rng.uniform(0.1, 0.6, (48, 64, 3)).astype(np.float32)
    pixels[10:20, 30:40] = 1.0  # a clipped lamp
    write_jpeg(photos / "a.jpg", np.round(pixels * 255).astype(np.uint8), exposure_time=1 / 60)
    write_jpeg(photos / "b.jpg", np.round(pixels * 230).astype(np.uint8), exposure_time=1 / 30)
    assert main(["hdr", str(photos), "-o", str(tmp_path / "hdr"), "--method", "linear"]) == 0
    view = tmp_path / "hdr" / "a.exr"
    floor = read_channel(view, CLIP_FLOOR_CHANNEL)
    radiance = read_image(view).pixels
    y = radiance @ luminance_weights(read_image(view).colour_space)
    assert floor is not None and floor.shape == (48, 64)
    clipped = floor > 0
    assert clipped[10:20, 30:40].mean() > 0.9 and clipped.mean() < 0.06
    # the floor is what the photo recorded there: the linearised clipped pixel
    np.testing.assert_allclose(floor[clipped], y[clipped], rtol=2e-3)
    assert read_image(view).pixels.shape == (48, 64, 3)  # RGB readers see RGB only


def _views_with_a_dark_frame(dark: int, n: int = 16) -> FitData:
    """``n`` views that clip a light at white 1 (floor 1 on 4 pixels), and one, ``dark``,
    that measured it unclipped at 400."""
    images, floors = [], []
    for i in range(n):
        img = np.full((6, 8, 3), 0.3, np.float32)
        floor = np.zeros((6, 8), np.float32)
        if i == dark:
            img[2:4, 3:5] = 400.0
        else:
            img[2:4, 3:5] = 6.0  # the uplift's fill
            floor[2:4, 3:5] = 1.0
        images.append(img)
        floors.append(floor)
    cams = [PinholeCamera(8, 6, 8.0, 8.0, 4.0, 3.0, np.eye(3), np.zeros(3))] * n
    return FitData(names=[f"v{i}" for i in range(n)], cameras=cams, images=images,
                   model=ColmapModel(cameras=[]), colour_space="lin_rec709_scene",
                   floors=floors)


def test_the_view_that_measured_a_clipped_light_is_never_held_out():
    plain = _views_with_a_dark_frame(dark=-1)
    assert plain.measures_highlights() == [] and plain.split(8)[1] == [4, 12]
    data = _views_with_a_dark_frame(dark=12)
    assert data.measures_highlights() == [12]
    train, held = data.split(8)
    assert 12 in train and held == [4, 13] and len(train) == 14
    # a fill above white is not a measurement: only the unclipped 400 counts
    assert _views_with_a_dark_frame(dark=4).split(8)[1] == [5, 12]


def test_a_bulbs_dark_frame_makes_the_ring_round_the_clipped_regions_a_bound():
    """With a view that measured the light at 400 x white, the measured pixels right round
    each other view's clipped region are bounds at their own value (a splat as bright as
    the light may spill its tail there); the clipped pixels keep their floors, the rest
    stays measured. Photos alone keep their floors as they are."""
    data = _views_with_a_dark_frame(dark=12)
    floors = data.loss_floors()
    assert floors[12] is None  # the dark frame clipped nothing
    ring = np.zeros((6, 8), bool)
    ring[1:5, 2:6] = True
    ring[2:4, 3:5] = False
    f = floors[0]
    np.testing.assert_allclose(f[2:4, 3:5], 1.0)
    np.testing.assert_allclose(f[ring], 0.3, rtol=1e-5)  # the measured grey, as a bound
    assert (f > 0).sum() == 16  # 4 clipped + their 12-pixel ring; the rest measured
    plain = _views_with_a_dark_frame(dark=-1)
    for got, want in zip(plain.loss_floors(), plain.floors, strict=True):
        np.testing.assert_array_equal(got, want)
    # 400 over a white of 1 passes RING_RATIO; a view measuring 40 would not
    weak = _views_with_a_dark_frame(dark=12)
    weak.images[12][2:4, 3:5] = 40.0
    np.testing.assert_array_equal(weak.loss_floors()[0], weak.floors[0])


def _lamp_views(lamp_values: list[float], clipped: list[bool]):
    """Views from cameras in a row looking down +z at a 3x3-pixel lamp 3 m away on grey;
    each view's lamp pixels hold ``lamp_values[i]``, clipped or not."""
    lamp = np.array([0.0, 0.0, 3.0])
    cams, images, floors = [], [], []
    for i, (value, clip) in enumerate(zip(lamp_values, clipped, strict=True)):
        centre = np.array([0.3 * i - 0.3, 0.0, 0.0])
        cam = PinholeCamera(32, 24, 30.0, 30.0, 16.0, 12.0, np.eye(3), -centre)
        img = np.full((24, 32, 3), 0.5, np.float32)
        floor = np.zeros((24, 32), np.float32)
        u, v = cam.project(lamp[None])[0][0].astype(int)
        img[v - 1:v + 2, u - 1:u + 2] = value
        floor[v - 1:v + 2, u - 1:u + 2] = 1.0 if clip else 0.0
        cams.append(cam)
        images.append(img)
        floors.append(floor)
    return lamp, cams, images, floors


def test_light_seeds_take_the_colour_a_view_measured_not_the_clipped_guesses():
    from gaslight_usd.fit.init import bright_points, measured_colours

    # two photos clipped the lamp (the uplift guessed 40), a dark frame measured 500
    lamp, cams, images, floors = _lamp_views([40.0, 40.0, 500.0], [True, True, False])
    points = np.array([lamp, [0.05, 0.0, 3.0], [0.6, 0.4, 4.0]])  # lamp, lamp, wall
    guess = np.array([[40.0] * 3, [40.0] * 3, [0.5] * 3], np.float32)
    np.testing.assert_allclose(measured_colours(points, guess, cams, images, floors),
                               [[500.0] * 3, [500.0] * 3, [0.5] * 3])
    # a clipped view's guess is never taken as a measurement, however high it is
    _, cams, images, floors = _lamp_views([40.0, 2000.0, 500.0], [True, True, False])
    np.testing.assert_allclose(measured_colours(points, guess, cams, images, floors)[:, 0],
                               [500.0, 500.0, 0.5])
    # the seeds bright_points makes from the clipped photos get the measured colour
    _, cams, images, floors = _lamp_views([40.0, 40.0, 500.0], [True, True, False])
    _, own = bright_points(cams, images, 27, np.random.default_rng(0))
    _, cols = bright_points(cams, images, 27, np.random.default_rng(0), floors=floors)
    assert (own[:, 0] == 40.0).sum() == 18 and (cols[:, 0] == 500.0).sum() > 9
    # a seed whose own pixel was measured keeps it: true HDR views change nothing
    _, cams, images, floors = _lamp_views([450.0, 480.0, 500.0], [False, False, False])
    _, own = bright_points(cams, images, 27, np.random.default_rng(0))
    _, cols = bright_points(cams, images, 27, np.random.default_rng(0), floors=floors)
    np.testing.assert_array_equal(cols, own)
