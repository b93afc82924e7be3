"""A generated scene's photo set with one darker frame aimed at each light.

The README's advice for shooting a set ("Shooting the lights") is one extra frame per
bright light, exposed for the light so it does not clip. A generated scene has the true
radiance of every view, so the bench can make that capture without rendering again:
for each light, the view that sees the light's centre nearest its image centre is
re-exposed so that the brightest pixel within the light's disc (a few pixels around
its projection) sits below white, rounded down to 1/3 stop as a camera would, and
written as the camera model of ``examples/make_room.py`` writes a photo
(``clip(radiance * t * K)``, sRGB OETF, 8-bit JPEG, EXIF ExposureTime / FNumber /
ISO). The other photos are linked unchanged. Used by ``bench --suite chain``'s
method "recursive + dark frames".
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import OpenImageIO as oiio

from ..atomic import atomic_path
from ..colour import convert
from ..errors import GaslightError
from ..imageio import read_header, read_image
from ..poses import read_poses

HEADROOM = 0.9
"""The light's brightest pixel lands at this fraction of white (JPEG ringing, 1/3-stop
rounding down keeps it there or below)."""
SEARCH_PX = 6
"""Half-size of the square around a light's projection where its peak is looked for."""
PHOTO_SPACE = "srgb_rec709_scene"
TRUTH_SPACE = "lin_rec709_scene"


def light_view(cameras: list, center: np.ndarray, taken: set[str]) -> Any | None:
    """The camera that sees ``center`` nearest its image centre (not one in ``taken``)."""
    best, best_d = None, math.inf
    for cam in cameras:
        if cam.name in taken:
            continue
        uv, z = cam.project(center[None])
        if z[0] <= 0:
            continue
        u, v = uv[0]
        if not (SEARCH_PX <= u < cam.width - SEARCH_PX and SEARCH_PX <= v < cam.height - SEARCH_PX):
            continue
        d = math.hypot((u - cam.cx) / cam.width, (v - cam.cy) / cam.height)
        if d < best_d:
            best, best_d = cam, d
    return best


def dark_exposure(radiance: np.ndarray, uv: np.ndarray, k_camera: float) -> float:
    """Exposure time (s) putting the peak near ``uv`` at HEADROOM x white, 1/3-stop steps."""
    u, v = int(uv[0]), int(uv[1])
    patch = radiance[max(0, v - SEARCH_PX):v + SEARCH_PX + 1,
                     max(0, u - SEARCH_PX):u + SEARCH_PX + 1]
    peak = float(patch.max())
    if peak <= 0:
        raise GaslightError("no light seen where the light projects")
    return 2.0 ** (math.floor(3 * math.log2(HEADROOM / (peak * k_camera))) / 3)


def write_photo(path: Path, radiance: np.ndarray, exposure_time: float, k_camera: float,
                like: Path) -> None:
    """``radiance`` as the scene's camera records it at ``exposure_time``, with the EXIF
    of ``like`` (its ExposureTime replaced)."""
    linear = np.clip(radiance * np.float32(exposure_time * k_camera), 0.0, 1.0)
    encoded = convert(linear.astype(np.float32), TRUTH_SPACE, PHOTO_SPACE)
    pixels = np.round(np.clip(encoded, 0.0, 1.0) * 255).astype(np.uint8)
    spec = oiio.ImageSpec(read_header(like))
    spec.set_format(oiio.UINT8)
    spec.attribute("ExposureTime", float(exposure_time))
    spec.attribute("Compression", "jpeg:93")
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec) or not out.write_image(pixels):
            raise GaslightError(f"cannot write {path}: {oiio.geterror()}")
        out.close()


def dark_frame_photos(folder: Path, dst: Path, lights: list[dict[str, Any]]
                      ) -> dict[str, dict[str, Any]]:
    """``dst``: the scene's photos, one per light re-exposed for that light.

    Returns, per re-exposed photo, the light it was aimed at and the exposure change
    in stops (also written beside ``dst`` as ``dark_frames.json``).
    """
    info = json.loads((folder / "scene.json").read_text())
    k_camera = float(info["exposure"]["K"])
    cameras = read_poses(folder / "sparse" / "0").cameras
    dst.mkdir(parents=True, exist_ok=True)
    chosen: dict[str, dict[str, Any]] = {}
    for light in lights:
        center = np.asarray(light["center"], np.float64)
        cam = light_view(cameras, center, set(chosen))
        if cam is None:
            continue
        photo = folder / "photos" / cam.name
        truth = read_image(folder / "truth" / (Path(cam.name).stem + ".exr")).pixels
        uv, _ = cam.project(center[None])
        t_dark = dark_exposure(truth, uv[0], k_camera)
        t_was = float(read_header(photo).getattribute("ExposureTime"))
        write_photo(dst / cam.name, truth, t_dark, k_camera, photo)
        chosen[cam.name] = {"light": light["name"],
                            "stops": round(math.log2(t_dark / t_was), 2)}
    for photo in sorted((folder / "photos").glob("*.jpg")):
        link = dst / photo.name
        if photo.name not in chosen and not link.exists():
            link.symlink_to(photo.resolve())
    (dst.parent / "dark_frames.json").write_text(json.dumps(chosen, indent=1))
    return chosen
