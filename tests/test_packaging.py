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
