"""The room's walls and ceiling drawn as sheets: the splats on a plane of the room's box
squashed flat onto it at the end of the fit.

A fit draws a wall or a ceiling with round splats a few centimetres thick about its
plane: seen square on they add up to the surface, but seen at a grazing angle the ones in
front stand up from it like pebbles and hide what is flush with it: from true HDR views a
probe low under the ceiling saw a ceiling panel partly hidden by the ceiling's own round
splats in front of it (``docs/measurements.md``, session 63).

Each splat whose centre is within :data:`SHEET_BAND_SHARE` of the scene's extent of a
plane of the room's box (:func:`gaslight_usd.fit.planes.room_box`), and that is not a
light, is squashed along that plane's normal to at most :data:`SHEET_THIN_SHARE` of the
extent thick: its covariance ``A S A^T`` with ``A = I - (1 - k) n n^T``. Seen along the
normal its footprint is unchanged (``A`` leaves the plane's directions as they are), so a
view square on draws the same; seen obliquely it is a disc in the plane, and discs that
tiled the surface still tile it. Measured by ``gaslight2usd bench --suite chain`` at the
probes that see a panel or a window at a grazing angle (``docs/measurements.md``).
"""

from __future__ import annotations

import numpy as np

from ..cameras import matrix_to_quaternion, quaternion_to_matrix
from ..splats import SplatScene
from .planes import Plane

SHEET_BAND_SHARE = 0.07
"""Splats whose centre is this near a plane of the room's box (a share of the scene's
extent: 12 cm in the chain bench's rooms) are that plane's."""
SHEET_THIN_SHARE = 0.003
"""...and are squashed to at most this thick along its normal (5 mm there)."""


def sheet_splats(scene: SplatScene, planes: list[Plane], extent: float,
                 exempt: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(rows, normals): the splats of ``scene`` within the band of a plane of the room's
    box (the nearest plane's normal for each), less those ``exempt`` ((N,) mask: lights,
    the backdrop)."""
    if not planes or scene.count == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3))
    normals = np.array([p.normal for p in planes], np.float64)
    offsets = np.array([p.offset for p in planes], np.float64)
    gap = np.abs(scene.positions.astype(np.float64) @ normals.T - offsets)
    nearest = np.argmin(gap, axis=1)
    near = gap[np.arange(scene.count), nearest] <= SHEET_BAND_SHARE * extent
    if exempt is not None:
        near &= ~np.asarray(exempt, bool)
    rows = np.flatnonzero(near)
    return rows, normals[nearest[rows]]


def squashed(scene: SplatScene, rows: np.ndarray, normals: np.ndarray, thin: float
             ) -> tuple[SplatScene, int]:
    """``scene`` with splats ``rows`` squashed along their ``normals`` ((len(rows), 3),
    unit) to at most ``thin`` thick (the std-dev along the normal); returns the scene and
    how many were thicker than that."""
    if not len(rows):
        return scene, 0
    rot = quaternion_to_matrix(scene.rotations[rows])
    var = np.exp(2.0 * scene.log_scales[rows].astype(np.float64))
    cov = np.einsum("nij,nj,nkj->nik", rot, var, rot)
    thick = np.sqrt(np.maximum(np.einsum("ni,nij,nj->n", normals, cov, normals), 1e-30))
    over = thick > thin * (1.0 + 1e-3)  # float32 round trip: a squashed one stays squashed
    if not over.any():
        return scene, 0
    n, k = normals[over], thin / thick[over]
    a = np.eye(3)[None] - (1.0 - k)[:, None, None] * np.einsum("ni,nj->nij", n, n)
    w, v = np.linalg.eigh(a @ cov[over] @ np.transpose(a, (0, 2, 1)))
    v[np.linalg.det(v) < 0, :, 0] *= -1.0  # a proper rotation
    out = scene.subset(np.arange(scene.count))
    pick = rows[over]
    out.log_scales[pick] = 0.5 * np.log(np.maximum(w, 1e-20))
    out.rotations[pick] = matrix_to_quaternion(v)
    return out, int(over.sum())
