"""Many scenes from one manifest: in-process, a local process pool, or a Dask cluster.

What a render-farm batch needs, and how this module gives it:

- **Plan first.** Each scene's chain is planned and compared with what its
  folder already holds (:meth:`ChainRun.preview`) before anything runs: a scene
  whose every stage matches its inputs and options is skipped without starting
  a worker, and ``--dry-run`` prints that plan and writes nothing.
- **Scenes apart.** A scene runs in its own process (``--jobs N``), or as one
  Dask task (``--dask``), into ``OUT/<name>/`` with its log in
  ``OUT/<name>/batch.log``. A scene that fails, or whose process dies, is
  reported with its error; the others go on.
- **Killed is resumable.** Every output is written atomically (temporary name,
  then rename), the chain's state after each stage; a scene's folder is locked
  while a run writes it, and the temporary files a SIGKILL left behind are
  removed by the next run before it starts. SIGTERM or Ctrl-C stop the running
  stages as Ctrl-C stops ``run`` (finished stages and scenes stay), and
  ``batch.json`` says which scenes were interrupted.
- **Dask, not a scheduler of our own.** ``--dask tcp://host:8786`` submits the
  same per-scene function to an existing cluster (the outputs must be on storage
  the workers share); ``--dask local:N`` starts a LocalCluster of N worker
  processes. The workers' own logs are gathered into ``OUT/dask-workers.log``.

``OUT/batch.json`` (schema ``schemas/batch.schema.json``) sums it up per scene:
status, time per stage, output sizes, key metrics and the lights found.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
import signal
import socket
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import asdict
from datetime import UTC, datetime
from multiprocessing import get_context
from multiprocessing.connection import wait
from pathlib import Path
from typing import Any, TextIO

from .atomic import PARTIAL_MARK, write_text
from .batch_summary import BATCH_FILE, LOG_FILE, batch_report, scene_summary, summary_table
from .chain import ChainRun
from .errors import GaslightError, InputError
from .manifest import ManifestError, Scene, load_manifest
from .outputs import check_output
from .pipeline import artifacts_from_paths, run_job, with_working_size
from .progress import Progress, format_seconds
from .provenance import tool_version
from .registry import Settings
from .stop_signals import claim_stop_signals, stop_on_signals, stop_requested

LOCK_FILE = ".batch.lock"
DASK_LOG_FILE = "dask-workers.log"
THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
STOP_GRACE_SECONDS = 60.0
"""How long a stopped batch waits for its scenes' processes to finish their
interrupted stage before killing them."""
LEFTOVER_PREFIXES = (".gaslight-write-check-",)


# -- planning -------------------------------------------------------------------
def preview_scene(scene: Scene) -> list[dict[str, Any]]:
    """What a run of ``scene`` would do per stage (``skip`` or ``run``), writing nothing."""
    job = scene.job
    runner = ChainRun(job.out_dir, Settings.resolved(**job.settings), progress=Progress(
        quiet=True))
    stages = runner.preview(artifacts_from_paths(job.inputs), job.targets, choose=job.choose,
                            options=with_working_size(job.options), resume=job.resume)
    return [asdict(s) for s in stages]


def plan_batch(scenes: list[Scene]) -> dict[str, dict[str, Any]]:
    """Each scene's stage preview, or the error that stops it before it starts."""
    plans: dict[str, dict[str, Any]] = {}
    for scene in scenes:
        try:
            stages = preview_scene(scene)
        except GaslightError as exc:
            plans[scene.name] = {"action": "fail", "stages": [], "error": str(exc)}
            continue
        action = "run" if any(s["action"] == "run" for s in stages) else "skip"
        plans[scene.name] = {"action": action, "stages": stages, "error": None}
    return plans


def plan_text(scenes: list[Scene], plans: dict[str, dict[str, Any]]) -> str:
    """The plan as ``--dry-run`` prints it."""
    lines = []
    for scene in scenes:
        plan = plans[scene.name]
        head = {"run": "run", "skip": "skip: every output matches its inputs and options",
                "fail": f"cannot run: {plan['error']}"}[plan["action"]]
        lines.append(f"{scene.name} -> {scene.job.out_dir}: {head}")
        lines += [f"  {s['name']:7s} {s['converter']:17s} {s['action']:4s}  {s['why']}"
                  for s in plan["stages"]]
    runs = sum(p["action"] == "run" for p in plans.values())
    skips = sum(p["action"] == "skip" for p in plans.values())
    lines.append(f"{len(scenes)} scenes: {runs} would run, {skips} would be skipped, "
                 f"{len(scenes) - runs - skips} cannot run (dry run: nothing written)")
    return "\n".join(lines)


# -- one scene (in-process, in a child process or on a Dask worker) ------------
def remove_leftovers(folder: Path) -> list[str]:
    """Delete the temporary files a killed run left in ``folder`` (hidden names with
    ``.partial-``: atomic writes that never reached their rename). Returns them."""
    removed = []
    for path in sorted(folder.rglob("*"), key=lambda p: len(p.parts), reverse=True):
        if PARTIAL_MARK in path.name or path.name.startswith(LEFTOVER_PREFIXES):
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path, ignore_errors=True)
            else:
                path.unlink(missing_ok=True)
            removed.append(str(path.relative_to(folder)))
    return removed


@contextlib.contextmanager
def scene_lock(folder: Path) -> Iterator[bool]:
    """Hold ``folder/.batch.lock`` (an advisory ``flock``) while a run writes the scene;
    yields False when another run holds it. The kernel drops the lock of a killed
    process, so a SIGKILL never leaves the scene locked."""
    try:
        import fcntl
    except ImportError:  # no flock on this platform: run unlocked
        yield True
        return
    with open(folder / LOCK_FILE, "a+") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            yield False
            return
        try:
            yield True
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def run_scene(scene: Scene) -> dict[str, Any]:
    """Run one scene's chain into its folder, logging to ``batch.log`` there.

    Returns ``{name, status, seconds, error, host, pid, log}`` (``log``: this run's
    lines). A failure is returned, not raised, so that one scene cannot stop a
    batch; KeyboardInterrupt (Ctrl-C, or SIGTERM in a batch process) is logged and
    raised.
    """
    out = Path(scene.job.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    log_path = out / LOG_FILE
    start = log_path.stat().st_size if log_path.exists() else 0
    t0 = time.perf_counter()
    status, error = "done", None
    with open(log_path, "a", encoding="utf-8") as log, scene_lock(out) as locked:
        stamp = datetime.now(UTC).isoformat(timespec="seconds")
        print(f"=== {stamp} gaslight2usd {tool_version()} batch: scene {scene.name} on "
              f"{socket.gethostname()} (pid {os.getpid()})", file=log, flush=True)
        if not locked:
            status, error = "failed", (f"another run is writing this scene ({out / LOCK_FILE} "
                                       "is locked)")
        else:
            removed = remove_leftovers(out)
            if removed:
                print(f"removed {len(removed)} temporary file(s) a killed run left: "
                      + ", ".join(removed), file=log, flush=True)
            try:
                run_job(scene.job, progress=Progress(label=scene.name, stream=log),
                        command=["gaslight2usd", "batch", scene.name])
            except GaslightError as exc:
                status, error = "failed", str(exc)
            except KeyboardInterrupt:
                print(f"interrupted after {time.perf_counter() - t0:.1f} s", file=log,
                      flush=True)
                raise
            except Exception as exc:  # one scene's crash must not stop the batch
                if stop_requested():  # the stop's own error, raised inside C code
                    print(f"interrupted after {time.perf_counter() - t0:.1f} s", file=log,
                          flush=True)
                    raise KeyboardInterrupt from exc
                status, error = "failed", f"internal error: {type(exc).__name__}: {exc}"
        seconds = round(time.perf_counter() - t0, 3)
        print(f"{status} in {seconds:.1f} s" + (f": {error}" if error else ""), file=log,
              flush=True)
    with open(log_path, encoding="utf-8", errors="replace") as log:
        log.seek(start)
        text = log.read()
    return {"name": scene.name, "status": status, "seconds": seconds, "error": error,
            "host": socket.gethostname(), "pid": os.getpid(), "log": text}


def _interrupted(scene: Scene, seconds: float = 0.0, status: str = "interrupted",
                 error: str | None = None) -> dict[str, Any]:
    return {"name": scene.name, "status": status, "seconds": round(seconds, 3),
            "error": error, "host": socket.gethostname(), "pid": None, "log": ""}


# -- signals ----------------------------------------------------------------------
def _exit_with_parent(parent: int) -> None:
    """In a batch's child: stop the scene (as Ctrl-C) when the batch process dies, so a
    killed batch leaves no orphan writing into OUT; hard exit if that does not end it."""
    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        import _thread

        _thread.interrupt_main()
        time.sleep(STOP_GRACE_SECONDS)
        os._exit(137)

    threading.Thread(target=watch, daemon=True, name="gaslight-parent-watch").start()


def _child_main(scene: Scene, conn: Any, parent: int) -> None:
    """Entry point of a scene's process: its output to the log, its outcome to ``conn``."""
    claim_stop_signals()
    _exit_with_parent(parent)
    out = Path(scene.job.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / LOG_FILE, "a", encoding="utf-8") as log:  # warnings, C libraries' prints
        os.dup2(log.fileno(), 1)
        os.dup2(log.fileno(), 2)
    t0 = time.perf_counter()
    try:
        outcome = run_scene(scene)
    except KeyboardInterrupt:
        outcome = _interrupted(scene, time.perf_counter() - t0)
    with contextlib.suppress(OSError):  # the batch process is gone: nobody to tell
        conn.send(outcome)
        conn.close()


@contextlib.contextmanager
def _thread_limits(threads: int) -> Iterator[dict[str, str]]:
    """Environment for scene processes: ``threads`` math threads each, so that N scenes
    share the cores instead of N x cores threads fighting (a variable the user set wins)."""
    env = {v: str(threads) for v in THREAD_VARS if v not in os.environ}
    os.environ.update(env)
    try:
        yield env
    finally:
        for v in env:
            os.environ.pop(v, None)


# -- runners ----------------------------------------------------------------------
Started = Callable[..., None]
Finished = Callable[[Scene, dict[str, Any]], None]


def _run_inline(scenes: list[Scene], started: Started, finished: Finished) -> None:
    for scene in scenes:
        started(scene)
        t0 = time.perf_counter()
        try:
            outcome = run_scene(scene)
        except KeyboardInterrupt:
            finished(scene, _interrupted(scene, time.perf_counter() - t0))
            raise
        finished(scene, outcome)


def _run_processes(scenes: list[Scene], jobs: int, started: Started, finished: Finished,
                   stopping: Callable[[str], None] = print) -> None:
    """Up to ``jobs`` scenes at once, each in a fresh process: a crash or a memory kill
    takes one scene, not the pool, and each scene's memory is returned when it ends."""
    ctx = get_context("spawn")
    pending = deque(scenes)
    running: dict[Any, dict[str, Any]] = {}  # sentinel -> process, pipe, scene, outcome
    threads = max(1, (os.cpu_count() or 1) // jobs)

    def finish(entry: dict[str, Any]) -> None:
        proc, reader, scene = entry["proc"], entry["reader"], entry["scene"]
        proc.join()
        outcome = entry["outcome"]
        if outcome is None and reader.poll():
            with contextlib.suppress(EOFError, OSError):
                outcome = reader.recv()
        reader.close()
        if outcome is None:
            code = proc.exitcode
            how = f"killed by signal {-code}" if code and code < 0 else f"exit status {code}"
            outcome = _interrupted(scene, time.perf_counter() - entry["t0"], "failed",
                                   f"the scene's process died ({how}); see its batch.log")
        finished(scene, outcome)

    try:
        while pending or running:
            while pending and len(running) < jobs:
                scene = pending.popleft()
                reader, writer = ctx.Pipe(duplex=False)
                with _thread_limits(threads):
                    proc = ctx.Process(target=_child_main, args=(scene, writer, os.getpid()),
                                       name=f"gaslight-{scene.name}")
                    proc.start()
                writer.close()
                running[proc.sentinel] = {"proc": proc, "reader": reader, "scene": scene,
                                          "outcome": None, "t0": time.perf_counter()}
                started(scene)
            readers = {e["reader"]: e for e in running.values() if e["outcome"] is None}
            ready = wait([*readers, *running], timeout=1.0)
            for obj in ready:
                if obj in readers:
                    with contextlib.suppress(EOFError, OSError):
                        readers[obj]["outcome"] = obj.recv()
            for obj in ready:
                if obj in running:
                    finish(running.pop(obj))
    except KeyboardInterrupt:
        stopping(f"batch: stopping {len(running)} running scene(s) (up to "
                 f"{STOP_GRACE_SECONDS:.0f} s); finished scenes and stages are kept")
        for entry in running.values():  # each stops its stage as Ctrl-C would
            with contextlib.suppress(ProcessLookupError):
                os.kill(entry["proc"].pid, signal.SIGINT)
        deadline = time.monotonic() + STOP_GRACE_SECONDS
        # read each outcome as it comes: a child blocks in its send while the pipe is full,
        # and joined before it is read it would be killed at the deadline as "died"
        unread = {e["reader"]: e for e in running.values() if e["outcome"] is None}
        while unread and time.monotonic() < deadline:
            for obj in wait(list(unread), timeout=max(0.0, deadline - time.monotonic())):
                entry = unread.pop(obj)
                with contextlib.suppress(EOFError, OSError):  # EOF: it died without one
                    entry["outcome"] = obj.recv()
        for entry in running.values():
            entry["proc"].join(max(0.0, deadline - time.monotonic()))
            if entry["proc"].is_alive():
                entry["proc"].kill()
            finish(entry)
        raise


def _dask_client(address: str) -> tuple[Any, Any]:
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:
        raise InputError("--dask needs the 'dask' extra: pip install "
                         "'gaslight-usd[dask]'") from exc
    if address.startswith("local:"):
        try:
            workers = int(address.split(":", 1)[1])
        except ValueError:
            workers = 0
        if workers < 1:
            raise InputError(f"--dask {address}: expected local:N with N >= 1 workers")
        threads = max(1, (os.cpu_count() or 1) // workers)
        env = {v: os.environ.get(v, str(threads)) for v in THREAD_VARS}
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, env=env)
        return Client(cluster), cluster
    try:
        return Client(address, timeout=30), None
    except OSError as exc:
        raise InputError(f"--dask: cannot reach the scheduler at {address}: {exc}") from None


class _BelowError(logging.Filter):
    """Drops Dask's records under ERROR (its loggers set their own levels)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return record.levelno >= logging.ERROR or not record.name.startswith(
            ("distributed", "tornado", "bokeh"))


@contextlib.contextmanager
def _quiet_dask() -> Iterator[None]:
    """Dask's own INFO lines (scheduler, nannies) off the console, where they would
    bury the batch's display; the workers' logs are gathered into a file instead.
    ``-v`` keeps them."""
    if logging.getLogger().isEnabledFor(logging.DEBUG):
        yield
        return
    handlers = [*logging.getLogger().handlers, *logging.getLogger("distributed").handlers]
    quiet = _BelowError()
    for handler in handlers:
        handler.addFilter(quiet)
    try:
        yield
    finally:
        for handler in handlers:
            handler.removeFilter(quiet)


def _run_dask(scenes: list[Scene], address: str, out_dir: Path, started: Started,
              finished: Finished, stopping: Callable[[str], None] = print) -> None:
    """Each scene as one task on a Dask cluster (``run_scene``, as in a local process)."""
    with _quiet_dask():
        _run_dask_quiet(scenes, address, out_dir, started, finished, stopping)


def _run_dask_quiet(scenes: list[Scene], address: str, out_dir: Path, started: Started,
                    finished: Finished, stopping: Callable[[str], None]) -> None:
    from distributed import as_completed

    client, cluster = _dask_client(address)
    futures: dict[Any, Scene] = {}
    try:
        for scene in scenes:
            futures[client.submit(run_scene, scene, key=f"gaslight-{scene.name}-"
                                  f"{os.getpid()}-{time.time_ns()}", pure=False)] = scene
            started(scene, "submitted")
        t0 = time.perf_counter()
        for future in as_completed(list(futures)):
            scene = futures.pop(future)
            try:
                outcome = future.result()
            except Exception as exc:  # a lost worker (KilledWorker), an unpicklable result
                outcome = _interrupted(scene, time.perf_counter() - t0, "failed",
                                       f"dask: {type(exc).__name__}: {exc}")
            finished(scene, outcome)
    except KeyboardInterrupt:
        stopping("batch: stopping; queued scenes are cancelled, a scene a remote worker has "
                 "started finishes there (a LocalCluster's workers are stopped)")
        client.cancel(list(futures))
        for scene in futures.values():
            finished(scene, _interrupted(scene))
        raise
    finally:
        _gather_worker_logs(client, out_dir / DASK_LOG_FILE)
        client.close()
        if cluster is not None:
            cluster.close()


def _gather_worker_logs(client: Any, path: Path) -> None:
    """The workers' own log lines (``Client.get_worker_logs``) into one file."""
    try:
        logs = client.get_worker_logs()
    except Exception as exc:  # the cluster may be gone already
        logs = {"(client)": [("WARNING", f"worker logs not gathered: {exc}")]}
    lines = [f"{worker} {level} {message}" for worker, entries in sorted(logs.items())
             for level, message in entries]
    write_text(path, "\n".join(lines) + "\n")


# -- the display -----------------------------------------------------------------
class BatchDisplay:
    """One progress display for the whole batch, on stderr.

    Lines when a scene starts and ends, and every ``interval`` seconds one status
    line: scenes done out of those to run, and each running scene's latest log
    line (read from ``OUT/<scene>/batch.log``, so it works for processes and Dask
    workers alike). On a terminal the status line redraws in place.
    """

    def __init__(self, total: int, out_dir: Path, quiet: bool = False,
                 stream: TextIO | None = None, interval: float | None = None):
        self.total, self.out_dir, self.quiet = total, out_dir, quiet
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.interval = interval if interval is not None else (2.0 if self.tty else 30.0)
        self.done = 0
        self.running: dict[str, float] = {}
        self.t0 = time.monotonic()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._status_shown = False

    def __enter__(self) -> BatchDisplay:
        if not self.quiet and self.total:
            self._thread = threading.Thread(target=self._tick, daemon=True,
                                            name="gaslight-batch-display")
            self._thread.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        self._clear()

    def line(self, text: str) -> None:
        if self.quiet:
            return
        with self._lock:
            self._clear_locked()
            print(text, file=self.stream, flush=True)

    def started(self, scene: Scene, how: str = "started") -> None:
        self.running[scene.name] = time.monotonic()
        self.line(f"[batch {self.done}/{self.total}] {scene.name}: {how}")

    def finished(self, scene: Scene, outcome: dict[str, Any]) -> None:
        self.running.pop(scene.name, None)
        self.done += 1
        error = f": {outcome['error']}" if outcome.get("error") else ""
        self.line(f"[batch {self.done}/{self.total}] {scene.name}: {outcome['status']} in "
                  f"{format_seconds(outcome['seconds'])}{error}")

    def status(self) -> str:
        parts = []
        for name in list(self.running):
            last = _last_line(self.out_dir / name / LOG_FILE)
            parts.append(f"{name}: {last}" if last else name)
        elapsed = format_seconds(time.monotonic() - self.t0)
        return f"[batch {self.done}/{self.total} done, {elapsed}] " + " | ".join(parts)

    def _tick(self) -> None:
        while not self._stop.wait(self.interval):
            text = self.status()
            with self._lock:
                if self.tty:
                    width = shutil.get_terminal_size((120, 20)).columns - 1
                    print("\r\033[K" + text[:width], end="", file=self.stream, flush=True)
                    self._status_shown = True
                else:
                    print(text, file=self.stream, flush=True)

    def _clear(self) -> None:
        with self._lock:
            self._clear_locked()

    def _clear_locked(self) -> None:
        if self._status_shown:
            print("\r\033[K", end="", file=self.stream, flush=True)
            self._status_shown = False


def _last_line(path: Path, tail: int = 4096) -> str:
    try:
        with open(path, "rb") as handle:
            handle.seek(max(0, handle.seek(0, os.SEEK_END) - tail))
            lines = handle.read().decode("utf-8", "replace").strip().splitlines()
    except OSError:
        return ""
    return lines[-1].strip() if lines else ""


# -- the batch --------------------------------------------------------------------
def run_batch(scenes: list[Scene], out_dir: str | Path, jobs: int = 1,
              dask: str | None = None, quiet: bool = False, manifest: str | Path | None = None,
              plans: dict[str, dict[str, Any]] | None = None,
              stream: TextIO | None = None) -> dict[str, Any]:
    """Run every scene that needs it; never stop at a failed one. Returns the batch
    report, also written to ``OUT/batch.json``.

    ``jobs`` > 1 runs that many scenes at once in their own processes; ``dask`` (an
    address, or ``local:N``) submits them to a Dask cluster instead. Scenes whose
    outputs all match their inputs and options are skipped without starting
    anything. SIGTERM or Ctrl-C stop the batch: running stages are interrupted,
    finished scenes and stages stay, and the report's ``status`` is ``interrupted``.
    """
    out_dir = check_output(Path(out_dir), folder=True)
    out_dir.mkdir(parents=True, exist_ok=True)
    started_at = datetime.now(UTC)
    t0 = time.perf_counter()
    plans = plans if plans is not None else plan_batch(scenes)
    outcomes: dict[str, dict[str, Any]] = {}
    for scene in scenes:
        plan = plans[scene.name]
        if plan["action"] == "skip":
            outcomes[scene.name] = {"name": scene.name, "status": "skipped", "seconds": 0.0,
                                    "error": None}
        elif plan["action"] == "fail":
            outcomes[scene.name] = {"name": scene.name, "status": "failed", "seconds": 0.0,
                                    "error": plan["error"]}
    to_run = [s for s in scenes if plans[s.name]["action"] == "run"]
    jobs = max(1, min(jobs, len(to_run) or 1))
    display = BatchDisplay(len(to_run), out_dir, quiet, stream)
    where = f"Dask ({dask})" if dask else (f"{jobs} processes" if jobs > 1 else "this process")
    skipped = sum(o["status"] == "skipped" for o in outcomes.values())
    display.line(f"batch: {len(scenes)} scenes: {len(to_run)} to run in {where}, {skipped} "
                 f"skipped (outputs match), {len(outcomes) - skipped} cannot run; "
                 f"logs in {out_dir}/<scene>/{LOG_FILE}")

    def finished(scene: Scene, outcome: dict[str, Any]) -> None:
        outcomes[scene.name] = outcome
        log_path = Path(scene.job.out_dir) / LOG_FILE
        if outcome.get("log") and not log_path.exists():  # a worker without shared storage
            write_text(log_path, outcome["log"])
        display.finished(scene, outcome)

    interrupted = False
    with display, stop_on_signals():
        try:
            if dask:
                _run_dask(to_run, dask, out_dir, display.started, finished, display.line)
            elif jobs > 1:
                _run_processes(to_run, jobs, display.started, finished, display.line)
            else:
                _run_inline(to_run, display.started, finished)
        except KeyboardInterrupt:
            interrupted = True
            display.line("batch: stopped; finished scenes and stages are kept")
    for scene in to_run:
        outcomes.setdefault(scene.name, _interrupted(scene, status="not started"))
    report = batch_report(scenes, outcomes, plans, out_dir, started_at,
                          time.perf_counter() - t0, jobs, dask, manifest, interrupted)
    write_text(out_dir / BATCH_FILE, json.dumps(report, indent=2, default=str))
    return report


__all__ = ["BATCH_FILE", "LOG_FILE", "BatchDisplay", "ManifestError", "Scene", "load_manifest",
           "plan_batch", "plan_text", "preview_scene", "remove_leftovers", "run_batch",
           "run_scene", "scene_summary", "summary_table"]
