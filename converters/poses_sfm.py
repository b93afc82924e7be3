"""LDR photos -> camera poses and sparse points by structure from motion (pycolmap).

Options: :class:`PosesOptions`, the SfM's own
(:class:`~gaslight_usd.poses.sfm.SfmOptions`: ``matcher``, ``camera_model``,
``single_camera``, ``min_registered``, ``panorama``, ``max_image_size``, ``verbose``...)
plus the frame's scale (``scale``, ``scale_from`` or ``camera_height``) and
``binary``.
The model is moved to the project's SfM frame (+Y up, the floor at y = 0, origin
under the cameras; see gaslight_usd.poses.frame) and written with its ``frame.json``.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from gaslight_usd.kinds import Kind
from gaslight_usd.poses.colmap import write_model
from gaslight_usd.poses.frame import sfm_frame
from gaslight_usd.poses.sfm import SfmOptions, solve_poses
from gaslight_usd.registry import Converter, StageContext, StageResult, options_from


@dataclass
class PosesOptions(SfmOptions):
    """The ``poses.sfm`` options: the SfM's, and how the model is scaled and written."""

    scale: float | None = None
    """Metres per SfM unit."""
    scale_from: str | None = None
    """``IMG_A,IMG_B,METRES``: a known distance between two photos' camera centres."""
    camera_height: float | None = None
    """The photos' median height above the floor, metres."""
    binary: bool = False
    """Write .bin files instead of .txt."""


def solve(ctx: StageContext) -> StageResult:
    opts = options_from(PosesOptions, ctx.options)
    sfm_opts = SfmOptions(**{f.name: getattr(opts, f.name) for f in fields(SfmOptions)})
    if "seed" not in ctx.options:
        sfm_opts.seed = ctx.settings.seed
    result = solve_poses(ctx.input(Kind.LDR_VIEWS).path, sfm_opts, ctx.progress)
    for warning in result.warnings:
        ctx.progress.message(f"warning: {warning}")
    model = sfm_frame(result.model, scale=opts.scale, scale_from=opts.scale_from,
                      camera_height=opts.camera_height)
    if not model.frame["scale_known"]:
        ctx.progress.message(f"warning: {model.frame['units']}")
    stats = dict(result.stats)
    posed = stats.pop("posed_as_neighbour", {})
    model.frame["sfm"] = {"matcher": sfm_opts.matcher, "camera_model": sfm_opts.camera_model,
                          "registered": len(result.registered), "photos": len(result.photos),
                          "unregistered": result.unregistered, "posed_as_neighbour": posed}
    write_model(ctx.output, model, binary=bool(opts.binary))
    errors = model.point_errors
    return StageResult(
        metadata={"frame": {k: v for k, v in model.frame.items() if k != "sfm"},
                  "unregistered": result.unregistered, "posed_as_neighbour": posed,
                  "notes": model.notes},
        counts={"photos": len(result.photos), "registered": len(result.registered),
                "images": len(model.cameras), "points": len(model.points)},
        metrics={"seconds_sfm": round(result.seconds, 3),
                 "mean_reprojection_error_px": float(errors.mean()) if len(errors) else None,
                 **stats},
    )


CONVERTERS = [
    Converter(
        name="poses.sfm",
        step="poses",
        inputs=(Kind.LDR_VIEWS,),
        output=Kind.POSES,
        run=solve,
        description="solve camera poses and sparse points from the photos (pycolmap SfM: "
                    "SIFT, matching, incremental mapping)",
        options=PosesOptions,
    ),
]
