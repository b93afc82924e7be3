"""``run`` on real fits: a killed fit resumes from its checkpoint, and a view with no
pose is left out of the fit (named) instead of failing the run."""

from __future__ import annotations

import _thread
import json
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import torch
from conftest import write_posed_views

from gaslight_usd.cli.main import main
from gaslight_usd.errors import EXIT_INTERRUPTED
from gaslight_usd.imageio import write_exr
from gaslight_usd.ply import read_ply


@pytest.fixture(scope="module")
def posed_views(tmp_path_factory):
    """Nine 48x48 HDR views of a closed synthetic scene and their COLMAP model."""
    root = tmp_path_factory.mktemp("posed")
    write_posed_views(root, with_points=False)
    return root


def interrupt_when(path: Path, timeout: float = 600) -> threading.Thread:
    """Press Ctrl-C (KeyboardInterrupt in the main thread) as soon as ``path`` exists."""
    def watch() -> None:
        deadline = time.monotonic() + timeout
        while not path.exists() and time.monotonic() < deadline:
            time.sleep(0.02)
        if path.exists():
            _thread.interrupt_main()

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


@pytest.fixture
def ctrl_c_raises():
    """Python's own SIGINT handler, even where the test runner was started with SIGINT
    ignored (a background job): Ctrl-C then raises KeyboardInterrupt, as for a user.
    torch's grad mode is restored too: an interrupt that lands inside a ``no_grad``
    block's entry leaves it off for the rest of the process."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    grad = torch.is_grad_enabled()
    yield
    signal.signal(signal.SIGINT, previous)
    torch.set_grad_enabled(grad)


@pytest.mark.slow
def test_a_killed_run_resumes_its_fit_from_the_checkpoint(posed_views, tmp_path, capsys,
                                                           ctrl_c_raises):
    out = tmp_path / "out"
    argv = ["run", str(posed_views / "hdr"), str(posed_views / "sparse"), "-o", str(out),
            "--to", "splats"]
    ckpt = out / ".splats.ply.fit-checkpoint.pt"
    watcher = interrupt_when(ckpt)
    assert main(argv) == EXIT_INTERRUPTED  # Ctrl-C once the first checkpoint is written
    watcher.join()
    assert ckpt.exists() and not (out / "splats.ply").exists()
    capsys.readouterr()
    assert main(argv) == 0
    err = capsys.readouterr().err
    resumed_at = [int(line.rsplit(" ", 1)[1]) for line in err.splitlines()
                  if "resuming at step" in line]
    assert resumed_at and resumed_at[0] >= 100 and resumed_at[0] % 100 == 0, err
    report = json.loads((out / "report.json").read_text())
    fit = next(s for s in report["stages"] if s["name"] == "fit")
    assert fit["counts"]["iterations"] == 300  # the fast preset's steps, counted once
    assert read_ply(out / "splats.ply").metadata["fit_metrics"]["resumed"] is True
    assert not ckpt.exists()


def test_a_changed_input_or_fresh_run_does_not_resume(posed_views, tmp_path):
    """The checkpoint is only trusted for the very stage that was killed."""
    from gaslight_usd.chain import ChainRun
    from gaslight_usd.kinds import Artifact, Kind
    from gaslight_usd.progress import Progress
    from gaslight_usd.registry import Converter, Registry, Settings, StageResult

    seen, kill = [], [False]

    def fit(ctx):
        seen.append(ctx.resume)
        if kill[0]:
            raise KeyboardInterrupt
        ctx.output.write_text("splats")
        return StageResult()

    reg = Registry()
    reg.add(Converter(name="fit.fake", step="fit", inputs=(Kind.HDR_VIEWS, Kind.POSES),
                      output=Kind.SPLATS, run=fit, description="fake"))
    given = [Artifact(Kind.HDR_VIEWS, posed_views / "hdr"),
             Artifact(Kind.POSES, posed_views / "sparse")]

    def run(seed, killed=False, resume=True):
        kill[0] = killed
        (tmp_path / "out" / "splats.ply").unlink(missing_ok=True)
        runner = ChainRun(tmp_path / "out", Settings.resolved(), reg, Progress(quiet=True))
        try:
            runner.run(given, [Kind.SPLATS], options={"fit": {"seed": seed}}, resume=resume)
        except KeyboardInterrupt:
            pass

    run(1, killed=True)
    run(2)               # other options than the killed stage's: starts over
    run(3, killed=True)
    run(3, resume=False)  # --fresh: starts over
    run(4, killed=True)
    run(4)               # the killed stage again, same inputs and options: continues
    assert seen == [False, False, False, False, False, True]


def test_a_stop_as_a_stage_starts_is_recorded_as_that_stage_s(posed_views, tmp_path,
                                                               monkeypatch):
    """A SIGTERM that lands just after a stage is announced (while its start is saved,
    before its converter runs) still leaves ``report.json`` naming the stage
    interrupted: ``batch`` reads its stages from there."""
    from gaslight_usd.chain import ChainRun
    from gaslight_usd.kinds import Artifact, Kind
    from gaslight_usd.progress import Progress
    from gaslight_usd.registry import Converter, Registry, Settings, StageResult

    def fit(ctx):
        raise AssertionError("the stop came first: the converter must not run")
        return StageResult()

    reg = Registry()
    reg.add(Converter(name="fit.fake", step="fit", inputs=(Kind.HDR_VIEWS, Kind.POSES),
                      output=Kind.SPLATS, run=fit, description="fake"))

    def stop(self, state):
        raise KeyboardInterrupt

    monkeypatch.setattr(ChainRun, "_save_state", stop)
    runner = ChainRun(tmp_path / "out", Settings.resolved(), reg, Progress(quiet=True))
    with pytest.raises(KeyboardInterrupt):
        runner.run([Artifact(Kind.HDR_VIEWS, posed_views / "hdr"),
                    Artifact(Kind.POSES, posed_views / "sparse")], [Kind.SPLATS])
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert [(s["name"], s["status"]) for s in report["stages"]] == [("fit", "interrupted")]


@pytest.mark.slow
def test_a_view_with_no_pose_is_left_out_and_named(posed_views, tmp_path, capsys):
    hdr = tmp_path / "hdr"
    hdr.mkdir()
    for exr in (posed_views / "hdr").glob("*.exr"):
        (hdr / exr.name).symlink_to(exr)
    noise = np.random.default_rng(0).uniform(0, 1, (48, 48, 3))
    write_exr(hdr / "zz_noise.exr", noise, "lin_rec709")
    out = tmp_path / "out"
    assert main(["run", str(hdr), str(posed_views / "sparse"), "-o", str(out),
                 "--to", "splats"]) == 0
    assert "left out of the fit: zz_noise" in capsys.readouterr().err
    report = json.loads((out / "report.json").read_text())
    fit = next(s for s in report["stages"] if s["name"] == "fit")
    assert fit["metadata"]["left_out_views"] == ["zz_noise"]
    assert fit["counts"]["views"] == 9
    meta = read_ply(out / "splats.ply").metadata
    assert meta["provenance"]["left_out_views"] == ["zz_noise"]
    assert "zz_noise" not in meta["provenance"]["views"]


def test_a_fit_called_with_gradients_off_still_trains(posed_views, tmp_path):
    """An API caller inside ``torch.no_grad()`` (or after a Ctrl-C that left grad mode
    off) gets a fit, not "element 0 of tensors does not require grad"."""
    out = tmp_path / "out"
    with torch.no_grad():
        assert main(["run", str(posed_views / "hdr"), str(posed_views / "sparse"), "-o",
                     str(out), "--to", "splats"]) == 0
    assert read_ply(out / "splats.ply").count > 0
