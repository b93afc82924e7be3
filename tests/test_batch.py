import json
import subprocess
import sys
from importlib.resources import files
from pathlib import Path

import jsonschema
import pytest

from gaslight_usd.batch import load_manifest, run_batch
from gaslight_usd.errors import InputError

CLI = [str(Path(sys.executable).with_name("gaslight2usd"))]


def schema(name: str) -> dict:
    return json.loads(files("gaslight_usd.schemas").joinpath(name).read_text())


def write_manifest(tmp_path, photo_folder, extra=None):
    manifest = {
        "defaults": {"targets": ["hdr"], "settings": {"working_space": "ACEScg"}},
        "scenes": [
            {"name": "good", "inputs": [str(photo_folder.relative_to(tmp_path))]},
            {"name": "empty", "inputs": ["empty"]},
            *(extra or []),
        ],
    }
    (tmp_path / "empty").mkdir(exist_ok=True)
    (tmp_path / "empty" / "notes.txt").write_text("no photos here")
    path = tmp_path / "shots.json"
    path.write_text(json.dumps(manifest))
    jsonschema.validate(manifest, schema("manifest.schema.json"))
    return path


def test_batch_runs_every_scene_and_reports_failures(tmp_path, photo_folder):
    manifest = write_manifest(tmp_path, photo_folder)
    out = tmp_path / "out"
    res = subprocess.run([*CLI, "batch", manifest, "-o", out, "--json", "-q"],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 1  # one scene failed
    report = json.loads(res.stdout)
    by_name = {s["name"]: s for s in report["scenes"]}
    assert by_name["good"]["status"] == "done"
    assert by_name["empty"]["status"] == "failed"
    assert "holds no photos" in by_name["empty"]["error"]
    assert len(list((out / "good" / "hdr").glob("*.exr"))) == 3
    scene_report = json.loads((out / "good" / "report.json").read_text())
    jsonschema.validate(scene_report, schema("report.schema.json"))
    assert json.loads((out / "batch-report.json").read_text())["done"] == 1


def test_batch_resumes_finished_scenes(tmp_path, photo_folder):
    manifest = write_manifest(tmp_path, photo_folder)
    jobs = [(n, j) for n, j in load_manifest(manifest, tmp_path / "out") if n == "good"]
    run_batch(jobs, tmp_path / "out", quiet=True)
    jobs = [(n, j) for n, j in load_manifest(manifest, tmp_path / "out") if n == "good"]
    run_batch(jobs, tmp_path / "out", quiet=True)
    stages = json.loads((tmp_path / "out" / "good" / "report.json").read_text())["stages"]
    assert [s["status"] for s in stages] == ["resumed"]


@pytest.mark.parametrize("bad, message", [
    ({"scenes": []}, "non-empty 'scenes'"),
    ({"scenes": [{"name": "a"}]}, "needs 'inputs'"),
    ({"scenes": [{"name": "a", "inputs": ["nowhere"]}]}, "missing input"),
    ({"scenes": [{"name": "a", "inputs": ["."], "targets": ["gold"]}]}, "unknown targets"),
])
def test_bad_manifests_name_the_problem(tmp_path, bad, message):
    path = tmp_path / "m.json"
    path.write_text(json.dumps(bad))
    with pytest.raises(InputError, match=message) as err:
        load_manifest(path, tmp_path / "out")
    assert "m.json" in str(err.value)
