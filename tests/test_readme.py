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


def test_readme_figure_script_draws_a_run_beside_the_truth(tmp_path):
    """``examples/readme_figure.py`` (the README's picture) on a run folder made of the
    example's own truth: a view as the uplift's HDR view, the true probe as the HDRI."""
    import json
    import subprocess
    import sys

    import OpenImageIO as oiio

    from gaslight_usd.imageio import read_image, write_exr

    room = REPO / "examples" / "room"
    run = tmp_path / "run"
    view = read_image(room / "truth" / "view_08.exr")
    write_exr(run / "hdr" / "view_08.exr", view.pixels, view.colour_space)
    probe = read_image(room / "probes" / "probe_1.exr")
    where = next(p["position"] for p in json.loads((room / "probes" / "probes.json")
                                                   .read_text())["probes"]
                 if p["name"] == "probe_1.exr")
    write_exr(run / "hdri" / "probe_000.exr", probe.pixels, probe.colour_space,
              {"gaslight:probePosition": [float(v) for v in where]})
    out = tmp_path / "figure.png"
    res = subprocess.run([sys.executable, str(REPO / "examples" / "readme_figure.py"),
                          str(run), "-o", str(out)], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    spec = oiio.ImageInput.open(str(out)).spec()
    assert (spec.width, spec.height) == (960, 720)
    # an HDRI far from every true probe is refused, not drawn beside the wrong one
    write_exr(run / "hdri" / "probe_000.exr", probe.pixels, probe.colour_space,
              {"gaslight:probePosition": [0.0, 0.5, 1.9]})
    res = subprocess.run([sys.executable, str(REPO / "examples" / "readme_figure.py"),
                          str(run), "-o", str(tmp_path / "other.png")], capture_output=True,
                         text=True, timeout=120)
    assert res.returncode != 0 and "from the nearest true probe" in res.stderr
    assert not (tmp_path / "other.png").exists()
