"""Small scenes for ``gaslight2usd batch``: subsets of the bundled room, true poses.

Scene ``k`` holds the room's photos ``view_i`` with ``i % N == k`` (four photos
around the room for N = 6) and the true COLMAP model of just those cameras, so
a batch of N scenes runs the whole chain (uplift, fit, USD with the light rig,
HDRIs) in minutes on a laptop CPU. Writes ``OUT/<scene>/photos``,
``OUT/<scene>/sparse`` and the manifest ``OUT/batch.toml``::

    python examples/batch/make_scenes.py /tmp/scenes --scenes 6
    gaslight2usd batch /tmp/scenes/batch.toml -o /tmp/lighting --jobs 2

docs/measurements.md ("batch") times such a batch.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from gaslight_usd.poses.colmap import ColmapModel, read_model, write_model

ROOM = Path(__file__).resolve().parents[1] / "room"

MANIFEST = """\
# {count} scenes of the bundled room (examples/batch/make_scenes.py): small on purpose
[defaults]
targets = ["splats", "usd", "hdri"]
preset = "fast"
probes = [[0.0, 1.5, 0.0], [1.5, 1.2, -1.0]]
colour = {{ working_space = "ACEScg" }}
[defaults.options.fit]
iterations = {iterations}
budget = {budget}
[defaults.options.export]
dome_width = 64
[defaults.options.hdri]
size = {hdri_size}
"""


def make_scenes(out: Path, count: int = 6, iterations: int = 60, budget: int = 1500,
                hdri_size: int = 128) -> Path:
    """Write ``count`` scenes and their manifest under ``out``; return the manifest."""
    model = read_model(ROOM / "sparse" / "0")
    cameras = sorted(model.cameras, key=lambda c: c.name)
    text = MANIFEST.format(count=count, iterations=iterations, budget=budget,
                           hdri_size=hdri_size)
    for k in range(count):
        name = f"room_{k}"
        picked = cameras[k::count]
        photos = out / name / "photos"
        photos.mkdir(parents=True, exist_ok=True)
        for cam in picked:
            shutil.copy2(ROOM / "photos" / cam.name, photos / cam.name)
        write_model(out / name / "sparse", ColmapModel(cameras=picked, frame=model.frame))
        text += f'\n[[scenes]]\nname = "{name}"\nphotos = "{name}/photos"\n' \
                f'poses = "{name}/sparse"\n'
    manifest = out / "batch.toml"
    manifest.write_text(text)
    return manifest


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--scenes", type=int, default=6)
    parser.add_argument("--iterations", type=int, default=60, help="fit steps per scene")
    parser.add_argument("--budget", type=int, default=1500, help="most splats per scene")
    parser.add_argument("--hdri-size", type=int, default=128, help="lat-long width")
    args = parser.parse_args()
    print(make_scenes(args.out, args.scenes, args.iterations, args.budget, args.hdri_size))


if __name__ == "__main__":
    main()
