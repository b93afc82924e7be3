"""A splat far over the white shines about alike from every side (``view_dependence_cap``)."""

from __future__ import annotations

import numpy as np
import torch

from gaslight_usd.fit.model import SplatModel
from gaslight_usd.render.sh import eval_sh

LRS = {"means": 1e-3, "quats": 1e-3, "log_scales": 1e-3, "opacity_logits": 1e-2,
       "log_colour": 1e-2, "sh_rel": 1e-3}


def _two_splats(cap: float) -> tuple[SplatModel, torch.Tensor]:
    """A dim splat (radiance 1) and a lamp's (radiance 1000), both with a strong degree-1
    term along +x: relative to their colour, -1.5 x their own level to one side."""
    model = SplatModel.initial(np.zeros((2, 3)), np.array([[1.0] * 3, [1000.0] * 3]),
                               np.full(2, 0.01), 0.9, LRS)
    with torch.no_grad():
        model.t["sh_rel"][:, 2] = 3.0  # the x term of degree 1 (y, z, x order)
    model.view_dependence_cap = cap
    return model, torch.tensor([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])


def _seen(model: SplatModel, directions: torch.Tensor) -> np.ndarray:
    """(2 splats, 2 directions) luminance-like red channel."""
    p = model.params(degree=1)
    sh = torch.cat([p.sh_dc[:, None, :], p.sh_rest], dim=1).detach()
    return np.stack([eval_sh(sh, d.expand(2, 3), degree=1)[:, 0].numpy() for d in directions],
                    axis=1)


def test_uncapped_lamp_goes_dark_from_one_side() -> None:
    model, dirs = _two_splats(cap=0.0)
    seen = _seen(model, dirs)
    assert seen[1].min() == 0.0  # clamped at 0: the lamp hides from one side
    assert seen[1].max() > 1500.0


def test_capped_lamp_shines_alike_and_dim_splat_keeps_its_sheen() -> None:
    capped, dirs = _two_splats(cap=4.0)
    free, _ = _two_splats(cap=0.0)
    seen, seen_free = _seen(capped, dirs), _seen(free, dirs)
    # the lamp varies by at most the cap's swing (4 x 1.5 = 6 either way) around 1000
    np.testing.assert_allclose(seen[1], 1000.0, atol=6.5)
    assert seen[1].min() > 990.0
    # a splat under the cap is untouched, view dependence and all
    np.testing.assert_allclose(seen[0], seen_free[0], rtol=1e-6)
    assert seen[0].max() > 2.0 * max(seen[0].min(), 1e-3)


def test_cap_reaches_the_exported_scene() -> None:
    capped, _ = _two_splats(cap=4.0)
    scene = capped.to_scene(1, {})
    # the lamp's stored higher terms are the cap's, not its own level's
    assert np.abs(scene.sh[1, 1:]).max() < 4.0 * 3.0 + 1e-3
    assert np.abs(scene.sh[0, 1:]).max() > 2.9
