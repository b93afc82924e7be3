"""A light one photo frames, fitted behind the ceiling, is put back on it
(gaslight_usd.fit.sunk_lights); one a second photo frames, or one hanging in the room,
stays."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from gaslight_usd.cameras import PinholeCamera
from gaslight_usd.colour import REC709_Y
from gaslight_usd.fit import preset
from gaslight_usd.fit.data import FitData
from gaslight_usd.fit.gather import aimed_camera
from gaslight_usd.fit.model import SplatModel
from gaslight_usd.fit.planes import Plane
from gaslight_usd.fit.sunk_lights import RULES, surface_sunk_lights
from gaslight_usd.fit.trainer import Trainer
from gaslight_usd.poses.colmap import ColmapModel
from gaslight_usd.render import render
from gaslight_usd.sightings import sight_lights
from gaslight_usd.splats import SplatScene

Y709 = np.array(REC709_Y, np.float32)
LIGHT = np.array([0.8, 3.0, 0.5])  # a small panel on the ceiling
EYE = np.array([0.0, 1.5, 0.0])  # the one photo that frames it
SUNK = EYE + 1.3 * (LIGHT - EYE)  # where the fit left it: on that photo's rays, 0.45 m up
WHITE = 1.0


def _box(step: float = 0.2, ceiling: float = 3.0) -> SplatScene:
    """A 5 x ``ceiling`` x 4 m room of flat, opaque, dim splats (radiance 0.3)."""
    xs, ys = np.arange(-2.4, 2.41, step), np.arange(0.1, ceiling - 0.09, step)
    zs = np.arange(-1.9, 1.91, step)
    faces = []
    for fixed, value, (a, b) in ((1, 0.0, (xs, zs)), (1, ceiling, (xs, zs)), (0, -2.5, (ys, zs)),
                                 (0, 2.5, (ys, zs)), (2, -2.0, (xs, ys)), (2, 2.0, (xs, ys))):
        u, v = np.meshgrid(a, b)
        pts = np.zeros((u.size, 3))
        free = [i for i in range(3) if i != fixed]
        pts[:, free[0]], pts[:, free[1]], pts[:, fixed] = u.ravel(), v.ravel(), value
        scales = np.full((len(pts), 3), step * 0.6)
        scales[:, fixed] = 0.005
        faces.append((pts, scales))
    pts = np.concatenate([f[0] for f in faces])
    scales = np.concatenate([f[1] for f in faces])
    return SplatScene.from_activated(pts, np.full((len(pts), 3), 0.3), scales,
                                     np.full(len(pts), 0.99), metadata={"antialiased": True})


def _light(at: np.ndarray, size: float = 1.0) -> SplatScene:
    """Five bright flat splats round ``at``, ``size`` x 6 cm out."""
    a = np.arange(5) * 2 * np.pi / 5
    pts = at + 0.06 * size * np.stack([np.cos(a), np.zeros(5), np.sin(a)], 1)
    scales = np.full((5, 3), 0.05 * size)
    scales[:, 1] = 0.005
    return SplatScene.from_activated(pts, np.full((5, 3), 20.0), scales, np.full(5, 0.9),
                                     metadata={"antialiased": True})


def _with(room: SplatScene, light: SplatScene) -> SplatScene:
    return SplatScene(*(np.concatenate([getattr(room, a), getattr(light, a)]) for a in
                        ("positions", "rotations", "log_scales", "opacity_logits", "sh")),
                      metadata={"antialiased": True})


def _camera(eye, target, name) -> PinholeCamera:
    aimed = aimed_camera(np.array(eye, float), np.array(target, float), 0.55, 8)
    return PinholeCamera(120, 90, 100.0, 100.0, 60.0, 45.0, aimed.R, aimed.t, name)


def _views(aim_light_from_second: bool = False):
    """The room's photos (the light on the ceiling, clipped at the white) and the fit
    with the light sunk: one photo frames the light; the others look at the walls and
    floor, or (``aim_light_from_second``) a second one also frames the light's place
    (and its photo saw none there): the move is refused."""
    truth = _with(_box(), _light(LIGHT))
    cams = [_camera(EYE, LIGHT, "up"),
            _camera([0.0, 1.5, 0.0], [-2.5, 1.2, 0.0], "west"),
            _camera([0.0, 1.5, 0.0], [0.0, 1.2, -2.0], "north"),
            _camera([0.3, 1.5, 0.3], [0.0, 0.0, 1.0], "floor"),
            _camera([-0.5, 1.4, 0.2], [0.0, 1.5, 2.0], "south")]
    images = [np.minimum(render(truth, cam).image.numpy(), WHITE * 1.5) for cam in cams]
    if aim_light_from_second:
        cams[1] = _camera([1.6, 1.2, -0.4], LIGHT, "across")
        images[1] = np.minimum(render(_box(), cams[1]).image.numpy(), WHITE)
    fit = _with(_box(), _light(SUNK, 1.3))
    return fit, cams, images


def _surface(fit, cams, images):
    whites = np.full(len(cams), WHITE)
    sightings = sight_lights(cams, images, whites, Y709)
    return surface_sunk_lights(fit, cams, images, whites, Y709, sightings)


def test_a_light_one_photo_frames_sunk_behind_the_ceiling_is_put_on_it():
    fit, cams, images = _views()
    out, report = _surface(fit, cams, images)
    light = np.arange(fit.count - 5, fit.count)
    assert report.moved == 5 and report.refused == 0
    assert report.power_share > 0.99
    moved = out.positions[light].astype(np.float64)
    # on the ceiling (within a few cm under it), along the photo's rays
    assert np.all(np.abs(moved[:, 1] - 3.0) < 0.06)
    assert np.linalg.norm(moved.mean(0) - LIGHT) < 0.1
    eye = cams[0].center
    before = fit.positions[light] - eye
    after = moved - eye
    cos = np.sum(before * after, 1) / np.linalg.norm(before, axis=1) / np.linalg.norm(after, axis=1)
    assert np.all(cos > 1 - 1e-9)
    # shrunk with the distance: the photo that framed it draws it on the same pixels
    ratio = np.linalg.norm(after, axis=1) / np.linalg.norm(before, axis=1)
    np.testing.assert_allclose(out.scales[light] / fit.scales[light],
                               np.repeat(ratio[:, None], 3, 1), rtol=1e-5)
    # nothing else moved
    np.testing.assert_array_equal(out.positions[: fit.count - 5], fit.positions[: fit.count - 5])
    # and the light is reported where the photo's outline places it: that photo, at the
    # moved splats' power-weighted centre, as large as the outline there
    assert len(report.placed) == 1 and report.as_dict()["placed_lights"] == 1
    placed = report.placed[0]
    assert placed.views == [0] and placed.framed == 1
    np.testing.assert_allclose(placed.position, moved.mean(0), atol=1e-3)
    assert 0.05 < placed.size < 0.2  # the splats lie within 6 cm of the centre, 5 cm wide


def test_a_light_whose_place_a_second_photo_frames_is_left_where_it_was():
    """There parallax, not the one photo, placed it (and this photo saw none there)."""
    fit, cams, images = _views(aim_light_from_second=True)
    out, report = _surface(fit, cams, images)
    assert report.moved == 0 and report.refused == 5 and not report.placed
    np.testing.assert_array_equal(out.positions, fit.positions)


CEILING = Plane(np.array([0.0, -1.0, 0.0]), -3.0, np.array([-2.5, -2.0]),
                np.array([2.5, 2.0]), np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), 500)
"""The room's ceiling as :func:`gaslight_usd.fit.planes.find_planes` gives it."""


@pytest.mark.parametrize("planes", [(), (CEILING,)])
def test_a_light_sunk_past_a_ceiling_smeared_deep_stops_on_the_rooms_plane(planes):
    """A ceiling few photos see is fitted deep (0.5 m up here) and the captured space's
    boundary with it: the light goes to that boundary, or, given the room's ceiling
    plane, stops where its photo's rays cross the plane first."""
    _, cams, images = _views()
    fit = _with(_box(ceiling=3.5), _light(EYE + 1.6 * (LIGHT - EYE), 1.6))
    whites = np.full(len(cams), WHITE)
    sightings = sight_lights(cams, images, whites, Y709)
    out, report = surface_sunk_lights(fit, cams, images, whites, Y709, sightings,
                                      planes=planes)
    assert report.moved == 5
    height = float(np.median(out.positions[-5:, 1]))
    if planes:
        assert height == pytest.approx(3.0, abs=0.06)
        assert np.linalg.norm(out.positions[-5:].mean(0) - LIGHT) < 0.1
    else:  # the boundary as the deep ceiling's 0.2 m tiles give it
        assert 3.25 < height < 3.55


def test_lights_inside_the_room_are_not_moved():
    """A lamp hanging under the ceiling, on the same photo's rays, stays."""
    _, cams, images = _views()
    hanging = _with(_box(), _light(EYE + 0.8 * (LIGHT - EYE), 0.8))
    out, report = _surface(hanging, cams, images)
    assert report.moved == 0 and report.refused == 0 and not report.placed
    np.testing.assert_array_equal(out.positions, hanging.positions)


NEAR = EYE + 0.05 * (LIGHT - EYE)  # the same light drawn 0.16 m in front of the camera


def _near_fit(near_only: bool, aim_light_from_second: bool = False):
    """The ceiling panel's photos as above; the fit drew it just in front of the one
    camera that frames it, 20x smaller (the same pixels in that photo)."""
    _, cams, images = _views(aim_light_from_second)
    fit = _with(_box(), _light(NEAR, 0.05))
    whites = np.full(len(cams), WHITE)
    sightings = sight_lights(cams, images, whites, Y709)
    rules = frozenset({"near"}) if near_only else RULES
    return fit, cams, surface_sunk_lights(fit, cams, images, whites, Y709, sightings,
                                          rules=rules)


@pytest.mark.parametrize("near_only", [False, True])
def test_a_light_drawn_just_in_front_of_its_one_camera_is_put_on_the_ceiling(near_only):
    fit, cams, (out, report) = _near_fit(near_only)
    light = np.arange(fit.count - 5, fit.count)
    assert report.moved == 5 and report.power_share > 0.99
    moved = out.positions[light].astype(np.float64)
    # on the ceiling: the room's boundary as its 0.2 m tiles give it, each splat on its ray
    assert np.all(np.abs(moved[:, 1] - 3.0) < 0.12)
    assert np.linalg.norm(moved.mean(0) - LIGHT) < 0.1
    eye = cams[0].center
    before, after = fit.positions[light] - eye, moved - eye
    ratio = np.linalg.norm(after, axis=1) / np.linalg.norm(before, axis=1)
    assert np.all(ratio > 15)  # each along its own ray, grown with the distance
    np.testing.assert_allclose(out.scales[light] / fit.scales[light],
                               np.repeat(ratio[:, None], 3, 1), rtol=1e-5)
    np.testing.assert_array_equal(out.positions[: fit.count - 5], fit.positions[: fit.count - 5])


@pytest.mark.parametrize("planes", [(), (CEILING,)])
def test_a_floater_under_a_ceiling_smeared_deep_stops_on_the_rooms_plane(planes):
    """The near rule moves onto the captured space's boundary, which a ceiling few photos
    see drags 0.5 m up (no other photo frames that place to say it is dark); given the
    room's ceiling plane, the light stops where its ray crosses the plane."""
    _, cams, images = _views()
    fit = _with(_box(ceiling=3.5), _light(NEAR, 0.05))
    whites = np.full(len(cams), WHITE)
    sightings = sight_lights(cams, images, whites, Y709)
    out, report = surface_sunk_lights(fit, cams, images, whites, Y709, sightings,
                                      rules=frozenset({"near"}), planes=planes)
    assert report.moved == 5
    height = float(np.median(out.positions[-5:, 1]))
    if planes:
        assert height == pytest.approx(3.0, abs=0.06)
        assert np.linalg.norm(out.positions[-5:].mean(0) - LIGHT) < 0.1
    else:
        assert height > 3.25


def test_a_light_near_its_camera_whose_new_place_another_photo_saw_dark_stays():
    fit, _, (out, report) = _near_fit(True, aim_light_from_second=True)
    assert report.moved == 0 and report.refused == 5
    np.testing.assert_array_equal(out.positions, fit.positions)


def test_the_floater_rule_alone_moves_no_sunk_or_hanging_light():
    """The rule the fit applies midway (floaters just in front of a camera) leaves a
    light sunk behind the ceiling or hanging in the room where it is."""
    fit, cams, images = _views()
    hanging = _with(_box(), _light(EYE + 0.8 * (LIGHT - EYE), 0.8))
    whites = np.full(len(cams), WHITE)
    sightings = sight_lights(cams, images, whites, Y709)
    for scene in (fit, hanging):
        out, report = surface_sunk_lights(scene, cams, images, whites, Y709, sightings,
                                          rules=frozenset({"near"}))
        assert report.moved == 0
        np.testing.assert_array_equal(out.positions, scene.positions)


WINDOW = dict(x=2.5, y=(1.3, 1.9), z=(-0.4, 0.4))


def _wall_with_window() -> SplatScene:
    """The room with a hole in its +x wall where the window is."""
    room = _box()
    p = room.positions
    hole = ((p[:, 0] > 2.4) & (p[:, 1] > WINDOW["y"][0] - 0.1) & (p[:, 1] < WINDOW["y"][1] + 0.1)
            & (p[:, 2] > WINDOW["z"][0] - 0.1) & (p[:, 2] < WINDOW["z"][1] + 0.1))
    return room.subset(np.flatnonzero(~hole))


def _window(x: float = WINDOW["x"] - 0.01) -> SplatScene:
    """A bright flat window (radiance 20) in the +x wall's plane."""
    ys = np.arange(WINDOW["y"][0], WINDOW["y"][1] + 1e-6, 0.1)
    zs = np.arange(WINDOW["z"][0], WINDOW["z"][1] + 1e-6, 0.1)
    u, v = np.meshgrid(ys, zs)
    pts = np.stack([np.full(u.size, x), u.ravel(), v.ravel()], 1)
    scales = np.full((len(pts), 3), 0.06)
    scales[:, 0] = 0.005
    return SplatScene.from_activated(pts, np.full((len(pts), 3), 20.0), scales,
                                     np.full(len(pts), 0.9), metadata={"antialiased": True})


def _window_views():
    """Photos of the room with its window from four places across the room (the window
    clipped at the white, broad: wider than a compact light's outline)."""
    truth = _with(_wall_with_window(), _window())
    centre = np.array([2.5, 1.6, 0.0])
    cams = [_camera([-0.5, 1.5, 0.0], centre, "facing"),
            _camera([-0.2, 1.4, -1.2], centre, "left"),
            _camera([-0.2, 1.6, 1.2], centre, "right"),
            _camera([0.5, 1.2, 0.3], [-2.5, 1.2, 0.0], "back"),
            _camera([0.0, 1.5, 0.0], [0.0, 0.0, 1.5], "floor")]
    images = [np.minimum(render(truth, cam).image.numpy(), WHITE * 1.5) for cam in cams]
    return cams, images


def test_a_window_floating_in_the_room_is_put_back_in_its_wall():
    """A broad light smeared along the rays (0.6 m in front of its wall) is moved onto
    the wall's plane, which the sealed captured space carries across the window."""
    cams, images = _window_views()
    eye = cams[0].center
    window = _window()
    floating = window.subset(np.arange(window.count))
    floating.positions = (eye + 0.78 * (window.positions - eye)).astype(np.float32)
    floating.log_scales = (window.log_scales + np.log(0.78)).astype(np.float32)
    fit = _with(_wall_with_window(), floating)
    out, report = _surface(fit, cams, images)
    light = np.arange(fit.count - window.count, fit.count)
    assert abs(float(np.median(fit.positions[light, 0])) - WINDOW["x"]) > 0.5
    assert report.moved >= 0.9 * window.count
    x = out.positions[light, 0].astype(np.float64)
    assert np.median(np.abs(x - WINDOW["x"])) < 0.08
    # the room's own splats stay
    np.testing.assert_array_equal(out.positions[: light[0]], fit.positions[: light[0]])


WINDOW_WALL = Plane(np.array([-1.0, 0.0, 0.0]), -2.5, np.array([0.0, -2.0]),
                    np.array([3.0, 2.0]), np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), 500)
"""The window's wall as :func:`gaslight_usd.fit.planes.room_box` keeps it."""


@pytest.mark.parametrize("planes", [(), (WINDOW_WALL, CEILING)])
def test_a_window_a_few_centimetres_off_its_wall_goes_onto_the_rooms_plane(planes):
    """A window fitted 15 cm in front of its wall (under the sealed boundary's share of its
    distance) stays without the room's planes; given the wall's plane, it goes onto it."""
    cams, images = _window_views()
    eye = cams[0].center
    window = _window()
    off = window.subset(np.arange(window.count))
    share = 1.0 - 0.15 / (WINDOW["x"] - eye[0])
    off.positions = (eye + share * (window.positions - eye)).astype(np.float32)
    off.log_scales = (window.log_scales + np.log(share)).astype(np.float32)
    fit = _with(_wall_with_window(), off)
    whites = np.full(len(cams), WHITE)
    sightings = sight_lights(cams, images, whites, Y709)
    out, report = surface_sunk_lights(fit, cams, images, whites, Y709, sightings,
                                      planes=planes, broad_on_planes=True)
    light = np.arange(fit.count - window.count, fit.count)
    x = out.positions[light, 0].astype(np.float64)
    if planes:  # not unless asked: the fit's first pass leaves them for the weighing
        kept, _ = surface_sunk_lights(fit, cams, images, whites, Y709, sightings,
                                      planes=planes)
        np.testing.assert_array_equal(kept.positions, fit.positions)
    if not planes:
        assert report.moved == 0
        assert np.median(np.abs(x - WINDOW["x"])) > 0.1
    else:
        assert report.moved >= 0.9 * window.count
        assert np.median(np.abs(x - WINDOW["x"])) < 0.02
        # along a photo's rays, its scales with it: still the window's size in that photo
        grown = np.exp(out.log_scales[light] - fit.log_scales[light]).astype(np.float64)
        np.testing.assert_allclose(grown.max(1), grown.min(1), rtol=1e-5)
        assert 1.0 < float(np.median(grown)) < 1.1
    np.testing.assert_array_equal(out.positions[: light[0]], fit.positions[: light[0]])


def test_a_window_in_its_wall_stays():
    cams, images = _window_views()
    fit = _with(_wall_with_window(), _window())
    out, report = _surface(fit, cams, images)
    assert report.moved == 0
    np.testing.assert_array_equal(out.positions, fit.positions)


def test_a_broad_light_hanging_in_the_room_is_not_pushed_onto_the_wall():
    """A lit shade 1 m in front of the back wall: photos from across the room see the
    wall behind it unlit, so it stays."""
    shade = _window(x=0.0)  # a bright panel hanging mid-room, facing +x
    shade.positions[:, 0] = -1.5
    truth = _with(_box(), shade)
    target = np.array([-2.5, 1.6, 0.0])
    cams = [_camera([1.5, 1.5, 0.0], target, "facing"),
            _camera([1.0, 1.4, -1.8], target, "left"),
            _camera([1.0, 1.6, 1.8], target, "right"),
            _camera([0.0, 1.5, 0.0], [0.0, 0.0, 1.5], "floor")]
    images = [np.minimum(render(truth, cam).image.numpy(), WHITE * 1.5) for cam in cams]
    out, report = _surface(truth, cams, images)
    assert report.moved <= 0.1 * shade.count
    np.testing.assert_allclose(np.median(out.positions[-shade.count:, 0]), -1.5, atol=0.05)


def _slab(y: float) -> SplatScene:
    """Dim opaque splats at height ``y`` under the panel's corner of the ceiling: the
    fitted surface hanging short of the true ceiling where few photos see it."""
    u, v = np.meshgrid(np.arange(0.2, 1.01, 0.1), np.arange(0.0, 0.81, 0.1))
    slab = np.stack([u.ravel(), np.full(u.size, y), v.ravel()], 1)
    scales = np.full((len(slab), 3), 0.06)
    scales[:, 1] = 0.005
    return SplatScene.from_activated(slab, np.full((len(slab), 3), 0.3), scales,
                                     np.full(len(slab), 0.99), metadata={"antialiased": True})


def test_a_floater_whose_boundary_hangs_short_of_the_ceiling_goes_on_to_the_light():
    """The fit's surfaces can hang under the true ceiling where few photos see it (a dim
    slab at 2.6 m here), and a side photo sees that place dark: the floater goes to the
    first place farther along its ray that no photo contradicts, the panel itself."""
    _, cams, images = _views()
    truth = _with(_box(), _light(LIGHT))
    cams[1] = _camera([1.6, 1.2, -0.4], LIGHT, "across")  # frames the slab and the light
    images[1] = np.minimum(render(truth, cams[1]).image.numpy(), WHITE * 1.5)
    fit = _with(_with(_box(), _slab(2.6)), _light(NEAR, 0.05))
    whites = np.full(len(cams), WHITE)
    sightings = sight_lights(cams, images, whites, Y709)
    # the boundary along the floater's rays is the slab, where the side photo saw none;
    # the first place past it the side photo sees lit is the panel (its outline a block
    # of the peaks' map wide, a few cm under the ceiling at most: 8 steps to the box)
    out, report = surface_sunk_lights(fit, cams, images, whites, Y709, sightings,
                                      rules=frozenset({"near"}))
    assert report.moved == 5 and report.refused == 0
    moved = out.positions[-5:].astype(np.float64)
    assert np.all(moved[:, 1] > 2.75)  # past the slab
    assert np.linalg.norm(moved.mean(0) - LIGHT) < 0.2


def _trainer_on_true_views() -> Trainer:
    """A fresh trainer on the panel room's views as true HDR (nothing clipped)."""
    _, cams, _ = _views()
    truth = _with(_box(), _light(LIGHT))
    images = [render(truth, cam).image.numpy() for cam in cams]
    data = FitData(names=[c.name for c in cams], cameras=cams, images=images,
                   model=ColmapModel(cameras=cams), colour_space="Linear Rec.709 (sRGB)")
    trainer = Trainer(data, preset("fast").updated(holdout_every=0, plane_prior="off",
                                                    init_points=200))
    trainer._fresh()
    return trainer


def test_a_fit_of_views_that_clipped_nothing_puts_a_sunk_light_on_the_ceiling():
    """True HDR views (or merged brackets): the sunk compact light rule runs too (one
    photo's light can sit anywhere along its rays whether or not it clipped)."""
    trainer = _trainer_on_true_views()
    fit = _with(_box(), _light(SUNK, 1.3))
    out, report = trainer._surface_sunk_lights(fit)
    assert report.moved == 5 and len(report.placed) == 1
    assert np.all(np.abs(out.positions[-5:, 1] - 3.0) < 0.06)


def test_the_fit_moves_a_floater_while_it_has_steps_to_go():
    """The trainer moves the lights drawn in front of a camera at the end of the densify
    window, in its own model (so the steps left can clear that photo's view of them),
    with the moved splats' Adam moments cleared; nothing else moves."""
    trainer = _trainer_on_true_views()
    fit = _with(_box(), _light(NEAR, 0.05))
    tensors = {"means": fit.positions, "quats": fit.rotations, "log_scales": fit.log_scales,
               "opacity_logits": fit.opacity_logits,
               "log_colour": np.log(np.maximum(fit.base_colours, 1e-4)),
               "sh_rel": np.zeros((fit.count, 15, 3), np.float32)}
    trainer.model = SplatModel({k: torch.as_tensor(np.asarray(v, np.float32))
                                for k, v in tensors.items()}, dict.fromkeys(tensors, 1e-3))
    trainer.model.params(0).means.sum().backward()  # a step: Adam holds moments
    trainer.model.step()
    trainer.step = trainer._floaters_step()
    before = trainer.model.t["means"].detach().numpy().copy()
    assert trainer._floaters_step() == int(0.6 * trainer.cfg.iterations)
    trainer._surface_floaters()
    after = trainer.model.t["means"].detach().numpy()
    light = slice(fit.count - 5, fit.count)
    assert np.all(after[light, 1] > 2.8)  # on the ceiling, from 0.16 m in front of the camera
    assert trainer.floaters_moved == 5
    np.testing.assert_array_equal(after[: fit.count - 5], before[: fit.count - 5])
    state = trainer.model.opt.state[trainer.model.t["means"]]
    assert float(state["exp_avg"][light].abs().max()) == 0.0
    assert float(state["exp_avg"][: fit.count - 5].abs().min()) > 0.0
