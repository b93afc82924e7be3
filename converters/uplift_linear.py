"""LDR views -> HDR views with no uplift: the photo linearised, nothing more.

The baseline every uplift method is measured against: clipped lamps stay
clipped at the photo's white level (divided by its exposure). Options:
:class:`LinearOptions`; photos are read one at a time.
"""

from __future__ import annotations

from dataclasses import dataclass

from gaslight_usd.imageio import LDR_EXTENSIONS, list_images
from gaslight_usd.kinds import Kind
from gaslight_usd.poses.views import iter_views, write_hdr_view
from gaslight_usd.registry import Converter, StageContext, StageResult, options_from
from gaslight_usd.uplift.checks import photo_set_warnings


@dataclass
class LinearOptions:
    max_size: int = 0
    """Long side (pixels) photos are shrunk to (0: as shot)."""


def linearise(ctx: StageContext) -> StageResult:
    s = ctx.settings
    opts = options_from(LinearOptions, ctx.options)
    photos = list_images(ctx.input(Kind.LDR_VIEWS).path, LDR_EXTENSIONS)
    ctx.output.mkdir(parents=True, exist_ok=True)
    clipped = []
    for i, view in enumerate(iter_views(photos, s.input_space, s.working_space, s.ocio_config,
                                        int(opts.max_size)), start=1):
        write_hdr_view(ctx.output, view, view.relative_radiance, s.working_space, "linear",
                       {"gaslight:clipped_fraction_after": view.clipped_fraction},
                       s.ocio_config)
        clipped.append(view.clipped_fraction)
        ctx.progress.update(i, len(photos), view=view.name)
    for warning in photo_set_warnings(photos, clipped):
        ctx.progress.message(f"warning: {warning}")
    return StageResult(
        metadata={"method": "linear", "colour_space": s.working_space},
        counts={"views": len(photos)},
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
        options=LinearOptions,
    ),
]
