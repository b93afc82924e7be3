"""The README's Python API example runs as written (it once raised AttributeError)."""

from __future__ import annotations

import contextlib
import io
import re

import numpy as np

from gaslight_usd.ply import write_ply
from gaslight_usd.splats import SplatScene

from .conftest import REPO


def readme_python_blocks() -> list[str]:
    text = (REPO / "README.md").read_text()
    section = text.split("## Python API", 1)[1]
    return re.findall(r"```python\n(.*?)```", section, flags=re.S)


def test_readme_python_example_runs_on_the_bundled_example(tmp_path, monkeypatch):
    blocks = readme_python_blocks()
    assert blocks, "the README lost its Python API example"
    (tmp_path / "examples" / "room").mkdir(parents=True)
    (tmp_path / "examples" / "room" / "photos").symlink_to(REPO / "examples/room/photos")
    colours = np.array([[0.2, 0.3, 0.4], [6.0, 5.0, 4.0]])
    write_ply(tmp_path / "splats.ply", SplatScene.from_activated(
        np.zeros((2, 3)), colours, np.full((2, 3), 0.1), np.full(2, 0.9), sh_degree=1))
    monkeypatch.chdir(tmp_path)
    printed = io.StringIO()
    namespace: dict = {}
    with contextlib.redirect_stdout(printed):
        for block in blocks:
            exec(compile(block, "README.md", "exec"), namespace)  # noqa: S102
    photos = sorted((REPO / "examples/room/photos").glob("*.jpg"))
    views = sorted((tmp_path / "out" / "hdr").glob("*.exr"))
    assert [v.stem for v in views] == [p.stem for p in photos]
    assert str(namespace["artifacts"][namespace["Kind"].HDR_VIEWS].path) == "out/hdr"
    count, degree, peak = printed.getvalue().split()
    assert (int(count), int(degree)) == (2, 1)
    assert abs(float(peak) - 6.0) < 1e-4
