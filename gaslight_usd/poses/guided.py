"""Feature matches guided by known poses: the epipolar line says where a match can be.

Triangulating with the poses fixed (:func:`gaslight_usd.poses.sfm.triangulate_known_poses`)
first matches SIFT features the usual way, each feature against every feature of the
other view with Lowe's ratio test, then keeps the pairs a RANSAC fit of their epipolar
geometry verifies. On smooth textures (plaster, paint, a room's walls at a few hundred
pixels across) the ratio test fails: many features look alike, the best match is rarely
clearly better than the second, and most pairs of views end with too few matches to
verify. A wall with few points is drawn where the fit's start guessed it, and a window in
it with it, off the wall and into the room, where a probe by the window sees it from
behind (``gaslight2usd bench --suite chain --scene shade``; ``docs/measurements.md``).

With the poses known the geometry need not be guessed: a feature's match in another
view lies within a few pixels of its epipolar line. The ratio test then runs among those
candidates only, both ways (mutual best), and the matches are written as the pair's
verified geometry for COLMAP's triangulator, which builds tracks and drops points that
do not reproject; a point must then be seen in :data:`MIN_TRACK` views. Without the
poses this module has nothing to offer. The cameras are taken as pinholes: a lens's
distortion must stay within :data:`EPIPOLAR_PX`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..cameras import PinholeCamera
from .agreement import essential

EPIPOLAR_PX = 2.0
"""Largest distance (pixels, both ways) of a match from its epipolar line: given poses
agree with COLMAP's verified matches to under a pixel on the bench's sets
(``pose_agreement``); a capture rig or an SfM solve of real photos to one or two."""
RATIO = 0.8
"""Lowe's ratio among the candidates near the epipolar line."""
MAX_DESCRIPTOR_DISTANCE = 0.7
"""Largest L2 distance of two unit SIFT descriptors that may match (COLMAP's default)."""
MAX_FEATURES = 2048
"""At most this many features per view are matched this way (the largest): every pair
costs the product of their counts (two 2048 x 2048 float32 tables, 34 MB)."""
MIN_TRACK = 3
"""Views a point triangulated with guided matches must be seen in: two views cannot tell
a match from a look-alike elsewhere on the same epipolar line, a third can (on the
bench's rooms two-view points were the outliers, ``docs/measurements.md``)."""
MIN_MATCHES = 15
"""Fewer guided matches than this between two views are not written (COLMAP's own
least number of inliers for a verified pair)."""


def fundamental(cam_a: PinholeCamera, cam_b: PinholeCamera) -> np.ndarray:
    """(3, 3) F with ``x_b^T F x_a = 0`` for pixel positions of one point in both views."""
    return np.linalg.inv(cam_b.K).T @ essential(cam_a, cam_b) @ np.linalg.inv(cam_a.K)


def epipolar_distances(F: np.ndarray, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
    """(Na, Nb) the larger of each pair's two point-to-epipolar-line distances (pixels)."""
    ha = np.column_stack([xa, np.ones(len(xa))])
    hb = np.column_stack([xb, np.ones(len(xb))])
    la = ha @ F.T  # lines in view b, (Na, 3)
    lb = hb @ F  # lines in view a, (Nb, 3)
    algebraic = np.abs(la @ hb.T).astype(np.float32)  # (Na, Nb): |x_b^T F x_a|
    in_b = 1.0 / np.maximum(np.hypot(la[:, 0], la[:, 1]), 1e-12).astype(np.float32)
    in_a = 1.0 / np.maximum(np.hypot(lb[:, 0], lb[:, 1]), 1e-12).astype(np.float32)
    return algebraic * np.maximum(in_b[:, None], in_a[None, :])


def unit_descriptors(descriptors: np.ndarray) -> np.ndarray:
    """(N, 128) float descriptors scaled to unit length."""
    d = np.asarray(descriptors, np.float32)
    return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)


def _best_two(dist: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row of ``dist``: the column of the least value, it, and the second least."""
    rows = np.arange(len(dist))
    best = np.argmin(dist, axis=1)
    d1 = dist[rows, best]
    held = dist[rows, best].copy()
    dist[rows, best] = np.inf
    d2 = dist.min(axis=1)
    dist[rows, best] = held
    return best, d1, d2


def guided_pair_matches(xa: np.ndarray, da: np.ndarray, xb: np.ndarray, db: np.ndarray,
                        F: np.ndarray, max_px: float = EPIPOLAR_PX, ratio: float = RATIO
                        ) -> np.ndarray:
    """(M, 2) indices (into a, into b) of mutual best matches among each feature's
    candidates within ``max_px`` of its epipolar line, each passing the ratio test
    against its second candidate there, both ways. ``da``, ``db``: unit descriptors;
    ``F``: :func:`fundamental` from a to b."""
    if not len(xa) or not len(xb):
        return np.zeros((0, 2), np.int64)
    dist = np.sqrt(np.maximum(2.0 - 2.0 * (da @ db.T), 0.0), dtype=np.float32)
    dist[epipolar_distances(F, xa, xb) > max_px] = np.inf
    best_b, d1_a, d2_a = _best_two(dist)
    best_a, d1_b, d2_b = _best_two(dist.T)
    a = np.arange(len(xa))
    ok = (np.isfinite(d1_a) & (d1_a <= MAX_DESCRIPTOR_DISTANCE) & (d1_a < ratio * d2_a)
          & (best_a[best_b] == a) & (d1_b[best_b] < ratio * d2_b[best_b]))
    return np.column_stack([a[ok], best_b[ok]]).astype(np.int64)


def strongest(keypoints: np.ndarray, count: int = MAX_FEATURES) -> np.ndarray:
    """Indices of the ``count`` keypoints (COLMAP's rows: x, y, then the affine shape)
    of largest scale, the most repeatable across views; all when there are fewer."""
    if len(keypoints) <= count:
        return np.arange(len(keypoints))
    k = np.asarray(keypoints, np.float64)
    scale = (np.abs(k[:, 2] * k[:, 5] - k[:, 3] * k[:, 4]) if k.shape[1] >= 6
             else np.abs(k[:, 2]) if k.shape[1] >= 3 else np.ones(len(k)))
    return np.sort(np.argsort(-scale, kind="stable")[:count])


def share_view(cam_a: PinholeCamera, cam_b: PinholeCamera, depths: np.ndarray) -> bool:
    """Whether some point a sees (a 5 x 5 grid of its pixels at ``depths``) lies in front
    of b and inside its frame: pairs that cannot share a feature are not compared."""
    u, v = np.meshgrid(np.linspace(0, cam_a.width, 5), np.linspace(0, cam_a.height, 5))
    rays = np.stack([(u.ravel() - cam_a.cx) / cam_a.fx, (v.ravel() - cam_a.cy) / cam_a.fy,
                     np.ones(u.size)], -1) @ cam_a.R
    points = cam_a.center + (rays[:, None, :] * depths[None, :, None]).reshape(-1, 3)
    uv, z = cam_b.project(points)
    inside = ((z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < cam_b.width) & (uv[:, 1] >= 0)
              & (uv[:, 1] < cam_b.height))
    return bool(inside.any())


def add_guided_matches(db: Any, cameras: dict[int, PinholeCamera],
                       max_px: float = EPIPOLAR_PX) -> int:
    """Write guided matches (module docstring) for every pair of ``cameras`` (database
    image id -> posed camera, in the keypoints' pixels) into the COLMAP database ``db``,
    each pair's union with the matches it already verified, as a calibrated two-view
    geometry; returns how many matches were added."""
    import pycolmap

    ids = sorted(cameras)
    keep, points, descriptors = {}, {}, {}
    for i in ids:
        keypoints = np.asarray(db.read_keypoints(i), np.float64)
        keypoints = keypoints if keypoints.size else np.zeros((0, 6))
        keep[i] = strongest(keypoints)
        points[i] = keypoints[keep[i], :2]
        descriptors[i] = unit_descriptors(np.asarray(db.read_descriptors(i).data)[keep[i]])
    centres = np.array([cameras[i].center for i in ids])
    spread = max(float(np.linalg.norm(centres - centres.mean(0), axis=1).max()), 1e-2)
    depths = spread * np.geomspace(0.05, 20.0, 24)  # near to far, in the cameras' scale
    added = 0
    for k, a in enumerate(ids):
        for b in ids[k + 1:]:
            if not share_view(cameras[a], cameras[b], depths):
                continue
            F = fundamental(cameras[a], cameras[b])
            pairs = guided_pair_matches(points[a], descriptors[a], points[b],
                                        descriptors[b], F, max_px)
            found = np.column_stack([keep[a][pairs[:, 0]], keep[b][pairs[:, 1]]])
            have = np.zeros((0, 2), np.int64)
            if db.exists_two_view_geometry(a, b):
                have = np.asarray(db.read_two_view_geometry(a, b).inlier_matches,
                                  np.int64).reshape(-1, 2)
            union = np.unique(np.concatenate([have, found]), axis=0)
            if len(union) < MIN_MATCHES or len(union) == len(have):
                continue
            added += len(union) - len(have)
            geometry = pycolmap.TwoViewGeometry()
            geometry.config = pycolmap.TwoViewGeometryConfiguration.CALIBRATED
            geometry.F = F
            geometry.inlier_matches = union.astype(np.uint32)
            if db.exists_two_view_geometry(a, b):
                db.delete_two_view_geometry(a, b)
            if db.exists_matches(a, b):
                db.delete_matches(a, b)
            db.write_matches(a, b, union.astype(np.uint32))
            db.write_two_view_geometry(a, b, geometry)
    return added
