"""A light the frame cuts in every photo that sees it is named (fit/frame_edge.py).

The stability sweep cropped the room's photos so its lamp sat on the frame's edge in
every photo that saw it (``--perturb light_half_out``); the fit lost the lamp and said
nothing. These tests run the check on the bundled example's true radiance (a perfect
uplift): as shot nothing is named; cropped as the sweep crops, the lamp is named where it
is; and the fit reports it."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import EXAMPLE, needs_example

from gaslight_usd.bench.perturb import CROP_WIDTH, edge_crop
from gaslight_usd.colour import luminance_weights
from gaslight_usd.fit.frame_edge import (
    CUT,
    LARGE_CUT,
    WHOLE,
    cut_lights,
    light_regions,
    meeting_points,
    white_ratios,
)
from gaslight_usd.imageio import read_image
from gaslight_usd.poses import read_poses
from gaslight_usd.resize import area_resize, fit_within

Y = luminance_weights("lin_rec709")


def test_regions_are_cut_compact_or_large_and_rays_meet():
    """A 40x30 view: a 3x3 lamp in the middle (whole), a 2x3 one on the left edge (cut),
    a wall over the white along the bottom (large, cut); two rays from (0,0,0) and
    (1,0,0) aimed at (0.5, 0, 2) meet there with no gap, parallel rays never."""
    ratio = np.full((30, 40), 0.3, np.float32)
    ratio[10:13, 20:23] = 12.0
    ratio[5:8, 0:2] = 9.0
    ratio[26:, :] = 1.5
    reg = light_regions(ratio)
    kinds = {int(reg.labels[11, 21]): WHOLE, int(reg.labels[6, 0]): CUT,
             int(reg.labels[28, 5]): LARGE_CUT}
    assert [int(reg.kind[k]) for k in kinds] == list(kinds.values())
    np.testing.assert_allclose(reg.centroids[reg.labels[11, 21] - 1], [21.5, 11.5])
    assert reg.peak[reg.labels[6, 0]] == pytest.approx(9.0)
    assert reg.nearest[6, 3] == reg.labels[6, 0] and reg.nearest[6, 5] == 0  # reach 2 px
    target = np.array([[0.5, 0.0, 2.0]])
    o1, o2 = np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0]])
    d1 = target / np.linalg.norm(target)
    d2 = (target - o2) / np.linalg.norm(target - o2)
    point, gap = meeting_points(o1, d1, o2, d2)
    np.testing.assert_allclose(point, target, atol=1e-12)
    assert gap[0] == pytest.approx(0.0, abs=1e-12)
    assert np.isinf(meeting_points(o1, d1, o2, d1)[1][0])


def example_views(crop: bool) -> tuple[list, list[np.ndarray], list[str], np.ndarray]:
    """The example's cameras and its true radiance as each photo's linear value
    (radiance x t x K: 1 is where the photo clips), shrunk to 120 px wide; ``crop``:
    cropped as ``--perturb light_half_out`` crops (the lamp on the edge, views with it
    in the middle dropped). Returns (cameras, linear views, names, the lamp's centre)."""
    info = json.loads((EXAMPLE / "scene.json").read_text())
    lamp = np.asarray(info["lamp"]["center"], np.float64)
    k = float(info["exposure"]["K"])
    cams, views, names = [], [], []
    for cam, entry in zip(read_poses(EXAMPLE / "sparse" / "0").cameras, info["views"],
                          strict=True):
        linear = read_image(EXAMPLE / entry["truth"]).pixels * np.float32(
            entry["exposure_time"] * k)
        if crop:
            x0 = edge_crop(cam, lamp)
            if x0 is None:
                continue
            width = int(round(cam.width * CROP_WIDTH))
            linear = linear[:, x0:x0 + width]
            cam = dataclasses.replace(cam, width=width, cx=cam.cx - x0)
        size = fit_within(cam.width, cam.height, 120)
        cams.append(cam)
        views.append(area_resize(np.ascontiguousarray(linear, np.float32), *size))
        names.append(Path(cam.name).stem)
    return cams, views, names, lamp


@needs_example
def test_a_lamp_cut_by_the_frame_in_every_photo_is_named():
    """As shot, every light is framed whole by some photo: nothing named. Cropped so the
    lamp sits on the frame's edge in every photo that sees it (17 of 24 kept), the lamp
    is named within 5 cm of where it is, with the photos that cut it, reading far over
    the white (the region's brightest pixel)."""
    cams, views, names, _ = example_views(crop=False)
    assert cut_lights(cams, white_ratios(views, 1.0, Y), names) == []
    cams, views, names, lamp = example_views(crop=True)
    assert len(cams) == 17
    found = cut_lights(cams, white_ratios(views, 1.0, Y), names)
    assert len(found) == 1
    light = found[0]
    assert np.linalg.norm(light.position - lamp) < 0.05
    assert len(light.views) >= 3 and set(light.views) <= set(names)
    assert light.peak > 10.0
    text = light.as_dict()["warning"]
    assert text.startswith("a light at (-0.") and "cut by the frame edge in every photo" in text
    assert "frame it whole in at least one photo" in text


@needs_example
def test_the_fit_reports_a_light_cut_by_the_frame(tmp_path):
    """The cropped views as fit data (relative radiance, clip floors where the photo
    clipped): the fit's metrics name the cut lamp (what the fit converter prints)."""
    from gaslight_usd.fit import fit_splats
    from gaslight_usd.fit.data import FitData
    from gaslight_usd.fit.presets import preset
    from gaslight_usd.poses.colmap import ColmapModel

    cams, views, names, lamp = example_views(crop=True)
    small = [dataclasses.replace(c, width=v.shape[1], height=v.shape[0],
                                 fx=c.fx * v.shape[1] / c.width, fy=c.fy * v.shape[0] / c.height,
                                 cx=c.cx * v.shape[1] / c.width, cy=c.cy * v.shape[0] / c.height)
             for c, v in zip(cams, views, strict=True)]
    floors = [np.where(v @ Y >= 1.0, np.float32(1.0), np.float32(0.0)) for v in views]
    data = FitData(names=names, cameras=small, images=views, model=ColmapModel(cameras=cams),
                   colour_space="lin_rec709", floors=floors)
    cfg = preset("fast").updated(working_size=0, iterations=4, init_points=200,
                                 densify_every=8, checkpoint_every=8, sh_raise_every=12,
                                 triangulate=False)
    found = fit_splats(data, cfg, seed=0).metrics["cut_lights"]
    assert len(found) == 1
    assert np.linalg.norm(np.array(found[0]["position"]) - lamp) < 0.05
    assert found[0]["warning"].startswith("a light at")
