"""PU21: perceptually uniform encoding of absolute luminance (cd/m^2).

Source: R. K. Mantiuk and M. Azimi, "PU21: A novel perceptually uniform
encoding for adapting existing quality metrics for HDR", Picture Coding
Symposium (PCS) 2021, doi:10.1109/PCS50896.2021.9477471.

The encoding is a fitted rational power function of luminance ``L`` clamped
to [0.005, 10000] cd/m^2::

    V(L) = p6 * (((p0 + p1 * L**p3) / (1 + p2 * L**p3)) ** p4 - p5)

with one parameter set per variant (the authors' reference code; only the
two banding variants are carried here). The ``banding_glare`` variant is the
one the authors recommend for quality metrics. Reference values
(banding_glare): 0.005, 1, 100, 10000 cd/m^2 -> about 0, 36.5, 256.4, 595.4.
An SDR display's range (0.1 to 100 cd/m^2) spans roughly 0 to 256, which is
why PSNR on PU values uses a peak of 256 (as in the authors' ``pu21_metric``).
"""

from __future__ import annotations

import numpy as np

L_MIN = 0.005
"""Lowest luminance the encoding distinguishes (cd/m^2); darker values are clamped."""
L_MAX = 10000.0
"""Highest luminance the encoding distinguishes (cd/m^2); brighter values are clamped."""
PSNR_PEAK = 256.0
"""Peak value for PSNR on PU21 values: the code of 100 cd/m^2 (SDR white), as pu21_metric."""

PARAMETERS: dict[str, tuple[float, ...]] = {
    "banding": (1.070275272, 0.4088273932, 0.153224308, 0.2520326168, 1.063512885,
                1.14115047, 521.4527484),
    "banding_glare": (0.353487901, 0.3734658629, 8.277049286e-05, 0.9062562627,
                      0.09150303166, 0.9099517204, 596.3148142),
}


def pu21_encode(luminance: np.ndarray | float, variant: str = "banding_glare") -> np.ndarray:
    """Absolute luminance or linear RGB in cd/m^2 (any shape) -> PU21 values.

    Values are clamped to [:data:`L_MIN`, :data:`L_MAX`] first; the encoding is
    applied element-wise, so RGB channels are encoded independently (as the
    reference implementation does for colour images).
    """
    try:
        p0, p1, p2, p3, p4, p5, p6 = PARAMETERS[variant]
    except KeyError:
        raise ValueError(f"unknown PU21 variant {variant!r}; one of {sorted(PARAMETERS)}") from None
    lum = np.clip(np.asarray(luminance, dtype=np.float64), L_MIN, L_MAX)
    lp = lum ** p3
    return p6 * (((p0 + p1 * lp) / (1.0 + p2 * lp)) ** p4 - p5)
