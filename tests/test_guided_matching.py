"""Feature matches guided by known poses (gaslight_usd.poses.guided) and the despeckled
views the fit triangulates from."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import EXAMPLE, needs_example

from gaslight_usd.cameras import PinholeCamera
from gaslight_usd.fit.triangulate import despeckle
from gaslight_usd.poses import read_poses
from gaslight_usd.poses.guided import (
    epipolar_distances,
    fundamental,
    guided_pair_matches,
    share_view,
    strongest,
    unit_descriptors,
)


def _camera(centre, yaw_deg: float) -> PinholeCamera:
    """A 320 x 240 camera at ``centre`` turned ``yaw_deg`` about +Y (COLMAP axes)."""
    a = np.radians(yaw_deg)
    rot = np.array([[np.cos(a), 0.0, -np.sin(a)], [0.0, 1.0, 0.0], [np.sin(a), 0.0, np.cos(a)]])
    centre = np.asarray(centre, np.float64)
    return PinholeCamera(320, 240, 250.0, 250.0, 160.0, 120.0, R=rot, t=-rot @ centre)


def _seen(cam: PinholeCamera, points: np.ndarray) -> np.ndarray:
    uv, _ = cam.project(points)
    return uv


def test_the_fundamental_matrix_of_two_posed_views_holds_for_their_points():
    rng = np.random.default_rng(0)
    a, b = _camera([0, 0, 0], 0.0), _camera([0.8, 0.1, 0.2], 12.0)
    points = rng.uniform([-1, -1, 3], [1, 1, 5], (50, 3))
    xa, xb = _seen(a, points), _seen(b, points)
    d = epipolar_distances(fundamental(a, b), xa, xb)
    assert np.diag(d).max() < 1e-3  # each point on its own epipolar line
    assert np.median(d[~np.eye(50, dtype=bool)]) > 5.0  # others are not


def test_look_alikes_off_the_epipolar_line_do_not_hide_a_match():
    """Smooth texture: each feature of view b has a look-alike elsewhere in the view (its
    descriptor nearly the same), so the plain ratio test keeps almost nothing. Near the
    epipolar line only the true match is left, and every one is found, none wrongly."""
    rng = np.random.default_rng(1)
    a, b = _camera([0, 0, 0], 0.0), _camera([0.8, 0.0, 0.0], 10.0)
    points = rng.uniform([-1, -0.8, 3], [1, 0.8, 5], (60, 3))
    xa, xb_true = _seen(a, points), _seen(b, points)
    base = unit_descriptors(rng.normal(size=(60, 128)))
    da = unit_descriptors(base + rng.normal(scale=0.01, size=base.shape))
    db_true = unit_descriptors(base + rng.normal(scale=0.01, size=base.shape))
    db_twin = unit_descriptors(base + rng.normal(scale=0.01, size=base.shape))
    xb_twin = xb_true + rng.choice([-1, 1], (60, 2)) * rng.uniform(30, 60, (60, 2))
    xb = np.concatenate([xb_true, xb_twin])
    db = np.concatenate([db_true, db_twin])
    dist = np.sqrt(np.maximum(2 - 2 * da @ db.T, 0))
    two = np.sort(dist, axis=1)[:, :2]
    plain = (two[:, 0] < 0.8 * two[:, 1]).sum()
    found = guided_pair_matches(xa, da, xb, db, fundamental(a, b))
    assert plain < 10
    assert len(found) >= 55
    assert np.array_equal(found[:, 1], found[:, 0])  # each to its own point, no twin


def test_views_facing_away_from_each_other_are_not_compared():
    depths = np.geomspace(0.1, 40.0, 24)
    a = _camera([0, 0, 0], 0.0)
    assert share_view(a, _camera([0.5, 0, 0], 20.0), depths)
    assert not share_view(a, _camera([0.5, 0, 0], 180.0), depths)  # back to back
    assert share_view(a, _camera([0, 0, 6.0], 180.0), depths)  # face to face


def test_the_strongest_keypoints_are_the_largest():
    k = np.zeros((5, 6))
    k[:, 2] = k[:, 5] = [1.0, 4.0, 2.0, 8.0, 3.0]  # affine shape: scale on the diagonal
    assert strongest(k, 2).tolist() == [1, 3]
    assert strongest(k, 9).tolist() == [0, 1, 2, 3, 4]


def test_despeckling_removes_isolated_fireflies_and_keeps_edges():
    image = np.zeros((40, 40, 3), np.uint8)
    image[:, 20:] = 200  # an edge
    rng = np.random.default_rng(2)
    spots = rng.integers(0, 40, (30, 2))
    noisy = image.copy()
    noisy[spots[:, 0], spots[:, 1]] = 255
    clean = despeckle(noisy)
    assert np.abs(clean.astype(int) - image).max() == 0


@needs_example
@pytest.mark.slow
def test_guided_matching_adds_points_on_the_examples_surfaces(tmp_path):
    """The example's photos with their true poses: guided matching keeps more points, as
    close to the room's shell and furniture as without it."""
    from gaslight_usd.poses.sfm import SfmOptions, triangulate_known_poses

    truth = read_poses(EXAMPLE / "sparse" / "0")
    scene = json.loads((EXAMPLE / "scene.json").read_text())
    lo, hi = np.array(scene["room"]["min"]), np.array(scene["room"]["max"])
    counts, inside = {}, {}
    for guided in (False, True):
        opts = SfmOptions(max_image_size=480, threads=1, extraction_threads=1,
                          matching_threads=1, guided_matching=guided)
        model = triangulate_known_poses(EXAMPLE / "photos", truth, opts)
        counts[guided] = len(model.points)
        inside[guided] = np.all((model.points > lo - 0.05) & (model.points < hi + 0.05),
                                axis=1).mean()
        if guided:
            assert all(len(track) >= 3 for track in model.tracks)
    assert counts[True] > 1.3 * counts[False]
    assert inside[True] > 0.95 and inside[True] >= inside[False] - 0.01


@needs_example
@pytest.mark.slow
def test_the_fit_triangulates_again_with_guided_matches_only_where_points_are_few(
        monkeypatch):
    """``fit.triangulate.triangulate_views``: the example's true HDR views with their
    poses give dense points plainly (two-view points kept), and the guided, despeckled
    pass runs only when a view averages fewer than ``SPARSE_POINTS_PER_VIEW`` (forced
    here), where it keeps the denser result (every point seen three times)."""
    from gaslight_usd.fit import triangulate

    truth = read_poses(EXAMPLE / "sparse" / "0")
    names = truth.names[::2]  # twelve views: half the time
    from gaslight_usd.poses.colmap import ColmapModel

    model = ColmapModel(cameras=[c for c in truth.cameras if c.name in names])
    views = {name: EXAMPLE / "truth" / (name.rsplit(".", 1)[0] + ".exr") for name in names}
    plain = triangulate.triangulate_views(model, views)
    assert len(plain.points) >= triangulate.SPARSE_POINTS_PER_VIEW * len(names)
    assert min(len(track) for track in plain.tracks) == 2
    monkeypatch.setattr(triangulate, "SPARSE_POINTS_PER_VIEW", 10**6)
    again = triangulate.triangulate_views(model, views)
    assert len(again.points) > len(plain.points)
    assert min(len(track) for track in again.tracks) >= 3
