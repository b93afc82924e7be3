"""The chain runner: plan a path of converters from what the user gives to what
they ask for, run it stage by stage with progress and timings, write
``report.json``, and resume after a failure.

Resuming: each finished stage is recorded in ``<out>/.gaslight-state.json``
with a fingerprint of its converter, options and inputs (paths, sizes,
modification times) and one of the files it wrote. A later run with the same
fingerprint and its outputs as they were written skips the stage; a stage
whose output was deleted or edited since runs again, and so does every stage
after it (their inputs change). :meth:`ChainRun.preview` says which stages a
run would skip without running any (``batch --dry-run``, and a batch skips a
scene whose stages all match). Outputs are written atomically by converters,
so a killed stage leaves nothing that looks finished. A stage that was started
with the same fingerprint and killed is told so (``StageContext.resume``): the
fit then continues from its checkpoint instead of step 1.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import sys
import time
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from .atomic import write_text
from .errors import InputError, NotBuiltYet, UsageError
from .kinds import Artifact, Kind
from .outputs import check_output
from .progress import Progress
from .provenance import tool_version, versions
from .registry import (
    Converter,
    Registry,
    Settings,
    StageContext,
    default_registry,
)
from .stop_signals import as_interrupt

STATE_FILE = ".gaslight-state.json"
REPORT_FILE = "report.json"


@dataclass
class StageRecord:
    name: str
    converter: str
    inputs: dict[str, str]
    output: str
    status: str
    seconds: float
    counts: dict[str, Any] = field(default_factory=dict)
    metrics: dict[str, Any] = field(default_factory=dict)
    metadata: dict[str, Any] = field(default_factory=dict)
    error: str | None = None
    fingerprint: str | None = None
    """sha256 of the converter, options, settings and inputs (paths, sizes, mtimes)."""
    output_fingerprint: str | None = None
    """sha256 of the files the stage wrote (paths, sizes, mtimes), as it wrote them."""


@dataclass
class StagePreview:
    """What a run would do with one stage: skip it (its outputs match) or run it."""

    name: str
    converter: str
    output: str
    action: str
    """``skip`` or ``run``."""
    why: str


def plan(available: Iterable[Kind], target: Kind, registry: Registry,
         choose: Mapping[str, str] | None = None) -> list[Converter]:
    """Shortest list of converters that makes ``target`` from ``available``.

    ``choose`` maps a step name to the converter the user picked for it
    (e.g. ``{"uplift": "uplift.bracket"}``). Raises GaslightError when no path
    exists, naming what is missing.
    """
    have = set(available)
    choose = dict(choose or {})

    def candidates(kind: Kind) -> list[Converter]:
        convs = registry.producing(kind)
        picked = [c for c in convs if choose.get(c.step) in (None, c.name)]
        return picked

    memo: dict[Kind, list[Converter] | None] = {}

    def solve(kind: Kind, visiting: frozenset[Kind]) -> list[Converter] | None:
        if kind in have:
            return []
        if kind in memo:
            return memo[kind]
        if kind in visiting:
            return None
        best: list[Converter] | None = None
        for conv in candidates(kind):
            steps: list[Converter] = []
            for need in conv.inputs:
                sub = solve(need, visiting | {kind})
                if sub is None:
                    break
                steps += [s for s in sub if s not in steps]
            else:
                steps.append(conv)
                if best is None or len(steps) < len(best):
                    best = steps
        memo[kind] = best
        return best

    result = solve(target, frozenset())
    if result is None:
        given = ", ".join(sorted(k.value for k in have)) or "nothing"
        makers = ", ".join(c.name for c in registry.producing(target))
        if not makers:
            raise NotBuiltYet(f"no converter makes {target.value} yet (none is installed)")
        raise UsageError(
            f"no converter chain makes {target.value} from {given} "
            f"(converters that make {target.value}: {makers})")
    return result


def _is_folder_output(kind: Kind, path: Path) -> bool:
    """Whether an output of ``kind`` at ``path`` is a folder (EXR views, a COLMAP model)."""
    return kind in (Kind.HDR_VIEWS, Kind.POSES, Kind.HDRI) and not path.suffix


def _fingerprint_path(path: Path) -> list:
    if not path.exists():
        return [str(path), None]
    if path.is_file():
        st = path.stat()
        return [str(path.resolve()), st.st_size, st.st_mtime_ns]
    entries = []
    for p in sorted(path.rglob("*")):
        if p.is_file() and not p.name.startswith("."):
            st = p.stat()
            entries.append([str(p.relative_to(path)), st.st_size, st.st_mtime_ns])
    return [str(path.resolve()), entries]


def output_files(out_path: Path, metadata: Mapping[str, Any]) -> list[Path]:
    """The files a stage wrote: its output and any others it lists in its metadata
    (the USD export's layers beside ``scene.usda``, the HDRIs' cube maps)."""
    listed = [*metadata.get("files", []),
              *(f for probe in metadata.get("probes", []) for f in probe.get("files", []))]
    extra = sorted({Path(f) for f in listed if isinstance(f, str)} - {Path(out_path)})
    return [Path(out_path), *extra]


def output_fingerprint(out_path: Path, metadata: Mapping[str, Any]) -> str:
    """sha256 of a stage's written files as they are now (paths, sizes, mtimes)."""
    blob = json.dumps([_fingerprint_path(p) for p in output_files(out_path, metadata)],
                      default=str)
    return hashlib.sha256(blob.encode()).hexdigest()


def fingerprint(conv: Converter, inputs: Mapping[Kind, Artifact], options: Mapping,
                settings: Settings) -> str:
    blob = json.dumps({
        "converter": conv.name,
        "inputs": {k.value: _fingerprint_path(a.path) for k, a in sorted(inputs.items())},
        "options": options,
        "settings": asdict(settings),
    }, sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()


def _finished(done: Mapping[str, Any] | None, key: str, out_path: Path) -> bool:
    """Whether a stage's state says it finished with fingerprint ``key`` and its
    written files are still as it wrote them (older states kept no output
    fingerprint: the output existing then suffices)."""
    if not done or done.get("fingerprint") != key or not out_path.exists():
        return False
    expected = done.get("output")
    metadata = done.get("record", {}).get("metadata", {})
    return expected is None or output_fingerprint(out_path, metadata) == expected


class ChainRun:
    """One run of a planned chain into an output folder."""

    def __init__(self, out_dir: str | Path, settings: Settings | None = None,
                 registry: Registry | None = None, progress: Progress | None = None,
                 command: list[str] | None = None):
        self.out_dir = Path(out_dir)
        self.settings = settings or Settings.resolved()
        self.registry = registry or default_registry()
        self.progress = progress or Progress()
        self.command = command if command is not None else list(sys.argv)
        self.records: list[StageRecord] = []
        self.started = datetime.now(UTC)

    # -- state for resuming -------------------------------------------------
    def _load_state(self) -> dict:
        path = self.out_dir / STATE_FILE
        if not path.exists():
            return {}
        try:
            return json.loads(path.read_text())
        except (OSError, json.JSONDecodeError):
            return {}

    def _save_state(self, state: dict) -> None:
        write_text(self.out_dir / STATE_FILE, json.dumps(state, indent=1, sort_keys=True))

    # -- running ------------------------------------------------------------
    def run(self, given: Iterable[Artifact], targets: Iterable[Kind],
            choose: Mapping[str, str] | None = None,
            options: Mapping[str, Mapping[str, Any]] | None = None,
            outputs: Mapping[Kind, Path] | None = None, resume: bool = True
            ) -> dict[Kind, Artifact]:
        """Make every kind in ``targets``; return every artifact known at the end.

        ``options`` maps a step name to that step's options; ``outputs`` maps a
        kind to where it should be written (default ``out_dir/<kind default>``).
        """
        artifacts: dict[Kind, Artifact] = {a.kind: a for a in given}
        self.given = list(artifacts.values())
        steps = self._steps(artifacts, targets, choose)
        for conv in steps:  # before any work: an unknown option is an error, not dropped
            self.registry.check_options(conv.step, (options or {}).get(conv.step, {}))
        check_output(self.out_dir, folder=True)
        for kind, path in (outputs or {}).items():
            check_output(path, folder=_is_folder_output(kind, Path(path)))
        created_out = not self.out_dir.exists()
        self.out_dir.mkdir(parents=True, exist_ok=True)
        # Without resume every stage runs, but the state of stages this run does not make
        # stays: `hdri out/splats.ply -o out/probe.exr` must not make the next `run -o out`
        # redo its fit.
        state = self._load_state()
        self._earlier = self._load_report()
        self._planned = {conv.step for conv in steps}
        total = len(steps)
        for index, conv in enumerate(steps, start=1):
            stage_options = dict((options or {}).get(conv.step, {}))
            inputs = {k: artifacts[k] for k in conv.inputs}
            conv = self._applicable(conv, inputs, explicit=conv.step in (choose or {}))
            out_path = Path((outputs or {}).get(conv.output) or
                            self.out_dir / conv.output.default_name)
            key = fingerprint(conv, inputs, stage_options, self.settings)
            label = f"{index}/{total} {conv.step}"
            if resume and _finished(state.get(conv.step), key, out_path):
                done = state[conv.step]
                self.progress.message(f"[{label}] {conv.name}: already done, resuming after it")
                record = StageRecord(**{**done["record"], "status": "resumed"})
                self.records.append(record)
                artifacts[conv.output] = Artifact(conv.output, out_path, record.metadata)
                continue
            t0 = time.perf_counter()
            record = StageRecord(
                name=conv.step, converter=conv.name,
                inputs={k.value: str(a.path) for k, a in inputs.items()},
                output=str(out_path), status="running", seconds=0.0, fingerprint=key)
            try:  # from the stage's first line on, a stop is recorded as this stage's
                self.progress.message(f"[{label}] {conv.name}: {conv.description}")
                # A stage started before with the same fingerprint and killed may continue
                # its own work (the fit from its checkpoint); with other inputs it starts
                # over.
                started = state.setdefault("started", {})
                continues = resume and started.get(conv.step) == key
                started[conv.step] = key
                self._save_state(state)
                ctx = StageContext(inputs=inputs, output=out_path, settings=self.settings,
                                   options=stage_options, progress=self.progress.child(label),
                                   resume=continues)
                result = conv.run(ctx)
            except BaseException as caught:
                exc = as_interrupt(caught)  # a stop signal's error is the stop
                record.status = "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed"
                record.error = str(exc) or type(exc).__name__
                record.seconds = round(time.perf_counter() - t0, 3)
                self.records.append(record)
                if created_out and isinstance(exc, InputError) and index == 1:
                    # Bad input caught by the first stage: leave no trace of the run.
                    shutil.rmtree(self.out_dir, ignore_errors=True)
                else:
                    self.write_report(status="failed")
                if exc is not caught:
                    raise exc from caught
                raise
            record.seconds = round(time.perf_counter() - t0, 3)
            record.status = "done"
            record.counts, record.metrics = result.counts, result.metrics
            record.metadata = result.metadata
            record.output_fingerprint = output_fingerprint(out_path, result.metadata)
            self.records.append(record)
            artifacts[conv.output] = Artifact(conv.output, out_path, result.metadata)
            state[conv.step] = {"fingerprint": key, "output": record.output_fingerprint,
                                "record": asdict(record)}
            self._save_state(state)
            self.write_report(status="running")
            self.progress.message(f"[{label}] done in {record.seconds:.1f} s")
        self.write_report(status="done")
        return artifacts

    def _steps(self, artifacts: Mapping[Kind, Artifact], targets: Iterable[Kind],
               choose: Mapping[str, str] | None) -> list[Converter]:
        """The converters that make ``targets`` from ``artifacts``, in order."""
        for art in artifacts.values():
            if not art.path.exists():
                raise InputError("no such file or folder", art.path)
        steps: list[Converter] = []
        for target in targets:
            for conv in plan(artifacts.keys() | {c.output for c in steps}, target,
                             self.registry, choose):
                if conv not in steps:
                    steps.append(conv)
        return steps

    def preview(self, given: Iterable[Artifact], targets: Iterable[Kind],
                choose: Mapping[str, str] | None = None,
                options: Mapping[str, Mapping[str, Any]] | None = None,
                resume: bool = True) -> list[StagePreview]:
        """What :meth:`run` would do with each stage, writing nothing.

        A stage is skipped when its fingerprint and its written files match the
        state; a stage after one that runs runs too (its input is remade).
        """
        artifacts: dict[Kind, Artifact] = {a.kind: a for a in given}
        steps = self._steps(artifacts, targets, choose)
        state = self._load_state() if resume else {}
        remade: str | None = None
        out: list[StagePreview] = []
        for conv in steps:
            stage_options = dict((options or {}).get(conv.step, {}))
            inputs = {k: artifacts[k] for k in conv.inputs}
            if remade is None:  # inputs exist as they are: the converter can be chosen
                conv = self._applicable(conv, inputs, explicit=conv.step in (choose or {}))
            out_path = self.out_dir / conv.output.default_name
            artifacts[conv.output] = Artifact(conv.output, out_path)
            done = state.get(conv.step)
            if remade is not None:
                action, why = "run", f"after {remade} (its input is remade)"
            elif not resume:
                action, why = "run", "fresh run"
            elif _finished(done, key := fingerprint(conv, inputs, stage_options,
                                                     self.settings), out_path):
                action, why = "skip", "outputs match inputs and options"
            elif not done:
                action, why = "run", "not run yet"
            elif done.get("fingerprint") != key:
                action, why = "run", "inputs or options changed"
            else:
                action, why = "run", "its output is missing or was changed"
            if action == "run" and remade is None:
                remade = conv.step
            out.append(StagePreview(conv.step, conv.name, str(out_path), action, why))
        return out

    def _applicable(self, conv: Converter, inputs: dict[Kind, Artifact],
                    explicit: bool) -> Converter:
        """``conv``, or the next converter of its step that accepts these inputs."""
        reason = conv.refusal(inputs)
        if reason is None:
            return conv
        if explicit:
            raise UsageError(f"{conv.name} cannot run on these inputs: {reason}")
        for alt in self.registry.alternatives(conv):
            if alt is not conv and alt.priority <= conv.priority and alt.refusal(inputs) is None:
                self.progress.message(f"{conv.name} does not apply ({reason}); using {alt.name}")
                return alt
        raise UsageError(f"no {conv.step} converter applies: {conv.name}: {reason}")

    def _load_report(self) -> dict[str, Any]:
        try:
            earlier = json.loads((self.out_dir / REPORT_FILE).read_text())
        except (OSError, json.JSONDecodeError):
            return {}
        return earlier if isinstance(earlier, dict) else {}

    def _kept_stages(self) -> list[dict[str, Any]]:
        """Stages of steps this run does not make, as an earlier command recorded them in
        this folder's report: a single-stage command adds to the report of a ``run``."""
        earlier = getattr(self, "_earlier", {})
        stages = earlier.get("stages")
        if not isinstance(stages, list):
            return []
        planned = getattr(self, "_planned", set())
        command = earlier.get("command")
        return [{**st, "command": st.get("command", command)} for st in stages
                if isinstance(st, dict) and st.get("name") not in planned]

    def report(self, status: str) -> dict[str, Any]:
        kept = self._kept_stages()
        return {
            "tool": "gaslight2usd",
            "version": tool_version(),
            "status": status,
            "command": self.command,
            "started": self.started.isoformat(timespec="seconds"),
            "finished": datetime.now(UTC).isoformat(timespec="seconds"),
            "inputs": [{"kind": a.kind.value, "path": str(a.path)}
                       for a in getattr(self, "given", [])],
            "colour": {"ocio_config": self.settings.ocio_config,
                       "working_space": self.settings.working_space,
                       "input_space": self.settings.input_space},
            "stages": kept + [asdict(r) for r in self.records],
            "total_seconds": round(sum(r.seconds for r in self.records), 3),
            "versions": versions(),
        }

    def write_report(self, status: str) -> Path:
        path = self.out_dir / REPORT_FILE
        write_text(path, json.dumps(self.report(status), indent=2, default=str))
        return path
