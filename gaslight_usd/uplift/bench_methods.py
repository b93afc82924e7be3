"""The uplift methods of this package, registered into ``bench --suite uplift``.

Imported by :mod:`gaslight_usd.bench.suite_uplift` (its plug-in module).
Method: ``recursive-fast`` (the paper's recursion with the fast predictor).
The recursion with the ``reexpose`` predictor equals ``ldr-baseline`` (tested
in tests/test_uplift.py), so it is not benchmarked.
"""

from __future__ import annotations

import numpy as np

from ..bench.suite_uplift import register_uplift_method
from .calibrate import evaluation_curve
from .fast_predictor import FastPredictor
from .recursive import uplift_recursive

_FAST = FastPredictor()


def recursive_fast(ldr: np.ndarray, curve: str) -> np.ndarray:
    return uplift_recursive(ldr, _FAST, evaluation_curve(curve)).linear


register_uplift_method("recursive-fast", recursive_fast)
