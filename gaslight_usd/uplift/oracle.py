"""The oracle predictor: re-exposes a ground-truth HDR image.

For tests and for the upper bound in benchmarks. ``hdr`` is linear radiance in
the curve's primaries on the scale of the photo (1.0 = the photo's white at
EV 0); ``darker`` at offset ``ev`` returns ``curve(hdr * 2**(ev - 2))`` clipped.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .curves import Curve


class OraclePredictor:
    name = "oracle"

    def __init__(self, hdr: np.ndarray | None = None):
        if hdr is None:
            raise InputError("the oracle predictor needs a ground-truth HDR image "
                             "(it exists for tests and benchmarks)")
        self.hdr = np.maximum(np.nan_to_num(np.asarray(hdr, np.float32)), 0.0)

    def _expose(self, curve: Curve, ev: float, shape: tuple[int, ...]) -> np.ndarray:
        if self.hdr.shape != shape:
            raise ValueError(f"oracle HDR is {self.hdr.shape}, photo is {shape}")
        lin = np.clip(self.hdr * np.float32(2.0 ** ev), 0.0, 1.0)
        return np.clip(curve.to_encoded(lin), 0.0, 1.0).astype(np.float32)

    def darker(self, encoded: np.ndarray, curve: Curve, ev: float) -> np.ndarray:
        return self._expose(curve, ev - 2.0, encoded.shape)

    def brighter(self, encoded: np.ndarray, curve: Curve, ev: float) -> np.ndarray:
        return self._expose(curve, ev + 2.0, encoded.shape)


PREDICTORS = {
    "oracle": (OraclePredictor,
               "re-exposes a ground-truth HDR (tests and benchmark upper bound)"),
}
"""The predictors this module offers: name -> (factory, description); see
:mod:`.predictors`."""
