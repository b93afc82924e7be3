"""Compact lights the photos clipped: found from their outlines, seeded, and kept as lights.

Views are rendered from the splat room of tests/test_lights.py (a lamp, a window, a
ceiling patch the lamp lights), then clipped as auto-exposed photos clip them: each view
at its own white, the lamp's pixels left at that white (an uplift that added nothing).
"""

from __future__ import annotations

import numpy as np
from test_lights import LAMP, _recoloured, room_scene
from test_sightings import Y709, _cameras, _views

from gaslight_usd.fit.data import FitData
from gaslight_usd.fit.frame_edge import light_regions
from gaslight_usd.fit.gather import aimed_camera
from gaslight_usd.fit.init import initial_points
from gaslight_usd.fit.light_seeds import (
    LightSeedPoints,
    clipped_at,
    find_light_seeds,
    measured_light_seeds,
    seed_lights,
    seed_points,
)
from gaslight_usd.fit.presets import FitConfig
from gaslight_usd.fit.trainer import Trainer
from gaslight_usd.lights import search_lights
from gaslight_usd.poses.colmap import ColmapModel
from gaslight_usd.render import render
from gaslight_usd.resize import area_resize
from gaslight_usd.sightings import (
    Sightings,
    block_max,
    peak_map,
    sight_lights,
    view_whites,
    without_specks,
)

# each view's white in the views' units: auto-exposure moved them by up to a stop
WHITES = np.array([1.0, 1.6, 0.8, 1.3, 1.1, 0.9, 1.5, 1.2])


def _clipped_views(specks: float = 0.0) -> tuple[list, list[np.ndarray]]:
    scene, _ = room_scene()
    cams = _cameras()
    rng = np.random.default_rng(3)
    views = []
    for image, white in zip(_views(scene, cams), WHITES, strict=True):
        image = np.minimum(image, white)
        if specks:  # single pixels over the white: sensor noise, fireflies
            hit = rng.random(image.shape[:2]) < specks
            image[hit] = 3.0 * white
        views.append(image.astype(np.float32))
    return cams, views


def test_a_clipped_lamp_is_placed_from_its_outlines_and_nothing_else_is_outlined():
    cams, views = _clipped_views()
    seeds = find_light_seeds(cams, views, WHITES, Y709)
    outlined = [s for s in seeds if s.share >= 1.0]
    assert len(outlined) == 1
    lamp = outlined[0]
    assert np.linalg.norm(lamp.position - LAMP) < 0.05
    assert len(lamp.views) >= 3 and 0.0 < lamp.size < 0.15
    # the window is a broad light (left to the surface fill), the rest is no light
    assert all(np.linalg.norm(s.position - LAMP) < 0.3 or s.share < 1.0 for s in seeds)
    # the seed points sit on the lamp, at least as bright as the white that clipped it
    pts, cols = seed_points(outlined, cams, views, views, np.random.default_rng(0), Y709)
    assert len(pts) == len(cols) > 0
    assert np.linalg.norm(pts - lamp.position, axis=1).max() <= lamp.size + 1e-9
    assert (cols @ Y709).min() >= WHITES[lamp.views].min() * 0.99


def test_a_view_that_clipped_the_lamp_but_filled_it_under_its_white_is_not_against_it():
    """The uplift may fill a clipped bulb at its clip level, under the view's white (the
    median of its clip floors): that view's outline misses the bulb. Read as "framed,
    not clipped" it made the bulb a hot spot (the chain bench's ``bulb:11``); with the
    photos' clip masks it says nothing either way and the bulb stays outlined."""
    cams, views = _clipped_views()
    masks = [(im @ Y709) >= 0.999 * w for im, w in zip(views, WHITES, strict=True)]
    lamp = next(s for s in find_light_seeds(cams, views, WHITES, Y709) if s.share >= 1.0)
    v = lamp.views[0]
    uv, _ = cams[v].project(lamp.position[None])
    ys, xs = np.mgrid[0:views[v].shape[0], 0:views[v].shape[1]]
    near = np.hypot(xs + 0.5 - uv[0, 0], ys + 0.5 - uv[0, 1]) < 12
    views[v] = np.where((near & masks[v])[..., None], 0.97 * WHITES[v], views[v]).astype(
        np.float32)
    plain = find_light_seeds(cams, views, WHITES, Y709)
    assert not any(s.share >= 1.0 and np.linalg.norm(s.position - LAMP) < 0.1 for s in plain)
    peaks = [peak_map(im, Y709, w, m) for im, w, m in zip(views, WHITES, masks, strict=True)]
    assert clipped_at(lamp.position[None], cams, peaks)[0, v]
    assert not clipped_at(lamp.position[None], cams, views).any()  # no masks: not known
    masked = find_light_seeds(cams, peaks, WHITES, Y709)
    outlined = [s for s in masked if s.share >= 1.0]
    assert len(outlined) == 1 and np.linalg.norm(outlined[0].position - LAMP) < 0.05
    assert v not in outlined[0].views  # held by the others, not counted against by v
    # clipped well under the white (one colour channel, a pale surface): still against
    views[v] = np.where((near & masks[v])[..., None], 0.8 * WHITES[v], views[v]).astype(
        np.float32)
    peaks = [peak_map(im, Y709, w, m) for im, w, m in zip(views, WHITES, masks, strict=True)]
    assert not clipped_at(lamp.position[None], cams, peaks)[0, v]


def _cones_at(bulb: np.ndarray, cams: list, seed: int, radius_deg: float) -> Sightings:
    """Each view's outline of ``bulb`` as a cone ``radius_deg`` wide whose centroid ray
    misses it by a fraction of a degree (0.6 degrees, random)."""
    rng = np.random.default_rng(seed)
    axes = []
    for cam in cams:
        d = (bulb - cam.center) / np.linalg.norm(bulb - cam.center)
        off = np.radians(0.6) * rng.normal(size=3)
        d = d + off - (off @ d) * d
        axes.append(d / np.linalg.norm(d))
    n = len(cams)
    return Sightings(np.array([c.center for c in cams]), np.arange(n), np.array(axes),
                     np.full(n, np.radians(radius_deg)), np.ones(n, bool), np.ones(n), 1.0)


def test_a_bulbs_outlines_meeting_again_along_their_rays_make_one_light():
    """Four nearby views frame a bulb (a dark frame among them outlines it too); their
    centroid rays miss it by a fraction of a degree, so three of them also meet 0.19 m
    behind it, inside all their cones, with the fourth framing that place and seeing the
    bulb beside it. One light, not a ghost behind it (``bulb:11`` with dark frames had
    two, 0.24 and 0.36 m off)."""
    bulb = np.array([0.0, 1.0, 3.0])
    cams = [aimed_camera(np.array([x, 1.0, 0.0]), bulb, 0.75, 160)
            for x in (-0.75, -0.25, 0.25, 0.75)]
    seeds = seed_lights(_cones_at(bulb, cams, 2, 1.5), cams)
    assert len(seeds) == 1
    assert np.linalg.norm(seeds[0].position - bulb) < 0.1


def test_noise_specks_over_the_white_place_no_lights():
    cams, clean = _clipped_views()
    _, noisy = _clipped_views(specks=0.02)
    # left in, the specks alone would be a region each in every view
    speckled = [len(light_regions(block_max((im @ Y709) / w)[0]).centroids)
                for im, w in zip(noisy, WHITES, strict=True)]
    assert min(speckled) > 20
    found = find_light_seeds(cams, noisy, WHITES, Y709)
    expected = find_light_seeds(cams, clean, WHITES, Y709)
    assert len(found) == len(expected)
    assert sum(s.share >= 1.0 for s in found) == 1


def test_one_shared_white_merges_the_lamp_into_a_brighter_views_lit_surroundings():
    """The view exposed a stop darker than the others has a wall over the shared white."""
    floors = [np.array([[0.0, 2.0], [2.2, 0.0]]), None, np.array([[0.5, 0.5], [0.0, 0.5]])]
    np.testing.assert_allclose(view_whites(floors, 1.0), [2.1, 1.0, 0.5])
    cams, views = _clipped_views()
    shared = sight_lights(cams, views, float(WHITES.min()), Y709)
    own = sight_lights(cams, views, WHITES, Y709)
    held_shared = shared.radii[shared.holding(LAMP[None])[0]]
    held_own = own.radii[own.holding(LAMP[None])[0]]
    assert held_own.max() < held_shared.max()


def test_full_size_peaks_keep_a_bulb_the_working_size_averages_away():
    image = np.full((480, 640, 3), 0.2, np.float32)
    image[200:202, 300:302] = 1.0  # a clipped bulb, 2 pixels across
    image[50, 50] = 1.0  # a speck
    small = area_resize(image, 120, 90) @ Y709
    assert small.max() < 1.0  # at the fit's working size the bulb is gone
    peaks = peak_map(image, Y709, 1.0)
    assert peaks.block == 4 and peaks.size == (640, 480)
    assert peaks.peaks[200 // 4, 300 // 4] >= 1.0
    assert peaks.peaks[50 // 4, 50 // 4] < 1.0  # the speck is not a light
    ratio = without_specks(image @ Y709)
    assert ratio[200, 300] >= 1.0 and ratio[50, 50] < 1.0


def test_a_short_lamp_the_outlines_placed_is_a_light_and_a_hot_spot_is_not():
    """The uplift left the lamp just over the white and the ceiling it lights is clipped
    too: the clipped ceiling may be up to the headroom brighter, so the emitter test
    alone takes the lamp for a lit surface. The photos placed a light there, clipped
    wherever it was framed: that makes it a light. An outline some view measured under
    the white (share < 1) does not."""
    scene, parts = room_scene()
    rgb = scene.base_colours.copy()
    rgb[parts["lamp"]] = [1.6, 1.5, 1.3]
    scene = _recoloured(scene, rgb)
    assert not search_lights(scene).emitters[parts["lamp"]].any()
    seed = {"position": LAMP.tolist(), "size": 0.05, "views": [0, 1, 2, 3], "framed": 4}
    scene.metadata = {**scene.metadata, "light_seeds": [seed]}
    found = search_lights(scene)
    assert found.emitters[parts["lamp"]].mean() > 0.9
    assert not found.emitters[parts["lit"]].any()
    lamp = min(found.lights, key=lambda li: np.linalg.norm(li.position - LAMP))
    assert np.linalg.norm(lamp.position - LAMP) < 0.05
    scene.metadata = {**scene.metadata, "light_seeds": [{**seed, "framed": 5}]}
    assert not search_lights(scene).emitters[parts["lamp"]].any()


def test_initial_points_add_the_seeded_lights():
    cams, views = _clipped_views()
    seeds = [s for s in find_light_seeds(cams, views, WHITES, Y709) if s.share >= 1.0]
    pts, cols = seed_points(seeds, cams, views, views, np.random.default_rng(0), Y709)
    model = ColmapModel(cameras=[])
    got, colours, how = initial_points(model, cams, views, [f"v{i}" for i in range(8)], 500,
                                       np.random.default_rng(0),
                                       seeded=LightSeedPoints(pts, cols, len(seeds)))
    assert how.endswith("+ 1 seeded light") and len(got) == len(colours)
    np.testing.assert_allclose(got[-len(pts):], pts)
    np.testing.assert_allclose(colours[-len(pts):], cols)


def test_a_light_the_other_points_already_cover_is_not_seeded_again():
    """A lamp the brightness test found keeps the start it had; a bare one is seeded."""
    rng = np.random.default_rng(0)
    centres = np.array([[0.0, 2.0, 0.0], [1.0, 1.0, 1.0]])
    seeded = LightSeedPoints(np.repeat(centres, 12, axis=0), np.ones((24, 3), np.float32), 2,
                             centres, np.array([0.05, 0.05]))
    others = np.concatenate([centres[0] + rng.normal(0, 0.01, (20, 3)),
                             rng.uniform(-2, 2, (200, 3))])
    left = seeded.missing_from(others)
    assert left.lights == 1 and len(left.points) == 12
    np.testing.assert_allclose(left.centres, centres[1:])
    np.testing.assert_allclose(left.points, np.repeat(centres[1:], 12, axis=0))


def _measured_views() -> tuple[list, list[np.ndarray]]:
    """The room's views as merged brackets or true HDR give them: nothing clipped."""
    scene, _ = room_scene()
    cams = _cameras()
    return cams, [v.astype(np.float32) for v in _views(scene, cams)]


def test_a_measured_lamp_is_placed_from_its_outlines_and_its_lit_patch_is_not():
    """Where no view clipped, the compact regions far over the views' level are lights:
    the lamp (hundreds of times the walls) is placed; the lit ceiling patch under it (5x
    the walls) and the window (broad) are not seeded."""
    cams, views = _measured_views()
    seeds = measured_light_seeds(cams, views, views, Y709)
    assert len(seeds) == 1
    assert np.linalg.norm(seeds[0].position - LAMP) < 0.05
    assert len(seeds[0].views) >= 3 and 0.0 < seeds[0].size < 0.15
    # a level no region reaches seeds nothing
    assert measured_light_seeds(cams, views, views, Y709, ratio=1e6) == []


def test_a_fit_of_measured_views_finds_the_lamp_and_records_no_clipped_light():
    """The measured lamp shields its splats from the plane prior's floater rule
    (``_assign_planes``: a bright splat in front of a lit patch of wall goes onto it; at
    ``balanced`` that moved ``bulb:7``'s bare bulb 0.9 m onto the wall behind it), but
    it is not recorded as a clipped light (nothing clipped) and adds no initial points."""
    cams, views = _measured_views()
    data = FitData(names=[f"v{i}" for i in range(len(views))], cameras=cams, images=views,
                   model=ColmapModel(cameras=cams), colour_space="lin_rec709")
    trainer = Trainer(data, FitConfig(iterations=1, init_points=2000, budget=4000))
    started = trainer._measured_lights()
    assert len(started) == 1 and np.linalg.norm(started[0].position - LAMP) < 0.05
    assert trainer._light_seeds() == []
    assert trainer._seeded_lights().lights == 0


def test_a_dark_frames_bulb_pixels_start_on_the_seeded_bulb():
    """A dark frame measures a bulb the other views clipped and filled a few times the
    white: no depth of its rays agrees with those fills, so the sweep alone put them
    anywhere along the rays (``bulb:11``: 0.1-14 m off). Its rays through the seeded
    bulb start on it; the other views' clipped pixels keep their sweep."""
    from gaslight_usd.fit.init import SEED_REACH, bright_points

    bulb = np.array([0.0, 1.0, 3.0])
    cams = [aimed_camera(np.array([x, 1.0, 0.0]), bulb + [0.2, 0.1, 0.0], 0.75, 96)
            for x in (-0.75, -0.25, 0.25, 0.75)]
    images, floors = [], []
    for v, cam in enumerate(cams):
        uv, _ = cam.project(bulb[None])
        ys, xs = np.mgrid[0:cam.height, 0:cam.width]
        disc = np.hypot(xs + 0.5 - uv[0, 0], ys + 0.5 - uv[0, 1]) <= 1.2
        image = np.full((cam.height, cam.width, 3), 0.5, np.float32)
        if v == 0:  # the dark frame: measured
            image[disc] = 5000.0
            floors.append(np.zeros((cam.height, cam.width), np.float32))
        else:  # clipped at the white, filled three times it
            image[disc] = 3.0
            floors.append(np.where(disc, 1.0, 0.0).astype(np.float32))
        images.append(image)
    seeds = (bulb[None], np.array([0.06]))  # its outlines' size: 1.2 px at 3 m
    pts, cols = bright_points(cams, images, 12, np.random.default_rng(0), floors=floors,
                              y_weights=Y709, seeds=seeds)
    assert len(pts) > 0 and (cols @ Y709).min() > 1000.0  # the dark frame's pixels
    # on the rays' points nearest the seed: within the reach of its size (the sweep alone:
    # 0.17-2 m off)
    assert np.linalg.norm(pts - bulb, axis=1).max() < SEED_REACH * 0.06


def test_a_clipped_lamp_a_darker_frame_measured_is_matched_to_that_frame_alone():
    """The photos clip the lamp; one more frame, from the first photo's place and
    darker, measured it. The fit matches the lamp drawn fine to that frame
    (``Trainer._lights_dark_frames_measured``, :mod:`gaslight_usd.fit.fine_power`): the
    seeded lamp, with that frame as its one view; without the frame, no lamp is."""
    cams, views = _clipped_views()
    scene, _ = room_scene()
    dark = render(scene, cams[0]).image.numpy().astype(np.float32)  # nothing clipped
    floors = [np.where((v >= w).any(axis=2), w, 0.0).astype(np.float32)
              for v, w in zip(views, WHITES, strict=True)]

    def trainer(images, floors):
        all_cams = cams + [cams[0]] * (len(images) - len(cams))
        data = FitData(names=[f"v{i}" for i in range(len(images))], cameras=all_cams,
                       images=images, model=ColmapModel(cameras=all_cams),
                       colour_space="lin_rec709", floors=floors)
        fit = Trainer(data, FitConfig(iterations=1, init_points=2000, budget=4000,
                                      holdout_every=0))
        fit.refiner = None  # not fitted: the poses as given
        return fit

    with_frame = trainer(views + [dark], floors + [None])
    seeds, seed_views = with_frame._lights_dark_frames_measured()
    assert len(seeds) == 1 and np.linalg.norm(seeds[0].position - LAMP) < 0.05
    assert seed_views == [[len(views)]]
    assert trainer(views, floors)._lights_dark_frames_measured()[0] == []


def test_a_far_bulbs_candidates_placed_beside_a_taken_light_are_that_light():
    """A bulb 4.2 m off, seen by a photo and its darker frame from one place and two
    photos 14 and 28 degrees round: the views' rays, a pixel off each, meet in candidates
    along their lines; one far enough from the light first taken to stand alone was placed
    8-13 cm from it, a second light in a streak along the rays (``hall:9``: three)."""
    bulb = np.array([0.0, 2.3, 0.0])
    eyes = []
    for a in np.radians([0.0, 0.0, 14.0, 28.0]):
        d = np.array([np.cos(a), -0.12, np.sin(a)])
        eyes.append(bulb + 4.2 * d / np.linalg.norm(d))
    cams = [aimed_camera(e, bulb, 1.0, 120) for e in eyes]
    seeds = seed_lights(_cones_at(bulb, cams, 9, 1.0), cams)
    assert len(seeds) == 1
    assert np.linalg.norm(seeds[0].position - bulb) < 0.25
