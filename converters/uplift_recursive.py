"""LDR views -> HDR views by the paper's recursive exposure prediction.

Options: :class:`~gaslight_usd.uplift.pipeline.UpliftOptions` (``predictor``,
``weights``, ``threshold``, ``max_steps``, ``brighter``, ``save_stacks``,
``panorama``, ``max_size``, ``extra``). Photos are read and uplifted one at a time.
"""

from __future__ import annotations

from gaslight_usd.imageio import LDR_EXTENSIONS, list_images
from gaslight_usd.kinds import Kind
from gaslight_usd.poses.views import iter_views, write_hdr_view
from gaslight_usd.registry import Converter, StageContext, StageResult, options_from
from gaslight_usd.uplift.checks import photo_set_warnings
from gaslight_usd.uplift.pipeline import (
    UpliftOptions,
    make_predictor,
    transform_for,
    uplift_view,
)


def uplift(ctx: StageContext) -> StageResult:
    s = ctx.settings
    opts = options_from(UpliftOptions, ctx.options)
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
    for warning in photo_set_warnings(photos, before):
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
        options=UpliftOptions,
    ),
]
