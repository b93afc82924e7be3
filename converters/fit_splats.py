"""HDR views + poses -> HDR Gaussian splats (PLY), fitted on the CPU or a CUDA GPU.

Options (step "fit"): :class:`FitOptions`.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from gaslight_usd.errors import InputError
from gaslight_usd.fit import PRESETS, fit_splats, load_fit_data, preset
from gaslight_usd.fit.presets import PLANE_PRIOR_MODES
from gaslight_usd.kinds import Kind
from gaslight_usd.ply import write_ply
from gaslight_usd.provenance import tool_version
from gaslight_usd.registry import Converter, StageContext, StageResult, options_from


@dataclasses.dataclass
class FitOptions:
    """The ``fit.splats`` options; None means the preset's or the run's value."""

    preset: str = "fast"
    """fast | balanced | best (:data:`gaslight_usd.fit.PRESETS`)."""
    budget: int | None = None
    """Most splats."""
    iterations: int | None = None
    seed: int | None = None
    """Default: the run's."""
    device: str | None = None
    """Default: the run's."""
    resume: bool | None = None
    """Continue from the checkpoint beside the output; default: whether the run
    resumes, so ``run`` and ``batch`` pick up a killed fit where its checkpoint left
    it (``run --fresh`` starts over)."""
    checkpoint: str | None = None
    """The checkpoint's path (default :func:`checkpoint_path`)."""
    keep_checkpoint: bool = False
    refine_poses: bool = False
    """Optimise the training views' poses too; the refined poses are written beside
    the output as a COLMAP text model (:func:`refined_poses_path`)."""
    uplift_power: bool = False
    """Leave clipped lights at the uplift's power (do not weigh them by the surfaces they
    light, :mod:`gaslight_usd.fit.power`)."""
    planes: str | None = None
    """``auto``, ``on`` or ``off``: keep the splats to the walls' planes
    (``FitConfig.plane_prior``; default: the preset's)."""
    working_size: int | None = None
    """The views' long side in the fit (default: the preset's; the bench's shortened fits)."""
    tolerance_stops: float | None = None
    """Keep the smallest cut-down model whose held-out error is within this many stops
    of the full fit's (:mod:`gaslight_usd.fit.smallest`); what it chose is in the
    report's metadata."""


HELD_OUT_WARN_STOPS = 2.0
"""Held-out log-luminance RMSE (stops) above which the fit says the photos do not cover the
set: a fit whose photos overlap scores well under 1 on the views it never saw, while the
stability sweep's 8-photo capture at ``balanced`` missed its held-out view by over 4 stops
and lost a stop of light with no other warning (``gaslight2usd bench --suite stability
--preset balanced --perturb photos``)."""


def checkpoint_path(output: Path) -> Path:
    """Where the fit of ``output`` keeps its checkpoint (a hidden sibling)."""
    return output.with_name(f".{output.name}.fit-checkpoint.pt")


def refined_poses_path(output: Path) -> Path:
    """Where a fit with pose refinement writes the refined poses (a COLMAP text model)."""
    return output.with_name(f"{output.stem}.refined-poses")


def _refined_model(data, cameras):
    """The user's model with the fit's refined extrinsics (intrinsics and points kept)."""
    by_stem = {name: cam for name, cam in zip(data.names, cameras, strict=True)}
    moved = []
    for cam in data.model.cameras:
        new = by_stem.get(Path(cam.name).stem)
        moved.append(cam if new is None else dataclasses.replace(cam, R=new.R, t=new.t))
    return dataclasses.replace(data.model, cameras=moved)


def length_unit(frame: dict) -> str:
    """The PLY's length unit in words: metres, or unknown with how to give one."""
    mpu = frame.get("meters_per_unit") if isinstance(frame, dict) else None
    if mpu:
        return "metres" if float(mpu) == 1.0 else f"{float(mpu)} metres"
    if isinstance(frame, dict) and frame.get("frame_source") == "sfm":
        return ("unknown (SfM scale): give --camera-height, --scale or --scale-from to "
                "`poses`/`run` for metres")
    return "unknown (the given poses' own unit)"


def fit(ctx: StageContext) -> StageResult:
    opts = options_from(FitOptions, ctx.options)
    name = opts.preset
    if name not in PRESETS:
        raise InputError(f"unknown fit preset {name!r}; choose from {', '.join(PRESETS)}")
    if opts.planes is not None and opts.planes not in PLANE_PRIOR_MODES:
        raise InputError(f"unknown planes mode {opts.planes!r}; choose from "
                         f"{', '.join(PLANE_PRIOR_MODES)}")
    cfg = preset(name).updated(budget=opts.budget, iterations=opts.iterations,
                               working_size=opts.working_size,
                               refine_poses=bool(opts.refine_poses),
                               infer_power=False if opts.uplift_power else None,
                               plane_prior=opts.planes)
    seed = int(opts.seed if opts.seed is not None else ctx.settings.seed)
    hdr_dir, poses = ctx.input(Kind.HDR_VIEWS).path, ctx.input(Kind.POSES).path
    data = load_fit_data(hdr_dir, poses, working_size=cfg.working_size)
    if data.left_out:
        ctx.progress.message(f"warning: {len(data.left_out)} HDR view(s) have no pose and are "
                             f"left out of the fit: {', '.join(data.left_out)}")
    ckpt = Path(opts.checkpoint or checkpoint_path(ctx.output))
    result = fit_splats(data, cfg, seed=seed, progress=ctx.progress, checkpoint=ckpt,
                        resume=bool(ctx.resume if opts.resume is None else opts.resume),
                        device=opts.device or ctx.settings.device)
    attrs = data.attributes
    metadata = {
        # what the fit put on its splats: how to draw them (``antialiased``; drawn the
        # other way, the HDRIs miss the light the fit saw: docs/measurements.md, session
        # 36), where the photos saw light over the white and the lights their outlines
        # placed (gaslight_usd.sightings, gaslight_usd.fit.light_seeds: the lights finder's)
        **result.scene.metadata,
        "colour_space": data.colour_space,
        "exposure_scale": float(attrs.get("gaslight:exposure_scale", 1.0)),
        "reference_ev": attrs.get("gaslight:reference_ev"),
        "units": "relative radiance (linear HDR, as the HDR views)",
        "frame": data.model.frame,
        "length_unit": length_unit(data.model.frame),
        # where the photos were taken: the default probe and the captured space start there
        "cameras": {"centres": [[round(float(v), 6) for v in c.center] for c in data.cameras]},
        "provenance": {
            "tool": f"gaslight2usd {tool_version()}",
            "method": "fit.splats (3DGS-style fit on linear HDR views)",
            "hdr_views": str(hdr_dir), "poses": str(poses), "views": data.names,
            "hdr_method": attrs.get("gaslight:method"),
            "left_out_views": data.left_out,
            "preset": name, "seed": seed, "config": cfg.as_dict(),
        },
        "fit_metrics": result.metrics,
    }
    if not result.metrics["held_out_views"]:
        ctx.progress.message(
            f"warning: only {len(data.names)} views, none held out: the fit could not tell "
            "when more splats stopped helping, and its errors (and --tolerance-stops) are "
            "measured on the views it was fitted to; shoot more photos")
    held_err = result.metrics.get("held_out_log_lum_rmse_stops")
    if result.metrics["held_out_views"] and held_err is not None and \
            held_err > HELD_OUT_WARN_STOPS:
        ctx.progress.message(
            f"warning: the fit misses the view(s) it never trained on "
            f"({', '.join(result.metrics['held_out_views'])}) by {held_err:.1f} stops "
            f"(log-luminance RMSE; over {HELD_OUT_WARN_STOPS:g} means the photos do not cover "
            "the set): what lies between the photos, lights included, is a guess; shoot more "
            "photos, each overlapping its neighbours")
    for light in result.metrics.get("single_view_lights") or []:
        where = ", ".join(f"{v:.2f}" for v in light["position"])
        framed = (f"is framed by {light['view']} alone" if light["view"]
                  else "lies where no photo looks")
        ctx.progress.message(
            f"warning: a light ({light['power_share']:.0%} of the bright splats' power, near "
            f"{where}) {framed}: its place and size are guesses (a light needs two photos "
            "from different places to be put in depth)")
    for light in result.metrics.get("clipped_lights") or []:
        where = ", ".join(f"{v:.2f}" for v in light["position"])
        if light["power_source"] in ("inferred", "fused"):
            ctx.progress.message(
                f"a clipped light at ({where}) weighed by the surfaces it lights: "
                f"{math.log2(light['factor']):+.1f} stops over the uplift's guess "
                f"(+-{light['power_uncertainty_stops']:.1f} stops"
                + (", a lower bound" if light.get("lower_bound") else "") + ")")
        elif light["power_source"] == "predicted":
            ctx.progress.message(
                f"warning: a clipped light at ({where}) keeps the uplift's guess of its power "
                f"({light.get('note', 'not weighed')}); one photo exposed for it measures it")
    for light in result.metrics.get("cut_lights") or []:
        ctx.progress.message(f"warning: {light['warning']}")
    agreement = result.metrics.get("pose_agreement") or {}
    if agreement.get("warning"):
        ctx.progress.message(f"warning: {agreement['warning']}")
    outliers = result.metrics.get("exposure_outliers") or []
    if outliers:
        listed = ", ".join(f"{o['view']} ({o['stops']:+.1f} stops)" for o in outliers)
        ctx.progress.message(
            f"warning: {len(outliers)} photo(s) read brighter or darker than the others see "
            f"the same set: {listed}; their EXIF exposure is likely wrong (exposure "
            "compensation or an ND filter the EXIF does not record): fix the tags or leave "
            "them out")
    result.scene.metadata = metadata
    m = result.metrics
    ctx.progress.message(f"kept {m['splats']} splats: {m['pruned_idle']} idle ones pruned, "
                         f"{m['backdrop_splats']} backdrop splats added after the last step")
    choice = None
    if opts.tolerance_stops is not None:
        from gaslight_usd.fit.smallest import choose_for_fit

        choice, smaller = choose_for_fit(data, result, float(opts.tolerance_stops),
                                         cfg.background)
        result.scene = smaller
        smaller.metadata = metadata
        metadata["model_choice"] = {k: v for k, v in choice.as_dict().items()
                                    if k != "candidates"}
        ctx.progress.message(("" if choice.held_out else "warning: ") + choice.sentence())
    write_ply(ctx.output, result.scene)
    extra = {}
    if cfg.refine_poses:
        from gaslight_usd.poses import write_poses

        refined = write_poses(refined_poses_path(ctx.output),
                              _refined_model(data, result.cameras))
        extra = {"refined_poses": str(refined), **result.metrics["pose_refinement"]}
    if not opts.keep_checkpoint:
        ckpt.unlink(missing_ok=True)
    m = result.metrics
    return StageResult(
        metadata={"colour_space": data.colour_space, "preset": name,
                  "exposure_scale": metadata["exposure_scale"], "frame": data.model.frame,
                  "history": result.history, "left_out_views": data.left_out, **extra,
                  **({"model_choice": choice.as_dict()} if choice else {})},
        counts={"splats": result.scene.count, "views": len(data.names),
                "held_out_views": len(m["held_out_views"]), "iterations": m["iterations"]},
        metrics={k: m[k] for k in ("held_out_log_lum_rmse_stops", "held_out_pu21_psnr",
                                   "sh_degree", "fit_seconds", "init_seconds", "pruned_idle",
                                   "backdrop_splats", "exposure_outliers",
                                   "single_view_lights", "pose_agreement", "cut_lights",
                                   "clipped_lights", "fine_power", "placed_by_frames",
                                   "room_box", "lit_floor", "holes_filled",
                                   "fog_dropped", "squashed_onto_planes",
                                   "shaded_sides_closed", "camera_floaters_dropped")},
    )


CONVERTERS = [
    Converter(
        name="fit.splats",
        step="fit",
        inputs=(Kind.HDR_VIEWS, Kind.POSES),
        output=Kind.SPLATS,
        run=fit,
        description="fit HDR Gaussian splats to the posed HDR views (linear HDR, CPU or CUDA)",
        options=FitOptions,
    ),
]
