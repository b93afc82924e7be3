"""PNG previews and the run's contact sheet: read back, pixels checked against the
OCIO display/view transform computed here independently."""

from __future__ import annotations

import numpy as np
import OpenImageIO as oiio
import PyOpenColorIO as OCIO
import pytest

from gaslight_usd.cli.main import main
from gaslight_usd.errors import EXIT_BAD_INPUT
from gaslight_usd.imageio import read_image, write_exr

CONFIG = "ocio://cg-config-latest"
PATCHES = np.array([[0.0, 0.0, 0.0], [0.18, 0.18, 0.18], [1.0, 1.0, 1.0], [8.0, 0.5, 0.1]],
                   np.float32)


def patches_exr(path):
    """Four 8x8 patches side by side, ACEScg."""
    pixels = np.repeat(np.repeat(PATCHES[None], 8, axis=0), 8, axis=1)
    return write_exr(path, pixels, "ACEScg", half=False)


def expected_codes(rgb, view):
    config = OCIO.Config.CreateFromFile(CONFIG)
    proc = config.getProcessor(OCIO.DisplayViewTransform(
        src="ACEScg", display="sRGB - Display", view=view)).getDefaultCPUProcessor()
    return np.array([np.rint(np.clip(proc.applyRGB([float(v) for v in c]), 0, 1) * 255)
                     for c in rgb])


def png_pixels(path):
    buf = oiio.ImageBuf(str(path))
    assert buf.spec().format == oiio.UINT8 and buf.file_format_name == "png"
    return np.asarray(buf.get_pixels(oiio.UINT8))


@pytest.mark.parametrize("view", ["ACES 2.0 - SDR 100 nits (Rec.709)", "Un-tone-mapped"])
def test_info_preview_is_the_display_view_transform_of_each_pixel(tmp_path, view):
    exr = patches_exr(tmp_path / "p.exr")
    png = tmp_path / "p.png"
    assert main(["info", str(exr), "--preview", str(png), "--view", view, "-q"]) == 0
    got = png_pixels(png)
    assert got.shape == (8, 32, 3)
    centres = got[4, 4::8].astype(float)
    np.testing.assert_allclose(centres, expected_codes(PATCHES, view), atol=1)
    if view == "Un-tone-mapped":  # sRGB encoding of 18 % grey: 0.4613 -> 118
        assert tuple(centres[1]) == (118, 118, 118)
        assert tuple(centres[2]) == (255, 255, 255)
    else:  # the ACES view rolls 1.0 off well below display white; the red lamp stays red
        assert centres[2].max() < 200 and centres[3, 0] > centres[3, 1] + 60


def test_hdri_preview_and_bad_preview_names(tmp_path, capsys):
    from gaslight_usd.ply import write_ply
    from gaslight_usd.splats import SplatScene

    rng = np.random.default_rng(0)
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ply = write_ply(tmp_path / "s.ply", SplatScene.from_activated(
        2 * d, np.full((200, 3), 0.4), np.full((200, 3), 0.4), np.full(200, 0.95)))
    png = tmp_path / "probe.png"
    assert main(["hdri", str(ply), "--at", "-0.2,0,0", "-o", str(tmp_path / "probe.exr"),
                 "--size", "32", "--preview", str(png), "-q"]) == 0
    lat = read_image(tmp_path / "probe.exr")
    shown = png_pixels(png)
    assert shown.shape == (16, 32, 3)
    view = "ACES 2.0 - SDR 100 nits (Rec.709)"
    sample = lat.pixels[8, 16:17]
    np.testing.assert_allclose(shown[8, 16:17].astype(float),
                               expected_codes(sample, view), atol=1)
    # Bad names fail before any work: nothing written.
    assert main(["hdri", str(ply), "-o", str(tmp_path / "q.exr"), "--preview",
                 str(tmp_path / "q.jpg")]) == EXIT_BAD_INPUT
    assert main(["info", str(ply), "--preview", str(tmp_path / "q.png")]) == EXIT_BAD_INPUT
    assert "draws images only" in capsys.readouterr().err
    assert not list(tmp_path.glob("q.*"))


def test_run_writes_a_contact_sheet_of_photos_and_hdr_views(photo_folder, tmp_path):
    out = tmp_path / "out"
    assert main(["run", str(photo_folder), "-o", str(out), "--to", "hdr",
                 "--method", "linear", "-q"]) == 0
    sheet = out / "contact-sheet.png"
    buf = oiio.ImageBuf(str(sheet))
    names = buf.spec().getattribute("ImageDescription").splitlines()
    assert names[1:] == ["shot_0.jpg", "shot_1.jpg", "shot_2.jpg",
                         "shot_0.exr", "shot_1.exr", "shot_2.exr"]
    pixels = png_pixels(sheet)
    # two rows (photos, HDR views) of three 240x120 cells with 4 px gaps
    assert pixels.shape == (4 + 2 * 124, 4 + 3 * 244, 3)
    # the first photo's thumbnail (48x64, shown at its size) is its display transform
    photo = read_image(photo_folder / "shot_0.jpg")
    from gaslight_usd import colour

    linear = colour.convert(photo.pixels, photo.colour_space, "ACEScg", CONFIG)
    row = 20
    want = expected_codes(linear[row, 10:14], "ACES 2.0 - SDR 100 nits (Rec.709)")
    np.testing.assert_allclose(pixels[4 + row, 4 + 10:4 + 14].astype(float), want, atol=1)
    # the first HDR view sits at the start of the second row
    hdr = read_image(out / "hdr" / "shot_0.exr")
    want = expected_codes(hdr.pixels[row, 10:14], "ACES 2.0 - SDR 100 nits (Rec.709)")
    np.testing.assert_allclose(pixels[4 + 124 + row, 4 + 10:4 + 14].astype(float), want,
                               atol=1)


def test_a_resumed_run_redraws_the_contact_sheet_only_when_a_file_changed(photo_folder,
                                                                          tmp_path):
    import os

    out = tmp_path / "out"
    args = ["run", str(photo_folder), "-o", str(out), "--to", "hdr", "--method", "linear", "-q"]
    assert main(args) == 0
    sheet = out / "contact-sheet.png"
    drawn = sheet.stat().st_mtime_ns
    assert main(args) == 0
    assert sheet.stat().st_mtime_ns == drawn  # nothing changed: not drawn again
    view = out / "hdr" / "shot_1.exr"
    os.utime(view, ns=(drawn + 10**9, drawn + 10**9))  # a view written after the sheet
    assert main(args) == 0
    assert sheet.stat().st_mtime_ns > drawn
    names = oiio.ImageBuf(str(sheet)).spec().getattribute("ImageDescription").splitlines()
    assert names[1:] == ["shot_0.jpg", "shot_1.jpg", "shot_2.jpg",
                         "shot_0.exr", "shot_1.exr", "shot_2.exr"]
