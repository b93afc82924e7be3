"""Import a USD layer into Blender, render it with Cycles and report what arrived.

Runs INSIDE a Python that has PyPI ``bpy`` (Blender as a module; its own venv,
numpy < 2), never in the project's venv, and imports nothing from gaslight_usd:

    python blender_import.py SCENE.usda REPORT.json [SETTINGS.json]

What it does:

1. resets to an empty factory scene and runs ``bpy.ops.wm.usd_import`` with
   ``import_all_materials=True`` (Blender binds prototype materials only then);
2. evaluates the depsgraph and lists every object instance (a USD
   PointInstancer arrives as a point-cloud object whose geometry-nodes modifier
   instances the prototypes), with its world position, scale, prototype and
   material emission (Principled "Emission Color" x "Emission Strength");
3. adds a grey Lambertian ground plane and a camera (from SETTINGS), hides the
   imported objects from camera rays (so the render shows the light they cast,
   not the emitters themselves), renders Cycles on the CPU and writes the
   render beside REPORT as a 32-bit float EXR;
4. writes REPORT: instances, lights, meshes with image textures, whether the
   scene has a World, counts, pixel statistics, and the mean colour of
   the render in a window around the projection of each emitting instance and
   of each SETTINGS ``probe_points`` entry, and far from all of them.

All positions are Blender world coordinates (Z up, metres: the importer
converts the stage's upAxis and metersPerUnit). Pixel rows count from the top.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import bpy
import numpy as np
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

DEFAULTS = {
    "working_space": None,  # Blender's name: "Linear Rec.709", "Linear Rec.2020", "ACEScg"
    "resolution": 128,
    "samples": 16,
    "seed": 0,
    "threads": 2,
    "camera_location": [0.0, 0.0, 6.0],
    "camera_target": [0.0, 0.0, 0.0],
    "camera_lens_mm": 35.0,
    "ground_z": 0.0,
    "ground_size": 20.0,
    "ground_albedo": 0.8,
    "hide_imported_from_camera": True,
    "probe_points": [],
    "near_radius_px": 3,
    "far_radius_px": 30,
}


def import_usd(path: str, working_space: str | None) -> None:
    """Empty factory scene, Blender's working colour space, then the USD import.

    Blender 5.0's importer copies colour values as they are (it does not read
    USD's ColorSpaceAPI), so a layer in ACEScg (``lin_ap1_scene``) is read
    right only when the file's working space is ACEScg.
    """
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if working_space:
        bpy.ops.wm.set_working_color_space(working_space=working_space, convert_colors=False)
    result = bpy.ops.wm.usd_import(filepath=path, import_all_materials=True,
                                   import_usd_preview=True, import_lights=True)
    if "FINISHED" not in result:
        raise SystemExit(f"usd_import failed on {path}: {result}")


def material_emission(material) -> list[float]:
    """Linear RGB emission of a node material (colour x strength), 0 when none."""
    if material is None or material.node_tree is None:
        return [0.0, 0.0, 0.0]
    total = np.zeros(3)
    for node in material.node_tree.nodes:
        colour = node.inputs.get("Emission Color") or node.inputs.get("Color")
        strength = node.inputs.get("Emission Strength") or node.inputs.get("Strength")
        if node.type not in ("BSDF_PRINCIPLED", "EMISSION") or colour is None:
            continue
        total += np.array(colour.default_value[:3]) * float(strength.default_value)
    return total.tolist()


def list_instances() -> tuple[list[dict], list[str]]:
    """Every instanced object the evaluated scene draws, and the real objects."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    instances, real = [], []
    for inst in depsgraph.object_instances:
        obj = inst.object
        if not inst.is_instance:
            real.append(f"{obj.name}:{obj.type}")
            continue
        slots = [s.material for s in obj.material_slots if s.material is not None]
        material = slots[0] if slots else None
        matrix = inst.matrix_world
        instances.append({
            "prototype": obj.original.name if obj.original else obj.name,
            "instancer": inst.parent.original.name if inst.parent else None,
            "material": material.original.name if material else None,
            "emission": material_emission(material.original if material else None),
            "position": list(matrix.translation),
            "scale": list(matrix.to_scale()),
        })
    return instances, real


def image_files(obj) -> list[str]:
    """Image files the object's materials read (image texture nodes)."""
    files = []
    for slot in obj.material_slots:
        tree = slot.material.node_tree if slot.material else None
        for node in tree.nodes if tree else []:
            if node.type == "TEX_IMAGE" and node.image is not None:
                files.append(bpy.path.abspath(node.image.filepath))
    return files


def add_ground(z: float, size: float, albedo: float) -> None:
    bpy.ops.mesh.primitive_plane_add(size=size, location=(0.0, 0.0, z))
    plane = bpy.context.active_object
    plane.name = "CheckGround"
    material = bpy.data.materials.new("CheckGroundLambert")
    nodes = material.node_tree.nodes
    nodes.clear()
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")  # roughness 0: Lambertian
    diffuse.inputs["Color"].default_value = (albedo, albedo, albedo, 1.0)
    diffuse.inputs["Roughness"].default_value = 0.0
    output = nodes.new("ShaderNodeOutputMaterial")
    material.node_tree.links.new(diffuse.outputs["BSDF"], output.inputs["Surface"])
    plane.data.materials.append(material)


def add_camera(location, target, lens_mm: float):
    data = bpy.data.cameras.new("CheckCamera")
    data.lens = lens_mm
    cam = bpy.data.objects.new("CheckCamera", data)
    bpy.context.scene.collection.objects.link(cam)
    cam.location = Vector(location)
    forward = Vector(target) - Vector(location)
    cam.rotation_euler = forward.to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.camera = cam
    return cam


def render_exr(path: Path, settings: dict) -> np.ndarray:
    """Cycles CPU render -> (H, W, 3) float32 linear, rows from the top."""
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = settings["samples"]
    scene.cycles.seed = settings["seed"]
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.render.threads_mode = "FIXED"
    scene.render.threads = settings["threads"]
    scene.render.resolution_x = scene.render.resolution_y = settings["resolution"]
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(path))
    w, h = image.size
    flat = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(flat)
    return flat.reshape(h, w, 4)[::-1, :, :3].copy()  # Blender stores rows bottom-up


def project(cam, positions: list[list[float]], size: int) -> np.ndarray:
    """World points -> (N, 2) pixel (x, y) from the top-left, pixel centres at +0.5."""
    scene = bpy.context.scene
    out = []
    for p in positions:
        ndc = world_to_camera_view(scene, cam, Vector(p))
        out.append([ndc.x * size, (1.0 - ndc.y) * size])
    return np.array(out, np.float64).reshape(-1, 2)


def window_stats(pixels: np.ndarray, xy: np.ndarray, near: float, far: float) -> dict:
    """Mean colour within ``near`` px of each point, and beyond ``far`` px of all."""
    h, w = pixels.shape[:2]
    gy, gx = np.mgrid[0:h, 0:w] + 0.5
    d2 = (gx[None] - xy[:, 0, None, None]) ** 2 + (gy[None] - xy[:, 1, None, None]) ** 2
    near_means = [pixels[m].mean(0).tolist() if m.any() else None for m in d2 <= near**2]
    far_mask = (d2 > far**2).all(0) if len(xy) else np.ones((h, w), bool)
    far_mean = pixels[far_mask].mean(0).tolist() if far_mask.any() else None
    return {"near": near_means, "far": far_mean, "far_pixels": int(far_mask.sum())}


def main(argv: list[str]) -> None:
    usd_path, report_path = argv[0], Path(argv[1])
    settings = dict(DEFAULTS)
    if len(argv) > 2:
        settings.update(json.loads(Path(argv[2]).read_text()))
    import_usd(usd_path, settings["working_space"])
    instances, real = list_instances()
    imported = [o for o in bpy.context.scene.objects]
    lights = [{"name": o.name, "type": o.data.type, "position": list(o.matrix_world.translation),
               "radius": float(getattr(o.data, "shadow_soft_size", 0.0)),
               "energy": float(o.data.energy), "colour": list(o.data.color)}
              for o in imported if o.type == "LIGHT"]
    textured = [{"name": o.name, "images": image_files(o)} for o in imported
                if o.type == "MESH" and image_files(o)]
    emitters = [i for i in instances if max(i["emission"]) > 0]
    report = {
        "blender": bpy.app.version_string,
        "usd": usd_path,
        "working_space": bpy.data.colorspace.working_space,
        "working_space_interop_id": bpy.data.colorspace.working_space_interop_id,
        "settings": settings,
        "real_objects": real,
        "lights": lights,
        "textured_meshes": textured,
        "world": bpy.context.scene.world is not None,
        "instances": instances,
        "counts": {"instances": len(instances), "emitters": len(emitters),
                   "materials": len(bpy.data.materials),
                   "pointclouds": sum(o.type == "POINTCLOUD" for o in imported)},
    }
    if settings["hide_imported_from_camera"]:
        for obj in bpy.data.objects:
            obj.visible_camera = False
    add_ground(settings["ground_z"], settings["ground_size"], settings["ground_albedo"])
    cam = add_camera(settings["camera_location"], settings["camera_target"],
                     settings["camera_lens_mm"])
    exr = report_path.with_suffix(".exr")
    pixels = render_exr(exr, settings)
    xy = project(cam, [i["position"] for i in emitters], settings["resolution"])
    probes = project(cam, settings["probe_points"], settings["resolution"])
    report["render"] = {
        "exr": str(exr),
        "shape": list(pixels.shape),
        "mean": pixels.mean((0, 1)).tolist(),
        "max": pixels.max((0, 1)).tolist(),
        "finite": bool(np.isfinite(pixels).all()),
        "emitter_pixels": xy.tolist(),
        "windows": window_stats(pixels, xy, settings["near_radius_px"],
                                settings["far_radius_px"]),
        "probe_pixels": probes.tolist(),
        "probe_windows": window_stats(pixels, probes, settings["near_radius_px"],
                                      settings["far_radius_px"]),
    }
    report_path.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:])
