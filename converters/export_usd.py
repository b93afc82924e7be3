"""Splats -> OpenUSD: ParticleField splats, emissive instancer, UsdLux rig.

Options: :class:`~gaslight_usd.export_options.UsdExportOptions`.
"""

from __future__ import annotations

import os
from pathlib import Path

from gaslight_usd.errors import GaslightError
from gaslight_usd.export_options import UsdExportOptions
from gaslight_usd.kinds import Kind
from gaslight_usd.ply import read_ply
from gaslight_usd.registry import Converter, StageContext, StageResult, options_from


def relative_source(source: Path, folder: Path) -> str:
    """``source`` as a path relative to ``folder`` (where the USD layers are written).

    A relative path survives moving the output folder together with its inputs,
    and says nothing of the machine's own folder layout; an absolute path is kept
    only where no relative one exists.
    """
    try:
        return os.path.relpath(Path(source).resolve(), Path(folder).resolve())
    except ValueError:  # another drive
        return str(Path(source).resolve())


def export_usd_stage(ctx: StageContext) -> StageResult:
    from gaslight_usd.usd.scene import VARIANTS, ExportOptions, export_usd

    o = options_from(UsdExportOptions, ctx.options)
    src = ctx.input(Kind.SPLATS).path
    scene = read_ply(src)
    out = Path(ctx.output)
    if out.suffix.lower() not in (".usda", ".usd", ".usdc"):
        out = out / Kind.USD.default_name
    opts = ExportOptions(
        variants=tuple(o.forms or VARIANTS),
        half=bool(o.half),
        emit_threshold=None if o.emit_threshold is None else float(o.emit_threshold),
        palette_tolerance=float(o.palette_tolerance),
        non_emitters=str(o.non_emitters),
        rig_tolerance=float(o.rig_tolerance),
        probe=None if o.at is None else tuple(float(v) for v in o.at),
        dome_width=int(o.dome_width),
        max_layer_bytes=int(o.max_layer_bytes or ExportOptions.max_layer_bytes),
        working_space=ctx.settings.working_space,
        ocio_config=ctx.settings.ocio_config,
        seed=ctx.settings.seed,
        default_variant=o.default_variant,
    )
    ctx.progress.message(f"exporting {scene.count} splats as {', '.join(opts.variants)}")
    report = export_usd(scene, out, opts, source=relative_source(src, out.parent),
                        progress=ctx.progress)
    files = [str(p) for p in report.files]
    metrics = dict(report.metrics)
    for light in metrics.get("lights", {}).get("lights", []):
        ctx.progress.message(
            "light at " + ", ".join(f"{v:.3g}" for v in light["position"])
            + f": radius {light['radius']:.3g}, power {max(light['power']):.3g} "
            f"({light['power_source']}, +-{light['power_uncertainty_stops']} stops)")
    warning = metrics.get("instancer", {}).get("warning")
    if warning:
        ctx.progress.message(f"warning: {warning}")
    if report.errors:
        raise GaslightError("USD validation failed: " + "; ".join(map(str, report.errors[:3])),
                            out)
    if o.usdz:
        from gaslight_usd.usd.usdz import package_usdz, validate_usdz

        usdz = package_usdz(out, out.with_suffix(".usdz"))
        findings = validate_usdz(usdz)
        bad = [f for f in findings if f.severity == "error"]
        if bad:
            raise GaslightError("USDZ validation failed: " + "; ".join(map(str, bad[:3])), usdz)
        files.append(str(usdz))
        metrics["usdz"] = {"path": str(usdz), "bytes": usdz.stat().st_size,
                           "validation_errors": 0}
    if o.display_ply:
        from gaslight_usd.ply_display import write_display_ply

        ev = write_display_ply(o.display_ply, scene, o.display_exposure,
                               ctx.settings.working_space, ctx.settings.ocio_config)
        files.append(str(o.display_ply))
        metrics["display_ply"] = {"path": str(o.display_ply), "exposure_ev": ev}
    metrics["validation"] = {"errors": 0, "warnings": len(report.findings)}
    return StageResult(
        metadata={"root": str(out), "files": files, "colour_space": ctx.settings.working_space},
        counts={"splats": scene.count, "files": len(files)},
        metrics={**metrics, "seconds": report.seconds},
    )


CONVERTERS = [
    Converter(
        name="export.usd",
        step="export",
        inputs=(Kind.SPLATS,),
        output=Kind.USD,
        run=export_usd_stage,
        description="write OpenUSD: ParticleField splats, emissive instancer, UsdLux rig",
        options=UsdExportOptions,
    ),
]
