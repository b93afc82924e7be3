"""The README's picture: what the chain makes of the bundled example's photos.

    gaslight2usd run examples/room/photos --poses examples/room/sparse \\
        --at 1.5,1.2,-1.0 -o out
    python examples/readme_figure.py out -o docs/readme-figure.png

Top row: one photo (the lamp clipped to white), the HDR view the uplift made of
it and the true radiance behind it, both shown 5 stops darker so the lamp's
core is visible. Lower rows: the lat-long HDRI the splats give at the probe
point beside the true probe there (``examples/room/probes``), at the set's
exposure and 8 stops darker. Every image goes through the OCIO config's default
display and view; each is first scaled so that its median luminance is 0.18,
so images on different scales (relative and absolute radiance) compare by eye.
Needs matplotlib (``pip install ".[test]"``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from gaslight_usd import colour
from gaslight_usd.imageio import Image, read_image
from gaslight_usd.preview import to_display

EXAMPLE = Path(__file__).resolve().parent / "room"
VIEW = "view_08"
"""A level view that frames the lamp and the window."""


def shown(pixels: np.ndarray, space: str, stops: float) -> np.ndarray:
    """Display-encoded RGB: scaled so the median luminance is 0.18, then by 2 ** stops."""
    luminance = pixels[..., :3] @ np.asarray(colour.REC709_Y, np.float32)
    median = float(np.median(luminance[luminance > 0])) if np.any(luminance > 0) else 1.0
    return to_display(pixels, space, exposure_ev=float(np.log2(0.18 / median)) + stops)


def probe_point(hdri: Image) -> tuple[float, float, float]:
    """The position an HDRI was rendered at (its ``gaslight:probePosition``)."""
    value = hdri.metadata.get("gaslight:probePosition")
    if value is None:
        raise SystemExit(f"{hdri.path}: no gaslight:probePosition attribute")
    return tuple(float(v) for v in np.ravel(value))


def nearest_true_probe(point: tuple[float, float, float]) -> tuple[Path, float]:
    listing = json.loads((EXAMPLE / "probes" / "probes.json").read_text())["probes"]
    dists = [float(np.linalg.norm(np.subtract(p["position"], point))) for p in listing]
    best = int(np.argmin(dists))
    return EXAMPLE / "probes" / listing[best]["name"], dists[best]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path, help="a `gaslight2usd run` output folder")
    parser.add_argument("-o", "--output", type=Path, default=Path("docs/readme-figure.png"))
    args = parser.parse_args()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    photo = read_image(EXAMPLE / "photos" / f"{VIEW}.jpg")
    uplift = read_image(args.run / "hdr" / f"{VIEW}.exr")
    truth = read_image(EXAMPLE / "truth" / f"{VIEW}.exr")
    hdri = sorted((args.run / "hdri").glob("*.exr"))
    hdri = [p for p in hdri if ".cube" not in p.name]
    if not hdri:
        raise SystemExit(f"{args.run / 'hdri'}: no lat-long HDRI")
    fitted = read_image(hdri[0])
    true_path, dist = nearest_true_probe(probe_point(fitted))
    if dist > 0.05:
        raise SystemExit(f"{hdri[0]} is {dist:.2f} m from the nearest true probe: run with "
                         "--poses examples/room/sparse --at 1.5,1.2,-1.0")
    true_probe = read_image(true_path)

    fig = plt.figure(figsize=(9.6, 7.2), dpi=100)
    grid = fig.add_gridspec(3, 6, height_ratios=[1.0, 1.0, 1.0])
    top = [(photo, "photo (8-bit JPEG): lamp and window clip", None),
           (uplift, "its HDR view from the uplift, -5 stops", -5.0),
           (truth, "the true radiance, -5 stops", -5.0)]
    for i, (image, title, stops) in enumerate(top):
        ax = fig.add_subplot(grid[0, 2 * i:2 * i + 2])
        # the photo is shown as the camera encoded it; the HDR images through OCIO
        ax.imshow(np.clip(image.pixels, 0.0, 1.0) if stops is None
                  else shown(image.pixels, image.colour_space, stops))
        ax.set_title(title, fontsize=9)
        ax.axis("off")
    for row, stops in ((1, 0.0), (2, -8.0)):
        for col, (image, title) in enumerate(((fitted, "HDRI from the splats"),
                                              (true_probe, "true probe"))):
            ax = fig.add_subplot(grid[row, 3 * col:3 * col + 3])
            ax.imshow(shown(image.pixels, image.colour_space, stops))
            ax.set_title(f"{title}, {stops:+g} stops" if stops else title, fontsize=9)
            ax.axis("off")
    fig.tight_layout()
    args.output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.output)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
