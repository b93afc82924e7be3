"""``gaslight2usd hdr PHOTOS... -o HDR_DIR``: photos to scene-linear HDR EXRs."""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

from ..chain import ChainRun
from ..errors import InputError, NotBuiltYet
from ..imageio import LDR_EXTENSIONS
from ..kinds import Artifact, Kind
from ..registry import default_registry
from ._common import add_common, emit, progress_from, settings_from

HELP = "uplift LDR photos to scene-linear HDR EXRs (one per photo)"
METHODS = {"linear": "uplift.linear", "bracket": "uplift.bracket",
           "recursive": "uplift.recursive"}
DESCRIPTION = """\
Uplift photos to HDR: one EXR per photo, named after it, in the working space
(ACEScg by default), with the method, EV steps and clipped fractions in its
header. Values are relative radiance normalised to the set's median EXIF
exposure.

methods:
  linear     the photo linearised, no uplift (the baseline; lamps stay clipped)
  bracket    merge bracketed exposures of each view (not built yet)
  recursive  GaSLight recursive exposure prediction (not built yet)
  auto       bracket when brackets are present, else recursive

examples:
  gaslight2usd hdr examples/room/photos -o out/hdr --method linear
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("hdr", help=HELP, description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("photos", nargs="+", type=Path, help="a folder of photos, or photo files")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="HDR_DIR",
                   help="folder for the EXRs (created)")
    p.add_argument("--method", choices=["auto", *METHODS], default="auto")
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


def run(args: argparse.Namespace) -> int:
    registry = default_registry()
    wanted = METHODS.get(args.method) if args.method != "auto" else None
    if args.method == "auto":
        wanted = next((c.name for c in registry.producing(Kind.HDR_VIEWS)
                       if c.step == "uplift"), None)
    if wanted not in registry:
        raise NotBuiltYet(f"uplift method {args.method!r} is not built yet; "
                          f"available: linear")
    settings = settings_from(args)
    out = args.output
    scratch = Path(tempfile.mkdtemp(prefix="gaslight-photos-"))
    try:
        folder = _photo_folder(args.photos, scratch)
        # The EXR folder is the run folder: report.json sits beside the views.
        runner = ChainRun(out, settings, registry, progress_from(args))
        arts = runner.run([Artifact(Kind.LDR_VIEWS, folder)], [Kind.HDR_VIEWS],
                          choose={"uplift": wanted}, outputs={Kind.HDR_VIEWS: out},
                          resume=False)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    record = runner.records[-1]
    emit(args, {"output": str(arts[Kind.HDR_VIEWS].path), **record.counts, **record.metrics},
         f"wrote {record.counts.get('views')} HDR views to {out}")
    return 0
