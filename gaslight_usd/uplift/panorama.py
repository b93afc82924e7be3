"""360 degree panoramas: split a lat-long photo into cube faces, uplift each, reassemble.

Faces are rendered with a wider field of view than 90 degrees (``overlap``) so
a light source on a seam is seen whole by at least one face; back in lat-long
each pixel blends the faces that see it with a weight that falls to 0 at the
face border (the face's angular distance from its edge), so seams do not show.
Faces, lat-long directions and bilinear sampling are the project's conventions
(:mod:`gaslight_usd.cameras`: OpenEXR envmap=latlong and cube face order).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..cameras import CUBE_FACE_AXES, CUBE_FACES, bilinear, latlong_directions, sample_latlong


def _axes(face: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(forward, right, down) of cube face ``face`` (OpenEXR order)."""
    right, down, fwd = CUBE_FACE_AXES[CUBE_FACES[face]]
    return fwd, right, down


def face_directions(size: int, face: int, fov_scale: float = 1.0) -> np.ndarray:
    """(size, size, 3) unit directions of a face's pixel centres.

    ``fov_scale`` > 1 widens the face beyond 90 degrees (tan of half-angle).
    """
    fwd, right, down = _axes(face)
    t = ((np.arange(size) + 0.5) / size * 2.0 - 1.0) * fov_scale
    u, v = np.meshgrid(t, t)
    d = fwd + u[..., None] * right + v[..., None] * down
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _face_lookup(directions: np.ndarray, face: int, size: int, fov_scale: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pixel coordinates of ``directions`` on a face, and a seam weight (0 outside)."""
    fwd, right, down = _axes(face)
    z = directions @ fwd
    safe = np.where(z > 1e-6, z, 1.0)
    u = (directions @ right) / safe / fov_scale
    v = (directions @ down) / safe / fov_scale
    inside = (z > 1e-6) & (np.abs(u) < 1) & (np.abs(v) < 1)
    weight = np.where(inside, np.clip(1 - np.maximum(np.abs(u), np.abs(v)), 0, 1), 0.0)
    return (v + 1) / 2 * size - 0.5, (u + 1) / 2 * size - 0.5, weight


def latlong_to_faces(latlong: np.ndarray, size: int, fov_scale: float = 1.15
                     ) -> list[np.ndarray]:
    return [sample_latlong(latlong, face_directions(size, f, fov_scale)) for f in range(6)]


def faces_to_latlong(faces: list[np.ndarray], width: int, height: int,
                     fov_scale: float = 1.15) -> np.ndarray:
    """Blend (possibly widened) faces back into a lat-long image."""
    dirs = latlong_directions(width, height)
    size = faces[0].shape[0]
    acc = np.zeros((height, width, faces[0].shape[2]), np.float64)
    total = np.zeros((height, width), np.float64)
    for f, face in enumerate(faces):
        row, col, weight = _face_lookup(dirs, f, size, fov_scale)
        sel = weight > 0
        if not sel.any():
            continue
        vals = bilinear(face, col[sel] + 0.5, row[sel] + 0.5)
        acc[sel] += weight[sel, None] * vals
        total[sel] += weight[sel]
    return (acc / np.maximum(total, 1e-12)[..., None]).astype(np.float32)


def uplift_panorama(encoded: np.ndarray, uplift_face: Callable[[np.ndarray], np.ndarray],
                    face_size: int | None = None, fov_scale: float = 1.15) -> np.ndarray:
    """Uplift a lat-long encoded photo face by face; returns linear lat-long radiance.

    ``uplift_face(encoded_face) -> linear_face``. Faces are sampled from the
    encoded image (the predictor sees a perspective photo, as it was built for).
    """
    h, w = encoded.shape[:2]
    size = face_size or max(16, w // 4)
    faces = [uplift_face(face) for face in latlong_to_faces(encoded, size, fov_scale)]
    return faces_to_latlong(faces, w, h, fov_scale)
