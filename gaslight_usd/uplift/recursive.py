"""The paper's recursive exposure prediction (GaSLight, section 3.1).

A predictor renders the photo 2 EV darker; it is applied to its own output
until the darkest image has no pixel above ``threshold`` (default 0.9) or
``max_steps`` steps (6, EV -12) are done. Optionally brighter steps (+2, +4)
run until the brightest image's minimum is above ``bright_threshold``. The
stack is merged with :func:`.merge.merge_stack`. A photo with nothing above the
threshold gets no darker step at all.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .curves import Curve
from .merge import merge_stack
from .predictors import Predictor

STEP_EV = 2.0


@dataclass
class UpliftResult:
    """Linear radiance relative to the photo's exposure, plus the stack behind it."""

    linear: np.ndarray
    stack: list[np.ndarray] = field(default_factory=list)
    evs: list[float] = field(default_factory=list)

    @property
    def darker_steps(self) -> int:
        return sum(1 for e in self.evs if e < 0)

    @property
    def brighter_steps(self) -> int:
        return sum(1 for e in self.evs if e > 0)

    @property
    def min_ev(self) -> float:
        return float(min(self.evs))


def _peak(encoded: np.ndarray) -> float:
    return float(np.max(encoded)) if encoded.size else 0.0


THRESHOLD = 0.9
"""Encoded level the darkest exposure's pixels must stay under (the paper's stop rule)."""
MAX_STEPS = 6
"""Most darker steps: 6 x 2 EV reaches EV -12."""


def uplift_recursive(encoded: np.ndarray, predictor: Predictor, curve: Curve,
                     threshold: float = THRESHOLD, max_steps: int = MAX_STEPS,
                     brighter: bool = False,
                     max_bright_steps: int = 2, bright_threshold: float = 0.8
                     ) -> UpliftResult:
    """Uplift one encoded photo ``(H, W, 3)`` in [0, 1] to linear radiance.

    Returns linear values in the curve's primaries, 1.0 = the photo's white.
    """
    if not 0.0 < threshold <= 1.0:
        raise ValueError("threshold must be in (0, 1]")
    photo = np.clip(np.asarray(encoded, np.float32), 0.0, 1.0)
    stack, evs = [photo], [0.0]
    current, ev = photo, 0.0
    for _ in range(max_steps):
        if _peak(current) < threshold:
            break
        current = np.clip(predictor.darker(current, curve, ev), 0.0, 1.0).astype(np.float32)
        ev -= STEP_EV
        stack.append(current)
        evs.append(ev)
    if brighter:
        current, ev = photo, 0.0
        for _ in range(max_bright_steps):
            if float(np.min(current)) > bright_threshold:
                break
            current = np.clip(predictor.brighter(current, curve, ev), 0.0, 1.0).astype(
                np.float32)
            ev += STEP_EV
            stack.insert(0, current)
            evs.insert(0, ev)
    if len(stack) == 1:
        return UpliftResult(curve.to_linear(photo), stack, evs)
    return UpliftResult(merge_stack(stack, evs, curve), stack, evs)
