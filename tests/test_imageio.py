import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import OpenImageIO as oiio
import pytest
from conftest import write_jpeg

from gaslight_usd.atomic import atomic_path
from gaslight_usd.errors import InputError
from gaslight_usd.imageio import list_images, read_image, write_exr


def test_exr_round_trip_keeps_values_and_metadata(tmp_path):
    rng = np.random.default_rng(0)
    pixels = (rng.random((16, 24, 3)) * 1000).astype(np.float32)
    path = write_exr(tmp_path / "a.exr", pixels, "ACEScg",
                     {"gaslight:method": "test", "gaslight:exposure_scale": 2.5})
    back = read_image(path)
    np.testing.assert_allclose(back.pixels, pixels, rtol=1e-3)  # half precision
    assert back.colour_space == "ACEScg"
    assert back.metadata["gaslight:method"] == "test"
    assert back.metadata["gaslight:exposure_scale"] == pytest.approx(2.5)
    chroma = back.metadata["chromaticities"]
    np.testing.assert_allclose(chroma, [0.713, 0.293, 0.165, 0.83, 0.128, 0.044, 0.32168, 0.33767],
                               atol=1e-6)
    assert oiio.ImageBuf(str(path)).spec().format == oiio.HALF


def test_exr_switches_to_float_above_half_range(tmp_path):
    pixels = np.full((4, 4, 3), 1.0e6, np.float32)
    path = write_exr(tmp_path / "bright.exr", pixels, "lin_rec709")
    assert oiio.ImageBuf(str(path)).spec().format == oiio.FLOAT
    assert read_image(path).pixels.max() == pytest.approx(1.0e6)


def test_ev_from_exif_written_to_jpeg(tmp_path):
    img = np.full((8, 8, 3), 128, np.uint8)
    path = write_jpeg(tmp_path / "x.jpg", img, exposure_time=1 / 50, f_number=2.8, iso=400)
    exposure = read_image(path).exposure
    # EXIF stores rationals: allow their rounding
    assert exposure.exposure_time == pytest.approx(1 / 50, rel=1e-4)
    assert exposure.f_number == pytest.approx(2.8, rel=1e-4)
    assert exposure.iso == pytest.approx(400)
    # EV relative to ISO 100, f/1, 1 s: log2(t * iso/100 / N^2)
    assert exposure.ev == pytest.approx(np.log2((1 / 50) * 4 / 2.8**2), abs=1e-3)


def test_exif_orientation_is_honoured(tmp_path):
    img = np.zeros((10, 20, 3), np.uint8)
    img[0, 0] = 255  # marker at top-left of the stored raster
    path = write_jpeg(tmp_path / "rot.jpg", img, orientation=6)  # rotate 90 CW to display
    pixels = read_image(path).pixels
    assert pixels.shape[:2] == (20, 10)
    assert pixels[0, -1].mean() > 0.5  # stored top-left shows at displayed top-right


def test_sixteen_bit_tiff_is_read_with_full_precision(tmp_path):
    values = np.linspace(0, 65535, 64, dtype=np.uint16).reshape(4, 16, 1).repeat(3, axis=2)
    spec = oiio.ImageSpec(16, 4, 3, oiio.UINT16)
    path = tmp_path / "deep.tif"
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), spec)
    out.write_image(values)
    out.close()
    pixels = read_image(path).pixels
    np.testing.assert_allclose(pixels, values / 65535.0, atol=1e-6)


def test_nan_in_exr_is_refused_naming_the_file(tmp_path):
    pixels = np.ones((4, 4, 3), np.float32)
    pixels[1, 2, 0] = np.nan
    path = tmp_path / "nan.exr"
    spec = oiio.ImageSpec(4, 4, 3, oiio.FLOAT)
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), spec)
    out.write_image(pixels)
    out.close()
    with pytest.raises(InputError) as err:
        read_image(path)
    assert "nan.exr" in str(err.value) and "NaN" in str(err.value)


def test_unreadable_and_missing_files(tmp_path):
    bad = tmp_path / "broken.jpg"
    bad.write_bytes(b"not a jpeg at all")
    with pytest.raises(InputError, match="broken.jpg"):
        read_image(bad)
    with pytest.raises(InputError, match="no such file"):
        read_image(tmp_path / "missing.exr")


def test_empty_folder_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="holds no images"):
        list_images(tmp_path)


def test_failed_write_leaves_nothing(tmp_path):
    final = tmp_path / "out.exr"
    with pytest.raises(RuntimeError):
        with atomic_path(final) as tmp:
            tmp.write_bytes(b"half of a file")
            raise RuntimeError("killed mid-write")
    assert not final.exists()
    assert list(tmp_path.iterdir()) == []


def test_killed_writer_process_leaves_no_final_file(tmp_path):
    """A writer killed by SIGKILL mid-write never produces the final name."""
    final = tmp_path / "big.ply"
    script = textwrap.dedent(f"""
        import sys, time
        from gaslight_usd.atomic import atomic_path
        with atomic_path({str(final)!r}) as tmp:
            with open(tmp, "wb") as f:
                f.write(b"x" * 1000)
                f.flush()
                print("writing", flush=True)
                time.sleep(30)
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE)
    assert proc.stdout.readline().strip() == b"writing"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not final.exists()


def test_jpeg_quality_is_read_from_the_quantisation_tables(tmp_path):
    """Written by OpenImageIO (libjpeg) at a quality, read back within one step; not a
    JPEG or a damaged table: None."""
    from gaslight_usd.imageio import jpeg_quality

    pixels = np.random.default_rng(0).uniform(0, 255, (32, 32, 3)).astype(np.uint8)
    for quality in (30, 50, 75, 93):
        path = tmp_path / f"q{quality}.jpg"
        spec = oiio.ImageSpec(32, 32, 3, oiio.UINT8)
        spec.attribute("Compression", f"jpeg:{quality}")
        out = oiio.ImageOutput.create(str(path))
        assert out.open(str(path), spec) and out.write_image(pixels)
        out.close()
        assert abs(jpeg_quality(path) - quality) <= 1
    data = (tmp_path / "q30.jpg").read_bytes()
    dqt = data.index(b"\xff\xdb")
    (tmp_path / "cut.jpg").write_bytes(data[:dqt + 30])
    assert jpeg_quality(tmp_path / "cut.jpg") is None
    (tmp_path / "x.png").write_bytes(b"\x89PNG\r\n")
    assert jpeg_quality(tmp_path / "x.png") is None
