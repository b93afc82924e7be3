"""Where a run's lights lie against a generated room's true ones (issue 17's done-when).

For a scene folder written by ``make_room.py`` (``photos/``, true poses in
``sparse/0``, ``scene.json`` with the room's bounds and lights) and a run's output
folder: runs ``gaslight2usd run SCENE/photos -o OUT`` first when ``OUT/splats.ply``
is missing (SfM poses, default settings; extra arguments go to ``run``), aligns the
run's cameras onto the true ones (a similarity), and reports in the true frame
(metres): the default probe, the emitter splats outside the room, each true light's
nearest emitter, and the lights the export writes (:func:`gaslight_usd.lights.search_lights`)
with how far each lies outside the room::

    python examples/check_lights.py examples/room /tmp/run_example
    python examples/check_lights.py SCENE OUT --preset fast

SfM is not deterministic here: two runs on the same photos can register different
photo sets, so compare rules on one run's ``splats.ply``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from gaslight_usd.bench.suite_chain import emitter_distance, scene_lights
from gaslight_usd.lights import search_lights
from gaslight_usd.ply import read_ply
from gaslight_usd.poses import read_poses
from gaslight_usd.poses.frame import align_and_compare, split_similarity
from gaslight_usd.probe import default_probe

MARGIN = 0.05
"""Metres outside the room's box that count as outside (SfM alignment error)."""


def main(folder: Path, out: Path, run_args: list[str]) -> None:
    if not (out / "splats.ply").exists():
        subprocess.run([sys.executable, "-m", "gaslight_usd.cli.main", "run",
                        str(folder / "photos"), "-o", str(out), "-q", *run_args], check=True)
    info = json.loads((folder / "scene.json").read_text())
    lo, hi = np.array(info["room"]["min"]), np.array(info["room"]["max"])
    cmp = align_and_compare(read_poses(out / "sparse"), read_poses(folder / "sparse" / "0"))
    s, rot, t = split_similarity(cmp["similarity"])

    def to_true(p: np.ndarray) -> np.ndarray:
        return (s * (rot @ np.asarray(p, np.float64).reshape(-1, 3).T)).T + t

    def beyond(p: np.ndarray) -> np.ndarray:
        return np.max(np.maximum(lo - p, p - hi), axis=-1)

    print(f"poses: median rotation error {cmp['median_rotation_error_deg']:.2f} deg, "
          f"centre error {cmp['median_centre_error_rel']:.4f} of the spread, scale {s:.3f}")
    scene = read_ply(out / "splats.ply")
    probe = to_true(default_probe(scene).position)[0]
    print("default probe", probe.round(2), "inside the room:", bool(beyond(probe) <= 0))
    found = search_lights(scene)
    em = to_true(scene.positions[found.emitters])
    # where the instancer writes them: moved where the evidence says (lights.py step 6)
    put = to_true(found.positions[found.emitters]) if len(em) else np.zeros((0, 3))
    print(f"emitters {len(em)}, outside the room by > {MARGIN} m: "
          f"{int((beyond(em) > MARGIN).sum()) if len(em) else 0} as fitted, "
          f"{int((beyond(put) > MARGIN).sum()) if len(put) else 0} as the instancer writes them")
    print("photos' word:", {k: v for k, v in found.counts.items()
                            if k in ("unseen_not_lights", "placed_by_outlines")})
    truth = scene_lights(info)
    for light in truth:
        d = emitter_distance(light, em).min() if len(em) else np.inf
        d_put = emitter_distance(light, put).min() if len(put) else np.inf
        print(f"  {light['name']}: nearest emitter {d:.3f} m as fitted, {d_put:.3f} m as "
              "written")
    pts = to_true(np.array([light.position for light in found.lights])) if found.lights \
        else np.zeros((0, 3))
    near = [min(float(emitter_distance(li, p[None])[0]) for li in truth) for p in pts]
    for p, light, d in zip(pts, found.lights, near, strict=True):
        print(f"  light at {p.round(2)} radius {light.radius * s:.3f} m, {d:.2f} m from the "
              f"nearest true light, {max(float(beyond(p)), 0.0):.2f} m outside")
    out_by = beyond(pts) if len(pts) else np.zeros(0)
    print(f"SUMMARY lights {len(pts)}; within 0.3 m of a true light "
          f"{sum(d < 0.3 for d in near)}; outside the room by > {MARGIN} m "
          f"{int((out_by > MARGIN).sum())} (by {np.round(out_by[out_by > MARGIN], 2).tolist()} m)")


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3:])
