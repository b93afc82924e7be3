"""The exported scene: one root layer, one choice of lighting.

``scene.usda`` holds the default prim ``/Scene`` with a variant set
``lighting`` whose variants reference ``.usdc`` layers written beside it:

=============  ====================================  ===============================
variant        prim under /Scene                     layer(s)
=============  ====================================  ===============================
particlefield  ``Splats`` (Xform, ``Part_000``...)    ``<stem>.particlefield[.NNN].usdc``
instancer      ``Emitters`` (Xform + PointInstancer)  ``<stem>.instancer.usdc``
rig            ``Rig`` (DomeLight + UsdLux lights)   ``<stem>.rig.usdc`` + dome EXR
=============  ====================================  ===============================

Each layer opens on its own too (units, up axis, colour space, provenance on
its default prim). Files are written into a hidden temporary folder and moved
into place with the root layer last, so a failed run leaves no root layer.
"""

from __future__ import annotations

import os
import secrets
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pxr import Usd, UsdGeom

from .. import colour
from ..errors import InputError
from ..export_options import DOME_WIDTH, PALETTE_TOLERANCE, RIG_TOLERANCE
from ..progress import Progress
from ..splats import SplatScene
from .particlefield import MAX_LAYER_BYTES, bytes_per_splat, chunk_ranges, write_particle_field
from .stage import Provenance, StageFrame, new_stage, tag_layer_root
from .validate import Finding, validate

VARIANTS = ("particlefield", "instancer", "rig")
VARIANT_SET = "lighting"
ROOT_PRIM = "Scene"
_CHILD = {"particlefield": "Splats", "instancer": "Emitters", "rig": "Rig"}


@dataclass
class ExportOptions:
    variants: tuple[str, ...] = VARIANTS
    half: bool = False
    emit_threshold: float | None = None
    """None: emitters are the lights finder's; a number: radiance above it (GaSLight)."""
    palette_tolerance: float = PALETTE_TOLERANCE
    non_emitters: str = "drop"
    rig_tolerance: float = RIG_TOLERANCE
    probe: tuple[float, float, float] | None = None
    dome_width: int = DOME_WIDTH
    max_layer_bytes: int = MAX_LAYER_BYTES
    working_space: str = colour.DEFAULT_WORKING_SPACE
    ocio_config: str | None = None
    seed: int = 0
    default_variant: str | None = None
    """The ``lighting`` variant selected in the root layer; None: :data:`DEFAULT_VARIANT`
    when written, else the first written."""


DEFAULT_VARIANT = "rig"
"""The variant a consumer sees unless it picks one: lights every renderer imports
(Blender, usdview, Karma read UsdLux), where Blender does not import ParticleFields."""


@dataclass
class ExportReport:
    root: Path
    files: list[Path] = field(default_factory=list)
    metrics: dict[str, Any] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)
    findings: list[Finding] = field(default_factory=list)

    @property
    def errors(self) -> list[Finding]:
        return [f for f in self.findings if f.severity == "error"]


def _layer_names(stem: str, variant: str, parts: int) -> list[str]:
    if variant == "particlefield" and parts > 1:
        return [f"{stem}.{variant}.{i:03d}.usdc" for i in range(parts)]
    return [f"{stem}.{variant}.usdc"]


def _write_particlefield(folder: Path, stem: str, scene: SplatScene, frame: StageFrame,
                         prov: Provenance, opts: ExportOptions, search=None
                         ) -> tuple[list[str], dict]:
    ranges = chunk_ranges(scene.count, bytes_per_splat(scene.sh.shape[1], opts.half),
                          opts.max_layer_bytes)
    names = _layer_names(stem, "particlefield", len(ranges))
    for name, (start, stop) in zip(names, ranges, strict=True):
        stage = Usd.Stage.CreateNew(str(folder / name))
        part = scene if (start, stop) == (0, scene.count) else scene.subset(np.arange(start, stop))
        _stage_frame(stage, frame)
        field_ = write_particle_field(stage, "/Splats", part, half=opts.half)
        stage.SetDefaultPrim(field_.GetPrim())
        tag_layer_root(field_.GetPrim(), prov, opts.ocio_config)
        stage.GetRootLayer().Save()
    return names, {"splats": scene.count, "layers": len(names), "half": opts.half}


def _stage_frame(stage: Usd.Stage, frame: StageFrame) -> None:
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if frame.up_axis == "Y" else UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, frame.meters_per_unit)


def _write_instancer(folder: Path, stem: str, scene: SplatScene, frame: StageFrame,
                     prov: Provenance, opts: ExportOptions, search=None
                     ) -> tuple[list[str], dict]:
    name = _layer_names(stem, "instancer", 1)[0]
    stage, root = new_stage(folder / name, frame, "Emitters", "Xform")
    tag_layer_root(root, prov, opts.ocio_config)
    from . import instancer as inst  # UsdShade: only when an instancer is written

    mask = None if opts.emit_threshold is not None or search is None else search.emitters
    if mask is not None and search.positions is not None and mask.any():
        # the emitters where the evidence puts them (on the surface they are seen
        # through, where their outlines meet), not sunk where the fit left them
        pos = scene.positions.copy()
        pos[mask] = search.positions[mask]
        scene = SplatScene(pos, scene.rotations, scene.log_scales, scene.opacity_logits,
                           scene.sh, normals=scene.normals, metadata=scene.metadata)
    report = inst.write_instancer(stage, root.GetPath(), scene, opts.emit_threshold,
                                  opts.palette_tolerance, opts.non_emitters, seed=opts.seed,
                                  mask=mask)
    stage.GetRootLayer().Save()
    rule = ("lights finder (gaslight_usd.lights)" if mask is not None
            else f"max channel of base colour > {opts.emit_threshold or 1.0}")
    metrics = {"emitters": report.emitters, "diffuse": report.diffuse,
               "dropped": report.dropped, "threshold": opts.emit_threshold, "rule": rule,
               "palette_tolerance_p95_relative": opts.palette_tolerance, **report.palette}
    p95 = report.palette.get("relative_error_p95")
    metrics["palette_tolerance_met"] = p95 is None or p95 <= opts.palette_tolerance
    if not metrics["palette_tolerance_met"]:
        metrics["warning"] = (f"instancer palette misses its tolerance: p95 colour error "
                              f"{p95:.3f} > {opts.palette_tolerance} with "
                              f"{report.palette.get('palette_size')} colours (at most "
                              f"{inst.MAX_PALETTE})")
    if report.diffuse_palette:
        metrics["diffuse_palette"] = report.diffuse_palette
    return [name], metrics


def _write_rig(folder: Path, stem: str, scene: SplatScene, frame: StageFrame,
               prov: Provenance, opts: ExportOptions, search=None
               ) -> tuple[list[str], dict]:
    from .rig import write_rig  # needs the splat renderer

    name = _layer_names(stem, "rig", 1)[0]
    stage, root = new_stage(folder / name, frame, "Rig", "Xform")
    tag_layer_root(root, prov, opts.ocio_config)
    result = write_rig(stage, root.GetPath(), scene, folder, f"{stem}.dome.exr",
                       probe=opts.probe, width=opts.dome_width,
                       tolerance=opts.rig_tolerance, threshold=opts.emit_threshold,
                       working_space=opts.working_space, ocio_config=opts.ocio_config,
                       seed=opts.seed, search=search)
    stage.GetRootLayer().Save()
    return [name, *result.pop("files")], result


WRITERS = {"particlefield": _write_particlefield, "instancer": _write_instancer,
           "rig": _write_rig}


def default_variant(written: list[str], wanted: str | None = None) -> str:
    """The variant the root layer selects: ``wanted``, else DEFAULT_VARIANT, else the first."""
    if wanted is not None:
        if wanted not in written:
            raise InputError(f"--default-variant {wanted!r} is not among the forms written "
                             f"({', '.join(written)})")
        return wanted
    return DEFAULT_VARIANT if DEFAULT_VARIANT in written else written[0]


def _write_root(path: Path, stem: str, layers: dict[str, list[str]], frame: StageFrame,
                prov: Provenance, opts: ExportOptions, lights: list | None = None) -> None:
    stage, root = new_stage(path, frame, ROOT_PRIM, "Xform", kind="assembly")
    if lights is not None:
        import json

        data = dict(stage.GetRootLayer().customLayerData)
        data["gaslight:lights"] = json.dumps(lights)
        stage.GetRootLayer().customLayerData = data
    tag_layer_root(root, prov, opts.ocio_config)
    vset = root.GetVariantSets().AddVariantSet(VARIANT_SET)
    for variant, names in layers.items():
        vset.AddVariant(variant)
        vset.SetVariantSelection(variant)
        with vset.GetVariantEditContext():
            child = root.GetPath().AppendChild(_CHILD[variant])
            usd_files = [n for n in names if n.endswith(".usdc")]
            if len(usd_files) == 1:
                # typeless: the referenced default prim brings its own type
                stage.DefinePrim(child).GetReferences().AddReference(f"./{usd_files[0]}")
            else:
                UsdGeom.Xform.Define(stage, child)
                for i, n in enumerate(usd_files):
                    part = stage.DefinePrim(child.AppendChild(f"Part_{i:03d}"))
                    part.GetReferences().AddReference(f"./{n}")
    vset.SetVariantSelection(default_variant(list(layers), opts.default_variant))
    stage.GetRootLayer().Save()


def export_usd(scene: SplatScene, out_path: str | Path, opts: ExportOptions | None = None,
               source: str = "", validate_output: bool = True,
               progress: Progress | None = None) -> ExportReport:
    """Write ``out_path`` (``.usda``/``.usd``) and its layers; return what was done.

    ``progress`` hears of each form as it starts and ends (the rig, which renders
    a dome and fits lights, takes the longest).
    """
    progress = progress or Progress(quiet=True)
    opts = opts or ExportOptions()
    out_path = Path(out_path)
    if out_path.suffix.lower() not in (".usda", ".usd", ".usdc"):
        raise InputError("the root layer must be .usda, .usd or .usdc (use --usdz for a "
                         "package)", out_path)
    unknown = [v for v in opts.variants if v not in VARIANTS]
    if unknown or not opts.variants:
        raise InputError(f"unknown export form(s) {unknown}; choose from {', '.join(VARIANTS)}")
    frame = StageFrame.from_metadata(scene.metadata)
    prov = Provenance.from_metadata(scene.metadata, source=source,
                                    working_space=colour.resolve_space(
                                        opts.working_space, opts.ocio_config),
                                    ocio_config=opts.ocio_config)
    prov.notes = "; ".join(frame.assumed)
    stem = out_path.name[: -len(out_path.suffix)]
    folder = out_path.parent
    folder.mkdir(parents=True, exist_ok=True)
    scratch = folder / f".{stem}.partial-{secrets.token_hex(4)}"
    scratch.mkdir()
    report = ExportReport(root=out_path)
    search = None
    try:
        if opts.emit_threshold is None and {"instancer", "rig"} & set(opts.variants):
            from ..lights import search_lights

            t0 = time.perf_counter()
            search = search_lights(scene)
            report.seconds["lights"] = round(time.perf_counter() - t0, 4)
            report.metrics["lights"] = search.summary()
        layers: dict[str, list[str]] = {}
        for variant in VARIANTS:
            if variant not in opts.variants:
                continue
            t0 = time.perf_counter()
            progress.message(f"writing the {variant} layer(s)")
            names, metrics = WRITERS[variant](scratch, stem, scene, frame, prov, opts, search)
            report.seconds[variant] = round(time.perf_counter() - t0, 4)
            progress.message(f"{variant} written in {report.seconds[variant]:.1f} s")
            layers[variant] = names
            report.metrics[variant] = metrics
        _write_root(scratch / out_path.name, stem, layers, frame, prov, opts,
                    None if search is None else [li.as_dict() for li in search.lights])
        moved = [n for names in layers.values() for n in names] + [out_path.name]
        for name in moved:  # root layer last
            os.replace(scratch / name, folder / name)
            report.files.append(folder / name)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    report.metrics["stage"] = {"upAxis": frame.up_axis, "metersPerUnit": frame.meters_per_unit,
                               "assumed": frame.assumed,
                               "colourSpace": prov.working_space}
    if validate_output:
        for path in report.files:
            if path.suffix in (".usda", ".usdc", ".usd"):
                report.findings += validate(path)
    return report


def open_variant(root: str | Path, variant: str) -> Usd.Stage:
    """Open ``root`` with the ``lighting`` variant set to ``variant``."""
    stage = Usd.Stage.Open(str(root))
    stage.GetDefaultPrim().GetVariantSet(VARIANT_SET).SetVariantSelection(variant)
    return stage
