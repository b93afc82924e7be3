"""One converter contract: typed options, defaults in one place, unknown options refused."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from gaslight_usd.chain import ChainRun
from gaslight_usd.errors import UsageError
from gaslight_usd.export_options import HdriOptions, UsdExportOptions
from gaslight_usd.kinds import Artifact, Kind
from gaslight_usd.registry import (
    Converter,
    Registry,
    StageResult,
    default_registry,
    option_names,
    options_from,
)


def test_every_builtin_converter_declares_typed_options():
    for conv in default_registry():
        if conv.name.split(".")[0] in ("uplift", "poses", "fit", "export"):
            assert conv.options is not None, conv.name
            conv.options()  # every field has a default


def test_options_from_keeps_defaults_for_none_and_maps_keys():
    o = options_from(UsdExportOptions, {"as": ["rig"], "palette_tolerance": None, "half": True})
    assert o.forms == ["rig"] and o.half is True
    assert o.palette_tolerance == UsdExportOptions.palette_tolerance
    assert "as" in option_names(UsdExportOptions) and "forms" not in option_names(UsdExportOptions)


def test_unknown_options_are_errors_naming_them():
    reg = default_registry()
    reg.check_options("hdri", {"size": 64, "cube": True})
    with pytest.raises(UsageError, match="unknown hdri option.*colour_size"):
        reg.check_options("hdri", {"colour_size": 64})
    # a step's options go to whichever converter runs: a bracket option is known to uplift
    reg.check_options("uplift", {"response": "debevec", "predictor": "fast", "max_size": 0})
    with pytest.raises(UsageError, match="iteration"):
        reg.check_options("fit", {"iteration": 5})


def test_a_plugin_without_declared_options_takes_any(tmp_path):
    @dataclass
    class Typed:
        n: int = 1

    def run(ctx):
        return StageResult(metadata={"seen": dict(ctx.options)})

    typed = Converter("x.typed", (Kind.SPLATS,), Kind.USD, run, "typed", "x", options=Typed)
    loose = Converter("x.loose", (Kind.SPLATS,), Kind.USD, run, "loose", "x", priority=-1)
    with pytest.raises(UsageError):
        Registry([typed]).check_options("x", {"m": 2})
    Registry([typed, loose]).check_options("x", {"m": 2})


def test_a_chain_refuses_an_unknown_option_before_any_work(tmp_path):
    ply = tmp_path / "s.ply"
    ply.write_text("not read: the options are checked first")
    out = tmp_path / "out"
    with pytest.raises(UsageError, match="unknown export option"):
        ChainRun(out).run([Artifact(Kind.SPLATS, ply)], [Kind.USD],
                          options={"export": {"palette_tolerence": 0.2}})
    assert not out.exists()


def test_cli_defaults_are_the_dataclass_defaults():
    from gaslight_usd.cli.main import build_parser

    export = build_parser("export").parse_args(["export", "s.ply", "-o", "scene.usda"])
    assert export.palette_tolerance == UsdExportOptions.palette_tolerance
    assert export.rig_tolerance == UsdExportOptions.rig_tolerance
    assert export.dome_size == UsdExportOptions.dome_width
    hdri = build_parser("hdri").parse_args(["hdri", "s.ply", "-o", "p.exr"])
    assert hdri.size == HdriOptions.size
