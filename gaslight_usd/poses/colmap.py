"""COLMAP sparse models (text or binary) read into and written from plain arrays.

A model is cameras (intrinsics), images (one world-to-camera pose each, with
their 2D observations) and points3D (sparse points with colour, reprojection
error and track). :class:`ColmapModel` holds one :class:`PinholeCamera` per
registered image, in image-id order, so the rest of the project never sees
COLMAP's split of intrinsics and poses. Lens distortion of SIMPLE_RADIAL,
RADIAL, OPENCV... cameras is kept in :attr:`ColmapModel.intrinsics` (and
written back unchanged) but the pinhole cameras ignore it; a note says so.

Layout written: ``cameras``, ``images``, ``points3D`` as ``.txt`` or ``.bin``
(the formats COLMAP 3.x/4.x and every 3DGS trainer read), plus ``frame.json``
when the model carries frame metadata (see :mod:`gaslight_usd.poses.frame`).
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass, field, replace
from itertools import chain
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import atomic_path, write_text
from ..cameras import PinholeCamera, matrix_to_quaternion, quaternion_to_matrix
from ..errors import InputError

FRAME_FILE = "frame.json"

# model id -> (name, number of params, params start with a single focal length)
CAMERA_MODELS: dict[int, tuple[str, int, bool]] = {
    0: ("SIMPLE_PINHOLE", 3, True),
    1: ("PINHOLE", 4, False),
    2: ("SIMPLE_RADIAL", 4, True),
    3: ("RADIAL", 5, True),
    4: ("OPENCV", 8, False),
    5: ("OPENCV_FISHEYE", 8, False),
    6: ("FULL_OPENCV", 12, False),
    7: ("FOV", 5, False),
    8: ("SIMPLE_RADIAL_FISHEYE", 4, True),
    9: ("RADIAL_FISHEYE", 5, True),
    10: ("THIN_PRISM_FISHEYE", 12, False),
}
MODEL_IDS = {name: mid for mid, (name, _, _) in CAMERA_MODELS.items()}
PINHOLE_MODELS = ("SIMPLE_PINHOLE", "PINHOLE")

_POINT2D = np.dtype([("x", "<f8"), ("y", "<f8"), ("id", "<i8")])
_POINT3D_HEAD = np.dtype([("id", "<u8"), ("xyz", "<f8", 3), ("rgb", "u1", 3),
                          ("error", "<f8"), ("track_length", "<u8")])
_TRACK = np.dtype([("image_id", "<u4"), ("point2d_idx", "<u4")])


@dataclass
class ColmapCamera:
    """One COLMAP camera (intrinsics shared by any number of images)."""

    camera_id: int
    model: str
    width: int
    height: int
    params: np.ndarray

    @property
    def pinhole(self) -> tuple[float, float, float, float]:
        """(fx, fy, cx, cy) of this camera, distortion dropped."""
        if self.model not in MODEL_IDS:
            raise ValueError(f"unknown COLMAP camera model {self.model}")
        p = [float(v) for v in self.params]
        if CAMERA_MODELS[MODEL_IDS[self.model]][2]:
            return p[0], p[0], p[1], p[2]
        return p[0], p[1], p[2], p[3]

    @property
    def distortion(self) -> np.ndarray:
        """The parameters after the focal lengths and principal point."""
        single = CAMERA_MODELS[MODEL_IDS[self.model]][2]
        return np.asarray(self.params[3 if single else 4:], np.float64)

    @classmethod
    def from_pinhole(cls, camera_id: int, cam: PinholeCamera) -> ColmapCamera:
        return cls(camera_id, "PINHOLE", int(cam.width), int(cam.height),
                   np.array([cam.fx, cam.fy, cam.cx, cam.cy], np.float64))


@dataclass
class ColmapModel:
    """A posed image set with sparse points, in COLMAP's conventions."""

    cameras: list[PinholeCamera]
    """One per registered image, in image-id order; ``name`` is the image file name."""
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """(N, 3) float64 sparse points in the world frame."""
    point_colours: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.uint8))
    """(N, 3) uint8 sRGB colours as COLMAP stores them."""
    point_errors: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """(N,) mean reprojection error in pixels."""
    point_ids: np.ndarray | None = None
    """(N,) int64 COLMAP point3D ids (1..N when None)."""
    image_ids: list[int] = field(default_factory=list)
    """COLMAP image id of each camera (1..M when empty)."""
    camera_ids: list[int] = field(default_factory=list)
    """COLMAP camera id (intrinsics) of each camera."""
    intrinsics: dict[int, ColmapCamera] = field(default_factory=dict)
    """COLMAP cameras by id, distortion included; built from the pinholes when empty."""
    points2d: list[np.ndarray] | None = None
    """Per image (M_i, 3) float64 rows (x, y, point3D id or -1); optional."""
    tracks: list[np.ndarray] | None = None
    """Per point (L, 2) int64 rows (image id, point2D index); optional."""
    frame: dict[str, Any] = field(default_factory=dict)
    """Frame metadata from ``frame.json`` (up axis, meters_per_unit, transform...)."""
    notes: list[str] = field(default_factory=list)
    """Things a user should know about this model (distortion ignored, ...)."""
    source: Path | None = None
    agreement: Any = None
    """How well the poses agree with the photos' feature matches, when measured (a
    :class:`~gaslight_usd.poses.agreement.PoseAgreement`, set by triangulation); not
    written to disk."""

    def __post_init__(self) -> None:
        n = len(self.cameras)
        self.points = np.asarray(self.points, np.float64).reshape(-1, 3)
        count = len(self.points)
        self.point_colours = np.asarray(self.point_colours, np.uint8).reshape(-1, 3)
        if len(self.point_colours) != count:
            self.point_colours = np.full((count, 3), 128, np.uint8)
        self.point_errors = np.asarray(self.point_errors, np.float64).reshape(-1)
        if len(self.point_errors) != count:
            self.point_errors = np.zeros(count)
        if self.point_ids is None or len(self.point_ids) != count:
            self.point_ids = np.arange(1, count + 1, dtype=np.int64)
        if len(self.image_ids) != n:
            self.image_ids = list(range(1, n + 1))
        if len(self.camera_ids) != n or not self.intrinsics:
            self.camera_ids, self.intrinsics = _intrinsics_from_pinholes(self.cameras)

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.cameras]

    def camera(self, name: str) -> PinholeCamera:
        for cam in self.cameras:
            if cam.name == name or Path(cam.name).stem == name:
                return cam
        raise KeyError(name)

    @property
    def centers(self) -> np.ndarray:
        """(M, 3) camera centres in the world frame."""
        return np.array([c.center for c in self.cameras]).reshape(-1, 3)


def with_added_images(model: ColmapModel, added: list[tuple[PinholeCamera, int]]
                      ) -> ColmapModel:
    """``model`` with more images: each ``(camera, k)`` posed as ``camera`` (its name the
    image's) and sharing the intrinsics of the model's image ``k``, with a new image id and
    no 2D points (nothing was triangulated from it)."""
    if not added:
        return model
    cameras, image_ids = list(model.cameras), list(model.image_ids)
    camera_ids = list(model.camera_ids)
    points2d = None if model.points2d is None else list(model.points2d)
    for cam, k in added:
        cameras.append(cam)
        image_ids.append(max(image_ids, default=0) + 1)
        camera_ids.append(camera_ids[k])
        if points2d is not None:
            points2d.append(np.zeros((0, 3)))
    return replace(model, cameras=cameras, image_ids=image_ids, camera_ids=camera_ids,
                   points2d=points2d)


def _intrinsics_from_pinholes(cameras: list[PinholeCamera]
                              ) -> tuple[list[int], dict[int, ColmapCamera]]:
    """Share one PINHOLE camera between images with identical intrinsics."""
    ids: list[int] = []
    by_key: dict[tuple, int] = {}
    intr: dict[int, ColmapCamera] = {}
    for cam in cameras:
        key = (cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy)
        if key not in by_key:
            by_key[key] = len(by_key) + 1
            intr[by_key[key]] = ColmapCamera.from_pinhole(by_key[key], cam)
        ids.append(by_key[key])
    return ids, intr


# -- reading -----------------------------------------------------------------

def read_model(path: str | Path) -> ColmapModel:
    """Read a COLMAP model folder (text or binary; binary preferred when both).

    ``path`` is the folder holding ``cameras.*`` or a parent with ``0/``,
    ``sparse/0`` or ``sparse``. Raises InputError naming the file on bad input.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("no such COLMAP model folder", path)
    folder = find_colmap_model(path) if path.is_dir() else None
    if folder is None:
        raise InputError("not a COLMAP model (no cameras.txt or cameras.bin here, "
                         "in 0/ or in sparse/0/)", path)
    binary = (folder / "cameras.bin").exists()
    ext = "bin" if binary else "txt"
    files = {part: folder / f"{part}.{ext}" for part in ("cameras", "images", "points3D")}
    for part in ("cameras", "images"):
        if not files[part].exists():
            raise InputError(f"COLMAP model lacks {part}.{ext}", folder)
    readers = ({"cameras": _read_cameras_bin, "images": _read_images_bin,
                "points3D": _read_points3d_bin} if binary else
               {"cameras": _read_cameras_txt, "images": _read_images_txt,
                "points3D": _read_points3d_txt})
    parts: dict[str, Any] = {"points3D": _empty_points()}
    for part, reader in readers.items():
        if not files[part].exists():
            continue
        try:
            parts[part] = reader(files[part])
        except InputError:
            raise
        except (ValueError, IndexError, KeyError, struct.error, UnicodeDecodeError) as exc:
            raise InputError(f"malformed COLMAP {part} file: {exc}", files[part]) from exc
    intr, images, pts = parts["cameras"], parts["images"], parts["points3D"]
    return _assemble(folder, intr, images, pts)


def _empty_points() -> dict[str, np.ndarray | list]:
    return {"ids": np.zeros(0, np.int64), "xyz": np.zeros((0, 3)),
            "rgb": np.zeros((0, 3), np.uint8), "error": np.zeros(0), "tracks": []}


def _assemble(folder: Path, intr: dict[int, ColmapCamera], images: list[dict],
              pts: dict) -> ColmapModel:
    images = sorted(images, key=lambda im: im["id"])
    cameras, notes = [], []
    for im in images:
        cid = im["camera_id"]
        if cid not in intr:
            raise InputError(f"image {im['name']} uses camera {cid}, which cameras.* "
                             "does not define", folder)
        fx, fy, cx, cy = intr[cid].pinhole
        cameras.append(PinholeCamera(
            width=intr[cid].width, height=intr[cid].height, fx=fx, fy=fy, cx=cx, cy=cy,
            R=quaternion_to_matrix(im["q"]), t=np.asarray(im["t"], np.float64),
            name=im["name"]))
    for cid, cam in sorted(intr.items()):
        if cam.model not in PINHOLE_MODELS and np.any(cam.distortion != 0):
            notes.append(f"camera {cid} is {cam.model}: its distortion "
                         f"{np.round(cam.distortion, 6).tolist()} is kept in the model but "
                         "ignored by the pinhole cameras (undistort the photos for accuracy)")
    frame: dict[str, Any] = {}
    for candidate in (folder / FRAME_FILE, folder.parent / FRAME_FILE):
        if candidate.exists():
            try:
                frame = json.loads(candidate.read_text())
            except json.JSONDecodeError as exc:
                raise InputError(f"bad JSON: {exc}", candidate) from exc
            break
    return ColmapModel(
        cameras=cameras, points=pts["xyz"], point_colours=pts["rgb"],
        point_errors=pts["error"], point_ids=pts["ids"],
        image_ids=[im["id"] for im in images], camera_ids=[im["camera_id"] for im in images],
        intrinsics=intr, points2d=[im["points2d"] for im in images],
        tracks=pts["tracks"], frame=frame, notes=notes, source=folder)


def _data_lines(path: Path) -> list[str]:
    return [ln for ln in path.read_text().splitlines()
            if ln.strip() and not ln.lstrip().startswith("#")]


def _read_cameras_txt(path: Path) -> dict[int, ColmapCamera]:
    cams = {}
    for line in _data_lines(path):
        parts = line.split()
        cid, model = int(parts[0]), parts[1]
        if model not in MODEL_IDS:
            raise InputError(f"unsupported COLMAP camera model {model}", path)
        params = np.array(parts[4:], np.float64)
        if len(params) != CAMERA_MODELS[MODEL_IDS[model]][1]:
            raise InputError(f"camera {cid} ({model}) has {len(params)} parameters", path)
        cams[cid] = ColmapCamera(cid, model, int(parts[2]), int(parts[3]), params)
    return cams


def _read_images_txt(path: Path) -> list[dict]:
    lines = path.read_text().splitlines()
    images, i = [], 0
    while i < len(lines):
        line = lines[i].strip()
        i += 1
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        if len(parts) < 10:
            raise InputError(f"image line {i} has {len(parts)} fields, expected 10", path)
        obs = lines[i].split() if i < len(lines) else []
        i += 1
        pts = np.array(obs, np.float64).reshape(-1, 3) if obs else np.zeros((0, 3))
        images.append({"id": int(parts[0]), "q": np.array(parts[1:5], np.float64),
                       "t": np.array(parts[5:8], np.float64), "camera_id": int(parts[8]),
                       "name": " ".join(parts[9:]), "points2d": pts})
    return images


def _read_points3d_txt(path: Path) -> dict:
    rows = [ln.split() for ln in _data_lines(path)]
    if not rows:
        return _empty_points()
    lengths = np.fromiter(map(len, rows), np.int64, len(rows))
    if np.any(lengths < 8) or np.any((lengths - 8) % 2):
        raise InputError("points3D line with a wrong number of fields", path)
    flat = np.array(list(chain.from_iterable(rows)), np.float64)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    head = flat[starts[:, None] + np.arange(8)]
    track_mask = np.ones(len(flat), bool)
    track_mask[(starts[:, None] + np.arange(8)).ravel()] = False
    pairs = flat[track_mask].astype(np.int64).reshape(-1, 2)
    splits = np.cumsum((lengths - 8) // 2)[:-1]
    return {"ids": head[:, 0].astype(np.int64), "xyz": head[:, 1:4],
            "rgb": head[:, 4:7].astype(np.uint8), "error": head[:, 7],
            "tracks": np.split(pairs, splits)}


class _Reader:
    def __init__(self, path: Path):
        self.data = path.read_bytes()
        self.pos = 0
        self.path = path

    def unpack(self, fmt: str) -> tuple:
        out = struct.unpack_from("<" + fmt, self.data, self.pos)
        self.pos += struct.calcsize("<" + fmt)
        return out

    def array(self, dtype: np.dtype, count: int) -> np.ndarray:
        out = np.frombuffer(self.data, dtype, count, self.pos)
        self.pos += dtype.itemsize * count
        return out

    def cstring(self) -> str:
        end = self.data.index(b"\0", self.pos)
        out = self.data[self.pos:end].decode("utf-8")
        self.pos = end + 1
        return out


def _read_cameras_bin(path: Path) -> dict[int, ColmapCamera]:
    r = _Reader(path)
    (count,) = r.unpack("Q")
    cams = {}
    for _ in range(count):
        cid, mid, w, h = r.unpack("iiQQ")
        if mid not in CAMERA_MODELS:
            raise InputError(f"unsupported COLMAP camera model id {mid}", path)
        name, nparams, _ = CAMERA_MODELS[mid]
        cams[cid] = ColmapCamera(cid, name, int(w), int(h),
                                 r.array(np.dtype("<f8"), nparams).copy())
    return cams


def _read_images_bin(path: Path) -> list[dict]:
    r = _Reader(path)
    (count,) = r.unpack("Q")
    images = []
    for _ in range(count):
        iid, qw, qx, qy, qz, tx, ty, tz, cid = r.unpack("I7dI")
        name = r.cstring()
        (npts,) = r.unpack("Q")
        obs = r.array(_POINT2D, npts)
        pts = np.stack([obs["x"], obs["y"], obs["id"].astype(np.float64)], axis=1)
        # COLMAP stores "no 3D point" as uint64 max, which reads as -1 in int64.
        images.append({"id": iid, "q": np.array([qw, qx, qy, qz]),
                       "t": np.array([tx, ty, tz]), "camera_id": cid, "name": name,
                       "points2d": pts})
    return images


def _read_points3d_bin(path: Path) -> dict:
    data = path.read_bytes()
    (count,) = struct.unpack_from("<Q", data, 0)
    if count == 0:
        return _empty_points()
    # Records have variable length; only the offsets need a sequential walk.
    offsets = np.empty(count, np.int64)
    lengths = np.empty(count, np.int64)
    pos, head = 8, _POINT3D_HEAD.itemsize
    unpack = struct.Struct("<Q").unpack_from
    for i in range(count):
        offsets[i] = pos
        (n,) = unpack(data, pos + head - 8)
        lengths[i] = n
        pos += head + 8 * n
    buf = np.frombuffer(data, np.uint8)
    heads = buf[offsets[:, None] + np.arange(head)].copy().view(_POINT3D_HEAD).reshape(-1)
    starts = np.repeat(offsets + head, lengths)
    within = np.arange(lengths.sum()) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    idx = (starts + 8 * within)[:, None] + np.arange(8)
    track = buf[idx].copy().view(_TRACK).reshape(-1) if len(idx) else np.zeros(0, _TRACK)
    pairs = np.stack([track["image_id"], track["point2d_idx"]], axis=1).astype(np.int64)
    return {"ids": heads["id"].astype(np.int64), "xyz": heads["xyz"].astype(np.float64),
            "rgb": heads["rgb"].astype(np.uint8), "error": heads["error"].astype(np.float64),
            "tracks": np.split(pairs, np.cumsum(lengths)[:-1])}


# -- writing -----------------------------------------------------------------

def write_model(folder: str | Path, model: ColmapModel, binary: bool = False) -> Path:
    """Write ``model`` as a standard COLMAP model into ``folder``.

    A new folder is filled under a temporary name and renamed into place; in
    an existing folder each file is replaced atomically, ``cameras`` last (the
    file readers look for). Files of the other format (and COLMAP 4's
    rigs/frames files, which would disagree with the new poses) are removed so
    readers never mix two models. ``frame.json`` is written when
    ``model.frame`` is not empty.
    """
    folder = Path(folder)
    if not folder.exists():
        with atomic_path(folder) as tmp:
            tmp.mkdir()
            _write_files(tmp, model, binary)
        return folder
    _write_files(folder, model, binary)
    return folder


def _write_files(folder: Path, model: ColmapModel, binary: bool) -> None:
    ext = "bin" if binary else "txt"
    qs = matrix_to_quaternion(np.array([c.R for c in model.cameras]).reshape(-1, 3, 3))
    if model.frame:
        write_text(folder / FRAME_FILE, json.dumps(model.frame, indent=2, default=float))
    else:
        (folder / FRAME_FILE).unlink(missing_ok=True)
    writers = {"points3D": _write_points3d_bin if binary else _write_points3d_txt,
               "images": _write_images_bin if binary else _write_images_txt,
               "cameras": _write_cameras_bin if binary else _write_cameras_txt}
    for part, writer in writers.items():
        with atomic_path(folder / f"{part}.{ext}") as tmp:
            writer(tmp, model, qs)
    other = "txt" if binary else "bin"
    for part in ("cameras", "images", "points3D", "rigs", "frames"):
        (folder / f"{part}.{other}").unlink(missing_ok=True)
        if part in ("rigs", "frames"):
            (folder / f"{part}.{ext}").unlink(missing_ok=True)


def _fmt(values: np.ndarray) -> str:
    return " ".join(repr(float(v)) for v in values)


def _write_cameras_txt(path: Path, model: ColmapModel, qs: np.ndarray) -> None:
    lines = ["# Camera list with one line of data per camera:",
             "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]",
             f"# Number of cameras: {len(model.intrinsics)}"]
    for cid, cam in sorted(model.intrinsics.items()):
        lines.append(f"{cid} {cam.model} {cam.width} {cam.height} {_fmt(cam.params)}")
    path.write_text("\n".join(lines) + "\n")


def _observations(model: ColmapModel, i: int) -> np.ndarray:
    if model.points2d is None or i >= len(model.points2d):
        return np.zeros((0, 3))
    return np.asarray(model.points2d[i], np.float64).reshape(-1, 3)


def _write_images_txt(path: Path, model: ColmapModel, qs: np.ndarray) -> None:
    lines = ["# Image list with two lines of data per image:",
             "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
             "#   POINTS2D[] as (X, Y, POINT3D_ID)",
             f"# Number of images: {len(model.cameras)}"]
    for i, cam in enumerate(model.cameras):
        lines.append(f"{model.image_ids[i]} {_fmt(qs[i])} {_fmt(cam.t)} "
                     f"{model.camera_ids[i]} {cam.name}")
        obs = _observations(model, i)
        lines.append(" ".join(f"{x!r} {y!r} {int(pid)}" for x, y, pid in obs.tolist()))
    path.write_text("\n".join(lines) + "\n")


def _track_text(track: np.ndarray) -> str:
    return " ".join(map(str, np.asarray(track, np.int64).ravel().tolist()))


def _write_points3d_txt(path: Path, model: ColmapModel, qs: np.ndarray) -> None:
    n = len(model.points)
    tracks = model.tracks if model.tracks is not None and len(model.tracks) == n else None
    lines = ["# 3D point list with one line of data per point:",
             "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)",
             f"# Number of points: {n}"]
    head = [f"{pid} {x!r} {y!r} {z!r} {r} {g} {b} {e!r}" for pid, (x, y, z), (r, g, b), e in
            zip(model.point_ids.tolist(), model.points.tolist(),
                model.point_colours.tolist(), model.point_errors.tolist(), strict=True)]
    if tracks is not None:
        head = [f"{h} {_track_text(t)}".rstrip() for h, t in zip(head, tracks, strict=True)]
    path.write_text("\n".join(lines + head) + "\n")


def _write_cameras_bin(path: Path, model: ColmapModel, qs: np.ndarray) -> None:
    chunks = [struct.pack("<Q", len(model.intrinsics))]
    for cid, cam in sorted(model.intrinsics.items()):
        chunks.append(struct.pack("<iiQQ", cid, MODEL_IDS[cam.model], cam.width, cam.height))
        chunks.append(np.asarray(cam.params, "<f8").tobytes())
    path.write_bytes(b"".join(chunks))


def _write_images_bin(path: Path, model: ColmapModel, qs: np.ndarray) -> None:
    chunks = [struct.pack("<Q", len(model.cameras))]
    for i, cam in enumerate(model.cameras):
        chunks.append(struct.pack("<I7dI", model.image_ids[i], *qs[i], *cam.t,
                                  model.camera_ids[i]))
        chunks.append(cam.name.encode("utf-8") + b"\0")
        obs = _observations(model, i)
        rec = np.empty(len(obs), _POINT2D)
        rec["x"], rec["y"], rec["id"] = obs[:, 0], obs[:, 1], obs[:, 2].astype(np.int64)
        chunks.append(struct.pack("<Q", len(obs)) + rec.tobytes())
    path.write_bytes(b"".join(chunks))


def _write_points3d_bin(path: Path, model: ColmapModel, qs: np.ndarray) -> None:
    n = len(model.points)
    tracks = (model.tracks if model.tracks is not None and len(model.tracks) == n
              else [np.zeros((0, 2), np.int64)] * n)
    lengths = np.fromiter((len(t) for t in tracks), np.int64, n)
    heads = np.empty(n, _POINT3D_HEAD)
    heads["id"], heads["xyz"] = model.point_ids, model.points
    heads["rgb"], heads["error"], heads["track_length"] = (
        model.point_colours, model.point_errors, lengths)
    flat = (np.concatenate([np.asarray(t, np.int64).reshape(-1, 2) for t in tracks])
            if n else np.zeros((0, 2), np.int64))
    track = np.empty(len(flat), _TRACK)
    track["image_id"], track["point2d_idx"] = flat[:, 0], flat[:, 1]
    # Interleave each point's fixed head with its track bytes.
    head_bytes = heads.view(np.uint8).reshape(n, -1)
    track_bytes = track.view(np.uint8)
    out = np.empty(8 + head_bytes.size + track_bytes.size, np.uint8)
    out[:8] = np.frombuffer(struct.pack("<Q", n), np.uint8)
    rec_len = head_bytes.shape[1] + 8 * lengths
    rec_start = 8 + np.concatenate([[0], np.cumsum(rec_len)[:-1]]).astype(np.int64)
    out[(rec_start[:, None] + np.arange(head_bytes.shape[1])).ravel()] = head_bytes.ravel()
    if len(track_bytes):
        starts = np.repeat(rec_start + head_bytes.shape[1], lengths)
        within = np.arange(lengths.sum()) - np.repeat(np.cumsum(lengths) - lengths, lengths)
        idx = ((starts + 8 * within)[:, None] + np.arange(8)).ravel()
        out[idx] = track_bytes
    path.write_bytes(out.tobytes())


def _is_colmap_model(folder: Path) -> bool:
    return any((folder / f"cameras.{ext}").exists() for ext in ("txt", "bin"))


def find_colmap_model(folder: Path) -> Path | None:
    """The folder holding cameras/images files: ``folder``, or ``folder/0``."""
    if _is_colmap_model(folder):
        return folder
    for sub in (folder / "0", folder / "sparse" / "0", folder / "sparse"):
        if sub.is_dir() and _is_colmap_model(sub):
            return sub
    return None
