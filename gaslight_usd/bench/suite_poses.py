"""Bench suite "poses": SfM on the bundled example against its true poses.

Each row is one full solve (features, matching, mapping; wall seconds on this
machine) followed by a similarity (Umeyama) alignment of the solved camera
centres onto the true ones. Errors: median rotation error (degrees) and
median centre error as a share of the scene size (the diagonal of the room's
bounding box from scene.json). Quick mode solves the 14 photos once (a subset
leaves too little overlap to register); the full run tries several matcher /
camera-model settings. With ``--megapixels`` (e.g. 12) the photos are also
enlarged to that size (pixels replicated, EXIF kept: :mod:`.suite_scale`) and
solved with features extracted at each of :data:`EXTRACTION_SIZES`, beside the
photos as shot: the measurement behind the presets' SfM sizes
(:data:`gaslight_usd.fit.presets.SFM_IMAGE_SIZES`).
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import GaslightError, InputError
from ..imageio import LDR_EXTENSIONS, list_images
from ..locate import example_room
from ..poses import read_poses
from ..poses.frame import align_and_compare, sfm_frame
from ..poses.sfm import SfmOptions, solve_poses

NAME = "poses"
DESCRIPTION = "structure from motion on the bundled example vs its true poses"
X = ("seconds", "seconds per solve (wall, whole SfM)")
Y = ("median_rotation_error_deg", "median rotation error after alignment (degrees)")
HIGHER_IS_BETTER = False

EXAMPLE = example_room()
FULL_SETTINGS = [("exhaustive", "SIMPLE_RADIAL"), ("exhaustive", "PINHOLE"),
                 ("sequential", "SIMPLE_RADIAL")]
QUICK_SETTINGS = [("exhaustive", "PINHOLE")]
EXTRACTION_SIZES = (640, 1024, 1600)
"""Long sides (pixels) the enlarged photos' features are extracted at."""


def _scene_size(example: Path) -> float:
    room = json.loads((example / "scene.json").read_text())["room"]
    return float(np.linalg.norm(np.subtract(room["max"], room["min"])))


def solve_and_score(photos: list[Path], truth_dir: Path, matcher: str, camera_model: str,
                    seed: int = 0, scene_size: float | None = None, **sfm: Any
                    ) -> dict[str, Any]:
    """One SfM solve of ``photos``, scored against the true model in ``truth_dir``;
    ``sfm``: further :class:`SfmOptions` (e.g. ``max_image_size``)."""
    truth = read_poses(truth_dir)
    keep = {p.name for p in photos}
    truth.cameras = [c for c in truth.cameras if c.name in keep]
    truth.image_ids, truth.camera_ids, truth.intrinsics = [], [], {}
    truth.__post_init__()
    row: dict[str, Any] = {"method": "pycolmap-sfm", "setting": f"{matcher}/{camera_model}",
                           "photos": len(photos)}
    t0 = time.perf_counter()
    try:
        result = solve_poses(photos, SfmOptions(matcher=matcher, camera_model=camera_model,
                                                seed=seed, min_registered=0.0, **sfm))
        cmp = align_and_compare(sfm_frame(result.model), truth, scene_size=scene_size)
    except InputError as exc:  # too few registered to align: a failed row, not a crash
        return {**row, "registered": 0, "seconds": round(time.perf_counter() - t0, 3),
                "median_rotation_error_deg": float("nan"),
                "median_centre_error_rel": float("nan"), "error": str(exc)}
    return {
        **row,
        "registered": len(result.registered),
        "points": len(result.model.points),
        "seconds": round(result.seconds, 3),
        "median_rotation_error_deg": cmp["median_rotation_error_deg"],
        "max_rotation_error_deg": cmp["max_rotation_error_deg"],
        "median_centre_error_rel": cmp["median_centre_error_rel"],
        "max_centre_error_rel": cmp["max_centre_error_rel"],
        "median_centre_error_m": cmp["median_centre_error"],
        "scene_size_m": cmp["scene_size"],
        **{k: v for k, v in result.stats.items()
           if k.endswith("_s") or k == "keypoints_median"},
    }


def run(options: dict) -> list[dict]:
    example = Path(options.get("example", EXAMPLE))
    if not (example / "scene.json").exists():
        raise GaslightError(f"the poses suite needs the bundled example scene at {example} "
                            "(python examples/make_room.py)")
    photos = list_images(example / "photos", LDR_EXTENSIONS)
    quick = bool(options.get("quick"))
    size = _scene_size(example)
    seed = int(options.get("seed", 0))
    if options.get("megapixels"):
        return size_rows(example, photos, options["megapixels"],
                         Path(options.get("out") or ".") / "photos", seed, size)
    return [solve_and_score(photos, example / "sparse" / "0", matcher, model,
                            seed=seed, scene_size=size)
            for matcher, model in (QUICK_SETTINGS if quick else FULL_SETTINGS)]


def size_rows(example: Path, photos: list[Path], megapixels: list[float], store: Path,
              seed: int, scene_size: float) -> list[dict[str, Any]]:
    """The photos as shot, then enlarged to each size and solved at each extraction size
    (exhaustive matching, SIMPLE_RADIAL: what ``run`` uses)."""
    from .suite_scale import photo_size, upscale_photos

    truth = example / "sparse" / "0"
    rows = [{**solve_and_score(photos, truth, "exhaustive", "SIMPLE_RADIAL", seed=seed,
                               scene_size=scene_size), "megapixels": 0.17,
             "max_image_size": 0}]
    for mp in megapixels:
        w, h = photo_size(mp)
        big = upscale_photos(example / "photos", store / f"{w}x{h}", w, h)
        for extract in EXTRACTION_SIZES:
            row = solve_and_score(big, truth, "exhaustive", "SIMPLE_RADIAL", seed=seed,
                                  scene_size=scene_size, max_image_size=extract)
            rows.append({**row, "setting": f"{w}x{h}, features at {extract}",
                         "megapixels": round(w * h / 1e6, 2), "max_image_size": extract})
    rows[0]["setting"] = "480x360 as shot"
    return rows
