"""Make the small real HDR panoramas the tests read (``tests/data/hdri``).

The tests need real HDR light (suns, lamps, 13-25 stops) on every clone, not
only where the larger shared set (``../shared/data/hdri``: eight CC0 HDRI Haven
panoramas by Greg Zaal, lat-long 1024x512) sits beside the checkout. This
script shrinks each shared panorama by an integer factor (default 4: 256x128)
and writes it as a half-float EXR with ZIP compression, about 0.1 MB each.

How: exact area averaging (:func:`~gaslight_usd.evaluation.resample.area_resize`)
keeps the image mean and every light's total power; a sun smaller than an
output pixel is spread over that pixel, as a lower-resolution camera would see
it, so the unclipped peaks drop (forest about 1000 -> 450) yet stay many stops
above the median. One exception keeps the clamp flags true: in the panoramas
whose brightest pixels were clamped (``SHARED_CLAMP_LEVELS``: city, interior and
sunrise at about 32000, studio at 100) an output pixel whose area holds a pixel
at or above half the clamp level takes that area's brightest pixel, as a smaller
camera would have clipped there too (the true sun is far above the clamp), so the
clamped core stays at the clamp level and is still found (and kept out of
light-source judgements) by
:meth:`~gaslight_usd.evaluation.reference.HDRSource.clamp_mask`. That core now
covers whole output pixels, so those panoramas hold more power than the clamped
originals (city, interior, sunrise: 2.4-3x the mean; studio 1.4x).

Run from the repository root (overwrites the files)::

    python tests/data/make_test_hdris.py [--source ../shared/data/hdri] [--factor 4]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gaslight_usd.errors import InputError
from gaslight_usd.evaluation.reference import SHARED_CLAMP_LEVELS
from gaslight_usd.evaluation.resample import area_resize
from gaslight_usd.imageio import read_image, write_exr

HERE = Path(__file__).resolve().parent
DEFAULT_SOURCE = HERE.parents[2] / "shared" / "data" / "hdri"
DEFAULT_OUT = HERE / "hdri"


def brightest_in_blocks(pixels: np.ndarray, factor: int) -> np.ndarray:
    """(H/f, W/f, C): the colour of the brightest pixel (by its largest channel, as
    ``clamp_mask`` measures) of each ``factor`` x ``factor`` block."""
    h, w, c = pixels.shape
    blocks = (pixels.reshape(h // factor, factor, w // factor, factor, c)
              .transpose(0, 2, 1, 3, 4).reshape(h // factor, w // factor, factor * factor, c))
    brightest = blocks.max(axis=-1).argmax(axis=-1)
    return np.take_along_axis(blocks, brightest[..., None, None], axis=2)[:, :, 0]


def shrink(pixels: np.ndarray, factor: int, clamp_level: float | None) -> np.ndarray:
    """Area-average ``pixels`` down by ``factor``; clamped cores keep their brightest pixel."""
    h, w = pixels.shape[:2]
    small = area_resize(pixels, h // factor, w // factor)
    if clamp_level is not None:
        peak = brightest_in_blocks(pixels, factor)
        clamped = peak.max(axis=-1) >= 0.5 * clamp_level
        small[clamped] = peak[clamped]
    return small


def make(source: Path, out: Path, factor: int) -> list[Path]:
    """Write the shrunk copy of every EXR in ``source`` into ``out``; returns the files."""
    files = sorted(source.glob("*.exr")) if source.is_dir() else []
    if not files:
        raise InputError("no EXR panoramas here", source)
    images = {path: read_image(path) for path in files}  # every file checked before writing
    for path, image in images.items():
        h, w = image.pixels.shape[:2]
        if h % factor or w % factor:
            raise InputError(f"{w}x{h} does not divide by the factor {factor}", path)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for path, image in images.items():
        pixels = np.maximum(image.pixels[..., :3], 0.0).astype(np.float32)
        small = shrink(pixels, factor, SHARED_CLAMP_LEVELS.get(path.stem))
        written.append(write_exr(
            out / path.name, small, image.colour_space, half=True, compression="zip",
            attributes={"Software": "gaslight2usd tests/data/make_test_hdris.py",
                        "ImageDescription": f"{path.name} (CC0, Greg Zaal, HDRI Haven) "
                                            f"area-averaged down {factor}x"}))
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", type=Path, default=DEFAULT_SOURCE,
                        help="folder of the full-size panoramas (default: ../shared/data/hdri)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument("--factor", type=int, default=4, help="integer shrink factor")
    args = parser.parse_args(argv)
    if args.factor < 1:
        parser.error(f"--factor must be a whole number >= 1, not {args.factor}")
    try:
        written = make(args.source, args.out, args.factor)
    except InputError as err:
        print(f"make_test_hdris: {err}", file=sys.stderr)
        return err.exit_code
    for path in written:
        small = read_image(path).pixels
        print(f"{path.name}: {small.shape[1]}x{small.shape[0]}, peak {small.max():.1f}, "
              f"median {np.median(small):.3f}, {path.stat().st_size // 1024} KiB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
