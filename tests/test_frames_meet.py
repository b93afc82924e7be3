"""A light two darker frames measured is put where their sight lines to it meet."""

from __future__ import annotations

import numpy as np
import pytest

from gaslight_usd.fit.data import scale_camera_to
from gaslight_usd.fit.frames_meet import (
    BULB_SHARE,
    bulb_sightings,
    frame_and_seed,
    frames_meeting,
    measuring_sightings,
    meeting_point,
    moved_to_meeting,
)
from gaslight_usd.fit.gather import aimed_camera
from gaslight_usd.render import render
from gaslight_usd.resize import area_resize
from gaslight_usd.splats import SplatScene

Y709 = np.array([0.2126, 0.7152, 0.0722], np.float32)
BULB = np.array([0.8, 2.1, 0.9])
SIZE = 64
WHITE = 1.0


def _bulb_under_a_ceiling(bulb: np.ndarray) -> SplatScene:
    """A dim ceiling 0.5 m over a 4 cm bulb (luminance about 2,000)."""
    g = np.linspace(-1.5, 1.5, 25)
    cu, cv = np.meshgrid(g, g)
    ceiling = np.column_stack([BULB[0] + cu.ravel(), np.full(cu.size, BULB[1] + 0.5),
                               BULB[2] + cv.ravel()])
    rng = np.random.default_rng(0)
    lamp = bulb + rng.normal(0.0, 0.012, (40, 3))
    pos = np.concatenate([ceiling, lamp])
    rgb = np.concatenate([np.full((len(ceiling), 3), 0.3), np.full((len(lamp), 3), 2000.0)])
    scales = np.concatenate([np.full((len(ceiling), 3), 0.12), np.full((len(lamp), 3), 0.012)])
    opac = np.concatenate([np.full(len(ceiling), 0.99), np.full(len(lamp), 0.7)])
    return SplatScene.from_activated(pos, rgb, scales, opac, metadata={"antialiased": True})


def _frames_from_below(spread: float = 0.36) -> list:
    """Two frames 0.65 m under the bulb, ``spread`` to either side, aimed at it."""
    eyes = [BULB + np.array([dx, -0.65, 0.0]) for dx in (-spread, spread)]
    return [aimed_camera(e, BULB, 0.6, SIZE) for e in eyes]


def _measured(scene: SplatScene, cams: list) -> list[np.ndarray]:
    return [area_resize(render(scene, scale_camera_to(cam, SIZE * 4, SIZE * 4)).image
                        .numpy(), SIZE, SIZE) for cam in cams]


def test_lines_meet_where_they_cross():
    point = np.array([0.3, -1.2, 2.0])
    origins = np.array([[0.0, 0.0, 0.0], [1.0, 0.5, -0.5], [-2.0, 1.0, 1.0]])
    directions = point - origins
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    np.testing.assert_allclose(meeting_point(origins, directions), point, atol=1e-9)


def test_two_frames_from_below_find_the_bulb_the_seed_missed():
    """The seed sits 0.18 m off, at the shade's opening; the frames' blobs meet at the
    bulb within a centimetre and give its radius."""
    truth = _bulb_under_a_ceiling(BULB)
    cams = _frames_from_below()
    images = _measured(truth, cams)
    seed = BULB + np.array([-0.09, -0.135, -0.07])
    sightings = measuring_sightings(seed, 0.13, cams, images, [None, None], Y709, WHITE)
    assert [s.view for s in sightings] == [0, 1]
    meeting = frames_meeting(sightings)
    assert meeting is not None
    assert np.linalg.norm(meeting.position - BULB) < 0.01
    assert 0.005 < meeting.radius < 0.05


def test_a_view_that_clipped_round_the_light_or_reads_it_dim_does_not_measure_it():
    truth = _bulb_under_a_ceiling(BULB)
    cams = _frames_from_below()
    images = _measured(truth, cams)
    clipped = np.zeros((SIZE, SIZE), np.float32)
    clipped[SIZE // 2, SIZE // 2] = WHITE
    assert [s.view for s in measuring_sightings(BULB, 0.05, cams, images, [clipped, None],
                                                Y709, WHITE)] == [1]
    assert measuring_sightings(BULB, 0.05, cams, [im * 1e-4 for im in images],
                               [None, None], Y709, WHITE) == []


def test_frames_nearly_in_line_or_seeing_different_things_place_nothing():
    truth = _bulb_under_a_ceiling(BULB)
    close = _frames_from_below(spread=0.03)  # 5 degrees apart
    sightings = measuring_sightings(BULB, 0.05, close, _measured(truth, close),
                                    [None, None], Y709, WHITE)
    assert len(sightings) == 2 and frames_meeting(sightings) is None
    cams = _frames_from_below()
    # each frame sees a different bulb, 0.4 m apart: their lines miss each other
    images = [_measured(_bulb_under_a_ceiling(BULB + shift), [cam])[0]
              for cam, shift in zip(cams, (np.array([0, 0, -0.2]), np.array([0, 0, 0.2])),
                                    strict=True)]
    sightings = measuring_sightings(BULB, 0.1, cams, images, [None, None], Y709, WHITE)
    assert len(sightings) == 2 and frames_meeting(sightings) is None


def test_the_fits_two_lobes_under_the_bulb_move_onto_it_and_the_glow_stays():
    """The fit drew the bulb as two lobes 0.1 m under it, each on one frame's sight line,
    with a dim glow round the opening: the lobes go to the bulb, drawn together to the
    frames' radius; the glow stays."""
    truth = _bulb_under_a_ceiling(BULB)
    cams = _frames_from_below()
    meeting = frames_meeting(measuring_sightings(BULB, 0.1, cams, _measured(truth, cams),
                                                 [None, None], Y709, WHITE))
    assert meeting is not None
    rng = np.random.default_rng(1)
    lobes = []
    for cam in cams:
        sight = BULB - cam.center
        sight /= np.linalg.norm(sight)
        depth = (BULB[1] - 0.1 - cam.center[1]) / sight[1]  # where it crosses 0.1 m lower
        lobes.append(cam.center + depth * sight + rng.normal(0.0, 0.01, (20, 3)))
    lobes = np.concatenate(lobes)
    angle = np.linspace(0.0, 2 * np.pi, 30, endpoint=False)
    glow = BULB + np.column_stack([0.11 * np.cos(angle), np.full(30, -0.1),
                                   0.11 * np.sin(angle)])
    pos = np.concatenate([lobes, glow])
    lum = np.concatenate([np.full(len(lobes), meeting.peak),
                          np.full(len(glow), 0.5 * BULB_SHARE * meeting.peak)])
    fit = SplatScene.from_activated(pos, np.repeat(lum[:, None], 3, axis=1),
                                    np.full((len(pos), 3), 0.01), np.full(len(pos), 0.5))
    moved, info, bulb_rows = moved_to_meeting(fit, np.arange(len(pos)), meeting, Y709)
    np.testing.assert_array_equal(bulb_rows, np.arange(len(lobes)))
    assert info.moved == len(lobes)
    assert info.shift == pytest.approx(0.1, abs=0.02)
    bulb = moved.positions[:len(lobes)]
    assert np.linalg.norm(bulb.mean(axis=0) - BULB) < 0.01
    assert np.linalg.norm(bulb - BULB, axis=1).max() < 3 * meeting.radius
    np.testing.assert_array_equal(moved.positions[len(lobes):], fit.positions[len(lobes):])


def test_one_frame_puts_the_bulb_where_its_line_passes_the_seed_and_draws_the_streak_in():
    """One darker frame 2.5 m off cannot say how far along its line the bulb is; the
    photos' seed, placed from places apart, can. The fit's streak along the frame's line
    (what the frame sees as one bulb) is drawn onto it."""
    eye = BULB + np.array([2.4, -0.7, 0.3])
    cam = aimed_camera(eye, BULB, 0.6, SIZE)
    seed = BULB + np.array([0.0, 0.02, 0.015])  # the seed a couple of cm off
    sightings = measuring_sightings(seed, 0.05, [cam], _measured(_bulb_under_a_ceiling(BULB),
                                                                [cam]), [None], Y709, WHITE)
    assert len(sightings) == 1 and frames_meeting(sightings) is None
    meeting = frame_and_seed(sightings, seed, 0.05)
    assert meeting is not None and meeting.views == [0]
    assert np.linalg.norm(meeting.position - BULB) < 0.025
    sight = (BULB - eye) / np.linalg.norm(BULB - eye)
    along = np.linspace(-0.15, 0.15, 31)
    streak = BULB + along[:, None] * sight
    fit = SplatScene.from_activated(streak, np.full((len(streak), 3), meeting.peak),
                                    np.full((len(streak), 3), 0.01), np.full(len(streak), 0.3))
    moved, info, rows = moved_to_meeting(fit, np.arange(len(streak)), meeting, Y709)
    assert info.moved == len(streak)
    # drawn in to the radius the frame measured (its blob's, a few pixels: 6 cm here),
    # each axis to a ball's share of it: along the line as far as across it
    rel = moved.positions - meeting.position
    along = rel @ sight
    assert meeting.radius < 0.07
    assert np.sqrt(np.mean(along ** 2)) == pytest.approx(meeting.radius / np.sqrt(3.0), rel=0.02)
    assert np.sqrt(np.mean(np.sum(rel ** 2, axis=1))) <= meeting.radius
    # a seed farther off the frame's line than its size is some other light
    assert frame_and_seed(sightings, BULB + np.array([0.0, 0.2, 0.0]), 0.05) is None
    assert frame_and_seed([], seed, 0.05) is None


def test_where_nothing_clipped_the_views_that_saw_only_a_shades_glow_do_not_place_it():
    """True HDR views: two from below see the bulb (2,000), two level ones only the glow
    at the shade's opening 12 cm under it (a tenth as bright). All four measured the
    light; their lines meet nowhere near the bulb. Kept to the views that read it
    brightest (the frames from below), they meet at the bulb."""
    below = _frames_from_below()
    glow_at = BULB + np.array([0.05, -0.12, 0.0])
    glow = _bulb_under_a_ceiling(glow_at)
    glow = SplatScene.from_activated(glow.positions, np.where(
        glow.base_colours > 100.0, 200.0, glow.base_colours), glow.scales * np.where(
        glow.base_colours[:, :1] > 100.0, 2.0, 1.0), glow.opacities,
        metadata={"antialiased": True})
    level = [aimed_camera(glow_at + np.array([dx, -0.35, 1.3]), glow_at, 0.6, SIZE)
             for dx in (-0.8, 0.8)]
    images = _measured(_bulb_under_a_ceiling(BULB), below) + _measured(glow, level)
    sightings = measuring_sightings(BULB, 0.1, below + level, images, [None] * 4, Y709,
                                    WHITE)
    assert [s.view for s in sightings] == [0, 1, 2, 3]
    everyone = frames_meeting(sightings)
    assert everyone is None or np.linalg.norm(everyone.position - BULB) > 0.03
    brightest = bulb_sightings(sightings)
    assert [s.view for s in brightest] == [0, 1]
    meeting = frames_meeting(brightest)
    assert meeting is not None and np.linalg.norm(meeting.position - BULB) < 0.01
    # a bare bulb every view read alike keeps every view
    assert bulb_sightings(sightings[:2]) == sightings[:2]
