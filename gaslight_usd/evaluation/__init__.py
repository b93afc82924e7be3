"""Ground truth and metrics: reference LDR/HDR pairs from real HDR images, the
relighting protocol (Mitsuba 3), PU21 and plain HDR errors.

- :mod:`.metrics`: MSE/PSNR, log-luminance RMSE, relative L1, angular error,
  PU21-PSNR (anchored at photo white or at the truth's peak), light-source
  power/peak errors in stops, exposure alignment;
- :mod:`.pu21`: the PU21 encoding (Mantiuk & Azimi, PCS 2021);
- :mod:`.relight`: spheres on a plane lit by an HDR image, renders compared;
- :mod:`.reference`: LDR/HDR test pairs from panoramas or any HDR image;
- :mod:`.curves`: camera curves (sRGB, gamma 2.2, filmic) and their inverses.

Mitsuba is imported only when a render is asked for.
"""

from .curves import CURVE_NAMES, decode, encode
from .metrics import (
    PSNR_CAP_DB,
    angular_error_deg,
    exposure_alignment_scale,
    hdr_errors,
    light_source_errors,
    log_luminance_rmse,
    mse,
    psnr,
    pu21_psnr,
    pu21_psnr_peak,
    relative_l1,
)
from .pu21 import pu21_encode
from .reference import ReferencePair, build_pairs, load_source, make_pair, shared_sources
from .relight import RelightRenderer, RelightScores, compare_renders, relight_scores

__all__ = [
    "CURVE_NAMES", "PSNR_CAP_DB", "ReferencePair", "RelightRenderer", "RelightScores",
    "angular_error_deg", "build_pairs", "compare_renders", "decode", "encode",
    "exposure_alignment_scale", "hdr_errors", "light_source_errors", "load_source",
    "log_luminance_rmse", "make_pair", "mse", "psnr", "pu21_encode", "pu21_psnr",
    "pu21_psnr_peak", "relative_l1", "relight_scores", "shared_sources",
]
