"""Print how our lat-long HDRI and Mitsuba's volprim_rf_basic compare (run by hand).

    python tests/consumers/mitsuba_numbers.py

Uses the scene and helpers of tests/test_consumers_mitsuba.py, then one splat
at a time on a face centre, 30 degrees off axis, on a seam and on a cube
corner, at several angular sizes: the light each renderer puts on the sphere.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import test_consumers_mitsuba as t  # noqa: E402

from gaslight_usd.ply import write_ply  # noqa: E402
from gaslight_usd.render.envmap import render_latlong  # noqa: E402
from gaslight_usd.splats import SplatScene  # noqa: E402


def main() -> None:
    mi = t._mitsuba()
    folder = Path(tempfile.mkdtemp())
    scene, dirs = t.probe_scene()
    ply = write_ply(folder / "splats.ply", scene)
    ours = render_latlong(scene, t.PROBE, t.WIDTH)
    mit = t.mitsuba_latlong(mi, ply, t.WIDTH)
    masks = t.windows(dirs, t.WIDTH, 5 * t.SIGMA_DEG)
    ratio = (t.window_power(ours, masks) @ t.LUMA) / (t.window_power(mit, masks) @ t.LUMA)
    shift = t.angle_deg(t.window_centroid(ours, masks), t.window_centroid(mit, masks))
    print(f"{len(dirs)} splats, sigma {t.SIGMA_DEG} deg, {t.OFF_AXIS_DEG} deg off a face axis, "
          f"lat-long {t.WIDTH} wide")
    print(f"  light ours/Mitsuba: median {np.median(ratio):.4f}, min {ratio.min():.4f}, "
          f"max {ratio.max():.4f}")
    print(f"  centroid ours vs Mitsuba: median {np.median(shift):.3f} deg, max {shift.max():.3f}")
    print("one splat (opacity 0.9, 3 m), light ours / Mitsuba by angular sigma:")
    sizes = (1.0, 2.0, 4.0, 8.0)
    print("  " + " " * 16 + "".join(f"{s:>8.1f}" for s in sizes))
    places = {"face centre": [0, 0, 1.0], "30 deg off axis": [np.tan(np.radians(30)), 0, 1],
              "seam (45 deg)": [1, 0, 1.0], "cube corner": [1, 1, 1.0]}
    for name, d in places.items():
        d = np.array(d) / np.linalg.norm(d)
        row = []
        for sigma in sizes:
            one = SplatScene.from_activated(t.PROBE[None] + 3 * d[None], np.ones((1, 3)),
                                            np.full((1, 3), 3 * np.radians(sigma)),
                                            np.full(1, 0.9))
            path = write_ply(folder / "one.ply", one)
            mask = t.windows(d[None], t.WIDTH, min(5 * sigma, 60))
            a = t.window_power(render_latlong(one, t.PROBE, t.WIDTH), mask)[0, 0]
            b = t.window_power(t.mitsuba_latlong(mi, path, t.WIDTH), mask)[0, 0]
            row.append(a / b)
        print(f"  {name:16s}" + "".join(f"{r:8.3f}" for r in row))


if __name__ == "__main__":
    main()
