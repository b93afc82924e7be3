"""Splats seeded on the compact clipped patches a fit leaves empty (gaslight_usd.fit.holes)."""

from __future__ import annotations

import numpy as np
import torch

from gaslight_usd.colour import REC709_Y
from gaslight_usd.fit import preset
from gaslight_usd.fit.data import FitData
from gaslight_usd.fit.gather import aimed_camera
from gaslight_usd.fit.holes import compact_patches, fill_holes
from gaslight_usd.fit.light_seeds import MAX_CONE_DEG
from gaslight_usd.fit.model import SplatModel
from gaslight_usd.fit.planes import Plane
from gaslight_usd.fit.trainer import Trainer
from gaslight_usd.poses.colmap import ColmapModel
from gaslight_usd.render import render
from gaslight_usd.splats import SplatScene

Y709 = np.array(REC709_Y, np.float32)


def _ceiling_with_gaps(gaps: list[tuple[float, float, float]], size: int = 128):
    """A ceiling at y = 3 of small flat splats with square gaps ``(x, z, side)`` in it (a
    panel one photo framed, which the fit left empty), seen from below."""
    g = np.arange(-1.0, 3.0, 0.05)
    x, z = np.meshgrid(g, g)
    pos = np.stack([x.ravel(), np.full(x.size, 3.0), z.ravel()], 1)
    keep = np.ones(len(pos), bool)
    for gx, gz, side in gaps:
        keep &= ~((np.abs(pos[:, 0] - gx) < side / 2) & (np.abs(pos[:, 2] - gz) < side / 2))
    pos = pos[keep]
    scales = np.tile([0.04, 0.002, 0.04], (len(pos), 1))
    scene = SplatScene.from_activated(pos, np.full((len(pos), 3), 0.4), scales,
                                      np.full(len(pos), 0.99),
                                      metadata={"antialiased": True})
    cam = aimed_camera(np.array([0.6, 1.2, 0.7]), np.array([1.0, 3.0, 1.0]), 0.6, size)
    return scene, cam


def test_a_compact_clipped_patch_no_splat_covers_gets_splats_on_the_surface_round_it():
    scene, cam = _ceiling_with_gaps([(1.0, 1.0, 0.25)])
    alpha = render(scene, cam).alpha.numpy()
    empty = alpha < 0.5
    assert empty.sum() > 60  # the gap shows through
    target = np.full(alpha.shape + (3,), 0.4, np.float32)
    target[empty] = 12.0  # the panel, as the uplift filled it
    holes = fill_holes(scene, [cam], [alpha], [target], ["view_14"], Y709, 1.0,
                       np.random.default_rng(0), [empty.copy()])
    assert holes.empty_pixels == {"view_14": int(empty.sum())}
    # one splat per 2 x 2 pixels of the gap, on the ceiling's plane, inside the gap
    assert abs(holes.count - empty.sum() / 4) <= 0.35 * empty.sum() / 4
    off = np.abs(holes.positions[:, 1] - 3.0)
    assert np.median(off) < 0.02 and off.max() < 0.2
    inside = (np.abs(holes.positions[:, [0, 2]] - 1.0) < 0.16).all(axis=1)
    assert inside.mean() > 0.95
    np.testing.assert_allclose(holes.colours, 12.0)
    assert np.all(holes.sizes > 0) and np.all(holes.sizes < 0.05)


def test_a_wide_clipped_patch_is_a_lit_surface_and_gets_nothing():
    # a 0.25 m gap (a panel) and a 0.9 m one (a lamp-lit stretch of ceiling) side by side
    scene, cam = _ceiling_with_gaps([(1.15, 1.0, 0.25), (0.35, 1.2, 0.9)])
    alpha = render(scene, cam).alpha.numpy()
    empty = alpha < 0.5
    target = np.repeat(np.where(empty, 12.0, 0.4)[..., None], 3, axis=2).astype(np.float32)
    holes = fill_holes(scene, [cam], [alpha], [target], ["v"], Y709, 1.0,
                       np.random.default_rng(0), [empty.copy()])
    assert holes.count > 10
    # only in the small gap: the wide one is left to the fit
    assert np.all(np.abs(holes.positions[:, 0] - 1.15) < 0.2)
    assert np.all(np.abs(holes.positions[:, 2] - 1.0) < 0.2)


def test_compact_patches_keeps_patches_within_the_compact_lights_cone():
    focal = 100.0
    pixels = np.zeros((200, 200), bool)
    small = np.radians(MAX_CONE_DEG) * focal * 0.6  # radius in pixels, well inside
    wide = np.radians(MAX_CONE_DEG) * focal * 1.6
    yy, xx = np.mgrid[:200, :200]
    pixels |= (yy - 40) ** 2 + (xx - 40) ** 2 <= small ** 2
    pixels |= (yy - 130) ** 2 + (xx - 130) ** 2 <= wide ** 2
    kept = compact_patches(pixels, focal)
    assert kept[40, 40] and not kept[130, 130]
    assert kept.sum() == ((yy - 40) ** 2 + (xx - 40) ** 2 <= small ** 2).sum()
    assert not compact_patches(np.zeros((8, 8), bool), focal).any()


def test_measured_pixels_dark_targets_and_covered_views_get_nothing():
    scene, cam = _ceiling_with_gaps([(1.0, 1.0, 0.25)])
    alpha = render(scene, cam).alpha.numpy()
    empty = alpha < 0.5
    lit = np.repeat(np.where(empty, 12.0, 0.4)[..., None], 3, axis=2).astype(np.float32)
    rng = np.random.default_rng(0)
    # the gap measured, not clipped: the fit's own loss fills it
    none_clipped = fill_holes(scene, [cam], [alpha], [lit], ["v"], Y709, 1.0, rng,
                              [np.zeros_like(empty)])
    assert none_clipped.count == 0 and none_clipped.empty_pixels == {}
    # a black target there is no surface to cover
    black = np.repeat(np.where(empty, 0.0, 0.4)[..., None], 3, axis=2).astype(np.float32)
    assert fill_holes(scene, [cam], [alpha], [black], ["v"], Y709, 1.0, rng,
                      [empty]).count == 0
    # a view its splats cover
    aside = aimed_camera(np.array([0.0, 1.2, -0.5]), np.array([0.0, 3.0, -0.2]), 0.4, 32)
    covered = render(scene, aside).alpha.numpy()
    assert covered.min() > 0.5
    assert fill_holes(scene, [aside], [covered], [np.full((32, 32, 3), 12.0, np.float32)],
                      ["v"], Y709, 1.0, rng, [np.ones((32, 32), bool)]).count == 0


def _ceiling_plane(height: float) -> Plane:
    """The room box's ceiling at ``height``, facing down to the cameras."""
    return Plane(normal=np.array([0.0, -1.0, 0.0]), offset=-height, lo=np.array([-3.0, -3.0]),
                 hi=np.array([3.0, 3.0]), axes=np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
                 points=100)


def _panel_hole():
    scene, cam = _ceiling_with_gaps([(1.0, 1.0, 0.25)])
    alpha = render(scene, cam).alpha.numpy()
    empty = alpha < 0.5
    target = np.repeat(np.where(empty, 12.0, 0.4)[..., None], 3, axis=2).astype(np.float32)
    return scene, cam, alpha, empty, target


def test_a_patch_under_the_photos_white_is_no_light_and_gets_nothing():
    scene, cam, alpha, empty, target = _panel_hole()
    rng = np.random.default_rng(0)
    assert fill_holes(scene, [cam], [alpha], [target], ["v"], Y709, 1.0, rng, [empty],
                      white=10.0).count > 10
    # the same patch where the photos' white is over its fill: a surface a brighter
    # view clipped, not a light
    assert fill_holes(scene, [cam], [alpha], [target], ["v"], Y709, 1.0, rng, [empty],
                      white=13.0).count == 0


def test_no_new_splat_lies_beyond_the_room_box():
    scene, cam, alpha, empty, target = _panel_hole()
    rng = np.random.default_rng(0)
    # the box's ceiling 0.2 m under the splats' (their smear): the patch's splats go onto it
    under = fill_holes(scene, [cam], [alpha], [target], ["v"], Y709, 1.0, rng, [empty],
                       planes=[_ceiling_plane(2.8)])
    assert under.count > 10
    np.testing.assert_allclose(under.positions[:, 1], 2.8, atol=1e-6)
    # a box plane beyond the surface round the hole changes nothing
    over = fill_holes(scene, [cam], [alpha], [target], ["v"], Y709, 1.0, rng, [empty],
                      planes=[_ceiling_plane(3.3)])
    assert np.median(np.abs(over.positions[:, 1] - 3.0)) < 0.02


def test_a_hole_another_view_draws_farther_away_is_a_wrong_depth_not_a_missing_light():
    scene, cam, alpha, empty, target = _panel_hole()
    rng = np.random.default_rng(0)
    # a second view of the same stretch of ceiling from further along the room
    other = aimed_camera(np.array([1.6, 1.0, 1.5]), np.array([1.0, 3.0, 1.0]), 0.6, 128)
    shown = np.full((128, 128, 3), 0.4, np.float32)
    none = np.zeros((128, 128), bool)
    alone = fill_holes(scene, [cam], [alpha], [target], ["v"], Y709, 1.0, rng, [empty])
    assert alone.count > 10
    # it draws nothing through the gap either: it says nothing, the splats stay
    open_above = fill_holes(scene, [cam, other], [alpha, render(scene, other).alpha.numpy()],
                            [target, shown], ["v", "w"], Y709, 1.0, rng, [empty, none])
    assert open_above.count >= 0.8 * alone.count
    # it draws a surface 0.5 m beyond the gap: it would show the new splats in front of
    # what it draws there, so the gap is the fit's wrong depth and gets nothing (the first
    # view's alpha is the gapped ceiling's, as a fit that put the light too far draws it)
    upper, _ = _ceiling_with_gaps([])
    both = SplatScene.from_activated(
        np.concatenate([scene.positions, upper.positions + [0.0, 0.5, 0.0]]),
        np.concatenate([scene.base_colours, upper.base_colours]),
        np.concatenate([scene.scales, upper.scales]),
        np.concatenate([scene.opacities, upper.opacities]), metadata={"antialiased": True})
    beyond = fill_holes(both, [cam, other], [alpha, render(both, other).alpha.numpy()],
                        [target, shown], ["v", "w"], Y709, 1.0, rng, [empty, none])
    assert beyond.count <= 0.1 * alone.count


def test_the_fit_seeds_a_one_photo_panel_at_the_end_of_its_densify_window():
    """The trainer's step: the panel's clipped pixels its splats leave empty get splats in
    its own model (fresh Adam moments), on the ceiling, and the fit reports them."""
    scene, cam, alpha, empty, target = _panel_hole()
    # a second view of the ceiling that does not frame the panel
    aside = aimed_camera(np.array([0.0, 1.2, -0.5]), np.array([0.0, 3.0, -0.2]), 0.4, 128)
    data = FitData(names=["view_14", "view_02"], cameras=[cam, aside],
                   images=[target, np.full((128, 128, 3), 0.4, np.float32)],
                   model=ColmapModel(cameras=[cam, aside]),
                   colour_space="Linear Rec.709 (sRGB)",
                   floors=[np.where(empty, 1.0, 0.0).astype(np.float32), None])
    trainer = Trainer(data, preset("fast").updated(holdout_every=0, plane_prior="off",
                                                    init_points=200))
    trainer._fresh()
    tensors = {"means": scene.positions, "quats": scene.rotations,
               "log_scales": scene.log_scales, "opacity_logits": scene.opacity_logits,
               "log_colour": np.log(np.maximum(scene.base_colours, 1e-4)),
               "sh_rel": np.zeros((scene.count, 15, 3), np.float32)}
    trainer.model = SplatModel({k: torch.as_tensor(np.asarray(v, np.float32))
                                for k, v in tensors.items()}, dict.fromkeys(tensors, 1e-3))
    trainer.room_planes = [_ceiling_plane(2.95)]
    # nothing over the white to seed: a fit over its budget is left as it is
    trainer._plane_white = 20.0
    trainer.cfg = trainer.cfg.updated(budget=scene.count // 2)
    trainer._fill_holes()
    assert trainer.holes_filled["splats"] == 0 and trainer.model.count == scene.count
    trainer.cfg = trainer.cfg.updated(budget=4 * scene.count)
    trainer._plane_white = 1.0
    trainer._fill_holes()
    added = trainer.holes_filled["splats"]
    assert added > 10 and trainer.model.count == scene.count + added
    assert list(trainer.holes_filled["empty_pixels"]) == ["view_14"]
    assert abs(trainer.holes_filled["empty_pixels"]["view_14"] - int(empty.sum())) <= 3
    new = trainer.model.t["means"].detach().numpy()[scene.count:]
    assert np.all(np.abs(new[:, 1] - 2.95) < 0.03)  # on the box's ceiling, not beyond it
    assert (np.abs(new[:, [0, 2]] - 1.0) < 0.2).all(axis=1).mean() > 0.9
    np.testing.assert_array_equal(trainer.model.t["means"].detach().numpy()[:scene.count],
                                  scene.positions)
