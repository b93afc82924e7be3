"""Blender as a consumer of the instancer export (PyPI ``bpy`` in its own venv).

The exported ``--as instancer`` scene is imported by Blender's own USD
importer (tests/consumers/blender_import.py, run by the bpy interpreter), and
what arrived is checked against what we wrote: every emitter present, at its
place and size, with its colour; and a Cycles render of a grey Lambertian
ground lit only by those emitters matches the irradiance a sphere of that
radius and radiance casts, is bright under each lamp, in the lamp's colour,
and dark far away.

The bpy interpreter comes from ``$GASLIGHT_BPY_PYTHON`` or ``.venv-bpy/bin/python``
at the repository root; without one the test is skipped (see
tests/consumers/README.md for the two-command set-up).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdShade

from gaslight_usd.colour import REC709_Y
from gaslight_usd.ply import write_ply
from gaslight_usd.splats import SplatScene
from gaslight_usd.usd.instancer import emitter_mask

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "tests" / "consumers" / "blender_import.py"
EXPORT = Path(sys.executable).with_name("gaslight2usd")

LAMPS_USD = np.array([[-1.2, 1.0, 0.4], [1.2, 1.0, 0.4], [0.0, 1.0, -1.2]])
"""Lamp centres in the splats' frame (+Y up, metres): 1 m above the floor y = 0."""
LAMP_RGB = np.array([[12.0, 1.0, 0.5], [0.5, 9.0, 1.0], [1.0, 1.5, 15.0]])
LAMP_SIGMA = 0.06
FAINT_USD = np.array([[-2.5, 1.5, -2.5], [2.5, 1.5, -2.5]])
"""Two emitters just above the threshold (max channel 1.3 and 1.1), far corners."""
FAINT_RGB = np.array([[1.3, 1.0, 0.9], [0.8, 1.1, 0.9]])
ALBEDO = 0.8
SIZE, SAMPLES, WINDOW_PX = 64, 64, 3
CAMERA_HEIGHT, LENS_MM = 6.0, 35.0
LUMA = np.array(REC709_Y)
RADIANCE_TOLERANCE = 0.12
"""Cycles noise in a 29-pixel window at 64 spp is about 3 % (1 sigma); converged
(1024 spp) the windows are within 0.3 % of the analytic value."""


def bpy_python() -> Path | None:
    env = os.environ.get("GASLIGHT_BPY_PYTHON")
    path = Path(env) if env else REPO / ".venv-bpy" / "bin" / "python"
    return path if path.is_file() and os.access(path, os.X_OK) else None


def lamp_scene(seed: int = 0) -> SplatScene:
    """Three coloured lamps, two faint emitters, and dim floor splats (below threshold)."""
    rng = np.random.default_rng(seed)
    floor = np.column_stack([rng.uniform(-2.5, 2.5, 30), np.zeros(30), rng.uniform(-2.5, 2.5, 30)])
    floor_rgb = rng.uniform(0.05, 0.9, (30, 3))
    pos = np.concatenate([LAMPS_USD, FAINT_USD, floor])
    rgb = np.concatenate([LAMP_RGB, FAINT_RGB, floor_rgb])
    sigma = np.concatenate([np.full(3, LAMP_SIGMA), np.full(2, 0.03), np.full(30, 0.1)])
    opacity = np.concatenate([np.full(5, 0.95), np.full(30, 0.8)])
    return SplatScene.from_activated(pos, rgb, np.repeat(sigma[:, None], 3, 1), opacity,
                                     metadata={"up_axis": "Y", "meters_per_unit": 1.0})


def usd_to_blender(p: np.ndarray) -> np.ndarray:
    """+Y-up metres -> Blender's +Z-up world (the importer rotates +90 degrees about X)."""
    p = np.asarray(p, np.float64)
    return np.stack([p[..., 0], -p[..., 2], p[..., 1]], -1)


def ground_radiance(points: np.ndarray, centres: np.ndarray, radii: np.ndarray,
                    rgb: np.ndarray, albedo: float) -> np.ndarray:
    """Radiance (N, 3) of a Lambertian floor z = 0 lit by emissive spheres.

    A sphere of radius r and radiance L, wholly above the floor at distance D
    with its centre at angle theta from the normal, gives irradiance
    E = pi L (r / D)^2 cos(theta) (exact); the floor sends albedo E / pi.
    """
    d = centres[None] - points[:, None]  # (N, S, 3)
    dist2 = (d * d).sum(-1)
    cos = d[..., 2] / np.sqrt(dist2)
    weight = albedo * (radii**2)[None] * cos / dist2
    return weight @ rgb


def window_ground_points(centre_px: np.ndarray, radius_px: float, size: int,
                         half_width: float) -> np.ndarray:
    """Floor points (M, 3) seen by the pixels whose centres lie within ``radius_px``.

    For the top-down camera the test sets: image right = +X, image up = +Y,
    ``half_width`` metres from the image centre to its edge on the floor.
    """
    gy, gx = np.mgrid[0:size, 0:size] + 0.5
    inside = (gx - centre_px[0]) ** 2 + (gy - centre_px[1]) ** 2 <= radius_px**2
    x = (gx[inside] / size - 0.5) * 2 * half_width
    y = (0.5 - gy[inside] / size) * 2 * half_width
    return np.column_stack([x, y, np.zeros_like(x)])


def run_blender(tmp_path: Path, usd: Path, settings: dict) -> dict:
    python = bpy_python()
    settings_path = tmp_path / "settings.json"
    settings_path.write_text(json.dumps(settings))
    report = tmp_path / "blender.json"
    done = subprocess.run([str(python), str(SCRIPT), str(usd), str(report), str(settings_path)],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(report.read_text())


def layer_colour_space(usd: Path) -> str:
    """colorSpace:name (Usd.ColorSpaceAPI) on the instancer layer's default prim."""
    layer = usd.with_name(f"{usd.stem}.instancer.usdc")
    stage = Usd.Stage.Open(str(layer))
    return str(stage.GetDefaultPrim().GetAttribute("colorSpace:name").Get())


def authored_palette(usd: Path) -> dict[str, np.ndarray]:
    """Prototype name -> emissiveColor as our layer authored it (read with pxr)."""
    stage = Usd.Stage.Open(str(usd))
    found = {}
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Mesh):
            material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
            shader = UsdShade.Shader(material.GetPrim().GetChild("Surface"))
            found[prim.GetName()] = np.array(shader.GetInput("emissiveColor").Get())
    return found


@pytest.mark.skipif(bpy_python() is None,
                    reason="no bpy interpreter: set GASLIGHT_BPY_PYTHON or create .venv-bpy "
                           "(tests/consumers/README.md)")
def test_instancer_imports_into_blender_and_lights_a_cycles_render(tmp_path):
    scene = lamp_scene()
    ply = write_ply(tmp_path / "splats.ply", scene)
    usd = tmp_path / "scene.usda"
    subprocess.run([str(EXPORT), "export", str(ply), "-o", str(usd), "--as", "instancer",
                    "-q"], check=True, timeout=120)
    mask = emitter_mask(scene)
    assert mask.sum() == 5  # the three lamps and the two faint emitters

    emit_pos = usd_to_blender(scene.positions[mask])
    radii = scene.scales[mask, 0] * np.sqrt(2 * scene.opacities[mask])
    nadirs = emit_pos[:3] * [1, 1, 0]  # floor points under the lamps
    report = run_blender(tmp_path, usd, {
        "working_space": "ACEScg", "resolution": SIZE, "samples": SAMPLES,
        "camera_location": [0, 0, CAMERA_HEIGHT], "camera_target": [0, 0, 0],
        "camera_lens_mm": LENS_MM, "ground_albedo": ALBEDO,
        "probe_points": nadirs.tolist(), "near_radius_px": WINDOW_PX, "far_radius_px": 15})

    # Every emitter arrived, once, and nothing else did (dim splats are dropped).
    counts = report["counts"]
    assert counts["instances"] == counts["emitters"] == int(mask.sum())
    assert counts["pointclouds"] == 1
    inst = report["instances"]
    got_pos = np.array([i["position"] for i in inst])
    match = np.argmin(np.linalg.norm(got_pos[:, None] - emit_pos[None], axis=-1), axis=1)
    assert sorted(match.tolist()) == list(range(5))
    np.testing.assert_allclose(got_pos, emit_pos[match], atol=1e-4)
    np.testing.assert_allclose(np.array([i["scale"] for i in inst]),
                               np.repeat(radii[match, None], 3, 1), rtol=1e-4)

    # Colours: our layer's colour space is the one Blender names its ACEScg working
    # space by (Blender 5.0 reads colour values raw, ignoring ColorSpaceAPI);
    # Blender's emission is exactly what we authored on each prototype,
    # and that is the splat's own colour within the palette tolerance (10 %).
    assert report["working_space_interop_id"] == layer_colour_space(usd) == "lin_ap1_scene"
    palette = authored_palette(usd)
    emission = np.array([i["emission"] for i in inst])
    authored = np.array([palette[i["prototype"]] for i in inst])
    np.testing.assert_allclose(emission, authored, rtol=1e-6)
    truth = scene.base_colours[mask][match]
    rel = np.linalg.norm(emission - truth, axis=1) / np.linalg.norm(truth, axis=1)
    assert rel.max() <= 0.10, rel

    # The render: finite, not black, bright under each lamp in its colour, dark far off.
    render = report["render"]
    assert render["finite"] and render["shape"] == [SIZE, SIZE, 3]
    assert max(render["mean"]) > 1e-3
    near = np.array(render["probe_windows"]["near"])
    far = np.array(render["probe_windows"]["far"])
    for lamp, rgb in enumerate(LAMP_RGB):
        assert np.argmax(near[lamp]) == np.argmax(rgb)
        assert near[lamp].sum() > 4 * far.sum()
    # ...and as bright as spheres of the instance radius and splat radiance make it,
    # averaged over the floor pixels of each window.
    half_width = CAMERA_HEIGHT * 18.0 / LENS_MM  # Blender's default 36 mm sensor width
    probe_px = np.array(render["probe_pixels"])
    expect_px = (nadirs[:, :2] / half_width * [0.5, -0.5] + 0.5) * SIZE
    np.testing.assert_allclose(probe_px, expect_px, atol=0.05)  # the camera we think it is
    expect = np.array([
        ground_radiance(window_ground_points(c, WINDOW_PX, SIZE, half_width), emit_pos,
                        radii, scene.base_colours[mask], ALBEDO).mean(0) for c in probe_px])
    ratio = (near @ LUMA) / (expect @ LUMA)
    assert np.all(np.abs(ratio - 1) < RADIANCE_TOLERANCE), ratio


@pytest.mark.skipif(bpy_python() is None,
                    reason="no bpy interpreter: set GASLIGHT_BPY_PYTHON or create .venv-bpy "
                           "(tests/consumers/README.md)")
def test_default_scene_file_brings_the_lights_and_the_dome_into_an_empty_blender(tmp_path):
    """The whole-scene file as `export` writes it by default, imported as is."""
    from test_lights import LAMP, WINDOW, room_scene

    scene, _ = room_scene()
    ply = write_ply(tmp_path / "splats.ply", scene)
    usd = tmp_path / "scene.usda"
    subprocess.run([str(EXPORT), "export", str(ply), "-o", str(usd), "--dome-size", "256",
                    "-q"], check=True, timeout=300)
    stage = Usd.Stage.Open(str(usd))
    assert stage.GetDefaultPrim().GetVariantSet("lighting").GetVariantSelection() == "rig"
    lights = json.loads(stage.GetRootLayer().customLayerData["gaslight:lights"])
    assert len(lights) == 2
    report = run_blender(tmp_path, usd, {"working_space": "ACEScg", "resolution": 32,
                                         "samples": 4, "camera_location": [0, 0, 1.5],
                                         "camera_target": [1, 0, 1.5]})
    assert not report["world"]  # an empty scene: Blender would drop a DomeLight...
    shells = [m for m in report["textured_meshes"]
              if any(Path(f).name == "scene.dome.exr" for f in m["images"])]
    assert len(shells) == 1  # ...the dome shell carries its light in
    got = np.array([li["position"] for li in report["lights"]])
    assert len(got) == 2 and all(li["type"] == "POINT" for li in report["lights"])
    radii = np.array([li["radius"] for li in report["lights"]])
    for true_light in (LAMP, WINDOW):
        dist = np.linalg.norm(got - usd_to_blender(true_light), axis=1)
        k = int(np.argmin(dist))
        # the window's light sits inside the room, pulled in from the wall by its radius
        assert dist[k] < radii[k] + 0.25
    assert report["render"]["finite"] and max(report["render"]["mean"]) > 0
