"""What the uplift cannot fix in a photo set, said once per run.

A photo that is mostly white holds no measurement: the uplift still makes an HDR view
of it (the recursive predictor invents one, the linear method leaves it flat at the
white level), and the fit treats that view like the others. Found silently by
``gaslight2usd bench --suite stability`` (perturbation ``clipped_frames``); now named.
"""

from __future__ import annotations

from collections.abc import Sequence

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
