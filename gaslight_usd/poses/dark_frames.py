"""Darker frames SfM cannot place, posed as the photo shot right before them.

The README's capture adds, beside the photos, a darker frame for each light, exposed for
the light and shot from a photo's position ("Shooting the lights"). A frame exposed for
a bare bulb is 10-13 stops darker than the photos: black but for the bulb, a few dozen
SIFT keypoints where SfM needs a hundred (the chain bench's shaded room: 29 and 34), so
it does not register and the fit would go without the only measurement of that light.

Such a frame is posed as the photo it was shot beside: of the photos just before and
after it in capture order (EXIF capture times, else file names, as brackets are
ordered: :func:`gaslight_usd.uplift.grouping.capture_order`) the one nearer in time,
within :data:`gaslight_usd.uplift.grouping.MAX_GAP_S`; without capture times the one
before it. That photo must have registered and be the same size, and the frame at least
:data:`MIN_STOPS_DARKER` darker by EXIF; SfM must have left the frame out for too few
features (:func:`gaslight_usd.poses.sfm.solve_poses` passes only those: a photo with
features that matched nothing was shot from elsewhere). A frame SfM did register keeps
its own pose; one that follows no such photo stays out (and is named). The report says
which frames were posed so (``SfmResult.stats["posed_as_neighbour"]``).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from ..uplift.grouping import MAX_GAP_S, Photo, capture_order, read_photo
from .colmap import ColmapModel, with_added_images

MIN_STOPS_DARKER = 2.0
"""How much darker than its neighbour (EXIF exposure) a frame must be to be taken for a
darker frame shot from that photo's position (the README: often 2-6 stops for windows,
10-13 for bare bulbs)."""


def _neighbour(photos: list[Photo], order: list[int], k: int, registered: set[str]
               ) -> Photo | None:
    """The photo ``photos[k]`` was shot beside, where SfM registered it and ``photos[k]``
    is a darker frame of it (module docstring): of the photos just before and after it
    in capture order the one nearer in capture time, within the gap; without capture
    times the one before it (the README: shot right after the photo)."""
    frame = photos[k]
    at = order.index(k)
    beside = [photos[order[j]] for j in (at - 1, at + 1) if 0 <= j < len(order)]
    timed = frame.taken is not None and all(p.taken is not None for p in beside)
    if timed:
        gaps = [(abs(float(p.taken) - float(frame.taken)), p) for p in beside]
        near = [(gap, p) for gap, p in gaps
                if gap <= MAX_GAP_S + (p.exposure_time or 0.0) + (frame.exposure_time or 0.0)]
        other = min(near, key=lambda gp: gp[0])[1] if near else None
    else:
        other = photos[order[at - 1]] if at > 0 else None
    if other is None or other.path.name not in registered or other.shape != frame.shape:
        return None
    if other.ev is None or frame.ev is None or other.ev - frame.ev < MIN_STOPS_DARKER:
        return None
    return other


def pose_dark_frames(model: ColmapModel, paths: list[Path], unregistered: dict[str, str]
                     ) -> tuple[ColmapModel, dict[str, str]]:
    """``model`` with each of the ``unregistered`` photos (names) that is a darker frame
    of a registered neighbour (module docstring) added at that neighbour's pose, and
    which frames were posed so (frame -> neighbour)."""
    if not unregistered or not model.cameras:
        return model, {}
    photos = [read_photo(p) for p in paths]
    order, _ = capture_order(photos)
    by_name = {cam.name: i for i, cam in enumerate(model.cameras)}
    registered = set(by_name)
    posed: dict[str, str] = {}
    added = []
    for k, photo in enumerate(photos):
        if photo.path.name not in unregistered:
            continue
        other = _neighbour(photos, order, k, registered)
        if other is None:
            continue
        i = by_name[other.path.name]
        added.append((replace(model.cameras[i], name=photo.path.name), i))
        posed[photo.path.name] = other.path.name
    return with_added_images(model, added), posed
