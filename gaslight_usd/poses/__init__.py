"""The posed set, whichever form it comes in; sparse points coloured from HDR views.

:func:`read_poses` accepts a COLMAP model folder (text or binary, or a parent
with ``0/`` / ``sparse/0``), a ``transforms.json`` or a folder holding one, and
returns a :class:`~gaslight_usd.poses.colmap.ColmapModel`. :func:`write_poses` writes
a folder as a COLMAP model (text, or binary) and a ``.json`` path as a
transforms.json. Poses the user gives keep their own frame; when they carry no
``frame.json`` the frame facts say so (up axis estimated, units unknown).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..cameras import bilinear
from ..errors import InputError
from .colmap import ColmapModel, find_colmap_model, read_model, write_model
from .frame import given_frame
from .transforms_json import read_transforms, transforms_path, write_transforms


def read_poses(path: str | Path) -> ColmapModel:
    """A COLMAP model or a transforms.json as a :class:`ColmapModel`.

    ``model.frame`` always holds the frame facts: the stored ``frame.json`` (or
    ``gaslight_frame`` key) when present, else :func:`~gaslight_usd.poses.frame.given_frame`.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("no such poses file or folder", path)
    if path.is_file():
        if path.suffix.lower() != ".json":
            raise InputError("poses must be a COLMAP model folder or a transforms.json", path)
        model, source = read_transforms(path), "transforms.json"
    elif find_colmap_model(path) is not None:
        model, source = read_model(path), "colmap"
    elif transforms_path(path).exists():
        model, source = read_transforms(path), "transforms.json"
    else:
        raise InputError("holds no COLMAP model (cameras.txt/.bin, also in 0/ or sparse/0/) "
                         "and no transforms.json", path)
    if not model.cameras:
        raise InputError("the poses hold no registered image", path)
    model.frame = given_frame(model, f"given ({source})")
    return model


def write_poses(out: str | Path, model: ColmapModel, binary: bool = False) -> Path:
    """``out`` ending in ``.json``: a transforms.json; otherwise a COLMAP model folder."""
    out = Path(out)
    if out.suffix.lower() == ".json":
        return write_transforms(out, model)
    return write_model(out, model, binary=binary)


def _visibility(model: ColmapModel, views: list[int], uv: np.ndarray, depth: np.ndarray,
                sizes: list[tuple[int, int]]) -> np.ndarray:
    """(V, N) which views see which points: the tracks when known, else the frustum."""
    inside = np.stack([(depth[v] > 0) & (uv[v, :, 0] >= 0) & (uv[v, :, 0] < w) &
                       (uv[v, :, 1] >= 0) & (uv[v, :, 1] < h)
                       for v, (w, h) in enumerate(sizes)])
    tracks = model.tracks
    if tracks is None or len(tracks) != len(model.points) or not any(len(t) for t in tracks):
        return inside
    lengths = np.fromiter((len(t) for t in tracks), np.int64, len(tracks))
    point_of = np.repeat(np.arange(len(tracks)), lengths)
    image_of = np.concatenate([np.asarray(t, np.int64).reshape(-1, 2)[:, 0] for t in tracks])
    ids = np.array([model.image_ids[i] for i in views], np.int64)
    lut = np.full(max(int(ids.max()), int(image_of.max(initial=0))) + 1, -1, np.int64)
    lut[ids] = np.arange(len(views))
    row = lut[np.clip(image_of, 0, None)]
    seen = np.zeros_like(inside)
    keep = row >= 0
    seen[row[keep], point_of[keep]] = True
    return seen & inside


def colour_points(model: ColmapModel, hdr_views: dict[str, np.ndarray]) -> np.ndarray:
    """(N, 3) float32 linear HDR colour of each sparse point.

    Each point is projected into the views that see it (its track when the
    model has tracks, else every view whose frustum holds it, occlusion
    ignored), sampled bilinearly (views of another size than the camera are
    scaled to it) and the per-channel median over those views is taken.
    ``hdr_views`` maps an image name (or its stem) to an (H, W, 3) array.
    Points no view sees get the median colour of all the others.
    """
    n = len(model.points)
    if n == 0:
        return np.zeros((0, 3), np.float32)
    views, images = [], []
    for i, cam in enumerate(model.cameras):
        img = hdr_views.get(cam.name, hdr_views.get(Path(cam.name).stem))
        if img is not None:
            views.append(i)
            images.append(np.asarray(img, np.float32))
    if not views:
        raise InputError("no HDR view matches a posed image name "
                         f"(posed: {', '.join(model.names[:4])}...)")
    uv = np.empty((len(views), n, 2))
    depth = np.empty((len(views), n))
    for r, i in enumerate(views):
        cam = model.cameras[i]
        uv[r], depth[r] = cam.project(model.points)
        h, w = images[r].shape[:2]
        uv[r] *= np.array([w / cam.width, h / cam.height])
    sizes = [(im.shape[1], im.shape[0]) for im in images]
    seen = _visibility(model, views, uv, depth, sizes)
    samples = np.full((len(views), n, 3), np.nan, np.float32)
    for r, img in enumerate(images):
        idx = np.flatnonzero(seen[r])
        if len(idx):
            samples[r, idx] = bilinear(img, uv[r, idx, 0], uv[r, idx, 1])
    counts = seen.sum(0)
    out = np.empty((n, 3), np.float32)
    have = counts > 0
    if have.any():
        out[have] = np.nanmedian(samples[:, have], axis=0)
        out[~have] = np.median(out[have], axis=0)
    else:
        out[:] = 0.0
    return out
