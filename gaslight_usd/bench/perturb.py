"""What real captures get wrong, made from a generated scene's true radiance.

A scene from ``examples/make_room.py`` holds every view's absolute radiance and its
camera (``photo = clip(radiance x t x K)``, sRGB OETF, 8-bit JPEG with EXIF). Each
perturbation re-makes the photo set (and, where it matters, the poses) from that truth
with one thing wrong, at a strength; ``gaslight2usd bench --suite stability`` runs the
chain on it. Strengths are listed mildest first: a break point is the first strength
that breaks.

Kinds (strength unit):

* ``photos`` -- only this many photos, evenly spread over the set;
* ``noise`` -- sensor noise, std ``s x sqrt(x + 0.01)`` of the linear value ``x``;
* ``jpeg`` -- JPEG quality;
* ``white_balance`` -- per-photo red and blue gains, log2 std in stops;
* ``exposure`` -- per-photo exposure off what the EXIF says, std in stops;
* ``motion_blur`` -- horizontal blur, length in pixels of the photo's width;
* ``light_half_out`` -- photos cropped to 2/3 width with the brightest light on the
  crop's edge (views where it sits in the middle are dropped); strength 1;
* ``light_one_view`` -- only one photo sees the brightest light; strength 1;
* ``no_clip`` -- this share of the photos exposed so that nothing clips;
* ``clipped_frames`` -- this many photos exposed 8 stops over (all but black clips);
* ``pose_noise`` -- poses rotated by this std (degrees) and moved by 1 cm per degree.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..imageio import read_image
from ..poses import read_poses, write_poses
from ..poses.colmap import ColmapModel
from .dark_frames import write_linear_photo

KINDS: dict[str, tuple[float, ...]] = {
    "photos": (12, 8, 4),
    "noise": (0.02, 0.05, 0.1),
    "jpeg": (60, 30, 10),
    "white_balance": (0.1, 0.3, 0.6),
    "exposure": (0.33, 1.0, 2.0),
    "motion_blur": (5, 15, 31),
    "light_half_out": (1,),
    "light_one_view": (1,),
    "no_clip": (0.5, 1.0),
    "clipped_frames": (2, 6, 12),
    "pose_noise": (0.5, 1.0, 2.0),
}
"""Each kind's strengths, mildest first (the full sweep)."""

CLIPPED_STOPS = 8.0
NO_CLIP_PEAK = 0.9
CROP_WIDTH = 2 / 3


@dataclass(frozen=True)
class Capture:
    photos: Path
    poses: Path
    note: str
    """What was changed, in words (e.g. the views dropped)."""


@dataclass
class _View:
    cam: Any
    photo: Path
    radiance: np.ndarray
    gain: float
    """Linear photo value per unit of radiance (t x K)."""
    shutter: float


def brightest_light(lights: list[dict[str, Any]]) -> dict[str, Any]:
    """The light of highest radiance (the one that clips)."""
    return max(lights, key=lambda li: float(np.max(li["radiance"])))


def sees(cam: Any, point: np.ndarray) -> tuple[bool, np.ndarray]:
    """Whether ``point`` projects inside ``cam``'s frame, and where."""
    uv, z = cam.project(point[None])
    u, v = uv[0]
    return bool(z[0] > 0 and 0 <= u < cam.width and 0 <= v < cam.height), uv[0]


def box_blur_rows(image: np.ndarray, length: int) -> np.ndarray:
    """Mean over ``length`` pixels along each row (edge pixels repeated)."""
    if length <= 1:
        return image
    half = length // 2
    padded = np.pad(image, ((0, 0), (half, length - 1 - half), (0, 0)), mode="edge")
    csum = np.cumsum(padded, axis=1, dtype=np.float64)
    csum = np.concatenate([np.zeros_like(csum[:, :1]), csum], axis=1)
    return ((csum[:, length:] - csum[:, :-length]) / length).astype(np.float32)


def _rotation(axis_angle: np.ndarray) -> np.ndarray:
    angle = float(np.linalg.norm(axis_angle))
    if angle == 0:
        return np.eye(3)
    k = axis_angle / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx


def make_capture(folder: Path, dst: Path, kind: str, strength: float, seed: int = 0,
                 lights: list[dict[str, Any]] | None = None) -> Capture:
    """Write ``dst/photos`` and ``dst/sparse`` for ``kind`` at ``strength`` (``kind``
    ``none``: the photos re-made as shot, the unperturbed baseline)."""
    if kind != "none" and kind not in KINDS:
        raise KeyError(f"unknown perturbation {kind!r}; choose from {', '.join(KINDS)}")
    info = json.loads((folder / "scene.json").read_text())
    k_cam = float(info["exposure"]["K"])
    f_number = float(info["exposure"]["FNumber"])
    model = read_poses(folder / "sparse" / "0")
    rng = np.random.default_rng(seed)
    views = []
    for cam in model.cameras:
        photo = folder / "photos" / cam.name
        radiance = read_image(folder / "truth" / (Path(cam.name).stem + ".exr")).pixels
        entry = next(v for v in info["views"] if v["name"] == cam.name)
        t = float(entry["exposure_time"])
        views.append(_View(cam, photo, radiance.astype(np.float32), t * k_cam, t))
    light = brightest_light(lights) if lights else None
    quality, note = 93, "as shot"
    make = _KIND_MAKERS.get(kind)
    if make is not None:
        views, quality, note = make(views, strength, rng, light)
    photos, sparse = dst / "photos", dst / "sparse"
    photos.mkdir(parents=True, exist_ok=True)
    for v in views:
        write_linear_photo(photos / v.cam.name, v.radiance * np.float32(v.gain),
                           (v.shutter, f_number), v.photo, quality)
    kept = ColmapModel(cameras=[v.cam for v in views], points=model.points,
                       point_colours=model.point_colours, frame=model.frame)
    write_poses(sparse, kept)
    return Capture(photos, sparse, note)


Maker = Callable[[list[_View], float, np.random.Generator, dict | None],
                 tuple[list[_View], int, str]]


def _photos(views, s, rng, light):
    keep = np.unique(np.linspace(0, len(views) - 1, int(s)).round().astype(int))
    return [views[i] for i in keep], 93, f"{len(keep)} of {len(views)} photos"


def _noise(views, s, rng, light):
    for v in views:
        x = v.radiance * np.float32(v.gain)
        noisy = x + rng.standard_normal(x.shape).astype(np.float32) * np.float32(s) * np.sqrt(
            np.maximum(x, 0) + np.float32(0.01))
        v.radiance = noisy / np.float32(v.gain)
    return views, 93, f"noise std {s:g} x sqrt(x + 0.01)"


def _jpeg(views, s, rng, light):
    return views, int(s), f"JPEG quality {int(s)}"


def _white_balance(views, s, rng, light):
    for v in views:
        r, b = 2.0 ** (rng.standard_normal(2) * s)
        v.radiance = v.radiance * np.array([r, 1.0, b], np.float32)
    return views, 93, f"red/blue gains with log2 std {s:g}"


def _exposure(views, s, rng, light):
    offsets = rng.standard_normal(len(views)) * s
    for v, d in zip(views, offsets, strict=True):
        v.gain *= float(2.0 ** d)
    return views, 93, f"exposure off the EXIF by std {s:g} stops (max {abs(offsets).max():.2f})"


def _motion_blur(views, s, rng, light):
    for v in views:
        v.radiance = box_blur_rows(v.radiance, int(s))
    return views, 93, f"horizontal motion blur over {int(s)} px"


def edge_crop(cam: Any, point: np.ndarray, share: float = CROP_WIDTH) -> int | None:
    """The first column of a crop ``share`` of ``cam``'s width wide with ``point`` on its
    left or right edge (the middle columns when ``cam`` does not see ``point``); None
    when no such crop holds it on an edge (it sits in the middle)."""
    width = int(round(cam.width * share))
    seen, (u, _) = sees(cam, point)
    if not seen:
        return (cam.width - width) // 2
    if u <= cam.width - width:
        return int(round(u))
    if u >= width:
        return int(round(u)) - width
    return None


def _light_half_out(views, s, rng, light):
    if light is None:
        return views, 93, "no light given"
    centre = np.asarray(light["center"], np.float64)
    out, dropped = [], 0
    for v in views:
        x0 = edge_crop(v.cam, centre)
        if x0 is None:
            dropped += 1
            continue
        width = int(round(v.cam.width * CROP_WIDTH))
        v.radiance = v.radiance[:, x0:x0 + width]
        v.cam = dataclasses.replace(v.cam, width=width, cx=v.cam.cx - x0)
        out.append(v)
    return out, 93, (f"cropped to {CROP_WIDTH:.2f} width, {light['name']} on the crop's edge; "
                     f"{dropped} view(s) with it in the middle dropped")


def _light_one_view(views, s, rng, light):
    if light is None:
        return views, 93, "no light given"
    centre = np.asarray(light["center"], np.float64)
    seeing = [i for i, v in enumerate(views) if sees(v.cam, centre)[0]]
    keep_one = min(seeing, key=lambda i: abs(sees(views[i].cam, centre)[1][0]
                                             - views[i].cam.cx)) if seeing else None
    out = [v for i, v in enumerate(views) if i not in seeing or i == keep_one]
    return out, 93, f"{light['name']} in 1 photo ({len(seeing) - 1} others dropped)"


def _no_clip(views, s, rng, light):
    count = int(round(s * len(views)))
    for i in np.linspace(0, len(views) - 1, count).round().astype(int) if count else []:
        v = views[i]
        peak = float(v.radiance.max())
        scale = min(1.0, NO_CLIP_PEAK / max(peak * v.gain, 1e-12))
        v.gain *= scale
        v.shutter *= scale
    return views, 93, f"{count} photo(s) exposed so nothing clips"


def _clipped_frames(views, s, rng, light):
    count = min(int(s), len(views))
    for i in np.linspace(0, len(views) - 1, count).round().astype(int):
        views[i].gain *= 2.0 ** CLIPPED_STOPS
        views[i].shutter *= 2.0 ** CLIPPED_STOPS
    return views, 93, f"{count} photo(s) exposed {CLIPPED_STOPS:g} stops over"


def _pose_noise(views, s, rng, light):
    for v in views:
        d_rot = _rotation(np.radians(rng.standard_normal(3) * s))
        centre = v.cam.center + rng.standard_normal(3) * 0.01 * s
        rot = d_rot @ v.cam.R
        v.cam = dataclasses.replace(v.cam, R=rot, t=-rot @ centre)
    return views, 93, f"poses rotated by std {s:g} deg, moved by std {s:g} cm"


_KIND_MAKERS: dict[str, Maker] = {
    "photos": _photos, "noise": _noise, "jpeg": _jpeg, "white_balance": _white_balance,
    "exposure": _exposure, "motion_blur": _motion_blur, "light_half_out": _light_half_out,
    "light_one_view": _light_one_view, "no_clip": _no_clip,
    "clipped_frames": _clipped_frames, "pose_noise": _pose_noise,
}
