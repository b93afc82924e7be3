"""COLMAP text/binary and transforms.json reading and writing, checked against
pycolmap (COLMAP's own reader/writer) and hand-computed poses."""

from __future__ import annotations

import json

import numpy as np
import pycolmap
import pytest

from gaslight_usd.cameras import PinholeCamera
from gaslight_usd.errors import InputError
from gaslight_usd.poses import read_poses, write_poses
from gaslight_usd.poses.colmap import ColmapModel, read_model, write_model
from gaslight_usd.poses.transforms_json import read_transforms, write_transforms


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """A COLMAP-written model (8 images, 200 points, SIMPLE_RADIAL) in text and binary."""
    pycolmap.set_random_seed(3)
    opts = pycolmap.SyntheticDatasetOptions(num_rigs=1, num_frames_per_rig=8,
                                            num_points3D=200)
    rec = pycolmap.synthesize_dataset(opts)
    root = tmp_path_factory.mktemp("synthetic")
    (root / "txt").mkdir()
    (root / "bin").mkdir()
    rec.write_text(str(root / "txt"))
    rec.write_binary(str(root / "bin"))
    return rec, root


def _assert_same_poses(a: ColmapModel, b: ColmapModel, tol: float = 1e-6) -> None:
    assert [c.name for c in a.cameras] == [c.name for c in b.cameras]
    for ca, cb in zip(a.cameras, b.cameras, strict=True):
        np.testing.assert_allclose(ca.R, cb.R, atol=tol)
        np.testing.assert_allclose(ca.t, cb.t, atol=tol)
        np.testing.assert_allclose([ca.fx, ca.fy, ca.cx, ca.cy],
                                   [cb.fx, cb.fy, cb.cx, cb.cy], atol=tol)
        assert (ca.width, ca.height) == (cb.width, cb.height)


@pytest.mark.parametrize("form", ["txt", "bin"])
def test_reads_what_colmap_wrote(synthetic, form):
    rec, root = synthetic
    model = read_model(root / form)
    assert len(model.cameras) == 8 and model.points.shape == (200, 3)
    for iid, cam in zip(model.image_ids, model.cameras, strict=True):
        m = rec.images[iid].cam_from_world().matrix()
        np.testing.assert_allclose(cam.R, m[:, :3], atol=1e-12)
        np.testing.assert_allclose(cam.t, m[:, 3], atol=1e-12)
        assert cam.name == rec.images[iid].name
    for pid, xyz, rgb, track in zip(model.point_ids, model.points, model.point_colours,
                                    model.tracks, strict=True):
        p = rec.points3D[int(pid)]
        np.testing.assert_allclose(xyz, p.xyz, atol=1e-12)
        assert tuple(rgb) == tuple(p.color)
        assert sorted(map(tuple, track)) == sorted(
            (e.image_id, e.point2D_idx) for e in p.track.elements)
    # SIMPLE_RADIAL: f shared, distortion kept and noted
    cam = model.cameras[0]
    params = rec.cameras[model.camera_ids[0]].params
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == (params[0], params[0], params[1], params[2])
    assert model.intrinsics[model.camera_ids[0]].distortion.tolist() == [params[3]]
    assert any("SIMPLE_RADIAL" in n for n in model.notes)


@pytest.mark.parametrize("binary", [False, True])
def test_round_trip_through_colmap(synthetic, tmp_path, binary):
    _, root = synthetic
    model = read_model(root / "bin")
    write_model(tmp_path / "m", model, binary=binary)
    back = read_model(tmp_path / "m")
    _assert_same_poses(model, back, tol=1e-12)
    np.testing.assert_array_equal(back.points, model.points)
    np.testing.assert_array_equal(back.point_errors, model.point_errors)
    assert all(np.array_equal(a, b) for a, b in zip(back.points2d, model.points2d, strict=True))
    # and COLMAP itself reads what we wrote, with the same poses and points
    rec = pycolmap.Reconstruction(str(tmp_path / "m"))
    assert rec.num_reg_images() == 8 and rec.num_points3D() == 200
    for iid, cam in zip(model.image_ids, model.cameras, strict=True):
        m = rec.images[iid].cam_from_world().matrix()
        np.testing.assert_allclose(np.hstack([cam.R, cam.t[:, None]]), m, atol=1e-9)
    assert rec.compute_mean_reprojection_error() < 1e-6


def test_parent_folder_and_frame_json(synthetic, tmp_path):
    _, root = synthetic
    model = read_model(root / "txt")
    model.frame = {"up_axis": "Y", "meters_per_unit": 1.0}
    write_model(tmp_path / "sparse" / "0", model)
    back = read_model(tmp_path)  # finds sparse/0
    assert back.frame == {"up_axis": "Y", "meters_per_unit": 1.0}
    assert back.source == tmp_path / "sparse" / "0"


def test_hand_written_text_model(tmp_path):
    """Identity rotation, camera at z = -4 (t = (0, 0, 4)): the origin projects to (cx, cy)."""
    (tmp_path / "cameras.txt").write_text("# c\n1 PINHOLE 640 480 500 510 320 240\n")
    (tmp_path / "images.txt").write_text(
        "# i\n7 1 0 0 0 0 0 4 1 a b.jpg\n\n"
        "9 0.7071067811865476 0 0.7071067811865476 0 1 2 3 1 c.png\n100.5 20.25 -1\n")
    (tmp_path / "points3D.txt").write_text("")
    m = read_model(tmp_path)
    assert m.names == ["a b.jpg", "c.png"] and m.image_ids == [7, 9]
    np.testing.assert_allclose(m.cameras[0].center, [0, 0, -4])
    uv, z = m.cameras[0].project(np.zeros((1, 3)))
    np.testing.assert_allclose(uv, [[320, 240]]) and np.testing.assert_allclose(z, [4])
    # 90 degrees about +y: camera z axis (third row of R) is world -x
    np.testing.assert_allclose(m.cameras[1].R[2], [-1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(m.points2d[1], [[100.5, 20.25, -1]])
    assert m.points.shape == (0, 3)


def test_bad_models_name_the_file(tmp_path):
    with pytest.raises(InputError, match="not a COLMAP model"):
        read_model(tmp_path)
    (tmp_path / "cameras.txt").write_text("1 PINHOLE 640 480 500 510 320\n")
    (tmp_path / "images.txt").write_text("")
    with pytest.raises(InputError, match="3 parameters") as err:
        read_model(tmp_path)
    assert "cameras.txt" in str(err.value)
    (tmp_path / "cameras.txt").write_text("1 PINHOLE 640 480 500 510 320 240\n")
    (tmp_path / "images.txt").write_text("1 1 0 0 0 0 0 0 2 a.jpg\n\n")
    with pytest.raises(InputError, match="camera 2"):
        read_model(tmp_path)
    (tmp_path / "cameras.bin").write_bytes(b"\x05\x00")
    (tmp_path / "images.bin").write_bytes(b"")
    with pytest.raises(InputError, match="malformed COLMAP cameras") as err:
        read_model(tmp_path)
    assert "cameras.bin" in str(err.value)


def _random_model(n: int = 6, seed: int = 0) -> ColmapModel:
    rng = np.random.default_rng(seed)
    cams = []
    for i in range(n):
        q = rng.normal(size=4)
        from gaslight_usd.cameras import quaternion_to_matrix
        cams.append(PinholeCamera(480, 360, 400.0 + i, 401.0 + i, 240.25, 180.5,
                                  R=quaternion_to_matrix(q), t=rng.normal(size=3),
                                  name=f"view_{i:02d}.jpg"))
    return ColmapModel(cameras=cams, points=rng.normal(size=(50, 3)),
                       point_colours=rng.integers(0, 256, (50, 3)))


def test_transforms_round_trip(tmp_path):
    model = _random_model()
    model.frame = {"up_axis": "Y", "meters_per_unit": None}
    write_poses(tmp_path / "transforms.json", model)
    back = read_poses(tmp_path / "transforms.json")
    _assert_same_poses(model, back, tol=1e-9)
    np.testing.assert_allclose(back.points, model.points, atol=1e-12)
    np.testing.assert_array_equal(back.point_colours, model.point_colours)
    assert back.frame["up_axis"] == "Y"
    # transforms.json -> COLMAP text -> COLMAP binary -> transforms.json
    write_poses(tmp_path / "txt", back)
    write_poses(tmp_path / "bin", read_poses(tmp_path / "txt"), binary=True)
    write_poses(tmp_path / "again.json", read_poses(tmp_path / "bin"))
    _assert_same_poses(model, read_transforms(tmp_path / "again.json"), tol=1e-9)


def test_transforms_opengl_convention(tmp_path):
    """An identity transform_matrix is a camera at the origin looking down -Z, +Y up."""
    data = {"camera_angle_x": 2 * np.arctan(0.5), "w": 100, "h": 80,
            "frames": [{"file_path": "./train/r_0.png",
                        "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 2], [0, 0, 1, 5],
                                             [0, 0, 0, 1]]}]}
    (tmp_path / "transforms.json").write_text(json.dumps(data))
    cam = read_transforms(tmp_path).cameras[0]
    assert cam.name == "r_0.png"
    np.testing.assert_allclose([cam.fx, cam.fy, cam.cx, cam.cy], [100, 100, 50, 40])
    np.testing.assert_allclose(cam.center, [0, 2, 5])
    np.testing.assert_allclose(cam.R, np.diag([1.0, -1, -1]))
    # a point straight ahead (-Z) and above (+Y) lands in the upper half of the image
    uv, z = cam.project(np.array([[0.0, 3.0, 0.0]]))
    assert z[0] == pytest.approx(5.0) and uv[0, 1] < 40 and uv[0, 0] == pytest.approx(50)
    # written back, the matrix is the same
    write_transforms(tmp_path / "out.json", read_transforms(tmp_path))
    frame = json.loads((tmp_path / "out.json").read_text())["frames"][0]
    np.testing.assert_allclose(frame["transform_matrix"], data["frames"][0]["transform_matrix"],
                               atol=1e-12)


def test_transforms_per_frame_intrinsics_and_errors(tmp_path):
    frames = [{"file_path": f"images/{i}.jpg", "fl_x": 300 + i, "fl_y": 300 + i, "cx": 160,
               "cy": 120, "w": 320, "h": 240, "transform_matrix": np.eye(4).tolist()}
              for i in range(2)]
    (tmp_path / "t.json").write_text(json.dumps({"frames": frames}))
    model = read_transforms(tmp_path / "t.json")
    assert [c.fx for c in model.cameras] == [300, 301] and len(model.intrinsics) == 2
    frames[1]["transform_matrix"] = (2 * np.eye(4)).tolist()
    (tmp_path / "t.json").write_text(json.dumps({"frames": frames}))
    with pytest.raises(InputError, match="1.jpg.*not a rigid"):
        read_transforms(tmp_path / "t.json")
    (tmp_path / "t.json").write_text("{")
    with pytest.raises(InputError, match="not valid JSON"):
        read_transforms(tmp_path / "t.json")
