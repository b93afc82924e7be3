"""``gaslight2usd batch``: manifests checked whole, scenes apart, resume, stop, kill, Dask.

Every scene here is real work on tiny inputs: three 48x64 JPEGs uplifted to HDR
views, or nine 48x48 HDR views of a synthetic room fitted in a few steps,
exported and probed at 32 pixels (``posed_hdr_scene``).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from importlib.resources import files
from pathlib import Path

import jsonschema
import pytest

from gaslight_usd.batch import run_batch
from gaslight_usd.cli.main import main
from gaslight_usd.errors import EXIT_BAD_INPUT
from gaslight_usd.imageio import read_image
from gaslight_usd.kinds import Kind
from gaslight_usd.manifest import load_manifest
from gaslight_usd.ply import read_ply

CLI = [str(Path(sys.executable).with_name("gaslight2usd"))]

TINY_FIT = """\
[defaults]
targets = ["splats", "usd", "hdri"]
probes = [[0, 0, 0]]
[defaults.options.fit]
iterations = 8
budget = 600
[defaults.options.export]
as = ["particlefield"]
[defaults.options.hdri]
size = 32
"""


def schema(name: str) -> dict:
    return json.loads(files("gaslight_usd.schemas").joinpath(name).read_text())


def posed_scenes(folder: Path, room: Path, *names: str, extra: str = "") -> Path:
    """``folder/m.toml``: tiny fit/export/HDRI scenes on the posed synthetic ``room``."""
    text = TINY_FIT + "".join(
        f'\n[[scenes]]\nname = "{n}"\ninputs = ["{room}/hdr", "{room}/sparse"]\nseed = {i}\n'
        for i, n in enumerate(names))
    return _write(folder / "m.toml", text + extra)


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def mtimes(folder: Path) -> dict[str, int]:
    """Every visible file under ``folder`` with its mtime (ns): outputs untouched or not."""
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.name.startswith(".") and p.name != "batch.log"}


def scene_entry(out: Path, name: str) -> dict:
    report = json.loads((out / "batch.json").read_text())
    jsonschema.validate(report, schema("batch.schema.json"))
    return next(s for s in report["scenes"] if s["name"] == name)


def leftovers(out: Path) -> list[str]:
    return [str(p) for p in out.rglob("*") if ".partial-" in p.name]


# -- the manifest -------------------------------------------------------------------
def test_toml_and_json_manifests_give_the_same_scenes(tmp_path, photo_folder,
                                                       posed_hdr_scene):
    sparse = posed_hdr_scene / "sparse"
    toml = _write(tmp_path / "m.toml", f"""\
[defaults]
preset = "fast"
colour = {{ working_space = "ACEScg", output_space = "Linear Rec.709 (sRGB)" }}
[defaults.options.fit]
budget = 900
iterations = 50

[[scenes]]
name = "hall"
photos = "photos"
poses = "{sparse}"
probes = [[0, 1.5, 0], [1, 1.2, -0.5]]
preset = "balanced"
[scenes.options.fit]
iterations = 70

[[scenes]]
name = "kitchen"
photos = "photos"
camera_height = 1.6
targets = ["hdr", "poses"]
method = "linear"
""")
    data = {"defaults": {"preset": "fast", "colour": {"working_space": "ACEScg",
                                                      "output_space": "Linear Rec.709 (sRGB)"},
                         "options": {"fit": {"budget": 900, "iterations": 50}}},
            "scenes": [{"name": "hall", "photos": "photos", "poses": str(sparse),
                        "probes": [[0, 1.5, 0], [1, 1.2, -0.5]], "preset": "balanced",
                        "options": {"fit": {"iterations": 70}}},
                       {"name": "kitchen", "photos": "photos", "camera_height": 1.6,
                        "targets": ["hdr", "poses"], "method": "linear"}]}
    jsonschema.validate(data, schema("manifest.schema.json"))
    js = _write(tmp_path / "m.json", json.dumps(data))
    from_toml, from_json = (load_manifest(m, tmp_path / "out") for m in (toml, js))
    assert [s.job for s in from_toml] == [s.job for s in from_json]
    hall, kitchen = (s.job for s in from_toml)
    assert hall.inputs == [photo_folder.resolve(), sparse.resolve()]
    assert hall.out_dir == tmp_path / "out" / "hall"
    # the scene's preset wins, its fit table merges key by key with the defaults'
    assert hall.options["fit"] == {"budget": 900, "iterations": 70, "preset": "balanced"}
    assert hall.options["hdri"] == {"at": [[0.0, 1.5, 0.0], [1.0, 1.2, -0.5]],
                                    "output_space": "Linear Rec.709 (sRGB)"}
    assert hall.settings == {"working_space": "ACEScg"}
    assert hall.targets == (Kind.SPLATS, Kind.USD, Kind.HDRI)
    assert kitchen.targets == (Kind.HDR_VIEWS, Kind.POSES)
    assert kitchen.options["poses"] == {"camera_height": 1.6}
    assert kitchen.choose == {"uplift": "uplift.linear"}


def test_a_bad_manifest_names_each_scene_and_key_and_writes_nothing(tmp_path, photo_folder,
                                                                     capsys):
    manifest = _write(tmp_path / "shots.toml", """\
[defaults]
preset = "fast"

[[scenes]]
name = "hall"
photos = "photos"
opitons = { fit = { iterations = 5 } }

[[scenes]]
name = "kitchen"
photos = "photos"
preset = "fastest"
probes = [[0, 1.5]]

[[scenes]]
name = "attic"
photos = "no/such/folder"
camera_height = 1.6
scale = 0.5
colour = { working_space = "ACEScgg" }

[[scenes]]
name = "hall"
photos = "photos"
""")
    out = tmp_path / "out"
    assert main(["batch", str(manifest), "-o", str(out), "--jobs", "2"]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    expected = [
        "scene 'hall' (scenes[0]): unknown key 'opitons'",
        "did you mean 'options'?",
        "scene 'kitchen' (scenes[1]): key 'preset': 'fastest' is not one of",
        "scene 'kitchen' (scenes[1]): key 'probes[0]': needs at least 3 item(s)",
        "scene 'attic' (scenes[2]): key 'photos': no such file or folder",
        "scene 'attic' (scenes[2]): keys 'camera_height' and 'scale' both give the scale",
        "scene 'attic' (scenes[2]): key 'colour.working_space': unknown colour space 'ACEScgg'",
        "scene 'hall' (scenes[3]): key 'name': 'hall' is used twice (also scenes[0])",
        "7 problem(s) in the manifest; nothing was run",
    ]
    for text in expected:
        assert text in err, (text, err)
    problem_lines = [line for line in err.splitlines() if line.startswith("gaslight2usd: error:")]
    assert len(problem_lines) == 7 and all("shots.toml: " in line for line in problem_lines)
    assert not out.exists()


def test_dry_run_prints_the_plan_and_writes_nothing(tmp_path, photo_folder, posed_hdr_scene,
                                                    capsys):
    (tmp_path / "empty").mkdir()
    manifest = posed_scenes(tmp_path, posed_hdr_scene, "room", extra=f"""
[[scenes]]
name = "shots"
photos = "{photo_folder}"
targets = ["hdr"]

[[scenes]]
name = "nothing"
photos = "{tmp_path / 'empty'}"
""")
    out = tmp_path / "out"
    assert main(["batch", str(manifest), "-o", str(out), "--dry-run"]) == 0
    text = capsys.readouterr().out
    assert f"room -> {out / 'room'}: run" in text
    for stage in ("fit     fit.splats        run   not run yet",
                  "export  export.usd        run   after fit (its input is remade)",
                  "hdri    export.hdri       run   after fit (its input is remade)",
                  "uplift  uplift.recursive  run   not run yet"):
        assert stage in text
    assert "nothing -> " in text and "cannot run:" in text and "holds no photos" in text
    assert "3 scenes: 2 would run, 0 would be skipped, 1 cannot run" in text
    assert not out.exists()


def manifest_examples() -> list[str]:
    """The manifest the README shows and the one ``batch --help`` shows."""
    from gaslight_usd.cli._batch import DESCRIPTION

    from .conftest import REPO

    readme = (REPO / "README.md").read_text().split("## Batch", 1)[1]
    help_lines = DESCRIPTION.split("(tables merge):\n", 1)[1].split("\n  other keys:")[0]
    return [readme.split("```toml\n", 1)[1].split("```", 1)[0],
            "\n".join(line[2:] for line in help_lines.splitlines())]


@pytest.mark.parametrize("where", ["README", "--help"])
def test_the_example_manifests_are_valid(where):
    import tomllib

    from gaslight_usd.jsoncheck import first_problem

    text = manifest_examples()[["README", "--help"].index(where)]
    data = tomllib.loads(text)
    jsonschema.validate(data, schema("manifest.schema.json"))
    assert first_problem(data, schema("manifest.schema.json")) is None
    assert [s["name"] for s in data["scenes"]] == ["kitchen", "hall"]


# -- running ------------------------------------------------------------------------
def test_scenes_run_in_processes_and_a_failing_one_does_not_stop_the_others(
        tmp_path, photo_folder):
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("no photos here")
    corrupt = tmp_path / "corrupt"
    corrupt.mkdir()
    for photo in photo_folder.iterdir():
        data = photo.read_bytes()
        (corrupt / photo.name).write_bytes(data if photo.name != "shot_1.jpg"
                                           else data[: len(data) // 3])
    manifest = _write(tmp_path / "shots.json", json.dumps({
        "defaults": {"targets": ["hdr"], "colour": {"working_space": "ACEScg"}},
        "scenes": [{"name": "good", "photos": "photos"},
                   {"name": "linear", "photos": "photos", "method": "linear"},
                   {"name": "corrupt", "photos": "corrupt"},
                   {"name": "empty", "photos": "empty"},
                   {"name": "badopt", "photos": "photos",
                    "options": {"uplift": {"predictor": "no-such"}}}]}))
    out = tmp_path / "out"
    res = subprocess.run([*CLI, "batch", manifest, "-o", out, "--jobs", "2"],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 1, res.stderr  # three scenes failed, the others ran
    by_name = {s["name"]: s for s in json.loads((out / "batch.json").read_text())["scenes"]}
    jsonschema.validate(json.loads((out / "batch.json").read_text()),
                        schema("batch.schema.json"))
    assert by_name["good"]["status"] == by_name["linear"]["status"] == "done"
    assert by_name["good"]["stages"][0]["converter"] == "uplift.recursive"
    assert by_name["linear"]["stages"][0]["converter"] == "uplift.linear"
    # found while planning: these never start
    assert by_name["corrupt"]["status"] == "failed"
    assert "shot_1.jpg" in by_name["corrupt"]["error"]
    assert by_name["empty"]["status"] == "failed" and "holds no photos" in \
        by_name["empty"]["error"]
    assert not (out / "corrupt").exists() and not (out / "empty").exists()
    # failed in its process: error, stage and log kept
    bad = by_name["badopt"]
    assert bad["status"] == "failed" and "unknown predictor 'no-such'" in bad["error"]
    assert bad["stages"][0]["status"] == "failed"
    assert any("unknown predictor" in line for line in bad["log_tail"])
    for name in ("good", "linear"):
        assert len(list((out / name / "hdr").glob("*.exr"))) == 3
        assert by_name[name]["metrics"]["hdr_views"] == 3
        assert by_name[name]["bytes"]["uplift"] > 0
        assert "[1/1 uplift] done in" in (out / name / "batch.log").read_text()
        jsonschema.validate(json.loads((out / name / "report.json").read_text()),
                            schema("report.schema.json"))
    assert "[batch 0/3] good: started" in res.stderr  # the empty one never starts
    table = res.stdout.splitlines()
    assert table[0].split()[:4] == ["scene", "status", "time", "uplift"]
    assert any(line.startswith("badopt") and "failed" in line for line in table)


def test_a_rerun_skips_and_a_new_probe_reruns_only_the_hdris(tmp_path, posed_hdr_scene):
    manifest = posed_scenes(tmp_path, posed_hdr_scene, "room")
    out = tmp_path / "out"
    report = run_batch(load_manifest(manifest, out), out, quiet=True)
    assert report["counts"]["done"] == 1
    first = mtimes(out / "room")
    entry = scene_entry(out, "room")
    assert [s["status"] for s in entry["stages"]] == ["done", "done", "done"]
    assert all(len(s["fingerprint"]) == 64 for s in entry["stages"])
    # the budget, less the few splats the fit's end prunes (planes on: nothing clipped)
    assert 500 < entry["metrics"]["splats"] <= 600 and entry["metrics"]["probes"] == 1

    report = run_batch(load_manifest(manifest, out), out, quiet=True)  # nothing changed
    entry = scene_entry(out, "room")
    assert entry["status"] == "skipped" and report["counts"]["skipped"] == 1
    assert [s["status"] for s in entry["stages"]] == ["skipped"] * 3
    assert mtimes(out / "room") == first  # not one file rewritten

    manifest.write_text(manifest.read_text().replace("probes = [[0, 0, 0]]",
                                                     "probes = [[0.2, 0.1, 0]]"))
    run_batch(load_manifest(manifest, out), out, quiet=True)
    entry = scene_entry(out, "room")
    assert entry["status"] == "done"
    assert [(s["name"], s["status"]) for s in entry["stages"]] == [
        ("fit", "skipped"), ("export", "skipped"), ("hdri", "done")]
    after = mtimes(out / "room")
    changed = {k for k in first if after.get(k) != first[k]}
    assert changed == {"hdri/probe_000.exr", "report.json", "contact-sheet.png"}
    stage = json.loads((out / "room" / "report.json").read_text())["stages"][2]
    assert stage["metadata"]["probes"][0]["position"] == pytest.approx([0.2, 0.1, 0.0])

    (out / "room" / "hdri" / "probe_000.exr").unlink()  # an output gone: its stage reruns
    run_batch(load_manifest(manifest, out), out, quiet=True)
    assert [s["status"] for s in scene_entry(out, "room")["stages"]] == [
        "skipped", "skipped", "done"]
    assert read_image(out / "room" / "hdri" / "probe_000.exr").pixels.shape == (16, 32, 3)


def wait_for(predicate, timeout: float = 240.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.05)


def log_has(path: Path, text: str, after: int = 0) -> bool:
    """Whether ``path`` holds ``text`` past its first ``after`` bytes (logs are appended
    to run after run)."""
    return path.exists() and text in path.read_bytes()[after:].decode(errors="replace")


def log_size(path: Path) -> int:
    return path.stat().st_size if path.exists() else 0


def test_sigterm_stops_cleanly_and_sigkill_loses_nothing(tmp_path, posed_hdr_scene):
    manifest = posed_scenes(tmp_path, posed_hdr_scene, "a", "b")
    out = tmp_path / "out"
    cmd = [*CLI, "batch", str(manifest), "-o", str(out), "-q"]

    # SIGTERM while both scenes fit in their processes: both stop as by Ctrl-C. The fits
    # are made long here, so that neither can finish before the signal on a fast machine
    # (with 8 steps, scene a was done before b had started fitting in one CI run).
    manifest.write_text(manifest.read_text().replace("iterations = 8", "iterations = 20000"))
    proc = subprocess.Popen([*cmd, "--jobs", "2"], stdout=subprocess.PIPE, text=True)
    wait_for(lambda: all(log_has(out / n / "batch.log", "[1/3 fit] fit.splats") for n in "ab"))
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=120) == 130
    report = json.loads((out / "batch.json").read_text())
    assert report["status"] == "interrupted"
    assert [s["status"] for s in report["scenes"]] == ["interrupted", "interrupted"]
    assert [s["stages"][0]["status"] for s in report["scenes"]] == ["interrupted"] * 2
    assert "interrupted after" in (out / "a" / "batch.log").read_text()
    assert not leftovers(out) and not (out / "a" / "splats.ply").exists()

    # SIGKILL of the whole batch once scene a is finished and b is under way (b's fit made
    # long, the last scene's own options, so that it cannot finish before the kill)
    tiny = manifest.read_text().replace("iterations = 20000", "iterations = 8")
    manifest.write_text(tiny + "[scenes.options.fit]\niterations = 20000\n")
    seen = {n: log_size(out / n / "batch.log") for n in "ab"}
    proc = subprocess.Popen(cmd, start_new_session=True)
    wait_for(lambda: log_has(out / "b" / "batch.log", "[1/3 fit] fit.splats", seen["b"]))
    assert log_has(out / "a" / "batch.log", "\ndone in", seen["a"])
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=60)
    finished_a = mtimes(out / "a")
    assert 500 < read_ply(out / "a" / "splats.ply").count <= 600
    # a writer SIGKILLed inside its atomic write leaves its temporary file, never the output
    writer = subprocess.Popen([sys.executable, "-c", (
        "import sys, time\nfrom gaslight_usd.atomic import atomic_path\n"
        "with atomic_path(sys.argv[1]) as tmp:\n"
        "    tmp.write_bytes(b'ply\\nformat binary_little_endian 1.0\\n')\n"
        "    time.sleep(120)\n"), str(out / "b" / "splats.ply")])
    # (the killed batch may have left its own, its state file's: wait for the writer's)
    wait_for(lambda: any(".splats.partial-" in p for p in leftovers(out / "b")))
    writer.kill()
    writer.wait()
    assert not (out / "b" / "splats.ply").exists()

    manifest.write_text(tiny)
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    report = json.loads((out / "batch.json").read_text())
    assert [s["status"] for s in report["scenes"]] == ["skipped", "done"]
    assert mtimes(out / "a") == finished_a  # nothing of the finished scene redone
    assert not leftovers(out)
    removed = [line for line in (out / "b" / "batch.log").read_text().splitlines()
               if "temporary file(s) a killed run left: " in line]
    assert len(removed) == 1 and ".splats.partial-" in removed[0]
    for name in "ab":
        assert 500 < read_ply(out / name / "splats.ply").count <= 600
        assert read_image(out / name / "hdri" / "probe_000.exr").pixels.shape == (16, 32, 3)


@pytest.mark.slow
def test_a_two_worker_dask_local_cluster_runs_the_scenes(tmp_path, photo_folder):
    pytest.importorskip("distributed")
    manifest = _write(tmp_path / "shots.toml", """\
[defaults]
targets = ["hdr"]
photos = "photos"

[[scenes]]
name = "one"

[[scenes]]
name = "two"
method = "linear"
""")
    out = tmp_path / "out"
    proc = subprocess.Popen([*CLI, "batch", manifest, "-o", out, "--dask", "local:2", "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 0, stderr
    report = json.loads(stdout)
    jsonschema.validate(report, schema("batch.schema.json"))
    assert report["dask"] == "local:2"
    assert [s["status"] for s in report["scenes"]] == ["done", "done"]
    for name in ("one", "two"):
        assert len(list((out / name / "hdr").glob("*.exr"))) == 3
        assert "[1/1 uplift] done in" in (out / name / "batch.log").read_text()
    pids = {int((out / name / "batch.log").read_text().split("(pid ", 1)[1].split(")")[0])
            for name in ("one", "two")}
    assert proc.pid not in pids  # run on the workers, not in the client
    assert "distributed.worker" in (out / "dask-workers.log").read_text()
    assert "INFO distributed" not in stderr  # Dask's chatter stays off the console
