"""Pictures a person can look at: PNG previews through an OCIO display/view transform.

Scene-linear EXRs are not pictures: a viewer that shows them raw clips the
lamps and shows the rest too dark or too bright. A preview sends the pixels
through the config's display/view transform (default: the config's default
display and view, for the built-in config 'sRGB - Display' with the ACES 2.0
SDR view), so highlights roll off as a colourist would see them, and writes an
8-bit PNG. A contact sheet puts many such thumbnails on one PNG, a row per
group (the photos, the HDR views, the HDRIs), in the order given; the file
names are kept in the PNG's ``Description`` text, one per line, in that order.

The photos, HDR views and HDRIs of a run share one scale (relative radiance:
1.0 is photo white at the set's reference exposure), so all are shown at the
same exposure and can be compared by eye.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import PyOpenColorIO as OCIO

from . import colour
from .atomic import atomic_path
from .errors import GaslightError, InputError
from .imageio import read_image
from .resize import area_resize

THUMB_HEIGHT = 120
COLUMNS = 8
GAP = 4
BACKGROUND = 0.12


@dataclass(frozen=True)
class DisplayView:
    """An OCIO display and view; None picks the config's defaults."""

    display: str | None = None
    view: str | None = None

    def resolved(self, config_uri: str) -> tuple[str, str]:
        config = colour.load_config(config_uri)
        display = self.display or config.getDefaultDisplay()
        if display not in list(config.getDisplays()):
            raise InputError(f"unknown OCIO display {display!r}; choose from "
                             + ", ".join(config.getDisplays()))
        view = self.view or config.getDefaultView(display)
        if view not in list(config.getViews(display)):
            raise InputError(f"unknown view {view!r} of display {display!r}; choose from "
                             + ", ".join(config.getViews(display)))
        return display, view


@lru_cache(maxsize=16)
def _display_processor(uri: str, src: str, display: str, view: str) -> OCIO.CPUProcessor:
    transform = OCIO.DisplayViewTransform(src=src, display=display, view=view)
    proc = colour.load_config(uri).getProcessor(transform)
    return proc.getOptimizedCPUProcessor(OCIO.OPTIMIZATION_DEFAULT)


def to_display(pixels: np.ndarray, space: str, config_uri: str | None = None,
               display_view: DisplayView = DisplayView(), exposure_ev: float = 0.0
               ) -> np.ndarray:
    """Scene-linear ``(H, W, 3)`` in ``space`` -> display-encoded floats in [0, 1]."""
    uri = colour.resolve_config_uri(config_uri)
    src = colour.resolve_space(space, uri)
    display, view = display_view.resolved(uri)
    out = np.ascontiguousarray(pixels[..., :3], dtype=np.float32) * np.float32(2.0 ** exposure_ev)
    flat = out.reshape(-1, 3)
    _display_processor(uri, src, display, view).apply(
        OCIO.PackedImageDesc(flat, flat.shape[0], 1, 3))
    return np.clip(np.nan_to_num(out, nan=0.0), 0.0, 1.0)


def resize_to_height(pixels: np.ndarray, height: int) -> np.ndarray:
    """Area-averaged shrink keeping the aspect (done in linear light, before display)."""
    h, w = pixels.shape[:2]
    width = max(1, round(w * height / h))
    return area_resize(np.ascontiguousarray(pixels[..., :3], dtype=np.float32), width, height)


def write_png(path: str | Path, display_rgb: np.ndarray, description: str = "") -> Path:
    """Write display-encoded ``[0, 1]`` RGB as an 8-bit PNG, atomically."""
    path = Path(path)
    data = np.rint(np.clip(display_rgb, 0.0, 1.0) * 255.0).astype(np.uint8)
    h, w = data.shape[:2]
    spec = oiio.ImageSpec(w, h, 3, oiio.UINT8)
    if description:
        spec.attribute("ImageDescription", description)
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            raise GaslightError(f"cannot write PNG: {oiio.geterror()}", path)
        ok = out.write_image(np.ascontiguousarray(data))
        out.close()
        if not ok:
            raise GaslightError("cannot write PNG", path)
    return path


def contact_sheet(groups: Sequence[Sequence[np.ndarray]], thumb_height: int = THUMB_HEIGHT,
                  columns: int = COLUMNS, gap: int = GAP) -> np.ndarray:
    """Display-encoded thumbnails laid out in cells ``2 * thumb_height`` wide.

    Each group starts a new row and wraps after ``columns`` cells; each image
    sits at the top-left of its cell. Returns ``(H, W, 3)`` floats in [0, 1].
    """
    cell_w, cell_h = 2 * thumb_height, thumb_height
    rows = [list(group[i:i + columns]) for group in groups if group
            for i in range(0, len(group), columns)]
    if not rows:
        raise ValueError("a contact sheet needs at least one image")
    width = gap + max(len(r) for r in rows) * (cell_w + gap)
    height = gap + len(rows) * (cell_h + gap)
    sheet = np.full((height, width, 3), BACKGROUND, np.float32)
    for r, row in enumerate(rows):
        y = gap + r * (cell_h + gap)
        for c, thumb in enumerate(row):
            x = gap + c * (cell_w + gap)
            h, w = min(thumb.shape[0], cell_h), min(thumb.shape[1], cell_w)
            sheet[y:y + h, x:x + w] = thumb[:h, :w]
    return sheet


def thumbnail(path: Path, config_uri: str, working_space: str, input_space: str,
              display_view: DisplayView, thumb_height: int, exposure_ev: float = 0.0
              ) -> np.ndarray:
    """One file as a display-encoded thumbnail ``thumb_height`` high.

    The pixels are first box-shrunk as stored to twice the thumbnail (a 12 MP photo
    converted whole would hold several full-size float copies at once), then
    linearised and shrunk the rest of the way.
    """
    image = read_image(path, ldr_space=input_space, config_uri=config_uri)
    h, w = image.pixels.shape[:2]
    scale = min(1.0, 2 * thumb_height / h)
    stored = area_resize(image.pixels, max(1, round(w * scale)), max(1, round(h * scale)))
    space = image.colour_space
    del image  # the full-size pixels go before the conversion allocates
    linear = colour.convert(stored, space, working_space, config_uri)
    small = resize_to_height(linear, min(thumb_height, h))
    return to_display(small, working_space, config_uri, display_view, exposure_ev)


def write_contact_sheet(path: str | Path, groups: Sequence[Sequence[Path]],
                        config_uri: str | None = None,
                        working_space: str = colour.DEFAULT_WORKING_SPACE,
                        input_space: str = colour.DEFAULT_INPUT_SPACE,
                        display_view: DisplayView = DisplayView(),
                        thumb_height: int = THUMB_HEIGHT, exposure_ev: float = 0.0) -> Path:
    """Read every file of every group, and write them as one contact-sheet PNG."""
    uri = colour.resolve_config_uri(config_uri)
    display, view = display_view.resolved(uri)
    thumbs = [[thumbnail(p, uri, working_space, input_space, display_view, thumb_height,
                         exposure_ev) for p in group] for group in groups]
    names = "\n".join(str(p.name) for group in groups for p in group)
    description = f"gaslight2usd contact sheet; OCIO {display} / {view}\n{names}"
    return write_png(path, contact_sheet(thumbs, thumb_height), description)


CONTACT_SHEET = "contact-sheet.png"


def latlong_hdris(folder: Path) -> list[Path]:
    """The lat-long EXRs of an HDRI folder (not the cube maps or their faces)."""
    if folder.is_file():
        return [folder] if folder.suffix.lower() == ".exr" else []
    return sorted(p for p in folder.glob("*.exr")
                  if len(p.suffixes) == 1 and not p.name.startswith("."))


def sheet_is_current(sheet: Path, files: Sequence[Path]) -> bool:
    """Whether ``sheet`` shows exactly ``files`` (its description lists their names)
    and was drawn after every one of them was written."""
    try:
        drawn = sheet.stat().st_mtime_ns
        if any(Path(p).stat().st_mtime_ns > drawn for p in files):
            return False
        image = oiio.ImageInput.open(str(sheet))
        if image is None:
            return False
        description = str(image.spec().getattribute("ImageDescription") or "")
        image.close()
    except OSError:
        return False
    return description.split("\n")[1:] == [Path(p).name for p in files]


def run_contact_sheet(out_dir: Path, photos: Sequence[Path], hdr_views: Sequence[Path],
                      hdris: Sequence[Path], settings) -> Path | None:
    """``OUT/contact-sheet.png`` of a run's photos, HDR views and HDRIs (None if none)."""
    groups = [list(g) for g in (photos, hdr_views, hdris) if g]
    if not groups:
        return None
    sheet = Path(out_dir) / CONTACT_SHEET
    if sheet_is_current(sheet, [p for g in groups for p in g]):
        return sheet  # a resumed run that changed nothing
    return write_contact_sheet(sheet, groups, settings.ocio_config,
                               settings.working_space, settings.input_space)


def write_preview(path: str | Path, images: Sequence[Path], config_uri: str | None = None,
                  working_space: str = colour.DEFAULT_WORKING_SPACE,
                  input_space: str = colour.DEFAULT_INPUT_SPACE,
                  display_view: DisplayView = DisplayView()) -> Path:
    """One image as a full-size PNG, or several as a contact sheet."""
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise InputError("a preview is a .png file", path)
    if len(images) != 1:
        return write_contact_sheet(path, [list(images)], config_uri, working_space,
                                   input_space, display_view)
    uri = colour.resolve_config_uri(config_uri)
    display, view = display_view.resolved(uri)
    image = read_image(images[0], ldr_space=input_space, config_uri=uri)
    linear = colour.convert(image.pixels, image.colour_space, working_space, uri)
    shown = to_display(linear, working_space, uri, display_view)
    return write_png(path, shown, f"{images[0].name}; OCIO {display} / {view}")
