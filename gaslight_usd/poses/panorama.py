"""Lat-long panoramas as rigs of six cube-face pinhole cameras sharing one centre.

SfM cannot use an equirectangular photo directly; its six 90-degree cube faces
are ordinary pinhole images. The faces are cut with the project's lat-long
convention (:mod:`gaslight_usd.cameras`, OpenEXR ``envmap=latlong``). The rig
frame is the ``front`` face's camera (looking at the panorama's centre
column); :data:`FACES` gives each face's rotation from it. Face images are
named ``cube_<face>/<photo name>``, so COLMAP's rig config groups the six faces
of one photo into one frame (one pose) by the part after the prefix.
"""

from __future__ import annotations

import numpy as np

from ..cameras import PinholeCamera, direction_to_latlong

PANORAMA_ASPECT = 2.0
FACE_PREFIX = "cube_"

# face -> (forward, down) in the panorama's own axes (+Y up, +Z at the centre column)
_FACE_AXES = {
    "front": ((0, 0, 1), (0, -1, 0)),
    "right": ((-1, 0, 0), (0, -1, 0)),
    "back": ((0, 0, -1), (0, -1, 0)),
    "left": ((1, 0, 0), (0, -1, 0)),
    "up": ((0, 1, 0), (0, 0, 1)),
    "down": ((0, -1, 0), (0, 0, -1)),
}


def _face_from_pano(forward, down) -> np.ndarray:
    fwd, dn = np.asarray(forward, np.float64), np.asarray(down, np.float64)
    return np.stack([np.cross(dn, fwd), dn, fwd])  # rows: camera x, y, z in panorama axes


FACE_FROM_PANO = {name: _face_from_pano(*axes) for name, axes in _FACE_AXES.items()}
"""Rotation taking panorama-frame directions to each face camera's axes."""
FACES = {name: rot @ FACE_FROM_PANO["front"].T for name, rot in FACE_FROM_PANO.items()}
"""cam_from_rig rotation of each face, the rig being the front face's camera."""


def is_latlong(width: int, height: int, tolerance: float = 0.01) -> bool:
    """Whether an image of this size has a lat-long panorama's 2:1 shape."""
    return height > 0 and abs(width / height - PANORAMA_ASPECT) <= tolerance * PANORAMA_ASPECT


def face_name(face: str, photo_name: str) -> str:
    return f"{FACE_PREFIX}{face}/{photo_name}"


def face_camera(face: str, size: int, rig: PinholeCamera | None = None) -> PinholeCamera:
    """The pinhole camera (90-degree field of view) of one face.

    With ``rig`` (the front face's posed camera) the face is posed in the same
    world; without, the world is the panorama frame expressed in front-camera
    axes (identity front pose).
    """
    half = size / 2.0
    r_rig, t_rig = ((rig.R, rig.t) if rig is not None else (np.eye(3), np.zeros(3)))
    rot = FACES[face]
    return PinholeCamera(size, size, half, half, half, half, R=rot @ r_rig, t=rot @ t_rig,
                         name=face)


def cube_faces(pixels: np.ndarray, size: int | None = None) -> dict[str, np.ndarray]:
    """Cut a lat-long image (H, W, C) into six square faces of ``size`` pixels.

    Bilinear sampling, wrapping across the panorama's left/right seam; works on
    any dtype (result float32). ``size`` defaults to a quarter of the width.
    """
    pix = np.asarray(pixels, np.float32)
    if pix.ndim == 2:
        pix = pix[..., None]
    h, w = pix.shape[:2]
    size = int(size or max(w // 4, 1))
    faces = {}
    for face in FACES:
        cam = face_camera(face, size)
        dirs_rig = cam.ray_directions()  # in the rig (front camera) axes
        dirs_pano = dirs_rig @ FACE_FROM_PANO["front"]  # rows: R^T applied
        faces[face] = _bilinear_wrap(pix, direction_to_latlong(dirs_pano, w, h))
    return faces


def _bilinear_wrap(pix: np.ndarray, xy: np.ndarray) -> np.ndarray:
    h, w = pix.shape[:2]
    x = xy[..., 0] - 0.5
    y = np.clip(xy[..., 1] - 0.5, 0, h - 1)
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    x0w, x1w = x0 % w, (x0 + 1) % w
    y1 = np.minimum(y0 + 1, h - 1)
    top = pix[y0, x0w] * (1 - fx) + pix[y0, x1w] * fx
    bottom = pix[y1, x0w] * (1 - fx) + pix[y1, x1w] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32)
