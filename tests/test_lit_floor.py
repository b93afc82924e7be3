"""A floor the sparse points miss, found where the views' lit patch on it agrees.

A room 5 x 3 x 4 m (floor y = 0): the sparse points lie on its walls from 0.3 m up (a
plain floor has none), a sunlit patch 0.9 x 0.8 m lies on the floor, and six cameras
1.2-1.6 m up look down at it. Each view's lit mask is where its rays meet the patch,
as a photo that clipped it shows it.
"""

from __future__ import annotations

import numpy as np
from test_flat_outlines import look_at

from gaslight_usd.fit.init import above_floor, surface_fill_points
from gaslight_usd.fit.lit_floor import find_lit_floor, floor_plane, room_vertical
from gaslight_usd.fit.planes import Plane

PATCH = (np.array([-0.45, 0.05]), np.array([0.45, 0.85]))  # x, z ranges on the floor
UP = np.array([0.0, 1.0, 0.0])


def patch_mask(cam, height: float = 0.0) -> np.ndarray:
    """Where ``cam``'s pixel rays meet the patch on the plane y = ``height``."""
    dirs = cam.ray_directions()
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (height - cam.center[1]) / np.where(dirs[..., 1] < -1e-6, dirs[..., 1], np.nan)
        hit = cam.center + dirs * t[..., None]
        return ((hit[..., 0] >= PATCH[0][0]) & (hit[..., 0] <= PATCH[1][0])
                & (hit[..., 2] >= PATCH[0][1]) & (hit[..., 2] <= PATCH[1][1]))


def cameras():
    target = [0.0, 0.0, 0.45]
    return [look_at(c, target) for c in
            ([-1.5, 1.5, -1.2], [1.2, 1.3, -1.5], [-0.3, 1.6, -1.8], [1.8, 1.2, 0.2],
             [-1.9, 1.4, 1.0], [0.5, 1.5, 2.0])]


def wall_points(rng: np.random.Generator, lowest: float = 0.3) -> np.ndarray:
    """Points on the room's four walls from ``lowest`` up to the 3 m ceiling."""
    n = 400
    y = rng.uniform(lowest, 3.0, n)
    side = rng.integers(0, 4, n)
    along = rng.uniform(-1.0, 1.0, n)
    x = np.where(side == 0, -2.5, np.where(side == 1, 2.5, along * 2.5))
    z = np.where(side == 2, -2.0, np.where(side == 3, 2.0, along * 2.0))
    return np.stack([x, y, z], 1)


def test_the_floor_is_where_the_views_outlines_of_the_patch_agree():
    cams = cameras()
    found = find_lit_floor(cams, [patch_mask(c) for c in cams], UP,
                           wall_points(np.random.default_rng(0)))
    assert found is not None
    assert abs(found.offset) < 0.02
    np.testing.assert_allclose(found.normal, UP)
    # its lit cells are the patch, each seen lit by the views that framed it
    inside = ((found.points[:, [0, 2]] >= PATCH[0] - 0.05)
              & (found.points[:, [0, 2]] <= PATCH[1] + 0.05)).all(1)
    assert inside.mean() > 0.95 and len(found.points) > 100
    assert found.seen.shape == (len(cams), len(found.points))
    assert found.seen.sum(0).min() >= 2


def test_no_lit_patch_no_floor_and_a_lit_desk_over_the_floors_points_is_none():
    cams = cameras()
    points = wall_points(np.random.default_rng(1))
    assert find_lit_floor(cams, [np.zeros((120, 160), bool) for _ in cams], UP, points) is None
    # the patch on a desk 0.75 m up, with the floor's own points under it
    floor = np.random.default_rng(2).uniform([-2.4, 0.0, -1.9], [2.4, 0.0, 1.9], (100, 3))
    desk = [patch_mask(c, 0.75) for c in cams]
    assert find_lit_floor(cams, desk, UP, np.concatenate([points, floor])) is None


def test_the_rooms_vertical_is_the_points_planes_not_the_cameras_lean():
    points = wall_points(np.random.default_rng(3), lowest=0.0)
    leaning = np.array([0.05, 1.0, 0.03])
    vertical = room_vertical(points, leaning, np.random.default_rng(4))
    assert vertical @ UP > np.cos(np.radians(0.5))


def test_the_box_takes_the_floor_only_where_it_has_none():
    cams = cameras()
    points = wall_points(np.random.default_rng(5))
    found = find_lit_floor(cams, [patch_mask(c) for c in cams], UP, points)
    plane = floor_plane(found, [], points)
    assert plane is not None and abs(plane.offset - found.offset) < 1e-9
    assert np.all(plane.hi - plane.lo > 3.5)  # across the room, from the walls' points
    existing = Plane(UP.copy(), 0.01, np.zeros(2), np.ones(2), np.eye(3)[[0, 2]], 50)
    assert floor_plane(found, [existing], points) is None
    assert floor_plane(None, [], points) is None


def test_nothing_is_filled_under_the_floor():
    cams = cameras()
    points = wall_points(np.random.default_rng(6))
    found = find_lit_floor(cams, [patch_mask(c) for c in cams], UP, points)
    eye = cams[0].center
    under = np.array([[0.0, -0.8, 0.4], [1.0, 0.5, 0.0]])
    moved = above_floor(eye, under, found)
    assert abs(moved[0, 1] - found.offset) < 1e-9  # back up its ray onto the floor
    ray = (under[0] - eye) / np.linalg.norm(under[0] - eye)
    np.testing.assert_allclose((moved[0] - eye) / np.linalg.norm(moved[0] - eye), ray)
    np.testing.assert_allclose(moved[1], under[1])  # above it: left alone
    # a point hanging in front of the patch, on a ray that meets the floor where the
    # view saw the patch lit, goes onto the floor; elsewhere it stays
    on_patch = np.array([0.0, 0.0, 0.45])
    hanging = eye + 0.6 * (on_patch - eye)
    np.testing.assert_allclose(above_floor(eye, hanging[None], found, 0)[0], on_patch,
                               atol=0.02)
    np.testing.assert_allclose(above_floor(eye, hanging[None], found)[0], hanging)
    off_patch = eye + 0.6 * (np.array([-1.5, 0.0, -0.5]) - eye)
    np.testing.assert_allclose(above_floor(eye, off_patch[None], found, 0)[0], off_patch)
    # the fill: the walls' points carried down put floor pixels under it; with the
    # floor as a bound none is, and the patch's pixels lie on it
    images = [np.full((120, 160, 3), 0.5, np.float32) for _ in cams]
    rng = np.random.default_rng(7)
    before, _ = surface_fill_points(points, None, cams, images, 3000, rng)
    after, _ = surface_fill_points(points, None, cams, images, 3000,
                                   np.random.default_rng(7), room_floor=found)
    assert (before[:, 1] < -0.05).mean() > 0.05
    assert (after[:, 1] < found.offset - 1e-6).sum() == 0
    on = ((after[:, [0, 2]] > PATCH[0] + 0.05) & (after[:, [0, 2]] < PATCH[1] - 0.05)).all(1)
    assert (on & (np.abs(after[:, 1] - found.offset) < 1e-6)).sum() > 50
    assert (on & (np.abs(before[:, 1]) < 1e-6)).sum() == 0


def test_the_starts_splats_on_the_floor_are_discs_lying_on_it():
    import torch

    from gaslight_usd.fit.lit_floor import floor_discs
    from gaslight_usd.render.project import quat_to_rotmat

    cams = cameras()
    found = find_lit_floor(cams, [patch_mask(c) for c in cams], UP,
                           wall_points(np.random.default_rng(8)))
    points = np.array([[0.0, found.offset, 0.4], [1.0, found.offset + 0.004, -1.0],
                       [0.0, 0.5, 0.0], [2.5, 1.0, 0.0]])
    on, quat = floor_discs(points, found, 0.005)
    assert on.tolist() == [0, 1]
    # the splat's z axis (the one the trainer shrinks) turned to the floor's normal
    axes = quat_to_rotmat(torch.as_tensor(quat[None], dtype=torch.float64))[0].numpy()
    np.testing.assert_allclose(axes[:, 2], found.normal, atol=1e-9)
    assert floor_discs(points, None, 0.005)[0].size == 0


def floor_radiance(cam) -> np.ndarray:
    """(H, W) radiance the view sees: the patch at 50, the floor round it lit less the
    farther from it (3 at its edge, falling by e over 0.3 m), the walls at 0.3."""
    dirs = cam.ray_directions()
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -cam.center[1] / np.where(dirs[..., 1] < -1e-6, dirs[..., 1], np.nan)
        hit = cam.center + dirs * t[..., None]
    xz = np.nan_to_num(hit[..., [0, 2]], nan=1e3)
    gap = np.linalg.norm(np.maximum(np.maximum(PATCH[0] - xz, xz - PATCH[1]), 0.0), axis=-1)
    floor = np.where(gap == 0.0, 50.0, 3.0 * np.exp(-gap / 0.3))
    return np.where(np.isfinite(t), floor, 0.3)


def test_two_darker_frames_are_swept_alone_one_falls_back_to_every_view():
    """Photos exposed for the room clip the patch and as much of the lit floor round it
    as passed each one's white (0.5-1.6): outlines of different sizes. Two darker frames
    aimed at the patch from two places measure it whole, and the floor is swept on
    theirs alone; one frame pins no depth, and every view's outlines are swept."""
    from gaslight_usd.fit.lit_floor import views_lit_floor

    cams = cameras()
    weights = np.array([0.2126, 0.7152, 0.0722])
    whites = [0.5, 0.8, 1.6, 0.6, 1.0, 1.2]
    radiance = [floor_radiance(c) for c in cams]
    photos = [np.repeat(np.minimum(r, w)[..., None], 3, 2).astype(np.float32)
              for r, w in zip(radiance, whites, strict=True)]
    floors = [np.where(r >= w, w, 0.0).astype(np.float32)
              for r, w in zip(radiance, whites, strict=True)]
    points = wall_points(np.random.default_rng(3))
    frames = [cams[0], cams[3]]  # two darker frames, beside the first and fourth photos
    dark = [np.repeat(radiance[k][..., None], 3, 2).astype(np.float32) for k in (0, 3)]
    views, images = cams + frames, photos + dark
    found = views_lit_floor(views, images, floors + [None, None], [False] * 6 + [True] * 2,
                            weights, UP, points)
    assert found is not None and abs(found.offset) < 0.02
    assert not found.seen[:6].any() and found.seen[6:].all(axis=0).mean() > 0.9
    inside = ((found.points[:, [0, 2]] >= PATCH[0] - 0.03)
              & (found.points[:, [0, 2]] <= PATCH[1] + 0.03)).all(1)
    assert inside.all()  # the patch, not the lit floor round it
    one = views_lit_floor(views[:7], images[:7], floors + [None], [False] * 6 + [True],
                          weights, UP, points)
    assert one is not None and one.seen[:6].any()
