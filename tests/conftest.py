"""Shared fixtures: small real files written with the project's own writers, and the
small real HDR panoramas that ship with the project (``tests/data/hdri``)."""

from __future__ import annotations

import contextlib
import io
import subprocess
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest

REPO = Path(__file__).resolve().parents[1]
TEST_HDRI = REPO / "tests" / "data" / "hdri"
"""Eight CC0 panoramas, 256x128 half-float EXR, made from the shared set by
tests/data/make_test_hdris.py (see tests/data/README.md). Tests read these, never
../shared/data, so they run the same on every clone."""
EXAMPLE = REPO / "examples" / "room"
"""The bundled example (photos, true HDR views, true poses, probes)."""
needs_example = pytest.mark.skipif(not (EXAMPLE / "digests.json").exists(),
                                   reason="the bundled example examples/room is missing: "
                                          "it ships with the project (git checkout "
                                          "examples/room)")


def run_cli(*args: str) -> subprocess.CompletedProcess:
    """Run the CLI in this process (a subprocess costs seconds of imports)."""
    from gaslight_usd.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(args))
    return subprocess.CompletedProcess(args, code, out.getvalue(), err.getvalue())


def write_jpeg(path: Path, pixels_u8: np.ndarray, exposure_time: float | None = None,
               f_number: float | None = None, iso: int | None = None,
               orientation: int | None = None) -> Path:
    """An 8-bit JPEG with the given EXIF exposure fields, via OpenImageIO."""
    h, w, c = pixels_u8.shape
    spec = oiio.ImageSpec(w, h, c, oiio.UINT8)
    if exposure_time is not None:
        spec.attribute("ExposureTime", float(exposure_time))
    if f_number is not None:
        spec.attribute("FNumber", float(f_number))
    if iso is not None:
        spec.attribute("Exif:ISOSpeedRatings", int(iso))
    if orientation is not None:
        spec.attribute("Orientation", int(orientation))
    spec.attribute("Compression", "jpeg:95")
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec)
    assert out.write_image(np.ascontiguousarray(pixels_u8))
    out.close()
    return path


@pytest.fixture
def photo_folder(tmp_path: Path) -> Path:
    """Three textured 8-bit JPEGs a stop apart, with EXIF exposure."""
    folder = tmp_path / "photos"
    folder.mkdir()
    rng = np.random.default_rng(0)
    for i, t in enumerate([1 / 120, 1 / 60, 1 / 30]):
        img = (rng.random((48, 64, 3)) * 200).astype(np.uint8)
        img[:8, :8] = 255  # a clipped corner
        write_jpeg(folder / f"shot_{i}.jpg", img, exposure_time=t, f_number=4.0, iso=100)
    return folder


@pytest.fixture
def bundled_hdri(monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The bundled panoramas, also made the library's default HDR folder
    (``$GASLIGHT_HDRI_DIR``), so code that reads the default set (the uplift bench,
    ``shared_sources()``, the known clamp levels) reads them."""
    monkeypatch.setenv("GASLIGHT_HDRI_DIR", str(TEST_HDRI))
    yield TEST_HDRI


def write_posed_views(root: Path, with_points: bool):
    """Nine 48x48 HDR views of a small closed synthetic room (bright emitters inside)
    into ``root/hdr`` and their true COLMAP model into ``root/sparse`` (with sparse
    points from the truth, or none: the fit then triangulates). Returns (truth, cameras)."""
    from gaslight_usd.fit.synthetic import closed_scene, ring_cameras
    from gaslight_usd.imageio import write_exr
    from gaslight_usd.poses.colmap import ColmapModel, write_model
    from gaslight_usd.render import render

    truth, cams = closed_scene(), ring_cameras()
    (root / "hdr").mkdir()
    for cam in cams:
        write_exr(root / "hdr" / f"{cam.name[:-4]}.exr", render(truth, cam).image.numpy(),
                  "lin_rec709", {"gaslight:exposure_scale": 1.0}, half=False)
    points = truth.positions[::3] if with_points else None
    write_model(root / "sparse", ColmapModel(cameras=cams) if points is None else ColmapModel(
        cameras=cams, points=points, point_colours=np.full((len(points), 3), 128, np.uint8)))
    return truth, cams


@pytest.fixture(scope="session")
def posed_hdr_scene(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """:func:`write_posed_views` with sparse points: the cheapest real input a fit, an
    export and HDRIs run on (``hdr/``, ``sparse/``)."""
    root = tmp_path_factory.mktemp("posed_hdr")
    write_posed_views(root, with_points=True)
    return root
