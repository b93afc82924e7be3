"""The tradeoff page (``gaslight2usd bench --suite tradeoff``): built from the runner's real
JSON reports, opened in headless Chromium, and the committed example rebuilt."""

from __future__ import annotations

import math
import re
import shutil
import subprocess
import types
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from conftest import REPO, run_cli

from gaslight_usd.bench.runner import run_suite
from gaslight_usd.bench.tradeoff_page import build_page, load_reports, points_of

CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium"
                                         if Path("/usr/bin/chromium").exists() else None)
DOCS = REPO / "docs" / "tradeoff"


def _suite(name: str, rows: list[dict], higher: bool = True) -> types.ModuleType:
    """A bench suite module (the runner's contract) whose run returns ``rows``."""
    module = types.ModuleType(f"suite_{name}")
    module.NAME, module.DESCRIPTION = name, f"{name} for the page test"
    module.X, module.Y = ("seconds", "seconds (s)"), ("psnr", "PSNR (dB)")
    module.HIGHER_IS_BETTER = higher
    module.REFERENCES = ("oracle",)
    module.run = lambda options: rows
    return module


@pytest.fixture
def reports(tmp_path: Path) -> Path:
    rows = [{"method": "fast one", "setting": "a", "seconds": 1.0, "psnr": 20.0},
            {"method": "slow good", "setting": "b", "seconds": 10.0, "psnr": 30.0},
            {"method": "slow bad", "setting": "c", "seconds": 12.0, "psnr": 15.0},
            {"method": "oracle", "setting": "", "seconds": 0.5, "psnr": 40.0}]
    run_suite(_suite("alpha", rows), {}, tmp_path)
    run_suite(_suite("beta", [{"method": "m", "setting": "x", "seconds": 2.0,
                               "psnr": math.nan}]), {}, tmp_path)
    return tmp_path


def test_points_front_and_references(reports):
    alpha = next(r for r in load_reports([reports]) if r["suite"] == "alpha")
    pts = {p["label"]: p for p in points_of(alpha)}
    assert pts["fast one · a"]["front"] and pts["slow good · b"]["front"]
    assert not pts["slow bad · c"]["front"]  # slower and worse than "slow good"
    assert pts["oracle"]["reference"] and not pts["oracle"]["front"]
    assert (pts["slow good · b"]["x"], pts["slow good · b"]["y"]) == (10.0, 30.0)


def test_page_holds_labelled_charts_and_tables_and_nothing_remote(reports):
    page = build_page(load_reports([reports]), "gaslight2usd bench --suite tradeoff -o X")
    assert page.count("<svg") == 2 and page.count("<table>") == 2
    for label in ("fast one · a", "slow good · b", "slow bad · c", "oracle"):
        assert f">{label}</text>" in page  # every point labelled in the chart
    assert "<td>slow good</td><td>b</td><td>1</td><td>10</td><td>30</td>" in page
    assert page.count('stroke="#c0392b" stroke-width="2"') == 2  # two points ringed
    assert "no point with both values" in page  # beta: Y is NaN everywhere
    assert not re.search(r"(src|href)=\"(https?:)?//", page)
    assert "<script" not in page
    assert build_page(load_reports([reports]), "c") == build_page(load_reports([reports]), "c")


def test_suite_writes_index_html_and_needs_results(reports, tmp_path):
    out = tmp_path / "page"
    res = run_cli("bench", "--suite", "tradeoff", "--from", str(reports), "-o", str(out))
    assert res.returncode == 0, res.stderr
    page = (out / "index.html").read_text()
    assert f"--from {reports} -o {out}" in page
    empty = run_cli("bench", "--suite", "tradeoff", "-o", str(tmp_path / "none"))
    assert empty.returncode != 0
    assert "no bench results" in empty.stdout + empty.stderr


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed "
                    "(apt-get install -y chromium; .ci/run installs it)")
def test_page_renders_in_headless_chromium(reports, tmp_path):
    page = tmp_path / "index.html"
    page.write_text(build_page(load_reports([reports]), "c"))
    shot = tmp_path / "shot.png"
    subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                    "--no-first-run", "--disable-background-networking",
                    "--disable-component-update", "--disable-sync",
                    f"--user-data-dir={tmp_path / 'profile'}", "--window-size=900,700",
                    f"--screenshot={shot}", page.as_uri()],
                   check=True, capture_output=True, timeout=120)
    image = oiio.ImageBuf(str(shot))
    pixels = image.get_pixels(oiio.FLOAT)[..., :3]
    assert pixels.shape[:2] == (700, 900)
    dark = (pixels.mean(axis=2) < 0.5).mean()
    blue = ((pixels[..., 2] > 0.6) & (pixels[..., 0] < 0.35)).sum()  # the chart's points
    assert 0.005 < dark < 0.5, dark  # text and axes drawn, not a black page
    assert blue > 50, blue
    assert float(pixels.std()) > 0.05


def test_committed_page_matches_a_fresh_build():
    page = DOCS / "index.html"
    if not page.exists():
        pytest.fail("docs/tradeoff/index.html is missing")
    first = page.read_text().split("<code>", 1)[1].split("</code>", 1)[0]
    sources = [REPO / s for s in re.findall(r"--from (\S+)", first)]
    assert sources and all(s.is_dir() for s in sources)
    rebuilt = build_page(load_reports(sources), first)
    assert rebuilt == page.read_text()
    assert np.all([(s / "stability.json").exists() or (s / "budget.json").exists()
                   for s in sources])


def test_reports_of_one_suite_are_joined(reports, tmp_path):
    more = tmp_path / "more"
    run_suite(_suite("alpha", [{"method": "other", "setting": "z", "seconds": 0.2,
                                "psnr": 25.0}]), {}, more)
    (more / "alpha.json").rename(more / "alpha-other.json")
    joined = {r["suite"]: r for r in load_reports([reports, more])}
    labels = [p["label"] for p in points_of(joined["alpha"])]
    assert labels == ["fast one · a", "slow good · b", "slow bad · c", "oracle", "other · z"]
    fronts = {p["label"]: p["front"] for p in points_of(joined["alpha"])}
    assert fronts["other · z"] and not fronts["fast one · a"]  # 0.2 s at 25 dB beats it
