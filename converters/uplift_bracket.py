"""LDR views -> HDR views by merging exposure brackets.

Options: ``group_file`` (explicit grouping), ``response`` (``ocio``: the input
space's transform, default; ``debevec``: recovered from each bracket),
``align`` (default on), ``save_stacks``, ``max_size`` (long side the photos are
shrunk to as they are read; 0: as shot). Refuses with an InputError when the
photos hold no bracket. One EXR per view, named after the bracket's middle
exposure (or its name in the grouping file); photos that form no bracket of
their own are linearised alone. How the photos were grouped is summarised, kept
in the stage result (``metadata["grouping"]``, so in report.json) and in each
EXR's header (``gaslight:bracket``: the source frames, ``gaslight:grouped_by``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gaslight_usd.colour import CLIP_LEVEL
from gaslight_usd.errors import InputError
from gaslight_usd.kinds import Kind
from gaslight_usd.poses.views import load_views, write_hdr_view
from gaslight_usd.registry import Converter, StageContext, StageResult, options_from
from gaslight_usd.uplift.bracket import (
    BracketOptions,
    check_bracket,
    find_brackets,
    group_views,
    merge_bracket,
    recover_response,
)
from gaslight_usd.uplift.pipeline import transform_for, write_stack


def merge(ctx: StageContext) -> StageResult:
    s = ctx.settings
    opts = options_from(BracketOptions, ctx.options)
    folder = ctx.input(Kind.LDR_VIEWS).path
    group_file = Path(opts.group_file) if opts.group_file else None
    views = load_views(folder, s.input_space, s.working_space, s.ocio_config,
                       int(opts.max_size))
    grouping = group_views(views, group_file)
    brackets = grouping.brackets
    ctx.progress.message(grouping.lines()[0])
    for warning in grouping.warnings:
        ctx.progress.message(f"warning: {warning}")
    if not any(b.is_bracket for b in brackets):
        raise InputError("the photos hold no exposure brackets (every view has a single "
                         "exposure, or EXIF exposure times are missing); use --method "
                         "recursive, or give --group-file", group_file or folder)
    transform = transform_for(s.input_space, s.working_space, s.ocio_config)
    response = opts.response
    ctx.output.mkdir(parents=True, exist_ok=True)
    merged_count, spans = 0, []
    for i, bracket in enumerate(brackets, start=1):
        if len(bracket.views) > 1:
            check_bracket(bracket, group_file or folder)
        stack = [v.encoded for v in bracket.views]
        evs = bracket.evs
        curve = transform.curve
        if response == "debevec" and bracket.is_bracket:
            curve = recover_response(stack, evs)
        result = merge_bracket(stack, evs, curve, align=opts.align)
        ref = bracket.views[result.reference]
        radiance = transform.to_working(result.linear) / np.float32(ref.exposure_ratio)
        darkest = stack[int(np.argmin(evs))]
        attrs = {
            "gaslight:bracket": ",".join(v.path.name for v in bracket.views),
            "gaslight:grouped_by": bracket.how,
            "gaslight:bracket_evs": [float(e) for e in result.evs],
            "gaslight:ev_steps": len(stack) - 1,
            "gaslight:min_ev": float(min(result.evs)),
            "gaslight:response": curve.name,
            "gaslight:shifts_px": [c for sh in result.shifts for c in sh],
            "gaslight:clipped_fraction_after": float(np.mean(darkest.max(axis=-1)
                                                            >= CLIP_LEVEL)),
        }
        ref.name = bracket.name
        write_hdr_view(ctx.output, ref, np.maximum(radiance, 0), s.working_space, "bracket",
                       attrs, s.ocio_config,
                       clipped_by=bracket.views[int(np.argmin(bracket.evs))],
                       crushed_by=bracket.views[int(np.argmax(bracket.evs))])
        if opts.save_stacks:
            write_stack(ctx.output / "stacks", ref.name, stack, result.evs)
        merged_count += int(bracket.is_bracket)
        spans.append(max(result.evs) - min(result.evs))
        ctx.progress.update(i, len(brackets), view=ref.name)
    return StageResult(
        metadata={"method": "bracket", "colour_space": s.working_space, "response": response,
                  "grouping": grouping.as_dict()},
        counts={"views": len(brackets), "brackets": merged_count, "photos": len(views)},
        metrics={"bracket_span_ev_max": float(max(spans))},
    )


def no_brackets(inputs: dict) -> str | None:
    """The reason this converter does not apply (None when brackets are present)."""
    from gaslight_usd.imageio import LDR_EXTENSIONS, list_images
    from gaslight_usd.registry import Settings

    s = Settings.resolved()
    found = find_brackets(list_images(inputs[Kind.LDR_VIEWS].path, LDR_EXTENSIONS),
                          s.input_space, s.working_space, s.ocio_config)
    return None if found else "the photos hold no exposure brackets"


CONVERTERS = [
    Converter(
        name="uplift.bracket",
        step="uplift",
        inputs=(Kind.LDR_VIEWS,),
        output=Kind.HDR_VIEWS,
        run=merge,
        description="merge exposure brackets (Debevec, aligned)",
        priority=20,
        accepts=no_brackets,
        options=BracketOptions,
    ),
]
