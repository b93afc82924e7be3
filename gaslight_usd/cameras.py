"""Cameras and directions: the conventions every module shares.

Pinhole cameras follow COLMAP: world-to-camera ``x_cam = R @ x_world + t``,
camera axes x right, y down, z forward; pixel centres at integer + 0.5 (the
top-left pixel's centre is (0.5, 0.5)).

Lat-long panoramas follow OpenEXR's ``envmap=latlong``: for column x of W and
row y of H (pixel centres), longitude = -2 pi ((x + 0.5) / W - 0.5), latitude =
pi (0.5 - (y + 0.5) / H), direction = (sin(lon) cos(lat), sin(lat),
cos(lon) cos(lat)). The image centre looks along +Z, a quarter width from the
left along +X, the top row is +Y. Directions are in the world frame. An image is
taken for a lat-long panorama when it is 2:1 within 1 % (:func:`is_latlong`).

Cube maps follow OpenEXR's ``envmap=cube``: faces +X, -X, +Y, -Y, +Z, -Z
(:data:`CUBE_FACES`), each a 90-degree pinhole camera whose axes (image right,
image down, view direction) :data:`CUBE_FACE_AXES` gives; every face is a
right-handed camera like any other.

Sampling is bilinear at continuous pixel coordinates, pixel centres at +0.5
(:func:`bilinear`); lat-long images wrap in longitude (:func:`sample_latlong`).

Every module takes these from here, so a panorama cut for SfM, uplifted face by
face or rendered from splats means the same directions everywhere.
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

    def pixels_of(self, points: np.ndarray, shape: tuple[int, ...]
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World points (N, 3) -> column and row indices (N,) in an image of ``shape``
        (H, W, ...) covering this camera's frame at any size, and whether each lies in
        front of the camera and inside the image (the indices are -1 elsewhere)."""
        uv, z = self.project(points)
        return self._indices(uv[:, 0], uv[:, 1], z, shape)

    def pixels_of_grid(self, base: np.ndarray, u: np.ndarray, v: np.ndarray,
                       gu: np.ndarray, gv: np.ndarray, shape: tuple[int, ...]
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`pixels_of` for the grid of points ``base + gu[i] u + gv[j] v``, in the
        order of ``np.meshgrid(gu, gv, indexing="ij")`` raveled. A plane's grid is one
        affine map in camera space: the outer sums cost a fraction of projecting each
        point (the lit outlines sweep grids of up to 160 000 cells through every view at
        21 depths)."""
        o = self.R @ np.asarray(base, np.float64) + self.t
        ru, rv = self.R @ np.asarray(u, np.float64), self.R @ np.asarray(v, np.float64)
        gu = np.asarray(gu, np.float64)[:, None]
        gv = np.asarray(gv, np.float64)[None, :]
        cam = [(o[k] + gu * ru[k] + gv * rv[k]).ravel() for k in range(3)]
        z = cam[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            px = self.fx * cam[0] / z + self.cx
            py = self.fy * cam[1] / z + self.cy
        return self._indices(px, py, z, shape)

    def _indices(self, px: np.ndarray, py: np.ndarray, z: np.ndarray,
                 shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        h, w = shape[:2]
        ahead = z > 0
        px = np.where(np.isfinite(px) & ahead, px, -1.0)
        py = np.where(np.isfinite(py) & ahead, py, -1.0)
        x = np.floor(px * w / self.width).astype(np.int64)
        y = np.floor(py * h / self.height).astype(np.int64)
        inside = ahead & (x >= 0) & (x < w) & (y >= 0) & (y < h)
        return np.where(inside, x, -1), np.where(inside, y, -1), inside

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
    out = np.empty((height, width, 3), np.float64)
    # the sines and cosines of one row and one column, multiplied out (a 2048-wide
    # panorama's 2M directions in a third of the time trigonometry per pixel took)
    out[..., 0] = np.cos(lat)[:, None] * np.sin(lon)[None, :]
    out[..., 1] = np.sin(lat)[:, None]
    out[..., 2] = np.cos(lat)[:, None] * np.cos(lon)[None, :]
    return out


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


LATLONG_ASPECT = 2.0
"""Width over height of a lat-long panorama."""


def is_latlong(width: int, height: int, tolerance: float = 0.01) -> bool:
    """Whether an image of this size has a lat-long panorama's 2:1 shape (within 1 %).

    A tolerance, because resized or cropped panoramas are often a pixel off 2:1.
    """
    return height > 0 and abs(width / height - LATLONG_ASPECT) <= tolerance * LATLONG_ASPECT


def bilinear(image: np.ndarray, x: np.ndarray, y: np.ndarray, wrap_x: bool = False
             ) -> np.ndarray:
    """Sample (H, W, C) at continuous pixel coordinates (centres at +0.5), float32 out.

    Rows clamp at the top and bottom; columns clamp too, or wrap around with
    ``wrap_x`` (a lat-long panorama's left/right seam).
    """
    h, w = image.shape[:2]
    fx, fy = x - 0.5, np.clip(y - 0.5, 0.0, h - 1)
    if not wrap_x:
        fx = np.clip(fx, 0.0, w - 1)
    x0, y0 = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
    ax, ay = (fx - x0)[..., None], (fy - y0)[..., None]
    y1 = np.minimum(y0 + 1, h - 1)
    if wrap_x:
        x0, x1 = x0 % w, (x0 + 1) % w
    else:
        x1 = np.minimum(x0 + 1, w - 1)
    top = image[y0, x0] * (1 - ax) + image[y0, x1] * ax
    bottom = image[y1, x0] * (1 - ax) + image[y1, x1] * ax
    return (top * (1 - ay) + bottom * ay).astype(np.float32)


def sample_latlong(panorama: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Bilinear lookup of a lat-long panorama (H, W, C) in unit directions (..., 3).

    Returns (..., C) float32; longitude wraps, latitude clamps.
    """
    pano = np.asarray(panorama, np.float32)
    h, w = pano.shape[:2]
    xy = direction_to_latlong(directions, w, h)
    return bilinear(pano, xy[..., 0], xy[..., 1], wrap_x=True)


CUBE_FACES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")
"""The faces of a cube map in OpenEXR order."""

_X, _Y, _Z = np.eye(3)
CUBE_FACE_AXES = {
    "+X": (_Z, -_Y, _X),
    "-X": (-_Z, -_Y, -_X),
    "+Y": (_X, -_Z, _Y),
    "-Y": (_X, _Z, -_Y),
    "+Z": (-_X, -_Y, _Z),
    "-Z": (_X, -_Y, -_Z),
}
"""Face -> (image right, image down, view direction) as world unit vectors; stacked as
rows they are the face camera's world-to-camera rotation."""


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
