"""The room's walls and ceiling squashed flat onto their planes: a panel flush with the
ceiling is seen whole at a grazing angle, and a view square on draws the same.

The ceiling (y = 3) is drawn as a fit draws it: round splats 4 cm wide, their centres up
to 2 cm below it; a 0.4 m panel is flush with it (flat splats 300 times brighter)."""

from __future__ import annotations

import numpy as np
import torch
from test_flat_outlines import look_at
from test_fog import EXTENT, _box

from gaslight_usd.cameras import quaternion_to_matrix
from gaslight_usd.fit.sheets import SHEET_BAND_SHARE, sheet_splats, squashed
from gaslight_usd.render import render
from gaslight_usd.render.params import SplatParams
from gaslight_usd.splats import SplatScene

WEIGHTS = np.array([0.2126, 0.7152, 0.0722])
PANEL = np.array([1.0, 2.995, 0.9])
THIN = 0.005


def ceiling_with_panel() -> tuple[SplatScene, np.ndarray]:
    """Ceiling blobs round (not over) the panel, the panel's flat grid; the panel's rows."""
    gx, gz = np.meshgrid(np.arange(-2.4, 2.5, 0.06), np.arange(-1.9, 2.0, 0.06))
    rng = np.random.default_rng(7)
    ceiling = np.column_stack([gx.ravel(), 3.0 - rng.uniform(0.0, 0.02, gx.size), gz.ravel()])
    over = (np.abs(ceiling[:, 0] - PANEL[0]) < 0.3) & (np.abs(ceiling[:, 2] - PANEL[2]) < 0.3)
    ceiling = ceiling[~over]
    px, pz = np.meshgrid(np.arange(-0.18, 0.2, 0.045), np.arange(-0.18, 0.2, 0.045))
    grid = np.column_stack([PANEL[0] + px.ravel(), np.full(px.size, PANEL[1]),
                            PANEL[2] + pz.ravel()])
    pos = np.concatenate([ceiling, grid])
    rgb = np.concatenate([np.full((len(ceiling), 3), 1.0), np.full((len(grid), 3), 300.0)])
    scales = np.concatenate([np.full((len(ceiling), 3), 0.04),
                             np.tile([0.027, 0.002, 0.027], (len(grid), 1))])
    opac = np.concatenate([np.full(len(ceiling), 0.9), np.full(len(grid), 0.99)])
    scene = SplatScene.from_activated(pos, rgb, scales, opac)
    return scene, np.arange(len(ceiling), len(pos))


def panel_power(scene: SplatScene, cam, panel_rows: np.ndarray) -> tuple[float, float]:
    """Luminance the view draws over the panel's pixels (those its grid alone covers), and
    what the grid alone draws there."""
    params = SplatParams.from_scene(scene)
    image = render(params, cam, background=0.0, sh_degree=0).image.detach().numpy()
    alone = render(SplatParams.from_scene(scene.subset(panel_rows)), cam, background=0.0,
                   sh_degree=0).image.detach().numpy()
    mask = alone @ WEIGHTS > 30.0
    assert mask.sum() > 4
    return float((image @ WEIGHTS)[mask].sum()), float((alone @ WEIGHTS)[mask].sum())


def test_a_round_splat_on_a_plane_is_squashed_to_a_disc_with_the_same_footprint():
    rng = np.random.default_rng(3)
    n = 50
    pos = np.column_stack([rng.uniform(-2, 2, n), 3.0 - rng.uniform(0, 0.1, n),
                           rng.uniform(-1.5, 1.5, n)])
    scales = rng.uniform(0.03, 0.12, (n, 3))
    q = rng.normal(size=(n, 4))
    scene = SplatScene.from_activated(pos, np.ones((n, 3)), scales, np.full(n, 0.8),
                                      rotations=(q / np.linalg.norm(q, axis=1, keepdims=True)))
    rows, normals = sheet_splats(scene, _box(), EXTENT)
    np.testing.assert_array_equal(rows, np.arange(n))
    np.testing.assert_allclose(normals, np.tile([0.0, -1.0, 0.0], (n, 1)))
    out, count = squashed(scene, rows, normals, THIN)
    assert count == n

    def cov(s):
        r = quaternion_to_matrix(s.rotations)
        return np.einsum("nij,nj,nkj->nik", r, np.exp(2.0 * s.log_scales.astype(float)), r)

    before, after = cov(scene), cov(out)
    np.testing.assert_allclose(np.sqrt(after[:, 1, 1]), THIN, rtol=1e-3)  # along the normal
    # seen along the normal (the x-z block), each footprint is what it was
    np.testing.assert_allclose(after[:, [0, 0, 2, 2], [0, 2, 0, 2]],
                               before[:, [0, 0, 2, 2], [0, 2, 0, 2]], rtol=1e-3, atol=1e-7)
    np.testing.assert_allclose(out.positions, scene.positions)
    np.testing.assert_allclose(out.opacities, scene.opacities, rtol=1e-6)
    # already thin, far from every plane or exempt (a light): left alone
    assert squashed(out, rows, normals, THIN)[1] == 0
    middle = scene.subset(np.arange(n))
    middle.positions = middle.positions - [0.0, SHEET_BAND_SHARE * EXTENT + 0.1, 0.0]
    assert len(sheet_splats(middle, _box(), EXTENT)[0]) == 0
    exempt = np.zeros(n, bool)
    exempt[:10] = True
    np.testing.assert_array_equal(sheet_splats(scene, _box(), EXTENT, exempt)[0],
                                  np.arange(10, n))
    # no room box: nothing is a sheet
    assert len(sheet_splats(scene, [], EXTENT)[0]) == 0


def test_a_panel_flush_with_the_ceiling_is_seen_whole_at_a_grazing_angle():
    scene, panel = ceiling_with_panel()
    exempt = np.zeros(scene.count, bool)
    exempt[panel] = True
    rows, normals = sheet_splats(scene, _box(), EXTENT, exempt)
    assert not np.isin(panel, rows).any()
    flat, count = squashed(scene, rows, normals, THIN)
    assert count == len(rows) > 0
    with torch.no_grad():
        # 10 degrees below the panel, 2.7 m off: the ceiling's blobs hid most of it
        grazing = look_at([PANEL[0] - 2.66, 2.5, PANEL[2]], PANEL)
        drawn, alone = panel_power(scene, grazing, panel)
        squashed_drawn, _ = panel_power(flat, grazing, panel)
        assert drawn < 0.4 * alone  # 0.28 of it
        assert squashed_drawn > 0.75 * alone  # 0.83: the discs up to 2 cm below it hide its edge
        # straight below it, the same light as before
        below = look_at([PANEL[0], 1.5, PANEL[2] + 0.01], PANEL)
        drawn, alone = panel_power(scene, below, panel)
        squashed_drawn, _ = panel_power(flat, below, panel)
        np.testing.assert_allclose(squashed_drawn, drawn, rtol=0.02)
