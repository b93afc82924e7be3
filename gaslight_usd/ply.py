"""3DGS PLY read and write (binary little-endian), vectorised with plyfile.

Property set (the 3DGS convention, read by every splat tool): x y z, optional
nx ny nz, f_dc_0..2, f_rest_0..(3*(K-1)-1) stored channel-major (all red
coefficients, then green, then blue), opacity (logit), scale_0..2 (log),
rot_0..3 (w x y z). Metadata (colour space, exposure scale, units...) travels
as ``comment gaslight <key> <json value>`` header lines.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from plyfile import PlyData, PlyElement

from .atomic import atomic_path
from .errors import InputError
from .splats import SplatScene, sh_coefficient_count, sh_degree_from_count

COMMENT_PREFIX = "gaslight "
_REQUIRED = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]


def _property_names(degree: int, with_normals: bool) -> list[str]:
    names = ["x", "y", "z"]
    if with_normals:
        names += ["nx", "ny", "nz"]
    names += ["f_dc_0", "f_dc_1", "f_dc_2"]
    names += [f"f_rest_{i}" for i in range(3 * (sh_coefficient_count(degree) - 1))]
    names += ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    return names


def write_ply(path: str | Path, scene: SplatScene, with_normals: bool = True) -> Path:
    """Write ``scene`` as a binary 3DGS PLY, atomically."""
    n, k = scene.count, scene.sh.shape[1]
    normals = scene.normals if scene.normals is not None else np.zeros((n, 3), np.float32)
    # f_rest is channel-major: (N, K-1, 3) -> (N, 3, K-1) -> (N, 3*(K-1))
    rest = np.ascontiguousarray(scene.sh[:, 1:].transpose(0, 2, 1)).reshape(n, 3 * (k - 1))
    columns = [scene.positions]
    if with_normals:
        columns.append(normals)
    columns += [scene.sh[:, 0], rest, scene.opacity_logits[:, None], scene.log_scales,
                scene.rotations]
    table = np.concatenate([np.asarray(c, dtype=np.float32) for c in columns], axis=1)
    names = _property_names(scene.sh_degree, with_normals)
    dtype = np.dtype([(name, "<f4") for name in names])
    vertices = np.ascontiguousarray(table).view(dtype).reshape(n)
    comments = [COMMENT_PREFIX + f"{key} {json.dumps(value)}"
                for key, value in sorted(scene.metadata.items())]
    data = PlyData([PlyElement.describe(vertices, "vertex")], text=False,
                   byte_order="<", comments=comments)
    with atomic_path(path) as tmp:
        data.write(str(tmp))
    return Path(path)


def _parse_comments(comments: list[str]) -> dict:
    meta = {}
    for line in comments:
        if not line.startswith(COMMENT_PREFIX):
            continue
        key, _, raw = line[len(COMMENT_PREFIX):].partition(" ")
        try:
            meta[key] = json.loads(raw)
        except json.JSONDecodeError:
            meta[key] = raw
    return meta


def read_ply(path: str | Path) -> SplatScene:
    """Read a 3DGS PLY written by this project or any other 3DGS tool."""
    path = Path(path)
    if not path.exists():
        raise InputError("no such file", path)
    try:
        data = PlyData.read(str(path))
    except Exception as exc:
        raise InputError(f"cannot read PLY: {exc}", path) from exc
    if "vertex" not in data:
        raise InputError("PLY has no 'vertex' element", path)
    vertex = data["vertex"].data
    names = set(vertex.dtype.names or ())
    missing = [p for p in _REQUIRED if p not in names]
    if missing:
        raise InputError(
            "not a 3DGS splat PLY: missing properties " + ", ".join(missing), path
        )
    n = len(vertex)
    rest_names = sorted((p for p in names if p.startswith("f_rest_")),
                        key=lambda p: int(p.split("_")[-1]))
    try:
        k = sh_degree_from_count(len(rest_names) // 3 + 1)
    except ValueError as exc:
        raise InputError(f"{len(rest_names)} f_rest properties: {exc}", path) from exc
    k = sh_coefficient_count(k)

    fields = list(vertex.dtype.names or ())
    packed_f4 = n > 0 and vertex.dtype.itemsize == 4 * len(fields) and all(
        vertex.dtype[f] == np.dtype("<f4") for f in fields)
    # All-float32 PLYs (nearly every 3DGS file): one (N, P) view, columns gathered at once.
    # one sequential copy out of plyfile's memory map, then column gathers in memory
    # (a float view copied as one block; gathering from the map or copying the
    # structured array field by field is 3-5x slower)
    table = (np.asarray(vertex).view("<f4").reshape(n, len(fields)).copy() if packed_f4
             else None)

    def stack(props: list[str]) -> np.ndarray:
        if not props:
            return np.zeros((n, 0), dtype=np.float32)
        if table is not None:
            cols = [fields.index(p) for p in props]
            if cols == list(range(cols[0], cols[0] + len(cols))):  # the usual layout
                return np.ascontiguousarray(table[:, cols[0]:cols[0] + len(cols)])
            # np.take gathers columns several times faster than fancy indexing here
            return np.take(table, cols, axis=1)
        return np.stack([np.asarray(vertex[p], dtype=np.float32) for p in props], axis=1)

    sh = np.empty((n, k, 3), dtype=np.float32)
    sh[:, 0] = stack(["f_dc_0", "f_dc_1", "f_dc_2"])
    if k > 1:
        sh[:, 1:] = stack(rest_names).reshape(n, 3, k - 1).transpose(0, 2, 1)
    normals = stack(["nx", "ny", "nz"]) if {"nx", "ny", "nz"} <= names else None
    scene = SplatScene(
        positions=stack(["x", "y", "z"]),
        rotations=stack(["rot_0", "rot_1", "rot_2", "rot_3"]),
        log_scales=stack(["scale_0", "scale_1", "scale_2"]),
        opacity_logits=stack(["opacity"])[:, 0].copy(),
        sh=sh,
        normals=normals,
        metadata=_parse_comments(list(data.comments)),
    )
    bad = out_of_range(scene)
    if bad.any():
        raise InputError(f"{int(bad.sum())} splat(s) have NaN, infinite or out-of-range "
                         f"values (the first: splat {int(np.argmax(bad))}); a damaged file?",
                         path)
    return scene


MAX_COORDINATE = 1e15
MAX_LOG_SCALE = 60.0
"""exp(60) ~ 1e26: a larger log scale overflows float32 once squared."""


def out_of_range(scene: SplatScene) -> np.ndarray:
    """Per splat: any value NaN or infinite, a coordinate beyond :data:`MAX_COORDINATE`,
    a log scale beyond :data:`MAX_LOG_SCALE` or a zero rotation quaternion (what a
    damaged file holds; drawing them would fail later, far from the cause)."""
    bad = ~np.isfinite(scene.sh).all(axis=(1, 2)) | ~np.isfinite(scene.opacity_logits)
    bad |= ~(np.abs(scene.positions) <= MAX_COORDINATE).all(axis=1)
    bad |= ~(np.abs(scene.log_scales) <= MAX_LOG_SCALE).all(axis=1)
    norm = np.linalg.norm(scene.rotations.astype(np.float64), axis=1)
    return bad | ~(np.isfinite(norm) & (norm > 0))
