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

from ..cameras import CUBE_FACE_AXES, PinholeCamera, sample_latlong

FACE_PREFIX = "cube_"

CUBE_FACE_OF = {"front": "+Z", "right": "-X", "back": "-Z", "left": "+X", "up": "+Y",
                "down": "-Y"}
"""Each rig face and its OpenEXR cube face (the panorama's own axes: +Y up, +Z at the
centre column)."""

FACE_FROM_PANO = {name: np.stack(CUBE_FACE_AXES[cube]) for name, cube in CUBE_FACE_OF.items()}
"""Rotation taking panorama-frame directions to each face camera's axes."""
FACES = {name: rot @ FACE_FROM_PANO["front"].T for name, rot in FACE_FROM_PANO.items()}
"""cam_from_rig rotation of each face, the rig being the front face's camera."""


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
    size = int(size or max(pix.shape[1] // 4, 1))
    faces = {}
    for face in FACES:
        cam = face_camera(face, size)
        dirs_rig = cam.ray_directions()  # in the rig (front camera) axes
        dirs_pano = dirs_rig @ FACE_FROM_PANO["front"]  # rows: R^T applied
        faces[face] = sample_latlong(pix, dirs_pano)
    return faces
