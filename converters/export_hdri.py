"""Splats -> HDRIs: a folder with one lat-long (and cube) EXR per probe point.

Options: :class:`~gaslight_usd.export_options.HdriOptions` (``at`` None: the
cameras' median point moved to free space, :func:`gaslight_usd.probe.default_probe`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gaslight_usd.errors import InputError
from gaslight_usd.export_options import HdriOptions
from gaslight_usd.kinds import Kind
from gaslight_usd.lights import find_lights
from gaslight_usd.ply import read_ply
from gaslight_usd.probe_check import (
    inside_warning,
    near_light_warning,
    outside_warning,
    unseen_angles,
    unseen_light_warning,
)
from gaslight_usd.registry import Converter, StageContext, StageResult, options_from
from gaslight_usd.sightings import Sightings


def probe_points(at, scene) -> list[tuple[float, float, float]]:
    """``at`` as a list of 3-tuples; the default probe (inside the set) when None."""
    return [p for p, _ in probe_choices(at, scene)]


def probe_choices(at, scene) -> list[tuple[tuple[float, float, float], str]]:
    """Probe points with how each was chosen (given, or the default probe's reason)."""
    if at is None or len(at) == 0:
        from gaslight_usd.probe import default_probe

        choice = default_probe(scene)
        return [(tuple(float(v) for v in choice.position), "default: " + choice.how)]
    arr = np.asarray(at, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[None]
    if arr.shape[-1] != 3 or not np.isfinite(arr).all():
        raise InputError(f"probe points must be finite X,Y,Z triples, got {at!r}")
    return [(tuple(float(v) for v in p), "given (--at)") for p in arr]


def export_hdri_stage(ctx: StageContext) -> StageResult:
    from gaslight_usd import colour
    from gaslight_usd.hdri import probe_output_paths, render_probe

    o = options_from(HdriOptions, ctx.options)
    src = ctx.input(Kind.SPLATS).path
    scene = read_ply(src)
    choices = probe_choices(o.at, scene)
    points = [p for p, _ in choices]
    out = Path(ctx.output)
    paths = o.paths or probe_output_paths(out, len(points))
    s = ctx.settings
    out_space = o.output_space
    if out_space:
        out_space = colour.resolve_space(out_space, s.ocio_config)
    written, warnings = [], []
    lights = find_lights(scene)
    sightings = Sightings.from_metadata(scene.metadata)
    for pos in points:
        found = [outside_warning(pos, scene.positions) if o.at else None,
                 near_light_warning(pos, lights), inside_warning(pos, scene),
                 unseen_light_warning(pos, lights, sightings)]
        for warning in filter(None, found):
            warnings.append(warning)
            ctx.progress.message(f"warning: {warning}")
    for i, ((pos, how), path) in enumerate(zip(choices, paths, strict=True), start=1):
        files = render_probe(scene, pos, path, width=int(o.size),
                             cube=bool(o.cube), faces=bool(o.faces),
                             tx=bool(o.tx), working_space=s.working_space,
                             output_space=out_space, config_uri=s.ocio_config,
                             attributes={"gaslight:source": str(src),
                                         "gaslight:probeChoice": how},
                             device=o.device or s.device)
        angles = unseen_angles(pos, np.array([lt.position for lt in lights]), sightings)
        written.append({"position": list(pos), "chosen": how,
                        "files": [str(p) for p in files.all()],
                        # per light (the lights finder's order, brightest first): how
                        # far from every photo that saw it this probe sees it
                        "lights_unseen_deg": [None if not np.isfinite(a) else round(float(a), 1)
                                              for a in angles]})
        if how.startswith("default"):
            ctx.progress.message(f"probe at {', '.join(f'{v:.3g}' for v in pos)} ({how})")
        ctx.progress.update(i, len(points), probe=str(path))
    return StageResult(
        metadata={"probes": written, "colour_space": out_space or s.working_space,
                  "warnings": warnings},
        counts={"probes": len(points), "files": sum(len(w["files"]) for w in written)},
        metrics={},
    )


CONVERTERS = [
    Converter(
        name="export.hdri",
        step="hdri",
        inputs=(Kind.SPLATS,),
        output=Kind.HDRI,
        run=export_hdri_stage,
        description="render lat-long (and cube) EXR HDRIs from the splats at probe points",
        options=HdriOptions,
    ),
]
