"""The light rig: a DomeLight rendered at a probe point plus the set's lights.

- The lights are the groups :func:`gaslight_usd.lights.search_lights` finds
  (splats no diffuse surface lit by the scene could explain, backdrop never).
  A flat one in a wall or ceiling of the fit's room box (a window, a ceiling
  panel: :func:`gaslight_usd.light_shapes.panel_of`) becomes a ``UsdLux.RectLight``
  in that plane facing into the room; every other one a ``UsdLux.SphereLight`` at
  its power-weighted centre, radius its spread, placed inside the captured space
  (pulled in from the walls by its radius). With an explicit ``threshold`` (the
  old GaSLight rule, radiance above it) the emitters are clustered in space
  instead (k-means, 1, 2, 3... sphere lights until the error is within tolerance).
- The ``DomeLight`` (OpenEXR lat-long convention, +Y pole: the original
  DomeLight schema) holds the panorama of every *other* splat rendered at the
  probe (default: :func:`gaslight_usd.probe.default_probe`), so lamps are not
  counted twice. ``DomeShell`` carries the same texture on an inward emissive
  sphere round the set, for Blender, which drops a DomeLight when importing
  into a scene without a World.
- Each light's power is measured, not guessed: the emitters' share of the
  probe's panorama (full render minus the dome's) is split by direction among
  the lights, giving each light's irradiance at the probe; a sphere's radiance is
  that x distance^2 / (pi r^2), a rectangle's that over the solid angle it fills
  at the probe, written as ``inputs:intensity`` (max channel) x ``inputs:color``
  in the working space (``normalize`` off).
- The rig's error is the irradiance error at the probe over 26 surface
  normals, relative to the largest reference irradiance:
  ``max_n |E_dome(n) + sum_lights E_l(n) - E_full(n)| / max_n E_full(n)``
  (luminance). Away from the probe the rig is an approximation (the dome has no
  parallax); :func:`rig_irradiance` evaluates it anywhere, and
  ``gaslight2usd bench --suite chain`` scores it at the bench rooms' probes
  (``rig_irradiance_psnr``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdLux

from .. import colour
from ..cameras import latlong_directions, latlong_solid_angles
from ..export_options import DOME_WIDTH, RIG_TOLERANCE
from ..flat_outlines import outlines_from_metadata
from ..hdri import write_latlong
from ..light_shapes import Panel, panel_of, room_planes, solid_angle
from ..splats import SplatScene
from .instancer import emitter_mask
from .palette import kmeans

MAX_LIGHTS = 16
DOME_SAMPLING_WIDTH = 1024
"""Lat-long width the dome's panorama is at least drawn at before it is box-filtered
(half the lights' :data:`gaslight_usd.render.envmap.SAMPLING_WIDTH`). Supersampling
keeps a small cluster of a light's splats from gaining power at a coarse pixel; the dome
holds no lights (they are the rig's lights), so at the default 1024 width it is drawn
once per pixel (what that costs in irradiance and saves in the export's ``seconds.rig``:
docs/measurements.md, "the export's dome")."""
EVAL_WIDTH = 256
"""Lat-long width the reference irradiance is measured at (it is a smooth integral)."""


def normals_26() -> np.ndarray:
    """Unit normals: the 6 faces, 12 edges and 8 corners of a cube."""
    g = np.stack(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1], indexing="ij"), -1)
    g = g.reshape(-1, 3).astype(np.float64)
    g = g[np.abs(g).sum(1) > 0]
    return g / np.linalg.norm(g, axis=1, keepdims=True)


def irradiance(pano: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(M, 3) RGB irradiance of a lat-long panorama on surfaces facing ``normals``."""
    h, w = pano.shape[:2]
    dirs = latlong_directions(w, h).reshape(-1, 3)
    d_omega = np.broadcast_to(latlong_solid_angles(w, h), (h, w)).reshape(-1)
    cos = np.clip(dirs @ normals.T, 0.0, None) * d_omega[:, None]  # (P, M)
    return cos.T @ pano.reshape(-1, 3).astype(np.float64)


def _cluster_lights(scene: SplatScene, probe: np.ndarray, k: int, seed: int,
                    emitted: np.ndarray, dirs: np.ndarray, d_omega: np.ndarray
                    ) -> dict[str, np.ndarray]:
    """k sphere lights for the emitter splats in ``scene``; powers from ``emitted``."""
    pos = scene.positions.astype(np.float64)
    centres = kmeans(pos, k, seed)
    labels = np.argmin(((pos[:, None] - centres[None]) ** 2).sum(-1), axis=1)
    k = centres.shape[0]
    weight = (scene.base_colours.max(1) * scene.opacities *
              np.prod(scene.scales, axis=1) ** (2 / 3)).astype(np.float64) + 1e-12
    wsum = np.bincount(labels, weight, minlength=k)
    used = wsum > 0
    centre = np.stack([np.bincount(labels, weight * pos[:, i], minlength=k)
                       for i in range(3)], 1) / np.maximum(wsum, 1e-30)[:, None]
    spread2 = np.bincount(labels, weight * ((pos - centre[labels]) ** 2).sum(1),
                          minlength=k) / np.maximum(wsum, 1e-30)
    size2 = np.bincount(labels, weight * (scene.scales.astype(np.float64) ** 2).mean(1),
                        minlength=k) / np.maximum(wsum, 1e-30)
    radius = np.sqrt(np.maximum(spread2, size2))
    return _measure_lights(centre[used], radius[used], np.bincount(labels, minlength=k)[used],
                           probe, emitted, dirs, d_omega)


def _measure_lights(centre: np.ndarray, radius: np.ndarray, members: np.ndarray,
                    probe: np.ndarray, emitted: np.ndarray, dirs: np.ndarray,
                    d_omega: np.ndarray, panels: list[Panel | None] | None = None
                    ) -> dict[str, np.ndarray]:
    """Lights at ``centre`` (L, 3): the emitters' panorama split among them by direction.

    ``panels``: per light, its rectangle (a ``RectLight``) or None (a sphere of
    ``radius``); a rectangle the probe sees edge-on or from behind is a sphere."""
    to_light = centre - probe
    dist = np.maximum(np.linalg.norm(to_light, axis=1), 1e-9)
    omega = to_light / dist[:, None]
    # Split the emitters' share of the panorama among the lights by direction.
    owner = np.argmax(dirs @ omega.T, axis=1)
    flux = np.stack([np.bincount(owner, emitted[:, c] * d_omega, minlength=len(centre))
                     for c in range(3)], 1)
    flux = np.maximum(flux, 0.0)  # irradiance normal to each light's direction
    rects: list[Panel | None] = list(panels) if panels is not None else [None] * len(centre)
    seen = np.full(len(centre), np.pi * radius**2 / dist**2)
    for i, panel in enumerate(rects):
        if panel is None:
            continue
        facing = float(panel.normal @ (probe - panel.centre)) > 0
        sr = solid_angle(panel.corners(), probe) if facing else 0.0
        if sr > 1e-9:
            seen[i] = sr
        else:
            rects[i] = None
    radiance = flux / np.maximum(seen, 1e-30)[:, None]
    order = np.argsort(-flux.sum(1))
    return {"position": centre[order], "radius": radius[order],
            "radiance": radiance[order], "flux": flux[order], "direction": omega[order],
            "members": np.asarray(members)[order], "panel": [rects[i] for i in order]}


def inside_position(space, position: np.ndarray, radius: float) -> np.ndarray:
    """``position`` moved so a sphere of ``radius`` lies inside the captured space.

    Clipped into the space's percentile box (inset by the radius where the box is
    wide enough), then pulled towards the first viewpoint until the sphere ends
    before the visible surface in its direction and before the light's own
    centre (a window or a wall lamp is itself the set's surface there).
    """
    lo, hi = space.box
    inset = np.minimum(radius, (hi - lo) / 4.0)
    p = np.clip(np.asarray(position, np.float64), lo + inset, hi - inset)
    view = space.views[0]
    b, r = view.bin_of(p[None])
    # the light's own centre bounds it too: a window is the set's surface there
    limit = min(float(view.depth[b[0]]), float(r[0]))
    if r[0] + radius > limit and r[0] > 0:
        u = (p - view.point) / r[0]
        p = view.point + u * max(limit - radius, 0.5 * limit)
    return p


def _lights_irradiance(lights: dict[str, np.ndarray], normals: np.ndarray) -> np.ndarray:
    cos = np.clip(lights["direction"] @ normals.T, 0.0, None)  # (L, M)
    return cos.T @ lights["flux"]


def fit_rig(scene: SplatScene, probe: np.ndarray, dome_pano: np.ndarray, full_pano: np.ndarray,
            mask: np.ndarray, tolerance: float, working_space: str,
            ocio_config: str | None, max_lights: int = MAX_LIGHTS, seed: int = 0,
            found: tuple[np.ndarray, np.ndarray, np.ndarray, list] | None = None
            ) -> tuple[dict[str, np.ndarray] | None, dict]:
    """Fewest lights whose irradiance error at ``probe`` is within ``tolerance``.

    ``found``: (centres (L, 3), radii (L,), splat counts (L,), rectangles (L,): a
    :class:`Panel` or None) of lights already found; then those are the lights and
    only their powers are measured.
    """
    lum = colour.luminance_weights(working_space, ocio_config).astype(np.float64)
    normals = normals_26()
    e_full = irradiance(full_pano, normals) @ lum
    e_dome = irradiance(dome_pano, normals) @ lum
    scale = max(float(e_full.max()), 1e-12)
    dome_error = float(np.abs(e_dome - e_full).max() / scale)
    metrics = {"lights": 0, "irradiance_error": dome_error, "dome_only_error": dome_error,
               "tolerance": tolerance, "met": dome_error <= tolerance}
    emitters = scene.subset(mask)
    if emitters.count == 0:
        return None, metrics
    h, w = full_pano.shape[:2]
    dirs = latlong_directions(w, h).reshape(-1, 3)
    d_omega = np.broadcast_to(latlong_solid_angles(w, h), (h, w)).reshape(-1)
    dome_small = _downsample(dome_pano, w)
    emitted = (full_pano - dome_small).reshape(-1, 3).astype(np.float64)
    if found is not None:
        lights = _measure_lights(*found[:3], probe, emitted, dirs, d_omega,
                                 panels=found[3])
        err = float(np.abs(e_dome + _lights_irradiance(lights, normals) @ lum - e_full).max()
                    / scale)
        metrics.update(lights=len(lights["radius"]), irradiance_error=err,
                       met=err <= tolerance)
        return lights, metrics
    best, best_err = None, np.inf
    for k in range(1, min(max_lights, emitters.count) + 1):
        lights = _cluster_lights(emitters, probe, k, seed, emitted, dirs, d_omega)
        err = float(np.abs(e_dome + _lights_irradiance(lights, normals) @ lum - e_full).max()
                    / scale)
        if err < best_err:
            best, best_err = lights, err
        if err <= tolerance:
            break
    metrics.update(lights=len(best["radius"]), irradiance_error=best_err,
                   met=best_err <= tolerance)
    return best, metrics


def _downsample(pano: np.ndarray, width: int) -> np.ndarray:
    """Box-filter a lat-long panorama to ``width`` (an integer factor of its width)."""
    h, w = pano.shape[:2]
    f = w // width
    if f <= 1:
        return pano
    return pano[: (h // f) * f, : width * f].reshape(h // f, f, width, f, 3).mean((1, 3))


SHELL_ROWS, SHELL_COLUMNS = 32, 64
"""The dome shell's latitude and longitude segments (its texture carries the detail)."""


def dome_shell_mesh(rows: int = SHELL_ROWS, columns: int = SHELL_COLUMNS
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A unit sphere for a lat-long texture, faces turned inwards.

    Returns points (P, 3), face vertex counts (F,), face vertex indices and
    texture coordinates (P, 2) per vertex: ``s`` runs with the panorama's
    columns (s = 0 at longitude +pi, the -Z side, through +X at 0.25, +Z at 0.5),
    ``t`` up (t = 1 at +Y), the OpenEXR lat-long convention of the dome EXR.
    The seam column is doubled so ``s`` does not wrap inside a face.
    """
    s = np.linspace(0.0, 1.0, columns + 1)
    t = np.linspace(0.0, 1.0, rows + 1)
    ss, tt = np.meshgrid(s, t)  # (rows + 1, columns + 1), t = 0 at the bottom
    lon = 2.0 * np.pi * (0.5 - ss)
    lat = np.pi * (tt - 0.5)
    points = np.stack([np.sin(lon) * np.cos(lat), np.sin(lat), np.cos(lon) * np.cos(lat)], -1)
    idx = np.arange((rows + 1) * (columns + 1)).reshape(rows + 1, columns + 1)
    a, b = idx[:-1, :-1], idx[:-1, 1:]
    c, d = idx[1:, 1:], idx[1:, :-1]
    # a (bottom-left), b (bottom-right), c (top-right), d (top-left) in (s, t): seen from
    # inside the sphere a -> b -> c -> d runs counter-clockwise, so normals face inwards
    quads = np.stack([a, b, c, d], -1).reshape(-1, 4)
    return (points.reshape(-1, 3), np.full(len(quads), 4, np.int32),
            quads.reshape(-1).astype(np.int32), np.stack([ss, tt], -1).reshape(-1, 2))


def _define_dome_shell(stage: Usd.Stage, path: Sdf.Path, dome_name: str,
                       centre: np.ndarray, radius: float) -> None:
    """An emissive inward sphere textured with the dome, round the set.

    Blender turns a DomeLight into its world only when the scene already has
    one, so into an empty scene the dome is lost; it does import meshes with
    UsdPreviewSurface textures (not ``proxy`` purpose ones: off by default in
    Blender 5), so this shell brings the dome's light along. In a path tracer the
    shell hides the DomeLight behind it (black diffuse, emitting the dome), so
    the environment is counted once either way; deactivate ``DomeShell`` to
    light with the DomeLight alone.
    """
    from pxr import UsdGeom, UsdShade, Vt

    points, counts, indices, st = dome_shell_mesh()
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy((points * radius).astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(counts))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(indices))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateDoubleSidedAttr(False)
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(-radius, -radius, -radius),
                                         Gf.Vec3f(radius, radius, radius)]))
    mesh.AddTranslateOp().Set(Gf.Vec3d(*centre))
    primvar = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
        "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex)
    primvar.Set(Vt.Vec2fArray.FromNumpy(st.astype(np.float32)))
    material = UsdShade.Material.Define(stage, path.AppendChild("Look"))
    surface = UsdShade.Shader.Define(stage, material.GetPath().AppendChild("Surface"))
    surface.CreateIdAttr("UsdPreviewSurface")
    surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0, 0, 0))
    surface.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(1.0)
    reader = UsdShade.Shader.Define(stage, material.GetPath().AppendChild("St"))
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
    texture = UsdShade.Shader.Define(stage, material.GetPath().AppendChild("Dome"))
    texture.CreateIdAttr("UsdUVTexture")
    texture.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(f"./{dome_name}"))
    texture.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("raw")
    texture.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(
        reader.ConnectableAPI(), "result")
    texture.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
    surface.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(
        texture.ConnectableAPI(), "rgb")
    material.CreateSurfaceOutput().ConnectToSource(surface.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)


@dataclass
class Rig:
    """A rig before it is written: the dome's panorama at ``probe`` and the lights."""

    probe: np.ndarray
    dome: np.ndarray
    """(H, W, 3) the panorama of every splat but the lights' at ``probe``."""
    lights: dict[str, np.ndarray] | None
    """:func:`fit_rig`'s lights (``panel``: each one's rectangle or None, a sphere)."""
    box: np.ndarray | None = None
    """(2, 3) the captured space's box (the dome shell is drawn round it)."""
    metrics: dict = field(default_factory=dict)


def build_rig(scene: SplatScene, probe=None, width: int = DOME_WIDTH,
              tolerance: float = RIG_TOLERANCE, threshold: float | None = None,
              working_space: str = colour.DEFAULT_WORKING_SPACE,
              ocio_config: str | None = None, seed: int = 0,
              max_lights: int = MAX_LIGHTS, search=None) -> Rig:
    """The rig :func:`write_rig` writes: its probe, dome panorama, lights and metrics.

    ``search``: a :class:`gaslight_usd.lights.LightSearch` of ``scene`` (made here
    when None); ``threshold``: use the old radiance-above-threshold rule instead.
    """
    from ..lights import outlined_lights, search_lights
    from ..probe import default_probe
    from ..render.envmap import render_latlong

    search = search if search is not None else search_lights(scene)
    probe_how = "given (--at)"
    if probe is None:
        choice = default_probe(scene, search.space)
        probe, probe_how = choice.position, "default: " + choice.how
    probe = np.asarray(probe, np.float64).reshape(3)
    found = None
    if threshold is not None:
        mask = emitter_mask(scene, threshold)
    else:
        mask = search.emitters
        if search.lights:
            planes = room_planes(scene.metadata)
            depth = search.space.median_depth()
            outlines = outlines_from_metadata(scene.metadata)
            compact = outlined_lights(scene.metadata)
            panels = [panel_of(light.position, light.extent, light.axes, planes, depth,
                               outlines, compact) for light in search.lights]
            radii = np.array([light.radius for light in search.lights])
            found = (np.array([panel.centre if panel is not None else
                               inside_position(search.space, light.position, r)
                               for light, r, panel in zip(search.lights, radii, panels,
                                                          strict=True)]),
                     radii, np.array([len(light.splats) for light in search.lights]),
                     panels)
    eval_width = min(EVAL_WIDTH, width)
    width = max(eval_width, (width // eval_width) * eval_width)
    dome_pano = render_latlong(scene.subset(~mask), probe, width,
                               supersample=max(1, math.ceil(DOME_SAMPLING_WIDTH / width)))
    full_pano = render_latlong(scene, probe, eval_width) if mask.any() else _downsample(
        dome_pano, eval_width)
    lights, metrics = fit_rig(scene, probe, dome_pano, full_pano, mask, tolerance,
                              working_space, ocio_config, max_lights, seed, found)
    count = 0 if lights is None else len(lights["radius"])
    shapes = [] if lights is None else lights["panel"]
    metrics["sphere_lights"] = [
        {"position": [round(float(v), 5) for v in lights["position"][i]],
         "radius": round(float(lights["radius"][i]), 5),
         "radiance": [float(f"{v:.6g}") for v in lights["radiance"][i]],
         "splats": int(lights["members"][i])} for i in range(count) if shapes[i] is None]
    metrics["rect_lights"] = [
        {**shapes[i].as_dict(), "radiance": [float(f"{v:.6g}") for v in lights["radiance"][i]],
         "splats": int(lights["members"][i])} for i in range(count) if shapes[i] is not None]
    metrics.update(probe=[float(v) for v in probe], probe_chosen=probe_how,
                   emitters=int(mask.sum()), dome_width=width,
                   rule="lights finder" if threshold is None else f"radiance > {threshold}")
    return Rig(probe=probe, dome=dome_pano, lights=lights, box=search.space.box,
               metrics=metrics)


def rig_irradiance(rig: Rig, point: np.ndarray, normals: np.ndarray,
                   cells: int = 16) -> np.ndarray:
    """(M, 3) RGB irradiance the rig sends to surfaces at ``point`` facing ``normals``
    (M, 3), as a renderer lighting with the rig alone would (no occlusion): the dome
    by direction, a sphere light as a disc facing the point (pi L r^2 / d^2), a
    rectangle summed over ``cells`` x ``cells`` patches, each lit side only."""
    point = np.asarray(point, np.float64).reshape(3)
    normals = np.asarray(normals, np.float64).reshape(-1, 3)
    total = irradiance(rig.dome, normals)
    if rig.lights is None:
        return total
    grid = (np.arange(cells) + 0.5) / cells * 2.0 - 1.0
    s, t = (g.reshape(-1) for g in np.meshgrid(grid, grid, indexing="ij"))
    for i, panel in enumerate(rig.lights["panel"]):
        radiance = rig.lights["radiance"][i].astype(np.float64)
        if panel is None:
            to = rig.lights["position"][i] - point
            r = float(rig.lights["radius"][i])
            dist = max(float(np.linalg.norm(to)), 1e-9)
            d = max(dist, 1.01 * r)  # a point inside the sphere: as if at its surface
            cos = np.clip(normals @ (to / dist), 0.0, None)
            total += np.outer(cos, radiance) * np.pi * r * r / (d * d)
            continue
        spots = (panel.centre + np.outer(s * panel.half_size[0], panel.u)
                 + np.outer(t * panel.half_size[1], panel.v))
        to = spots - point
        d2 = np.maximum((to**2).sum(1), 1e-12)
        unit = to / np.sqrt(d2)[:, None]
        emit = np.clip(-(unit @ panel.normal), 0.0, None)  # the lit side faces the point
        weight = emit * (panel.area / len(spots)) / d2
        cos = np.clip(unit @ normals.T, 0.0, None)  # (cells^2, M)
        total += np.outer(cos.T @ weight, radiance)
    return total


def write_rig(stage: Usd.Stage, root: Sdf.Path, scene: SplatScene, folder: Path,
              dome_name: str, probe=None, width: int = DOME_WIDTH,
              tolerance: float = RIG_TOLERANCE, threshold: float | None = None,
              working_space: str = colour.DEFAULT_WORKING_SPACE,
              ocio_config: str | None = None, seed: int = 0,
              max_lights: int = MAX_LIGHTS, search=None) -> dict:
    """Author ``<root>/Dome`` and ``<root>/Light_NNN``; write the dome EXR in ``folder``.

    The rig is :func:`build_rig`'s (same arguments)."""
    rig = build_rig(scene, probe, width, tolerance, threshold, working_space, ocio_config,
                    seed, max_lights, search)
    probe, lights, metrics = rig.probe, rig.lights, rig.metrics
    space = colour.resolve_space(working_space, ocio_config)
    write_latlong(folder / dome_name, rig.dome, probe, space, None, ocio_config,
                  {"gaslight:content": "splats other than the rig's lights"})
    dome = UsdLux.DomeLight.Define(stage, root.AppendChild("Dome"))
    dome.CreateTextureFileAttr(Sdf.AssetPath(f"./{dome_name}"))
    dome.CreateTextureFormatAttr(UsdLux.Tokens.latlong)
    dome.CreateIntensityAttr(1.0)
    dome.CreateColorAttr(Gf.Vec3f(1.0, 1.0, 1.0))
    dome.GetPrim().SetCustomDataByKey("gaslight:probePosition", Gf.Vec3d(*probe))
    lo, hi = rig.box
    reach = float(np.linalg.norm(np.maximum(np.abs(lo - probe), np.abs(hi - probe))))
    shell_radius = 2.0 * reach if np.isfinite(reach) and reach > 0 else 100.0
    _define_dome_shell(stage, root.AppendChild("DomeShell"), dome_name, probe, shell_radius)
    count = 0 if lights is None else len(lights["radius"])
    for i in range(count):
        rad = lights["radiance"][i]
        peak = float(rad.max())
        path = root.AppendChild(f"Light_{i:03d}")
        panel = lights["panel"][i]
        if panel is None:
            light = UsdLux.SphereLight.Define(stage, path)
            light.CreateRadiusAttr(float(lights["radius"][i]))
            light.AddTranslateOp().Set(Gf.Vec3d(*lights["position"][i]))
        else:
            light = UsdLux.RectLight.Define(stage, path)
            light.CreateWidthAttr(float(2 * panel.half_size[0]))
            light.CreateHeightAttr(float(2 * panel.half_size[1]))
            # rows: the light's X (u), Y (v) and Z (-normal: it emits along -Z), origin
            frame = np.eye(4)
            frame[0, :3], frame[1, :3], frame[2, :3] = panel.u, panel.v, -panel.normal
            frame[3, :3] = panel.centre
            light.AddTransformOp().Set(Gf.Matrix4d(frame.tolist()))
        light.CreateIntensityAttr(peak)
        light.CreateColorAttr(Gf.Vec3f(*(float(c) for c in rad / max(peak, 1e-30))))
        light.CreateNormalizeAttr(False)
        light.GetPrim().SetCustomDataByKey("gaslight:splats", int(lights["members"][i]))
    dome.GetPrim().SetCustomDataByKey("gaslight:probeChoice", metrics["probe_chosen"])
    metrics["files"] = [dome_name]
    return metrics
