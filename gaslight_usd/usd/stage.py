"""Shared stage set-up: units, up axis, colour space and provenance.

Every layer this project writes can be opened on its own, so each one carries
``upAxis``, ``metersPerUnit`` (always authored: Blender reads an unset value as
centimetres), the colour space of its radiance through ``Usd.ColorSpaceAPI``
on the default prim, and the project's ``GaslightProvenanceAPI`` (a codeless
schema in ``schemas/gaslight``, registered at run time).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pxr import Plug, Sdf, Usd, UsdGeom

from .. import colour
from ..errors import InputError
from ..provenance import versions
from ..schemas import PLUGIN_DIR, PROVENANCE_API

DEFAULT_METERS_PER_UNIT = 1.0
"""Used when the splats do not say: the SfM frame is metres when a scale is known."""
DEFAULT_UP_AXIS = "Y"
"""Used when the splats do not say: the project's SfM frame is +Y up."""

# The provenance schema's attributes (name -> value type), mirrored from
# schemas/gaslight/generatedSchema.usda for the fallback in apply_provenance.
PROVENANCE_ATTRIBUTES = {
    "gaslight:sourceImages": Sdf.ValueTypeNames.StringArray,
    "gaslight:method": Sdf.ValueTypeNames.String,
    "gaslight:exposureScale": Sdf.ValueTypeNames.Float,
    "gaslight:versions": Sdf.ValueTypeNames.String,
    "gaslight:workingSpace": Sdf.ValueTypeNames.String,
    "gaslight:ocioConfig": Sdf.ValueTypeNames.String,
    "gaslight:source": Sdf.ValueTypeNames.String,
    "gaslight:notes": Sdf.ValueTypeNames.String,
}


def register_schemas() -> bool:
    """Register the codeless schema; True when USD's schema registry knows it.

    USD builds its schema registry once; if something built it before this ran,
    the API is still authored (see :func:`apply_provenance`) but not introspectable.
    """
    Plug.Registry().RegisterPlugins(str(PLUGIN_DIR))
    return Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(PROVENANCE_API) is not None


@dataclass
class StageFrame:
    """Units and up axis of the splats' world frame, and whether they were known."""

    up_axis: str = DEFAULT_UP_AXIS
    meters_per_unit: float = DEFAULT_METERS_PER_UNIT
    assumed: list[str] = field(default_factory=list)
    units: str = "metres"
    """The length unit in words (what to do when unknown), for customLayerData."""

    @classmethod
    def from_metadata(cls, metadata: Mapping[str, Any]) -> StageFrame:
        assumed = []
        # Keys at the top level, or inside the poses' frame record (frame.json).
        frame = metadata.get("frame")
        frame = frame if isinstance(frame, Mapping) else {}
        up = str(metadata.get("up_axis") or frame.get("up_axis") or "").upper().lstrip("+")
        if up not in ("Y", "Z"):
            up = DEFAULT_UP_AXIS
            assumed.append(f"up axis unknown, assumed {DEFAULT_UP_AXIS}")
        mpu = metadata.get("meters_per_unit") or frame.get("meters_per_unit")
        try:
            mpu = float(mpu)
            if not mpu > 0:
                raise ValueError
        except (TypeError, ValueError):
            mpu = DEFAULT_METERS_PER_UNIT
            assumed.append(f"units unknown, metersPerUnit assumed {DEFAULT_METERS_PER_UNIT}")
            units = str(metadata.get("length_unit") or frame.get("units") or "unknown")
            if not units.startswith("unknown") and "unknown" not in units:
                units = f"unknown ({units})"
        else:
            units = "metres" if mpu == 1.0 else f"{mpu} metres"
        return cls(up, mpu, assumed, units)


@dataclass
class Provenance:
    """What :func:`apply_provenance` writes (see the schema's docs)."""

    source_images: Sequence[str] = ()
    method: str = ""
    exposure_scale: float = 1.0
    working_space: str = colour.DEFAULT_WORKING_SPACE
    ocio_config: str = colour.BUILTIN_CONFIG
    source: str = ""
    notes: str = ""

    @classmethod
    def from_metadata(cls, metadata: Mapping[str, Any], source: str = "",
                      working_space: str | None = None,
                      ocio_config: str | None = None) -> Provenance:
        prov = metadata.get("provenance") or {}
        images = metadata.get("source_images") or (
            (prov.get("source_images") or prov.get("views"))
            if isinstance(prov, Mapping) else None) or []
        method = metadata.get("method") or (
            prov.get("method") if isinstance(prov, Mapping) else "") or ""
        try:
            exposure = float(metadata.get("exposure_scale", 1.0))
        except (TypeError, ValueError):
            exposure = 1.0
        return cls(
            source_images=[str(p) for p in images],
            method=str(method),
            exposure_scale=exposure,
            working_space=working_space or str(metadata.get("colour_space")
                                               or colour.DEFAULT_WORKING_SPACE),
            ocio_config=ocio_config or colour.resolve_config_uri(None),
            source=source,
        )


def colour_space_token(space: str, config_uri: str | None = None) -> str:
    """The USD ColorSpaceAPI token of an OCIO scene-linear space (``lin_ap1_scene``...)."""
    info = colour.space_info(space, config_uri)
    token = info.usd_token
    if not token:
        raise InputError(f"colour space {info.name!r} has no USD colour-space token; "
                         "USD radiance must be scene-linear (e.g. ACEScg, Linear Rec.709)")
    return token


def new_stage(path: str | Path, frame: StageFrame, default_prim: str,
              prim_type: str = "Xform", kind: str | None = None) -> tuple[Usd.Stage, Usd.Prim]:
    """A new stage at ``path`` with units, up axis and one typed default prim."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if frame.up_axis == "Y" else UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, frame.meters_per_unit)
    data = {"gaslight:upAxisKnown": "up axis unknown" not in " ".join(frame.assumed),
            "gaslight:unitsKnown": "units unknown" not in " ".join(frame.assumed),
            "gaslight:units": frame.units}
    if frame.assumed:
        data["gaslight:assumed"] = "; ".join(frame.assumed)
    stage.GetRootLayer().customLayerData = data
    prim = stage.DefinePrim(Sdf.Path(f"/{default_prim}"), prim_type)
    stage.SetDefaultPrim(prim)
    if kind:
        Usd.ModelAPI(prim).SetKind(kind)
    return stage, prim


def apply_colour_space(prim: Usd.Prim, space: str, config_uri: str | None = None) -> str:
    """State the radiance colour space on ``prim`` (inherited by its descendants)."""
    token = colour_space_token(space, config_uri)
    Usd.ColorSpaceAPI.Apply(prim).CreateColorSpaceNameAttr(token)
    return token


def apply_provenance(prim: Usd.Prim, prov: Provenance) -> None:
    """Apply ``GaslightProvenanceAPI`` and author its attributes."""
    if not (register_schemas() and prim.ApplyAPI(PROVENANCE_API)):
        prim.AddAppliedSchema(PROVENANCE_API)  # same scene description, written by hand
    values = {
        "gaslight:sourceImages": list(prov.source_images),
        "gaslight:method": prov.method,
        "gaslight:exposureScale": float(prov.exposure_scale),
        "gaslight:versions": json.dumps(versions(), sort_keys=True),
        "gaslight:workingSpace": prov.working_space,
        "gaslight:ocioConfig": prov.ocio_config,
        "gaslight:source": prov.source,
        "gaslight:notes": prov.notes,
    }
    for name, value in values.items():
        prim.CreateAttribute(name, PROVENANCE_ATTRIBUTES[name]).Set(value)


def tag_layer_root(prim: Usd.Prim, prov: Provenance, config_uri: str | None = None) -> None:
    """Colour space plus provenance on a layer's default prim."""
    apply_colour_space(prim, prov.working_space, config_uri)
    apply_provenance(prim, prov)
