"""Pose refinement: the corrections' algebra, per-view Adam steps, recovery of
perturbed poses on a synthetic scene, and the refined poses the CLI writes."""

from __future__ import annotations

import dataclasses
import itertools
import json

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from gaslight_usd.cameras import PinholeCamera
from gaslight_usd.cli.main import main
from gaslight_usd.fit import fit_splats, preset
from gaslight_usd.fit.pose_refine import PoseRefiner, rotation_error_deg
from gaslight_usd.fit.synthetic import closed_scene, ring_cameras, synthetic_data
from gaslight_usd.imageio import write_exr
from gaslight_usd.poses.colmap import ColmapModel, read_model, write_model
from gaslight_usd.render import render


def perturbed(cams: list[PinholeCamera], degrees: float, shift: float, seed: int = 3,
              keep=lambda i: False) -> list[PinholeCamera]:
    rng = np.random.default_rng(seed)
    out = []
    for i, c in enumerate(cams):
        axis = rng.normal(size=3)
        turn = Rotation.from_rotvec(axis / np.linalg.norm(axis) * np.radians(degrees))
        move = rng.normal(0, shift, 3)
        if keep(i):
            out.append(c)
            continue
        out.append(dataclasses.replace(c, R=turn.as_matrix() @ c.R,
                                       t=turn.as_matrix() @ c.t + move))
    return out


def relative_rotation_error(cams, truth) -> float:
    """Median over view pairs of the error of their relative rotation (frame-free)."""
    return float(np.median([rotation_error_deg(cams[i].R @ cams[j].R.T,
                                               truth[i].R @ truth[j].R.T)
                            for i, j in itertools.combinations(range(len(cams)), 2)]))


def test_zero_correction_is_the_given_pose_and_rotates_about_the_centre():
    cams = ring_cameras(3)
    refiner = PoseRefiner(cams, 1e-3, 1e-3)
    R, t = refiner.pose(1)
    np.testing.assert_allclose(R.detach().numpy(), cams[1].R, atol=1e-6)
    np.testing.assert_allclose(t.detach().numpy(), cams[1].t, atol=1e-6)
    with torch.no_grad():
        refiner.params[1, :3] = torch.tensor([0.0, 0.1, 0.0])
    moved = refiner.cameras(cams)[1]
    # a pure rotation correction turns the camera about its own centre
    np.testing.assert_allclose(moved.center, cams[1].center, atol=1e-5)
    assert rotation_error_deg(moved.R, cams[1].R) == pytest.approx(np.degrees(0.1), rel=1e-4)


def test_a_step_moves_only_the_rendered_view_by_the_learning_rate():
    cams = ring_cameras(3)
    refiner = PoseRefiner(cams, 1e-3, 2e-2)
    R, t = refiner.pose(2)
    (R.sum() + 3.0 * t[0]).backward()
    grad = refiner.params.grad[2].clone()
    refiner.step(2)
    after = refiner.params.detach()
    assert torch.count_nonzero(after[:2]) == 0
    # Adam's first step is lr * sign(gradient)
    expected = -torch.tensor([1e-3] * 3 + [2e-2] * 3) * torch.sign(grad)
    torch.testing.assert_close(after[2], expected, atol=1e-7, rtol=1e-5)
    assert refiner.params.grad is None


@pytest.mark.slow
def test_refinement_brings_perturbed_poses_back():
    truth, data = synthetic_data(views=10, size=64)
    noisy = perturbed(data.cameras, 1.5, 0.02, keep=lambda i: i == 4)  # the held-out view
    before = relative_rotation_error(noisy, data.cameras)
    cfg = preset("fast").updated(working_size=0, iterations=500, init_points=1500,
                                 densify_every=40, refine_poses=True)
    result = fit_splats(dataclasses.replace(data, cameras=noisy), cfg, seed=0)
    after = relative_rotation_error(result.cameras, data.cameras)
    summary = result.metrics["pose_refinement"]
    assert summary["views"] == 9 and summary["rotation_deg_max"] > 0.1
    # the held-out view keeps the pose it was given
    np.testing.assert_array_equal(result.cameras[4].R, noisy[4].R)
    assert after < 0.8 * before, (before, after)


@pytest.mark.slow
def test_cli_writes_the_refined_poses_beside_the_splats(tmp_path):
    truth, cams = closed_scene(), ring_cameras()
    (tmp_path / "hdr").mkdir()
    for cam in cams:
        write_exr(tmp_path / "hdr" / f"{cam.name[:-4]}.exr", render(truth, cam).image.numpy(),
                  "lin_rec709", {"gaslight:exposure_scale": 1.0}, half=False)
    write_model(tmp_path / "sparse", ColmapModel(cameras=perturbed(cams, 1.0, 0.01)))
    out = tmp_path / "out" / "splats.ply"
    code = main(["fit", str(tmp_path / "hdr"), "--poses", str(tmp_path / "sparse"), "-o",
                 str(out), "--iterations", "60", "--refine-poses", "-q"])
    assert code == 0
    given = read_model(tmp_path / "sparse")
    refined = read_model(tmp_path / "out" / "splats.refined-poses")
    assert [c.name for c in refined.cameras] == [c.name for c in given.cameras]
    moved = [rotation_error_deg(a.R, b.R) for a, b in zip(refined.cameras, given.cameras,
                                                           strict=True)]
    assert max(moved) > 0.0
    assert moved[4] == 0.0  # the held-out view's pose is not touched
    assert refined.cameras[4].fx == given.cameras[4].fx
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    stage = next(s for s in report["stages"] if s["converter"] == "fit.splats")
    assert stage["metadata"]["refined_poses"].endswith("splats.refined-poses")
    assert stage["metadata"]["views"] == 8
