"""``gaslight2usd hdr PHOTOS... -o HDR_DIR``: photos to scene-linear HDR EXRs."""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

from ..chain import ChainRun
from ..errors import InputError, NotBuiltYet
from ..imageio import LDR_EXTENSIONS, list_images
from ..kinds import Artifact, Kind
from ..registry import default_registry
from ..uplift.bracket import BracketOptions
from ..uplift.pipeline import UpliftOptions
from ._common import add_common, emit, progress_from, settings_from

HELP = "uplift LDR photos to scene-linear HDR EXRs (one per photo)"
METHODS = {"linear": "uplift.linear", "bracket": "uplift.bracket",
           "recursive": "uplift.recursive"}
DESCRIPTION = """\
Uplift photos to HDR: one EXR per photo, named after it (with bracket: one per
bracket, named after its middle exposure), in the working space (ACEScg by
default), with the method, source photos, EV steps and clipped fractions in its
header. Values are relative radiance normalised to the set's median EXIF
exposure.

methods:
  linear     the photo linearised, no uplift (the baseline; lamps stay clipped)
  bracket    merge bracketed exposures of each view; photos that are no bracket
             are linearised alone; refuses photos that hold no bracket at all
  recursive  GaSLight recursive exposure prediction: a predictor renders the photo
             2 EV darker, again and again until nothing is above --threshold
             (at most 6 steps, EV -12); the stack is merged (Debevec, log domain)
  auto       bracket when brackets are present, else recursive

predictors (--predictor, recursive only):
  fast       calibrated highlight model, CPU, no downloaded weights (default)
  diffusion  the GaSLight diffusion model; bring your own weights: --weights PATH
             or $GASLIGHT_WEIGHTS (needs the optional `diffusers` package)
  reexpose   no prediction (clipped regions stay flat; a baseline)
  oracle     tests and benchmarks only (needs a ground-truth HDR)

bracket grouping (printed, and kept in report.json and each EXR's header):
  Photos are taken in capture order (EXIF DateTimeOriginal + SubSecTimeOriginal
  when every photo has it, else file names). A bracket is a run of consecutive
  photos of one size, shot at most 2 s apart, whose exposures (EXIF exposure
  time, f-number, ISO) step by a constant ratio once sorted (0/-2/+2 EV and
  -2/0/+2 EV alike), each frame looking like its nearest exposure where both are
  unclipped and above the noise floor. A photo left alone beside a bracket is
  warned about. --group-file FILE overrides, one view per entry, file names
  relative to the photo folder; unlisted photos become views of their own:
    text:  hall: IMG_0101.jpg IMG_0102.jpg IMG_0103.jpg   (# starts a comment)
    JSON:  {"hall": ["IMG_0101.jpg", "IMG_0102.jpg"], ...}
           or [["IMG_0101.jpg", "IMG_0102.jpg"], ...] (named after the middle exposure)

A 2:1 photo is treated as a lat-long panorama: uplifted face by face on a cube
and blended back (--panorama off to disable).

examples:
  gaslight2usd hdr examples/room/photos -o out/hdr
  gaslight2usd hdr shots/ -o out/hdr --method bracket --group-file groups.txt
  gaslight2usd hdr examples/room/photos -o out/hdr --method linear
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("hdr", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("photos", nargs="+", type=Path, help="a folder of photos, or photo files")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="HDR_DIR",
                   help="folder for the EXRs (created)")
    p.add_argument("--method", choices=["auto", *METHODS], default="auto")
    u = p.add_argument_group("uplift")
    u.add_argument("--predictor", default=UpliftOptions.predictor, metavar="NAME",
                   help="exposure predictor for --method recursive "
                        f"(default: {UpliftOptions.predictor})")
    u.add_argument("--weights", metavar="PATH",
                   help="predictor weights (diffusion: checkpoint; default $GASLIGHT_WEIGHTS)")
    u.add_argument("--threshold", type=float, default=UpliftOptions.threshold,
                   help="stop darker steps when the darkest image's max is below this "
                        f"(encoded, default {UpliftOptions.threshold})")
    u.add_argument("--max-steps", type=int, default=UpliftOptions.max_steps,
                   help=f"most darker steps (default {UpliftOptions.max_steps})")
    u.add_argument("--brighter", action="store_true",
                   help="also predict +2/+4 EV images for the shadows")
    u.add_argument("--save-stacks", action="store_true",
                   help="write the exposure stacks as 16-bit PNGs under HDR_DIR/stacks")
    u.add_argument("--group-file", type=Path, metavar="FILE",
                   help="bracket grouping that overrides EXIF: lines 'view: a.jpg b.jpg' or "
                        "JSON {view: [photos]} / [[photos], ...] (see above)")
    u.add_argument("--response", choices=["ocio", "debevec"], default=BracketOptions.response,
                   help="bracket camera response: the --input-space transform (default) or "
                        "recovered from each bracket (Debevec-Malik)")
    u.add_argument("--panorama", choices=["auto", "on", "off"], default=UpliftOptions.panorama,
                   help="treat 2:1 photos as lat-long panoramas "
                        f"(default {UpliftOptions.panorama})")
    add_common(p, colour=True)
    p.set_defaults(handler=run)


def _photo_folder(paths: list[Path], scratch: Path) -> Path:
    """A folder holding exactly the given photos (links in a scratch folder)."""
    if len(paths) == 1 and paths[0].is_dir():
        return paths[0]
    for p in paths:
        if not p.is_file():
            raise InputError("no such photo", p)
        if p.suffix.lower() not in LDR_EXTENSIONS:
            raise InputError("not a photo (expected JPEG, PNG or TIFF)", p)
        (scratch / p.name).symlink_to(p.resolve())
    return scratch


def _photo_paths(paths: list[Path]) -> list[Path]:
    if len(paths) == 1 and paths[0].is_dir():
        return list_images(paths[0], LDR_EXTENSIONS)
    return [p for p in paths if p.is_file()]


def _auto_method(args: argparse.Namespace) -> str:
    """bracket when brackets are present (or a grouping file is given), else recursive."""
    if args.group_file:
        return "bracket"
    from ..uplift.bracket import find_brackets

    s = settings_from(args)
    found = find_brackets(_photo_paths(args.photos), s.input_space, s.working_space,
                          s.ocio_config)
    return "bracket" if found else "recursive"


def _stage_options(args: argparse.Namespace) -> dict:
    if not 0.0 < args.threshold <= 1.0:
        raise InputError(f"--threshold must be in (0, 1], got {args.threshold}")
    if args.max_steps < 0:
        raise InputError(f"--max-steps must be >= 0, got {args.max_steps}")
    return {"predictor": args.predictor, "weights": args.weights,
            "threshold": args.threshold, "max_steps": args.max_steps,
            "brighter": args.brighter, "save_stacks": args.save_stacks,
            "group_file": str(args.group_file) if args.group_file else None,
            "response": args.response, "panorama": args.panorama}


def run(args: argparse.Namespace) -> int:
    registry = default_registry()
    method = _auto_method(args) if args.method == "auto" else args.method
    wanted = METHODS.get(method)
    if wanted not in registry:
        built = ", ".join(m for m, c in METHODS.items() if c in registry)
        raise NotBuiltYet(f"uplift method {method!r} is not built yet; available: {built}")
    settings = settings_from(args)
    out = args.output
    scratch = Path(tempfile.mkdtemp(prefix="gaslight-photos-"))
    try:
        folder = _photo_folder(args.photos, scratch)
        # The EXR folder is the run folder: report.json sits beside the views.
        runner = ChainRun(out, settings, registry, progress_from(args))
        arts = runner.run([Artifact(Kind.LDR_VIEWS, folder)], [Kind.HDR_VIEWS],
                          choose={"uplift": wanted}, outputs={Kind.HDR_VIEWS: out},
                          options={"uplift": _stage_options(args)},
                          resume=False)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    record = runner.records[-1]
    grouping = record.metadata.get("grouping")
    data = {"output": str(arts[Kind.HDR_VIEWS].path), **record.counts, **record.metrics}
    text = f"wrote {record.counts.get('views')} HDR views to {out} ({method})"
    if grouping:
        data["grouping"] = grouping
        text += "\n" + "\n".join(grouping_lines(grouping))
    emit(args, data, text)
    return 0


def grouping_lines(grouping: dict) -> list[str]:
    """What became of each photo: one line per HDR view, then the warnings."""
    lines = [f"grouping ({grouping['order']}): {grouping['brackets']} bracket(s), "
             f"{grouping['singles']} single photo(s)"]
    for view in grouping["views"]:
        how = view["how"]
        if len(view["photos"]) > 1:
            step = f", {view['step_ev']:.2g} EV apart" if view.get("step_ev") else ""
            how = f"{len(view['photos'])} frames{step}; {how}"
        lines.append(f"  {view['name']}.exr <- {' '.join(view['photos'])} ({how})")
    lines += [f"warning: {w}" for w in grouping.get("warnings", [])]
    return lines
