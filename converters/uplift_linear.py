"""LDR views -> HDR views with no uplift: the photo linearised, nothing more.

The baseline every uplift method is measured against: clipped lamps stay
clipped at the photo's white level (divided by its exposure).
"""

from __future__ import annotations

from gaslight_usd.chain import StageContext, StageResult
from gaslight_usd.kinds import Kind
from gaslight_usd.registry import Converter
from gaslight_usd.views import load_views, write_hdr_view


def linearise(ctx: StageContext) -> StageResult:
    s = ctx.settings
    views = load_views(ctx.input(Kind.LDR_VIEWS).path, s.input_space, s.working_space,
                       s.ocio_config)
    ctx.output.mkdir(parents=True, exist_ok=True)
    for i, view in enumerate(views, start=1):
        write_hdr_view(ctx.output, view, view.relative_radiance, s.working_space, "linear",
                       {"gaslight:clipped_fraction_after": view.clipped_fraction},
                       s.ocio_config)
        ctx.progress.update(i, len(views), view=view.name)
    clipped = [v.clipped_fraction for v in views]
    return StageResult(
        metadata={"method": "linear", "colour_space": s.working_space},
        counts={"views": len(views)},
        metrics={"clipped_fraction_mean": float(sum(clipped) / len(clipped))},
    )


CONVERTERS = [
    Converter(
        name="uplift.linear",
        step="uplift",
        inputs=(Kind.LDR_VIEWS,),
        output=Kind.HDR_VIEWS,
        run=linearise,
        description="linearise photos to the working space (no uplift; the baseline)",
        priority=-10,
    ),
]
