"""USD export: values read back, stage metadata, validation, variants, USDZ, splitting."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest
from plyfile import PlyData, PlyElement
from pxr import Usd, UsdGeom, UsdLux, UsdShade, UsdVol

from gaslight_usd.cli.main import main
from gaslight_usd.ply import read_ply, write_ply
from gaslight_usd.splats import SH_C0, SplatScene
from gaslight_usd.usd.palette import fit_palette
from gaslight_usd.usd.particlefield import bytes_per_splat, chunk_ranges, read_particle_field
from gaslight_usd.usd.scene import ExportOptions, export_usd, open_variant
from gaslight_usd.usd.usdz import package_usdz, validate_usdz
from gaslight_usd.usd.validate import errors


def other_tool_ply(path: Path, n: int = 300, seed: int = 1) -> dict[str, np.ndarray]:
    """A 3DGS PLY written with plain plyfile, as other trainers do (normals zero, SH 3)."""
    rng = np.random.default_rng(seed)
    props = {"x": rng.normal(size=n), "y": rng.normal(size=n), "z": rng.normal(size=n),
             "nx": np.zeros(n), "ny": np.zeros(n), "nz": np.zeros(n)}
    dc = rng.normal(size=(n, 3))
    rest = rng.normal(size=(n, 45)) * 0.1
    for i in range(3):
        props[f"f_dc_{i}"] = dc[:, i]
    for i in range(45):
        props[f"f_rest_{i}"] = rest[:, i]
    props["opacity"] = rng.normal(size=n)
    scales = rng.uniform(-4, -2, (n, 3))
    rot = rng.normal(size=(n, 4))
    for i in range(3):
        props[f"scale_{i}"] = scales[:, i]
    for i in range(4):
        props[f"rot_{i}"] = rot[:, i]
    table = np.empty(n, dtype=[(k, "<f4") for k in props])
    for k, v in props.items():
        table[k] = v
    PlyData([PlyElement.describe(table, "vertex")]).write(str(path))
    return {"dc": dc, "rest": rest, "scales": scales, "rot": rot, "props": props}


def lamp_scene(n: int = 400, seed: int = 0) -> SplatScene:
    """Walls on a sphere of radius 3 plus two coloured lamps (radiance > 1)."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    pos = 3 * d / np.linalg.norm(d, axis=1, keepdims=True)
    col = rng.uniform(0.1, 0.6, (n, 3))
    lamps = [(np.array([1.0, 0.3, 0.0]), (30.0, 25.0, 15.0)),
             (np.array([-0.4, 0.8, -0.6]), (5.0, 10.0, 40.0))]
    for centre, rgb in lamps:
        near = np.linalg.norm(pos - 3 * centre / np.linalg.norm(centre), axis=1) < 0.6
        col[near] = rgb
    return SplatScene.from_activated(pos, col, np.full((n, 3), 0.15), np.full(n, 0.9),
                                     sh_degree=1,
                                     metadata={"up_axis": "Z", "meters_per_unit": 0.01,
                                               "exposure_scale": 2.0,
                                               "source_images": ["a.jpg", "b.jpg"],
                                               "method": "test"})


def test_particlefield_values_from_another_tools_ply(tmp_path):
    raw = other_tool_ply(tmp_path / "other.ply")
    scene = read_ply(tmp_path / "other.ply")
    report = export_usd(scene, tmp_path / "scene.usda",
                        ExportOptions(variants=("particlefield",)))
    assert report.errors == []
    stage = open_variant(tmp_path / "scene.usda", "particlefield")
    prims = [p for p in stage.Traverse() if p.IsA(UsdVol.ParticleField3DGaussianSplat)]
    assert len(prims) == 1
    got = read_particle_field(prims[0])
    np.testing.assert_allclose(got["positions"][:, 0], raw["props"]["x"], rtol=1e-6)
    np.testing.assert_allclose(got["scales"], np.exp(raw["scales"]), rtol=1e-5)
    np.testing.assert_allclose(got["opacities"], 1 / (1 + np.exp(-raw["props"]["opacity"])),
                               rtol=1e-5)
    unit = raw["rot"] / np.linalg.norm(raw["rot"], axis=1, keepdims=True)
    np.testing.assert_allclose(got["orientations"], unit, atol=1e-6)  # w x y z
    # USD layout: per particle, DC first, then the f_rest coefficients (channel-major
    # in the PLY: coefficient j of red is f_rest_j, of green f_rest_{15+j}).
    np.testing.assert_allclose(got["sh"][:, 0], raw["dc"], rtol=1e-6)
    np.testing.assert_allclose(got["sh"][:, 5, 1], raw["rest"][:, 15 + 4], rtol=1e-6)
    field = UsdVol.ParticleField3DGaussianSplat(prims[0])
    assert field.GetRadianceSphericalHarmonicsDegreeAttr().Get() == 3
    lo, hi = np.asarray(field.GetExtentAttr().Get())
    assert (lo <= got["positions"].min(0)).all() and (hi >= got["positions"].max(0)).all()
    # Unknown units/up axis: defaults authored and the assumption stated.
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdGeom.GetStageUpAxis(stage) == "Y"
    data = stage.GetRootLayer().customLayerData
    assert data["gaslight:unitsKnown"] is False and "assumed" in data["gaslight:assumed"]


def test_half_precision_and_quaternion_order(tmp_path):
    q = np.array([[0.9, 0.1, -0.3, 0.2]], np.float32)  # w x y z
    scene = SplatScene.from_activated(np.zeros((1, 3)), [[2.0, 0.5, 0.25]], [[0.1, 0.2, 0.3]],
                                      [0.75], rotations=q)
    export_usd(scene, tmp_path / "s.usda", ExportOptions(variants=("particlefield",), half=True))
    layer = Usd.Stage.Open(str(tmp_path / "s.particlefield.usdc"))
    field = UsdVol.ParticleField3DGaussianSplat(layer.GetDefaultPrim())
    assert not field.GetOrientationsAttr().HasAuthoredValue()
    quat = field.GetOrientationshAttr().Get()[0]
    unit = q[0] / np.linalg.norm(q[0])
    assert abs(float(quat.GetReal()) - unit[0]) < 1e-3
    np.testing.assert_allclose(list(quat.GetImaginary()), unit[1:], atol=1e-3)
    np.testing.assert_allclose(list(field.GetScaleshAttr().Get()[0]), [0.1, 0.2, 0.3],
                               rtol=1e-3)
    assert abs(float(field.GetOpacitieshAttr().Get()[0]) - 0.75) < 1e-3
    dc = np.asarray(field.GetRadianceSphericalHarmonicsCoefficientshAttr().Get()[0], float)
    np.testing.assert_allclose(dc * SH_C0 + 0.5, [2.0, 0.5, 0.25], rtol=2e-3)


def test_stage_metadata_colour_space_provenance_and_variants(tmp_path):
    scene = lamp_scene()
    report = export_usd(scene, tmp_path / "scene.usda",
                        ExportOptions(variants=("particlefield", "instancer")))
    assert report.errors == []
    stage = Usd.Stage.Open(str(tmp_path / "scene.usda"))
    assert UsdGeom.GetStageUpAxis(stage) == "Z"
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.01)
    root = stage.GetDefaultPrim()
    assert root.GetPath() == "/Scene"
    assert Usd.ColorSpaceAPI(root).GetColorSpaceNameAttr().Get() == "lin_ap1_scene"
    assert "GaslightProvenanceAPI" in root.GetAppliedSchemas()
    assert root.GetAttribute("gaslight:exposureScale").Get() == pytest.approx(2.0)
    assert list(root.GetAttribute("gaslight:sourceImages").Get()) == ["a.jpg", "b.jpg"]
    vset = root.GetVariantSet("lighting")
    assert sorted(vset.GetVariantNames()) == ["instancer", "particlefield"]
    # no rig written: the first form written is the default
    assert vset.GetVariantSelection() == "particlefield"
    vset.SetVariantSelection("instancer")
    inst = stage.GetPrimAtPath("/Scene/Emitters/Instancer")
    assert inst.IsA(UsdGeom.PointInstancer)
    assert stage.GetPrimAtPath("/Scene/Emitters").IsA(UsdGeom.Xform)
    assert not stage.GetPrimAtPath("/Scene/Splats")
    # The referenced layer states its colour space too (it opens on its own).
    emitters = stage.GetPrimAtPath("/Scene/Emitters")
    assert emitters.GetAttribute("colorSpace:name").Get() == "lin_ap1_scene"


def test_instancer_emitters_palette_and_materials(tmp_path):
    scene = lamp_scene()
    colours = scene.base_colours
    bright = colours.max(1) > 1.0
    export_usd(scene, tmp_path / "scene.usda", ExportOptions(variants=("instancer",)))
    stage = Usd.Stage.Open(str(tmp_path / "scene.instancer.usdc"))
    assert errors(stage) == []
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Emitters/Instancer"))
    idx = np.asarray(inst.GetProtoIndicesAttr().Get())
    assert len(idx) == int(bright.sum()) > 0
    protos = inst.GetPrototypesRel().GetTargets()
    assert len(protos) == 2  # two lamp colours, exactly
    emitted = []
    for path in protos:
        mesh = stage.GetPrimAtPath(path)
        assert mesh.IsA(UsdGeom.Mesh)  # not an implicit Sphere (Blender drops its material)
        material = UsdShade.MaterialBindingAPI(mesh).ComputeBoundMaterial()[0]
        shader = UsdShade.Shader(material.GetPrim().GetChild("Surface"))
        emitted.append(np.asarray(shader.GetInput("emissiveColor").Get()))
    emitted = np.array(emitted)
    per_instance = emitted[idx]
    np.testing.assert_allclose(per_instance, colours[bright], rtol=1e-5)
    # Scale: sigma * sqrt(2 * opacity) keeps the emitted power of the splat.
    scales = np.asarray(inst.GetScalesAttr().Get())
    np.testing.assert_allclose(scales, scene.scales[bright] * np.sqrt(2 * 0.9), rtol=1e-4)


def test_palette_is_smallest_within_tolerance():
    rng = np.random.default_rng(0)
    base = np.array([[10.0, 8.0, 5.0], [2.0, 4.0, 20.0], [50.0, 5.0, 5.0]])
    colours = base[rng.integers(0, 3, 600)] * (1 + rng.normal(0, 0.01, (600, 3)))
    pal = fit_palette(colours, tolerance=0.05)
    assert pal.size == 3
    assert pal.summary()["relative_error_p95"] <= 0.05
    tight = fit_palette(colours, tolerance=1e-4, max_size=8)
    assert tight.size == 8  # cannot meet it: max size, and the error says so
    assert tight.summary()["relative_error_p95"] > 1e-4


def test_layers_split_under_a_byte_threshold(tmp_path):
    scene = lamp_scene(n=250)
    per = bytes_per_splat(scene.sh.shape[1])
    ranges = chunk_ranges(scene.count, per, max_bytes=per * 100)
    assert ranges == [(0, 100), (100, 200), (200, 250)]
    report = export_usd(scene, tmp_path / "scene.usda",
                        ExportOptions(variants=("particlefield",), max_layer_bytes=per * 100))
    assert report.errors == []
    names = sorted(p.name for p in tmp_path.glob("scene.particlefield.*.usdc"))
    assert names == [f"scene.particlefield.{i:03d}.usdc" for i in range(3)]
    stage = Usd.Stage.Open(str(tmp_path / "scene.usda"))
    fields = [read_particle_field(p) for p in stage.Traverse()
              if p.IsA(UsdVol.ParticleField3DGaussianSplat)]
    np.testing.assert_array_equal(np.concatenate([f["positions"] for f in fields]),
                                  scene.positions)
    assert not list(tmp_path.glob(".*partial*"))


@pytest.mark.slow
def test_rig_lights_and_dome(tmp_path):
    scene = lamp_scene(n=500)
    report = export_usd(scene, tmp_path / "scene.usda",
                        ExportOptions(variants=("rig",), dome_width=64, rig_tolerance=0.1,
                                      probe=(0.0, 0.0, 0.0)))
    assert report.errors == []
    rig = report.metrics["rig"]
    assert rig["dome_only_error"] > 0.1  # the dome alone misses the lamps...
    assert rig["irradiance_error"] <= 0.1 and rig["met"]  # ...the lights restore them
    stage = Usd.Stage.Open(str(tmp_path / "scene.rig.usdc"))
    dome = UsdLux.DomeLight(stage.GetPrimAtPath("/Rig/Dome"))
    assert dome.GetTextureFormatAttr().Get() == "latlong"
    assert (tmp_path / dome.GetTextureFileAttr().Get().path).exists()
    lights = [p for p in stage.Traverse() if p.IsA(UsdLux.SphereLight)]
    assert 1 <= len(lights) == rig["lights"] <= 4
    # A light sits at each lamp, with the lamp's colour (warm / blue).
    pos = np.array([UsdGeom.Xformable(p).ComputeLocalToWorldTransform(0).ExtractTranslation()
                    for p in lights])
    for direction, order in (([1.0, 0.3, 0.0], [0, 1, 2]), ([-0.4, 0.8, -0.6], [2, 1, 0])):
        lamp = 3 * np.array(direction) / np.linalg.norm(direction)
        nearest = int(np.argmin(np.linalg.norm(pos - lamp, axis=1)))
        radius = UsdLux.SphereLight(lights[nearest]).GetRadiusAttr().Get()
        assert np.linalg.norm(pos[nearest] - lamp) < 0.5 + radius
        # inside the set: the whole sphere within the walls (radius 3, splats 0.15 wide)
        assert np.linalg.norm(pos[nearest]) + radius <= 3.0 + 0.15
        colour = np.asarray(UsdLux.SphereLight(lights[nearest]).GetColorAttr().Get())
        assert colour[order[0]] >= colour[order[1]] >= colour[order[2]]


def test_usdz_package_validates(tmp_path):
    scene = lamp_scene(n=200)
    export_usd(scene, tmp_path / "scene.usda",
               ExportOptions(variants=("particlefield", "instancer", "rig"), dome_width=32))
    usdz = package_usdz(tmp_path / "scene.usda", tmp_path / "scene.usdz")
    assert [f for f in validate_usdz(usdz) if f.severity == "error"] == []
    names = zipfile.ZipFile(usdz).namelist()
    assert names[0] == "scene.usda"
    assert {"scene.particlefield.usdc", "scene.instancer.usdc", "scene.rig.usdc",
            "scene.dome.exr"} <= set(names)


def test_cli_export_and_bad_input(tmp_path, capsys):
    other_tool_ply(tmp_path / "other.ply", n=50)
    out = tmp_path / "out" / "scene.usda"
    code = main(["export", str(tmp_path / "other.ply"), "-o", str(out), "--as",
                 "particlefield,instancer", "--half", "-q",
                 "--display-ply", str(tmp_path / "out" / "display.ply")])
    assert code == 0 and out.exists()
    assert (tmp_path / "out" / "display.ply").exists()
    assert main(["export", str(tmp_path / "missing.ply"), "-o", str(out)]) == 3
    (tmp_path / "bad.ply").write_text("not a ply")
    assert main(["export", str(tmp_path / "bad.ply"), "-o", str(out)]) == 3
    assert "bad.ply" in capsys.readouterr().err


def test_frame_record_from_poses_sets_up_axis_and_units():
    """Fitted splats carry the poses' frame.json under 'frame': the stage uses it."""
    from gaslight_usd.usd.stage import StageFrame

    known = StageFrame.from_metadata({"frame": {"up_axis": "Y", "meters_per_unit": 0.01}})
    assert (known.up_axis, known.meters_per_unit, known.assumed) == ("Y", 0.01, [])
    unscaled = StageFrame.from_metadata({"frame": {"up_axis": "Y", "meters_per_unit": None}})
    assert unscaled.up_axis == "Y"
    assert unscaled.assumed == ["units unknown, metersPerUnit assumed 1.0"]


def test_instancer_says_when_its_palette_misses_the_tolerance(tmp_path, capsys):
    """Issue 24 item 6: 64 colours cannot hold 2000 random emitter colours within 10 %."""
    rng = np.random.default_rng(4)
    n = 2000
    colours = np.exp(rng.uniform(0.5, 7.0, (n, 3)))
    scene = SplatScene.from_activated(rng.normal(size=(n, 3)), colours, np.full((n, 3), 0.05),
                                      np.full(n, 0.9), metadata={"meters_per_unit": 1.0})
    report = export_usd(scene, tmp_path / "scene.usda",
                        ExportOptions(variants=("instancer",), emit_threshold=1.0))
    inst = report.metrics["instancer"]
    assert inst["palette_size"] == 64 and inst["relative_error_p95"] > 0.10
    assert inst["palette_tolerance_met"] is False
    assert "misses its tolerance" in inst["warning"] and "64 colours" in inst["warning"]
    ply = write_ply(tmp_path / "many.ply", scene)
    assert main(["export", str(ply), "-o", str(tmp_path / "cli.usda"), "--as", "instancer",
                 "--emit-threshold", "1"]) == 0
    assert "misses its tolerance" in capsys.readouterr().out
    # a palette that meets it says so
    ok = export_usd(lamp_scene(), tmp_path / "ok.usda", ExportOptions(variants=("instancer",)))
    assert ok.metrics["instancer"]["palette_tolerance_met"] is True
    assert "warning" not in ok.metrics["instancer"]


def test_unknown_sfm_units_are_stated_in_the_usd(tmp_path):
    """SfM poses without a scale: the stage says the unit is unknown and how to give one."""
    from gaslight_usd.converters.fit_splats import length_unit

    from gaslight_usd.poses.frame import UNKNOWN_UNITS_HINT

    frame = {"frame_source": "sfm", "up_axis": "Y", "meters_per_unit": None,
             "units": UNKNOWN_UNITS_HINT}
    assert "--camera-height" in length_unit(frame)
    assert length_unit({**frame, "meters_per_unit": 1.0}) == "metres"
    scene = lamp_scene(n=50)
    scene.metadata = {"frame": frame, "length_unit": length_unit(frame)}
    export_usd(scene, tmp_path / "scene.usda", ExportOptions(variants=("particlefield",)))
    stage = Usd.Stage.Open(str(tmp_path / "scene.usda"))
    data = stage.GetRootLayer().customLayerData
    assert data["gaslight:unitsKnown"] is False
    assert data["gaslight:units"].startswith("unknown") and "--camera-height" in data[
        "gaslight:units"]
    scene.metadata = {"frame": {**frame, "meters_per_unit": 1.0}}
    export_usd(scene, tmp_path / "m.usda", ExportOptions(variants=("particlefield",)))
    stage = Usd.Stage.Open(str(tmp_path / "m.usda"))
    data = stage.GetRootLayer().customLayerData
    assert data["gaslight:unitsKnown"] is True and data["gaslight:units"] == "metres"
