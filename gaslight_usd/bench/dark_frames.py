"""A generated scene's photo set with one darker frame aimed at each light.

The README's advice for shooting a set ("Shooting the lights") is one extra frame per
bright light, exposed for the light so it does not clip. A generated scene has the true
radiance of every view, so the bench can make that capture without rendering again:
for each light, the view that sees the light's centre nearest its image centre is
re-exposed so that the brightest pixel within the light's disc (a few pixels around
its projection) sits below white, rounded down to 1/3 stop as a camera would (the
shutter no shorter than 1/8000 s, then the aperture closed down to f/22; a light
brighter than that still clips and ``dark_frames.json`` says so), and
written as the camera model of ``examples/make_room.py`` writes a photo
(``clip(radiance * t * K)``, sRGB OETF, 8-bit JPEG, EXIF ExposureTime / FNumber /
ISO). The other photos are linked unchanged. Used by ``bench --suite chain``'s
method "recursive + dark frames".

That method re-exposes the chosen photo in place, so the set loses that photo's view
of the room round the light. The README's advice is an *extra* frame from a
neighbouring photo's position: with ``extra`` the darker frame is written beside the
photo it was made from (``<stem>_dark.jpg``, :data:`DARK_SUFFIX`) and posed as that
photo (:func:`poses_with_dark_frames`), the method "recursive + extra dark frames".
A light no photo's position shows (a bulb inside a shade, which the README says to shoot
from below) gets its frame from a view the scene renders for it and no photo has
(``scene.json``'s ``extra_views``: ``examples/make_room.py`` renders one below a shaded
lamp), posed where it was rendered.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import OpenImageIO as oiio

from ..atomic import atomic_path
from ..cameras import quaternion_to_matrix
from ..colour import convert
from ..errors import GaslightError
from ..imageio import read_header, read_image
from ..poses import read_poses, write_poses
from ..poses.colmap import with_added_images

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


SHORTEST_EXPOSURE = 1.0 / 8000.0
"""A camera's fastest shutter (s); EXIF's rationals also lose much shorter times (OpenImageIO
wrote 4.6e-6 s as 0)."""
SMALLEST_APERTURE = 22.0
"""The f-number a lens closes down to."""


def dark_exposure(radiance: np.ndarray, uv: np.ndarray, k_camera: float) -> float:
    """Exposure (s at the scene's f-number) putting the peak near ``uv`` at HEADROOM x
    white, in 1/3-stop steps."""
    u, v = int(uv[0]), int(uv[1])
    patch = radiance[max(0, v - SEARCH_PX):v + SEARCH_PX + 1,
                     max(0, u - SEARCH_PX):u + SEARCH_PX + 1]
    peak = float(patch.max())
    if peak <= 0:
        raise GaslightError("no light seen where the light projects")
    return 2.0 ** (math.floor(3 * math.log2(HEADROOM / (peak * k_camera))) / 3)


def camera_settings(exposure: float, f_number: float) -> tuple[float, float]:
    """(shutter s, f-number) giving ``exposure`` (s at ``f_number``) as a camera can: the
    shutter down to :data:`SHORTEST_EXPOSURE`, then the aperture down to
    :data:`SMALLEST_APERTURE`; beyond both, as dark as the camera goes."""
    shutter = max(exposure, SHORTEST_EXPOSURE)
    aperture = min(f_number * math.sqrt(shutter / exposure), SMALLEST_APERTURE)
    return shutter, max(aperture, f_number)


def write_photo(path: Path, radiance: np.ndarray, settings: tuple[float, float],
                k_camera: float, f_number: float, like: Path) -> None:
    """``radiance`` as the scene's camera records it at ``settings`` (shutter s,
    f-number; ``k_camera`` holds at ``f_number``), with the EXIF of ``like`` (its
    ExposureTime and FNumber replaced)."""
    shutter, aperture = settings
    gain = shutter * k_camera * (f_number / aperture) ** 2
    write_linear_photo(path, radiance * np.float32(gain), settings, like)


def write_linear_photo(path: Path, linear: np.ndarray, settings: tuple[float, float],
                       like: Path, quality: int = 93) -> None:
    """A linear Rec.709 sensor image (1 = white) as the scene's camera writes it: clipped,
    sRGB OETF, 8-bit JPEG at ``quality``, the EXIF of ``like`` with ExposureTime and
    FNumber set from ``settings`` (shutter s, f-number)."""
    shutter, aperture = settings
    linear = np.clip(linear, 0.0, 1.0)
    encoded = convert(linear.astype(np.float32), TRUTH_SPACE, PHOTO_SPACE)
    pixels = np.round(np.clip(encoded, 0.0, 1.0) * 255).astype(np.uint8)
    spec = oiio.ImageSpec(read_header(like))
    spec.width, spec.height = pixels.shape[1], pixels.shape[0]
    spec.full_width, spec.full_height = spec.width, spec.height
    spec.set_format(oiio.UINT8)
    spec.attribute("ExposureTime", float(shutter))
    spec.attribute("FNumber", float(aperture))
    spec.attribute("Compression", f"jpeg:{int(quality)}")
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec) or not out.write_image(pixels):
            raise GaslightError(f"cannot write {path}: {oiio.geterror()}")
        out.close()


DARK_SUFFIX = "_dark"
"""An extra dark frame's name: the photo it was made from, this appended to its stem."""


def dark_frame_photos(folder: Path, dst: Path, lights: list[dict[str, Any]],
                      extra: bool = False) -> dict[str, dict[str, Any]]:
    """``dst``: the scene's photos, one per light re-exposed for that light (``extra``:
    the re-exposed frame added beside the photo, ``<stem>_dark.jpg``, the photo kept).

    Returns, per dark frame (by its file name), the light it was aimed at, the exposure
    change in stops, its shutter and f-number, whether the light still clips and the
    photo it was made from (also written beside ``dst`` as ``dark_frames.json``).
    """
    info = json.loads((folder / "scene.json").read_text())
    k_camera = float(info["exposure"]["K"])
    f_number = float(info["exposure"]["FNumber"])
    cameras = read_poses(folder / "sparse" / "0").cameras
    dst.mkdir(parents=True, exist_ok=True)
    chosen: dict[str, dict[str, Any]] = {}
    used: set[str] = set()
    for light in lights:
        center = np.asarray(light["center"], np.float64)
        cam = light_view(cameras, center, used)
        if cam is None:
            continue
        used.add(cam.name)
        photo = folder / "photos" / cam.name
        truth = read_image(folder / "truth" / (Path(cam.name).stem + ".exr")).pixels
        uv, _ = cam.project(center[None])
        wanted = dark_exposure(truth, uv[0], k_camera)
        shutter, aperture = camera_settings(wanted, f_number)
        t_was = float(read_header(photo).getattribute("ExposureTime"))
        name = (Path(cam.name).stem + DARK_SUFFIX + Path(cam.name).suffix if extra
                else cam.name)
        write_photo(dst / name, truth, (shutter, aperture), k_camera, f_number, photo)
        given = shutter * (f_number / aperture) ** 2
        chosen[name] = {"light": light["name"],
                        "stops": round(math.log2(given / t_was), 2),
                        "shutter_s": shutter, "f_number": round(aperture, 2),
                        "still_clips": given > wanted * 1.001, "of": cam.name}
    if extra:
        chosen |= _frames_from_extra_views(folder, info, dst, lights, k_camera, f_number)
    for photo in sorted((folder / "photos").glob("*.jpg")):
        link = dst / photo.name
        if photo.name not in chosen and not link.exists():
            link.symlink_to(photo.resolve())
    (dst.parent / "dark_frames.json").write_text(json.dumps(chosen, indent=1))
    return chosen


def _frames_from_extra_views(folder: Path, info: dict[str, Any], dst: Path,
                             lights: list[dict[str, Any]], k_camera: float, f_number: float
                             ) -> dict[str, dict[str, Any]]:
    """A darker frame from each of the scene's ``extra_views`` aimed at one of ``lights``
    (a view from below a shaded lamp), exposed for that light; per frame what
    :func:`dark_frame_photos` records, with the view's pose (``qvec``, ``tvec``) in place
    of the photo it was made from (``of``: None)."""
    names = {light["name"]: light for light in lights}
    like = sorted((folder / "photos").glob("*.jpg"))
    template = read_poses(folder / "sparse" / "0").cameras[0]
    chosen: dict[str, dict[str, Any]] = {}
    for view in info.get("extra_views", []):
        light = names.get(view.get("aimed_at"))
        if light is None or not like:
            continue
        cam = replace(template, R=quaternion_to_matrix(np.asarray(view["qvec"], np.float64)),
                      t=np.asarray(view["tvec"], np.float64), name=view["name"])
        truth = read_image(folder / view["truth"]).pixels
        uv, z = cam.project(np.asarray(light["center"], np.float64)[None])
        if z[0] <= 0:
            raise GaslightError(f"{view['name']}: aimed at the {light['name']}, which lies "
                                "behind it")
        wanted = dark_exposure(truth, uv[0], k_camera)
        shutter, aperture = camera_settings(wanted, f_number)
        name = Path(view["name"]).stem + DARK_SUFFIX + Path(view["name"]).suffix
        write_photo(dst / name, truth, (shutter, aperture), k_camera, f_number, like[0])
        given = shutter * (f_number / aperture) ** 2
        chosen[name] = {"light": light["name"], "shutter_s": shutter,
                        "f_number": round(aperture, 2), "still_clips": given > wanted * 1.001,
                        "of": None, "qvec": list(view["qvec"]), "tvec": list(view["tvec"])}
    return chosen


def poses_with_dark_frames(folder: Path, chosen: dict[str, dict[str, Any]], out: Path
                           ) -> Path:
    """The scene's poses (``folder/sparse/0``) with each extra dark frame of ``chosen``
    (:func:`dark_frame_photos` with ``extra``) posed as the photo it was made from, or,
    made from an extra view, at that view's pose; written to ``out`` (a COLMAP model
    folder, returned)."""
    model = read_poses(folder / "sparse" / "0")
    by_name = {cam.name: k for k, cam in enumerate(model.cameras)}
    added = []
    for name, what in chosen.items():
        k = by_name.get(what["of"]) if what["of"] is not None else 0
        if k is None or name in by_name:
            continue
        cam = replace(model.cameras[k], name=name)
        if what["of"] is None:
            cam = replace(cam, R=quaternion_to_matrix(np.asarray(what["qvec"], np.float64)),
                          t=np.asarray(what["tvec"], np.float64))
        added.append((cam, k))
    return write_poses(out, with_added_images(model, added))


def truth_with_extra_views(folder: Path, out: Path) -> tuple[Path, Path]:
    """(HDR views folder, poses folder) of the scene's true HDR views and its
    ``extra_views``' (a view from below a shaded lamp) at their poses, under ``out``: the
    ceiling for a capture that adds darker frames from those viewpoints, which without
    them would score a fit that never saw a shaded bulb (the level views all look at its
    shade). A scene without extra views gives its own ``truth`` and poses."""
    info = json.loads((folder / "scene.json").read_text())
    extra = info.get("extra_views", [])
    if not extra:
        return folder / "truth", folder / "sparse" / "0"
    hdr = out / "truth"
    hdr.mkdir(parents=True, exist_ok=True)
    for view in [*sorted((folder / "truth").glob("*.exr")),
                 *(folder / v["truth"] for v in extra)]:
        link = hdr / view.name
        if not link.exists():
            link.symlink_to(view.resolve())
    posed = {v["name"]: {"of": None, "qvec": list(v["qvec"]), "tvec": list(v["tvec"])}
             for v in extra}
    return hdr, poses_with_dark_frames(folder, posed, out / "sparse")
