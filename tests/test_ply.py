import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from gaslight_usd.errors import InputError
from gaslight_usd.ply import read_ply, write_ply
from gaslight_usd.splats import SH_C0, SplatScene, sh_coefficient_count


def random_scene(n: int, degree: int, seed: int = 0) -> SplatScene:
    rng = np.random.default_rng(seed)
    k = sh_coefficient_count(degree)
    return SplatScene(
        positions=rng.normal(size=(n, 3)).astype(np.float32),
        rotations=rng.normal(size=(n, 4)).astype(np.float32),
        log_scales=rng.normal(-3, 1, size=(n, 3)).astype(np.float32),
        opacity_logits=rng.normal(size=n).astype(np.float32),
        sh=(rng.normal(size=(n, k, 3)) * 10).astype(np.float32),
        metadata={"colour_space": "ACEScg", "exposure_scale": 0.25, "up_axis": "Y"},
    )


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
@pytest.mark.parametrize("normals", [True, False])
def test_round_trip_is_exact(tmp_path, degree, normals):
    scene = random_scene(257, degree)
    path = write_ply(tmp_path / "s.ply", scene, with_normals=normals)
    back = read_ply(path)
    assert back.sh_degree == degree
    for name in ("positions", "rotations", "log_scales", "opacity_logits", "sh"):
        assert np.array_equal(getattr(back, name), getattr(scene, name)), name
    assert back.metadata == scene.metadata
    assert (back.normals is not None) == normals


def test_property_layout_follows_3dgs(tmp_path):
    scene = random_scene(3, 1)
    path = write_ply(tmp_path / "s.ply", scene)
    v = PlyData.read(str(path))["vertex"]
    names = [p.name for p in v.properties]
    assert names[:9] == ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    assert names[-8:] == ["opacity", "scale_0", "scale_1", "scale_2",
                          "rot_0", "rot_1", "rot_2", "rot_3"]
    # f_rest is channel-major: the first (K-1) are red, then green, then blue
    assert v["f_rest_0"][1] == scene.sh[1, 1, 0]
    assert v["f_rest_3"][1] == scene.sh[1, 1, 1]
    assert v["f_rest_8"][2] == scene.sh[2, 3, 2]


def test_reads_ply_from_another_tool(tmp_path):
    """A PLY as other 3DGS trainers write it: float props, zero normals, no comments."""
    n = 5
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
             *[f"f_rest_{i}" for i in range(45)], "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    data = np.zeros(n, dtype=[(p, "f4") for p in names])
    data["f_dc_0"] = (2.0 - 0.5) / SH_C0  # red 2.0: an HDR colour
    data["opacity"] = 0.0
    data["rot_0"] = 1.0
    path = tmp_path / "other.ply"
    PlyData([PlyElement.describe(data, "vertex")]).write(str(path))
    scene = read_ply(path)
    assert scene.sh_degree == 3 and scene.count == n
    np.testing.assert_allclose(scene.base_colours[:, 0], 2.0, rtol=1e-6)
    np.testing.assert_allclose(scene.opacities, 0.5)
    np.testing.assert_allclose(scene.scales, 1.0)


def test_point_cloud_ply_is_refused_clearly(tmp_path):
    data = np.zeros(3, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    path = tmp_path / "points.ply"
    PlyData([PlyElement.describe(data, "vertex")]).write(str(path))
    with pytest.raises(InputError, match="not a 3DGS splat PLY"):
        read_ply(path)


def test_activated_values():
    scene = SplatScene.from_activated(
        positions=np.zeros((2, 3)), colours=np.array([[5.0, 0.5, 0.0], [0.1, 0.2, 0.3]]),
        scales=np.array([0.01, 0.2]), opacities=np.array([0.9, 0.1]))
    np.testing.assert_allclose(scene.base_colours, [[5.0, 0.5, 0.0], [0.1, 0.2, 0.3]],
                               rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(scene.scales[:, 2], [0.01, 0.2], rtol=1e-5)
    np.testing.assert_allclose(scene.opacities, [0.9, 0.1], rtol=1e-5)
