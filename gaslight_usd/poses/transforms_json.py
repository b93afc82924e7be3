"""nerfstudio / instant-ngp ``transforms.json`` read and written as a ColmapModel.

``transform_matrix`` is camera-to-world with the OpenGL camera axes (x right,
y up, z backward: the camera looks along -Z); COLMAP's camera has x right,
y down, z forward. So ``c2w_colmap = c2w_gl @ diag(1, -1, -1, 1)`` and back.
The world frame is the file's own and is kept untouched (nerfstudio's own
COLMAP import additionally swaps world axes; we do not).

Intrinsics: ``fl_x``, ``fl_y``, ``cx``, ``cy``, ``w``, ``h`` at the top level
(shared) or per frame (per-frame wins); instant-ngp's ``camera_angle_x``/``_y``
stand in for missing focal lengths, the image centre for a missing principal
point, and the image's own header for a missing size. Both tools use COLMAP's
pixel convention for ``cx``/``cy``, so they are copied as they are. Distortion
(``k1``, ``k2``, ``p1``, ``p2``) is kept as an OPENCV camera and noted.

Sparse points come from ``ply_file_path`` (nerfstudio) when present. Our frame
facts travel under the ``gaslight_frame`` key.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import atomic_path, write_text
from ..cameras import PinholeCamera
from ..errors import InputError
from .colmap import ColmapCamera, ColmapModel

GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])
"""Flips the camera's y and z axes: COLMAP/OpenCV <-> OpenGL camera axes."""
FRAME_KEY = "gaslight_frame"
DISTORTION_KEYS = ("k1", "k2", "p1", "p2")
POINTS_PLY = "sparse_pc.ply"


def _intrinsics(entry: dict, base: dict, path: Path, image: Path) -> dict[str, float]:
    """Merge frame-level over file-level intrinsics and fill the gaps."""
    get = {**base, **{k: v for k, v in entry.items() if k != "transform_matrix"}}.get
    w, h = get("w"), get("h")
    if w is None or h is None:
        if not image.exists():
            raise InputError(f"no image size (w, h) given and {image.name} is not there "
                             "to read it from", path)
        from ..imageio import read_header
        spec = read_header(image)
        w, h = spec.width, spec.height
    fx, fy = get("fl_x"), get("fl_y")
    if fx is None and get("camera_angle_x") is not None:
        fx = 0.5 * float(w) / math.tan(0.5 * float(get("camera_angle_x")))
    if fy is None and get("camera_angle_y") is not None:
        fy = 0.5 * float(h) / math.tan(0.5 * float(get("camera_angle_y")))
    fx = fx if fx is not None else fy
    fy = fy if fy is not None else fx
    if fx is None:
        raise InputError("a frame has no focal length (fl_x, fl_y or camera_angle_x)", path)
    return {"w": int(w), "h": int(h), "fx": float(fx), "fy": float(fy),
            "cx": float(get("cx", float(w) / 2)), "cy": float(get("cy", float(h) / 2)),
            **{k: float(get(k, 0.0)) for k in DISTORTION_KEYS}}


def _frame_values(entry: dict, data: dict, path: Path) -> tuple[dict[str, float], np.ndarray]:
    """A frame's intrinsics (checked positive and finite) and camera-to-world matrix."""
    k = _intrinsics(entry, data, path, path.parent / str(entry["file_path"]))
    if k["w"] <= 0 or k["h"] <= 0 or not all(math.isfinite(v) for v in k.values()) or \
            k["fx"] <= 0 or k["fy"] <= 0:
        raise ValueError(f"image size and focal length must be positive and finite: {k}")
    return k, np.asarray(entry["transform_matrix"], np.float64)


def transforms_path(path: str | Path) -> Path:
    """``path`` itself, or ``path/transforms.json`` for a folder."""
    path = Path(path)
    return path / "transforms.json" if path.is_dir() else path


def read_transforms(path: str | Path) -> ColmapModel:
    """Read a transforms.json (or a folder holding one) as a :class:`ColmapModel`."""
    path = transforms_path(path)
    if not path.exists():
        raise InputError("no such transforms.json", path)
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"not valid JSON: {exc}", path) from exc
    frames = data.get("frames") if isinstance(data, dict) else None
    if not frames:
        raise InputError("transforms.json has no 'frames'", path)
    if not isinstance(frames, list):
        raise InputError("'frames' is not a list", path)
    cameras, intr, cam_ids, keys, notes = [], {}, [], {}, []
    for i, entry in enumerate(frames):
        if not isinstance(entry, dict) or "file_path" not in entry or \
                "transform_matrix" not in entry:
            raise InputError(f"frame {i} lacks file_path or transform_matrix", path)
        try:
            k, c2w = _frame_values(entry, data, path)
        except (TypeError, ValueError, OverflowError) as exc:  # wrong types, ragged arrays
            raise InputError(f"frame {i}: a value is not what transforms.json holds ({exc})",
                             path) from None
        if c2w.shape == (3, 4):
            c2w = np.vstack([c2w, [0, 0, 0, 1]])
        if c2w.shape != (4, 4) or not np.all(np.isfinite(c2w)):
            raise InputError(f"frame {i} ({entry['file_path']}): transform_matrix is not a "
                             "finite 4x4 matrix", path)
        w2c = np.linalg.inv(c2w @ GL_FROM_CV)
        rot = w2c[:3, :3]
        if abs(np.linalg.det(rot) - 1) > 1e-4:
            raise InputError(f"frame {i} ({entry['file_path']}): transform_matrix has scale "
                             "or shear, not a rigid camera pose", path)
        key = tuple(k.values())
        if key not in keys:
            cid = keys[key] = len(keys) + 1
            dist = [k[d] for d in DISTORTION_KEYS]
            if any(dist):
                intr[cid] = ColmapCamera(cid, "OPENCV", k["w"], k["h"], np.array(
                    [k["fx"], k["fy"], k["cx"], k["cy"], *dist]))
                notes.append(f"camera {cid} has distortion {dist}: kept, but ignored by "
                             "the pinhole cameras")
            else:
                intr[cid] = ColmapCamera(cid, "PINHOLE", k["w"], k["h"], np.array(
                    [k["fx"], k["fy"], k["cx"], k["cy"]]))
        cam_ids.append(keys[key])
        cameras.append(PinholeCamera(k["w"], k["h"], k["fx"], k["fy"], k["cx"], k["cy"],
                                     R=rot.copy(), t=w2c[:3, 3].copy(),
                                     name=Path(entry["file_path"]).name))
    points, colours = _read_points(path, data)
    return ColmapModel(cameras=cameras, points=points, point_colours=colours,
                       image_ids=list(range(1, len(cameras) + 1)), camera_ids=cam_ids,
                       intrinsics=intr, frame=dict(data.get(FRAME_KEY) or {}), notes=notes,
                       source=path)


def _read_points(path: Path, data: dict) -> tuple[np.ndarray, np.ndarray]:
    ply = data.get("ply_file_path")
    if not ply or not (path.parent / ply).exists():
        return np.zeros((0, 3)), np.zeros((0, 3), np.uint8)
    from plyfile import PlyData
    try:
        vertex = PlyData.read(str(path.parent / ply))["vertex"]
        xyz = np.stack([vertex[a] for a in "xyz"], axis=1).astype(np.float64)
        names = vertex.data.dtype.names
        rgb = (np.stack([vertex[a] for a in ("red", "green", "blue")], axis=1)
               if "red" in names else np.full((len(xyz), 3), 128))
    except (KeyError, ValueError, OSError) as exc:
        raise InputError(f"cannot read sparse points: {exc}", path.parent / ply) from exc
    return xyz, rgb.astype(np.uint8)


def _camera_entry(cam: PinholeCamera, distortion: dict[str, float]) -> dict[str, Any]:
    entry = {"w": int(cam.width), "h": int(cam.height), "fl_x": float(cam.fx),
             "fl_y": float(cam.fy), "cx": float(cam.cx), "cy": float(cam.cy)}
    if any(distortion.values()):
        entry.update({"camera_model": "OPENCV", **distortion})
    else:
        entry["camera_model"] = "PINHOLE"
    return entry


def _distortion_of(model: ColmapModel, index: int) -> dict[str, float]:
    cam = model.intrinsics.get(model.camera_ids[index])
    if cam is None or cam.model == "PINHOLE" or cam.model == "SIMPLE_PINHOLE":
        return {}
    d = cam.distortion
    if cam.model == "SIMPLE_RADIAL":
        return {"k1": float(d[0])}
    if cam.model == "RADIAL":
        return {"k1": float(d[0]), "k2": float(d[1])}
    if cam.model == "OPENCV":
        return dict(zip(DISTORTION_KEYS, map(float, d[:4]), strict=True))
    return {}  # other models have no transforms.json form: noted by read_model


def write_transforms(path: str | Path, model: ColmapModel, image_prefix: str = "images/",
                     with_points: bool = True) -> Path:
    """Write ``model`` as a transforms.json (atomically); shared intrinsics go on top.

    ``file_path`` of each frame is ``image_prefix + name``. Sparse points, when
    any, go to ``sparse_pc.ply`` beside it (``ply_file_path``).
    """
    path = Path(path)
    entries = [_camera_entry(c, _distortion_of(model, i))
               for i, c in enumerate(model.cameras)]
    shared = all(e == entries[0] for e in entries) if entries else False
    data: dict[str, Any] = dict(entries[0]) if shared else {}
    frames = []
    for cam, entry in zip(model.cameras, entries, strict=True):
        c2w = np.linalg.inv(cam.world_to_camera) @ GL_FROM_CV
        frame = {"file_path": f"{image_prefix}{cam.name}",
                 "transform_matrix": c2w.tolist()}
        if not shared:
            frame.update(entry)
        frames.append(frame)
    data["frames"] = frames
    if model.frame:
        data[FRAME_KEY] = model.frame
    if with_points and len(model.points):
        _write_points(path.parent / POINTS_PLY, model)
        data["ply_file_path"] = POINTS_PLY
    return write_text(path, json.dumps(data, indent=2))


def _write_points(path: Path, model: ColmapModel) -> None:
    from plyfile import PlyData, PlyElement
    rec = np.empty(len(model.points), [("x", "f8"), ("y", "f8"), ("z", "f8"),
                                       ("red", "u1"), ("green", "u1"), ("blue", "u1")])
    for i, axis in enumerate("xyz"):
        rec[axis] = model.points[:, i]
    for i, ch in enumerate(("red", "green", "blue")):
        rec[ch] = model.point_colours[:, i]
    with atomic_path(path) as tmp:
        PlyData([PlyElement.describe(rec, "vertex")]).write(str(tmp))
