"""``gaslight2usd poses``: solve camera poses from photos, or import/convert given poses."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from ..chain import ChainRun
from ..errors import InputError
from ..kinds import Artifact, Kind
from ..poses.sfm import CAMERA_MODELS, MATCHERS, SfmOptions
from ..registry import default_registry
from ._common import add_common, emit, progress_from, settings_from

HELP = "solve camera poses from photos (SfM), or import and convert given poses"
DESCRIPTION = """\
Solve where every photo was taken (structure from motion with pycolmap: SIFT
features, matching, incremental mapping), or take poses you already have.

Solving:  gaslight2usd poses PHOTOS_DIR -o SPARSE_DIR
  Writes a standard COLMAP text model (cameras.txt, images.txt, points3D.txt;
  --binary for .bin) that COLMAP, nerfstudio and 3DGS trainers read, plus
  frame.json. The solved poses are moved to a well-behaved frame: +Y up (the
  cameras' mean up vector), the mean viewing heading along -Z, the floor (the
  lowest dense layer of sparse points) at y = 0 and the origin on it under the
  cameras' median point. Units stay unknown unless you give a scale
  (--camera-height, --scale or --scale-from); then they are metres and
  frame.json says meters_per_unit 1.
  Photos that do not register are named with the reason (too few features,
  no overlap with the others...); the run fails when fewer than
  --min-registered of them register. Lat-long panoramas (2:1 photos) become
  six cube-face cameras sharing one centre (--panorama).

Importing: gaslight2usd poses --from POSES -o OUT
  POSES is a COLMAP model folder (text or binary; also a parent holding 0/ or
  sparse/0) or a nerfstudio/instant-ngp transforms.json. OUT ending in .json
  is written as transforms.json, anything else as a COLMAP text model folder.
  Given poses keep their own frame. Add PHOTOS_DIR to triangulate sparse
  points with the given poses held fixed when POSES has none.

examples:
  gaslight2usd poses examples/room/photos -o out/sparse
  gaslight2usd poses photos -o sparse --scale-from IMG_0001.jpg,IMG_0002.jpg,0.5
  gaslight2usd poses photos -o sparse --camera-height 1.6
  gaslight2usd poses video_frames -o sparse --matcher sequential
  gaslight2usd poses --from sparse -o transforms.json
  gaslight2usd poses examples/room/photos --from examples/room/sparse/0 -o out/sparse
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("poses", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("photos", nargs="?", type=Path, metavar="PHOTOS_DIR",
                   help="folder of LDR photos (JPEG/PNG/TIFF)")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="OUT",
                   help="COLMAP model folder to write (created), or a .json for "
                        "transforms.json (with --from)")
    p.add_argument("--from", dest="from_poses", type=Path, metavar="POSES",
                   help="import these poses instead of solving (COLMAP model or "
                        "transforms.json)")
    s = p.add_argument_group("structure from motion")
    s.add_argument("--matcher", choices=MATCHERS, default=SfmOptions.matcher,
                   help="exhaustive: every pair (best for up to ~100 photos); sequential: "
                        "neighbours in file-name order (video frames)")
    s.add_argument("--camera-model", choices=CAMERA_MODELS, default=SfmOptions.camera_model,
                   help="COLMAP camera model (default SIMPLE_RADIAL: one focal length and "
                        "one radial distortion term; PINHOLE for rendered or undistorted "
                        "photos)")
    s.add_argument("--separate-cameras", action="store_true",
                   help="solve intrinsics per photo (default: one camera shared by all)")
    s.add_argument("--min-registered", type=float, default=SfmOptions.min_registered,
                   metavar="SHARE", help="fail when fewer than this share of the photos "
                   f"register (default {SfmOptions.min_registered}); otherwise the rest are "
                   "left out with a warning")
    s.add_argument("--panorama", choices=("auto", "on", "off"), default=SfmOptions.panorama,
                   help="treat photos as lat-long panoramas cut into 6 cube faces on one "
                        "centre: auto = photos with a 2:1 shape (default)")
    s.add_argument("--binary", action="store_true", help="write .bin files instead of .txt")
    scale = s.add_mutually_exclusive_group()
    scale.add_argument("--scale", type=float, metavar="FACTOR",
                       help="metres per SfM unit: the model is scaled to metres")
    scale.add_argument("--scale-from", metavar="IMG_A,IMG_B,METRES",
                       help="known distance in metres between the camera centres of two "
                            "photos: the model is scaled to metres")
    scale.add_argument("--camera-height", type=float, metavar="METRES",
                       help="the photos' median height above the floor: the model is "
                            "scaled to metres (needs the floor in some photos)")
    add_common(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    if args.from_poses is not None:
        return _import(args)
    if args.photos is None:
        raise InputError("give PHOTOS_DIR to solve poses, or --from POSES to import them")
    if args.output.suffix.lower() == ".json":
        raise InputError("SfM writes a COLMAP model folder; convert it to transforms.json "
                         "afterwards with --from", args.output)
    options = {"matcher": args.matcher, "camera_model": args.camera_model,
               "single_camera": not args.separate_cameras,
               "min_registered": args.min_registered, "panorama": args.panorama,
               "scale": args.scale, "scale_from": args.scale_from,
               "camera_height": args.camera_height, "binary": args.binary,
               "verbose": args.verbose}
    runner = ChainRun(args.output, settings_from(args), default_registry(),
                      progress_from(args))
    runner.run([Artifact(Kind.LDR_VIEWS, args.photos)], [Kind.POSES],
               choose={"poses": "poses.sfm"}, options={"poses": options},
               outputs={Kind.POSES: args.output}, resume=False)
    record = runner.records[-1]
    unregistered = record.metadata.get("unregistered", {})
    frame = record.metadata.get("frame", {})
    text = (f"registered {record.counts['registered']} of {record.counts['photos']} photos "
            f"({record.counts['points']} sparse points) in {record.seconds:.1f} s; "
            f"wrote {args.output}; units: {frame.get('units')}")
    posed = record.metadata.get("posed_as_neighbour", {})
    for name, photo in posed.items():
        text += f"\n  posed as {photo} (a darker frame too dark for SfM): {name}"
    for name, why in unregistered.items():
        text += f"\n  not registered: {name}: {why}"
    emit(args, {"output": str(args.output), **record.counts, **record.metrics,
                "seconds": record.seconds, "unregistered": unregistered,
                "posed_as_neighbour": posed, "frame": frame,
                "notes": record.metadata.get("notes", [])}, text)
    return 0


def _import(args: argparse.Namespace) -> int:
    from ..outputs import check_output
    from ..poses import read_poses, write_poses
    from ..poses.sfm import triangulate_known_poses

    t0 = time.perf_counter()
    check_output(args.output, folder=args.output.suffix.lower() != ".json")
    model = read_poses(args.from_poses)
    triangulated = False
    if args.photos is not None and len(model.points) == 0:
        model = triangulate_known_poses(
            args.photos, model, SfmOptions(verbose=args.verbose), progress_from(args))
        triangulated = True
    write_poses(args.output, model, binary=args.binary)
    seconds = time.perf_counter() - t0
    text = (f"wrote {len(model.cameras)} posed images and {len(model.points)} points "
            f"{'(triangulated) ' if triangulated else ''}to {args.output}")
    for note in model.notes:
        text += f"\nnote: {note}"
    emit(args, {"output": str(args.output), "images": len(model.cameras),
                "points": len(model.points), "triangulated": triangulated,
                "seconds": round(seconds, 3), "frame": model.frame, "notes": model.notes},
         text)
    return 0
