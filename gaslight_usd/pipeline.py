"""The whole chain as one call: what ``gaslight2usd run`` and ``batch`` use.

Options are grouped by step name (``uplift``, ``poses``, ``fit``, ``export``,
``hdri``) and passed to whichever converter runs that step. Unless the job
says otherwise (``uplift.max_size``; 0 keeps the photos' size), photos are
uplifted at the fit preset's working size (:func:`..fit.presets.uplift_size`) and
SfM features are extracted at the preset's size (:func:`..fit.presets.sfm_options`):
work and memory then follow the preset, not the camera's megapixels.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .chain import ChainRun
from .kinds import Artifact, Kind, detect_kind
from .progress import Progress
from .registry import Registry, Settings, default_registry

DEFAULT_TARGETS = (Kind.SPLATS, Kind.USD, Kind.HDRI)


@dataclass
class Job:
    """One scene to process: its inputs, what to make, and the step options."""

    inputs: list[Path]
    out_dir: Path
    targets: tuple[Kind, ...] = DEFAULT_TARGETS
    choose: dict[str, str] = field(default_factory=dict)
    options: dict[str, dict[str, Any]] = field(default_factory=dict)
    settings: dict[str, Any] = field(default_factory=dict)
    resume: bool = True


def artifacts_from_paths(paths: list[Path]) -> list[Artifact]:
    """Tell what each input path holds; two inputs of one kind is an error."""
    from .errors import InputError

    found: dict[Kind, Artifact] = {}
    for path in paths:
        kind = detect_kind(path)
        if kind in found:
            raise InputError(f"two inputs hold {kind.value} (also {found[kind].path})", path)
        found[kind] = Artifact(kind, Path(path))
    return list(found.values())


def with_working_size(options: Mapping[str, Mapping[str, Any]]) -> dict[str, dict[str, Any]]:
    """``options`` with ``uplift.max_size`` and the SfM's feature size and count
    (``poses.max_image_size``, ``poses.max_features``) set from the fit preset when not
    given."""
    from .fit.presets import PRESETS, sfm_options, uplift_size

    out = {step: dict(opts) for step, opts in options.items()}
    name = out.get("fit", {}).get("preset") or "fast"
    uplift = out.setdefault("uplift", {})
    if uplift.get("max_size") is None:
        uplift["max_size"] = uplift_size(PRESETS[name]) if name in PRESETS else 0
    poses = out.setdefault("poses", {})
    for key, value in sfm_options(name).items():
        if poses.get(key) is None:
            poses[key] = value
    return out


def run_job(job: Job, registry: Registry | None = None, progress: Progress | None = None,
            command: list[str] | None = None) -> dict[Kind, Artifact]:
    settings = Settings.resolved(**job.settings)
    progress = progress or Progress()
    runner = ChainRun(job.out_dir, settings, registry or default_registry(), progress, command)
    artifacts = runner.run(artifacts_from_paths(job.inputs), job.targets, choose=job.choose,
                           options=with_working_size(job.options), resume=job.resume)
    write_run_pictures(job.out_dir, artifacts, settings, progress)
    return artifacts


def write_run_pictures(out_dir: Path, artifacts: Mapping, settings: Settings,
                       progress: Progress) -> Path | None:
    """``OUT/contact-sheet.png``: the run's photos, HDR views and HDRIs to look at.

    A failure to draw it is a warning, not a failed run.
    """
    from .errors import GaslightError
    from .imageio import LDR_EXTENSIONS, list_images
    from .poses.views import hdr_view_paths
    from .preview import latlong_hdris, run_contact_sheet

    def files(kind: Kind, lister) -> list[Path]:
        art = artifacts.get(kind)
        if art is None or not Path(art.path).is_dir():
            return []
        try:
            return lister(Path(art.path))
        except GaslightError:
            return []

    try:
        return run_contact_sheet(
            out_dir, files(Kind.LDR_VIEWS, lambda p: list_images(p, LDR_EXTENSIONS)),
            files(Kind.HDR_VIEWS, hdr_view_paths), files(Kind.HDRI, latlong_hdris), settings)
    except (GaslightError, OSError) as exc:
        progress.message(f"warning: no contact sheet: {exc}")
        return None


def step_options(pairs: Mapping[str, Mapping[str, Any]]) -> dict[str, dict[str, Any]]:
    """Drop unset (None) values so converters see only what the user gave."""
    return {step: {k: v for k, v in opts.items() if v is not None}
            for step, opts in pairs.items()}
