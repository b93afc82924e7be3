"""Is a probe point where the splats are? A point far outside sees the set from outside.

A typo in ``--at`` (a sign, a unit: 135 for 1.35) still renders an HDRI, of
the set seen from afar: nearly black, or one bright blob. The point is judged
against the box holding the central 96 % of the splats on each axis (far
backdrop splats do not widen it); a point further outside that box than a
quarter of its diagonal is reported.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

CENTRAL_SHARE = 0.96
FAR_FRACTION = 0.25


def splat_box(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Low and high corners of the box holding the central share of the positions."""
    tail = (1.0 - CENTRAL_SHARE) / 2.0
    lo, hi = np.quantile(np.asarray(positions, np.float64), [tail, 1.0 - tail], axis=0)
    return lo, hi


def outside_warning(point: Sequence[float], positions: np.ndarray) -> str | None:
    """A one-line warning when ``point`` lies far outside the splats, else None."""
    if len(positions) == 0:
        return None
    lo, hi = splat_box(positions)
    p = np.asarray(point, np.float64)
    gap = float(np.linalg.norm(np.maximum(lo - p, 0.0) + np.maximum(p - hi, 0.0)))
    diagonal = float(np.linalg.norm(hi - lo))
    if gap <= FAR_FRACTION * max(diagonal, 1e-9):
        return None
    span = ", ".join(f"{axis} {a:.3g}..{b:.3g}" for axis, a, b in zip("xyz", lo, hi,
                                                                      strict=True))
    where = ",".join(f"{v:.4g}" for v in p)
    return (f"probe point {where} lies {gap:.3g} units outside the splats (most lie within "
            f"{span}): its HDRI sees the set from outside")
