"""Sparse points for poses that carry none, triangulated from the HDR views themselves.

Given poses (a synthetic set, a capture rig, a ``transforms.json``) often come
without points, and a fit started from guessed depths learns poor geometry.
The HDR views are tone-mapped to 8-bit (one exposure for all views, so
matching sees consistent brightness; sRGB encoding) and handed to
:func:`gaslight_usd.poses.sfm.triangulate_known_poses`, which matches SIFT features
and triangulates them with the poses held fixed. No photos are needed.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np

from ..colour import luminance_weights, srgb_encode
from ..errors import GaslightError
from ..imageio import read_image
from ..poses.colmap import ColmapModel
from ..progress import Progress

DESPECKLE = 3
"""Side (pixels) of the median filter the tone-mapped views pass before SIFT when the plain
views give too few points (:data:`SPARSE_POINTS_PER_VIEW`). A room lit indirectly (a
shaded lamp) and path traced, or shot at high ISO, is speckled at every pixel, and SIFT
finds its features in the speckle, which no other view shares: the fit then starts from a
handful of points and draws the walls off their places (``gaslight2usd bench --suite chain
--scene shade``, ``docs/measurements.md``)."""
SPARSE_POINTS_PER_VIEW = 10
"""Fewer points than this per view and the views are triangulated again, despeckled
(:data:`DESPECKLE`) and with matches the poses guide (:mod:`gaslight_usd.poses.guided`).
A speckled room falls far under it and a textured one far over it. Where the plain start
is dense the second pass costs: its extra points include faint false ones in front of
the windows, which the fit keeps as a veil over them; where it is sparse it is what draws
the walls where they are (``gaslight2usd bench --suite chain --method "truth HDR"``, and
with ``recursive + extra dark frames``; figures in ``docs/measurements.md``)."""
MID_GREY = 0.18
"""Where the median luminance of all views lands after the shared exposure."""


def tone_map_8bit(image: np.ndarray, scale: float) -> np.ndarray:
    """(H, W, 3) linear HDR x ``scale`` -> sRGB-encoded uint8, highlights clipped."""
    x = np.clip(np.asarray(image, np.float32) * scale, 0.0, 1.0)
    v = srgb_encode(x)
    return np.round(v * 255.0).astype(np.uint8)


def despeckle(image: np.ndarray, size: int = DESPECKLE) -> np.ndarray:
    """(H, W, 3) ``image`` through a ``size`` x ``size`` median filter per channel."""
    from scipy.ndimage import median_filter

    return median_filter(image, size=(size, size, 1)) if size > 1 else image


def shared_scale(images: list[np.ndarray], y_weights: np.ndarray | None = None) -> float:
    """Exposure putting the median luminance of all views at mid grey.

    ``y_weights``: the views' colour space's luminance weights (default Rec.709's).
    """
    weights = luminance_weights() if y_weights is None else y_weights
    lum = np.concatenate([(im[::4, ::4] @ weights).ravel() for im in images])
    median = float(np.median(lum[lum > 0])) if (lum > 0).any() else 1.0
    return MID_GREY / median


def _model_at_view_size(model: ColmapModel, images: dict[str, np.ndarray]) -> ColmapModel:
    """``model`` with every camera scaled to its view's size (itself when they agree)."""
    from .data import scale_camera_to

    sizes = {name: (img.shape[1], img.shape[0]) for name, img in images.items()}
    if all(sizes[c.name] == (c.width, c.height) for c in model.cameras):
        return model
    return ColmapModel(cameras=[scale_camera_to(c, *sizes[c.name]) for c in model.cameras],
                       image_ids=list(model.image_ids), frame=dict(model.frame),
                       notes=list(model.notes), source=model.source)


def triangulate_views(model: ColmapModel, view_paths: dict[str, Path],
                      progress: Progress | None = None) -> ColmapModel | None:
    """``model`` with points triangulated from its HDR views, or None when that fails.

    ``view_paths`` maps each posed image name to its HDR view: the camera's size,
    or that size shrunk evenly (``run`` uplifts at the working size); the model's
    cameras are then scaled to the views' size for the triangulation, so the
    returned model's cameras are at that size (the points are the same).
    Failure (too little texture, an image type COLMAP cannot read) is not an
    error: the caller falls back to a points-free start. Views that give fewer than
    :data:`SPARSE_POINTS_PER_VIEW` points each are triangulated again, despeckled and
    with guided matches, and the denser result is kept.
    """
    progress = progress or Progress(quiet=True)
    work = Path(tempfile.mkdtemp(prefix="gaslight-fit-tri-"))
    try:
        read = {name: read_image(view_paths[name]) for name in model.names}
        images = {name: image.pixels for name, image in read.items()}
        model = _model_at_view_size(model, images)
        space = next(iter(read.values())).colour_space if read else None
        scale = shared_scale(list(images.values()), luminance_weights(space, fallback=True))
        tone_mapped = {name: tone_map_8bit(image, scale) for name, image in images.items()}
        filled = _triangulate(work / "plain", model, tone_mapped, False, progress)
        enough = SPARSE_POINTS_PER_VIEW * len(images)
        if filled is not None and len(filled.points) >= enough:
            return filled
        progress.message(f"{0 if filled is None else len(filled.points)} points from "
                         f"{len(images)} views (under {SPARSE_POINTS_PER_VIEW} a view): "
                         "again, despeckled and with matches the poses guide")
        again = _triangulate(work / "guided", model,
                             {name: despeckle(v) for name, v in tone_mapped.items()}, True,
                             progress)
        if again is None or (filled is not None and len(again.points) <= len(filled.points)):
            return filled
        return again
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _triangulate(work: Path, model: ColmapModel, views: dict[str, np.ndarray], guided: bool,
                 progress: Progress) -> ColmapModel | None:
    """``model`` with points triangulated from the 8-bit ``views`` (written into ``work``),
    ``guided``: with the poses' guided matches; None when that fails."""
    import OpenImageIO as oiio

    from ..poses.sfm import SfmOptions, triangulate_known_poses

    for name, view in views.items():
        target = work / name
        target.parent.mkdir(parents=True, exist_ok=True)
        if not oiio.ImageBuf(np.ascontiguousarray(view)).write(str(target)):
            progress.message(f"cannot write a tone-mapped view as {name!r}; no triangulation")
            return None
    progress.message(f"triangulating sparse points from {len(views)} HDR views "
                     "(poses fixed)")
    try:
        # one thread throughout: COLMAP's threaded extraction, matching and triangulation
        # order their work by timing, so the points (and the fit after them) would change
        # from run to run; the fit must be deterministic for a seed. The views are at the
        # working size, so one thread is cheap.
        return triangulate_known_poses(work, model,
                                       SfmOptions(threads=1, extraction_threads=1,
                                                  matching_threads=1, guided_matching=guided),
                                       progress=progress)
    except (GaslightError, RuntimeError, ValueError) as err:
        progress.message(f"triangulation failed ({err}); starting without points")
        return None
