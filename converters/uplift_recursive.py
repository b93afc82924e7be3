"""LDR views -> HDR views by the paper's recursive exposure prediction.

Options (``ctx.options``, from ``gaslight2usd hdr``): ``predictor`` (default
``fast``), ``weights``, ``threshold`` (0.9), ``max_steps`` (6), ``brighter``,
``save_stacks``, ``panorama`` (auto|on|off), ``max_size`` (long side the photos are
shrunk to first; 0: as shot). Photos are read and uplifted one at a time.
"""

from __future__ import annotations

from gaslight_usd.chain import StageContext, StageResult
from gaslight_usd.imageio import LDR_EXTENSIONS, list_images
from gaslight_usd.kinds import Kind
from gaslight_usd.registry import Converter
from gaslight_usd.uplift.checks import clipped_photos_warning
from gaslight_usd.uplift.pipeline import (
    UpliftOptions,
    make_predictor,
    transform_for,
    uplift_view,
)
from gaslight_usd.views import iter_views, write_hdr_view


def uplift(ctx: StageContext) -> StageResult:
    s = ctx.settings
    opts = UpliftOptions.from_dict(ctx.options)
    predictor = make_predictor(opts)
    photos = list_images(ctx.input(Kind.LDR_VIEWS).path, LDR_EXTENSIONS)
    transform = transform_for(s.input_space, s.working_space, s.ocio_config)
    ctx.output.mkdir(parents=True, exist_ok=True)
    stack_dir = ctx.output / "stacks" if opts.save_stacks else None
    steps, after, before = [], [], []
    for i, view in enumerate(iter_views(photos, s.input_space, s.working_space, s.ocio_config,
                                        opts.max_size), start=1):
        result = uplift_view(view, predictor, transform, opts, stack_dir)
        write_hdr_view(ctx.output, view, result.radiance, s.working_space, "recursive",
                       result.attributes, s.ocio_config)
        steps.append(result.attributes["gaslight:ev_steps"])
        after.append(result.attributes["gaslight:clipped_fraction_after"])
        before.append(view.clipped_fraction)
        ctx.progress.update(i, len(photos), view=view.name, steps=steps[-1])
    warning = clipped_photos_warning([p.name for p in photos], before)
    if warning:
        ctx.progress.message(f"warning: {warning}")
    return StageResult(
        metadata={"method": "recursive", "predictor": predictor.name,
                  "colour_space": s.working_space, "curve": transform.curve.name},
        counts={"views": len(photos), "ev_steps_total": int(sum(steps))},
        metrics={"clipped_fraction_before_mean": float(sum(before) / len(before)),
                 "clipped_fraction_after_mean": float(sum(after) / len(after)),
                 "ev_steps_max": int(max(steps))},
    )


CONVERTERS = [
    Converter(
        name="uplift.recursive",
        step="uplift",
        inputs=(Kind.LDR_VIEWS,),
        output=Kind.HDR_VIEWS,
        run=uplift,
        description="recursive exposure prediction + Debevec merge (GaSLight 3.1)",
        priority=10,
    ),
]
