"""What a file holds: the facts behind ``gaslight2usd info``.

Each ``describe_*`` returns a JSON-ready dict; :func:`format_facts` renders
one for people.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError
from .kinds import USD_EXTENSIONS

IMAGE_INFO_EXTENSIONS = (".exr", ".hdr", ".jpg", ".jpeg", ".png", ".tif", ".tiff", ".tx")

# OpenImageIO reads OpenEXR's ``envmap`` attribute (and a .tx's texture kind) as
# ``textureformat``; info names it the way OpenEXR does.
ENVMAP_NAMES = {"LatLong Environment": "latlong", "CubeFace Environment": "cube"}


def dynamic_range_stops(luminance: np.ndarray) -> float:
    """log2(peak / 1st percentile) over the positive luminance values."""
    positive = luminance[luminance > 0]
    if positive.size == 0:
        return 0.0
    low = float(np.percentile(positive, 1))
    return float(np.log2(float(positive.max()) / low)) if low > 0 else 0.0


def describe_image(path: Path) -> dict[str, Any]:
    import OpenImageIO as oiio

    from . import colour
    from .imageio import read_pixels

    spec, pixels = read_pixels(path)
    pixels = pixels.astype(np.float32, copy=False)
    inp = oiio.ImageInput.open(str(path))
    file_format = inp.format_name() if inp is not None else None
    if inp is not None:
        inp.close()
    finite = np.isfinite(pixels)
    rgb = np.where(finite, pixels, 0.0)[..., :3]
    if rgb.shape[-1] < 3:
        rgb = np.repeat(rgb[..., :1], 3, axis=-1)
    tagged = spec.getattribute("oiio:ColorSpace") or spec.getattribute("colorSpace")
    weights = colour.luminance_weights(tagged if isinstance(tagged, str) else None,
                                       fallback=True)
    lum = rgb @ weights
    attrs = {a.name: a.value for a in spec.extra_attribs}
    return {
        "file": str(path),
        "type": "image",
        "format": file_format,
        "width": spec.width,
        "height": spec.height,
        "channels": list(spec.channelnames),
        "pixel_type": str(spec.format),
        "colour_space": tagged if isinstance(tagged, str) else None,
        "chromaticities": list(attrs["chromaticities"]) if "chromaticities" in attrs else None,
        "envmap": envmap_kind(attrs),
        "min": [float(v) for v in rgb.reshape(-1, 3).min(axis=0)],
        "max": [float(v) for v in rgb.reshape(-1, 3).max(axis=0)],
        "peak_luminance": float(lum.max()),
        "median_luminance": float(np.median(lum)),
        "dynamic_range_stops": round(dynamic_range_stops(lum), 2),
        "nonfinite_samples": int((~finite).sum()),
        "attributes": {k: _jsonable(v) for k, v in attrs.items()
                       if k.startswith("gaslight:") or k in ("ExposureTime", "FNumber",
                                                           "Exif:ISOSpeedRatings")},
        "bytes": path.stat().st_size,
    }


def envmap_kind(attrs: dict[str, Any]) -> str | None:
    """``latlong`` or ``cube`` for an environment map, else None."""
    raw = attrs.get("envmap") or attrs.get("textureformat")
    if raw is None:
        return None
    return ENVMAP_NAMES.get(str(raw), str(raw))


def describe_ply(path: Path) -> dict[str, Any]:
    from .ply import read_ply

    scene = read_ply(path)
    lo, hi = scene.bounds()
    colours = scene.base_colours
    peak = colours.max(axis=1) if scene.count else np.zeros(0)
    return {
        "file": str(path),
        "type": "splats",
        "splats": scene.count,
        "sh_degree": scene.sh_degree,
        "has_normals": scene.normals is not None,
        "bounds_min": [float(v) for v in lo],
        "bounds_max": [float(v) for v in hi],
        "opacity_median": float(np.median(scene.opacities)) if scene.count else None,
        "scale_median": float(np.median(scene.scales)) if scene.count else None,
        "colour_max": float(peak.max()) if scene.count else None,
        "emitters_above_1": int((peak > 1.0).sum()),
        "length_unit": scene.metadata.get("length_unit") or (
            "metres" if (scene.metadata.get("frame") or {}).get("meters_per_unit") == 1.0
            else "unknown"),
        "lights": _lights(scene),
        "colour_dynamic_range_stops": round(dynamic_range_stops(peak), 2) if scene.count else 0,
        "metadata": {**scene.metadata, **_sightings_line(scene.metadata)},
        "bytes": path.stat().st_size,
    }


def _lights(scene) -> list[dict[str, Any]]:
    """The set's lights (gaslight_usd.lights), one line's worth each."""
    from .lights import find_lights

    return [_light_line(light.as_dict()) for light in find_lights(scene)]


def _sightings_line(metadata: dict[str, Any]) -> dict[str, Any]:
    """The photos' light regions in a line, not a row per region (they are for the
    lights finder; ``gaslight_usd.sightings.Sightings.from_metadata`` reads them)."""
    from .sightings import Sightings

    if "light_sightings" not in metadata:
        return {}
    seen = Sightings.from_metadata(metadata)
    if seen is None:
        return {"light_sightings": "unreadable (no camera centres, or malformed)"}
    return {"light_sightings": (
        f"{seen.count} light regions over white {seen.white:.4g} ({int(seen.whole.sum())} "
        f"framed whole) in {len(set(seen.view.tolist()))} of {len(seen.origins)} photos")}


def _light_line(light: dict[str, Any]) -> dict[str, Any]:
    keys = ("position", "radius", "power", "colour", "power_source", "power_uncertainty_stops")
    return {k: light[k] for k in keys if k in light}


def usd_error_line(exc: Exception) -> str:
    """The first line of what USD's error says after its C++ location prefix."""
    try:
        text = " ".join(str(exc).split())
    except UnicodeDecodeError:  # the message quotes the file's own (binary) bytes
        return "its text is not UTF-8"
    return text.split(" : ", 1)[-1][:200] if " : " in text else text[:200]


def describe_usd(path: Path) -> dict[str, Any]:
    from pxr import Tf, Usd, UsdGeom

    try:
        stage = Usd.Stage.Open(str(path))
    except Tf.ErrorException as exc:  # a damaged layer: USD's parser says where
        raise InputError(f"not a readable USD stage ({usd_error_line(exc)})", path) from None
    if stage is None:
        raise InputError("cannot open USD stage", path)
    kinds: Counter[str] = Counter()
    particles = []
    for prim in stage.TraverseAll():
        kinds[str(prim.GetTypeName()) or "(untyped)"] += 1
        if prim.GetTypeName() == "ParticleField3DGaussianSplat":
            attr = prim.GetAttribute("positions")
            value = attr.Get() if attr else None
            particles.append({"path": str(prim.GetPath()),
                              "splats": len(value) if value is not None else 0})
    root = stage.GetRootLayer()
    default = stage.GetDefaultPrim()
    variant_sets = {}
    if default:
        for name in default.GetVariantSets().GetNames():
            vs = default.GetVariantSet(name)
            variant_sets[name] = {"choices": vs.GetVariantNames(),
                                  "selected": vs.GetVariantSelection()}
    import json

    lights_text = root.customLayerData.get("gaslight:lights")
    try:
        lights = [_light_line(li) for li in json.loads(lights_text)] if lights_text else []
    except (ValueError, TypeError, KeyError):
        lights = []
    return {
        "file": str(path),
        "type": "usd",
        "lights": lights,
        "up_axis": str(UsdGeom.GetStageUpAxis(stage)),
        "meters_per_unit": float(UsdGeom.GetStageMetersPerUnit(stage)),
        "meters_per_unit_authored": stage.HasAuthoredMetadata("metersPerUnit"),
        "default_prim": str(default.GetPath()) if default else None,
        "colour_space": _stage_colour_space(stage),
        "prims": sum(kinds.values()),
        "prim_types": dict(sorted(kinds.items())),
        "particle_fields": particles,
        "variant_sets": variant_sets,
        "layers": [layer.identifier for layer in stage.GetUsedLayers()],
        "custom_layer_data": {k: _jsonable(v) for k, v in root.customLayerData.items()
                              if k != "gaslight:lights"},
        "bytes": path.stat().st_size,
    }


def _stage_colour_space(stage) -> str | None:
    default = stage.GetDefaultPrim()
    if not default:
        return None
    attr = default.GetAttribute("colorSpace:name")
    return str(attr.Get()) if attr and attr.HasAuthoredValue() else None


def _jsonable(value: Any) -> Any:
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    try:
        return [_jsonable(v) for v in value]
    except TypeError:
        return str(value)


def describe(path: str | Path) -> dict[str, Any]:
    path = Path(path)
    if not path.exists():
        raise InputError("no such file", path)
    if path.is_dir():
        raise InputError("is a folder; info takes an EXR, PLY or USD file", path)
    suffix = path.suffix.lower()
    if suffix == ".ply":
        return describe_ply(path)
    if suffix in USD_EXTENSIONS:
        return describe_usd(path)
    if suffix in IMAGE_INFO_EXTENSIONS:
        return describe_image(path)
    raise InputError("unknown file type; info reads EXR/HDR/JPEG/PNG/TIFF/.tx, PLY "
                     "and USD", path)


def format_facts(facts: dict[str, Any]) -> str:
    lines = []
    for key, value in facts.items():
        if key == "lights" and isinstance(value, list):
            lines.append(f"lights: {len(value)}")
            lines += ["  " + ", ".join(f"{k} {v}" for k, v in light.items()) for light in value]
        elif isinstance(value, dict):
            if not value:
                continue
            lines.append(f"{key}:")
            lines += [f"  {k}: {v}" for k, v in value.items()]
        elif isinstance(value, list) and value and isinstance(value[0], float):
            lines.append(f"{key}: " + ", ".join(f"{v:.6g}" for v in value))
        elif isinstance(value, float):
            lines.append(f"{key}: {value:.6g}")
        else:
            lines.append(f"{key}: {value}")
    return "\n".join(lines)
