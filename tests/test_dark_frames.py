"""The chain bench's capture with one darker frame per light (bench/dark_frames.py):
the frame is aimed at its light, the light no longer clips, and the photo reads back
with the exposure it was given."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gaslight_usd.bench.dark_frames import (
    DARK_SUFFIX,
    HEADROOM,
    SHORTEST_EXPOSURE,
    SMALLEST_APERTURE,
    camera_settings,
    dark_exposure,
    dark_frame_photos,
    poses_with_dark_frames,
    truth_with_extra_views,
)
from gaslight_usd.bench.suite_chain import scene_lights
from gaslight_usd.colour import convert
from gaslight_usd.imageio import read_image
from gaslight_usd.locate import example_room
from gaslight_usd.poses import read_poses

EXAMPLE = example_room()


def test_dark_exposure_puts_the_peak_below_white_in_third_stops():
    radiance = np.full((40, 40, 3), 0.5, np.float32)
    radiance[20, 21] = [3000.0, 2000.0, 1000.0]
    t = dark_exposure(radiance, np.array([20.5, 19.5]), 10.0)
    assert 3000.0 * t * 10.0 <= HEADROOM
    assert 3000.0 * t * 10.0 > HEADROOM * 2 ** (-1 / 3)  # no darker than it must be
    assert 3 * math.log2(t) == pytest.approx(round(3 * math.log2(t)))


def test_a_dark_frame_is_what_a_camera_can_shoot():
    assert camera_settings(1 / 500, 4.0) == (1 / 500, 4.0)
    # 2 stops past the fastest shutter: the aperture closes 2 stops (f/4 -> f/8)
    shutter, aperture = camera_settings(SHORTEST_EXPOSURE / 4, 4.0)
    assert shutter == SHORTEST_EXPOSURE and aperture == pytest.approx(8.0)
    # past f/22 too: as dark as the camera goes
    assert camera_settings(SHORTEST_EXPOSURE / 1000, 4.0) == (SHORTEST_EXPOSURE,
                                                               SMALLEST_APERTURE)


def test_each_light_gets_a_frame_that_sees_it_unclipped(tmp_path):
    info = json.loads((EXAMPLE / "scene.json").read_text())
    lights = scene_lights(info)
    chosen = dark_frame_photos(EXAMPLE, tmp_path / "photos", lights)
    assert sorted(c["light"] for c in chosen.values()) == ["lamp", "window"]
    cams = {c.name: c for c in read_poses(EXAMPLE / "sparse" / "0").cameras}
    k_camera = info["exposure"]["K"]
    for name, what in chosen.items():
        photo = read_image(tmp_path / "photos" / name)
        truth = read_image(EXAMPLE / "truth" / name.replace(".jpg", ".exr")).pixels
        was = read_image(EXAMPLE / "photos" / name).exposure.exposure_time
        t = photo.exposure.exposure_time * (4.0 / photo.exposure.f_number) ** 2
        assert math.log2(t / was) == pytest.approx(what["stops"], abs=0.01)
        assert what["stops"] < 0
        light = next(li for li in lights if li["name"] == what["light"])
        ((u, v),), _ = cams[name].project(np.array([light["center"]]))
        v0, u0 = int(v), int(u)
        patch = photo.pixels[v0 - 3:v0 + 4, u0 - 3:u0 + 4]
        assert patch.max() < 0.99  # the light is measured, not clipped
        # the recorded value is the camera model's: sRGB(truth x t x K) (JPEG aside)
        linear = np.clip(truth[v0 - 3:v0 + 4, u0 - 3:u0 + 4] * t * k_camera, 0, 1)
        expect = convert(linear.astype(np.float32), "lin_rec709_scene", "srgb_rec709_scene")
        assert np.abs(patch - expect).max() < 0.05
    unchanged = sorted(set(cams) - set(chosen))
    assert (tmp_path / "photos" / unchanged[0]).resolve() == \
        (EXAMPLE / "photos" / unchanged[0]).resolve()
    assert json.loads((tmp_path / "dark_frames.json").read_text()) == chosen


def test_extra_dark_frames_are_added_beside_their_photos_and_posed_as_them(tmp_path):
    """The README's capture: every photo kept, each darker frame added as
    ``<stem>_dark.jpg`` at the pose of the photo it was made from."""
    info = json.loads((EXAMPLE / "scene.json").read_text())
    chosen = dark_frame_photos(EXAMPLE, tmp_path / "photos", scene_lights(info), extra=True)
    assert sorted(c["light"] for c in chosen.values()) == ["lamp", "window"]
    originals = sorted(p.name for p in (EXAMPLE / "photos").glob("*.jpg"))
    written = sorted(p.name for p in (tmp_path / "photos").glob("*.jpg"))
    assert written == sorted(originals + list(chosen))
    for name, what in chosen.items():
        assert name == what["of"].replace(".jpg", f"{DARK_SUFFIX}.jpg")
        assert (tmp_path / "photos" / what["of"]).resolve() == \
            (EXAMPLE / "photos" / what["of"]).resolve()  # the photo itself, unchanged
        dark = read_image(tmp_path / "photos" / name).exposure.exposure_time
        shot = read_image(EXAMPLE / "photos" / what["of"]).exposure.exposure_time
        assert dark < shot
    model = read_poses(poses_with_dark_frames(EXAMPLE, chosen, tmp_path / "sparse"))
    cams = {c.name: c for c in model.cameras}
    assert sorted(cams) == sorted(originals + list(chosen))
    assert len(set(model.image_ids)) == len(model.cameras)
    for name, what in chosen.items():
        np.testing.assert_allclose(cams[name].center, cams[what["of"]].center, atol=1e-9)
        np.testing.assert_allclose(cams[name].R, cams[what["of"]].R, atol=1e-9)
        assert cams[name].fx == cams[what["of"]].fx


def scene_with_extra_view(tmp_path):
    """The example with one extra view aimed at its lamp (a copy of the truth and pose of
    the photo that frames the lamp best, under another name), as ``make_room.py`` poses
    its frame from below a shaded lamp."""
    from gaslight_usd.bench.dark_frames import light_view
    from gaslight_usd.cameras import matrix_to_quaternion

    folder = tmp_path / "scene"
    folder.mkdir()
    for sub in ("photos", "truth", "sparse"):
        (folder / sub).symlink_to(EXAMPLE / sub)
    info = json.loads((EXAMPLE / "scene.json").read_text())
    lamp = next(li for li in scene_lights(info) if li["name"] == "lamp")
    cams = read_poses(EXAMPLE / "sparse" / "0").cameras
    cam = light_view(cams, np.asarray(lamp["center"]), set())
    (folder / "extra").mkdir()
    (folder / "extra" / "below_00.exr").symlink_to(
        EXAMPLE / "truth" / cam.name.replace(".jpg", ".exr"))
    info["extra_views"] = [{"name": "below_00.jpg", "truth": "extra/below_00.exr",
                            "aimed_at": "lamp",
                            "qvec": matrix_to_quaternion(cam.R).tolist(),
                            "tvec": cam.t.tolist()}]
    (folder / "scene.json").write_text(json.dumps(info))
    return folder, info, lamp, cam


def test_a_light_no_photo_shows_gets_its_frame_from_the_scenes_extra_view(tmp_path):
    """A shaded lamp's frame from below is no photo's re-exposure: it is made from the
    scene's extra view, exposed for the light, and posed where that view was rendered."""
    folder, info, lamp, cam = scene_with_extra_view(tmp_path)
    chosen = dark_frame_photos(folder, tmp_path / "photos", scene_lights(info), extra=True)
    name = f"below_00{DARK_SUFFIX}.jpg"
    assert chosen[name]["light"] == "lamp" and chosen[name]["of"] is None
    assert sorted(c["light"] for c in chosen.values()) == ["lamp", "lamp", "window"]
    photo = read_image(tmp_path / "photos" / name)
    ((u, v),), _ = cam.project(np.array([lamp["center"]]))
    patch = photo.pixels[int(v) - 3:int(v) + 4, int(u) - 3:int(u) + 4]
    assert 0.3 < patch.max() < 0.99  # exposed for the lamp: measured, not clipped
    model = read_poses(poses_with_dark_frames(folder, chosen, tmp_path / "sparse"))
    posed = {c.name: c for c in model.cameras}[name]
    np.testing.assert_allclose(posed.R, cam.R, atol=1e-9)
    np.testing.assert_allclose(posed.center, cam.center, atol=1e-9)
    assert len(set(model.image_ids)) == len(model.cameras)
    # the in-place capture replaces photos; a frame no photo was taken from is not one
    in_place = dark_frame_photos(folder, tmp_path / "in_place", scene_lights(info))
    assert name not in in_place


def test_a_shaded_room_rendered_without_its_frames_from_below_is_rendered_again(tmp_path):
    """The bench's scene cache: a shaded room from before the views from below lacks
    them, and is rendered again rather than benched without them."""
    from gaslight_usd.bench.suite_chain import lacks_frames_from_below

    folder, info, _, _ = scene_with_extra_view(tmp_path)
    info["lights"] = [dict(li, shaded=li["name"] == "lamp") for li in scene_lights(info)]
    (folder / "scene.json").write_text(json.dumps(info))
    assert not lacks_frames_from_below(folder)
    (folder / "scene.json").write_text(json.dumps({k: v for k, v in info.items()
                                                   if k != "extra_views"}))
    assert lacks_frames_from_below(folder)
    bare = {k: v for k, v in info.items() if k != "extra_views"}
    bare["lights"] = [dict(li, shaded=False) for li in info["lights"]]
    (folder / "scene.json").write_text(json.dumps(bare))
    assert not lacks_frames_from_below(folder)  # no shade: nothing to shoot from below


def test_the_true_hdr_ceiling_fits_the_viewpoints_the_capture_adds(tmp_path):
    """The chain bench's ``truth HDR`` fits the true views from every viewpoint the
    README's capture photographs: the extra view's truth, posed where it was rendered,
    beside the level views; the fit data pairs each with its pose. A scene without extra
    views is its own truth and poses."""
    from gaslight_usd.fit.data import load_fit_data

    folder, _, lamp, cam = scene_with_extra_view(tmp_path)
    hdr, poses = truth_with_extra_views(folder, tmp_path / "work")
    levels = sorted(p.name for p in (EXAMPLE / "truth").glob("*.exr"))
    assert sorted(p.name for p in hdr.glob("*.exr")) == sorted([*levels, "below_00.exr"])
    data = load_fit_data(hdr, poses, working_size=64)
    k = data.names.index("below_00")
    np.testing.assert_allclose(data.cameras[k].center, cam.center, atol=1e-9)
    twin = data.names.index(cam.name.replace(".jpg", ""))
    np.testing.assert_array_equal(data.images[k], data.images[twin])
    assert len(data.cameras) == len(levels) + 1
    assert truth_with_extra_views(EXAMPLE, tmp_path / "bare") == (
        EXAMPLE / "truth", EXAMPLE / "sparse" / "0")
