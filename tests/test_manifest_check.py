"""Manifest typos are errors (the schema's additionalProperties is applied), and the
project's own checker agrees with the reference ``jsonschema`` on the bundled schema."""

from __future__ import annotations

import json

import jsonschema
import pytest

from gaslight_usd.batch import load_manifest
from gaslight_usd.cli.main import main
from gaslight_usd.errors import EXIT_BAD_INPUT, InputError
from gaslight_usd.jsoncheck import bundled_schema, first_problem

GOOD = {"defaults": {"targets": ["hdr"], "options": {"fit": {"preset": "fast"}},
                     "colour": {"working_space": "ACEScg"}, "seed": 1},
        "scenes": [{"name": "a", "inputs": ["photos"], "choose": {"uplift": "uplift.linear"},
                    "probes": [[0, 1.5, 0]], "preset": "balanced", "camera_height": 1.6}]}

BAD = [
    ({**GOOD, "defualts": {}}, "(top level): unknown key 'defualts'", "'defaults'"),
    ({"defaults": {"opitons": {}}, "scenes": GOOD["scenes"]}, "defaults: unknown key 'opitons'",
     "'options'"),
    ({"scenes": [{"name": "a", "inputs": ["p"], "taregts": ["hdr"]}]},
     "scenes[0]: unknown key 'taregts'", "'targets'"),
    ({"scenes": [{"name": "a", "inputs": ["p"], "options": {"fti": {}}}]},
     "scenes[0].options: unknown key 'fti'", "'fit'"),
    ({"scenes": [{"name": "a", "inputs": ["p"], "colour": {"workingspace": "x"}}]},
     "scenes[0].colour: unknown key 'workingspace'", "'working_space'"),
    ({"scenes": [{"name": "a", "inputs": ["p"], "probes": [[0, 1.5]]}]},
     "scenes[0].probes[0]: needs at least 3 item(s)", None),
    ({"scenes": [{"name": "a", "inputs": ["p"], "preset": "fastest"}]},
     "scenes[0].preset: 'fastest' is not one of", None),
    ({"scenes": [{"name": "a", "inputs": ["p"], "camera_height": 0}]},
     "scenes[0].camera_height: 0 must be above 0", None),
    ({"scenes": [{"name": "a", "inputs": ["p"], "targets": ["usd", "hdrii"]}]},
     "scenes[0].targets[1]: 'hdrii' is not one of", None),
    ({"scenes": [{"name": "a b", "inputs": ["p"]}]}, "scenes[0].name: 'a b' does not match",
     None),
    ({"scenes": [{"inputs": ["p"]}]}, "scenes[0]: missing required key 'name'", None),
    ({"scenes": []}, "scenes: needs at least 1 item", None),
    ({"scenes": [{"name": "a", "inputs": ["p"], "seed": "1"}]},
     "scenes[0].seed: expected integer, got str", None),
]


def test_the_good_manifest_passes_both_checkers():
    schema = bundled_schema("manifest.schema.json")
    jsonschema.validate(GOOD, schema)
    assert first_problem(GOOD, schema) is None


@pytest.mark.parametrize(("doc", "message", "hint"), BAD)
def test_each_mistake_is_named_and_jsonschema_agrees(doc, message, hint):
    schema = bundled_schema("manifest.schema.json")
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(doc, schema)
    problem = first_problem(doc, schema)
    assert problem is not None and problem.startswith(message), problem
    if hint:
        assert f"did you mean {hint}?" in problem


def test_a_typo_stops_the_batch_before_any_work(tmp_path, capsys):
    (tmp_path / "photos").mkdir()
    manifest = tmp_path / "m.json"
    manifest.write_text(json.dumps({"defaults": {"opitons": {"fit": {"preset": "best"}}},
                                    "scenes": [{"name": "a", "inputs": ["photos"]}]}))
    with pytest.raises(InputError, match="m.json: defaults: unknown key 'opitons'"):
        load_manifest(manifest, tmp_path / "out")
    assert main(["batch", str(manifest), "-o", str(tmp_path / "out")]) == EXIT_BAD_INPUT
    assert "did you mean 'options'?" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("scene", [{"inputs": ["photos"], "options": "fast"},
                                   {"inputs": ["photos"], "choose": ["uplift.linear"]}])
def test_a_wrong_type_is_named_not_an_internal_error(tmp_path, scene):
    (tmp_path / "photos").mkdir()
    manifest = tmp_path / "m.json"
    manifest.write_text(json.dumps({"scenes": [{"name": "a", **scene}]}))
    with pytest.raises(InputError, match=r"scene 'a' \(scenes\[0\]\): key '\w+': expected "
                                         "object"):
        load_manifest(manifest, tmp_path / "out")
