"""Which photos are one bracket: grouped the way cameras shoot them.

A camera's auto-exposure bracket (AEB) is a run of frames shot one after the
other, the same size, whose exposures step by a constant ratio: in capture
order 0, -2, +2 EV (most cameras' default) or -2, 0, +2, so the *sorted* EVs
are evenly spaced. Photos are put in capture order (EXIF DateTimeOriginal +
SubSecTimeOriginal when every photo has it, else file-name order) and split
into runs that are either single photos or brackets:

- EXIF: consecutive, same size, known and distinct exposures, sorted EVs
  evenly spaced (``step_tolerance``: shutter speeds are rounded, 1/60 is not
  quite 2 stops from 1/250), no more than ``MAX_GAP_S`` (+ the earlier frame's
  exposure time) between capture times;
- pixels, when they are at hand: each frame looks like its nearest exposure
  in the bracket (:mod:`.similarity`, compared only where both saw the scene;
  a pair with nothing to compare, such as a nearly black frame beside a
  clipped one, is left to EXIF, but some pair of the bracket must compare).

Of all such splits the one with the most photos in brackets, then the fewest
brackets, wins (a longer first bracket on a tie): so a clipped bright frame or
a nearly black dark frame still joins its bracket, and two brackets shot back
to back are not merged into one (their exposures repeat).

A single photo shot right beside a bracket (same size, within the time gap)
gets a warning that says why it was left alone. A grouping file overrides all
of this (:func:`read_group_file`).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError

MAX_GAP_S = 2.0
"""Most seconds between the capture times of two frames of a bracket (plus exposure time)."""
MIN_EV_STEP = 0.3
"""Smallest exposure step of a bracket (cameras offer 1/3 stop)."""
MAX_BRACKET_FRAMES = 15
SAME_VIEW_SIMILARITY = 0.87
"""Least rank correlation (:func:`.similarity.similarity`) of two frames of one bracket:
between the lowest a bracket's exposure neighbours score and the highest two different
views of the bundled example (its smooth ceiling) score, as measured by
``pytest tests/test_bracket.py -k similarity_separates -s``."""

BY_EXIF_AND_PIXELS = "consecutive, EXIF exposure step, image similarity"
BY_EXIF = "consecutive, EXIF exposure step (images not comparable)"
BY_FILE = "grouping file"
SINGLE = "single photo"

Similar = Callable[[int, int], "float | None"]
"""Similarity of photos i and j (indices into the photo list); None when unmeasurable."""


@dataclass
class Photo:
    """What grouping needs of a photo, read from its header alone."""

    name: str
    path: Path
    ev: float | None
    exposure_time: float | None
    shape: tuple[int, ...]
    taken: float | None = None
    """Capture time, POSIX seconds with sub-seconds (EXIF), when known."""


@dataclass
class Bracket:
    """The photos of one view, in capture order: indices into the photo list while
    :func:`plan_groups` plans, Views (or Photos) once the caller maps them."""

    name: str
    views: list[Any]
    how: str = ""
    similarity: list[float | None] = field(default_factory=list)
    """Between exposure neighbours (sorted by EV); None where nothing could be compared."""

    @property
    def evs(self) -> list[float]:
        return [float(v.ev) if v.ev is not None else 0.0 for v in self.views]

    @property
    def is_bracket(self) -> bool:
        evs = self.evs
        return len(self.views) >= 2 and (max(evs) - min(evs)) >= MIN_EV_STEP

    def as_dict(self) -> dict[str, Any]:
        evs = [v.ev for v in self.views]
        return {"name": self.name, "photos": [v.path.name for v in self.views],
                "evs": [None if e is None else round(float(e), 3) for e in evs],
                "step_ev": _round(ev_step([e for e in evs if e is not None])),
                "how": self.how,
                "similarity": [None if s is None else round(s, 3) for s in self.similarity]}


@dataclass
class Grouping:
    """Brackets (and single photos) of a photo set, and how they were found."""

    brackets: list[Bracket]
    order: str
    warnings: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return {"order": self.order, "views": [b.as_dict() for b in self.brackets],
                "brackets": sum(b.is_bracket for b in self.brackets),
                "singles": sum(not b.is_bracket for b in self.brackets),
                "warnings": list(self.warnings)}

    def lines(self) -> list[str]:
        """Human-readable summary: one line per view."""
        n = sum(b.is_bracket for b in self.brackets)
        out = [f"grouped {sum(len(b.views) for b in self.brackets)} photos into {n} "
               f"bracket(s) and {len(self.brackets) - n} single photo(s); order: {self.order}"]
        for b in self.brackets:
            names = " ".join(v.path.name for v in b.views)
            if b.is_bracket:
                step = ev_step(b.evs)
                sims = ", ".join("-" if s is None else f"{s:.2f}" for s in b.similarity)
                detail = f"{len(b.views)} frames" + (f", {step:.2g} EV apart" if step else "")
                detail += f", similarity {sims}" if sims else ""
                out.append(f"  {b.name}: {names} ({detail}; {b.how})")
            else:
                out.append(f"  {b.name}: {names} ({b.how})")
        return out


def _round(x: float | None) -> float | None:
    return None if x is None else round(float(x), 3)


# -- capture time and order ---------------------------------------------------

def capture_time(spec: Any) -> float | None:
    """EXIF DateTimeOriginal (+ SubSecTimeOriginal) as POSIX seconds, or None."""
    raw = spec.getattribute("Exif:DateTimeOriginal") or spec.getattribute("DateTime")
    if not isinstance(raw, str):
        return None
    try:
        when = datetime.strptime(raw.strip()[:19], "%Y:%m:%d %H:%M:%S")
    except ValueError:
        return None
    sub = spec.getattribute("Exif:SubsecTimeOriginal") or spec.getattribute("Exif:SubsecTime")
    digits = re.sub(r"\D", "", str(sub)) if sub is not None else ""
    fraction = int(digits) / 10 ** len(digits) if digits else 0.0
    return when.timestamp() + fraction


def read_photo(path: Path) -> Photo:
    """A :class:`Photo` from the file's header."""
    from ..imageio import exposure_from_spec, read_header

    spec = read_header(path)
    exp = exposure_from_spec(spec)
    return Photo(Path(path).stem, Path(path), exp.ev if exp.known else None,
                 exp.exposure_time, (spec.height, spec.width, 3), capture_time(spec))


def capture_order(photos: Sequence[Photo]) -> tuple[list[int], str]:
    """Indices of ``photos`` in capture order, and which order that is."""
    by_name = sorted(range(len(photos)), key=lambda i: photos[i].path.name)
    missing = sum(p.taken is None for p in photos)
    if missing == 0 and photos:
        return (sorted(by_name, key=lambda i: photos[i].taken),
                "capture time (EXIF DateTimeOriginal)")
    if missing == len(photos):
        return by_name, "file name (no EXIF capture times)"
    return by_name, f"file name ({missing} of {len(photos)} photos have no EXIF capture time)"


# -- what makes a bracket -----------------------------------------------------

def step_tolerance(step: float) -> float:
    return max(0.2, 0.15 * step)


def ev_step(evs: Sequence[float]) -> float | None:
    """The constant step of ``evs`` once sorted, or None if they are not evenly spaced."""
    if len(evs) < 2:
        return None
    steps = np.diff(np.sort(np.asarray(evs, np.float64)))
    step = float(np.median(steps))
    if step < MIN_EV_STEP or np.any(np.abs(steps - step) > step_tolerance(step)):
        return None
    return step


def _link_problem(a: Photo, b: Photo) -> str | None:
    """Why consecutive photos ``a`` then ``b`` cannot be in one bracket (None: they can)."""
    if a.shape != b.shape:
        return "its size differs"
    if a.taken is not None and b.taken is not None:
        gap = abs(b.taken - a.taken)
        if gap > MAX_GAP_S + (a.exposure_time or 0.0):
            return f"it was shot {gap:.1f} s apart"
    return None


def _exif_problem(photos: Sequence[Photo], seg: Sequence[int]) -> str | None:
    """Why the photos ``seg`` (consecutive in capture order) are not a bracket by EXIF."""
    evs = [photos[i].ev for i in seg]
    if any(e is None for e in evs):
        return "a photo has no EXIF exposure time"
    sorted_evs = np.sort(np.asarray(evs, np.float64))
    if np.any(np.diff(sorted_evs) < MIN_EV_STEP):
        return "an exposure repeats"
    if ev_step(evs) is None:
        return "the exposures do not step by a constant ratio"
    return None


def bracket_candidates(photos: Sequence[Photo]) -> set[int]:
    """Photos that EXIF allows in some bracket: each in a valid pair with a capture neighbour."""
    order, _ = capture_order(photos)
    found: set[int] = set()
    for a, b in zip(order[:-1], order[1:], strict=True):
        if _link_problem(photos[a], photos[b]) is None and _exif_problem(photos, (a, b)) is None:
            found.update((a, b))
    return found


def _pixel_check(photos: Sequence[Photo], seg: Sequence[int], similar: Similar | None,
                 threshold: float
                 ) -> tuple[list[float | None], tuple[int, int, float | None] | None]:
    """Similarities of exposure neighbours; the first pair below ``threshold``, or the
    extremes with similarity None when no pair could be compared; None when it passes."""
    if similar is None:
        return [], None
    by_ev = sorted(seg, key=lambda i: photos[i].ev)
    sims: list[float | None] = []
    for i, j in zip(by_ev[:-1], by_ev[1:], strict=True):
        s = similar(i, j)
        sims.append(s)
        if s is not None and s < threshold:
            return sims, (i, j, s)
    if all(s is None for s in sims):  # nothing confirms it: frames too far apart to compare
        return sims, (by_ev[0], by_ev[-1], None)
    return sims, None


def _reference_name(photos: Sequence[Photo], seg: Sequence[int]) -> str:
    """The middle exposure's name: the frame the merge takes as its reference."""
    evs = [photos[i].ev if photos[i].ev is not None else 0.0 for i in seg]
    return photos[seg[int(np.argsort(evs, kind="stable")[len(seg) // 2])]].name


def plan_groups(photos: Sequence[Photo], similar: Similar | None = None,
                threshold: float = SAME_VIEW_SIMILARITY) -> Grouping:
    """Split photos into brackets and singles (see the module doc); items are indices."""
    order, order_text = capture_order(photos)
    n = len(order)
    links = [_link_problem(photos[order[k]], photos[order[k + 1]]) for k in range(n - 1)]
    sims_of: dict[tuple[int, ...], list[float | None]] = {}

    def valid(seg: tuple[int, ...]) -> bool:
        if _exif_problem(photos, seg) is not None:
            return False
        sims, failed = _pixel_check(photos, seg, similar, threshold)
        sims_of[seg] = sims
        return failed is None

    # best[k]: (photos in brackets, -brackets, segments) for order[k:]
    best: list[tuple[int, int, list[tuple[int, ...]]]] = [(0, 0, [])] * (n + 1)
    for k in range(n - 1, -1, -1):
        reach = 1
        while reach < min(MAX_BRACKET_FRAMES, n - k) and links[k + reach - 1] is None:
            reach += 1
        choice = None
        for length in range(reach, 0, -1):
            seg = tuple(order[k:k + length])
            if length > 1 and not valid(seg):
                continue
            covered, neg, rest = best[k + length]
            score = (covered + (length if length > 1 else 0), neg - (length > 1))
            if choice is None or score > choice[:2]:
                choice = (*score, [seg, *rest])
        best[k] = choice
    brackets = []
    for seg in best[0][2]:
        sims = sims_of.get(seg, [])
        how = SINGLE if len(seg) == 1 else (
            BY_EXIF_AND_PIXELS if any(s is not None for s in sims) else BY_EXIF)
        brackets.append(Bracket(_reference_name(photos, seg), list(seg), how, sims))
    grouping = Grouping(brackets, order_text)
    grouping.warnings = _lonely_warnings(photos, order, links, brackets, similar, threshold)
    return grouping


def _lonely_warnings(photos: Sequence[Photo], order: list[int], links: list[str | None],
                     brackets: list[Bracket], similar: Similar | None,
                     threshold: float) -> list[str]:
    """A warning for each single photo shot right beside a bracket, saying why it is alone."""
    where = {i: b for b in brackets for i in b.views}
    warnings = []
    for k, i in enumerate(order):
        if len(where[i].views) > 1:
            continue
        for side in (-1, 1):
            m = k + side
            if not 0 <= m < len(order) or links[min(k, m)] is not None:
                continue
            neighbour = where[order[m]]
            if len(neighbour.views) < 2:
                continue
            joined = tuple(sorted([*neighbour.views, i], key=order.index))
            reason = _exif_problem(photos, joined)
            if reason is None:
                _, failed = _pixel_check(photos, joined, similar, threshold)
                if failed is None:
                    continue  # it fits; the split was chosen for the brackets around it
                a, b, s = failed
                other = photos[b if a == i else a].path.name
                reason = (f"its image differs from {other} (similarity {s:.2f} < {threshold})"
                          if s is not None else
                          f"its image and {other}'s share nothing to compare (one is clipped "
                          "or black where the other is not)")
            elif reason == "a photo has no EXIF exposure time":
                reason = "it has no EXIF exposure time"
            elif reason == "an exposure repeats":
                reason = "its exposure repeats one of the bracket's"
            else:
                reason = "its exposure does not continue the bracket's constant step"
            names = ", ".join(photos[j].path.name for j in neighbour.views)
            warnings.append(f"{photos[i].path.name} is left as a view of its own beside the "
                            f"bracket {names}: {reason}; to merge it, list it with them in a "
                            "grouping file")
            break
    return warnings


# -- grouping file ------------------------------------------------------------

def read_group_file(path: Path) -> list[tuple[str | None, list[str]]]:
    """Parse a grouping file into (view name or None, photo file names) pairs.

    JSON: ``{"view": ["a.jpg", "b.jpg"], ...}``, or a list of lists (each view
    then named after its middle exposure); or text, one view a line:
    ``view: a.jpg b.jpg`` (``#`` starts a comment). Photo names are file names
    (or stems) in the photo folder; a photo may be listed once.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("no such grouping file", path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the grouping file: {exc}", path) from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError:
        data = None
    if data is None:
        groups: list[tuple[str | None, list[str]]] = []
        for n, line in enumerate(text.splitlines(), start=1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            if ":" not in line:
                raise InputError(f"line {n}: expected 'view: photo photo ...'", path)
            name, files = line.split(":", 1)
            groups.append((name.strip() or None, re.split(r"[\s,]+", files.strip())))
    elif isinstance(data, dict):
        groups = [(str(k), v) for k, v in data.items()]
    elif isinstance(data, list):
        groups = [(None, v) for v in data]
    else:
        groups = [(None, data)]
    seen_photos: set[str] = set()
    seen_names: set[str] = set()
    for name, files in groups:
        if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
            raise InputError("expected an object mapping view names to lists of photo file "
                             "names, a list of such lists, or lines 'view: a.jpg b.jpg'", path)
        files[:] = [f for f in files if f]
        if not files:
            raise InputError(f"view {name or '(unnamed)'!r} lists no photos", path)
        if name is not None and (not name or set(name) & set("/\\") or name in (".", "..")):
            raise InputError(f"view name {name!r} cannot name a file (no slashes)", path)
        if name is not None and name in seen_names:
            raise InputError(f"view {name!r} is named twice", path)
        seen_names.add(name or "")
        for f in files:
            if f in seen_photos:
                raise InputError(f"photo {f} is listed twice", path)
            seen_photos.add(f)
    return groups


def group_from_file(photos: Sequence[Photo], path: Path) -> Grouping:
    """The grouping a file gives; photos it does not list are single views (with a warning)."""
    by_name = {p.path.name: i for i, p in enumerate(photos)}
    by_stem = {p.name: i for i, p in enumerate(photos)}
    brackets, listed = [], set()
    for name, files in read_group_file(path):
        missing = [f for f in files if f not in by_name and f not in by_stem]
        if missing:
            raise InputError(f"view {name or files[0]!r} names photos that are not in the "
                             "input: " + ", ".join(missing), path)
        seg = [by_name[f] if f in by_name else by_stem[f] for f in files]
        listed.update(seg)
        brackets.append(Bracket(name or _reference_name(photos, seg), seg, BY_FILE))
    order, _ = capture_order(photos)
    rest = [i for i in order if i not in listed]
    for i in rest:
        brackets.append(Bracket(photos[i].name, [i], f"{SINGLE} (not in the grouping file)"))
    names = [b.name for b in brackets]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"view name(s) {', '.join(twice)} would name two HDR views "
                         "(a view and an unlisted photo of that name?)", path)
    warnings = []
    if rest:
        warnings.append(f"{len(rest)} photo(s) not in the grouping file {Path(path).name}, "
                        "each a view of its own: "
                        + ", ".join(photos[i].path.name for i in rest))
    return Grouping(brackets, f"grouping file {Path(path).name}", warnings)
