"""HDRI files: conventions in pixels and headers, round trip, output space, .tx, CLI."""

from __future__ import annotations

import numpy as np
import OpenEXR
import OpenImageIO as oiio
import pytest

from gaslight_usd import colour
from gaslight_usd.cli.main import main
from gaslight_usd.hdri import face_paths, render_probe, write_cube, write_latlong
from gaslight_usd.imageio import read_image
from gaslight_usd.ply import write_ply
from gaslight_usd.render.envmap import cube_to_latlong, latlong_to_cube, render_latlong
from gaslight_usd.splats import SplatScene


def beacons() -> SplatScene:
    """Three coloured splats at 2 m along +X (red), +Y (green) and +Z (blue)."""
    pos = np.array([[2.0, 0, 0], [0, 2.0, 0], [0, 0, 2.0]])
    col = np.array([[8.0, 0, 0], [0, 8.0, 0], [0, 0, 8.0]])
    return SplatScene.from_activated(pos, col, np.full((3, 3), 0.15), np.full(3, 0.99))


def shell(n: int = 600, seed: int = 0) -> SplatScene:
    """A smooth-ish environment: overlapping splats on a sphere of radius 3."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    col = 0.5 + 0.4 * d + rng.uniform(0, 0.1, (n, 3))
    col[d[:, 1] > 0.9] *= 20  # a bright "sky" cap, well above 1
    return SplatScene.from_activated(3 * d, col, np.full((n, 3), 0.35), np.full(n, 0.95))


def test_latlong_follows_openexr_convention(tmp_path):
    pano = render_latlong(beacons(), (0, 0, 0), 64)
    h, w = pano.shape[:2]
    assert (h, w) == (32, 64)
    # +X at a quarter width on the horizon, +Z at the centre, +Y on the top row.
    red = np.unravel_index(np.argmax(pano[..., 0]), (h, w))
    blue = np.unravel_index(np.argmax(pano[..., 2]), (h, w))
    green = np.unravel_index(np.argmax(pano[..., 1]), (h, w))
    assert abs(red[1] - w / 4) <= 1 and abs(red[0] - h / 2) <= 1
    assert abs(blue[1] - w / 2) <= 1 and abs(blue[0] - h / 2) <= 1
    assert green[0] <= 1
    write_latlong(tmp_path / "p.exr", pano, (0, 0, 0))
    header = OpenEXR.File(str(tmp_path / "p.exr")).header()
    assert header["envmap"] == OpenEXR.Envmap.ENVMAP_LATLONG
    assert "centre +Z" in header["gaslight:convention"]
    assert len(header["chromaticities"]) == 8  # ACEScg primaries stated
    back = read_image(tmp_path / "p.exr", ldr_space=colour.DEFAULT_INPUT_SPACE)
    np.testing.assert_allclose(back.pixels, pano, rtol=1e-3, atol=1e-3)  # half precision


def test_latlong_drawn_in_another_frames_axes():
    # the beacons solved in a frame of their own, turned 90 degrees about +Y (an SfM
    # frame): drawn with the rotation back, the panorama is the true frame's
    turn = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # x_true = turn @ x_own
    true = beacons()
    own = SplatScene.from_activated(true.positions @ turn, np.array(
        [[8.0, 0, 0], [0, 8.0, 0], [0, 0, 8.0]]), np.full((3, 3), 0.15), np.full(3, 0.99))
    want = render_latlong(true, (0, 0, 0), 64)
    np.testing.assert_allclose(render_latlong(own, (0, 0, 0), 64, rotation=turn), want,
                               atol=1e-4)
    assert not np.allclose(render_latlong(own, (0, 0, 0), 64), want, atol=1e-2)


def test_cube_layout_faces_and_radiance_unclamped(tmp_path):
    scene = beacons()
    scene.sh[0, 0] *= 100000  # red beacon far above the half range (65504)
    files = render_probe(scene, (0, 0, 0), tmp_path / "p.exr", width=64, cube=True,
                         faces=True)
    header = OpenEXR.File(str(files.cube)).header()
    assert header["envmap"] == OpenEXR.Envmap.ENVMAP_CUBE
    cube = read_image(files.cube, ldr_space=colour.DEFAULT_INPUT_SPACE).pixels
    size = 16
    assert cube.shape == (6 * size, size, 3)
    faces = cube.reshape(6, size, size, 3)
    # +X face (index 0) holds red at its centre, +Y (2) green, +Z (4) blue.
    for face, channel in ((0, 0), (2, 1), (4, 2)):
        centre = faces[face, size // 2 - 2: size // 2 + 2, size // 2 - 2: size // 2 + 2]
        assert centre[..., channel].max() == faces[..., channel].max()
    assert faces[..., 0].max() > 65504  # unclamped, float EXR
    assert [p.name for p in files.faces] == [p.name for p in face_paths(tmp_path / "p.exr")]
    px = read_image(files.faces[0], ldr_space=colour.DEFAULT_INPUT_SPACE).pixels
    np.testing.assert_allclose(px, faces[0], rtol=1e-6)


def test_round_trip_latlong_cube_latlong_within_one_percent():
    pano = render_latlong(shell(), (0.2, -0.1, 0.3), 256)
    back = cube_to_latlong(latlong_to_cube(pano, 128), 256)
    h, w = pano.shape[:2]
    # Away from edges: leave out the rows next to the poles.
    rows = slice(h // 16, h - h // 16)
    a, b = pano[rows], back[rows]
    assert float(np.abs(b - a).mean() / a.mean()) < 0.01
    assert abs(float(b.sum() / a.sum()) - 1) < 0.01
    assert pano.max() > 5  # HDR content took part


def test_output_space_conversion_and_cube_write(tmp_path):
    rng = np.random.default_rng(0)
    pano = rng.uniform(0, 4, (8, 16, 3)).astype(np.float32)
    write_latlong(tmp_path / "rec709.exr", pano, (1, 2, 3), output_space="lin_rec709")
    got = read_image(tmp_path / "rec709.exr", ldr_space=colour.DEFAULT_INPUT_SPACE)
    want = colour.convert(pano, "ACEScg", "Linear Rec.709 (sRGB)")
    np.testing.assert_allclose(got.pixels, want, rtol=2e-3, atol=2e-3)
    header = OpenEXR.File(str(tmp_path / "rec709.exr")).header()
    assert header["colorSpace"] == "Linear Rec.709 (sRGB)"
    assert tuple(header["gaslight:probePosition"]) == (1, 2, 3)
    with pytest.raises(ValueError):
        write_cube(tmp_path / "bad.exr", np.zeros((5, 4, 4, 3)), (0, 0, 0))


def test_tx_is_tiled_and_mipmapped(tmp_path):
    files = render_probe(beacons(), (0, 0, 0), tmp_path / "p.exr", width=64, tx=True)
    inp = oiio.ImageInput.open(str(files.tx))
    spec = inp.spec()
    levels = 0
    while inp.seek_subimage(0, levels):
        levels += 1
    inp.close()
    assert spec.tile_width > 0 and levels > 1
    assert spec.get_string_attribute("textureformat") == "LatLong Environment"


def test_cli_several_probes(tmp_path):
    write_ply(tmp_path / "b.ply", beacons())
    code = main(["hdri", str(tmp_path / "b.ply"), "--at", "0,0,0", "--at", "0.5,0,0",
                 "-o", str(tmp_path / "h" / "probe.exr"), "--size", "32", "-q"])
    assert code == 0
    assert (tmp_path / "h" / "probe.000.exr").exists()
    second = OpenEXR.File(str(tmp_path / "h" / "probe.001.exr")).header()
    assert tuple(second["gaslight:probePosition"]) == (0.5, 0, 0)
    with pytest.raises(SystemExit) as usage:
        main(["hdri", str(tmp_path / "b.ply"), "--at", "1,2", "-o", str(tmp_path / "x.exr")])
    assert usage.value.code == 2
    assert main(["hdri", str(tmp_path / "b.ply"), "-o", str(tmp_path / "x.exr"),
                 "--output-space", "no-such-space"]) == 3
    # A device torch cannot use: a usage error before anything is rendered or written.
    assert main(["hdri", str(tmp_path / "b.ply"), "--at", "0,0,0", "-o",
                 str(tmp_path / "y.exr"), "--device", "tpu", "-q"]) == 2
    assert not (tmp_path / "y.exr").exists()


def test_default_probe_is_inside_the_set_and_stated(tmp_path, capsys):
    """Without --at the probe is where the cameras stood, not the splats' bounds centre."""
    import json

    from test_lights import ROOM_HI, ROOM_LO, room_scene, with_far_backdrop

    scene = with_far_backdrop(room_scene()[0])
    ply = write_ply(tmp_path / "room.ply", scene)
    out = tmp_path / "probe.exr"
    assert main(["hdri", str(ply), "-o", str(out), "--size", "64", "--json"]) == 0
    probe = json.loads(capsys.readouterr().out)["probes"][0]
    pos = np.array(probe["position"])
    assert np.all(pos > ROOM_LO + 0.3) and np.all(pos < ROOM_HI - 0.3)
    assert probe["chosen"].startswith("default: median of 12 camera centres")
    spec = oiio.ImageInput.open(str(out)).spec()
    assert spec.getattribute("gaslight:probeChoice") == probe["chosen"]
    np.testing.assert_allclose(spec.getattribute("gaslight:probePosition"), pos, rtol=1e-5)
