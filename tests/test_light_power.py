"""Clipped lights' power inferred from the surfaces they light (gaslight_usd.fit.power)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import needs_example
from test_lights import LAMP, _recoloured, room_scene
from test_sightings import _cameras, _views, _with_sightings

from gaslight_usd.cameras import PinholeCamera
from gaslight_usd.colour import REC709_Y
from gaslight_usd.fit.albedos import (
    ALBEDO_PRIOR_MEDIAN,
    evenness_floor,
    solve_factors,
    with_albedo_prior,
)
from gaslight_usd.fit.gather import aimed_camera, gather_irradiance
from gaslight_usd.fit.power import (
    LightPower,
    clipped_extent,
    infer_light_power,
    light_is_clipped,
    light_sighting,
    lights_to_weigh,
    measured_radiance,
    scaled_sh,
)
from gaslight_usd.render import render
from gaslight_usd.splats import SplatScene

Y709 = np.array(REC709_Y, np.float32)


def _flat(positions, size, colours, normal_axis=1, opacity=0.99):
    scales = np.full((len(positions), 3), size, np.float32)
    scales[:, normal_axis] = size * 0.03
    return SplatScene.from_activated(positions, colours, scales, np.full(len(positions), opacity),
                                     metadata={"antialiased": True})


def _concat(*scenes):
    return SplatScene(*(np.concatenate([getattr(s, a) for s in scenes]) for a in
                        ("positions", "rotations", "log_scales", "opacity_logits", "sh")),
                      metadata={"antialiased": True})


def test_light_irradiance_matches_a_gaussian_emitter():
    """One translucent Gaussian of radiance R, opacity a, std s at distance d straight above
    a point gives irradiance R a 2 pi s^2 / d^2 (its alpha footprint's integral)."""
    r, a, s, d = 50.0, 0.3, 0.05, 1.5
    lamp = SplatScene.from_activated(np.array([[0.0, d, 0.0]]), np.full((1, 3), r),
                                     np.full((1, 3), s), np.array([a]))
    irr = gather_irradiance(lamp, [np.array([0])], np.zeros((1, 3)),
                            np.array([[0.0, 1.0, 0.0]]), np.array([1e-3]), Y709)
    expected = r * a * 2 * math.pi * s * s / (d - 1e-3) ** 2
    assert irr[0, 0] == 0.0
    assert abs(irr[0, 1] / expected - 1) < 0.05


def test_a_cluster_of_tiny_opaque_splats_keeps_its_power_in_the_aimed_view(monkeypatch):
    """A bulb fitted as hundreds of 2 mm splats: drawn coarsely, each is widened to a
    pixel, the cluster turns translucent and the splats behind shine through. A faint halo
    of large splats (as fits grow round a bulb) widens the view aimed at it. That view is
    sized to the light's splats (``light_view_size``), so its irradiance is what a
    1024-pixel view gives, where 24 pixels overstate it."""
    from gaslight_usd.fit import gather

    rng = np.random.default_rng(0)
    n = 400
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    pos = dirs * 0.02 * rng.uniform(0, 1, (n, 1)) ** (1 / 3) + np.array([0.0, 1.5, 0.0])
    halo = np.array([0.0, 1.5, 0.0]) + 0.08 * np.vstack([np.eye(3), -np.eye(3)])
    bulb = SplatScene.from_activated(
        np.vstack([pos, halo]), np.vstack([np.full((n, 3), 100.0), np.full((6, 3), 0.5)]),
        np.vstack([np.full((n, 3), 0.002), np.full((6, 3), 0.04)]),
        np.concatenate([np.full(n, 0.99), np.full(6, 0.3)]), metadata={"antialiased": True})
    n += 6

    def gathered(least: int, most: int) -> float:
        monkeypatch.setattr(gather, "LIGHT_VIEW_SIZE", least)
        monkeypatch.setattr(gather, "MAX_LIGHT_VIEW_SIZE", most)
        return float(gather_irradiance(bulb, [np.arange(n)], np.zeros((1, 3)),
                                       np.array([[0.0, 1.0, 0.0]]), np.array([1e-3]),
                                       Y709)[0, 1])

    fine, coarse = gathered(1024, 1024), gathered(24, 24)
    default = gathered(24, 192)
    assert coarse > 1.15 * fine
    assert abs(default / fine - 1) < 0.05


def _room(k_true: float, seed: int = 0):
    """A floor of textured splats under a dome of sky splats (radiance 0.05, 6 m away) and a lamp of
    seven translucent splats, the floor lit by the lamp at k_true x its fitted radiance.

    The floor's radiance is analytic: albedo / pi x (pi x 0.05 from the sky + the lamp's
    splats as Gaussian emitters, R a 2 pi s^2 cos / d^2 each x k_true)."""
    rng = np.random.default_rng(seed)
    g = np.arange(-1.9375, 1.95, 0.125)
    fx, fz = np.meshgrid(g, g)
    floor_pos = np.stack([fx.ravel(), np.zeros(fx.size), fz.ravel()], 1)
    albedo = rng.uniform(0.15, 0.8, len(floor_pos))
    th, ph = np.meshgrid(np.linspace(0.05, 1.5, 14), np.linspace(0, 2 * np.pi, 48,
                                                                  endpoint=False))
    dome_pos = 6.0 * np.stack([np.sin(th) * np.cos(ph), np.cos(th), np.sin(th) * np.sin(ph)],
                              -1).reshape(-1, 3)
    dome = SplatScene.from_activated(dome_pos, np.full((len(dome_pos), 3), 0.05),
                                     np.full((len(dome_pos), 3), 0.65),
                                     np.full(len(dome_pos), 0.99))
    a = np.arange(7) * 2 * np.pi / 7
    lamp_pos = np.array([0.0, 1.2, 0.0]) + 0.08 * np.stack([np.cos(a), np.zeros(7),
                                                            np.sin(a)], 1)
    r_fit, opacity, sigma = 40.0, 0.3, 0.012
    lamp = SplatScene.from_activated(lamp_pos, np.full((7, 3), r_fit), np.full((7, 3), sigma),
                                     np.full(7, opacity))
    d = lamp_pos[None] - floor_pos[:, None]
    dist = np.linalg.norm(d, axis=-1)
    direct = (r_fit * opacity * 2 * np.pi * sigma ** 2 * d[..., 1] / dist ** 3).sum(1)
    radiance = albedo / np.pi * (np.pi * 0.05 + k_true * direct)
    floor = _flat(floor_pos, 0.08, np.repeat(radiance[:, None], 3, 1))
    scene = _concat(floor, dome, lamp)
    lamp_idx = np.arange(scene.count - 7, scene.count)
    # three views above the floor; the lamp clipped where it lands (floor 10: dimmer than
    # the fill of 40, as a photo records less than the light)
    cams = [PinholeCamera(64, 48, 40.0, 40.0, 32.0, 24.0, *_look(e, [0.0, 1.0, 0.0]))
            for e in ([2.5, 2.0, 0.5], [-2.0, 2.2, 1.5], [0.3, 2.4, -2.5])]
    floors = []
    for cam in cams:
        f = np.zeros((48, 64), np.float32)
        uv, _ = cam.project(lamp_pos)
        for u, v in uv:
            f[int(v) - 1:int(v) + 2, int(u) - 1:int(u) + 2] = 10.0
        floors.append(f)
    return scene, cams, floors, lamp_idx, len(floor_pos)


def _look(eye, target):
    cam = aimed_camera(np.array(eye, float), np.array(target, float), 0.6, 8)
    return cam.R, cam.t


def _photos(k_true: float, scramble: bool = False):
    """:func:`_room` seen by its three cameras as the photos saw it: the lamp at ``k_true``
    x its fitted radiance (so the floor's light is the lamp's), clipped where it lands.
    ``scramble``: the fit's floor splats swap colours among themselves (a fit's single
    splats are not the surface the photos measured; only their composite is)."""
    scene, cams, floors, lamp_idx, n_floor = _room(k_true)
    truth = scene.subset(np.arange(scene.count))
    truth.sh[lamp_idx] = scaled_sh(scene.sh[lamp_idx], k_true)
    images = [render(truth, cam).image.numpy() for cam in cams]
    if scramble:
        scene.sh[:n_floor] = scene.sh[np.random.default_rng(5).permutation(n_floor)]
    surfaces = np.zeros(scene.count, bool)
    surfaces[:n_floor] = True
    opaque = scene.opacities > 0.5
    light = LightPower(position=scene.positions[lamp_idx].mean(0), splats=lamp_idx,
                       radius=0.09)
    return scene, cams, images, floors, light, surfaces, opaque


def _weigh(k_true: float, scramble: bool = False):
    scene, cams, images, floors, light, surfaces, opaque = _photos(k_true, scramble)
    out = infer_light_power(scene, [light], cams, images, floors, Y709, surfaces, opaque,
                            extent=4.0, seed=1)
    return scene, out, light


def test_power_of_a_clipped_lamp_is_inferred_from_the_floor_the_photos_measured():
    """The lamp's fitted radiance is 16x (4 stops) short; the floor it lights says so."""
    scene, out, light = _weigh(16.0)
    inferred, sigma = (light.details["inferred_log2_factor"],
                       light.details["inferred_sigma_stops"])
    # the floor's albedo texture (0.15-0.8) dominates its variation: within 3/4 stop, and
    # the stated uncertainty covers the error
    assert abs(inferred - 4.0) <= 0.75
    assert abs(inferred - 4.0) <= 2.5 * sigma
    # the fill (k = 1) is only a lower bound: over it, the surfaces' word stands whole
    assert math.log2(light.factor) == pytest.approx(inferred)
    assert light.source == "inferred"
    assert light.uncertainty_stops == pytest.approx(sigma, abs=1e-3)
    assert not light.details["lower_bound"]  # the sky's light pins the albedos' scale
    lamp = light.splats
    ratio = out.base_colours[lamp].mean() / scene.base_colours[lamp].mean()
    assert abs(ratio / light.factor - 1) < 1e-4
    others = np.setdiff1d(np.arange(scene.count), lamp)
    np.testing.assert_array_equal(out.sh[others], scene.sh[others])


def test_surfaces_that_say_less_than_the_fill_leave_the_fill_as_its_bound():
    """The fit holds a clipped lamp at least at its fill; when its surfaces say it is
    dimmer (here it was fitted 2x too bright), the fill stands and says so."""
    _, out, light = _weigh(0.5)
    assert light.details["inferred_log2_factor"] < -0.5
    assert light.factor == 1.0 and light.source == "fused"
    assert light.uncertainty_stops == pytest.approx(light.details["inferred_sigma_stops"],
                                                    abs=1e-3)


def test_at_most_the_gathered_points_are_weighed_and_all_of_few(monkeypatch):
    """Of the candidates the photos measured, GATHERED_POINTS are gathered; where fewer
    qualify, every one is (a room that clips much keeps all it has)."""
    from gaslight_usd.fit import power

    def used(light):
        return light.details["surface_points"] + light.details["clipped_surface_points"]

    monkeypatch.setattr(power, "GATHERED_POINTS", 320)  # under the toy room's 1024
    _, _, light = _weigh(16.0)
    assert used(light) == power.GATHERED_POINTS
    monkeypatch.setattr(power, "SAMPLE_POINTS", 150)
    _, _, light = _weigh(16.0)
    assert 100 <= used(light) <= 150 < power.GATHERED_POINTS
    assert abs(light.details["inferred_log2_factor"] - 4.0) <= 0.75


def test_a_point_only_one_view_sees_is_neither_measured_nor_bounded(monkeypatch):
    """One view cannot place a point (a floater in front of a wall reads as the wall behind
    it): with fewer than MIN_VIEWS views seeing it, a point says nothing."""
    from gaslight_usd.fit import power

    scene, cams, images, floors, _, _, _ = _photos(16.0)
    points = scene.positions[:1024:7].astype(np.float64)
    normals = np.tile([0.0, 1.0, 0.0], (len(points), 1))
    both = measured_radiance(scene, points, normals, cams, images, floors, Y709)
    alone = measured_radiance(scene, points, normals, cams[:1], images[:1], floors[:1], Y709)
    assert np.isfinite(both[0]).sum() > 0.5 * len(points)
    assert not np.isfinite(alone[0]).any() and not np.isfinite(alone[1]).any()
    monkeypatch.setattr(power, "MIN_VIEWS", 1)
    trusted = measured_radiance(scene, points, normals, cams[:1], images[:1], floors[:1],
                                Y709)[0]
    agree = np.isfinite(trusted) & np.isfinite(both[0])
    assert agree.sum() > 0.3 * len(points)
    # a matte floor reads alike from every view (each 3x3 block blurs its texture a little
    # differently)
    assert abs(np.median(np.log2(trusted[agree] / both[0][agree]))) < 0.05


def test_the_photos_not_the_splats_colours_say_what_the_surfaces_reflect():
    """Shuffled floor splat colours leave the photos (and the answer) as they were; the
    splats' colours alone would say nothing (a uniform random texture, no lamp in it)."""
    _, _, light = _weigh(16.0, scramble=True)
    assert abs(light.details["inferred_log2_factor"] - 4.0) <= 0.75


def test_surfaces_clipped_under_the_lamp_are_bounds_not_left_out():
    """Near a clipped lamp the photos clip the surfaces it lights brightest too. Left out,
    they select the darker ones, whose albedos only look like the rest's at a lower
    factor; as bounds ("at least the white") they keep the factor where it is."""
    rng = np.random.default_rng(3)
    n = 300
    rest = rng.uniform(0.2, 1.0, n)  # irradiance from everything but the lamp
    lamp = rest * rng.lognormal(0.0, 1.5, n) * 0.02  # the lamp as fitted: 6 stops short
    albedo = np.exp(rng.normal(np.log(0.3), 0.5, n))  # a textured surface
    radiance = albedo / math.pi * (rest + 64.0 * lamp)
    white = float(np.quantile(radiance, 0.7))
    clipped = radiance > white
    measured = np.where(clipped, np.nan, radiance)
    bound = np.where(clipped, white, np.nan)
    irr = np.stack([rest, lamp], 1)
    with_bounds = solve_factors(measured, bound, irr)[0]
    left_out = solve_factors(measured[~clipped], bound[~clipped], irr[~clipped])[0]
    assert abs(with_bounds - 6.0) <= 0.25
    assert left_out <= 6.0 - 0.75  # the bias the bounds remove


def test_a_lamp_whose_floor_clips_is_weighed_through_the_bounds():
    """The synthetic room with every pixel over a white clipped (a quarter of the sampled
    floor points, those the lamp lights most): they count as bounds, and the factor stays
    within 3/4 stop."""
    scene, cams, images, floors, light, surfaces, opaque = _photos(16.0)
    lum = np.concatenate([(img @ Y709).ravel() for img in images])
    white = float(np.quantile(lum[lum < 5.0], 0.9))
    for img, f in zip(images, floors, strict=True):
        over = (img @ Y709) > white
        f[over] = np.maximum(f[over], white)
        img[over] *= (white / (img[over] @ Y709))[:, None]
    infer_light_power(scene, [light], cams, images, floors, Y709, surfaces, opaque,
                      extent=4.0, seed=1)
    assert light.details["clipped_surface_points"] >= 20
    assert abs(light.details["inferred_log2_factor"] - 4.0) <= 0.75


def test_a_lamp_the_fit_got_right_is_left_alone():
    _, out, light = _weigh(1.0)
    assert abs(light.details["inferred_log2_factor"]) <= 0.75
    assert math.log2(light.factor) <= 0.75


def test_a_light_inside_a_wide_clipped_region_is_part_of_a_wide_source():
    """A fit may cut a window into lights of its own; the photos' clipped region around a
    light says how wide its source is (the second smallest view's reading)."""
    scene, cams, _, floors, light, _, _ = _photos(16.0)
    small = clipped_extent(light.position, cams, floors)
    assert 0.0 < small < 0.3  # the lamp's 3x3-pixel blobs, about 2.3 m away
    wide = [f.copy() for f in floors]
    for f in wide[:2]:
        f[:, 16:48] = 10.0  # two views see it inside a clipped region half the frame wide
    assert clipped_extent(light.position, cams, wide) > 1.0
    wide[1] = floors[1]  # one view alone does not make it wide
    assert clipped_extent(light.position, cams, wide) < 0.3


def test_a_lamp_some_photo_measured_is_not_weighed():
    scene, cams, images, floors, light, _, _ = _photos(16.0)
    assert light_is_clipped(light.position, cams, images, floors, Y709, white=1.0)
    floors[1] = None  # a darker frame: it saw the lamp unclipped, far over the white
    assert not light_is_clipped(light.position, cams, images, floors, Y709, white=1.0)


def test_a_light_no_view_frames_is_unseen_not_clipped():
    """A stray bright splat outside every training view: no photo says it clipped."""
    scene, cams, images, floors, light, _, _ = _photos(16.0)
    assert light_sighting(light.position, cams, images, floors, Y709, white=1.0) == "clipped"
    behind = 2.0 * cams[0].center - light.position  # behind the first camera
    assert cams[0].project(behind[None])[1][0] < 0
    assert light_sighting(behind, [cams[0]], [images[0]], [floors[0]], Y709,
                          white=1.0) == "unseen"
    assert not light_is_clipped(behind, [cams[0]], [images[0]], [floors[0]], Y709, white=1.0)


def test_scaled_sh_scales_the_radiance_not_the_offset_coefficients():
    sh = np.random.default_rng(0).normal(0, 0.5, (5, 4, 3)).astype(np.float32)
    scene = SplatScene(np.zeros((5, 3), np.float32), np.tile([1, 0, 0, 0], (5, 1)).astype(
        np.float32), np.zeros((5, 3), np.float32), np.zeros(5, np.float32), sh)
    scaled = SplatScene(scene.positions, scene.rotations, scene.log_scales,
                        scene.opacity_logits, scaled_sh(sh, 3.0))
    np.testing.assert_allclose(scaled.base_colours[scene.base_colours > 0],
                               3.0 * scene.base_colours[scene.base_colours > 0], rtol=1e-5)
    np.testing.assert_allclose(scaled.sh[:, 1:], 3.0 * sh[:, 1:], rtol=1e-6)


def test_a_lamp_left_nine_stops_short_is_still_weighed_by_the_floor_it_lights():
    """As fitted, a lamp 9 stops short gives the floor 0.2 % of its light; the factor is
    judged where the floor's albedos are even, not as fitted (the lights the uplift
    leaves shortest are the ones to correct). At the right power the lamp gives the floor
    almost all its light, so the albedos' spread no longer depends on the factor and the
    cap (three quarters of them matte, at most 1) decides: a lower bound, and said."""
    _, _, light = _weigh(512.0)
    assert "note" not in light.details
    assert light.details["lower_bound"]
    assert 9.0 - 1.25 <= light.details["inferred_log2_factor"] <= 9.0 + 0.25
    assert light.source == "inferred" and math.log2(light.factor) >= 9.0 - 1.5


@pytest.mark.slow
@needs_example
def test_the_examples_lamp_is_weighed_from_its_photos(tmp_path):
    """The bundled example's photos clip its lamp, and the uplift leaves it about 6.5 stops
    short (``gaslight2usd bench --suite chain``); the fit weighs it by the surfaces it lights
    and puts it within two stops, says where that came from, and leaves the window (a
    broad light) at the uplift's power. ``--uplift-power`` turns it off."""
    from gaslight_usd.cli.main import main
    from gaslight_usd.locate import example_room
    from gaslight_usd.ply import read_ply

    example = example_room()
    lamp = np.array(json.loads((example / "scene.json").read_text())["lamp"]["center"])
    assert main(["hdr", str(example / "photos"), "-o", str(tmp_path / "hdr"), "-q"]) == 0
    # the second fit only shows the weighing switched off: a few steps do
    for flags, name in (([], "weighed.ply"), (["--uplift-power", "--iterations", "30"],
                                              "uplift.ply")):
        assert main(["fit", str(tmp_path / "hdr"), "--poses", str(example / "sparse" / "0"),
                     "-o", str(tmp_path / name), "-q", *flags]) == 0
    weighed = read_ply(tmp_path / "weighed.ply").metadata["fit_metrics"]["clipped_lights"]
    at_lamp = [li for li in weighed if np.linalg.norm(np.array(li["position"]) - lamp) < 0.1]
    assert len(at_lamp) == 1 and at_lamp[0]["power_source"] in ("inferred", "fused")
    assert 4.5 <= math.log2(at_lamp[0]["factor"]) <= 8.5
    assert at_lamp[0]["power_uncertainty_stops"] < 1.5
    others = [li for li in weighed if li is not at_lamp[0]]
    assert all(li["factor"] == 1.0 and "note" in li for li in others)
    plain = read_ply(tmp_path / "uplift.ply").metadata
    assert plain["provenance"]["config"]["infer_power"] is False
    assert plain["fit_metrics"]["clipped_lights"] == []


def _two_lights(pattern_b, k_a: float, k_b: float, seed: int = 0):
    """Radiances of 300 matte points (albedos 0.2-0.5) lit by the rest of the room, which
    falls off across them, and two lights at ``2**k`` times their fills; light A's
    irradiance grows across the points, light B's follows ``pattern_b`` (per point, at
    its fill)."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, 300)
    irr = np.stack([0.2 * (2.0 - x), 0.01 * (0.2 + 2.0 * x), pattern_b(x)], axis=1)
    albedo = rng.uniform(0.2, 0.5, 300)
    radiance = albedo * (irr[:, 0] + 2.0**k_a * irr[:, 1] + 2.0**k_b * irr[:, 2]) / math.pi
    return radiance, np.full(300, np.nan), irr


def test_two_lights_the_surfaces_see_alike_share_one_factor():
    """Where two lights light the surfaces alike the albedos pin their sum, not the
    split: one factor for both (the separate search gives +4.9 and +1.6 here)."""
    radiance, bound, irr = _two_lights(lambda x: 0.01 * (0.25 + 1.9 * x), 4.0, 4.0)
    k = solve_factors(radiance, bound, irr)
    assert k[0] == k[1]
    assert abs(k[0] - 4.0) <= 0.5


def test_two_lights_the_surfaces_tell_apart_keep_their_own_factors():
    """Light B lights only the far half of the points: the albedos there say its factor."""
    radiance, bound, irr = _two_lights(lambda x: 0.02 * (x > 0.5) * x, 2.0, 5.0)
    k = solve_factors(radiance, bound, irr)
    assert abs(k[0] - 2.0) <= 0.5 and abs(k[1] - 5.0) <= 0.5


def _one_light_everywhere_alike(k_true: float, median_albedo: float, seed: int = 0):
    """300 matte points whose light from the lamp is the same share of their light
    everywhere (a bare bulb amid the room): the albedos' uniformity cannot say ``k``."""
    rng = np.random.default_rng(seed)
    rest = rng.uniform(0.05, 0.4, 300)
    irr = np.stack([rest, 0.02 * rest], axis=1)  # the lamp: 5/6 of it at k = 8
    albedo = median_albedo * 2.0 ** rng.normal(0.0, 0.7, 300)
    radiance = albedo * (irr[:, 0] + 2.0**k_true * irr[:, 1]) / math.pi
    return radiance, np.full(300, np.nan), irr


def test_the_albedos_level_decides_where_their_uniformity_cannot():
    """The uniformity is flat along ``k`` here; a search on it lands anywhere and its
    bootstrap runs to the search's ends (given as +13, 6 stops uncertain). The surfaces'
    median albedo (0.3, the prior's) pins the lamp at its true +8."""
    radiance, bound, irr = _one_light_everywhere_alike(8.0, ALBEDO_PRIOR_MEDIAN)
    k, sigma = with_albedo_prior(np.array([13.0]), np.array([6.0]), radiance, bound, irr)
    assert abs(k[0] - 8.0) <= 0.5
    assert sigma[0] < 2.0  # the level narrowed it
    darker = _one_light_everywhere_alike(8.0, ALBEDO_PRIOR_MEDIAN / 2.0)
    k_dark, _ = with_albedo_prior(np.array([13.0]), np.array([6.0]), *darker)
    # a room a stop darker than the prior's reads its lamp dimmer (the measured level
    # moves it), by less than that stop over the lamp's share
    assert 8.0 - 1.25 <= k_dark[0] <= k[0] - 0.5
    # where the photos only bounded most points (clipped in every view) the level is not
    # measured: the uniformity's estimate stands as it came
    clipped = np.arange(300) % 5 != 0
    bounded = np.where(clipped, radiance * 0.9, np.nan)
    k_b, sigma_b = with_albedo_prior(np.array([13.0]), np.array([6.0]),
                                     np.where(clipped, np.nan, radiance), bounded, irr)
    assert k_b[0] == 13.0 and sigma_b[0] == 6.0


def test_a_sharp_uniformity_is_not_moved_by_the_albedos_level():
    """Light surfaces (albedo 0.6-0.9, two stops over the prior's median) and a lamp whose
    share falls off across them: the uniformity pins it, the prior barely pulls."""
    radiance, bound, irr = _two_lights(lambda x: 0.0 * x, 5.0, 0.0)
    radiance = radiance * 2.0  # albedos 0.4-1.0
    irr = irr[:, :2]
    k0 = solve_factors(radiance, bound, irr)
    assert abs(k0[0] - 5.0) <= 0.5
    k, sigma = with_albedo_prior(k0, np.array([0.2]), radiance, bound, irr)
    assert abs(k[0] - k0[0]) <= 0.25 and sigma[0] <= 0.25


def _level_room(seed: int = 0):
    """300 points: the lamp's fitted irradiance, the rest of the room's, albedos around 0.3
    (half a stop), the lamp 2^10 over its fill."""
    rng = np.random.default_rng(seed)
    n = 300
    lamp = rng.uniform(0.5, 2.0, n) * 1e-3
    rest = rng.uniform(0.8, 1.2, n)
    albedo = ALBEDO_PRIOR_MEDIAN * 2 ** rng.normal(0, 0.5, n)
    radiance = albedo / math.pi * (rest + 2 ** 10 * lamp)
    return radiance, np.full(n, np.nan), np.stack([rest, lamp], 1), rng


def test_an_evenness_that_runs_off_the_search_is_a_floor_not_a_centre():
    """Where the albedos only grow more even the brighter the light, up to the search's
    end, their evenness says "at least this", not "this": the level decides above that
    floor, and the search's end no longer pulls the factor up."""
    radiance, bound, irr, rng = _level_room()
    interior = solve_factors(radiance, bound, irr)
    assert abs(interior[0] - 10.0) <= 0.5
    assert np.isnan(evenness_floor(interior, radiance, bound, irr)[0])  # a centre, no floor
    ran_off, sigma = np.array([16.0]), np.array([1.0])
    as_centre = with_albedo_prior(ran_off, sigma, radiance, bound, irr)[0][0]
    below = with_albedo_prior(ran_off, sigma, radiance, bound, irr, at_least=np.array([9.0]))
    above = with_albedo_prior(ran_off, sigma, radiance, bound, irr, at_least=np.array([12.0]))
    assert as_centre > 13.0  # dragged towards the search's end
    assert abs(below[0][0] - 10.0) <= 0.5  # the level decides above the floor
    assert 11.0 <= above[0][0] <= 12.0  # a floor over the truth still holds it up, softly
    # noise in the rest of the room's gathered irradiance (2 stops) makes it run off
    noisy = irr.copy()
    noisy[:, 0] *= 2 ** rng.normal(0, 2.0, len(noisy))
    best = solve_factors(radiance, bound, noisy)
    floor = evenness_floor(best, radiance, bound, noisy)
    assert best[0] == 16.0 and 10.0 < floor[0] < 16.0


def _lamp_and_lit_patch(patch_albedo: float, patch_fill: float):
    """:func:`_photos` (the lamp 4 stops over its fill) and a pale patch on the floor 1.7 m
    from the lamp's foot that the photos clipped at what it truly reflects, fitted as a
    bright cluster (``patch_fill``) the lights finder took for a light."""
    scene, cams, images, floors, light, surfaces, opaque = _photos(16.0)
    lamp = scene.subset(light.splats)
    centre = np.array([1.2, 0.02, 1.2])
    a = np.arange(6) * 2 * np.pi / 6
    spots = centre + 0.06 * np.stack([np.cos(a), np.zeros(6), np.sin(a)], 1)
    # what the patch reflects: the sky (pi 0.05) and the lamp's seven splats at 16x
    d = lamp.positions[None].astype(np.float64) - centre[None, None]
    dist = np.linalg.norm(d, axis=-1)
    r, s = lamp.base_colours[:, 0].astype(np.float64), lamp.scales[:, 0].astype(np.float64)
    direct = (16.0 * r * lamp.opacities * 2 * np.pi * s ** 2 * d[..., 1] / dist ** 3).sum()
    truth = patch_albedo / np.pi * (np.pi * 0.05 + direct)
    patch = _flat(spots, 0.05, np.full((6, 3), patch_fill))
    scene = _concat(scene, patch)
    idx = np.arange(scene.count - 6, scene.count)
    surfaces, opaque = np.append(surfaces, np.zeros(6, bool)), scene.opacities > 0.5
    framed = 0
    for cam, img, f in zip(cams, images, floors, strict=True):
        uv, z = cam.project(spots)
        for (u, v), depth in zip(uv, z, strict=True):
            if depth > 0 and 1 <= u < 63 and 1 <= v < 47:
                f[int(v) - 1:int(v) + 2, int(u) - 1:int(u) + 2] = truth
                img[int(v) - 1:int(v) + 2, int(u) - 1:int(u) + 2] = truth
                framed += 1
    assert framed >= 6
    patch_light = LightPower(position=centre, splats=idx, radius=0.08)
    return scene, cams, images, floors, [light, patch_light], surfaces, opaque, truth


def test_a_pale_surface_the_photos_clipped_is_not_weighed_as_a_light():
    """A patch the lamp lights, clipped where the photos see it, reads no brighter than a
    matte surface of albedo 0.7 there: it keeps its fill and says why; the lamp beside it
    is weighed as it is alone."""
    scene, cams, images, floors, lights, surfaces, opaque, _ = _lamp_and_lit_patch(
        0.7, patch_fill=4.0 * 0.7 * 0.5)
    out = infer_light_power(scene, lights, cams, images, floors, Y709, surfaces, opaque,
                            extent=4.0, seed=1)
    lamp, patch = lights
    assert patch.factor == 1.0 and patch.source == "predicted"
    assert "lit surface" in patch.details["note"]
    # it faces its views, not the lamp: a little less light than its upward face gets
    assert 0.5 <= patch.details["lit_surface_albedo"] <= 1.0
    np.testing.assert_array_equal(out.sh[patch.splats], scene.sh[patch.splats])
    assert abs(lamp.details["inferred_log2_factor"] - 4.0) <= 0.75
    assert lamp.details["lit_surface_albedo"] > 10.0
    assert lamp.source == "inferred"


def test_a_clipped_patch_brighter_than_any_lit_surface_is_weighed_as_a_light():
    """The same patch read 5x brighter than white paper would be there: no surface, a
    light."""
    scene, cams, images, floors, lights, surfaces, opaque, _ = _lamp_and_lit_patch(
        5.0, patch_fill=4.0)
    infer_light_power(scene, lights, cams, images, floors, Y709, surfaces, opaque,
                      extent=4.0, seed=1)
    patch = lights[1]
    assert patch.details["lit_surface_albedo"] > 2.0
    assert "inferred_log2_factor" in patch.details
    assert "lit surface" not in patch.details.get("note", "")


def _clipped_room(lamp_rgb):
    """``test_lights``' room (its lamp coloured ``lamp_rgb``) seen by eight photos that
    clip at the white (1): the scene with their sightings and the photos' outlines placing
    a light at the lamp (``light_seeds``), their cameras, views and clip floors."""
    scene, parts = room_scene()
    rgb = scene.base_colours.copy()
    rgb[parts["lamp"]] = lamp_rgb
    scene = _recoloured(scene, rgb)
    cams = _cameras()
    images = _views(scene, cams)
    floors = [np.where((img @ Y709) >= 1.0, np.float32(1.0), np.float32(0.0)) for img in images]
    clipped = [np.minimum(img, 1.0) for img in images]
    scene = _with_sightings(scene, cams, clipped)
    scene.metadata["light_seeds"] = [{"position": LAMP.tolist(), "size": 0.05,
                                      "views": [0, 1], "framed": 2}]
    return scene, cams, clipped, floors


def test_a_light_the_uplift_filled_at_its_clip_level_is_not_weighed():
    """A clipped cluster the uplift filled at about the white is a surface that just
    clipped, as the uplift read it: weighed, such a patch of ceiling over the chain
    bench's sunlit floor took that floor's light and came out 2^15 times its fill (the
    photos' outlines had placed a light there). A lamp filled well over the white is
    weighed."""
    lamp_found = []
    for level, weighed in ((20.0, True), (1.2, False)):
        scene, cams, images, floors = _clipped_room([level, level, level])
        weigh, keep, _, _ = lights_to_weigh(scene, cams, images, floors, Y709)
        at_lamp = [entry for entry in weigh + keep
                   if np.linalg.norm(entry.position - LAMP) < 0.1]
        assert len(at_lamp) == 1
        lamp_found.append(at_lamp[0])
        assert any(entry is at_lamp[0] for entry in weigh) == weighed
    note = lamp_found[1].details["note"]
    assert "filled it under 1.5 x the white" in note and lamp_found[1].source == "predicted"


def test_an_uncertain_weighing_that_is_surely_over_the_fill_is_taken(monkeypatch):
    """The fill is a lower bound: surfaces that put a lamp 9 stops over it, give or take
    more than the fill's own 3 stops, still rule the fill out (one-sided, 95 %), as a
    shaded lamp's clipped surroundings did; where the same stops are no surer than that,
    the fill stands. (Round a shaded lamp the photos clip most surfaces, so their albedos'
    level is not weighed: nor is it here.)"""
    from gaslight_usd.fit import albedos, power

    monkeypatch.setattr(albedos, "LEVEL_MEASURED_SHARE", 2.0)
    monkeypatch.setattr(power, "SYSTEMATIC_STOPS", 4.5)
    _, _, light = _weigh(512.0)
    inferred, sigma = (light.details["inferred_log2_factor"],
                       light.details["inferred_sigma_stops"])
    assert sigma > power.MAX_INFERRED_SIGMA_STOPS
    assert inferred >= power.SURE_OVER_FILL_SIGMAS * sigma
    assert light.source == "inferred" and "note" not in light.details
    assert math.log2(light.factor) == pytest.approx(inferred)
    assert light.uncertainty_stops == pytest.approx(sigma, abs=1e-3)

    monkeypatch.setattr(power, "SYSTEMATIC_STOPS", 7.0)
    _, _, light = _weigh(512.0)
    assert light.details["inferred_log2_factor"] < (power.SURE_OVER_FILL_SIGMAS
                                                    * light.details["inferred_sigma_stops"])
    assert light.source == "predicted" and light.factor == 1.0
    assert "not surely over its fill" in light.details["note"]


def test_where_the_level_is_not_measured_an_evenness_that_ran_off_gives_its_floor(
        monkeypatch):
    """Round a shaded lamp the photos clip most surfaces, so their albedos' level is not
    weighed; an evenness that runs off the search's top then says only "at least this".
    The floor is the factor (a lower bound), not the search's top (which no acceptance
    takes, leaving the light at its fill, a lower bound stops under the floor)."""
    from gaslight_usd.fit import albedos

    monkeypatch.setattr(albedos, "LEVEL_MEASURED_SHARE", 2.0)
    radiance, bound, irr, _ = _level_room()
    ran_off, sigma = np.array([16.0]), np.array([2.5])
    k, spread = with_albedo_prior(ran_off, sigma, radiance, bound, irr,
                                  at_least=np.array([9.0]))
    assert k[0] == 9.0 and spread[0] == 2.5
    k, _ = with_albedo_prior(ran_off, sigma, radiance, bound, irr)
    assert k[0] == 16.0  # no floor: the search's top, which the weighing refuses
    interior = np.array([10.0])
    k, _ = with_albedo_prior(interior, sigma, radiance, bound, irr, at_least=np.array([np.nan]))
    assert k[0] == 10.0


def test_a_lamp_whose_evenness_runs_off_unmeasured_is_raised_to_its_floor(monkeypatch):
    """The lamp 9 stops short, the rest of the room's gathered light noisy (3 stops, as a
    fit's stray splats can make it) so that the albedos grow more even up to the search's
    end, and their level not weighed: the lamp is raised to the evenness's floor and says
    it is a lower bound. (Such noise biases the evenness up, as it biases its minimum
    where it does not run off: ``docs/lights.md``; the floor is trusted as much.)"""
    from gaslight_usd.fit import albedos, power

    monkeypatch.setattr(albedos, "LEVEL_MEASURED_SHARE", 2.0)
    gather = power.gather_irradiance
    rng = np.random.default_rng(3)

    def noisy_gather(*args, **kwargs):
        irr = gather(*args, **kwargs)
        if len(irr) > 1:  # the surface points, not the lamp's own place
            irr[:, 0] *= 2.0 ** rng.normal(0.0, 3.0, len(irr))
        return irr

    monkeypatch.setattr(power, "gather_irradiance", noisy_gather)
    _, _, light = _weigh(512.0)
    floor = light.details["uniformity_at_least"]
    assert light.details["uniformity_ran_off"] and floor is not None
    assert light.details["uniformity_log2_factor"] == 16.0
    assert 0.0 < floor < 16.0
    assert light.details["inferred_log2_factor"] == pytest.approx(floor)
    assert light.source == "inferred" and light.details["lower_bound"]
    assert "note" not in light.details
    assert math.log2(light.factor) == pytest.approx(floor)
