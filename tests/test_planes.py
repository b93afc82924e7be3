"""The plane prior (:mod:`gaslight_usd.fit.planes`): a room's planes found from smeared
points, slices through the room refused, held splats put back on their planes."""

from dataclasses import asdict

import numpy as np
import pytest
import torch

from gaslight_usd.fit.planes import (
    Plane,
    PlanePrior,
    ceiling_at_sparse_points,
    ceiling_from_walls,
    far_walls,
    find_planes,
    on_a_plane,
    room_box,
    sparse_axes,
)

ROOM_LO, ROOM_HI = np.array([-2.5, 0.0, -2.0]), np.array([2.5, 3.0, 2.0])


def room_points(rng, per_face=400, smear=0.02, junk=300):
    """Points on a 5 x 3 x 4 m room's six faces (Gaussian smear along the normal), plus
    junk scattered through the room (the fill's stray points)."""
    pts = []
    for axis in range(3):
        for value in (ROOM_LO[axis], ROOM_HI[axis]):
            p = rng.uniform(ROOM_LO, ROOM_HI, (per_face, 3))
            p[:, axis] = value + rng.normal(0, smear, per_face)
            pts.append(p)
    pts.append(rng.uniform(ROOM_LO, ROOM_HI, (junk, 3)))
    return np.concatenate(pts)


def cameras_inside(rng, n=12):
    return rng.uniform([-1.0, 1.2, -1.0], [1.0, 1.6, 1.0], (n, 3))


def test_finds_a_rooms_six_faces_through_the_smear():
    rng = np.random.default_rng(0)
    # the room turned 20 deg about the vertical: the directions come from the points
    yaw = np.radians(20)
    rot = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
    pts = room_points(rng) @ rot.T
    planes, tau = find_planes(pts, cameras_inside(rng) @ rot.T, rng)
    assert len(planes) == 6
    # (room axis, where along it): n . x = offset with n along that axis
    found = [(a, float(p.offset / (p.normal @ rot[:, a])))
             for p in planes for a in range(3) if abs(p.normal @ rot[:, a]) > 0.99]
    assert len(found) == 6
    assert sorted(a for a, _ in found) == [0, 0, 1, 1, 2, 2]
    for axis, offset in found:
        truth = min((ROOM_LO[axis], ROOM_HI[axis]), key=lambda v: abs(v - offset))
        assert offset == pytest.approx(truth, abs=0.01)
    for plane in planes:  # normals face the cameras
        assert plane.normal @ (np.array([0, 1.4, 0]) @ rot.T) - plane.offset > 0


def test_the_fills_lean_does_not_tilt_the_planes_the_sparse_points_square():
    """The start's fill, leaning 3 degrees about z (its depth errors, the uplifted
    photos'), outnumbers the triangulated points 5 to 1: planes found in all the points
    along their own directions lean with it; along the sparse points' directions they are
    square and where the faces are."""
    rng = np.random.default_rng(3)
    sparse = room_points(rng, per_face=80, smear=0.005, junk=0)
    lean = np.radians(3.0)
    turn = np.array([[np.cos(lean), -np.sin(lean), 0], [np.sin(lean), np.cos(lean), 0],
                     [0, 0, 1]])
    centre = (ROOM_LO + ROOM_HI) / 2
    fill = (room_points(rng, per_face=400, smear=0.02, junk=100) - centre) @ turn.T + centre
    points = np.concatenate([sparse, fill])
    cams = cameras_inside(rng)

    def worst_tilt(planes):
        return max(np.degrees(np.arccos(np.abs(p.normal).max())) for p in planes)

    leaning, _ = find_planes(points, cams, np.random.default_rng(0))
    assert worst_tilt(leaning) > 2.0
    axes = sparse_axes(sparse, np.random.default_rng(0))
    assert axes is not None and np.allclose(np.abs(axes).max(axis=1), 1.0, atol=1e-3)
    square, _ = find_planes(points, cams, np.random.default_rng(0), axes)
    assert len(square) >= 5 and worst_tilt(square) < 0.3
    for plane in square:
        axis = int(np.argmax(np.abs(plane.normal)))
        value = plane.offset / plane.normal[axis]
        truth = min((ROOM_LO[axis], ROOM_HI[axis]), key=lambda v: abs(v - value))
        assert value == pytest.approx(truth, abs=0.06)
    assert sparse_axes(sparse[:20], np.random.default_rng(0)) is None


def test_a_slice_through_the_room_is_not_a_plane():
    """Box tops at one height across the room crowd like a plane, but the floor lies
    behind them: refused (and the floor, the ceiling are still found)."""
    rng = np.random.default_rng(1)
    pts = room_points(rng)
    tops = rng.uniform(ROOM_LO, ROOM_HI, (300, 3))
    tops[:, 1] = 0.9 + rng.normal(0, 0.01, 300)
    planes, _ = find_planes(np.concatenate([pts, tops]), cameras_inside(rng), rng)
    heights = sorted(abs(p.offset) for p in planes if abs(p.normal[1]) > 0.99)
    assert heights == pytest.approx([0.0, 3.0], abs=0.02)


def test_a_plain_ceiling_is_held_and_a_table_top_is_not():
    """A ceiling the points barely see (its fill scattered behind it, more than it holds)
    is held where the walls stop at it; a table top over the floor's fill is refused,
    the walls going on below it."""
    rng = np.random.default_rng(7)
    faces = []
    for axis in (0, 2):  # four walls, floor to ceiling
        for value in (ROOM_LO[axis], ROOM_HI[axis]):
            p = rng.uniform(ROOM_LO, ROOM_HI, (400, 3))
            p[:, axis] = value + rng.normal(0, 0.01, 400)
            faces.append(p)
    ceiling = rng.uniform(ROOM_LO, ROOM_HI, (200, 3))
    ceiling[:, 1] = 3.0 + rng.normal(0, 0.01, 200)
    smear = rng.uniform(ROOM_LO, ROOM_HI, (400, 3))
    smear[:, 1] = rng.uniform(3.05, 3.5, 400)  # the fill, behind the ceiling
    table = rng.uniform([-1.2, 0, -1.0], [1.2, 0, 1.0], (200, 3))
    table[:, 1] = 0.6 + rng.normal(0, 0.01, 200)
    under = rng.uniform([-1.2, 0.0, -1.0], [1.2, 0.5, 1.0], (300, 3))  # the floor's fill
    points = np.concatenate(faces + [ceiling, smear, table, under])
    planes, _ = find_planes(points, cameras_inside(rng), rng)
    level = [p for p in planes if abs(p.normal[1]) > 0.99]
    assert len(level) == 1
    assert level[0].normal[1] < 0 and -level[0].offset == pytest.approx(3.0, abs=0.02)
    assert len(planes) == 5


def _plane(normal, offset, points=500) -> Plane:
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.cross(normal, [0.0, 0.0, 1.0] if abs(normal[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    return Plane(normal, offset, np.array([-2.0, -2.0]), np.array([2.0, 2.0]),
                 np.stack([u, np.cross(normal, u)]), points)


def test_the_room_box_is_its_strong_planes_square_to_two_facing_walls():
    """What bounds a sunk light's move: the room's six faces pass; a plane leaning 30 deg
    off them, or one holding too few points, does not."""
    rng = np.random.default_rng(3)
    pts = room_points(rng)
    planes, _ = find_planes(pts, cameras_inside(rng), rng)
    tilted = _plane([np.sin(np.radians(30)), -np.cos(np.radians(30)), 0.0], -2.5)
    weak = _plane([0.0, -1.0, 0.0], -2.0, points=30)
    box = room_box(planes + [tilted, weak], len(pts))
    assert len(box) == 6 and all(any(p is q for q in planes) for p in box)


def _no_ceiling(rng, wall_tops=(3.0, 3.0, 3.0, 3.0), per_face=400, smear=0.02):
    """A room's points with no ceiling among them (a ceiling few photos see, smeared
    beyond what crowds like a plane), each wall's points up to its ``wall_tops``."""
    pts = []
    floor = rng.uniform(ROOM_LO, ROOM_HI, (per_face, 3))
    floor[:, 1] = ROOM_LO[1] + rng.normal(0, smear, per_face)
    pts.append(floor)
    walls = [(0, ROOM_LO[0]), (0, ROOM_HI[0]), (2, ROOM_LO[2]), (2, ROOM_HI[2])]
    for (axis, value), top in zip(walls, wall_tops, strict=True):
        p = rng.uniform(ROOM_LO, [ROOM_HI[0], top, ROOM_HI[2]], (per_face, 3))
        p[:, axis] = value + rng.normal(0, smear, per_face)
        pts.append(p)
    return np.concatenate(pts)


def test_a_box_without_its_ceiling_gets_one_where_its_walls_stop():
    rng = np.random.default_rng(5)
    pts = _no_ceiling(rng)
    planes, tau = find_planes(pts, cameras_inside(rng), rng)
    box = room_box(planes, len(pts))
    assert box and not any(p.normal[1] < -0.99 for p in box)
    ceiling = ceiling_from_walls(box, pts, tau, np.array([0.05, 1.0, 0.0]))
    assert ceiling is not None
    assert ceiling.normal @ np.array([0.0, -1.0, 0.0]) > 0.999  # facing down, at the cameras
    assert -ceiling.offset == pytest.approx(3.0, abs=0.2)  # the walls' 95 % (2.85)
    # a ray from a camera up through it stops there
    ratio = ceiling.crossing(np.array([[0.0, 1.5, 0.0]]), np.array([[0.5, 4.5, 0.5]]))[0]
    assert 1.5 + 3.0 * ratio == pytest.approx(-ceiling.offset, abs=0.01)
    # a box with its ceiling, or no up, gets none
    full = room_points(rng)
    planes_full, tau_full = find_planes(full, cameras_inside(rng), rng)
    assert ceiling_from_walls(room_box(planes_full, len(full)), full, tau_full,
                              np.array([0.0, 1.0, 0.0])) is None
    assert ceiling_from_walls(box, pts, tau, np.zeros(3)) is None


def _box_with_a_low_ceiling(rng):
    """A room's box as the start's points gave it, its ceiling 12 cm low (the fill's
    smear crowded there), and the sparse points: each wall's up to the ceiling, 20 on
    the ceiling itself (3.0 m, 1 cm noise)."""
    walls = [_plane([1.0, 0.0, 0.0], -2.5), _plane([-1.0, 0.0, 0.0], -2.5),
             _plane([0.0, 0.0, 1.0], -2.0), _plane([0.0, 0.0, -1.0], -2.0)]
    box = [*walls, _plane([0.0, 1.0, 0.0], 0.0), _plane([0.0, -1.0, 0.0], -2.88)]
    sparse = []
    for axis, value in ((0, -2.5), (0, 2.5), (2, -2.0), (2, 2.0)):
        p = rng.uniform(ROOM_LO, ROOM_HI, (100, 3))
        p[:, axis] = value
        p[:, 1] = rng.uniform(2.0, 2.9, 100)  # the walls' tops, near the low ceiling
        sparse.append(p)
    top = rng.uniform([-1.8, 3.0, -1.4], [1.8, 3.0, 1.4], (20, 3))
    top[:, 1] += rng.normal(0.0, 0.01, 20)
    return box, np.concatenate(sparse), top


def test_a_ceiling_found_low_in_the_fill_is_put_at_the_sparse_points_on_it():
    rng = np.random.default_rng(8)
    box, walls, ceiling = _box_with_a_low_ceiling(rng)
    up, tau = np.array([0.05, 1.0, 0.0]), 0.07
    moved = ceiling_at_sparse_points(box, np.concatenate([walls, ceiling]), tau, up)
    assert -moved[-1].offset == pytest.approx(3.0, abs=0.01)
    np.testing.assert_array_equal(moved[-1].normal, box[-1].normal)
    # the walls and the floor are left as found
    assert all(a is b for a, b in zip(moved[:-1], box[:-1], strict=True))
    # the walls' own points near the ceiling are not the ceiling: without the points on
    # the ceiling itself, or with too few of them, or without an up, it stays
    for sparse in (walls, np.concatenate([walls, ceiling[:5]])):
        assert ceiling_at_sparse_points(box, sparse, tau, up)[-1].offset == -2.88
    assert ceiling_at_sparse_points(box, np.concatenate([walls, ceiling]), tau,
                                    np.zeros(3))[-1].offset == -2.88


def _room_with_a_window_wall(rng, window_wall_points: int, through_window: int = 0):
    """The room's points with its x+ wall (a large window in it) holding only
    ``window_wall_points``, and ``through_window`` more scattered up to 0.5 m behind it
    where the window is (the fill of the window's pixels, at its neighbours' depths)."""
    pts = room_points(rng, per_face=400, smear=0.02, junk=600)
    on_far = np.abs(pts[:, 0] - ROOM_HI[0]) < 0.1
    keep = ~on_far
    keep[np.flatnonzero(on_far)[:window_wall_points]] = True
    behind = np.column_stack([ROOM_HI[0] + rng.uniform(0.05, 0.5, through_window),
                              rng.uniform(1.0, 2.2, through_window),
                              rng.uniform(-1.0, 1.0, through_window)])
    return np.concatenate([pts[keep], behind])


def test_a_window_wall_refused_for_what_it_hides_is_added_to_the_room_box():
    """The window's wall hides the fill seen through the window, so it is no plane
    (:data:`MAX_BEHIND`); beyond the cameras the points still crowd most there, and the
    box gets it back, facing the cameras. A box with all its walls gets nothing more."""
    rng = np.random.default_rng(5)
    pts = _room_with_a_window_wall(rng, 150, through_window=400)
    cams = cameras_inside(rng)
    planes, tau = find_planes(pts, cams, rng)
    box = room_box(planes, len(pts))
    assert not any(p.normal[0] < -0.99 for p in box)  # the x+ wall is missing
    added = far_walls(box, pts, cams, tau, np.array([0.0, 1.0, 0.0]))
    assert len(added) == 1
    wall = added[0]
    assert wall.normal[0] < -0.99  # faces the cameras, back into the room
    assert -wall.offset == pytest.approx(ROOM_HI[0], abs=0.03)
    assert np.all(cams @ wall.normal - wall.offset > 0)
    whole = room_points(np.random.default_rng(6))
    planes, tau = find_planes(whole, cams, np.random.default_rng(6))
    assert far_walls(room_box(planes, len(whole)), whole, cams, tau,
                     np.array([0.0, 1.0, 0.0])) == []


def test_a_window_wall_is_added_where_the_box_has_neither_wall_of_that_direction():
    """The hall with a dark frame of its window: neither end wall is a plane (the x- side
    here is open, only the fill's scatter), so the direction has no wall to face. Square
    to the walls found, the window's side still crowds and gets its wall, facing the
    cameras and spanning the room; the open side gets none."""
    rng = np.random.default_rng(5)
    pts = _room_with_a_window_wall(rng, 80, through_window=200)
    pts = pts[np.abs(pts[:, 0] - ROOM_LO[0]) > 0.1]  # no x- wall either
    cams = cameras_inside(rng)
    planes, tau = find_planes(pts, cams, rng)
    box = room_box(planes, len(pts))
    assert not any(abs(p.normal[0]) > 0.99 for p in box)  # no wall along x at all
    added = far_walls(box, pts, cams, tau, np.array([0.0, 1.0, 0.0]))
    assert len(added) == 1
    wall = added[0]
    assert wall.normal[0] < -0.99
    assert -wall.offset == pytest.approx(ROOM_HI[0], abs=0.03)
    assert np.all(cams @ wall.normal - wall.offset > 0)
    # its patch spans the room's width and height (a ray to the window's middle crosses it)
    ratio = wall.crossing(cams[:1], np.array([[4.0, 1.5, 0.0]]))[0]
    assert np.isfinite(ratio)


def test_no_far_wall_where_nothing_crowds_beyond_the_cameras():
    """An open side (no wall, only the fill's scatter past the cameras) gets no wall."""
    rng = np.random.default_rng(7)
    pts = _room_with_a_window_wall(rng, 0)
    cams = cameras_inside(rng)
    planes, tau = find_planes(pts, cams, rng)
    box = room_box(planes, len(pts))
    assert far_walls(box, pts, cams, tau, np.array([0.0, 1.0, 0.0])) == []


def test_no_far_wall_where_the_points_only_thin_away_from_the_cameras():
    """Furniture just past the cameras crowds the first bins beyond them, and thins out
    from there: no wall (``bulb:11`` with dark frames had one put 0.7 m inside the room so).
    A wall is a crowd that rises over the bins between the cameras and it."""
    rng = np.random.default_rng(7)
    pts = _room_with_a_window_wall(rng, 0)
    cams = cameras_inside(rng)
    ramp = np.column_stack([cams[:, 0].max() + 0.1 + rng.exponential(0.25, 300),
                            rng.uniform(0.0, 1.0, 300), rng.uniform(-2.0, 2.0, 300)])
    pts = np.concatenate([pts, ramp])
    planes, tau = find_planes(pts, cams, rng)
    box = room_box(planes, len(pts))
    assert not any(p.normal[0] < -0.99 for p in box)
    assert far_walls(box, pts, cams, tau, np.array([0.0, 1.0, 0.0])) == []


def test_walls_that_stop_at_different_heights_make_no_ceiling():
    rng = np.random.default_rng(6)
    pts = _no_ceiling(rng, wall_tops=(3.0, 1.8, 3.0, 1.8))
    planes, tau = find_planes(pts, cameras_inside(rng), rng)
    box = room_box(planes, len(pts))
    assert box
    assert ceiling_from_walls(box, pts, tau, np.array([0.0, 1.0, 0.0])) is None


def test_a_ray_crosses_a_planes_patch_from_its_front_only():
    ceiling = Plane(np.array([0.0, -1.0, 0.0]), -3.0, np.array([-2.5, -2.0]),
                    np.array([2.5, 2.0]), np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), 500)
    eye = np.array([[0.0, 1.5, 0.0]] * 4)
    targets = np.array([[0.8, 4.0, 0.5],   # up through the ceiling: 1.5 of its 2.5 m rise
                        [0.8, 2.0, 0.5],   # stops short of it
                        [0.0, 0.0, 0.0],   # down, away from it
                        [9.0, 4.0, 0.0]])  # crosses the plane outside the patch
    np.testing.assert_allclose(ceiling.crossing(eye, targets), [0.6, 3.0, np.inf, np.inf])
    above = np.array([[0.0, 3.5, 0.0]])  # behind the plane: no crossing from its front
    assert ceiling.crossing(above, np.array([[0.0, 5.0, 0.0]]))[0] == np.inf
    again = Plane(**asdict(ceiling))  # a checkpoint's copy
    np.testing.assert_array_equal(again.crossing(eye, targets), ceiling.crossing(eye, targets))


def test_a_light_flush_with_a_planes_patch_is_on_it_and_a_bulb_before_a_wall_is_not():
    """A measured ceiling panel is the plane's light (the floater rule may put its splats
    back on it); a bulb 0.9 m under it, or a point past the patch's edge, is not on it."""
    ceiling = Plane(np.array([0.0, -1.0, 0.0]), -3.0, np.array([-2.5, -2.0]),
                    np.array([2.5, 2.0]), np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), 500)
    assert on_a_plane(np.array([-1.2, 3.02, -0.6]), 0.5, [ceiling])
    assert on_a_plane(np.array([-1.2, 2.98, -0.6]), 0.05, [ceiling])
    assert not on_a_plane(np.array([1.2, 2.1, 1.1]), 0.1, [ceiling])
    assert not on_a_plane(np.array([4.0, 3.0, 0.0]), 0.1, [ceiling])
    assert not on_a_plane(np.array([0.0, 3.0, 0.0]), 0.1, [])


def test_splats_whose_reach_touches_a_planes_patch_are_on_it():
    """A ceiling splat, one 0.1 m under it that reaches it (3 sigma 0.15 m), one as far
    that does not, and one in the ceiling's plane past the patch's edge."""
    from gaslight_usd.fit.planes import on_planes
    from gaslight_usd.splats import SplatScene

    ceiling = Plane(np.array([0.0, -1.0, 0.0]), -3.0, np.array([-2.5, -2.0]),
                    np.array([2.5, 2.0]), np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), 500)
    pos = np.array([[0.0, 3.0, 0.0], [1.0, 2.9, 0.5], [1.0, 2.9, 0.5], [4.0, 3.0, 0.0]])
    scales = np.array([[0.02] * 3, [0.05] * 3, [0.02] * 3, [0.02] * 3])
    scene = SplatScene.from_activated(pos, np.full((4, 3), 0.5), scales, np.full(4, 0.9))
    assert on_planes(scene, [ceiling]).tolist() == [True, True, False, False]
    assert not on_planes(scene, []).any()


@pytest.mark.parametrize("normals", [[[0.67, -0.2, 0.71]], [[1, 0, 0], [0, 1, 0]],
                                     [[1, 0, 0], [1, 0, 0.05]]])
def test_no_two_facing_walls_no_room_box(normals):
    """One diagonal plane (``shade:7``'s from photos), two square ones, or two walls on
    the same side: nothing bounds."""
    planes = [_plane(n, -2.0) for n in normals]
    assert room_box(planes, 4000) == []


def test_cameras_on_both_sides_make_no_plane():
    rng = np.random.default_rng(2)
    pts = rng.uniform(-1, 1, (1500, 3))
    pts[:800, 0] = rng.normal(0, 0.005, 800)  # a dense sheet x = 0
    cams = np.array([[-0.8, 0, 0], [0.8, 0, 0], [-0.5, 0.3, 0], [0.5, -0.3, 0.1]])
    planes, _ = find_planes(pts, cams, rng)
    assert not [p for p in planes if abs(p.normal[0]) > 0.99]


def test_too_few_points_make_no_planes():
    planes, tau = find_planes(np.zeros((10, 3)), np.zeros((2, 3)), np.random.default_rng(0))
    assert planes == [] and tau == 0.0


def test_prior_puts_held_splats_on_their_plane_and_leaves_the_rest():
    rng = np.random.default_rng(3)
    planes, tau = find_planes(room_points(rng), cameras_inside(rng), rng)
    prior = PlanePrior(planes, tau)
    means = torch.tensor([[0.3, 2.95, 0.2],    # 5 cm under the ceiling: held
                          [0.3, 1.50, 0.2],    # mid-room: free
                          [2.45, 1.0, 0.5],    # 5 cm off the wall x = 2.5: held
                          [9.0, 2.98, 9.0],    # under the ceiling's plane, off its patch
                          [-1.0, 3.25, 0.5],   # 25 cm behind the ceiling (a sunk light)
                          [-1.0, 2.60, 0.5],   # 40 cm under it: free
                          [-1.0, 3.60, 0.5]],  # 60 cm behind it: too far to say
                         dtype=torch.float32)
    prior.assign(means)
    assert [m >= 0 for m in prior.member.tolist()] == [True, False, True, False, True, False,
                                                       False]
    before = means.clone()
    prior.snap(means)
    assert float(means[0, 1]) == pytest.approx(3.0, abs=0.02)
    assert float(means[2, 0]) == pytest.approx(2.5, abs=0.02)
    assert float(means[4, 1]) == pytest.approx(3.0, abs=0.02)
    for free in (1, 3, 5, 6):
        assert torch.equal(means[free], before[free])


def test_flatness_is_a_held_splats_thickness_along_its_plane():
    rng = np.random.default_rng(4)
    planes, tau = find_planes(room_points(rng), cameras_inside(rng), rng)
    prior = PlanePrior(planes, tau)
    prior.assign(torch.tensor([[0.0, 2.99, 0.0]]))
    ceiling = planes[int(prior.member[0])]
    # a disc lying in the ceiling (thin along y) and the same disc on its edge
    quats = torch.tensor([[1.0, 0.0, 0.0, 0.0]])
    flat = torch.log(torch.tensor([[0.2, 0.001, 0.2]]))
    edge = torch.log(torch.tensor([[0.2, 0.2, 0.001]]))
    assert abs(ceiling.normal[1]) > 0.99
    thin = float(prior.flatness(quats, flat))
    thick = float(prior.flatness(quats, edge))
    assert thin == pytest.approx(0.001 / tau, rel=0.05)
    assert thick == pytest.approx(0.2 / tau, rel=0.05)


def test_state_round_trip():
    rng = np.random.default_rng(5)
    planes, tau = find_planes(room_points(rng), cameras_inside(rng), rng)
    prior = PlanePrior(planes, tau)
    prior.assign(torch.tensor([[0.0, 2.97, 0.0], [0.0, 1.5, 0.0]]))
    again = PlanePrior.from_state(prior.state_dict())
    assert again.member.tolist() == prior.member.tolist()
    assert [p.as_dict() for p in again.planes] == [p.as_dict() for p in prior.planes]


def box_room_data(seed: int = 0):
    """Eight 48x48 HDR views from inside a 5 x 3 x 4 m room of flat splats (textured
    faces, so the fit has something to match), with sparse points on its faces."""
    from gaslight_usd.cameras import PinholeCamera
    from gaslight_usd.fit.data import FitData
    from gaslight_usd.fit.synthetic import look_at
    from gaslight_usd.poses.colmap import ColmapModel
    from gaslight_usd.render import render
    from gaslight_usd.splats import SplatScene

    rng = np.random.default_rng(seed)
    faces, rots = [], []
    for axis in range(3):
        for value in (ROOM_LO[axis], ROOM_HI[axis]):
            p = rng.uniform(ROOM_LO, ROOM_HI, (700, 3))
            p[:, axis] = value
            faces.append(p)
            # a disc in the face: its thin axis (local z) along the face's normal
            q = {0: [np.cos(np.pi / 4), 0, np.sin(np.pi / 4), 0],
                 1: [np.cos(np.pi / 4), np.sin(np.pi / 4), 0, 0], 2: [1.0, 0, 0, 0]}[axis]
            rots.append(np.tile(q, (700, 1)))
    pos = np.concatenate(faces)
    n = len(pos)
    colours = np.exp(rng.normal(-1.0, 0.6, (n, 3)))
    scales = np.tile([0.2, 0.2, 0.004], (n, 1))
    truth = SplatScene.from_activated(pos, colours, scales, np.full(n, 0.99),
                                      rotations=np.concatenate(rots))
    cams = []
    for k in range(8):
        a = 2 * np.pi * k / 8
        centre = np.array([0.8 * np.sin(a), 1.4, 0.6 * np.cos(a)])
        rot, t = look_at(centre, centre + [np.sin(a), -0.15 + 0.3 * (k % 2), np.cos(a)])
        cams.append(PinholeCamera(48, 48, 30, 30, 24, 24, rot, t, name=f"view_{k}.jpg"))
    images = [render(truth, c).image.numpy() for c in cams]
    sparse = pos[rng.choice(n, 600, replace=False)]
    model = ColmapModel(cameras=cams, points=sparse)
    return FitData(names=[c.name[:-4] for c in cams], cameras=cams, images=images,
                   model=model, colour_space="lin_rec709")


def test_a_fit_keeps_its_held_splats_on_the_rooms_planes():
    """The trainer finds the box room's faces in its initial points and ends with the
    splats it holds on them; the same fit without the prior leaves them off."""
    from gaslight_usd.fit import fit_splats, preset

    data = box_room_data()
    cfg = preset("fast").updated(iterations=60, densify_every=20, working_size=0,
                                 backdrop_tiles=0, infer_power=False,
                                 plane_prior="auto")  # the views clip nothing: on
    held = fit_splats(data, cfg, seed=0)
    planes = held.metrics["planes"]
    assert len(planes["planes"]) >= 4  # the walls (the views see little floor or ceiling)
    for plane in planes["planes"]:
        normal = np.abs(plane["normal"])
        axis = int(np.argmax(normal))
        assert normal[axis] > 0.999
        along = abs(plane["offset"])
        assert min(abs(along - abs(ROOM_LO[axis])), abs(along - ROOM_HI[axis])) < 0.01
    assert planes["splats_held"] > 0.5 * held.scene.count
    # the room box (which bounds a light's move) is reported, with or without the prior
    box = held.metrics["room_box"]
    assert len(box) >= 4 and {"normal", "offset", "points", "size"} <= set(box[0])

    def off_faces(scene):
        p = scene.positions.astype(np.float64)
        d = np.concatenate([np.abs(p - ROOM_LO), np.abs(p - ROOM_HI)], axis=1).min(axis=1)
        return np.median(d)

    free = fit_splats(data, cfg.updated(plane_prior="off"), seed=0)
    assert free.metrics["planes"] is None
    assert len(free.metrics["room_box"]) >= 4  # the prior off: the box still bounds lights
    assert off_faces(held.scene) < 0.004
    assert off_faces(held.scene) < 0.5 * off_faces(free.scene)


def test_free_splats_near_a_plane_are_kept_in_front_of_it():
    """A light's splats (free) are not held, but one sunk behind its ceiling, or just
    under it, is put a little in front, where the views see it over the ceiling."""
    from gaslight_usd.fit.planes import LIFT

    rng = np.random.default_rng(6)
    planes, tau = find_planes(room_points(rng), cameras_inside(rng), rng)
    prior = PlanePrior(planes, tau)
    means = torch.tensor([[0.3, 3.04, 0.2],    # 4 cm behind the ceiling: lifted
                          [0.3, 2.998, 0.2],   # on it: lifted
                          [0.3, 2.90, 0.2],    # 10 cm under it: left where it is
                          [0.3, 2.95, 0.2]],   # 5 cm under it, but held (not free)
                         dtype=torch.float32)
    free = torch.tensor([True, True, True, False])
    prior.assign(means, free)
    assert prior.member.tolist()[:3] == [-1, -1, -1] and prior.member.tolist()[3] >= 0
    assert prior.as_dict()["lights_lifted"] == 3
    ceiling = planes[int(prior.member[3])]
    before = means.clone()
    prior.snap(means)
    def signed(k):  # distance in front of the ceiling (towards the cameras)
        return float(means[k].double().numpy() @ ceiling.normal - ceiling.offset)

    for k in (0, 1):
        assert signed(k) == pytest.approx(LIFT * tau, abs=1e-5)
    assert torch.equal(means[2], before[2])
    assert signed(3) == pytest.approx(0.0, abs=1e-5)


def test_a_wall_off_square_keeps_its_own_normal():
    """The main directions are squared up to the first wall; a wall 3 deg off square
    gets its own least-squares normal, not the squared-up one."""
    rng = np.random.default_rng(7)
    pts = room_points(rng, smear=0.01)
    on_far_wall = np.abs(pts[:, 0] - 2.5) < 0.05
    tilt = np.radians(3.0)  # the wall x = 2.5 turned about the vertical through z = 0
    pts[on_far_wall, 0] = 2.5 + np.tan(tilt) * pts[on_far_wall, 2] + rng.normal(
        0, 0.01, on_far_wall.sum())
    planes, _ = find_planes(pts, cameras_inside(rng), rng)
    far = [p for p in planes if p.normal[0] < -0.9]
    assert len(far) == 1
    truth = -np.array([np.cos(tilt), 0.0, -np.sin(tilt)])  # facing the room
    assert np.degrees(np.arccos(min(1.0, far[0].normal @ truth))) < 0.5


def window_wall(rng, count=600):
    """A plane x = 2.5 (cameras at x < 2.5) held by dim wall splats with a bright
    window patch (|y - 1.6| < 0.4, |z| < 0.45) among them: points, luminance, plane."""
    from gaslight_usd.fit.planes import Plane

    plane = Plane(np.array([-1.0, 0.0, 0.0]), -2.5, np.array([0.0, -2.0]),
                  np.array([3.0, 2.0]), np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), count)
    wall = np.column_stack([np.full(count, 2.5), rng.uniform(0, 3, count),
                            rng.uniform(-2, 2, count)])
    window = (np.abs(wall[:, 1] - 1.6) < 0.4) & (np.abs(wall[:, 2]) < 0.45)
    return wall, np.where(window, 5.0, 0.1), plane


def test_bright_floaters_in_front_of_a_lit_patch_belong_on_it():
    """A window's clump floating in front of it is the window's; the same brightness
    over plain wall, a lamp far brighter than the window, one beyond reach and one
    inside a seeded lamp's keep-out are not."""
    from gaslight_usd.fit.planes import FLOAT_REACH, bright_floaters

    rng = np.random.default_rng(3)
    wall, wall_lum, plane = window_wall(rng)
    tau = 0.08
    probe = np.array([[2.2, 1.6, 0.1],    # 0.3 m in front of the window: a floater
                      [1.8, 1.5, -0.2],   # 0.7 m in front of it: a floater
                      [2.2, 0.5, -1.5],   # as bright, over plain wall: not
                      [2.2, 1.7, 0.0],    # a lamp 1000x the window: not
                      [2.5 - (FLOAT_REACH + 1) * tau, 1.6, 0.1],  # beyond reach: not
                      [2.1, 1.4, 0.3],    # in a seeded lamp's keep-out: not
                      [2.2, 1.6, 0.1]])   # as dim as the wall: not
    lum = np.array([5.5, 4.0, 5.0, 5000.0, 5.0, 5.0, 0.1])
    points = np.concatenate([wall, probe])
    on_plane = np.concatenate([np.zeros(len(wall), int), np.full(len(probe), -1)])
    found = bright_floaters(points, np.concatenate([wall_lum, lum]), on_plane, [plane], tau,
                            keep_out=[(np.array([2.05, 1.4, 0.3]), 0.04)])
    assert found[:len(wall)].tolist() == [-1] * len(wall)  # held already
    assert found[len(wall):].tolist() == [0, 0, -1, -1, -1, -1, -1]


def test_floaters_brought_back_onto_their_wall():
    """Assigned with their luminance, a held floater is snapped onto the wall and a free
    one (a clipped light's) just in front of it; both are counted."""
    from gaslight_usd.fit.planes import LIFT

    rng = np.random.default_rng(4)
    wall, wall_lum, plane = window_wall(rng)
    prior = PlanePrior([plane], 0.08)
    means = torch.tensor(np.concatenate([wall, [[2.1, 1.6, 0.1], [2.0, 1.7, -0.1]]]),
                         dtype=torch.float32)
    lum = torch.tensor(np.concatenate([wall_lum, [5.0, 6.0]]), dtype=torch.float32)
    free = torch.zeros(len(means), dtype=torch.bool)
    free[-1] = True
    prior.assign(means, free, lum)
    assert prior.member[-2] == 0 and prior.lifted[-1] == 0
    assert prior.as_dict()["floaters_on_planes"] == 2
    prior.snap(means)
    assert float(means[-2, 0]) == pytest.approx(2.5, abs=1e-5)
    assert float(means[-1, 0]) == pytest.approx(2.5 - LIFT * 0.08, abs=1e-5)
    assert float(means[-1, 1]) == pytest.approx(1.7, abs=1e-6)  # along the normal only
    restored = PlanePrior.from_state(prior.state_dict())
    assert torch.equal(restored.floating, prior.floating)
