import json
import os
import signal
import time

import numpy as np
import pytest

from gaslight_usd import registry as registry_mod
from gaslight_usd.chain import ChainRun, plan
from gaslight_usd.errors import GaslightError, NotBuiltYet, UsageError
from gaslight_usd.imageio import read_image, write_exr
from gaslight_usd.kinds import Artifact, Kind, detect_kind
from gaslight_usd.poses.views import hdr_view_paths
from gaslight_usd.progress import Progress
from gaslight_usd.registry import Converter, Registry, Settings, StageResult, default_registry
from gaslight_usd.stop_signals import stop_on_signals


def mean_panorama(ctx):
    """HDR views -> an 'HDRI' folder holding the mean view (a real, tiny converter)."""
    if ctx.options.get("fail"):
        raise RuntimeError("asked to fail")
    views = [read_image(p).pixels for p in hdr_view_paths(ctx.input(Kind.HDR_VIEWS).path)]
    ctx.output.mkdir(parents=True, exist_ok=True)
    write_exr(ctx.output / "mean.exr", np.mean(views, axis=0), ctx.settings.working_space)
    return StageResult(counts={"views": len(views)})


MEAN = Converter(name="test.mean", step="hdri", inputs=(Kind.HDR_VIEWS,), output=Kind.HDRI,
                 run=mean_panorama, description="mean of the HDR views")


def registry_with_mean() -> Registry:
    """The linear uplift and the mean converter only: independent of other plug-ins."""
    return Registry([default_registry()["uplift.linear"], MEAN])


def test_builtins_are_discovered():
    assert "uplift.linear" in default_registry()


def test_plan_finds_the_shortest_chain_and_respects_choices():
    reg = registry_with_mean()
    steps = plan({Kind.LDR_VIEWS}, Kind.HDRI, reg)
    assert [s.name for s in steps] == ["uplift.linear", "test.mean"]
    assert [s.name for s in plan({Kind.HDR_VIEWS}, Kind.HDRI, reg)] == ["test.mean"]
    with pytest.raises(GaslightError, match="no converter chain makes hdri"):
        plan({Kind.LDR_VIEWS}, Kind.HDRI, reg, choose={"uplift": "uplift.nonexistent"})
    with pytest.raises(NotBuiltYet, match="no converter makes usd"):
        plan({Kind.LDR_VIEWS}, Kind.USD, Registry([MEAN]))


def test_run_writes_outputs_report_and_resumes(photo_folder, tmp_path):
    out = tmp_path / "run"
    run = ChainRun(out, Settings.resolved(), registry_with_mean(), Progress(quiet=True))
    arts = run.run([Artifact(Kind.LDR_VIEWS, photo_folder)], [Kind.HDRI])
    assert (arts[Kind.HDRI].path / "mean.exr").exists()
    assert len(hdr_view_paths(out / "hdr")) == 3
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "done"
    assert [s["name"] for s in report["stages"]] == ["uplift", "hdri"]
    assert report["stages"][0]["counts"]["views"] == 3
    assert all(s["seconds"] >= 0 for s in report["stages"])
    assert report["colour"]["working_space"] == "ACEScg"
    assert "numpy" in report["versions"]

    again = ChainRun(out, Settings.resolved(), registry_with_mean(), Progress(quiet=True))
    again.run([Artifact(Kind.LDR_VIEWS, photo_folder)], [Kind.HDRI])
    assert [r.status for r in again.records] == ["resumed", "resumed"]


def test_a_single_stage_into_a_run_folder_keeps_the_runs_state_and_report(photo_folder,
                                                                            tmp_path):
    """`hdri out/splats.ply -o out/probe.exr` after `run -o out`: the next run still
    resumes the stages the single-stage command did not make, and report.json lists both."""
    out = tmp_path / "run"
    ChainRun(out, Settings.resolved(), registry_with_mean(), Progress(quiet=True),
             command=["gaslight2usd", "run"]).run([Artifact(Kind.LDR_VIEWS, photo_folder)],
                                                  [Kind.HDRI])
    single = ChainRun(out, Settings.resolved(), registry_with_mean(), Progress(quiet=True),
                      command=["gaslight2usd", "hdri"])
    single.run([Artifact(Kind.HDR_VIEWS, out / "hdr")], [Kind.HDRI],
               outputs={Kind.HDRI: out / "second"}, resume=False)
    assert (out / "second" / "mean.exr").exists()
    report = json.loads((out / "report.json").read_text())
    assert [(s["name"], s["output"]) for s in report["stages"]] == [
        ("uplift", str(out / "hdr")), ("hdri", str(out / "second"))]
    assert report["stages"][0]["command"] == ["gaslight2usd", "run"]
    again = ChainRun(out, Settings.resolved(), registry_with_mean(), Progress(quiet=True))
    again.run([Artifact(Kind.LDR_VIEWS, photo_folder)], [Kind.HDRI])
    assert [r.status for r in again.records] == ["resumed", "done"]


def test_failure_is_reported_and_the_rerun_resumes_after_done_stages(photo_folder, tmp_path):
    out = tmp_path / "run"
    reg = registry_with_mean()
    failing = ChainRun(out, Settings.resolved(), reg, Progress(quiet=True))
    with pytest.raises(RuntimeError):
        failing.run([Artifact(Kind.LDR_VIEWS, photo_folder)], [Kind.HDRI],
                    options={"hdri": {"fail": True}})
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "failed"
    assert [s["status"] for s in report["stages"]] == ["done", "failed"]
    assert not (out / "hdri").exists()

    fixed = ChainRun(out, Settings.resolved(), reg, Progress(quiet=True))
    fixed.run([Artifact(Kind.LDR_VIEWS, photo_folder)], [Kind.HDRI])
    assert [r.status for r in fixed.records] == ["resumed", "done"]


def test_changed_input_invalidates_the_resume(photo_folder, tmp_path):
    out = tmp_path / "run"
    ChainRun(out, Settings.resolved(), registry_with_mean(), Progress(quiet=True)).run(
        [Artifact(Kind.LDR_VIEWS, photo_folder)], [Kind.HDR_VIEWS])
    (photo_folder / "shot_0.jpg").unlink()
    rerun = ChainRun(out, Settings.resolved(), registry_with_mean(), Progress(quiet=True))
    rerun.run([Artifact(Kind.LDR_VIEWS, photo_folder)], [Kind.HDR_VIEWS])
    assert [r.status for r in rerun.records] == ["done"]


def test_linear_uplift_normalises_exif_exposure(photo_folder, tmp_path):
    """Three photos a stop apart: relative radiance = linear / 2**(ev - median ev)."""
    out = tmp_path / "run"
    ChainRun(out, Settings.resolved(working_space="lin_rec709"), registry_with_mean(),
             Progress(quiet=True)).run(
        [Artifact(Kind.LDR_VIEWS, photo_folder)], [Kind.HDR_VIEWS])
    first = read_image(out / "hdr" / "shot_0.exr")
    assert first.metadata["gaslight:exposure_ratio"] == pytest.approx(0.5, rel=1e-3)
    source = read_image(photo_folder / "shot_0.jpg", to_space="lin_rec709").pixels
    np.testing.assert_allclose(first.pixels, source / 0.5, rtol=2e-3, atol=1e-4)


def test_a_refusing_converter_falls_back_to_the_next(photo_folder, tmp_path):
    picky = Converter(name="test.picky", step="uplift", inputs=(Kind.LDR_VIEWS,),
                      output=Kind.HDR_VIEWS, run=mean_panorama, description="never applies",
                      priority=50, accepts=lambda inputs: "no brackets in these photos")
    reg = Registry([picky, *registry_with_mean()])
    run = ChainRun(tmp_path / "run", Settings.resolved(), reg, Progress(quiet=True))
    run.run([Artifact(Kind.LDR_VIEWS, photo_folder)], [Kind.HDR_VIEWS])
    assert [r.converter for r in run.records] == ["uplift.linear"]
    explicit = ChainRun(tmp_path / "run2", Settings.resolved(), reg, Progress(quiet=True))
    with pytest.raises(UsageError, match="no brackets"):
        explicit.run([Artifact(Kind.LDR_VIEWS, photo_folder)], [Kind.HDR_VIEWS],
                     choose={"uplift": "test.picky"})


def test_detect_kind(photo_folder, tmp_path):
    assert detect_kind(photo_folder) is Kind.LDR_VIEWS
    (tmp_path / "sparse" / "0").mkdir(parents=True)
    (tmp_path / "sparse" / "0" / "cameras.txt").write_text("# empty\n")
    assert detect_kind(tmp_path / "sparse") is Kind.POSES


def test_entry_point_plugins_are_loaded(tmp_path, monkeypatch):
    site = tmp_path / "site"
    (site / "gaslight_test_plugin-0.1.dist-info").mkdir(parents=True)
    (site / "gaslight_test_plugin-0.1.dist-info" / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: gaslight-test-plugin\nVersion: 0.1\n")
    (site / "gaslight_test_plugin-0.1.dist-info" / "entry_points.txt").write_text(
        "[gaslight_usd.converters]\nmine = gaslight_test_plugin:CONVERTERS\n")
    (site / "gaslight_test_plugin.py").write_text(
        "from gaslight_usd.registry import Converter\n"
        "from gaslight_usd.kinds import Kind\n"
        "CONVERTERS = [Converter(name='plugin.demo', step='export', inputs=(Kind.SPLATS,),\n"
        "    output=Kind.USD, run=lambda ctx: None, description='demo')]\n")
    monkeypatch.syspath_prepend(str(site))
    names = [c.name for c in registry_mod._plugin_converters()]
    assert "plugin.demo" in names


def stopped_inside_c_code(ctx):
    """A stage hit by SIGTERM while C code ran a Python callback: numpy swallows the
    KeyboardInterrupt there and raises its own TypeError (seen in a batch on 2 cores)."""
    try:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)  # the handler raises here
    except KeyboardInterrupt:
        raise TypeError("Cannot compare structured arrays unless they have a common "
                        "dtype.") from None
    raise AssertionError("the stop signal never came")


def test_an_error_raised_by_a_stop_signal_is_an_interruption(photo_folder, tmp_path):
    stage = Converter(name="test.stopped", step="hdri", inputs=(Kind.HDR_VIEWS,),
                      output=Kind.HDRI, run=stopped_inside_c_code, description="stopped")
    reg = Registry([default_registry()["uplift.linear"], stage])
    run = ChainRun(tmp_path / "run", Settings.resolved(), reg, Progress(quiet=True))
    with stop_on_signals(preload_pycolmap=False), pytest.raises(KeyboardInterrupt) as caught:
        run.run([Artifact(Kind.LDR_VIEWS, photo_folder)], [Kind.HDRI])
    assert isinstance(caught.value.__cause__, TypeError)
    report = json.loads((tmp_path / "run" / "report.json").read_text())
    assert [s["status"] for s in report["stages"]] == ["done", "interrupted"]

    # without a stop signal the same error is the stage's failure
    def plain_error(ctx):
        raise TypeError("a real bug")

    reg = Registry([default_registry()["uplift.linear"],
                    Converter(name="test.bug", step="hdri", inputs=(Kind.HDR_VIEWS,),
                              output=Kind.HDRI, run=plain_error, description="bug")])
    run = ChainRun(tmp_path / "run2", Settings.resolved(), reg, Progress(quiet=True))
    with stop_on_signals(preload_pycolmap=False), pytest.raises(TypeError, match="real bug"):
        run.run([Artifact(Kind.LDR_VIEWS, photo_folder)], [Kind.HDRI])
    report = json.loads((tmp_path / "run2" / "report.json").read_text())
    assert [s["status"] for s in report["stages"]] == ["done", "failed"]
