"""The bundled example scene: intact, self-consistent, and regenerated bit-for-bit."""

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gaslight_usd.colmap import read_model
from gaslight_usd.imageio import read_image

ROOT = Path(__file__).resolve().parents[1] / "examples"
ROOM = ROOT / "room"


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_committed_files_match_their_digests():
    digests = json.loads((ROOM / "digests.json").read_text())
    assert len(digests) >= 12 + 12 + 3  # photos, truths, probes at least
    for rel, digest in digests.items():
        assert sha256(ROOM / rel) == digest, rel


def test_photos_truths_and_poses_agree():
    """Each photo is its truth exposed by EXIF time * K, clipped, sRGB-encoded."""
    scene = json.loads((ROOM / "scene.json").read_text())
    model = read_model(ROOM / "sparse" / "0")
    photos = sorted((ROOM / "photos").glob("*.jpg"))
    assert len(photos) == len(scene["views"]) >= 12
    assert sorted(c.name for c in model.cameras) == [p.name for p in photos]
    k = scene["exposure"]["K"]
    photo = read_image(photos[0], to_space="lin_rec709")
    truth = read_image(ROOM / "truth" / f"{photos[0].stem}.exr").pixels
    assert photo.pixels.shape == truth.shape == (360, 480, 3)
    exposed = truth * photo.exposure.exposure_time * k
    unclipped = (exposed.max(axis=-1) < 0.9) & (exposed.min(axis=-1) > 0.02)
    ratio = np.median(photo.pixels[unclipped] / exposed[unclipped])
    assert ratio == pytest.approx(1.0, abs=0.03)
    assert (photo.pixels >= 0.99).any()  # the lamp is clipped
    assert truth.max() > 100 * np.median(truth)  # ...and far brighter than the walls


def test_verify_checks_projections_and_probes():
    res = subprocess.run([sys.executable, str(ROOT / "make_room.py"), "--verify"],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "verify: OK" in res.stdout


@pytest.mark.slow
def test_script_regenerates_the_scene_bit_for_bit(tmp_path):
    """Renders everything again (a few minutes on 2 cores) and compares every SHA-256."""
    from gaslight_usd.evaluation.relight import load_mitsuba

    scene = json.loads((ROOM / "scene.json").read_text())
    if "llvm" not in load_mitsuba().variant():
        pytest.skip("bit-exact regeneration needs Mitsuba's llvm_ad_rgb (Debian libllvm19)")
    assert "llvm" in json.dumps(scene)  # the committed files were made with that variant
    out = tmp_path / "room"
    res = subprocess.run([sys.executable, str(ROOT / "make_room.py"), "--out", str(out)],
                         capture_output=True, text=True, timeout=1200)
    assert res.returncode == 0, res.stderr[-2000:]
    expected = json.loads((ROOM / "digests.json").read_text())
    assert json.loads((out / "digests.json").read_text()) == expected
    for rel, digest in expected.items():
        assert sha256(out / rel) == digest, rel
