"""What the uplift cannot fix in a photo set, said once per run.

A photo that is mostly white holds no measurement: the uplift still makes an HDR view
of it (the recursive predictor invents one, the linear method leaves it flat at the
white level), and the fit treats that view like the others. Found silently by
``gaslight2usd bench --suite stability`` (perturbation ``clipped_frames``); now named.
So are photos saved at a low JPEG quality: the blocks smear the edges of clipped
regions, which the uplift reads as the lights' size (perturbation ``jpeg`` measures what
that costs at the probes).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ..imageio import jpeg_quality

LOW_JPEG_QUALITY = 50
"""JPEG quality under which a photo is named."""
MOSTLY_CLIPPED = 0.5
"""Share of a photo's pixels at white above which it is called mostly clipped."""


def clipped_photos_warning(names: Sequence[str], fractions: Sequence[float],
                           limit: float = MOSTLY_CLIPPED) -> str | None:
    """One line naming the photos with more than ``limit`` of their pixels clipped, or
    None when there are none."""
    bad = [(n, f) for n, f in zip(names, fractions, strict=True) if f > limit]
    if not bad:
        return None
    shown = ", ".join(f"{n} ({f:.0%})" for n, f in bad[:5]) + (" ..." if len(bad) > 5 else "")
    return (f"{len(bad)} of {len(names)} photo(s) are mostly clipped (over {limit:.0%} of "
            f"their pixels at white): {shown}; their HDR views are guesses, not measurements: "
            "reshoot them darker or leave them out")


def low_quality_warning(paths: Sequence[Path], limit: int = LOW_JPEG_QUALITY) -> str | None:
    """One line naming the JPEG photos saved at a quality under ``limit`` (estimated
    from their quantisation tables, :func:`gaslight_usd.imageio.jpeg_quality`), or None."""
    bad = [(p.name, q) for p in paths
           if p.suffix.lower() in (".jpg", ".jpeg") and (q := jpeg_quality(p)) is not None
           and q < limit]
    if not bad:
        return None
    shown = ", ".join(f"{n} (~{q})" for n, q in bad[:5]) + (" ..." if len(bad) > 5 else "")
    return (f"{len(bad)} of {len(paths)} photo(s) were saved at a low JPEG quality: {shown}; "
            "block artefacts blur the clipped lights' edges and bias their power: export "
            f"at quality {limit} or more (or shoot RAW/TIFF)")


def photo_set_warnings(paths: Sequence[Path], clipped_fractions: Sequence[float]) -> list[str]:
    """Every warning of this module for an uplifted photo set, in the order they are told."""
    found = (clipped_photos_warning([p.name for p in paths], clipped_fractions),
             low_quality_warning(paths))
    return [w for w in found if w]
