"""Bench suite "chain": the light that comes out of the PHOTOS, on rooms never tuned on.

Each scene is a room rendered by ``examples/make_room.py`` (the bundled example
``room`` and the variants ``bulb``, ``panels``, ``shade``, ``sun`` (a sun patch on the
floor far brighter than the window: a lit surface the photos clip, not a light) and
``hall`` (a larger room, its lamp in a far corner): other lights, layouts, albedos and
photo counts; ``NAME:SEED`` draws another room of the variant, e.g. ``room:11``;
rendered into ``<out>/scenes/`` the first time, about 2-3 min each on 2 cores, 10 for
a ``room`` draw's 24 photos at 480 x 360). For every scene the chain runs from its LDR
photos with the true poses (so the uplift and the fit are measured, not SfM), once per method:

* ``truth HDR`` -- the fit from the true HDR views: the ceiling of what the fit can do
  (with the scene's ``extra_views``, the viewpoints the README's capture adds, below);
* ``clipped photos`` -- the photos linearised, clipped lights left clipped (and not
  weighed by the surfaces they light): the floor;
* ``recursive`` -- GaSLight's recursive uplift (fast predictor), clipped pixels fitted
  as bounds (:func:`gaslight_usd.fit.losses.bounded_l1`);
* ``recursive, fills as targets`` -- the same uplift, its fills fitted like measurements
  (the behaviour before bounds), to show what the bound-aware loss buys;
* ``recursive, uplift's power`` -- the same uplift and fit, the clipped lights left at the
  uplift's power (not weighed by the surfaces they light, :mod:`gaslight_usd.fit.power`),
  to show what that buys;
* ``recursive + dark frames`` -- one photo per light re-exposed for that light
  (:mod:`.dark_frames`), the rest as shot; its unclipped light pixels are measurements,
  the other photos' clipped ones bounds;
* ``recursive + extra dark frames`` -- the capture the README advises: those darker
  frames added beside the photos they were made from (same pose), every photo kept,
  and for a shaded lamp a darker frame from below, where the shade's opening shows its
  bulb (the scene's ``extra_views``, which ``examples/make_room.py`` renders);
* ``truth HDR, planes off``, ``recursive, planes on`` -- those fits with the planes'
  prior the other way round (``fit --planes off|on``; by default it is on where no view
  clipped, as in the true HDR views, and off for clipped photos).

Then lat-long panoramas are drawn at the scene's probes (the room's middle and
0.5 m from its lights) and scored against the path-traced probes, in absolute
units (a photo-derived HDR view's relative radiance times the EXIF exposure and
the scene's camera constant K gives radiance; the bench knows K, a user would not):

* ``irradiance_psnr`` -- diffuse irradiance over 64 normals, PSNR against its peak;
* ``relight_psnr`` -- the GaSLight relight protocol (Mitsuba sphere + plane);
* ``pu21_psnr_peak`` -- PU21-PSNR with the truth's peak at 1000 cd/m^2;
* ``power_err_<light>`` -- log2(found / true) of the light arriving at the probe from
  each true light's direction (a cone 5 degrees wider than the light), in stops; the
  same for a bright surface that is not a light (``power_err_sun_patch``:
  :func:`lit_regions`), left out of ``power_err_stops_max``;
* ``unseen_deg_<light>`` -- how far the probe sees each true light from every photo that
  saw it (degrees at the light, from the fit's light sightings: what ``hdri`` warns
  about, :mod:`gaslight_usd.probe_check`);
* ``rig_irradiance_psnr`` -- ``irradiance_psnr`` of the light rig the export writes
  (:func:`gaslight_usd.usd.rig.build_rig` at its default probe: the dome and the lights,
  windows and panels as rectangles), evaluated at the probe as a renderer lighting with
  the rig alone would (:func:`gaslight_usd.usd.rig.rig_irradiance`);
* ``inside_alpha`` -- the opacity the fit's splats lay on the probe point itself: a probe
  among splats floating in the room sees them from inside (what ``hdri`` warns about
  over :data:`gaslight_usd.probe_check.INSIDE_ALPHA`);
* ``light_dist_<light>``, ``lights_found``, ``stray_light_share``, ``rect_iou_<light>``
  -- where the lights the export would write are and how well its rectangles fit the
  windows and panels (:func:`light_placement`), the same on each probe's row;
  ``light_spread_<light>``, ``floating_share`` -- where their splats are
  (:func:`emitter_spread`);
* ``weighing_<light>``, ``false_lights_weighed`` -- what the fit decided about the
  clipped light at each true light (its power's source and factor, or that it was
  taken for a lit surface), and how many clipped lights away from every true one it
  raised (:func:`weighing_summary`);
* ``one_photo_lights`` -- sunk compact lights the fit moved back along the one photo
  that frames them and kept as lights there (:mod:`gaslight_usd.fit.sunk_lights`);
* ``holes_filled`` -- splats the fit seeded on the views' compact clipped patches that
  nothing covered at the end of its densify window (:mod:`gaslight_usd.fit.holes`);
* ``planes_held``, ``floaters_on_planes``, ``wall_offset_m`` -- how many planes the fit
  held its splats on (:mod:`gaslight_usd.fit.planes`), how many bright floaters it
  brought back onto a lit patch of one (a window's), and how far its opaque splats near
  the walls lie off them (median, :func:`wall_offset`);
* ``room_faces_found``, ``room_faces_missing``, ``room_face_offset_m``,
  ``room_box_tilt_deg`` -- which of the room's walls, floor and ceiling the fit's room box
  (the planes that bound where its lights may be moved) found, how far off and how
  tilted (:func:`room_box_fit`);
* ``fill_err_<light>``, ``fill_spread_<light>``, ``fill_views_<light>`` -- the uplift's
  own error for each light before any fitting, median and spread over the views that
  clipped it (:mod:`.uplift_fill`; methods that uplift photos only).

Rows are one per (scene, method, probe); the chart puts each method's median
irradiance PSNR against its chain seconds (uplift + fit). The summary (:func:`summaries`)
scores each method against issue 16's goals over the whole run (probes within 3 dB of
the true HDR fit's, light-probe pairs within half a stop) and holds each weighed light's
claimed uncertainty against its errors.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..cameras import latlong_directions, latlong_solid_angles
from ..colour import REC709_Y, convert
from ..errors import GaslightError
from ..evaluation.metrics import psnr_from_mse, pu21_psnr_peak
from ..fit import fit_splats, load_fit_data, preset
from ..flat_outlines import outlines_from_metadata
from ..imageio import read_image
from ..light_shapes import Panel, panel_of, room_planes
from ..lights import outlined_lights, search_lights
from ..locate import example_room, find_data
from ..probe_check import inside_alpha, unseen_angles
from ..render.envmap import render_latlong
from ..sightings import Sightings
from ..splats import SplatScene
from .uplift_fill import fill_errors

NAME = "chain"
DESCRIPTION = "the light from the photos: probe errors per uplift method vs the true-HDR ceiling"
X = ("seconds", "uplift + fit seconds")
Y = ("irradiance_psnr", "probe irradiance PSNR (dB)")
HIGHER_IS_BETTER = True
TABLE = ("scene", "probe", "seconds", "irradiance_psnr", "relight_psnr", "pu21_psnr_peak",
         "power_err_stops_max", "rig_irradiance_psnr")
REFERENCES = ("truth HDR", "clipped photos")
TRUTH_HDR_METHOD = "measured (the scene's true HDR views)"
"""The ``hdr_method`` a fit from the true HDR views carries: its lights' power is
measured (:func:`gaslight_usd.lights.power_source`)."""
SCENES = ("room", "bulb", "panels", "shade", "sun", "hall")
METHODS = ("truth HDR", "clipped photos", "recursive", "recursive, fills as targets",
           "recursive, uplift's power", "recursive + dark frames",
           "recursive + extra dark frames", "truth HDR, planes off", "recursive, planes on")
PLANES_SUFFIXES = {", planes on": "on", ", planes off": "off"}
"""A method's suffix: the fit with ``--planes on`` or ``off`` (:mod:`gaslight_usd.fit.planes`;
without one, the default ``auto``)."""
TRUTH_SPACE = "lin_rec709_scene"
CONE_MARGIN_DEG = 5.0
MIN_CONE_DEG = 6.0


def notes(options: dict[str, Any]) -> list[str]:
    presets = ", ".join(options.get("presets") or ("fast",))
    return [f"preset {presets}; true poses; probe panoramas "
            "scored in absolute radiance (EXIF exposure x the scene's camera constant K)"]


# -- scenes ---------------------------------------------------------------------------------

def split_scene(name: str) -> tuple[str, int | None]:
    """``VARIANT`` or ``VARIANT:SEED`` (another draw of the variant's textures and
    objects: ``room:11`` is a room the bench and the fit were never tuned on)."""
    variant, _, seed = name.partition(":")
    if variant not in SCENES or (seed and not seed.isdigit()):
        raise GaslightError(f"chain suite: unknown scene {name!r} (scenes: {', '.join(SCENES)}, "
                            "each optionally :SEED, e.g. room:11)")
    return variant, int(seed) if seed else None


def scene_dir(name: str, out: Path, progress=None) -> Path:
    """The scene's folder: the bundled example, or a variant rendered once into ``out``."""
    variant, seed = split_scene(name)
    if name == "room":
        return example_room()
    folder = out / "scenes" / (variant if seed is None else f"{variant}-{seed}")
    if (folder / "digests.json").exists() and not lacks_frames_from_below(folder):
        return folder
    script = find_data("examples/make_room.py")
    if not script.exists():
        raise FileNotFoundError("examples/make_room.py not found: run the bench from a checkout")
    if progress is not None:
        progress.message(f"rendering scene {name!r} with Mitsuba (2-3 min on 2 cores)")
    args = ["--variant", variant] + ([] if seed is None else ["--seed", str(seed)])
    subprocess.run([sys.executable, str(script), *args, "--out", str(folder)],
                   check=True, stdout=subprocess.DEVNULL)
    return folder


def lacks_frames_from_below(folder: Path) -> bool:
    """A rendered room with a shaded lamp but no views from below it (``scene.json``'s
    ``extra_views``): rendered by a ``make_room.py`` older than those views, so the
    README's capture would go without them; :func:`scene_dir` renders it again."""
    info = json.loads((folder / "scene.json").read_text())
    shaded = any(light.get("shaded") for light in info.get("lights", []))
    return shaded and not info.get("extra_views")


def scene_lights(info: dict[str, Any]) -> list[dict[str, Any]]:
    """The true emitters: ``scene.json``'s ``lights`` (variants) or its lamp and window."""
    if "lights" in info:
        return info["lights"]
    lamp, win = info["lamp"], info["window"]
    return [{"name": "lamp", "kind": "sphere", "center": lamp["center"],
             "radius": lamp["radius"], "radiance": lamp["radiance"]},
            {"name": "window", "kind": "rectangle", "center": win["center"],
             "corners": win["corners"], "normal": win["normal"], "radiance": win["radiance"]}]


def lit_regions(info: dict[str, Any]) -> list[dict[str, Any]]:
    """Bright surfaces of a room that are not lights (the ``sun`` room's sunlit floor,
    ``scene.json``'s ``sun_patch``), as rectangles: scored from each probe like a light
    (``power_err_<name>``), never counted among the lights."""
    patch = info.get("sun_patch")
    if patch is None:
        return []
    (x0, z0), (x1, z1) = patch["min_xz"], patch["max_xz"]
    return [{"name": "sun_patch", "kind": "rectangle",
             "center": [(x0 + x1) / 2, 0.0, (z0 + z1) / 2], "normal": [0.0, 1.0, 0.0],
             "corners": [[x0, 0.0, z0], [x1, 0.0, z0], [x1, 0.0, z1], [x0, 0.0, z1]]}]


def dark_frame_targets(info: dict[str, Any]) -> list[dict[str, Any]]:
    """What the README's capture aims a darker frame at: each light, and each bright
    surface every photo clips, twice, from two places (a sunlit patch lights the room as
    a lamp does, and only a frame that measured it pins its power; a plain floor holds
    no sparse point, and only two such frames' outlines of the patch pin its depth:
    :mod:`gaslight_usd.fit.lit_floor`)."""
    regions = lit_regions(info)
    return scene_lights(info) + regions + regions


def light_cone(light: dict[str, Any], position: np.ndarray) -> tuple[np.ndarray, float]:
    """Unit direction from ``position`` to the light and the cone half-angle (radians)
    that holds it, widened by :data:`CONE_MARGIN_DEG`."""
    centre = np.asarray(light["center"], np.float64)
    d = centre - position
    dist = float(np.linalg.norm(d))
    axis = d / dist
    if light["kind"] == "sphere":
        half = math.asin(min(1.0, light["radius"] / dist))
    else:
        corners = np.asarray(light["corners"], np.float64) - position
        corners /= np.linalg.norm(corners, axis=1, keepdims=True)
        half = float(np.arccos(np.clip(corners @ axis, -1, 1)).max())
    return axis, max(half + math.radians(CONE_MARGIN_DEG), math.radians(MIN_CONE_DEG))


# -- scores ---------------------------------------------------------------------------------

def fibonacci_normals(n: int = 64) -> np.ndarray:
    """``n`` unit vectors spread evenly over the sphere."""
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    theta = math.pi * (1 + 5 ** 0.5) * i
    return np.stack([np.cos(theta) * np.sin(phi), np.cos(phi), np.sin(theta) * np.sin(phi)], 1)


def irradiance_luminance(pano: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Luminance of the irradiance of a Rec.709 lat-long panorama on ``normals``."""
    h, w = pano.shape[:2]
    dirs = latlong_directions(w, h).reshape(-1, 3)
    d_omega = np.broadcast_to(latlong_solid_angles(w, h), (h, w)).reshape(-1)
    lum = pano.reshape(-1, 3).astype(np.float64) @ np.array(REC709_Y)
    return (np.clip(dirs @ normals.T, 0.0, None) * (d_omega * lum)[:, None]).sum(0)


def irradiance_psnr(pano: np.ndarray, truth: np.ndarray) -> float:
    """PSNR of the irradiance luminance over 64 normals, the truth's largest as the peak."""
    normals = fibonacci_normals()
    return _against_truth(irradiance_luminance(pano, normals), truth, normals)


def _against_truth(found: np.ndarray, truth: np.ndarray, normals: np.ndarray) -> float:
    """PSNR of irradiance luminances ``found`` on ``normals`` against the truth panorama's."""
    e_true = irradiance_luminance(truth, normals)
    return psnr_from_mse(float(np.mean((found - e_true) ** 2)), peak=float(e_true.max()))


def cone_power(pano: np.ndarray, axis: np.ndarray, half_angle: float) -> float:
    """Luminance x solid angle of a lat-long panorama inside a cone."""
    h, w = pano.shape[:2]
    dirs = latlong_directions(w, h)
    inside = dirs @ axis >= math.cos(half_angle)
    d_omega = np.broadcast_to(latlong_solid_angles(w, h), (h, w))
    lum = pano.astype(np.float64) @ np.array(REC709_Y)
    return float((lum * d_omega)[inside].sum())


def power_errors(pano: np.ndarray, truth: np.ndarray, lights: list[dict[str, Any]],
                 position: np.ndarray) -> dict[str, float]:
    """Stops between the found and the true light from each light's direction."""
    out = {}
    for light in lights:
        axis, half = light_cone(light, position)
        found, true = cone_power(pano, axis, half), cone_power(truth, axis, half)
        out[f"power_err_{light['name']}"] = float(np.log2(max(found, 1e-9) / max(true, 1e-9)))
    return out


# -- the chain ------------------------------------------------------------------------------

def emitter_distance(light: dict[str, Any], points: np.ndarray) -> np.ndarray:
    """Distances (m) from ``points`` (N, 3) to a true emitter's surface: a sphere's, or a
    rectangle's (the nearest point of the rectangle, edges included)."""
    centre = np.asarray(light["center"], np.float64)
    if light["kind"] == "sphere":
        return np.abs(np.linalg.norm(points - centre, axis=1) - float(light["radius"]))
    corners = np.asarray(light["corners"], np.float64)
    u, v = corners[1] - corners[0], corners[3] - corners[0]
    rel = points - corners[0]
    a = np.clip(rel @ u / (u @ u), 0.0, 1.0)
    b = np.clip(rel @ v / (v @ v), 0.0, 1.0)
    nearest = corners[0] + a[:, None] * u + b[:, None] * v
    return np.linalg.norm(points - nearest, axis=1)


def light_placement(scene: SplatScene, lights: list[dict[str, Any]], search=None
                    ) -> dict[str, Any]:
    """Where the output's lights are (:func:`gaslight_usd.lights.find_lights`, the rig
    the USD export writes) against the true emitters:

    * ``lights_found`` -- how many lights the export would write;
    * ``light_dist_<name>`` -- metres from each true emitter to the nearest found light
      (its power-weighted centre), minus that light's radius (0 when it covers it);
    * ``stray_light_share`` -- the share of the found lights' power more than 0.3 m from
      every true emitter (floating or smeared bright splats);
    * ``rect_iou_<name>`` -- for each true rectangle (a window, a panel), the overlap
      (intersection over union) of the best of the rig's rectangles
      (:func:`gaslight_usd.light_shapes.panel_of`) with it, 0 where the rig has none.
    """
    search = search if search is not None else search_lights(scene)
    found = search.lights
    row: dict[str, Any] = {"lights_found": len(found), **emitter_spread(scene, search.emitters,
                                                                        lights)}
    if not found:
        return row | {f"light_dist_{li['name']}": float("nan") for li in lights} | {
            "stray_light_share": float("nan")}
    pos = np.stack([f.position for f in found]).astype(np.float64)
    radius = np.array([f.radius for f in found])
    dists = np.stack([emitter_distance(li, pos) for li in lights])  # (lights, found)
    for li, d in zip(lights, dists, strict=True):
        row[f"light_dist_{li['name']}"] = round(float(np.maximum(d - radius, 0.0).min()), 3)
    power = np.array([float(f.power.sum()) for f in found])
    stray = np.maximum(dists.min(axis=0) - radius, 0.0) > 0.3
    row["stray_light_share"] = round(float(power[stray].sum() / max(power.sum(), 1e-30)), 3)
    planes, outlines = room_planes(scene.metadata), outlines_from_metadata(scene.metadata)
    depth = search.space.median_depth()
    compact = outlined_lights(scene.metadata)
    panels = [p for p in (panel_of(f.position, f.extent, f.axes, planes, depth, outlines,
                                   compact) for f in found) if p is not None]
    for li in lights:
        if li.get("kind") != "sphere" and "corners" in li:
            corners = np.asarray(li["corners"], np.float64)
            row[f"rect_iou_{li['name']}"] = round(max(
                (rect_iou(p, corners) for p in panels), default=0.0), 3)
    return row


def rect_iou(panel: Panel, corners: np.ndarray, samples: int = 64) -> float:
    """Intersection over union of a rig rectangle and a true one (``corners`` (4, 3), in
    order round it), by sampling the true one; 0 where their planes are over 0.1 m
    apart or cross."""
    corners = np.asarray(corners, np.float64)
    side_a, side_b = corners[1] - corners[0], corners[3] - corners[0]
    true_area = float(np.linalg.norm(np.cross(side_a, side_b)))
    if abs(float(np.cross(side_a, side_b) @ panel.normal)) < 0.9 * true_area:
        return 0.0
    g = (np.arange(samples) + 0.5) / samples
    pts = (corners[0] + g[:, None, None] * side_a + g[None, :, None] * side_b).reshape(-1, 3)
    rel = pts - panel.centre
    inside = ((np.abs(rel @ panel.u) <= panel.half_size[0])
              & (np.abs(rel @ panel.v) <= panel.half_size[1])
              & (np.abs(rel @ panel.normal) <= 0.1))
    inter = float(inside.mean()) * true_area
    return inter / max(panel.area + true_area - inter, 1e-12)


WALL_NEAR_M = 0.5
"""Opaque splats within this of a room's wall count as the wall's (:func:`wall_offset`)."""


def wall_offset(scene: SplatScene, room: dict[str, Any], backdrop: int) -> float:
    """Median distance (m) from the room's nearest wall of the fitted opaque splats
    (opacity over 0.5, the backdrop's last ``backdrop`` left out) within
    :data:`WALL_NEAR_M` of a wall (the x and z faces of the box ``room``): how far the
    fit smears its walls (furniture near a wall counts too, a few per cent). NaN where
    none is near."""
    lo, hi = np.asarray(room["min"], np.float64), np.asarray(room["max"], np.float64)
    fitted = scene.count - backdrop
    pos = scene.positions[:fitted].astype(np.float64)[scene.opacities[:fitted] > 0.5]
    dist = np.abs(np.concatenate([pos[:, [0, 2]] - lo[[0, 2]], pos[:, [0, 2]] - hi[[0, 2]]],
                                 axis=1)).min(axis=1)
    near = dist[dist < WALL_NEAR_M]
    return round(float(np.median(near)), 4) if len(near) else float("nan")


ROOM_FACE_NEAR_M = 0.15
"""A plane of the fit's room box lies on a face of the true room when it passes within
this of the face's centre..."""
ROOM_FACE_TILT_DEG = 5.0
"""...and its normal is within this of the face's (:func:`room_box_fit`)."""
ROOM_FACES = ("x-", "x+", "floor", "ceiling", "z-", "z+")
"""The true room's faces: its box's (axis, side) in order x, y (up), z."""


def room_box_fit(planes: list[dict[str, Any]], room: dict[str, Any]) -> dict[str, Any]:
    """How the fit's room box (``fit_metrics["room_box"]``: the planes that bound where a
    light may be moved, :func:`gaslight_usd.fit.planes.room_box`) matches the generated
    room's axis-aligned box ``room``:

    * ``room_faces_found`` -- how many of the six faces a plane of the box lies on
      (:data:`ROOM_FACE_NEAR_M`, :data:`ROOM_FACE_TILT_DEG`); ``room_faces_missing`` the
      others (``x-``, ``x+``, ``floor``, ``ceiling``, ``z-``, ``z+``): a window's wall
      missing leaves its floating splats where they are;
    * ``room_face_offset_m`` -- the largest distance from a found face's centre to its
      plane (NaN where none is found);
    * ``room_box_tilt_deg`` -- the largest angle between a plane's normal and the room's
      nearest axis (the box's planes are squared to the fit's main directions: a tilted
      frame spreads every plane along the other two, and those go unfound).
    """
    lo, hi = np.asarray(room["min"], np.float64), np.asarray(room["max"], np.float64)
    mid = (lo + hi) / 2.0
    normals = np.array([p["normal"] for p in planes], np.float64).reshape(-1, 3)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    offsets = np.array([p["offset"] for p in planes], np.float64)
    cos_min = math.cos(math.radians(ROOM_FACE_TILT_DEG))
    found, missing, offsets_m = 0, [], []
    for k, name in enumerate(ROOM_FACES):
        axis, side = divmod(k, 2)
        centre = mid.copy()
        centre[axis] = (lo if side == 0 else hi)[axis]
        dist = np.abs(normals @ centre - offsets)
        on = (np.abs(normals[:, axis]) >= cos_min) & (dist <= ROOM_FACE_NEAR_M)
        if on.any():
            found += 1
            offsets_m.append(float(dist[on].min()))
        else:
            missing.append(name)
    tilt = np.degrees(np.arccos(np.clip(np.abs(normals).max(axis=1, initial=0.0), 0.0, 1.0)))
    return {"room_faces_found": found, "room_faces_missing": " ".join(missing),
            "room_face_offset_m": round(max(offsets_m), 3) if offsets_m else float("nan"),
            "room_box_tilt_deg": round(float(tilt.max()), 2) if len(tilt) else float("nan")}


def weighing_summary(clipped: list[dict[str, Any]], lights: list[dict[str, Any]]
                     ) -> dict[str, Any]:
    """What the fit decided about each clipped light (``fit_metrics["clipped_lights"]``,
    :mod:`gaslight_usd.fit.power`), against the true emitters:

    * ``weighing_<name>`` -- for the clipped light nearest each true emitter (within
      :data:`NEAR_EMITTER_M`): its power's source and factor over the fill, ``inferred
      +10.75 (1.2)`` (log2, its uncertainty in stops), or why it was not weighed; empty
      where no clipped light is near it;
    * ``power_source_<name>``, ``claimed_stops_<name>`` -- that light's power source and
      the uncertainty the output claims for it (stops; empty and NaN where none is near),
      which :func:`summaries` holds against the errors at the probes;
    * ``false_lights_weighed`` -- clipped lights farther than that from every true
      emitter whose power was raised (a lit surface or a floater taken for a lamp).
    """
    row: dict[str, Any] = {}
    for li in lights:
        row |= {f"weighing_{li['name']}": "", f"power_source_{li['name']}": "",
                f"claimed_stops_{li['name']}": float("nan")}
    if not clipped or not lights:
        return row | {"false_lights_weighed": 0}
    pos = np.array([c["position"] for c in clipped], np.float64)
    dists = np.stack([emitter_distance(li, pos) for li in lights])  # (lights, clipped)
    for li, d in zip(lights, dists, strict=True):
        k = int(np.argmin(d))
        if d[k] > NEAR_EMITTER_M:
            continue
        c = clipped[k]
        text = (f"{c['power_source']} {math.log2(max(c['factor'], 1e-30)):+.2f} "
                f"({c['power_uncertainty_stops']:.1f})")
        if c.get("lit_surface_albedo") is not None:
            text += f" lit-surface albedo {c['lit_surface_albedo']:.2f}"
        row[f"weighing_{li['name']}"] = text
        row[f"power_source_{li['name']}"] = c["power_source"]
        row[f"claimed_stops_{li['name']}"] = float(c["power_uncertainty_stops"])
    false = dists.min(axis=0) > NEAR_EMITTER_M
    row["false_lights_weighed"] = int(sum(1 for c, f in zip(clipped, false, strict=True)
                                          if f and c["factor"] > 1.0))
    return row


NEAR_EMITTER_M = 0.3
"""A clipped light this close to a true emitter's surface is that emitter's."""
FLOATING_M = 0.1
"""Emitter splats farther than this from every true emitter's surface are floating."""


def emitter_spread(scene: SplatScene, emitters: np.ndarray, lights: list[dict[str, Any]]
                   ) -> dict[str, Any]:
    """Where each light's *splats* are, not just its centre (issue 16 item 4: a window
    is flat in its wall, a bulb compact; splats floating off it or smeared along the
    viewing rays are a defect a probe near the light sees close up):

    * ``light_spread_<name>`` -- metres from the true emitter's surface within which 90 %
      of the power of the emitter splats nearest to it lies (NaN: no emitter near it);
    * ``floating_share`` -- the share of all emitter splats' power more than
      :data:`FLOATING_M` from every true emitter.

    Power is radiance x integrated alpha (:func:`gaslight_usd.surroundings.splat_sigma`).
    """
    from ..surroundings import splat_sigma

    idx = np.flatnonzero(emitters)
    row: dict[str, Any] = {f"light_spread_{li['name']}": float("nan") for li in lights}
    if not len(idx) or not lights:
        return row | {"floating_share": float("nan")}
    pos = scene.positions[idx].astype(np.float64)
    power = (scene.base_colours[idx].max(axis=1) * scene.opacities[idx]
             * splat_sigma(scene)[idx] ** 2).astype(np.float64)
    dists = np.stack([emitter_distance(li, pos) for li in lights])  # (lights, splats)
    nearest = dists.argmin(axis=0)
    best = dists.min(axis=0)
    for k, li in enumerate(lights):
        mine = nearest == k
        if mine.any():
            order = np.argsort(best[mine])
            share = np.cumsum(power[mine][order]) / max(power[mine].sum(), 1e-30)
            at = min(int(np.searchsorted(share, 0.9)), len(order) - 1)
            row[f"light_spread_{li['name']}"] = round(float(best[mine][order][at]), 3)
    row["floating_share"] = round(float(power[best > FLOATING_M].sum()
                                        / max(power.sum(), 1e-30)), 3)
    return row


def absolute_scale(hdr_attrs: dict[str, Any], exposure: dict[str, Any]) -> float:
    """Radiance per unit of relative radiance: the reference exposure's t x K.

    Relative radiance 1 reads as linear 1 at the set's reference EV
    (``log2(t * ISO/100 / N^2)``); the scene's camera gives photo = radiance x t x K.
    """
    ref_ev = float(hdr_attrs.get("gaslight:reference_ev", 0.0))
    t_ref = 2.0 ** ref_ev * exposure["FNumber"] ** 2 * 100.0 / exposure["ISO"]
    return 1.0 / (t_ref * exposure["K"])


def uplift(photos: Path, out: Path, method: str) -> Path:
    """Run one uplift converter on the photos; returns the HDR view folder."""
    from ..kinds import Kind
    from ..pipeline import Job, run_job
    from ..progress import Progress

    converter = {"clipped photos": "uplift.linear"}.get(method, "uplift.recursive")
    job = Job(inputs=[photos], out_dir=out, targets=(Kind.HDR_VIEWS,),
              choose={"uplift": converter}, resume=False)
    found = run_job(job, progress=Progress(quiet=True))
    return found[Kind.HDR_VIEWS].path


def fitted_scene(folder: Path, method: str, work: Path, preset_name: str, seed: int,
                 progress=None) -> tuple[SplatScene, float, float, dict[str, Any]]:
    """(splats, seconds, scale to absolute Rec.709 radiance, fit metrics) for a method."""
    t0 = time.perf_counter()
    info = json.loads((folder / "scene.json").read_text())
    planes = next((mode for suffix, mode in PLANES_SUFFIXES.items()
                   if method.endswith(suffix)), None)
    for suffix in PLANES_SUFFIXES:
        method = method.removesuffix(suffix)
    poses = folder / "sparse" / "0"
    if method == "truth HDR":
        from .dark_frames import truth_with_extra_views

        hdr, poses = truth_with_extra_views(folder, work)
        scale = 1.0
    elif method in ("recursive + dark frames", "recursive + extra dark frames"):
        from .dark_frames import dark_frame_photos, poses_with_dark_frames

        photos = work / "photos"
        extra = method == "recursive + extra dark frames"
        chosen = dark_frame_photos(folder, photos, dark_frame_targets(info), extra=extra)
        if extra:
            poses = poses_with_dark_frames(folder, chosen, work / "sparse")
        hdr = uplift(photos, work / "run", method)
    else:
        hdr = uplift(folder / "photos", work, method)
    cfg = preset(preset_name)
    if method == "recursive, fills as targets":
        cfg = cfg.updated(clip_bounds=False)
    if method in ("recursive, uplift's power", "clipped photos"):
        cfg = cfg.updated(infer_power=False)  # the floor: the photos as they are
    if planes is not None:
        cfg = cfg.updated(plane_prior=planes)
    data = load_fit_data(hdr, poses, working_size=cfg.working_size)
    if method != "truth HDR":
        scale = absolute_scale(data.attributes, info["exposure"])
    result = fit_splats(data, cfg, seed=seed, progress=progress)
    seconds = time.perf_counter() - t0
    metrics = dict(result.metrics)
    # what the export's lights finder reads (converters/fit_splats.py writes the same):
    # the HDR method says whether clipped power is a lower bound, the fit's metrics which
    # lights it weighed
    result.scene.metadata.update({
        "exposure_scale": float(data.attributes.get("gaslight:exposure_scale", 1.0) or 1.0),
        "provenance": {"hdr_method": data.attributes.get("gaslight:method")},
        "fit_metrics": result.metrics})
    if method == "truth HDR":
        # true radiance, as merged brackets measure it: the lights finder's clipped-source
        # headroom (power unknown, 7 stops) would let the lamp explain the window away
        result.scene.metadata["hdr_method"] = TRUTH_HDR_METHOD
    else:
        metrics["uplift_fill"] = fill_errors(folder, hdr, scene_lights(info), scale)
    return result.scene, seconds, scale, metrics


def unseen_columns(scene: SplatScene, lights: list[dict[str, Any]], position: np.ndarray
                   ) -> dict[str, float]:
    """``unseen_deg_<light>``: how far (degrees, at the true light) the probe is from every
    photo that saw the light, as the fit's light sightings tell it (what ``hdri`` warns
    about past :data:`gaslight_usd.probe_check.UNSEEN_LIGHT_DEG`); NaN where no photo's
    light region holds the light."""
    centres = np.array([light["center"] for light in lights], np.float64)
    angles = unseen_angles(position, centres, Sightings.from_metadata(scene.metadata))
    return {f"unseen_deg_{light['name']}": float(a)
            for light, a in zip(lights, angles, strict=True)}


RIG_DOME_WIDTH = 256
"""The rig's dome is drawn this wide for ``rig_irradiance_psnr`` (irradiance is smooth:
the export's 1024 moves it little and costs 16 times the pixels)."""


def rig_irradiance_psnr(rig, truth: np.ndarray, position: np.ndarray, space: str,
                        scale: float) -> float:
    """``irradiance_psnr`` of the rig's light at ``position`` against the truth panorama."""
    from ..usd.rig import rig_irradiance

    normals = fibonacci_normals()
    rgb = rig_irradiance(rig, position, normals)
    if space != TRUTH_SPACE:
        rgb = convert(rgb.astype(np.float32), space, TRUTH_SPACE).astype(np.float64)
    return _against_truth((rgb * scale) @ np.array(REC709_Y), truth, normals)


def probe_rows(scene: SplatScene, folder: Path, scale: float, relight: bool,
               renderer=None, rig=None) -> list[dict[str, Any]]:
    """One row per probe: the scores of the module docstring (``rig_irradiance_psnr``
    where ``rig``, a :class:`gaslight_usd.usd.rig.Rig` of ``scene``, is given)."""
    info = json.loads((folder / "scene.json").read_text())
    probes = json.loads((folder / "probes" / "probes.json").read_text())["probes"]
    lights = scene_lights(info)
    space = scene.metadata.get("colour_space") or TRUTH_SPACE
    rows = []
    for k, probe in enumerate(probes):
        truth = read_image(folder / "probes" / probe["name"]).pixels
        pos = np.asarray(probe["position"], np.float64)
        pano = render_latlong(scene, pos, truth.shape[1])
        if space != TRUTH_SPACE:
            pano = convert(pano, space, TRUTH_SPACE)
        pano = np.maximum(pano * np.float32(scale), 0.0)
        light_errors = power_errors(pano, truth, lights, pos)
        row: dict[str, Any] = {"probe": k, "irradiance_psnr": irradiance_psnr(pano, truth),
                               "pu21_psnr_peak": pu21_psnr_peak(pano, truth),
                               **light_errors,
                               **power_errors(pano, truth, lit_regions(info), pos),
                               **unseen_columns(scene, lights, pos),
                               "inside_alpha": inside_alpha(pos, scene)}
        if rig is not None:
            row["rig_irradiance_psnr"] = rig_irradiance_psnr(rig, truth, pos, space, scale)
        errs = [abs(v) for v in light_errors.values()]
        row["power_err_stops_max"] = max(errs) if errs else float("nan")
        if relight:
            from ..evaluation.relight import relight_scores
            row["relight_psnr"] = relight_scores(pano, truth, renderer).psnr
        rows.append(row)
    return rows


def run(options: dict[str, Any]) -> list[dict[str, Any]]:
    from ..usd.rig import build_rig

    quick = bool(options.get("quick"))
    seed = int(options.get("seed", 0))
    out = Path(options.get("out") or ".")
    progress = options.get("progress")
    presets = options.get("presets") or ("fast",)
    scenes = options.get("scenes") or (("room",) if quick else SCENES)
    methods = options.get("methods") or (("clipped photos", "recursive") if quick
                                         else METHODS)
    unknown = [n for n in methods if n not in METHODS]
    if unknown:
        raise GaslightError(f"chain suite: unknown method {', '.join(unknown)} "
                            f"(methods: {', '.join(METHODS)})")
    for name in scenes:
        split_scene(name)
    renderer = None
    if not quick:
        from ..evaluation.relight import RelightRenderer
        renderer = RelightRenderer()
    rows: list[dict[str, Any]] = []
    for scene_name in scenes:
        folder = scene_dir(scene_name, out, progress)
        for preset_name in presets:
            for method in methods:
                if progress is not None:
                    progress.message(f"{scene_name}: {method} ({preset_name})")
                work = out / "work" / scene_name.replace(":", "-") / method.replace(
                    " ", "_").replace(",", "").replace("'", "")
                scene, seconds, scale, metrics = fitted_scene(folder, method, work,
                                                              preset_name, seed)
                info = json.loads((folder / "scene.json").read_text())
                search = search_lights(scene)
                placement = light_placement(scene, scene_lights(info), search)
                placement |= weighing_summary(metrics.get("clipped_lights") or [],
                                              scene_lights(info))
                placement["one_photo_lights"] = int(
                    (metrics.get("surfaced_lights") or {}).get("placed_lights", 0))
                placement["holes_filled"] = int(
                    (metrics.get("holes_filled") or {}).get("splats", 0))
                planes = metrics.get("planes") or {}
                placement["planes_held"] = len(planes.get("planes", []))
                placement["floaters_on_planes"] = int(planes.get("floaters_on_planes", 0))
                placement["wall_offset_m"] = wall_offset(scene, info["room"],
                                                         int(metrics.get("backdrop_splats", 0)))
                placement |= room_box_fit(metrics.get("room_box") or [], info["room"])
                placement |= metrics.get("uplift_fill", {})
                rig = build_rig(scene, width=RIG_DOME_WIDTH, search=search)
                for row in probe_rows(scene, folder, scale, relight=not quick,
                                      renderer=renderer, rig=rig):
                    rows.append({"method": method, "setting": preset_name,
                                 "scene": scene_name, "seconds": round(seconds, 2),
                                 "splats": metrics["splats"], **row, **placement})
    return rows


# -- the goals, per method ------------------------------------------------------------------

GOAL_DB = 3.0
"""Issue 16's goal: irradiance PSNR within this of the fit from the true HDR views."""
GOAL_STOPS = 0.5
"""...and every light's power within this many stops, at every probe."""
WEIGHED_SOURCES = ("inferred", "fused")
"""Power sources whose uncertainty the surfaces' weighing claims
(:mod:`gaslight_usd.fit.power`)."""


def _share(flags: list[bool]) -> float:
    return round(float(np.mean(flags)), 3) if flags else float("nan")


def summaries(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (method, preset), over every scene and probe of the run, the goals and how
    honest the output's uncertainties are:

    * ``irradiance_psnr_mean`` / ``_median``; ``within_3db_of_truth`` -- the share of
      probes within :data:`GOAL_DB` of the ``truth HDR`` fit's on the same scene, probe
      and preset (NaN without that method in the run);
    * ``light_probe_pairs``, ``lights_median_abs_stops``, ``lights_within_half_stop`` --
      every true light's ``power_err`` at every probe (lit surfaces such as a sunlit
      floor are not lights: left out);
    * ``weighed_pairs``, ``weighed_within_claim``, ``weighed_z_rms`` -- the pairs whose
      light's power the surfaces weighed (:data:`WEIGHED_SOURCES`): the share whose error
      is within the uncertainty the output claims for that light (about 68 % if the claim
      is one honest sigma), and the root mean square of error / claim (about 1);
    * ``predicted_pairs``, ``predicted_within_claim`` -- the same for lights left at the
      uplift's fill (``predicted``, claimed :data:`gaslight_usd.fit.power.PREDICTOR_SIGMA_STOPS`).
    """
    truth = {(r["scene"], r["setting"], r["probe"]): float(r["irradiance_psnr"])
             for r in rows if r.get("method") == "truth HDR"}
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in rows:
        groups.setdefault((str(row.get("method")), str(row.get("setting"))), []).append(row)
    out = []
    for (method, setting), members in groups.items():
        psnr = [float(r["irradiance_psnr"]) for r in members]
        errors: list[float] = []
        claims: dict[str, list[tuple[float, float]]] = {"weighed": [], "predicted": []}
        for r in members:
            for key in r:
                if not key.startswith("weighing_"):
                    continue
                name = key[len("weighing_"):]
                err = float(r.get(f"power_err_{name}", math.nan))
                if not math.isfinite(err):
                    continue
                errors.append(err)
                source = r.get(f"power_source_{name}", "")
                claim = float(r.get(f"claimed_stops_{name}", math.nan))
                kind = ("weighed" if source in WEIGHED_SOURCES
                        else "predicted" if source == "predicted" else None)
                if kind and math.isfinite(claim) and claim > 0:
                    claims[kind].append((err, claim))
        paired = [(p, truth[(r["scene"], r["setting"], r["probe"])])
                  for p, r in zip(psnr, members, strict=True)
                  if (r["scene"], r["setting"], r["probe"]) in truth]
        weighed = claims["weighed"]
        entry: dict[str, Any] = {
            "method": method, "preset": setting, "probes": len(members),
            "irradiance_psnr_mean": round(float(np.mean(psnr)), 2),
            "irradiance_psnr_median": round(float(np.median(psnr)), 2),
            "within_3db_of_truth": (_share([p >= t - GOAL_DB for p, t in paired])
                                    if method != "truth HDR" else float("nan")),
            "light_probe_pairs": len(errors),
            "lights_median_abs_stops": (round(float(np.median(np.abs(errors))), 2)
                                        if errors else float("nan")),
            "lights_within_half_stop": _share([abs(e) <= GOAL_STOPS for e in errors]),
            "weighed_pairs": len(weighed),
            "weighed_within_claim": _share([abs(e) <= c for e, c in weighed]),
            "weighed_z_rms": (round(float(np.sqrt(np.mean([(e / c) ** 2 for e, c in weighed]))),
                                    2) if weighed else float("nan")),
            "predicted_pairs": len(claims["predicted"]),
            "predicted_within_claim": _share([abs(e) <= c for e, c in claims["predicted"]]),
        }
        out.append(entry)
    return out
