"""Where the photos saw light: cones from the views' regions over the white.

Views are rendered from a room of splats with a lamp and a window (tests/test_lights.py),
then the splats are spoiled as fits spoil them: a bright patch no photo saw, a lamp
pushed along the rays. The lights finder, given the views' sightings, undoes both.
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom
from test_lights import LAMP, room_scene

from gaslight_usd.fit.backdrop import concatenate
from gaslight_usd.fit.gather import aimed_camera
from gaslight_usd.lights import search_lights
from gaslight_usd.ply import read_ply, write_ply
from gaslight_usd.render import render
from gaslight_usd.sightings import Sightings, block_max, sight_lights
from gaslight_usd.splats import SplatScene
from gaslight_usd.usd.scene import ExportOptions, export_usd

Y709 = np.array([0.2126, 0.7152, 0.0722], np.float32)
SIZE = 96


def _cameras() -> list:
    """Eight photos from the middle of the room, each aimed between the lamp and the
    window (both framed whole where they are in front)."""
    angles = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    eyes = np.column_stack([0.9 * np.cos(angles), 1.4 + 0.1 * np.sin(angles),
                            0.9 * np.sin(angles) - 0.3])
    target = np.array([0.4, 1.8, 0.3])
    return [aimed_camera(e, target, 0.75, SIZE) for e in eyes]


def _views(scene: SplatScene, cams: list) -> list[np.ndarray]:
    return [render(scene, cam).image.numpy() for cam in cams]


def _with_sightings(scene: SplatScene, cams: list, images: list[np.ndarray]) -> SplatScene:
    meta = dict(scene.metadata)
    meta["cameras"] = {"centres": [c.center.tolist() for c in cams]}
    meta["light_sightings"] = sight_lights(cams, images, 1.0, Y709).as_dict()
    scene.metadata = meta
    return scene


def test_block_max_keeps_a_one_pixel_light():
    image = np.zeros((480, 640), np.float32)
    image[101, 333] = 9.0
    small, k = block_max(image)
    assert k == 4 and small.shape == (120, 160)
    assert small.max() == 9.0 and small[101 // 4, 333 // 4] == 9.0


def test_sightings_hold_the_lamp_not_the_dark_floor_and_survive_a_ply(tmp_path):
    scene, _ = room_scene()
    cams = _cameras()
    sightings = sight_lights(cams, _views(scene, cams), 1.0, Y709)
    assert sightings.count > 0 and sightings.whole.any()
    seen = sightings.seen(np.array([LAMP, [0.6, 0.8, -0.5]]))
    assert seen.tolist() == [True, False]
    # the cones travel in the PLY's metadata and read back the same
    scene = _with_sightings(scene, cams, _views(scene, cams))
    back = Sightings.from_metadata(read_ply(write_ply(tmp_path / "s.ply", scene)).metadata)
    assert back is not None and back.count == sightings.count
    np.testing.assert_allclose(back.axes, sightings.axes, atol=1e-5)
    np.testing.assert_allclose(back.radii, sightings.radii, atol=1e-5)
    # a light framed whole by several views is placed where their rays meet
    lamp = LAMP + np.random.default_rng(1).normal(0, 0.01, (20, 3))
    met = back.locate(lamp, np.ones(len(lamp)))
    assert met is not None and len(met["views"]) >= 2
    assert np.linalg.norm(met["position"] - LAMP) < 0.04


def test_a_bright_patch_no_photo_saw_is_not_a_light():
    scene, parts = room_scene()
    cams = _cameras()
    images = _views(scene, cams)
    # the fit's floater: a patch in the room far brighter than anything could light it,
    # where every photo saw a dim wall behind it
    rng = np.random.default_rng(2)
    patch_pos = np.array([0.6, 0.8, -0.5]) + rng.normal(0, 0.03, (12, 3))
    patch = SplatScene.from_activated(patch_pos, np.full((12, 3), 40.0), np.full((12, 3), 0.03),
                                      np.full(12, 0.9))
    spoiled = concatenate(patch, scene)  # first: the fit's backdrop stays last
    spoiled.metadata = dict(scene.metadata)
    patch_idx = np.arange(12)
    parts = {k: v + 12 for k, v in parts.items()}
    blind = search_lights(spoiled)
    assert blind.emitters[patch_idx].all()  # without the photos' word it is a light
    found = search_lights(_with_sightings(spoiled, cams, images))
    assert not found.emitters[patch_idx].any()
    assert found.emitters[parts["lamp"]].all() and found.emitters[parts["window"]].mean() > 0.9
    assert len(found.lights) == 2 and found.counts["unseen_not_lights"] == 1
    assert all(light.test["seen_share"] > 0.9 for light in found.lights)


def test_a_lamp_pushed_along_the_rays_goes_back_where_its_outlines_meet(tmp_path):
    scene, parts = room_scene()
    cams = _cameras()
    images = _views(scene, cams)
    # push the lamp 12 cm along the mean ray of the photos framing it: they still see it
    # inside its outline, but the fit put it at the wrong depth
    pos = scene.positions.copy()
    ray = LAMP - np.mean([c.center for c in cams], axis=0)
    pos[parts["lamp"]] += 0.12 * ray / np.linalg.norm(ray)
    pushed = SplatScene(pos, scene.rotations, scene.log_scales, scene.opacity_logits, scene.sh,
                        metadata=dict(scene.metadata))
    before = [li for li in search_lights(pushed).lights if li.radius < 0.1][0]
    assert np.linalg.norm(before.position - LAMP) > 0.1
    found = search_lights(_with_sightings(pushed, cams, images))
    lamp = [li for li in found.lights if li.radius < 0.1][0]
    assert found.counts["placed_by_outlines"] >= 1
    assert lamp.test["outline_baseline_deg"] >= 10.0
    assert np.linalg.norm(lamp.position - LAMP) < 0.04
    # the instancer's emitters are where the light is, not where the fit pushed them
    export_usd(pushed, tmp_path / "scene.usda", ExportOptions(variants=("instancer",)))
    stage = Usd.Stage.Open(str(tmp_path / "scene.instancer.usdc"))
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Emitters/Instancer"))
    points = np.asarray(inst.GetPositionsAttr().Get(), np.float64)
    near_lamp = np.linalg.norm(points - LAMP, axis=1) < 0.1
    assert near_lamp.sum() == len(parts["lamp"])


def test_a_light_clipped_at_the_white_is_a_region_whatever_the_float_sums_say():
    """A photo records a clipped lamp at its white in every channel; weighed into
    luminance in float32 that reads 0.9 on one CPU and 0.8999999 (1 ulp under) on another,
    and a region test against the white itself lost the lamp on the second machine."""
    from gaslight_usd.colour import AT_WHITE
    from gaslight_usd.fit.frame_edge import light_regions

    ratio = np.full((40, 40), 0.3, np.float32)
    ratio[10:14, 20:24] = np.nextafter(np.float32(1.0), np.float32(0.0))  # 1 ulp under
    ratio[30:33, 5:8] = np.float32(0.999)  # a surface a quarter of an 8-bit code under the white
    regions = light_regions(ratio)
    assert len(regions.centroids) == 1
    np.testing.assert_allclose(regions.centroids[0], [22.0, 12.0])
    assert 0.999 < AT_WHITE < 1.0
    # the same through a view: a lamp clipped at 0.9 in every channel
    image = np.full((40, 40, 3), 0.2, np.float32)
    image[10:14, 20:24] = 0.9
    cam = aimed_camera(np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), 0.6, 40)
    found = sight_lights([cam], [image], 0.9, np.array([0.2126, 0.7152, 0.0722], np.float32))
    assert len(found.view) == 1 and bool(found.whole[0])


def test_a_measured_views_region_points_at_the_bulb_not_the_lit_wall_round_it():
    """In a view that clipped nothing (merged brackets, true HDR) the wall a bare bulb
    lights is over the white too: one region, most of it wall. Its ray goes to the bulb;
    a clipped photo's region, whose values over the white are the uplift's guess, keeps
    its plain centroid, as does a measured region of even brightness."""
    from gaslight_usd.fit.frame_edge import pixel_rays

    def angle(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0))))

    cam = aimed_camera(np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), 0.6, 64)
    image = np.full((64, 64, 3), 0.2, np.float32)
    image[20:44, 20:44] = 2.0  # the lit wall, two whites
    image[22:24, 40:42] = 5000.0  # the bulb, near the glow's corner
    bulb = pixel_rays(cam, np.array([[41.0, 23.0]]))[0]
    middle = pixel_rays(cam, np.array([[32.0, 32.0]]))[0]
    assert angle(middle, bulb) > 5.0
    found = sight_lights([cam], [image], 1.0, Y709, measured=True)
    assert len(found.view) == 1
    assert angle(found.axes[0], bulb) < 1.5
    assert found.radii[0] >= np.radians(10.0)  # the cone still holds the whole region
    clipped = sight_lights([cam], [image], 1.0, Y709)  # a photo's region at its fill
    assert angle(clipped.axes[0], middle) < 0.5
    even = np.full((64, 64, 3), 0.2, np.float32)
    even[20:44, 20:44] = 2.0
    plain = sight_lights([cam], [even], 1.0, Y709, measured=True)
    assert angle(plain.axes[0], middle) < 0.5
