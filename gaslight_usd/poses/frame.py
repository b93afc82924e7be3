"""World frames: similarity transforms of posed models, the SfM frame, pose errors.

SfM poses come in an arbitrary frame (COLMAP's first image pair). We move them
to a well-behaved one (:func:`sfm_frame`):

* **up**: +Y is the cameras' mean up vector (the world direction of each
  camera's -y axis), so exports are not upside down or tilted;
* **heading**: the cameras' mean viewing direction, flattened to the floor,
  looks along -Z (as a USD/OpenGL camera does);
* **floor**: the lowest dense layer of sparse points below the cameras (a
  height histogram's lowest bin holding at least :data:`FLOOR_PEAK_SHARE` of
  the fullest bin below the cameras), put at y = 0, as a TD expects a set;
* **origin**: on the floor under the cameras' median point (where the photos
  were taken from); without a floor, the cameras' median point itself;
* **scale**: kept as solved (units arbitrary: ``meters_per_unit`` is ``None``
  and ``scale_known`` false) unless the user gives a factor (``--scale``: metres
  per SfM unit), a known distance between two camera centres
  (``--scale-from A,B,DIST``) or the photos' median height above the floor
  (``--camera-height METRES``); then units are metres (``meters_per_unit`` 1.0).

The transform applied (``x_new = s R x_old + t`` as a 4x4 matrix) and the
frame facts go to ``frame.json`` beside the model; user-given poses keep their
own frame and get a ``frame.json`` saying so (:func:`given_frame`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..cameras import PinholeCamera
from ..errors import InputError
from .colmap import ColmapModel

MIN_POINTS_FOR_CENTRE = 10
MIN_FLOOR_POINTS = 20
"""Sparse points below the cameras needed to look for a floor."""
FLOOR_BINS = 60
"""Height histogram bins between the lowest point (1st percentile) and the lowest camera."""
FLOOR_PEAK_SHARE = 0.3
"""A floor bin holds at least this share of the fullest bin below the cameras."""
STRAY_SHARE = 0.01
"""At most this share of the points below the cameras are strays under the floor."""
UNKNOWN_UNITS_HINT = ("units unknown (SfM scale): give --camera-height METRES (the photos' "
                      "median height above the floor), --scale or --scale-from for metres")
AXES = {"X": np.array([1.0, 0, 0]), "Y": np.array([0, 1.0, 0]), "Z": np.array([0, 0, 1.0])}


# -- similarity transforms ---------------------------------------------------

def umeyama(src: np.ndarray, dst: np.ndarray, with_scale: bool = True
            ) -> tuple[float, np.ndarray, np.ndarray]:
    """Least-squares similarity ``dst ~ s R src + t`` (Umeyama 1991).

    ``src``, ``dst``: (N, 3) corresponding points, N >= 3 not collinear.
    Returns (s, R (3, 3) proper rotation, t (3,)).
    """
    src, dst = np.asarray(src, np.float64), np.asarray(dst, np.float64)
    if src.shape != dst.shape or src.ndim != 2 or src.shape[0] < 3:
        raise ValueError("umeyama needs two (N>=3, 3) arrays of corresponding points")
    mu_s, mu_d = src.mean(0), dst.mean(0)
    a, b = src - mu_s, dst - mu_d
    cov = b.T @ a / len(src)
    u, d, vt = np.linalg.svd(cov)
    sign = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        sign[2, 2] = -1
    rot = u @ sign @ vt
    var = (a * a).sum() / len(src)
    s = float(np.trace(np.diag(d) @ sign) / var) if with_scale and var > 0 else 1.0
    return s, rot, mu_d - s * rot @ mu_s


def similarity_matrix(s: float, rot: np.ndarray, t: np.ndarray) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = s * np.asarray(rot), t
    return m


def split_similarity(m: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """4x4 similarity -> (s, R, t)."""
    m = np.asarray(m, np.float64)
    s = float(np.cbrt(np.linalg.det(m[:3, :3])))
    return s, m[:3, :3] / s, m[:3, 3].copy()


def transform_camera(cam: PinholeCamera, s: float, rot: np.ndarray, t: np.ndarray
                     ) -> PinholeCamera:
    """The same camera after the world moves by ``x' = s R x + t``."""
    r_new = cam.R @ rot.T
    return replace(cam, R=r_new, t=s * np.asarray(cam.t, np.float64) - r_new @ t)


def transform_model(model: ColmapModel, s: float, rot: np.ndarray, t: np.ndarray
                    ) -> ColmapModel:
    """A copy of ``model`` with cameras and points moved by ``x' = s R x + t``."""
    return replace(model, cameras=[transform_camera(c, s, rot, t) for c in model.cameras],
                   points=model.points @ (s * rot).T + t, frame=dict(model.frame),
                   notes=list(model.notes))


# -- the SfM frame -------------------------------------------------------------

def camera_axes(cameras: list[PinholeCamera]) -> tuple[np.ndarray, np.ndarray]:
    """World up (-y camera axis) and forward (+z) of each camera, (M, 3) each."""
    rots = np.array([c.R for c in cameras]).reshape(-1, 3, 3)
    return -rots[:, 1, :], rots[:, 2, :]


def _rotation_to(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit vector ``a`` to unit vector ``b``."""
    v, c = np.cross(a, b), float(np.dot(a, b))
    if c < -1 + 1e-12:  # opposite: turn half way round any perpendicular axis
        axis = np.cross(a, [1.0, 0, 0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0, 1.0, 0])
        axis /= np.linalg.norm(axis)
        return 2 * np.outer(axis, axis) - np.eye(3)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1 + c)


def scene_centre(model: ColmapModel, rot: np.ndarray | None = None
                 ) -> tuple[np.ndarray, str]:
    """The scene centre (in axes rotated by ``rot``) and how it was taken."""
    rot = np.eye(3) if rot is None else rot
    if len(model.points) >= MIN_POINTS_FOR_CENTRE:
        return (np.median(model.points @ rot.T, axis=0),
                "per-axis median of the sparse points (in the new axes)")
    return model.centers.mean(0) @ rot.T, "mean of the camera centres"


def up_rotation(model: ColmapModel) -> np.ndarray:
    """Rotation taking the mean camera up to +Y and mean view heading to -Z."""
    ups, fwds = camera_axes(model.cameras)
    up = ups.mean(0)
    if np.linalg.norm(up) < 1e-6:
        raise InputError("cannot tell which way is up: the cameras' up vectors cancel out")
    r1 = _rotation_to(up / np.linalg.norm(up), AXES["Y"])
    fwd = (fwds @ r1.T).mean(0)
    fwd[1] = 0.0
    if np.linalg.norm(fwd) < 1e-6:  # cameras look all round: keep the first one's heading
        fwd = (fwds[0] @ r1.T) * np.array([1.0, 0, 1.0])
    if np.linalg.norm(fwd) < 1e-6:
        return r1
    fwd /= np.linalg.norm(fwd)
    return _rotation_to(fwd, -AXES["Z"]) @ r1


def find_floor(heights: np.ndarray, camera_heights: np.ndarray) -> float | None:
    """Height of the floor among sparse point ``heights`` (+Y up), or None when unseen.

    The floor is the lowest dense horizontal layer below the cameras: the lowest
    bin of a height histogram (from the points' 1st percentile up to the lowest
    camera) holding at least FLOOR_PEAK_SHARE of the fullest bin; its points'
    median height. Stray points under the floor fill no bin that much. A floor
    of repeating tiles gives SfM few points (the example's floor holds 5 of its
    1176), so the lowest furniture tops can make the denser layer: the floor is
    never above the height with only STRAY_SHARE of the points under it.
    """
    heights = np.asarray(heights, np.float64)
    top = float(np.min(camera_heights))
    below = heights[heights < top]
    if len(below) < MIN_FLOOR_POINTS:
        return None
    low = float(np.percentile(below, 1))
    if not top > low:
        return None
    counts, edges = np.histogram(below, bins=FLOOR_BINS, range=(low, top))
    if counts.max() < MIN_FLOOR_POINTS // 2:
        return None
    first = int(np.flatnonzero(counts >= FLOOR_PEAK_SHARE * counts.max())[0])
    lo, hi = edges[max(first - 1, 0)], edges[min(first + 3, FLOOR_BINS)]
    layer = float(np.median(below[(below >= lo) & (below <= hi)]))
    k = max(int(STRAY_SHARE * len(below)), 3)
    lowest = float(np.partition(below, k)[k])
    width = edges[1] - edges[0]
    if layer - lowest <= 3 * width:  # the layer is the floor (its noise reaches below)
        return layer
    band = below[(below >= lowest) & (below <= lowest + 2 * width)]
    return float(np.median(band))  # the floor's points, not its lowest noise


def parse_scale_from(text: str) -> tuple[str, str, float]:
    """``"IMG_A,IMG_B,DIST"`` -> (name a, name b, distance in metres)."""
    parts = [p.strip() for p in str(text).split(",")]
    try:
        if len(parts) != 3:
            raise ValueError
        dist = float(parts[2])
    except ValueError:
        raise InputError(f"--scale-from wants IMG_A,IMG_B,DISTANCE_IN_METRES, got {text!r}"
                         ) from None
    if not dist > 0:
        raise InputError(f"--scale-from distance must be positive, got {parts[2]}")
    return parts[0], parts[1], dist


def sfm_frame(model: ColmapModel, scale: float | None = None,
              scale_from: tuple[str, str, float] | str | None = None,
              camera_height: float | None = None) -> ColmapModel:
    """Move an SfM model to the well-behaved frame (module docstring); record it."""
    if not model.cameras:
        raise InputError("no registered cameras to define a frame")
    given = [n for n, v in (("--scale", scale), ("--scale-from", scale_from),
                            ("--camera-height", camera_height)) if v is not None]
    if len(given) > 1:
        raise InputError(f"give one of --scale, --scale-from, --camera-height (got "
                         f"{', '.join(given)})")
    rot = up_rotation(model)
    cams = model.centers @ rot.T
    cam_median = np.median(cams, axis=0)
    floor = find_floor((model.points @ rot.T)[:, 1], cams[:, 1]) if len(model.points) else None
    centre = cam_median.copy()
    if floor is not None:
        centre[1] = floor
        centre_how = "on the floor (lowest dense layer of sparse points) under the cameras' " \
                     "median point"
    else:
        centre_how = "the cameras' median point (no floor found among the sparse points)"
    s, scale_source = 1.0, None
    if scale_from is not None:
        a, b, dist = parse_scale_from(scale_from) if isinstance(scale_from, str) else scale_from
        try:
            gap = float(np.linalg.norm(model.camera(a).center - model.camera(b).center))
        except KeyError as exc:
            raise InputError(f"--scale-from names {exc.args[0]}, which is not a registered "
                             f"photo (registered: {', '.join(model.names)})") from None
        if gap <= 0:
            raise InputError(f"--scale-from: {a} and {b} have the same camera centre")
        s, scale_source = dist / gap, f"distance {dist} m between cameras {a} and {b}"
    elif scale is not None:
        if not scale > 0:
            raise InputError(f"--scale must be positive, got {scale}")
        s, scale_source = float(scale), f"factor {scale} metres per SfM unit"
    elif camera_height is not None:
        if not camera_height > 0:
            raise InputError(f"--camera-height must be positive, got {camera_height}")
        if floor is None:
            raise InputError("--camera-height needs the floor, and no floor was found among "
                             "the sparse points (photos of the floor help); use --scale or "
                             "--scale-from instead")
        above = float(np.median(cams[:, 1]) - floor)
        s = camera_height / above
        scale_source = f"cameras' median height {camera_height} m above the floor"
    t = -s * centre
    out = transform_model(model, s, rot, t)
    height = None if floor is None else float(s * (np.median(cams[:, 1]) - floor))
    out.frame = {
        "frame_source": "sfm",
        "up_axis": "Y",
        "meters_per_unit": 1.0 if scale_source else None,
        "scale_known": scale_source is not None,
        "scale_source": scale_source,
        "units": "metres" if scale_source else UNKNOWN_UNITS_HINT,
        "origin": centre_how,
        "floor": {"found": floor is not None, "y": 0.0 if floor is not None else None,
                  "camera_height_median": height},
        "up": "mean camera up vector -> +Y; mean viewing heading -> -Z",
        "transform_from_sfm": similarity_matrix(s, rot, t).tolist(),
    }
    return out


def given_frame(model: ColmapModel, source: str) -> dict[str, Any]:
    """Frame facts for poses the user gave: their frame is kept, up is estimated."""
    if model.frame:
        return dict(model.frame)
    ups, _ = camera_axes(model.cameras) if model.cameras else (np.zeros((1, 3)), None)
    up = ups.mean(0)
    best = max(AXES, key=lambda k: abs(float(np.dot(up, AXES[k]))))
    return {
        "frame_source": source,
        "up_axis": best,
        "up_axis_estimated": True,
        "up_sign": "+" if np.dot(up, AXES[best]) >= 0 else "-",
        "meters_per_unit": None,
        "scale_known": False,
        "units": "as given (unknown)",
    }


# -- pose errors ---------------------------------------------------------------

def rotation_angle_deg(ra: np.ndarray, rb: np.ndarray) -> np.ndarray:
    """Angles (degrees) of ``ra @ rb^T`` for stacks of rotations (..., 3, 3)."""
    rel = np.einsum("...ij,...kj->...ik", ra, rb)
    cos = (np.trace(rel, axis1=-2, axis2=-1) - 1) / 2
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def align_and_compare(estimate: ColmapModel, truth: ColmapModel,
                      scene_size: float | None = None) -> dict[str, Any]:
    """Similarity-align ``estimate``'s camera centres onto ``truth``'s and compare.

    Cameras are matched by image name. Returns per-camera centre errors (in
    truth units and as a fraction of the scene size: ``scene_size`` when given,
    else the largest distance of a true point (or, with no points, of a true
    camera centre) from their centroid), rotation errors (degrees), their medians, the similarity
    and the names of true cameras the estimate lacks.
    """
    est = {c.name: c for c in estimate.cameras}
    common = [c.name for c in truth.cameras if c.name in est]
    missing = [c.name for c in truth.cameras if c.name not in est]
    if len(common) < 3:
        raise InputError(f"only {len(common)} cameras in common with the truth; need 3")
    true_cams = [truth.camera(n) for n in common]
    src = np.array([est[n].center for n in common])
    dst = np.array([c.center for c in true_cams])
    s, rot, t = umeyama(src, dst)
    aligned = [transform_camera(est[n], s, rot, t) for n in common]
    centre_err = np.linalg.norm(np.array([c.center for c in aligned]) - dst, axis=1)
    rot_err = rotation_angle_deg(np.array([c.R for c in aligned]),
                                 np.array([c.R for c in true_cams]))
    size = scene_size
    if size is None:
        extent = truth.points if len(truth.points) else dst
        size = float(np.max(np.linalg.norm(extent - extent.mean(0), axis=1))) or 1.0
    return {
        "names": common,
        "missing": missing,
        "centre_errors": centre_err,
        "rotation_errors_deg": rot_err,
        "scene_size": size,
        "median_centre_error": float(np.median(centre_err)),
        "median_centre_error_rel": float(np.median(centre_err) / size),
        "max_centre_error_rel": float(np.max(centre_err) / size),
        "median_rotation_error_deg": float(np.median(rot_err)),
        "max_rotation_error_deg": float(np.max(rot_err)),
        "similarity": similarity_matrix(s, rot, t),
    }
