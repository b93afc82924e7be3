"""Structure from motion with pycolmap: photos -> posed cameras + sparse points.

SIFT features, exhaustive (small sets) or sequential (video-like sets)
matching with geometric verification, incremental mapping; one shared camera
by default. Everything happens in a temporary work folder; only the final model
is written (file by file, atomically) by the caller.

Photos that do not register are explained from the database: too few features,
no verified matches with any other photo (no overlap), matched only inside a
separate group, or matched but not solvable. A darker frame too dark for SfM, shot
from a photo's position, takes that photo's pose (:mod:`.dark_frames`). The run fails
with an InputError naming the rest when fewer than ``min_registered`` (a share)
register.

Lat-long panoramas (2:1 photos with ``panorama="auto"``, or all photos with
``"on"``) are cut into six cube faces that form a COLMAP rig: one centre, six
fixed rotations (:mod:`gaslight_usd.poses.panorama`). The model then holds the face
cameras, named ``cube_<face>/<photo>``.
"""

from __future__ import annotations

import contextlib
import logging
import shutil
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..cameras import is_latlong
from ..errors import GaslightError, InputError
from ..imageio import LDR_EXTENSIONS, list_images, read_header, read_pixels
from ..progress import Progress
from . import panorama
from .colmap import ColmapCamera, ColmapModel, read_model, write_model
from .dark_frames import pose_dark_frames

log = logging.getLogger(__name__)

MATCHERS = ("exhaustive", "sequential")
CAMERA_MODELS = ("SIMPLE_PINHOLE", "PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV")
MIN_FEATURES = 100
"""Fewer SIFT keypoints than this: the photo is blank, blurred or too dark."""
FEW_FEATURES = "too few features"
"""How the reason for a photo with fewer than :data:`MIN_FEATURES` keypoints begins."""
MIN_INLIERS = 15
"""Verified matches (inliers) a photo pair needs to count as overlapping (COLMAP's default)."""


@dataclass
class SfmOptions:
    matcher: str = "exhaustive"
    camera_model: str = "SIMPLE_RADIAL"
    single_camera: bool = True
    min_registered: float = 0.5
    """Share of photos that must register, else the run fails."""
    max_image_size: int = 1600
    """Longer photo side used for features (larger photos are downscaled)."""
    max_features: int = 8192
    peak_threshold: float = 0.004
    """SIFT contrast threshold (COLMAP's default 0.0067 finds too few points on small photos)."""
    init_min_inliers: int = 50
    """Verified matches the first image pair needs (COLMAP's 100 suits big photos only)."""
    panorama: str = "auto"
    """"auto": 2:1 photos are lat-long panoramas; "on": all are; "off": none."""
    seed: int = 0
    threads: int = 1
    """Threads of the mapping (and of the triangulation with known poses). 1 keeps the
    result the same from run to run (threaded bundle adjustment sums in the order its
    threads finish); -1 uses every core."""
    matching_threads: int = -1
    """Threads of the feature matching and its geometric verification (-1: every core).
    Each pair's RANSAC is seeded by ``seed``, so the verified pairs do not depend on the
    threads' timing (three solves of the example with 2 matching threads and one
    extraction thread gave identical poses and points)."""
    scale_verify_error: bool = True
    """Scale the geometric verification's RANSAC error (COLMAP's 4 px, meant for features
    found at the photo's own size) by how much the photos were shrunk for features: a
    12 MP photo's features found at 640 px are 6 px apart in its own pixels, and a
    4 px bound then rejects good matches and draws more samples (matching CPU time and
    pose accuracy: ``gaslight2usd bench --suite poses --megapixels 12``)."""
    extraction_threads: int = -1
    """Threads of the feature extraction (-1: every core). With 12 MP photos decoding and
    SIFT are most of the SfM's time. Threaded extraction writes the photos' features in
    the order they finish, which can reorder the matching after it: set 1 (with
    ``threads=1``) where the result must repeat exactly."""
    guided_matching: bool = True
    """With the poses known (:func:`triangulate_known_poses`), also match features near
    their epipolar lines (:mod:`gaslight_usd.poses.guided`): smooth walls keep points
    the plain ratio test loses. The fit's own triangulation from its HDR views turns it on
    only where the plain pass is sparse
    (:data:`gaslight_usd.fit.triangulate.SPARSE_POINTS_PER_VIEW`: where it is dense, the
    guided points' faint false ones cost the fits)."""
    verbose: bool = False


@dataclass
class SfmResult:
    model: ColmapModel
    """The largest reconstruction, in COLMAP's own (arbitrary) frame."""
    photos: list[str]
    registered: list[str]
    unregistered: dict[str, str]
    """Photo name -> why it did not register."""
    seconds: float
    stats: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


class _PhaseClock:
    """Wall and CPU seconds (all threads) of each SfM phase: on a shared machine the CPU
    seconds still compare settings when the wall seconds do not."""

    def __init__(self, wall0: float) -> None:
        self.wall, self.cpu = wall0, time.process_time()
        self.seconds: dict[str, float] = {}

    def lap(self, name: str) -> None:
        wall, cpu = time.perf_counter(), time.process_time()
        self.seconds[f"{name}_s"] = round(wall - self.wall, 3)
        self.seconds[f"{name}_cpu_s"] = round(cpu - self.cpu, 3)
        self.wall, self.cpu = wall, cpu


@contextlib.contextmanager
def colmap_logging(verbose: bool) -> Iterator[None]:
    """Keep COLMAP's (glog) INFO chatter off stderr unless ``verbose``."""
    import pycolmap
    old = pycolmap.logging.minloglevel
    pycolmap.logging.minloglevel = 0 if verbose else 3
    try:
        yield
    finally:
        pycolmap.logging.minloglevel = old


def _check_options(opts: SfmOptions) -> None:
    if opts.matcher not in MATCHERS:
        raise InputError(f"unknown matcher {opts.matcher!r}; choose one of {', '.join(MATCHERS)}")
    if opts.camera_model not in CAMERA_MODELS:
        raise InputError(f"unknown camera model {opts.camera_model!r}; choose one of "
                         f"{', '.join(CAMERA_MODELS)}")
    if not 0 <= opts.min_registered <= 1:
        raise InputError(f"--min-registered must be a share in [0, 1], got {opts.min_registered}")
    if opts.panorama not in ("auto", "on", "off"):
        raise InputError(f"--panorama must be auto, on or off, got {opts.panorama!r}")


def _stage_photos(photos: list[Path], work: Path, opts: SfmOptions
                  ) -> tuple[list[str], dict[str, list[str]], dict[str, tuple[int, int]]]:
    """Link (or cut into cube faces) every photo into ``work``.

    Returns the image names COLMAP sees, photo name -> its image names, and
    the photo sizes.
    """
    import OpenImageIO as oiio
    names, owners, sizes = [], {}, {}
    for path in photos:
        # Decoded here (not only by COLMAP) so a truncated photo fails, named.
        spec, pixels = read_pixels(path, oiio.UINT8)
        sizes[path.name] = (spec.width, spec.height)
        pano = opts.panorama == "on" or (
            opts.panorama == "auto" and is_latlong(spec.width, spec.height))
        if not pano:
            (work / path.name).symlink_to(path.resolve())
            names.append(path.name)
            owners[path.name] = [path.name]
            continue
        faces = panorama.cube_faces(pixels[..., :3], size=max(spec.width // 4, 64))
        owners[path.name] = []
        for face, img in faces.items():
            name = panorama.face_name(face, Path(path.name).with_suffix(".jpg").name)
            (work / name).parent.mkdir(parents=True, exist_ok=True)
            out = oiio.ImageBuf(np.clip(np.rint(img), 0, 255).astype(np.uint8))
            if not out.write(str(work / name)):
                raise GaslightError(f"cannot write cube face {name}: {out.geterror()}")
            names.append(name)
            owners[path.name].append(name)
    return names, owners, sizes


def solve_poses(photos: Path | list[Path], options: SfmOptions | None = None,
                progress: Progress | None = None) -> SfmResult:
    """Run SfM on a folder (or list) of LDR photos; see the module docstring."""
    import pycolmap
    opts = options or SfmOptions()
    _check_options(opts)
    progress = progress or Progress(quiet=True)
    paths = list_images(photos, LDR_EXTENSIONS) if isinstance(photos, Path) else list(photos)
    if len(paths) < 2:
        raise InputError("SfM needs at least 2 photos", paths[0] if paths else photos)
    t0 = time.perf_counter()
    clock = _PhaseClock(t0)
    work = Path(tempfile.mkdtemp(prefix="gaslight-sfm-"))
    try:
        images = work / "images"
        images.mkdir()
        names, owners, sizes = _stage_photos(paths, images, opts)
        clock.lap("stage")
        db_path = work / "database.db"
        pycolmap.set_random_seed(opts.seed)
        with colmap_logging(opts.verbose):
            panos = [p for p, imgs in owners.items() if imgs != [p]]
            plain = [p for p in owners if p not in panos]
            warnings: list[str] = []
            extraction = pycolmap.FeatureExtractionOptions(
                max_image_size=opts.max_image_size, num_threads=opts.extraction_threads)
            extraction.sift.max_num_features = opts.max_features
            extraction.sift.peak_threshold = opts.peak_threshold
            progress.message(f"extracting SIFT features from {len(names)} images")
            if plain:
                mode = pycolmap.CameraMode.SINGLE
                plain_sizes = {sizes[p] for p in plain}
                if not opts.single_camera or len(plain_sizes) > 1:
                    mode = pycolmap.CameraMode.PER_IMAGE
                    if opts.single_camera:
                        warnings.append("photos differ in size: one camera per photo")
                prior = (_exif_focal_prior([q for q in paths if q.name in plain], sizes)
                         if mode == pycolmap.CameraMode.SINGLE else None)
                if prior:
                    progress.message(f"focal length prior from EXIF: {prior[0]:.1f} px")
                reader = pycolmap.ImageReaderOptions(
                    camera_model=opts.camera_model,
                    camera_params=_camera_params(opts.camera_model, *prior) if prior else "")
                pycolmap.extract_features(db_path, images, image_names=plain, camera_mode=mode,
                                          reader_options=reader, extraction_options=extraction,
                                          device=pycolmap.Device.cpu)
            constant_cameras: set[int] = set()
            if panos:
                face_names = [n for p in panos for n in owners[p]]
                face_sizes = {sizes[p][0] // 4 for p in panos}
                if len(face_sizes) > 1:
                    raise InputError("panoramas of different sizes: resize them to one size",
                                     paths[0].parent)
                half = max(face_sizes.pop(), 64) / 2.0
                # one exact 90-degree PINHOLE camera per face folder, held fixed
                reader = pycolmap.ImageReaderOptions(
                    camera_model="PINHOLE", camera_params=f"{half},{half},{half},{half}")
                pycolmap.extract_features(db_path, images, image_names=face_names,
                                          camera_mode=pycolmap.CameraMode.PER_FOLDER,
                                          reader_options=reader,
                                          extraction_options=extraction,
                                          device=pycolmap.Device.cpu)
                constant_cameras = _apply_panorama_rig(db_path, set(face_names))
            clock.lap("extract")
            progress.message(f"matching ({opts.matcher})")
            matching = pycolmap.FeatureMatchingOptions(num_threads=opts.matching_threads)
            # the largest image COLMAP sees: a photo, or a panorama's cube face
            longest = max([max(sizes[p]) for p in plain] +
                          [max(sizes[p][0] // 4, 64) for p in panos])
            shrink = longest / opts.max_image_size if opts.max_image_size > 0 else 1.0
            verification = _verification_options(
                opts.seed, max(shrink, 1.0) if opts.scale_verify_error else 1.0)
            if opts.matcher == "exhaustive":
                pycolmap.match_exhaustive(db_path, matching_options=matching,
                                          verification_options=verification,
                                          device=pycolmap.Device.cpu)
            else:
                pycolmap.match_sequential(db_path, matching_options=matching,
                                          verification_options=verification,
                                          device=pycolmap.Device.cpu)
            clock.lap("match")
            mapping = pycolmap.IncrementalPipelineOptions(
                num_threads=opts.threads, random_seed=opts.seed, min_model_size=3)
            mapping.mapper.init_min_num_inliers = opts.init_min_inliers
            if constant_cameras:
                mapping.constant_cameras = constant_cameras
            mapping.mapper.abs_pose_min_num_inliers = min(
                mapping.mapper.abs_pose_min_num_inliers, MIN_INLIERS)
            progress.message(f"incremental mapping of {len(names)} images")
            done = [0]

            def next_image() -> None:
                # Called once per image registered after the initial pair (two images).
                done[0] += 1
                progress.update(min(done[0] + 2, len(names)), len(names))

            recs = pycolmap.incremental_mapping(db_path, images, work / "sparse",
                                                options=mapping,
                                                next_image_callback=next_image)
            clock.lap("map")
            model_names = _reconstruction_names(recs)
            best = max(recs, key=lambda k: recs[k].num_reg_images()) if recs else None
            stats, reasons = _diagnose(db_path, names, model_names, best)
        if best is None:
            model = ColmapModel(cameras=[])
        else:
            model_dir = work / "model"
            model_dir.mkdir()
            recs[best].write_text(str(model_dir))
            model = read_model(model_dir)
            model.source = None
        registered_images = set(model.names)
        progress.message(f"registered {len(registered_images)} of {len(names)} images "
                         f"({len(model.points)} points)")
        registered = [p for p, imgs in owners.items() if set(imgs) & registered_images]
        unregistered = {p: _photo_reason(imgs, reasons) for p, imgs in owners.items()
                        if not set(imgs) & registered_images}
        # a darker frame too dark for SfM, shot from a photo's position: that photo's pose
        # (one with features that matched nothing is no such frame: it stays out)
        model, posed = pose_dark_frames(
            model, [path for path in paths if owners[path.name] == [path.name]],
            {p: r for p, r in unregistered.items()
             if owners[p] == [p] and r.startswith(FEW_FEATURES)})
        if posed:
            registered += list(posed)
            unregistered = {p: r for p, r in unregistered.items() if p not in posed}
            stats["posed_as_neighbour"] = posed
            warnings.append(
                f"{len(posed)} darker frame(s) too dark for SfM posed as the photo shot "
                "beside them: " + "; ".join(f"{f} as {n}" for f, n in sorted(posed.items())))
            progress.message(warnings[-1])
    finally:
        shutil.rmtree(work, ignore_errors=True)
    result = SfmResult(model=model, photos=list(owners), registered=registered,
                       unregistered=unregistered, seconds=time.perf_counter() - t0,
                       stats={**stats, "reconstructions": len(recs),
                              "points": len(model.points),
                              **clock.seconds},
                       warnings=warnings)
    _judge(result, opts, paths[0].parent)
    return result


def _verification_options(seed: int, error_scale: float = 1.0) -> Any:
    """Geometric verification whose RANSAC is seeded (COLMAP's default, -1, seeds each
    matching thread from the clock, so verified pairs could differ from run to run);
    its inlier error times ``error_scale``."""
    import pycolmap
    verification = pycolmap.TwoViewGeometryOptions()
    verification.ransac.random_seed = seed
    verification.ransac.max_error *= error_scale
    return verification


def _exif_focal_prior(paths: list[Path], sizes: dict[str, tuple[int, int]]
                      ) -> tuple[float, int, int] | None:
    """(focal px, width, height) shared by all photos from EXIF, else None.

    Uses FocalLengthIn35mmFilm (36 mm across the long side) or FocalLength with
    FocalPlaneXResolution; COLMAP itself only knows sensor sizes of cameras in
    its database and otherwise guesses 1.2 x the long side.
    """
    found = set()
    for path in paths:
        spec = read_header(path)
        w, h = sizes[path.name]
        f35 = spec.get_float_attribute("Exif:FocalLengthIn35mmFilm", 0.0)
        f_mm = spec.get_float_attribute("Exif:FocalLength", 0.0)
        res = spec.get_float_attribute("Exif:FocalPlaneXResolution", 0.0)
        unit = spec.get_int_attribute("Exif:FocalPlaneResolutionUnit", 2)
        if f35 > 0:
            f_px = f35 / 36.0 * max(w, h)
        elif f_mm > 0 and res > 0 and unit in (2, 3, 4):
            per_mm = res / {2: 25.4, 3: 10.0, 4: 1.0}[unit]
            f_px = f_mm * per_mm * max(w, h) / max(spec.width, spec.height, 1)
        else:
            return None
        found.add((round(f_px, 3), w, h))
    return found.pop() if len(found) == 1 else None


def _camera_params(model: str, f: float, w: int, h: int) -> str:
    cx, cy = w / 2.0, h / 2.0
    params = {"SIMPLE_PINHOLE": [f, cx, cy], "PINHOLE": [f, f, cx, cy],
              "SIMPLE_RADIAL": [f, cx, cy, 0], "RADIAL": [f, cx, cy, 0, 0],
              "OPENCV": [f, f, cx, cy, 0, 0, 0, 0]}[model]
    return ",".join(repr(float(v)) for v in params)


def _photo_reason(images: list[str], reasons: dict[str, str]) -> str:
    if len(images) == 1:
        return reasons.get(images[0], "not registered")
    return "panorama faces: " + "; ".join(f"{i.split('/')[0]}: {reasons.get(i, '?')}"
                                          for i in images)


def _reconstruction_names(recs: dict) -> dict[int, set[str]]:
    return {k: {im.name for im in rec.images.values() if im.has_pose}
            for k, rec in recs.items()}


def _diagnose(db_path: Path, names: list[str], model_names: dict[int, set[str]],
              best: int | None) -> tuple[dict[str, Any], dict[str, str]]:
    """Per image: keypoints, verified partners; a reason for each unregistered one."""
    import pycolmap
    db = pycolmap.Database.open(db_path)
    try:
        by_id = {im.image_id: im.name for im in db.read_all_images()}
        keypoints = {name: db.num_keypoints_for_image(iid) for iid, name in by_id.items()}
        pair_ids, inliers = db.read_two_view_geometry_num_inliers()
    finally:
        db.close()
    partners: dict[str, list[tuple[str, int]]] = {n: [] for n in names}
    for pid, count in zip(pair_ids, inliers, strict=True):
        a, b = pycolmap.pair_id_to_image_pair(pid)
        na, nb = by_id.get(a), by_id.get(b)
        if na in partners and nb in partners:
            partners[na].append((nb, int(count)))
            partners[nb].append((na, int(count)))
    main = model_names.get(best, set()) if best is not None else set()
    reasons = {}
    for name in names:
        if name in main:
            continue
        kp = keypoints.get(name, 0)
        good = [(n, c) for n, c in partners[name] if c >= MIN_INLIERS]
        other = next((imgs for k, imgs in model_names.items() if k != best and name in imgs),
                     None)
        if kp < MIN_FEATURES:
            reasons[name] = (f"{FEW_FEATURES} ({kp} SIFT keypoints, need {MIN_FEATURES}): "
                             "blank, blurred or too dark?")
        elif not good:
            top = max((c for _, c in partners[name]), default=0)
            reasons[name] = (f"no overlap: no verified matches with any other photo "
                             f"(best {top} inliers, need {MIN_INLIERS})")
        elif other is not None:
            group = sorted(other - {name} - main)
            reasons[name] = (f"overlaps only with a separate group of {len(group)} photo(s) "
                             f"({', '.join(group[:5])}) that shares too little with the rest")
        elif all(n not in main for n, _ in good):
            reasons[name] = ("matches only photos that did not register either "
                             f"({', '.join(n for n, _ in good[:5])})")
        else:
            reasons[name] = (f"matched {len(good)} photo(s) but its pose could not be solved "
                             "(too few matches on triangulated points)")
    stats = {"keypoints_median": float(np.median(list(keypoints.values()) or [0])),
             "verified_pairs": int(sum(1 for c in inliers if c >= MIN_INLIERS))}
    return stats, reasons


def _judge(result: SfmResult, opts: SfmOptions, where: Path) -> None:
    """Fail (InputError) below the stated share; warn otherwise."""
    total = len(result.photos)
    share = len(result.registered) / total if total else 0.0
    if result.unregistered:
        listing = "; ".join(f"{n}: {r}" for n, r in sorted(result.unregistered.items()))
        if share < opts.min_registered or len(result.registered) < 2:
            raise InputError(
                f"only {len(result.registered)} of {total} photos registered "
                f"(need {opts.min_registered:.0%}); not registered: {listing}", where)
        msg = (f"{len(result.unregistered)} of {total} photos did not register and are left "
               f"out: {listing}")
        result.warnings.append(msg)


def _apply_panorama_rig(db_path: Path, face_names: set[str]) -> set[int]:
    """Group each panorama's six faces into one rig frame with fixed rotations.

    Returns the face cameras' ids (their intrinsics are exact: keep them fixed).
    """
    import pycolmap
    cameras = []
    for face, rot in panorama.FACES.items():
        cam = pycolmap.RigConfigCamera(image_prefix=f"{panorama.FACE_PREFIX}{face}/")
        if face == "front":
            cam.ref_sensor = True
        else:
            cam.cam_from_rig = pycolmap.Rigid3d(pycolmap.Rotation3d(rot), np.zeros(3))
        cameras.append(cam)
    db = pycolmap.Database.open(db_path)
    try:
        pycolmap.apply_rig_config([pycolmap.RigConfig(cameras=cameras)], db)
        return {im.camera_id for im in db.read_all_images() if im.name in face_names}
    finally:
        db.close()


def triangulate_known_poses(photos_dir: str | Path, model: ColmapModel,
                            options: SfmOptions | None = None,
                            progress: Progress | None = None) -> ColmapModel:
    """Fill ``model``'s sparse points by matching ``photos_dir`` with the poses fixed.

    Poses and intrinsics stay exactly as given; returns a copy with points3D,
    their colours, errors and tracks (the frame metadata is kept).
    """
    import pycolmap
    opts = options or SfmOptions()
    progress = progress or Progress(quiet=True)
    photos_dir = Path(photos_dir)
    missing = [n for n in model.names if not (photos_dir / n).is_file()]
    if missing:
        raise InputError(f"photos of the posed images are missing: {', '.join(missing[:5])}"
                         + (" ..." if len(missing) > 5 else ""), photos_dir)
    work = Path(tempfile.mkdtemp(prefix="gaslight-tri-"))
    pycolmap.set_random_seed(opts.seed)
    try:
        db_path = work / "database.db"
        with colmap_logging(opts.verbose):
            progress.message(f"extracting SIFT features from {len(model.names)} posed photos")
            extraction = pycolmap.FeatureExtractionOptions(
                max_image_size=opts.max_image_size, num_threads=opts.extraction_threads)
            extraction.sift.peak_threshold = opts.peak_threshold
            shared = len(model.intrinsics) == 1
            pycolmap.extract_features(
                db_path, photos_dir, image_names=model.names,
                camera_mode=pycolmap.CameraMode.SINGLE if shared else
                pycolmap.CameraMode.PER_IMAGE,
                reader_options=pycolmap.ImageReaderOptions(camera_model="PINHOLE"),
                extraction_options=extraction, device=pycolmap.Device.cpu)
            progress.message("matching (exhaustive)")
            pycolmap.match_exhaustive(
                db_path, matching_options=pycolmap.FeatureMatchingOptions(
                    num_threads=opts.matching_threads),
                verification_options=_verification_options(opts.seed),
                device=pycolmap.Device.cpu)
            # The reconstruction must use the database's image, camera (and so rig
            # and frame) ids: write the given poses under those ids.
            db = pycolmap.Database.open(db_path)
            try:
                db_ids = {im.name: (im.image_id, im.camera_id) for im in db.read_all_images()}
                agreement = _match_agreement(db, model, db_ids)
                if opts.guided_matching:
                    _guide(db, model, db_ids, progress)
            finally:
                db.close()
            intr = {}
            for name, cid in zip(model.names, model.camera_ids, strict=True):
                src = model.intrinsics[cid]
                db_cid = db_ids[name][1]
                intr[db_cid] = ColmapCamera(db_cid, src.model, src.width, src.height,
                                            src.params.copy())
            given = work / "given"
            write_model(given, ColmapModel(
                cameras=model.cameras, image_ids=[db_ids[n][0] for n in model.names],
                camera_ids=[db_ids[n][1] for n in model.names], intrinsics=intr))
            rec = pycolmap.Reconstruction(str(given))
            progress.message("triangulating with the poses fixed")
            out = work / "triangulated"
            out.mkdir()
            rec = pycolmap.triangulate_points(rec, db_path, photos_dir, out,
                                              options=pycolmap.IncrementalPipelineOptions(
                                                  num_threads=opts.threads,
                                                  random_seed=opts.seed))
            if opts.guided_matching:
                _drop_short_tracks(rec)
                rec.write(str(out))  # the binary files triangulate_points wrote, pruned
            rec.write_text(str(out))
        filled = read_model(out)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    by_name = {c.name: c for c in filled.cameras}
    drift = max(float(np.abs(by_name[c.name].R - c.R).max() + np.abs(by_name[c.name].t - c.t)
                      .max()) for c in model.cameras if c.name in by_name)
    if drift > 1e-6:
        raise GaslightError(f"triangulation moved the given poses (by {drift:.2e})")
    # Keep the given cameras and ids; re-key the tracks from pycolmap's image ids to ours.
    id_map = {fid: model.image_ids[model.names.index(c.name)]
              for fid, c in zip(filled.image_ids, filled.cameras, strict=True)}
    lookup = np.zeros(max(id_map) + 1, np.int64)
    lookup[list(id_map)] = list(id_map.values())
    tracks = [np.column_stack([lookup[t[:, 0]], t[:, 1]]) for t in filled.tracks or []]
    points2d = [filled.points2d[filled.names.index(n)] if n in by_name else np.zeros((0, 3))
                for n in model.names]
    result = ColmapModel(cameras=model.cameras, points=filled.points,
                         point_colours=filled.point_colours, point_errors=filled.point_errors,
                         point_ids=filled.point_ids, image_ids=model.image_ids,
                         camera_ids=model.camera_ids, intrinsics=model.intrinsics,
                         points2d=points2d, tracks=tracks, frame=dict(model.frame),
                         notes=list(model.notes), source=model.source, agreement=agreement)
    if agreement is not None and agreement.warns:
        result.notes.append(agreement.sentence())
    return result


def _drop_short_tracks(rec: Any) -> None:
    """Remove ``rec``'s points fewer than :data:`.guided.MIN_TRACK` views see: a guided
    match's false twin lies on the same epipolar line, where two views cannot tell it."""
    from .guided import MIN_TRACK

    for pid in [pid for pid, point in rec.points3D.items()
                if point.track.length() < MIN_TRACK]:
        rec.delete_point3D(pid)


def _guide(db: Any, model: ColmapModel, db_ids: dict[str, tuple[int, int]],
           progress: Progress) -> None:
    """Add the given poses' guided matches (:mod:`.guided`) to ``db`` (the cameras are
    at the photos' size, as the triangulation needs them)."""
    from .guided import add_guided_matches

    added = add_guided_matches(db, {db_ids[cam.name][0]: cam for cam in model.cameras})
    progress.message(f"{added} more matches near the poses' epipolar lines")


def _match_agreement(db: Any, model: ColmapModel, db_ids: dict[str, tuple[int, int]]):
    """The verified matches in ``db`` against ``model``'s given poses
    (:func:`gaslight_usd.poses.agreement.epipolar_agreement`); None without matches."""
    import pycolmap

    from .agreement import epipolar_agreement

    name_of = {iid: name for name, (iid, _) in db_ids.items()}
    pair_ids, geometries = db.read_two_view_geometries()
    matches = []
    for pid, geometry in zip(pair_ids, geometries, strict=True):
        a, b = pid if isinstance(pid, tuple) else pycolmap.pair_id_to_image_pair(pid)
        inliers = np.asarray(geometry.inlier_matches, np.int64).reshape(-1, 2)
        if a in name_of and b in name_of and len(inliers):
            matches.append((name_of[a], name_of[b], inliers))
    used = {n for a, b, _ in matches for n in (a, b)}
    keypoints = {name_of[iid]: np.asarray(db.read_keypoints(iid), np.float64)[:, :2]
                 for iid in name_of if name_of[iid] in used}
    return epipolar_agreement(model, keypoints, matches)
