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
    assert 12 <= len(photos) <= 16
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
def test_script_regenerates_the_scene(tmp_path):
    """Renders everything again (a few minutes on 2 cores) and compares with the committed files.

    Poses are compared exactly; pixels within render-noise tolerances. Regeneration was
    bit-for-bit (every SHA-256 equal) in 3 of 4 runs on this machine but not in one, so
    bit-exactness is reported, not asserted (see the issue note).
    """
    from gaslight_usd.evaluation.relight import load_mitsuba

    if "llvm" not in load_mitsuba().variant():
        pytest.skip("regeneration needs Mitsuba's llvm_ad_rgb (Debian libllvm19)")
    out = tmp_path / "room"
    res = subprocess.run([sys.executable, str(ROOT / "make_room.py"), "--out", str(out)],
                         capture_output=True, text=True, timeout=1200)
    assert res.returncode == 0, res.stderr[-2000:]
    expected = json.loads((ROOM / "digests.json").read_text())
    assert sorted(json.loads((out / "digests.json").read_text())) == sorted(expected)
    same = [rel for rel, digest in expected.items() if sha256(out / rel) == digest]
    print(f"bit-identical files: {len(same)} of {len(expected)}")
    for rel in expected:
        new, old = out / rel, ROOM / rel
        if rel.startswith("sparse/"):
            assert new.read_bytes() == old.read_bytes(), rel
        elif rel.endswith(".jpg"):
            # Auto-exposure may land a third of a stop apart: compare exposure-normalised.
            a, b = (read_image(p, to_space="lin_rec709") for p in (new, old))
            a_px, b_px = a.pixels / a.exposure.relative, b.pixels / b.exposure.relative
            ok = (a.pixels < 0.9) & (b.pixels < 0.9) & (b.pixels > 0.02)
            # 8-bit quantisation + render noise: ~5% median; a 1/3-stop slip would be 26%.
            assert np.median(np.abs(a_px[ok] - b_px[ok]) / b_px[ok]) < 0.1, rel
        elif rel.endswith(".exr"):
            a, b = read_image(new).pixels, read_image(old).pixels
            rel_err = np.abs(a - b) / np.maximum(np.abs(b), 1e-3)
            assert np.median(rel_err) < 0.03, rel
