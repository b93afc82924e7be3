"""Frames, alignment, HDR point colours, panoramas, and SfM on real photos."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from conftest import EXAMPLE, needs_example

from gaslight_usd.bench.dark_frames import dark_frame_photos, write_linear_photo
from gaslight_usd.bench.suite_chain import scene_lights
from gaslight_usd.cameras import (
    PinholeCamera,
    direction_to_latlong,
    is_latlong,
    quaternion_to_matrix,
)
from gaslight_usd.errors import InputError
from gaslight_usd.poses import colour_points, read_poses
from gaslight_usd.poses.colmap import ColmapModel, read_model
from gaslight_usd.poses.dark_frames import pose_dark_frames
from gaslight_usd.poses.frame import (
    align_and_compare,
    camera_axes,
    parse_scale_from,
    rotation_angle_deg,
    sfm_frame,
    split_similarity,
    transform_model,
    umeyama,
)
from gaslight_usd.poses.panorama import FACES, cube_faces, face_camera
from gaslight_usd.poses.sfm import SfmOptions, solve_poses, triangulate_known_poses

ROOT = Path(__file__).resolve().parents[1]
HDRI = ROOT / "tests" / "data" / "hdri"


def look_at(centre, target, up=(0, 1, 0), name="") -> PinholeCamera:
    """A COLMAP camera at ``centre`` looking at ``target`` with world ``up`` up."""
    z = np.asarray(target, float) - centre
    z /= np.linalg.norm(z)
    x = np.cross(z, -np.asarray(up, float))
    x /= np.linalg.norm(x)
    rot = np.stack([x, np.cross(z, x), z])
    return PinholeCamera(64, 48, 50.0, 50.0, 32.0, 24.0, R=rot, t=-rot @ centre, name=name)


def ring_model(seed: int = 0) -> ColmapModel:
    """8 cameras on a ring round a point cloud, +Y up, then moved by a random similarity."""
    rng = np.random.default_rng(seed)
    cams = [look_at(np.array([3 * np.cos(a), 1.5, 3 * np.sin(a)]), np.zeros(3),
                    name=f"v{i}.jpg") for i, a in enumerate(np.linspace(0, 6, 8))]
    points = rng.normal(size=(200, 3)) * 0.5 + [0.2, 1.0, -0.1]
    model = ColmapModel(cameras=cams, points=points)
    rot = quaternion_to_matrix(rng.normal(size=4))
    return transform_model(model, 0.37, rot, rng.normal(size=3))


def test_threaded_matching_verifies_pairs_with_a_seeded_ransac():
    from gaslight_usd.poses.sfm import _verification_options

    assert SfmOptions().matching_threads == -1 and SfmOptions().threads == 1
    assert _verification_options(7).ransac.random_seed == 7  # COLMAP's -1: from the clock


def test_umeyama_recovers_a_similarity():
    rng = np.random.default_rng(1)
    src = rng.normal(size=(20, 3))
    rot = quaternion_to_matrix(rng.normal(size=4))
    s, r, t = umeyama(src, 2.5 * src @ rot.T + [1, -2, 3])
    assert s == pytest.approx(2.5) and np.allclose(r, rot) and np.allclose(t, [1, -2, 3])


def test_sfm_frame_puts_y_up_and_centre_at_origin():
    tilted = ring_model()
    ups, _ = camera_axes(tilted.cameras)
    assert np.mean(ups, 0)[1] / np.linalg.norm(np.mean(ups, 0)) < 0.99  # really tilted
    framed = sfm_frame(tilted)
    ups, fwds = camera_axes(framed.cameras)
    up = ups.mean(0) / np.linalg.norm(ups.mean(0))
    np.testing.assert_allclose(up, [0, 1, 0], atol=1e-9)
    # no floor among these points: the origin is the cameras' median point
    assert not framed.frame["floor"]["found"]
    np.testing.assert_allclose(np.median(framed.centers, 0), 0, atol=1e-9)
    heading = fwds.mean(0) * [1, 0, 1]
    np.testing.assert_allclose(heading / np.linalg.norm(heading), [0, 0, -1], atol=1e-9)
    # the same photos: every point lands on the same pixel in every camera
    for a, b in zip(tilted.cameras, framed.cameras, strict=True):
        np.testing.assert_allclose(a.project(tilted.points)[0], b.project(framed.points)[0],
                                   atol=1e-8)
    f = framed.frame
    assert f["up_axis"] == "Y" and f["meters_per_unit"] is None and not f["scale_known"]
    m = np.array(f["transform_from_sfm"])
    np.testing.assert_allclose(tilted.points @ m[:3, :3].T + m[:3, 3], framed.points, atol=1e-9)


def room_model(seed: int = 0, strays: int = 0) -> ColmapModel:
    """Cameras at 1.5 m round a room whose floor (y = 0) and walls hold the points,
    moved by a random similarity (SfM's arbitrary frame and scale)."""
    rng = np.random.default_rng(seed)
    cams = [look_at(np.array([1.2 * np.cos(a) + 0.4, 1.5 + 0.05 * np.sin(3 * a),
                              1.2 * np.sin(a) - 0.3]), np.array([0.4, 1.2, -0.3]),
                    up=(0, -1, 0), name=f"v{i}.jpg")  # image rows run down the world
            for i, a in enumerate(np.linspace(0, 6, 10))]
    floor = np.column_stack([rng.uniform(-2.5, 2.5, 300), rng.normal(0, 0.005, 300),
                             rng.uniform(-2, 2, 300)])
    walls = np.column_stack([np.full(200, 2.5), rng.uniform(0, 3, 200), rng.uniform(-2, 2, 200)])
    stray = rng.uniform(-3, 3, (strays, 3)) * [1, 0, 1] + [0, -1.0, 0]
    model = ColmapModel(cameras=cams, points=np.concatenate([floor, walls, stray]))
    rot = quaternion_to_matrix(rng.normal(size=4))
    return transform_model(model, 0.37, rot, rng.normal(size=3))


def test_sfm_frame_puts_the_floor_at_zero_under_the_cameras():
    framed = sfm_frame(room_model(strays=3))  # stray points under the floor are ignored
    f = framed.frame
    assert f["floor"]["found"] and f["units"].startswith("units unknown")
    assert "--camera-height" in f["units"]
    floor_pts = framed.points[:300]
    assert abs(float(np.median(floor_pts[:, 1]))) < 0.01 * 0.37 * 3
    centres = framed.centers
    np.testing.assert_allclose(np.median(centres, 0)[[0, 2]], 0, atol=1e-9)
    assert np.median(centres[:, 1]) > 0
    # --camera-height: metres, the cameras' median height exactly that above the floor
    metric = sfm_frame(room_model(strays=3), camera_height=1.5)
    assert metric.frame["meters_per_unit"] == 1.0 and metric.frame["scale_known"]
    assert np.median(metric.centers[:, 1]) == pytest.approx(1.5)
    assert np.median(metric.points[:300, 1]) == pytest.approx(0.0, abs=0.01)
    assert metric.frame["floor"]["camera_height_median"] == pytest.approx(1.5)
    # the room's true size comes back: the model was shrunk by 0.37 from metres, and
    # its cameras' true median height is not quite 1.5
    true_median = np.median(1.5 + 0.05 * np.sin(3 * np.linspace(0, 6, 10)))
    scale, _, _ = split_similarity(np.array(metric.frame["transform_from_sfm"]))
    assert scale * 0.37 == pytest.approx(1.5 / true_median, rel=0.005)


def test_camera_height_needs_a_floor_and_one_scale():
    with pytest.raises(InputError, match="no floor"):
        sfm_frame(ring_model(), camera_height=1.5)
    with pytest.raises(InputError, match="one of"):
        sfm_frame(room_model(), scale=2.0, camera_height=1.5)


def test_scale_from_two_cameras_gives_metres():
    framed = sfm_frame(ring_model(), scale_from="v0.jpg,v4.jpg,2.0")
    gap = np.linalg.norm(framed.camera("v0.jpg").center - framed.camera("v4.jpg").center)
    assert gap == pytest.approx(2.0)
    assert framed.frame["meters_per_unit"] == 1.0 and framed.frame["scale_known"]
    assert sfm_frame(ring_model(), scale=3.0).frame["scale_source"].startswith("factor 3")
    with pytest.raises(InputError, match="nope.jpg"):
        sfm_frame(ring_model(), scale_from="v0.jpg,nope.jpg,1")
    with pytest.raises(InputError, match="IMG_A,IMG_B"):
        parse_scale_from("a,b")


def test_align_and_compare_is_zero_for_a_moved_copy():
    truth = ring_model(2)
    report = align_and_compare(sfm_frame(truth, scale=0.1), truth)
    assert report["median_centre_error_rel"] < 1e-9
    assert report["median_rotation_error_deg"] < 1e-5 and report["missing"] == []


def test_colour_points_median_over_seeing_views():
    """Views of constant colours 1, 2, 3 (and a gradient view): medians are hand-computed."""
    cams = [look_at(np.array([0.0, 0, -5 + 0.1 * i]), np.zeros(3), name=f"v{i}.exr")
            for i in range(3)]
    pts = np.array([[0.0, 0, 0], [0.1, -0.1, 0], [0, 0, -10]])  # the last is behind all
    model = ColmapModel(cameras=cams, points=pts)
    views = {f"v{i}": np.full((48, 64, 3), i + 1.0, np.float32) for i in range(3)}
    views["v2"][..., 0] = np.arange(64, dtype=np.float32)[None, :] * 100  # red = 100 * x
    colours = colour_points(model, views)
    uv, _ = cams[2].project(pts[:1])
    # point 0: views give red 1, 2 and 100*(u-0.5) (bilinear on pixel centres) -> median 2
    assert colours[0].tolist() == pytest.approx([2.0, 2.0, 2.0])
    assert 100 * (uv[0, 0] - 0.5) > 2
    # the unseen point takes the median of the seen ones
    assert colours[2].tolist() == pytest.approx(np.median(colours[:2], 0).tolist())
    # with tracks, only the views in the track count: point 0 seen by v2 alone
    model.tracks = [np.array([[3, 0]]), np.array([[1, 0], [2, 0]]), np.zeros((0, 2), int)]
    colours = colour_points(model, views)
    assert colours[0, 0] == pytest.approx(100 * (uv[0, 0] - 0.5), rel=1e-5)
    assert colours[1].tolist() == pytest.approx([1.5, 1.5, 1.5])


def test_cube_faces_sample_the_right_directions():
    w, h = 256, 128
    pano = np.zeros((h, w, 3), np.float32)
    pano[..., 0] = np.arange(w)[None, :]  # red = column
    pano[..., 1] = np.arange(h)[:, None]  # green = row
    faces = cube_faces(pano, size=32)
    assert set(faces) == set(FACES) and faces["front"].shape == (32, 32, 3)
    for face, img in faces.items():
        cam = face_camera(face, 32)
        d = cam.ray_directions()[16, 16]  # rig (front camera) axes: x right, y down, z fwd
        d_pano = np.array([-d[0], -d[1], d[2]])  # panorama axes: +Y up, +Z centre column
        x, y = direction_to_latlong(d_pano, w, h)
        if face not in ("up", "down"):
            assert img[16, 16, 0] == pytest.approx(x - 0.5, abs=0.6), face
        assert img[16, 16, 1] == pytest.approx(np.clip(y - 0.5, 0, h - 1), abs=0.6), face
    # front looks at the centre column, right at three quarters of the width
    assert faces["front"][16, 16, 0] == pytest.approx(w / 2, abs=1)
    assert faces["right"][16, 16, 0] == pytest.approx(3 * w / 4, abs=1)
    assert is_latlong(1024, 512) and not is_latlong(480, 360)


def _write_jpeg(path: Path, pixels: np.ndarray) -> None:
    enc = np.clip(pixels, 0, 1) ** (1 / 2.2)
    buf = oiio.ImageBuf((enc * 255 + 0.5).astype(np.uint8))
    assert buf.write(str(path))


@pytest.fixture(scope="module")
def unrelated(tmp_path_factory):
    """Five photos of nothing in common: four crops of different HDRIs, one noise."""
    folder = tmp_path_factory.mktemp("unrelated")
    for name in ("city", "forest", "interior", "sunset"):
        buf = oiio.ImageBuf(str(HDRI / f"{name}.exr"))
        pano = np.asarray(buf.get_pixels(oiio.FLOAT))[..., :3]
        h, w = pano.shape[:2]  # the same view at any size: rows 29-76 %, columns 29-61 %
        px = pano[h * 150 // 512:h * 390 // 512, w * 300 // 1024:w * 620 // 1024]
        _write_jpeg(folder / f"{name}.jpg", px / (4 * np.median(px) + 1e-6))
    rng = np.random.default_rng(0)
    _write_jpeg(folder / "noise.jpg", rng.random((240, 320, 3)))
    return folder


def test_unrelated_photos_fail_naming_them(unrelated):
    with pytest.raises(InputError) as err:
        solve_poses(unrelated, SfmOptions(max_image_size=400))
    msg = str(err.value)
    assert "0 of 5 photos registered" in msg
    for name in ("city.jpg", "forest.jpg", "interior.jpg", "sunset.jpg", "noise.jpg"):
        assert name in msg
    assert "no overlap" in msg


@needs_example
@pytest.mark.slow
def test_sfm_on_the_example_matches_the_true_poses(tmp_path):
    """The bundled photos, the README's darker frames beside them and one unrelated
    photo: all of them register, the stray is named; the bulb's frame, too dark for SfM,
    takes the pose of the photo it was shot beside."""
    photos = tmp_path / "photos"
    chosen = dark_frame_photos(EXAMPLE, photos, scene_lights(json.loads(
        (EXAMPLE / "scene.json").read_text())), extra=True)
    lamp_frame = next(name for name, what in chosen.items() if what["light"] == "lamp")
    assert chosen[lamp_frame]["stops"] < -8  # black but for the bulb
    rng = np.random.default_rng(1)
    # a stray shot at 1/8000 s right after the last photo: far darker than it, but full of
    # features that match nothing, so no darker frame of that photo (it stays out)
    write_linear_photo(photos / "zz_stray.jpg", rng.random((360, 480, 3)).astype(np.float32),
                       (1 / 8000, 4.0), EXAMPLE / "photos" / "view_00.jpg")
    out = tmp_path / "sparse"
    proc = subprocess.run(
        [str(Path(sys.executable).with_name("gaslight2usd")), "poses", str(photos), "-o", str(out),
         "--camera-model", "PINHOLE", "--json", "-q"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    truth = read_poses(EXAMPLE / "sparse" / "0")
    assert report["registered"] == len(truth.cameras) + 2 == report["photos"] - 1
    assert list(report["unregistered"]) == ["zz_stray.jpg"]
    assert report["posed_as_neighbour"] == {lamp_frame: chosen[lamp_frame]["of"]}
    model = read_model(out)
    posed, photo = model.camera(lamp_frame), model.camera(chosen[lamp_frame]["of"])
    np.testing.assert_allclose(posed.R, photo.R, atol=1e-9)
    np.testing.assert_allclose(posed.center, photo.center, atol=1e-9)
    assert model.frame["up_axis"] == "Y" and model.frame["frame_source"] == "sfm"
    scene = json.loads((EXAMPLE / "scene.json").read_text())
    size = float(np.linalg.norm(np.subtract(scene["room"]["max"], scene["room"]["min"])))
    cmp = align_and_compare(model, truth, scene_size=size)
    assert cmp["missing"] == []
    assert cmp["median_centre_error_rel"] < 0.01
    assert cmp["median_rotation_error_deg"] < 1.0
    # +Y up: the SfM frame's up agrees with the true (+Y up) frame after alignment
    rot = cmp["similarity"][:3, :3] / np.cbrt(np.linalg.det(cmp["similarity"][:3, :3]))
    assert rot[1, 1] > 0.99


@needs_example
@pytest.mark.slow
def test_triangulate_known_poses_on_the_example():
    truth = read_poses(EXAMPLE / "sparse" / "0")
    assert len(truth.points) == 0
    filled = triangulate_known_poses(EXAMPLE / "photos", truth, SfmOptions(max_image_size=480))
    assert len(filled.points) > 200
    for a, b in zip(filled.cameras, truth.cameras, strict=True):
        assert np.array_equal(a.R, b.R) and np.array_equal(a.t, b.t)
    scene = json.loads((EXAMPLE / "scene.json").read_text())
    lo, hi = np.array(scene["room"]["min"]), np.array(scene["room"]["max"])
    inside = np.all((filled.points > lo - 0.05) & (filled.points < hi + 0.05), axis=1)
    assert inside.mean() > 0.95  # true poses -> points on the room's surfaces
    assert np.median(filled.point_errors) < 1.5


def test_cli_converts_colmap_to_transforms_and_back(tmp_path):
    model = ring_model(4)
    from gaslight_usd.poses.colmap import write_model
    write_model(tmp_path / "sparse" / "0", model, binary=True)
    cli = [str(Path(sys.executable).with_name("gaslight2usd")), "poses"]
    proc = subprocess.run(cli + ["--from", str(tmp_path / "sparse"), "-o",
                                 str(tmp_path / "t" / "transforms.json"), "--json"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["images"] == 8
    proc = subprocess.run(cli + ["--from", str(tmp_path / "t" / "transforms.json"), "-o",
                                 str(tmp_path / "back")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    back = read_model(tmp_path / "back")
    for a, b in zip(model.cameras, back.cameras, strict=True):
        np.testing.assert_allclose(b.R, a.R, atol=1e-9)
        np.testing.assert_allclose(b.t, a.t, atol=1e-9)
    np.testing.assert_allclose(back.points, model.points, atol=1e-9)
    assert back.frame["frame_source"] == "given (colmap)"  # carried through the .json
    proc = subprocess.run(cli + ["--from", str(tmp_path / "nothing"), "-o", str(tmp_path / "x")],
                          capture_output=True, text=True)
    assert proc.returncode == 3 and "nothing" in proc.stderr


@pytest.mark.slow
@needs_example
def test_fit_bench_moves_sfm_poses_into_the_true_frame(tmp_path):
    """The fit bench's 'room-sfm' case: SfM poses in the true frame, so probe points agree."""
    from gaslight_usd.bench.suite_fit import sfm_poses_in_true_frame

    model = read_poses(sfm_poses_in_true_frame(tmp_path / "sfm", example=EXAMPLE))
    truth = {c.name: c for c in read_poses(EXAMPLE / "sparse" / "0").cameras}
    assert {c.name for c in model.cameras} == set(truth)
    centre_err = [np.linalg.norm(c.center - truth[c.name].center) for c in model.cameras]
    assert np.median(centre_err) < 0.03  # metres, in a 5 x 4 x 3 m room
    rot_err = rotation_angle_deg(np.array([c.R for c in model.cameras]),
                                 np.array([truth[c.name].R for c in model.cameras]))
    assert np.median(rot_err) < 1.0
    # the sparse points moved with the cameras: they lie inside the room
    lo, hi = np.array([-2.6, -0.1, -2.1]), np.array([2.6, 3.1, 2.1])
    inside = np.all((model.points > lo) & (model.points < hi), axis=1)
    assert len(model.points) > 100 and inside.mean() > 0.95


@pytest.mark.slow
@needs_example
def test_triangulated_fit_start_is_the_same_every_run():
    """The fit's start points (COLMAP on the HDR views) repeat exactly: the fit is
    deterministic for a seed only if they do (threaded COLMAP reorders its work)."""
    from gaslight_usd.fit.triangulate import triangulate_views

    full = read_poses(EXAMPLE / "sparse" / "0")
    model = ColmapModel(cameras=full.cameras[:12])  # the level ring: enough for COLMAP's threads
    views = {n: EXAMPLE / "truth" / (Path(n).stem + ".exr") for n in model.names}
    first, second = triangulate_views(model, views), triangulate_views(model, views)
    assert first is not None and len(first.points) > 300
    np.testing.assert_array_equal(first.points, second.points)


def test_only_a_much_darker_frame_beside_a_registered_photo_takes_its_pose(tmp_path):
    """The rule of :mod:`gaslight_usd.poses.dark_frames` on photos SfM left out: a frame
    7 stops darker than the registered photo before it (by file name) takes that photo's
    pose; one a stop darker (an auto-exposure step, not a darker frame), one beside a photo
    that did not register, and one of another size stay out."""
    like = sorted((EXAMPLE / "photos").glob("*.jpg"))[0]
    grey = np.full((36, 48, 3), 0.3, np.float32)
    shots = {"a.jpg": 1 / 60, "a_dark.jpg": 1 / 8000, "b.jpg": 1 / 60, "b_dim.jpg": 1 / 125,
             "c.jpg": 1 / 60, "c_dark.jpg": 1 / 8000, "d.jpg": 1 / 60}
    for name, t in shots.items():
        write_linear_photo(tmp_path / name, grey, (t, 4.0), like)
    write_linear_photo(tmp_path / "d_dark.jpg", np.full((24, 48, 3), 0.3, np.float32),
                       (1 / 8000, 4.0), like)
    paths = sorted(tmp_path.glob("*.jpg"))
    cam = read_poses(EXAMPLE / "sparse" / "0").cameras
    model = ColmapModel(cameras=[replace(cam[0], name="a.jpg"), replace(cam[1], name="b.jpg"),
                                 replace(cam[2], name="d.jpg")])
    left_out = {"a_dark.jpg": "too dark", "b_dim.jpg": "too dark", "c.jpg": "no overlap",
                "c_dark.jpg": "too dark", "d_dark.jpg": "too dark"}
    posed_model, posed = pose_dark_frames(model, paths, left_out)
    assert posed == {"a_dark.jpg": "a.jpg"}
    assert posed_model.names == ["a.jpg", "b.jpg", "d.jpg", "a_dark.jpg"]
    np.testing.assert_allclose(posed_model.camera("a_dark.jpg").R, cam[0].R)
    np.testing.assert_allclose(posed_model.camera("a_dark.jpg").center, cam[0].center)
    assert len(set(posed_model.image_ids)) == 4
