"""Do the given poses agree with the photos? Measured on what the photos themselves say.

Poses a user brings (a capture rig, another tool, an old solve) can be slightly off, or
belong to other photos. The fit would still run: the splats bend to each view and blur,
and the lights move, with nothing said. Two checks, both from image measurements and
both independent of scale and frame:

* **reprojection** -- a COLMAP model with observations (``points2D`` with point3D ids):
  each observed point projected through its image's given camera lands this far from
  where the photo observed it;
* **epipolar** -- feature matches verified between two photos (RANSAC on the matches
  alone, so the poses do not shape them): each match lies this far from the epipolar
  line the two given poses predict (symmetric distance, :func:`epipolar_errors`).
  The fit measures this when it triangulates points for poses that carry none.

Errors are taken in the cameras' normalised plane (lens distortion removed by
pycolmap's camera model), so the threshold is an angle: :data:`MAX_MEDIAN_DEG`
(2 px in the bundled example's 480-px photos with a 65 deg lens). True poses of the
example give 0.27 px (0.04 deg) on its matches; SfM's own poses reproject under 1 px.
``gaslight2usd bench --suite stability --perturb pose_noise`` (poses rotated by 1 deg
std) gave 8.7 px.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..cameras import PinholeCamera
from .colmap import ColmapCamera, ColmapModel

MAX_MEDIAN_DEG = 0.3
"""The median error over every measurement above which the poses are said to disagree."""
OUTLIER_DEG = 1.0
"""One photo's own median error above which its pose is named even when the set agrees."""
MIN_MEASURES = 20
"""A photo is judged alone only on at least this many measurements."""
MIN_PAIR_INLIERS = 15
"""Verified pairs with fewer inlier matches are not used (as SfM's ``MIN_INLIERS``)."""
MIN_BAD_PAIRS = 2
"""With matches, a photo is named only when at least this many of its pairs, and most of
them, disagree (pair median over :data:`OUTLIER_DEG`): a wrong pose moves every pair it
is in, while a pair whose verification kept wrong matches does not say much."""
MIN_VOTE_INLIERS = 30
"""Only pairs with at least this many verified matches vote on a photo's pose: a pair
verified on barely :data:`MIN_PAIR_INLIERS` matches in a dark, featureless photo can be
wrong as a whole (``gaslight2usd bench --suite stability``, the ``no_clip`` case: a true
pose of a floor view named from its three such pairs)."""


@dataclass
class PoseAgreement:
    """How far the photos' own measurements lie from what the given poses predict."""

    kind: str
    """``reprojection`` or ``epipolar``."""
    measured: int
    """Observations (reprojection) or verified matches (epipolar) measured."""
    median_px: float
    median_deg: float
    per_image: dict[str, tuple[float, float, int]] = field(default_factory=dict)
    """Image name -> (median px, median deg, measurements) over what involves it."""
    pair_votes: dict[str, tuple[int, int]] = field(default_factory=dict)
    """Epipolar only: image name -> (its voting pairs that disagree, its voting pairs)."""

    @property
    def disagrees(self) -> bool:
        return self.median_deg > MAX_MEDIAN_DEG

    def outliers(self) -> list[str]:
        """Photos whose own median is over :data:`OUTLIER_DEG`, worst first."""
        bad = [(deg, name) for name, (_, deg, n) in self.per_image.items()
               if n >= MIN_MEASURES and deg > OUTLIER_DEG and self._pairs_agree_bad(name)]
        return [name for _, name in sorted(bad, reverse=True)]

    def _pairs_agree_bad(self, name: str) -> bool:
        """Whether ``name``'s pairs say its pose is off (always, without pairs)."""
        if name not in self.pair_votes:
            return True
        bad, total = self.pair_votes[name]
        return bad >= MIN_BAD_PAIRS and 2 * bad > total

    def worst(self, count: int = 5) -> list[str]:
        """The ``count`` photos of largest median error."""
        ranked = sorted(self.per_image.items(), key=lambda kv: -kv[1][1])
        return [name for name, _ in ranked[:count]]

    @property
    def warns(self) -> bool:
        return self.disagrees or bool(self.outliers())

    def sentence(self) -> str:
        """The warning a user reads (empty when the poses agree)."""
        if not self.warns:
            return ""
        what = ("the model's points reproject" if self.kind == "reprojection" else
                "the feature matches between the photos lie")
        where = ("from where the photos observed them" if self.kind == "reprojection" else
                 "off the epipolar lines the poses predict")
        names = self.worst() if self.disagrees else self.outliers()[:5]
        listed = ", ".join(f"{n} ({self.per_image[n][0]:.1f} px)" for n in names)
        head = ("the given poses disagree with the photos" if self.disagrees else
                f"the given pose(s) of {len(self.outliers())} photo(s) disagree with the "
                "photos")
        return (f"{head}: {what} a median {self.median_px:.1f} px "
                f"({self.median_deg:.2f} deg) {where}, over {self.measured} measurements "
                f"(poses that fit give under {MAX_MEDIAN_DEG:g} deg); worst: {listed}. "
                "The fit blurs the set and moves its lights: check that these poses belong "
                "to these photos (names, intrinsics, undistorted), leave the poses out so SfM "
                "solves them, or fit with --refine-poses")

    def as_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "measured": self.measured,
                "median_px": round(self.median_px, 3), "median_deg": round(self.median_deg, 4),
                "disagrees": self.disagrees, "outliers": self.outliers(),
                "worst": [{"view": n, "median_px": round(self.per_image[n][0], 2)}
                          for n in self.worst()],
                "warning": self.sentence()}


def normalised(intrinsics: ColmapCamera, xy: np.ndarray) -> np.ndarray:
    """(N, 2) image points (COLMAP pixels, centre of the first pixel at 0.5) -> the
    camera's normalised plane (x/z, y/z), its lens distortion removed."""
    import pycolmap

    cam = pycolmap.Camera(model=intrinsics.model, width=int(intrinsics.width),
                          height=int(intrinsics.height),
                          params=np.asarray(intrinsics.params, np.float64))
    xy = np.ascontiguousarray(np.asarray(xy, np.float64).reshape(-1, 2))
    return np.asarray(cam.cam_from_img(xy), np.float64).reshape(-1, 2) if len(xy) else xy


def _focal(intrinsics: ColmapCamera) -> float:
    fx, fy, _, _ = intrinsics.pinhole
    return 0.5 * (fx + fy)


def _summarise(kind: str, errors: np.ndarray, px: np.ndarray,
               images: list[np.ndarray], names: list[str]) -> PoseAgreement | None:
    """``errors``: (M,) normalised-plane errors, ``px``: the same in pixels, ``images``:
    per name the indices of the measurements that involve it."""
    if not len(errors):
        return None
    per = {name: (float(np.median(px[idx])), math.degrees(float(np.median(errors[idx]))),
                  int(len(idx)))
           for name, idx in zip(names, images, strict=True) if len(idx)}
    return PoseAgreement(kind, int(len(errors)), float(np.median(px)),
                         math.degrees(float(np.median(errors))), per)


def reprojection_agreement(model: ColmapModel) -> PoseAgreement | None:
    """The model's observed points through its given cameras (None when it holds no
    observation of a 3D point)."""
    if model.points2d is None or not len(model.points) or \
            len(model.points2d) != len(model.cameras):
        return None
    order = np.argsort(model.point_ids)
    sorted_ids = np.asarray(model.point_ids)[order]
    errors, pixels, owners = [], [], []
    start = 0
    for cam, cid, obs in zip(model.cameras, model.camera_ids, model.points2d, strict=True):
        obs = np.asarray(obs, np.float64).reshape(-1, 3)
        pid = obs[:, 2].astype(np.int64)
        at = np.clip(np.searchsorted(sorted_ids, pid), 0, len(sorted_ids) - 1)
        known = (pid >= 0) & (sorted_ids[at] == pid)
        cam_pts = model.points[order[at[known]]] @ cam.R.T + cam.t
        front = cam_pts[:, 2] > 1e-9
        predicted = cam_pts[front, :2] / cam_pts[front, 2:]
        observed = normalised(model.intrinsics[cid], obs[known][front, :2])
        err = np.linalg.norm(predicted - observed, axis=1)
        errors.append(err)
        pixels.append(err * _focal(model.intrinsics[cid]))
        owners.append(np.arange(start, start + len(err)))
        start += len(err)
    if not start:
        return None
    return _summarise("reprojection", np.concatenate(errors), np.concatenate(pixels), owners,
                      model.names)


def essential(first: PinholeCamera, second: PinholeCamera) -> np.ndarray:
    """The essential matrix E with ``x2^T E x1 = 0`` for normalised points of the two
    (world-to-camera) poses: ``E = [t]x R`` of the relative pose."""
    rot = second.R @ first.R.T
    t = second.t - rot @ first.t
    skew = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    return skew @ rot


def epipolar_errors(x1: np.ndarray, x2: np.ndarray, e: np.ndarray) -> tuple[np.ndarray,
                                                                            np.ndarray]:
    """Distances (normalised plane) of (M, 2) matches from their epipolar lines under
    (M, 3, 3) essential matrices: (in the second image, in the first)."""
    h1 = np.concatenate([x1, np.ones((len(x1), 1))], axis=1)
    h2 = np.concatenate([x2, np.ones((len(x2), 1))], axis=1)
    line2 = np.einsum("mij,mj->mi", e, h1)
    line1 = np.einsum("mji,mj->mi", e, h2)
    num = np.abs(np.sum(h2 * line2, axis=1))
    with np.errstate(divide="ignore", invalid="ignore"):
        return (num / np.hypot(line2[:, 0], line2[:, 1]),
                num / np.hypot(line1[:, 0], line1[:, 1]))


def epipolar_agreement(model: ColmapModel, keypoints: dict[str, np.ndarray],
                       matches: list[tuple[str, str, np.ndarray]]) -> PoseAgreement | None:
    """Verified matches against the model's poses.

    ``keypoints``: image name -> (K, 2) COLMAP pixel positions; ``matches``: (name a,
    name b, (M, 2) keypoint indices into a and b). Pairs with fewer than
    :data:`MIN_PAIR_INLIERS` matches, or whose cameras share a centre (no epipolar
    geometry: a panorama's faces), are skipped.
    """
    index = {name: i for i, name in enumerate(model.names)}
    cams = model.cameras
    norm = {name: normalised(model.intrinsics[model.camera_ids[index[name]]], kp)
            for name, kp in keypoints.items() if name in index}
    spread = float(np.linalg.norm(model.centers - model.centers.mean(0), axis=1).max())
    x1s, x2s, es, f1s, f2s, pair_of = [], [], [], [], [], []
    pairs: list[tuple[int, int]] = []
    for a, b, m in matches:
        m = np.asarray(m, np.int64).reshape(-1, 2)
        if a not in norm or b not in norm or len(m) < MIN_PAIR_INLIERS:
            continue
        ca, cb = cams[index[a]], cams[index[b]]
        if np.linalg.norm(ca.center - cb.center) <= 1e-6 * max(spread, 1e-12):
            continue
        x1s.append(norm[a][m[:, 0]])
        x2s.append(norm[b][m[:, 1]])
        es.append(np.broadcast_to(essential(ca, cb), (len(m), 3, 3)))
        f1s.append(np.full(len(m), _focal(model.intrinsics[model.camera_ids[index[a]]])))
        f2s.append(np.full(len(m), _focal(model.intrinsics[model.camera_ids[index[b]]])))
        pair_of.append(np.full(len(m), len(pairs)))
        pairs.append((index[a], index[b]))
    if not pairs:
        return None
    d2, d1 = epipolar_errors(np.concatenate(x1s), np.concatenate(x2s), np.concatenate(es))
    f1, f2 = np.concatenate(f1s), np.concatenate(f2s)
    ok = np.isfinite(d1) & np.isfinite(d2)
    errors = 0.5 * (d1 + d2)[ok]
    px = 0.5 * (d1 * f1 + d2 * f2)[ok]
    pair_of_match = np.concatenate(pair_of)[ok]
    pair_index = np.asarray(pairs, np.int64)
    owners = [np.flatnonzero((pair_index[pair_of_match, 0] == i)
                             | (pair_index[pair_of_match, 1] == i))
              for i in range(len(cams))]
    agreement = _summarise("epipolar", errors, px, owners, model.names)
    if agreement is not None:
        agreement.pair_votes = _pair_votes(errors, pair_of_match, pair_index, model.names)
    return agreement


def _pair_votes(errors: np.ndarray, pair_of_match: np.ndarray, pair_index: np.ndarray,
                names: list[str]) -> dict[str, tuple[int, int]]:
    """Per image: (its voting pairs whose median error exceeds :data:`OUTLIER_DEG`, its
    voting pairs); pairs with fewer than :data:`MIN_VOTE_INLIERS` matches do not vote."""
    order = np.lexsort((errors, pair_of_match))  # by pair, then by error
    used, start, count = np.unique(pair_of_match[order], return_index=True,
                                   return_counts=True)
    ranked = errors[order]
    medians = 0.5 * (ranked[start + (count - 1) // 2] + ranked[start + count // 2])
    voting = count >= MIN_VOTE_INLIERS
    used, medians = used[voting], medians[voting]
    bad = np.degrees(medians) > OUTLIER_DEG
    ends = pair_index[used]
    return {name: (int(bad[(ends == i).any(axis=1)].sum()), int((ends == i).any(axis=1).sum()))
            for i, name in enumerate(names)}


def pose_agreement(model: ColmapModel) -> PoseAgreement | None:
    """What is known of ``model``'s poses against its photos: the epipolar check made
    when its points were triangulated (``model.agreement``), else the reprojection of
    its observed points, else None (a model without observations is not checked)."""
    if isinstance(model.agreement, PoseAgreement):
        return model.agreement
    return reprojection_agreement(model)
