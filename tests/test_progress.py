"""Progress lines that tell the truth: an ETA on long stages, whose line it is."""

from __future__ import annotations

import io

from gaslight_usd.progress import Progress, format_seconds


def test_eta_is_the_rate_so_far_times_what_is_left():
    p = Progress(quiet=True)
    assert p.eta(0, 100, now=10.0) is None           # the first update starts the clock
    assert p.eta(10, 100, now=12.0) is None          # under 3 s: too early to say
    assert p.eta(20, 100, now=14.0) == 16.0          # 4 s for 20 steps: 80 left -> 16 s
    assert p.eta(100, 100, now=30.0) is None         # finished
    assert p.eta(5, 50, now=31.0) is None            # a new count restarts the clock
    assert p.eta(30, 50, now=36.0) == 4.0


def test_update_prints_count_extras_and_eta(monkeypatch):
    stream = io.StringIO()
    p = Progress("fit", stream=stream, interval=0.0)
    clock = iter([100.0, 106.0])
    monkeypatch.setattr("gaslight_usd.progress.time.monotonic", lambda: next(clock))
    p.update(0, 300, splats=10)
    p.update(100, 300, loss=0.25, splats=1200)
    assert stream.getvalue().splitlines() == [
        "[fit] 0/300 splats=10",
        "[fit] 100/300 loss=0.25 splats=1200, eta 12 s",
    ]


def test_child_lines_keep_the_scene_name():
    stream = io.StringIO()
    scene = Progress("stage_b", stream=stream)
    scene.child("3/5 fit").message("kept 10 splats")
    assert stream.getvalue() == "[stage_b 3/5 fit] kept 10 splats\n"
    plain = io.StringIO()
    Progress(stream=plain).child("1/2 uplift").message("x")
    assert plain.getvalue() == "[1/2 uplift] x\n"


def test_format_seconds():
    assert [format_seconds(s) for s in (0.4, 42, 185, 3720)] == [
        "0 s", "42 s", "3 min 05 s", "1 h 02 min"]
