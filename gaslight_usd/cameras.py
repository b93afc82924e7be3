"""Cameras and directions: the conventions every module shares.

Pinhole cameras follow COLMAP: world-to-camera ``x_cam = R @ x_world + t``,
camera axes x right, y down, z forward; pixel centres at integer + 0.5 (the
top-left pixel's centre is (0.5, 0.5)).

Lat-long panoramas follow OpenEXR's ``envmap=latlong``: for column x of W and
row y of H (pixel centres), longitude = -2 pi ((x + 0.5) / W - 0.5), latitude =
pi (0.5 - (y + 0.5) / H), direction = (sin(lon) cos(lat), sin(lat),
cos(lon) cos(lat)). The image centre looks along +Z, a quarter width from the
left along +X, the top row is +Y. Directions are in the world frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class PinholeCamera:
    """A posed pinhole camera (COLMAP conventions)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    R: np.ndarray
    """(3, 3) world-to-camera rotation."""
    t: np.ndarray
    """(3,) world-to-camera translation."""
    name: str = ""

    @property
    def center(self) -> np.ndarray:
        """Camera centre in world coordinates, ``-R^T t``."""
        return (-self.R.T @ self.t).astype(np.float64)

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1]], np.float64)

    @property
    def world_to_camera(self) -> np.ndarray:
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = self.R, self.t
        return m

    @property
    def camera_to_world(self) -> np.ndarray:
        return np.linalg.inv(self.world_to_camera)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points (N, 3) -> pixel coordinates (N, 2) and depths (N,)."""
        cam = np.asarray(points, np.float64) @ self.R.T + self.t
        z = cam[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = np.stack([self.fx * cam[:, 0] / z + self.cx,
                           self.fy * cam[:, 1] / z + self.cy], axis=1)
        return uv, z

    def ray_directions(self) -> np.ndarray:
        """(H, W, 3) unit world directions through every pixel centre."""
        xs = (np.arange(self.width) + 0.5 - self.cx) / self.fx
        ys = (np.arange(self.height) + 0.5 - self.cy) / self.fy
        gx, gy = np.meshgrid(xs, ys)
        d_cam = np.stack([gx, gy, np.ones_like(gx)], axis=-1)
        d_world = d_cam @ self.R  # R^T applied to row vectors
        return d_world / np.linalg.norm(d_world, axis=-1, keepdims=True)


def latlong_directions(width: int, height: int) -> np.ndarray:
    """(H, W, 3) unit world directions of a lat-long panorama's pixel centres."""
    lon = -2.0 * np.pi * ((np.arange(width) + 0.5) / width - 0.5)
    lat = np.pi * (0.5 - (np.arange(height) + 0.5) / height)
    lon, lat = np.meshgrid(lon, lat)
    return np.stack([np.sin(lon) * np.cos(lat), np.sin(lat), np.cos(lon) * np.cos(lat)],
                    axis=-1)


def direction_to_latlong(directions: np.ndarray, width: int, height: int) -> np.ndarray:
    """Unit directions (..., 3) -> continuous pixel coordinates (..., 2) as (x, y).

    The inverse of :func:`latlong_directions`: pixel centres map to integer + 0.5.
    """
    d = np.asarray(directions, np.float64)
    lon = np.arctan2(d[..., 0], d[..., 2])
    lat = np.arcsin(np.clip(d[..., 1], -1.0, 1.0))
    x = (0.5 - lon / (2.0 * np.pi)) * width
    y = (0.5 - lat / np.pi) * height
    return np.stack([x, y], axis=-1)


def latlong_solid_angles(width: int, height: int) -> np.ndarray:
    """(H, 1) solid angle of each pixel in a row of a lat-long panorama (sr)."""
    lat_edges = np.pi * (0.5 - np.arange(height + 1) / height)
    band = np.sin(lat_edges[:-1]) - np.sin(lat_edges[1:])
    return (band * (2.0 * np.pi / width))[:, None]


def quaternion_to_matrix(q: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) as w x y z (normalised here) -> rotation matrices (..., 3, 3)."""
    q = np.asarray(q, np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=-2)


def matrix_to_quaternion(m: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> unit quaternions (..., 4) as w x y z, w >= 0."""
    m = np.asarray(m, np.float64)
    t = np.trace(m, axis1=-2, axis2=-1)
    # Shepperd's method, picking the numerically largest component per matrix.
    cands = np.stack([
        1 + t,
        1 + 2 * m[..., 0, 0] - t,
        1 + 2 * m[..., 1, 1] - t,
        1 + 2 * m[..., 2, 2] - t,
    ], axis=-1)
    k = np.argmax(cands, axis=-1)
    s = np.sqrt(np.maximum(np.take_along_axis(cands, k[..., None], -1)[..., 0], 1e-300)) * 2
    w = np.stack([
        s / 4,
        (m[..., 2, 1] - m[..., 1, 2]) / s,
        (m[..., 0, 2] - m[..., 2, 0]) / s,
        (m[..., 1, 0] - m[..., 0, 1]) / s,
    ], -1)
    x = np.stack([
        (m[..., 2, 1] - m[..., 1, 2]) / s,
        s / 4,
        (m[..., 0, 1] + m[..., 1, 0]) / s,
        (m[..., 0, 2] + m[..., 2, 0]) / s,
    ], -1)
    y = np.stack([
        (m[..., 0, 2] - m[..., 2, 0]) / s,
        (m[..., 0, 1] + m[..., 1, 0]) / s,
        s / 4,
        (m[..., 1, 2] + m[..., 2, 1]) / s,
    ], -1)
    z = np.stack([
        (m[..., 1, 0] - m[..., 0, 1]) / s,
        (m[..., 0, 2] + m[..., 2, 0]) / s,
        (m[..., 1, 2] + m[..., 2, 1]) / s,
        s / 4,
    ], -1)
    table = np.stack([w, x, y, z], axis=-2)  # (..., 4 cases, 4 comps)
    q = np.take_along_axis(table, k[..., None, None], axis=-2)[..., 0, :]
    q = q * np.where(q[..., :1] < 0, -1.0, 1.0)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)
