"""The splat renderer against hand-computed cases, its dense reference, and
OpenEXR's cube-map convention."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
import torch

from gaslight_usd.cameras import CUBE_FACES, PinholeCamera, latlong_directions
from gaslight_usd.imageio import read_image, write_exr
from gaslight_usd.render import (
    RASTERIZER_ENV,
    RASTERIZERS,
    SplatParams,
    rasterizer_for,
    render,
    render_reference,
)
from gaslight_usd.render.envmap import (
    cube_face_cameras,
    cube_to_latlong,
    latlong_to_cube,
    render_cube,
    render_latlong,
)
from gaslight_usd.render.sh import C0, C1, eval_sh
from gaslight_usd.splats import SplatScene


def camera(size=65, f=100.0, R=None, t=None) -> PinholeCamera:
    return PinholeCamera(size, size, f, f, size / 2, size / 2,
                         np.eye(3) if R is None else R, np.zeros(3) if t is None else t)


def one_splat(pos, colour, scale, opacity, sh_degree=0) -> SplatScene:
    return SplatScene.from_activated(np.array([pos], float), np.array([colour], float),
                                     np.array([[scale] * 3]), np.array([opacity]),
                                     sh_degree=sh_degree)


def random_scene(n, rng, sh_degree=3) -> SplatScene:
    s = SplatScene.from_activated(rng.uniform([-1, -1, 2], [1, 1, 4], (n, 3)),
                                  rng.uniform(0, 3, (n, 3)), rng.uniform(0.01, 0.1, (n, 3)),
                                  rng.uniform(0.05, 0.99, n), rotations=rng.normal(size=(n, 4)),
                                  sh_degree=sh_degree)
    s.sh[:, 1:] = rng.normal(0, 0.2, s.sh[:, 1:].shape)
    return s


def surrounding_params(n, rng, half, scales, sh_degree, antialiased) -> SplatParams:
    """Splats all round the origin (within +-``half``), of sizes ``scales`` (lo, hi)."""
    scene = random_scene(n, rng, sh_degree=sh_degree)
    scene.positions[:] = rng.uniform(-half, half, (n, 3)).astype(np.float32)
    scene.log_scales[:] = np.log(rng.uniform(*scales, (n, 3))).astype(np.float32)
    scene.metadata = {"antialiased": antialiased}
    return SplatParams.from_scene(scene)


def test_isotropic_gaussian_peak_and_width():
    # Splat on the optical axis at z=5, std 0.05 -> 1 px at f=100, plus the 0.3 px^2 dilation.
    scene = one_splat([0, 0, 5], [4.0, 2.0, 1.0], 0.05, 0.5)
    out = render(scene, camera())
    img = out.image.numpy()
    # Pixel (32, 32) has its centre at 32.5 = cx: the peak, alpha = opacity.
    np.testing.assert_allclose(img[32, 32], [2.0, 1.0, 0.5], rtol=1e-5)
    var = 1.0 + 0.3
    for k in (1, 2, 3):
        expect = 0.5 * np.exp(-0.5 * k * k / var)
        np.testing.assert_allclose(out.alpha[32, 32 + k].item(), expect, rtol=1e-4)
        np.testing.assert_allclose(out.alpha[32 - k, 32].item(), expect, rtol=1e-4)
    # Beyond alpha < 1/255 nothing is drawn.
    assert out.alpha[32, 32 + 5].item() == 0.0


def test_hdr_colour_is_not_clamped_above_and_alpha_is_capped():
    scene = one_splat([0, 0, 5], [500.0, 0.0, 20.0], 0.2, 1.0 - 1e-6)
    img = render(scene, camera()).image.numpy()
    np.testing.assert_allclose(img[32, 32], [0.99 * 500, 0, 0.99 * 20], rtol=1e-4)


def test_front_to_back_order():
    red = one_splat([0, 0, 4], [1, 0, 0], 0.5, 0.6)
    green = one_splat([0, 0, 6], [0, 1, 0], 0.5, 0.8)

    def both(front, back):
        return SplatScene(*(np.concatenate([getattr(front, k), getattr(back, k)])
                            for k in ("positions", "rotations", "log_scales",
                                      "opacity_logits", "sh")))

    for scene in (both(red, green), both(green, red)):  # input order must not matter
        px = render(scene, camera(), background=(0, 0, 1.0)).image.numpy()[32, 32]
        np.testing.assert_allclose(px, [0.6, 0.4 * 0.8, 0.4 * 0.2], rtol=1e-4)


def test_sh_colour_at_known_direction():
    sh = torch.zeros(1, 4, 3)
    sh[0, 0] = 1.0
    sh[0, 2] = torch.tensor([0.5, -2.0, 0.0])  # the C1 * z term
    along_z = eval_sh(sh, torch.tensor([[0.0, 0.0, 1.0]]))
    np.testing.assert_allclose(along_z[0].numpy(),
                               [0.5 + C0 + 0.5 * C1, max(0.0, 0.5 + C0 - 2 * C1), 0.5 + C0],
                               rtol=1e-6)
    # The same through the renderer: the view direction is splat - camera centre.
    scene = one_splat([0, 0, 5], [0, 0, 0], 0.3, 1.0 - 1e-6, sh_degree=1)
    scene.sh[0] = sh[0].numpy()
    px = render(scene, camera()).image.numpy()[32, 32] / 0.99
    np.testing.assert_allclose(px, along_z[0].numpy(), rtol=1e-4)
    # Degree 0 ignores the higher terms.
    px0 = render(scene, camera(), sh_degree=0).image.numpy()[32, 32] / 0.99
    np.testing.assert_allclose(px0, [0.5 + C0] * 3, rtol=1e-4)


@pytest.mark.parametrize("rasterizer", RASTERIZERS)
@pytest.mark.parametrize("tile", [8, 16])
def test_tiled_matches_dense_reference_values_and_gradients(tile, rasterizer, monkeypatch):
    monkeypatch.setenv(RASTERIZER_ENV, rasterizer)
    rng = np.random.default_rng(1)
    scene = random_scene(250, rng)
    cam = PinholeCamera(70, 50, 60, 60, 33, 26, np.eye(3), np.zeros(3))
    weights = torch.as_tensor(rng.uniform(0, 1, (50, 70, 3)), dtype=torch.float32)
    grads = []
    for fn in (lambda p: render(p, cam, background=0.2, tile=tile),
               lambda p: render_reference(p, cam, background=0.2)):
        p = SplatParams.from_scene(scene, requires_grad=True)
        out = fn(p)
        (out.image * weights).sum().backward()
        grads.append((out.image.detach(), out.alpha.detach(),
                      {k: v.grad for k, v in p.tensors().items()}))
    (img_a, alpha_a, g_a), (img_b, alpha_b, g_b) = grads
    assert img_b.max() > 1.0
    torch.testing.assert_close(img_a, img_b, atol=1e-4, rtol=1e-4)
    torch.testing.assert_close(alpha_a, alpha_b, atol=1e-5, rtol=1e-4)
    for k in g_a:
        scale = float(g_b[k].abs().max())
        assert float((g_a[k] - g_b[k]).abs().max()) <= 2e-5 * scale + 1e-6, k


@pytest.mark.parametrize("antialiased", [False, True])
def test_the_frustum_test_keeps_every_splat_a_view_draws(antialiased):
    """in_frustum (render_many's cull before the covariance work) may only drop splats
    render would not draw: narrow, wide, cube-face and off-axis views; the narrow view
    leaves few splats to project."""
    from gaslight_usd.render.project import OPACITY_LOGIT_MIN, in_frustum, jacobian_limits

    params = surrounding_params(3000, np.random.default_rng(4), 3.0, (0.005, 0.4), 0,
                                antialiased)
    views = [camera(24, 12.0), camera(16, 200.0), *cube_face_cameras([0.3, -0.2, 0.1], 12),
             PinholeCamera(40, 30, 30.0, 30.0, 5.0, 28.0, np.eye(3), np.array([0.5, 0, 1]))]
    kept = []
    for cam in views:
        R = torch.as_tensor(cam.R, dtype=torch.float32)
        t = torch.as_tensor(cam.t, dtype=torch.float32)
        keep = in_frustum(params.means @ R.T + t, torch.exp(params.log_scales.max(1).values),
                          params.opacity_logits > OPACITY_LOGIT_MIN,
                          torch.tensor([[cam.fx, cam.fy, cam.cx, cam.cy]]),
                          torch.tensor([jacobian_limits(cam)]), (cam.width, cam.height), 0.01)
        drawn = render(params, cam, near=0.01).index
        assert len(drawn) > 0 and bool(keep[drawn].all())
        kept.append(int(keep.sum()))
    assert kept[1] < 300  # the narrow view (of 3000 splats, about half in front)


def test_many_small_views_in_one_pass_match_one_render_each():
    """render_many draws each view as render does: cube faces at several points and
    narrow views of different focal lengths, each with its own near plane; large splats
    near a view's edge must not bleed into the next view's block of the atlas."""
    from gaslight_usd.render.many import render_many

    rng = np.random.default_rng(5)
    params = surrounding_params(1500, rng, 2.0, (0.01, 0.5), 1, True)
    cams = [c for p in rng.uniform(-1, 1, (3, 3)) for c in cube_face_cameras(p, 12)]
    cams += [PinholeCamera(12, 12, f, f, 6.0, 6.0, np.eye(3), np.array([0.0, 0.0, 2.5]))
             for f in (4.0, 30.0, 300.0)]
    nears = rng.uniform(0.01, 0.3, len(cams))
    many = render_many(params, cams, near=nears, background=0.2)
    with torch.no_grad():
        one = np.stack([render(params, c, near=n, background=0.2).image.numpy()
                        for c, n in zip(cams, nears, strict=True)])
    assert many.shape == (len(cams), 12, 12, 3)
    assert one.std() > 0.1
    np.testing.assert_allclose(many, one, atol=1e-4 * one.max(), rtol=1e-3)


def _opaque_stack_gradients(threads: int) -> tuple[torch.Tensor, dict]:
    import numba

    rng = np.random.default_rng(4)
    scene = random_scene(3000, rng)
    scene.opacity_logits[:] = 4.0  # opaque: most pixels stop early (transmittance < 1e-4)
    cam = PinholeCamera(96, 64, 80, 80, 48, 32, np.eye(3), np.zeros(3))
    p = SplatParams.from_scene(scene, requires_grad=True)
    default = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        out = render(p, cam, background=0.5)
        (out.image * torch.linspace(0, 1, out.image.numel()).reshape(out.image.shape)
         ).sum().backward()
    finally:
        numba.set_num_threads(default)
    return out.image.detach(), {k: v.grad for k, v in p.tensors().items()}


def test_numba_kernels_match_torch_on_opaque_stacks_and_ignore_thread_count(monkeypatch):
    """Early termination, the 0.99 alpha cap and the per-pair gradient sums: numba against
    the vectorised torch version, and bit-identical whatever the thread count."""
    monkeypatch.setenv(RASTERIZER_ENV, "numba")
    image_1, grads_1 = _opaque_stack_gradients(1)
    image_2, grads_2 = _opaque_stack_gradients(2)
    assert torch.equal(image_1, image_2)
    for k in grads_1:
        assert torch.equal(grads_1[k], grads_2[k]), k
    monkeypatch.setenv(RASTERIZER_ENV, "torch")
    image_t, grads_t = _opaque_stack_gradients(1)
    torch.testing.assert_close(image_1, image_t, atol=1e-4, rtol=1e-4)
    for k in grads_t:
        scale = float(grads_t[k].abs().max())
        assert scale > 0, k
        assert float((grads_1[k] - grads_t[k]).abs().max()) <= 1e-4 * scale, k


def test_rasterizer_choice(monkeypatch):
    from gaslight_usd.render.rasterize import rasterize
    from gaslight_usd.render.rasterize_numba import rasterize_numba

    monkeypatch.delenv(RASTERIZER_ENV, raising=False)
    assert rasterizer_for(torch.device("cpu"), torch.float32) is rasterize_numba
    assert rasterizer_for(torch.device("cpu"), torch.float64) is rasterize
    monkeypatch.setenv(RASTERIZER_ENV, "torch")
    assert rasterizer_for(torch.device("cpu"), torch.float32) is rasterize
    monkeypatch.setenv(RASTERIZER_ENV, "numba")
    with pytest.raises(ValueError, match="float32"):
        rasterizer_for(torch.device("cpu"), torch.float64)
    monkeypatch.setenv(RASTERIZER_ENV, "cuda-magic")
    with pytest.raises(ValueError, match="expected one of numba, torch"):
        rasterizer_for(torch.device("cpu"), torch.float32)


@pytest.mark.parametrize("antialiased", [False, True])
def test_antialiased_mode_keeps_a_tiny_splats_power_at_any_resolution(antialiased, tmp_path):
    """A splat 0.2 px wide at f=100: its image integral (per steradian, sum / f^2) should not
    depend on the camera's resolution. The plain 0.3 px^2 dilation inflates it where the splat
    is sub-pixel; the antialiased mode keeps it within 5% of the analytic power (what it
    loses is the tail under the 1/255 alpha cut, which rises as the opacity is scaled down)."""
    from gaslight_usd.ply import read_ply, write_ply

    scene = one_splat([0, 0, 5], [1.0, 1.0, 1.0], 0.01, 0.9)
    if antialiased:
        scene.metadata["antialiased"] = True
        scene = read_ply(write_ply(tmp_path / "aa.ply", scene))  # the flag travels in the PLY
        assert SplatParams.from_scene(scene).antialiased
    truth = 0.9 * 2 * np.pi * (0.01 / 5) ** 2  # opacity x Gaussian integral, steradians
    power = {}
    for f in (100.0, 400.0, 1600.0):
        size = int(f * 0.12) | 1
        img = render(scene, camera(size=size, f=f)).image.numpy()
        power[f] = float(img[..., 0].sum()) / f ** 2
    if antialiased:
        for f, value in power.items():
            assert value == pytest.approx(truth, rel=0.05), f
    else:
        assert power[100.0] > 2.0 * truth  # 0.2 px splat: dilated to ~1.1 px, 30x the area
        assert power[1600.0] == pytest.approx(truth, rel=0.05)  # 3.2 px: the dilation is small


def test_nothing_in_front_gives_background():
    scene = one_splat([0, 0, -3], [1, 1, 1], 0.5, 0.9)
    out = render(scene, camera(), background=(0.25, 0.5, 1.0))
    np.testing.assert_allclose(out.image.numpy(), np.broadcast_to([0.25, 0.5, 1.0],
                                                                  (65, 65, 3)))
    assert out.alpha.abs().max() == 0


def test_scene_round_trip_through_params():
    rng = np.random.default_rng(2)
    scene = random_scene(20, rng, sh_degree=2)
    back = SplatParams.from_scene(scene).to_scene({"colour_space": "ACEScg"})
    np.testing.assert_array_equal(back.sh, scene.sh)
    np.testing.assert_array_equal(back.positions, scene.positions)
    assert back.metadata["colour_space"] == "ACEScg"


# -- environment maps -------------------------------------------------------------------

def _openexr_direction(face: str, col: int, row: int, size: int) -> np.ndarray:
    """OpenEXR CubeMap::direction for a data-window pixel, pixelPosition inverted by hand."""
    s = size - 1
    pif = {"+X": (s - row, col), "-X": (s - row, s - col), "+Y": (col, s - row),
           "-Y": (col, row), "+Z": (s - col, s - row), "-Z": (col, s - row)}[face]
    a, b = (pif[0] / s * 2 - 1), (pif[1] / s * 2 - 1)
    d = {"+X": (1, a, b), "-X": (-1, a, b), "+Y": (a, 1, b), "-Y": (a, -1, b),
         "+Z": (a, b, 1), "-Z": (a, b, -1)}[face]
    d = np.array(d, float)
    return d / np.linalg.norm(d)


def test_cube_face_cameras_follow_openexr():
    size = 6
    cams = cube_face_cameras([1.0, 2.0, 3.0], size)
    assert [c.name for c in cams] == list(CUBE_FACES)
    for cam in cams:
        np.testing.assert_allclose(cam.center, [1, 2, 3], atol=1e-12)
        dirs = cam.ray_directions()
        for row in range(size):
            for col in range(size):
                np.testing.assert_allclose(dirs[row, col],
                                           _openexr_direction(cam.name, col, row, size),
                                           atol=1e-12)


def test_latlong_cube_round_trip():
    d = latlong_directions(128, 64)
    image = ((1 + 0.5 * d[..., :1] + d[..., 1:2] ** 2) * [1, 2, 3]).astype(np.float32)
    back = cube_to_latlong(latlong_to_cube(image, 48), 128)
    assert back.shape == image.shape
    assert np.abs(back - image).max() < 0.01


@pytest.mark.skipif(shutil.which("exrenvmap") is None,
                    reason="needs OpenEXR's exrenvmap: apt-get install openexr")
def test_latlong_to_cube_matches_exrenvmap(tmp_path):
    d = latlong_directions(256, 128)
    image = (1.5 + d[..., 0:1] * [1, 0, 0] + d[..., 1:2] * [0, 1, 0] + d[..., 2:3] * [0, 0, 1])
    src = write_exr(tmp_path / "ll.exr", image.astype(np.float32), "lin_rec709",
                    {"textureformat": "LatLong Environment"}, half=False)
    dst = tmp_path / "cube.exr"
    subprocess.run(["exrenvmap", "-c", "-w", "16", "-f", "1", "1", str(src), str(dst)],
                   check=True, capture_output=True)
    theirs = read_image(dst).pixels.reshape(6, 16, 16, 3)
    ours = latlong_to_cube(image.astype(np.float32), 16)
    assert np.abs(theirs - ours).max() < 0.03


@pytest.mark.parametrize("direction", [(0.3, 0.2, 1.0), (1.0, -1.0, 0.7)])
def test_coarse_latlong_keeps_a_small_lights_power(direction):
    """A "lamp" of 300 overlapping opaque splats 0.34 degrees wide (a cluster about 2.8
    degrees across) in a 64-wide panorama (5.6 degree pixels). Drawn once per pixel it
    carries 3.5x its power (widened splats, the cluster no longer opaque); the default
    supersampling (pixels as averages of a 1024-wide drawing here) keeps it within 5% of a
    drawing at twice that resolution."""
    from gaslight_usd.render.envmap import latlong_supersample

    rng = np.random.default_rng(0)
    d = np.asarray(direction) / np.linalg.norm(direction)
    n = 300
    scene = SplatScene.from_activated(2.0 * d + rng.normal(0, 0.024, (n, 3)),
                                      np.full((n, 3), 100.0), np.full((n, 3), 0.012),
                                      np.full(n, 0.95), sh_degree=0)
    scene.metadata["antialiased"] = True
    width = 64
    assert latlong_supersample(width) == 16
    rows = (np.arange(width // 2) + 0.5) / (width // 2)
    solid = np.cos(np.pi * (0.5 - rows))[:, None] * (2 * np.pi / width) * (np.pi / (width // 2))

    def power(supersample=None):
        pano = render_latlong(scene, [0.0, 0.0, 0.0], width, supersample=supersample)
        return float((pano[..., 0] * solid).sum())

    reference = power(32)
    assert power() == pytest.approx(reference, rel=0.05)
    assert power(1) > 2.0 * reference


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
def test_gpu_panoramas_match_the_cpus():
    rng = np.random.default_rng(3)
    n = 2000
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    scene = SplatScene.from_activated(dirs * rng.uniform(1.5, 3.0, (n, 1)),
                                      rng.uniform(0.1, 50.0, (n, 3)), np.full((n, 3), 0.08),
                                      rng.uniform(0.3, 0.95, n), sh_degree=0)
    cpu = render_latlong(scene, [0.1, 0.0, -0.2], 128)
    gpu = render_latlong(scene, [0.1, 0.0, -0.2], 128, device="cuda")
    assert isinstance(gpu, np.ndarray) and gpu.shape == cpu.shape == (64, 128, 3)
    np.testing.assert_allclose(gpu, cpu, rtol=1e-3, atol=1e-4 * cpu.max())


def test_probe_sees_splats_on_the_right_faces():
    # A bright splat along +X and a dim one along -Z, seen from the origin.
    scene = SplatScene.from_activated(np.array([[3.0, 0, 0], [0, 0, -3.0]]),
                                      np.array([[10.0, 0, 0], [0, 2.0, 0]]),
                                      np.full((2, 3), 0.3), np.array([0.9, 0.9]))
    faces = render_cube(scene, [0, 0, 0], 33)
    plus_x, minus_z = CUBE_FACES.index("+X"), CUBE_FACES.index("-Z")
    assert faces[plus_x, 16, 16, 0] > 5 and faces[plus_x, ..., 1].max() < 1e-6
    assert faces[minus_z, 16, 16, 1] > 1 and faces[minus_z, ..., 0].max() < 1e-6
    pano = render_latlong(scene, [0, 0, 0], 128)
    assert pano.shape == (64, 128, 3)
    # OpenEXR lat-long: +X a quarter width from the left, -Z at the left/right edge.
    row, col = np.unravel_index(np.argmax(pano[..., 0]), pano.shape[:2])
    assert abs(col - 32) <= 1 and abs(row - 32) <= 1
    assert pano[32, 0, 1] > 1 and pano[32, 127, 1] > 1
    # A splat behind the probe's near plane on every face is not drawn at all.
    near = SplatScene.from_activated(np.array([[0.0, 0, 0]]), np.array([[5.0, 5, 5]]),
                                     np.full((1, 3), 0.3), np.array([0.9]))
    assert render_cube(near, [0, 0, 0], 8).max() == 0


def test_a_panorama_drawn_again_comes_from_the_last_draw_and_a_changed_scene_does_not(
        monkeypatch):
    """``run``'s export and its ``hdri`` stage draw the same probe 2048 wide; the second
    is the first box-filtered again, while any change to the splats or the probe redraws."""
    from gaslight_usd.render import envmap

    rng = np.random.default_rng(1)
    n = 200
    scene = SplatScene.from_activated(rng.normal(0, 1.0, (n, 3)) + [0, 0, 3.0],
                                      rng.uniform(0.1, 2.0, (n, 3)), np.full((n, 3), 0.05),
                                      np.full(n, 0.9), sh_degree=0)
    draws = []
    real = envmap._draw_fine
    monkeypatch.setattr(envmap, "_draw_fine", lambda *a: draws.append(a[2]) or real(*a))
    envmap._FINE_DRAWN.clear()
    small = render_latlong(scene, [0.0, 0.0, 0.0], 16, supersample=8)
    large = render_latlong(scene, [0.0, 0.0, 0.0], 64, supersample=2)
    assert draws == [128]
    np.testing.assert_allclose(small, large.reshape(8, 4, 16, 4, 3).mean(axis=(1, 3)),
                               rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(large, render_latlong(scene, [0.0, 0.0, 0.0], 64,
                                                     supersample=2))
    assert draws == [128]
    brighter = SplatScene.from_activated(scene.positions, scene.base_colours * 2.0,
                                         scene.scales, scene.opacities, sh_degree=0)
    twice = render_latlong(brighter, [0.0, 0.0, 0.0], 64, supersample=2)
    render_latlong(brighter, [0.0, 0.1, 0.0], 64, supersample=2)
    assert draws == [128, 128, 128]
    np.testing.assert_allclose(twice, 2.0 * large, rtol=1e-4, atol=1e-5)
