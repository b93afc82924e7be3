"""Many scenes from one manifest: a process pool on one machine, Dask beyond.

A manifest (JSON, schema in ``schemas/manifest.schema.json``)::

    {"defaults": {"targets": ["splats", "usd", "hdri"],
                  "options": {"fit": {"preset": "fast"}},
                  "settings": {"working_space": "ACEScg"}},
     "scenes": [{"name": "stage_a", "inputs": ["stage_a/photos"]},
                {"name": "stage_b", "inputs": ["b/photos", "b/sparse"],
                 "options": {"fit": {"preset": "balanced"}}}]}

The manifest is checked against that schema before any work (an unknown key
such as ``"opitons"`` is an error naming it). Relative paths are relative to
the manifest. Each scene runs into
``OUT/<name>/`` with its own ``report.json``; the batch writes
``OUT/batch-report.json``. Scenes are independent and resumable: a re-run skips
finished stages, so a failed batch is simply run again.
"""

from __future__ import annotations

import json
import re
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

from .atomic import write_text
from .errors import GaslightError, InputError
from .jsoncheck import bundled_schema, first_problem
from .kinds import Kind
from .outputs import check_output
from .pipeline import Job, run_job
from .progress import Progress

TARGET_NAMES = {"hdr": Kind.HDR_VIEWS, "poses": Kind.POSES, "splats": Kind.SPLATS,
                "usd": Kind.USD, "hdri": Kind.HDRI}
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


@dataclass
class SceneOutcome:
    name: str
    status: str
    seconds: float
    out_dir: str
    error: str | None = None


def _merge(base: dict, over: dict) -> dict:
    merged = {k: dict(v) if isinstance(v, dict) else v for k, v in base.items()}
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = {**merged[key], **value}
        else:
            merged[key] = value
    return merged


def load_manifest(path: str | Path, out_dir: str | Path) -> list[tuple[str, Job]]:
    """Parse and check a manifest; every problem is an InputError naming it."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no such manifest", path)
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc}", path) from exc
    scenes = data.get("scenes") if isinstance(data, dict) else None
    if not isinstance(scenes, list) or not scenes:
        raise InputError("manifest needs a non-empty 'scenes' list", path)
    # The checks below name the common mistakes in their own words; the schema then
    # finds the rest (unknown keys such as "opitons", wrong types) before any work.
    problem = first_problem(data, bundled_schema("manifest.schema.json"))
    try:
        jobs = _jobs(scenes, data.get("defaults", {}), path, Path(out_dir))
    except (TypeError, AttributeError, ValueError) as exc:  # a wrong type in the manifest
        raise InputError(f"manifest: {problem or exc}", path) from None
    if problem:
        raise InputError(f"manifest: {problem}", path)
    return jobs


def _jobs(scenes: list, defaults: dict, path: Path, out_dir: Path) -> list[tuple[str, Job]]:
    jobs: list[tuple[str, Job]] = []
    seen: set[str] = set()
    for i, scene in enumerate(scenes):
        where = f"scenes[{i}]"
        if not isinstance(scene, dict) or not scene.get("inputs"):
            raise InputError(f"{where} needs 'inputs' (a list of paths)", path)
        name = str(scene.get("name") or Path(scene["inputs"][0]).parent.name or f"scene{i}")
        if not _NAME.match(name) or name in seen:
            raise InputError(f"{where}: scene name {name!r} is invalid or repeated", path)
        seen.add(name)
        merged = _merge(defaults, scene)
        targets = merged.get("targets", ["splats", "usd", "hdri"])
        unknown = [t for t in targets if t not in TARGET_NAMES]
        if unknown:
            raise InputError(f"{where}: unknown targets {unknown}; "
                             f"choose from {sorted(TARGET_NAMES)}", path)
        inputs = [(path.parent / p).resolve() for p in merged["inputs"]]
        missing = [str(p) for p in inputs if not p.exists()]
        if missing:
            raise InputError(f"{where} ({name}): missing input {missing[0]}", path)
        jobs.append((name, Job(
            inputs=inputs,
            out_dir=out_dir / name,
            targets=tuple(TARGET_NAMES[t] for t in targets),
            choose=dict(merged.get("choose", {})),
            options={k: dict(v) for k, v in merged.get("options", {}).items()},
            settings=dict(merged.get("settings", {})),
        )))
    return jobs


def _run_one(name: str, job: Job, quiet: bool) -> SceneOutcome:
    t0 = time.perf_counter()
    try:
        run_job(job, progress=Progress(label=name, quiet=quiet),
                command=["gaslight2usd", "batch", name])
        status, error = "done", None
    except GaslightError as exc:
        status, error = "failed", str(exc)
    except Exception as exc:  # one scene's crash must not stop the batch
        status, error = "failed", f"internal error: {type(exc).__name__}: {exc}"
    return SceneOutcome(name, status, round(time.perf_counter() - t0, 3), str(job.out_dir),
                        error)


def run_batch(jobs: list[tuple[str, Job]], out_dir: str | Path, workers: int = 1,
              dask_address: str | None = None, quiet: bool = False) -> dict[str, Any]:
    """Run every scene; never stops at the first failure. Returns the batch report."""
    out_dir = check_output(Path(out_dir), folder=True)
    out_dir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    if dask_address:
        try:
            from distributed import Client
        except ImportError as exc:
            raise InputError("--dask needs the 'dask' extra: pip install "
                             "'gaslight-usd[dask]'") from exc
        with Client(dask_address) as client:
            futures = [client.submit(_run_one, n, j, True, key=f"gaslight-{n}", pure=False)
                       for n, j in jobs]
            outcomes = client.gather(futures)
    elif workers > 1:
        with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
            outcomes = list(pool.map(_run_one, *zip(*jobs, strict=True),
                                     [quiet] * len(jobs)))
    else:
        outcomes = [_run_one(n, j, quiet) for n, j in jobs]
    report = {
        "scenes": [vars(o) for o in outcomes],
        "done": sum(o.status == "done" for o in outcomes),
        "failed": sum(o.status != "done" for o in outcomes),
        "seconds": round(time.perf_counter() - t0, 3),
        "workers": workers,
        "dask": dask_address,
    }
    write_text(out_dir / "batch-report.json", json.dumps(report, indent=2))
    return report
