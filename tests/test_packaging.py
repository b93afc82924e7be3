"""The distribution installs gaslight_usd only: no bare top-level `converters`/`schemas`."""

from importlib.metadata import distribution
from importlib.resources import files


def test_no_bare_top_level_modules():
    dist = distribution("gaslight-usd")
    tops = {str(f).split("/")[0] for f in dist.files or []}
    assert "converters" not in tops and "schemas" not in tops
    top_level = dist.read_text("top_level.txt")
    if top_level is not None:  # written by regular (non-editable) installs
        assert set(top_level.split()) <= {"gaslight_usd"}


def test_converters_install_inside_the_package():
    assert files("gaslight_usd.converters").joinpath("uplift_linear.py").is_file()


def test_every_subpackage_is_installed():
    """pyproject lists packages explicitly: a new subpackage must be added there."""
    import importlib.util
    from pathlib import Path

    source = Path(__file__).resolve().parents[1] / "gaslight_usd"
    for init in source.glob("*/__init__.py"):
        name = f"gaslight_usd.{init.parent.name}"
        assert importlib.util.find_spec(name) is not None, f"{name} is not installed"
