"""Emissive instancer: bright splats as point-instanced emissive icospheres.

For renderers that do not draw splats (Blender, most path tracers):

- the emitters are the splats of the set's lights
  (:func:`gaslight_usd.lights.search_lights`: no diffuse surface lit by the
  scene explains them, backdrop never), or, with an explicit ``threshold``,
  the splats whose radiance (the **max channel** of the base colour) exceeds
  it (the GaSLight rule);
- every emitter becomes an instance of an icosphere ``Mesh`` prototype with
  the unit sphere's surface area
  (Blender drops materials bound to implicit ``UsdGeom.Sphere`` prototypes and
  ignores per-instance primvars), so colour lives on a small palette of
  prototypes, each with its own emissive ``UsdPreviewSurface``;
- instance scales are ``sigma * sqrt(2 * opacity)`` per axis: a sphere of
  radius r and radiance L sends ``L * pi * r^2`` towards any direction, a
  Gaussian splat ``L * opacity * 2 * pi * sigma^2``; equal for that radius;
- the rest of the splats are dropped (default) or become diffuse instances
  on their own palette (``non_emitters="diffuse"``).

The PointInstancer sits under a typed Xform (Blender imports it only there).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

from ..export_options import PALETTE_TOLERANCE
from ..splats import SplatScene
from .palette import DEFAULT_THRESHOLD, Palette, fit_palette

MAX_PALETTE = 64


@dataclass
class InstancerReport:
    emitters: int = 0
    diffuse: int = 0
    dropped: int = 0
    palette: dict[str, float] = field(default_factory=dict)
    diffuse_palette: dict[str, float] = field(default_factory=dict)


def splat_radiance(scene: SplatScene) -> np.ndarray:
    """(N,) the emitter measure: max channel of the base colour (linear)."""
    return scene.base_colours.max(axis=1) if scene.count else np.zeros(0, np.float32)


def emitter_mask(scene: SplatScene, threshold: float = DEFAULT_THRESHOLD) -> np.ndarray:
    return splat_radiance(scene) > threshold


def icosphere(subdivisions: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Unit icosphere: (V, 3) float32 points and (F, 3) int32 triangles (CCW outward)."""
    t = (1.0 + 5.0**0.5) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
             (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9),
             (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2),
             (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
             (8, 6, 7), (9, 8, 1)]
    points = [np.array(v, np.float64) / np.linalg.norm(v) for v in verts]
    for _ in range(subdivisions):
        faces = _subdivide(points, faces)
    return np.array(points, np.float32), np.array(faces, np.int32)


def _subdivide(points: list[np.ndarray], faces: list[tuple[int, int, int]]
               ) -> list[tuple[int, int, int]]:
    """Split each triangle in four, new vertices pushed onto the unit sphere."""
    midpoint: dict[tuple[int, int], int] = {}

    def mid(a: int, b: int) -> int:
        key = (min(a, b), max(a, b))
        if key not in midpoint:
            m = points[a] + points[b]
            points.append(m / np.linalg.norm(m))
            midpoint[key] = len(points) - 1
        return midpoint[key]

    new_faces = []
    for a, b, c in faces:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        new_faces += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
    return new_faces


def area_matched_icosphere(subdivisions: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Icosphere scaled so its surface area is the unit sphere's (4 pi).

    A convex emitter's mean projected area is a quarter of its surface area
    (Cauchy), so this prototype sends the power of a unit sphere; the inscribed
    icosphere(1) has 7.2 % less area and would make every emitter that much dimmer
    (seen in a Cycles render of the instancer, tests/test_consumers_blender.py).
    """
    points, faces = icosphere(subdivisions)
    tri = points[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
                                axis=1).sum()
    return (points * np.sqrt(4.0 * np.pi / area)).astype(np.float32), faces


def _define_sphere_prototype(stage: Usd.Stage, path: Sdf.Path) -> UsdGeom.Mesh:
    points, faces = area_matched_icosphere(1)
    radius = float(np.linalg.norm(points, axis=1).max())
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.reshape(-1)))
    mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(points / radius))
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(-radius, -radius, -radius),
                                         Gf.Vec3f(radius, radius, radius)]))
    return mesh


def _define_material(stage: Usd.Stage, path: Sdf.Path, rgb: np.ndarray,
                     emissive: bool) -> UsdShade.Material:
    material = UsdShade.Material.Define(stage, path)
    shader = UsdShade.Shader.Define(stage, path.AppendChild("Surface"))
    shader.CreateIdAttr("UsdPreviewSurface")
    colour = Gf.Vec3f(*(float(c) for c in rgb))
    black = Gf.Vec3f(0.0, 0.0, 0.0)
    diffuse = black if emissive else Gf.Vec3f(*(float(min(max(c, 0.0), 1.0)) for c in rgb))
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(diffuse)
    shader.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).Set(
        colour if emissive else black)
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(1.0)
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return material


def _instance_scales(scene: SplatScene) -> np.ndarray:
    return (scene.scales * np.sqrt(2.0 * scene.opacities)[:, None]).astype(np.float32)


def write_instancer(stage: Usd.Stage, root: Sdf.Path, scene: SplatScene,
                    threshold: float | None = DEFAULT_THRESHOLD,
                    tolerance: float = PALETTE_TOLERANCE,
                    non_emitters: str = "drop", max_palette: int = MAX_PALETTE,
                    seed: int = 0, mask: np.ndarray | None = None) -> InstancerReport:
    """Author ``<root>/Instancer`` (a PointInstancer) and ``<root>/Looks`` under ``root``.

    ``root`` must already be a typed Xform (the layer's default prim). The
    emitters are ``mask`` when given (the lights finder's), else the splats
    above ``threshold``.
    """
    if non_emitters not in ("drop", "diffuse"):
        raise ValueError(f"non_emitters must be 'drop' or 'diffuse', not {non_emitters!r}")
    if mask is None:
        mask = emitter_mask(scene, DEFAULT_THRESHOLD if threshold is None else threshold)
    report = InstancerReport(emitters=int(mask.sum()))
    groups: list[tuple[str, SplatScene, Palette, bool]] = []
    colours = scene.base_colours
    emitters = scene.subset(mask)
    pal = fit_palette(colours[mask], tolerance, max_palette, seed)
    groups.append(("Emitter", emitters, pal, True))
    report.palette = pal.summary()
    if non_emitters == "diffuse":
        rest = scene.subset(~mask)
        dpal = fit_palette(np.clip(colours[~mask], 0.0, 1.0), tolerance, max_palette, seed)
        groups.append(("Diffuse", rest, dpal, False))
        report.diffuse, report.diffuse_palette = rest.count, dpal.summary()
    else:
        report.dropped = int((~mask).sum())

    instancer = UsdGeom.PointInstancer.Define(stage, root.AppendChild("Instancer"))
    protos_root = UsdGeom.Scope.Define(stage, instancer.GetPath().AppendChild("Prototypes"))
    looks = UsdGeom.Scope.Define(stage, root.AppendChild("Looks"))
    targets, indices, parts = [], [], []
    for prefix, part, palette, emissive in groups:
        base = len(targets)
        for i, rgb in enumerate(palette.colours):
            name = f"{prefix}_{i:03d}"
            mesh = _define_sphere_prototype(stage, protos_root.GetPath().AppendChild(name))
            material = _define_material(stage, looks.GetPath().AppendChild(name), rgb, emissive)
            UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
            targets.append(mesh.GetPath())
        indices.append(palette.labels.astype(np.int32) + base)
        parts.append(part)

    positions = np.concatenate([p.positions for p in parts]).astype(np.float32)
    rot = np.concatenate([p.unit_rotations for p in parts])
    scales = np.concatenate([_instance_scales(p) for p in parts])
    instancer.CreatePrototypesRel().SetTargets(targets)
    instancer.CreateProtoIndicesAttr(Vt.IntArray.FromNumpy(np.concatenate(indices)))
    instancer.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(positions))
    instancer.CreateOrientationsAttr(Vt.QuathArray.FromNumpy(
        np.ascontiguousarray(np.roll(rot, -1, axis=1)).astype(np.float16)))
    instancer.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(scales))
    if len(positions):
        reach = float(np.linalg.norm(area_matched_icosphere(1)[0], axis=1).max())
        pad = scales.max(axis=1, keepdims=True) * reach
        extent = np.stack([(positions - pad).min(0), (positions + pad).max(0)])
    else:
        extent = np.zeros((2, 3), np.float32)
    instancer.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(extent.astype(np.float32)))
    return report
