"""Error metrics for HDR images, each with its formula and source.

Conventions: ``pred`` and ``truth`` are float arrays ``(H, W, 3)`` of linear
relative radiance in the same colour space (luminance weights default to
ITU-R BT.709, pass the working space's weights from
:func:`gaslight_usd.colour.luminance_weights` otherwise). Truth values of 1.0
mean "the white level of the photo" (the reference pairs and the project's
relative-radiance views share that scale), so truth pixels in [0.2, 0.8] are
the well-exposed ones used for exposure alignment.

Hand-computed cases (tested): identical images give MSE 0 and PSNR
:data:`PSNR_CAP_DB`; a prediction one stop too bright (2x) gives log-luminance
RMSE 1 stop, relative L1 1.0 (0.5 for one stop too dark), a light power error
of +1 stop, and after exposure alignment every error returns to 0.
"""

from __future__ import annotations

import numpy as np

from ..colour import REC709_Y
from .pu21 import PSNR_PEAK, pu21_encode

REC709_LUMINANCE = np.array(REC709_Y)
"""ITU-R BT.709 luminance weights (Y of linear R, G, B)."""
PSNR_CAP_DB = 100.0
"""PSNR of identical images (MSE 0) is reported as this cap instead of infinity."""
ALIGN_RANGE = (0.2, 0.8)
"""Truth values used for exposure alignment (GaSLight's evaluation protocol)."""
PU21_WHITE_NITS = 100.0
"""Relative radiance 1.0 (photo white) is shown as 100 cd/m^2 for PU21 metrics."""
PU21_PEAK_NITS = 1000.0
"""The truth's peak is shown at 1000 cd/m^2 (an HDR display) for :func:`pu21_psnr_peak`."""


def luminance(rgb: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """``Y = w . rgb`` for an ``(..., 3)`` array (BT.709 weights by default)."""
    w = REC709_LUMINANCE if weights is None else np.asarray(weights, np.float64)
    return np.asarray(rgb, np.float64) @ w


def exposure_alignment_scale(pred: np.ndarray, truth: np.ndarray,
                             value_range: tuple[float, float] = ALIGN_RANGE,
                             weights: np.ndarray | None = None) -> float:
    """Scale ``s`` so that ``s * pred`` matches ``truth`` in exposure.

    ``s = mean(Y_truth[M]) / mean(Y_pred[M])`` over the mask ``M`` of pixels
    whose truth luminance lies in ``value_range`` (the mean-of-[0.2, 0.8]
    alignment of GaSLight, Lyu et al., ICCV 2025, and of the SI-HDR relighting
    evaluations it follows). When fewer than 16 pixels qualify, ``M`` falls
    back to every pixel with positive truth. Returns 1.0 when ``pred`` is black
    on ``M``.
    """
    yt, yp = luminance(truth, weights), luminance(pred, weights)
    lo, hi = value_range
    mask = (yt >= lo) & (yt <= hi)
    if np.count_nonzero(mask) < 16:
        mask = yt > 0
    denom = float(np.mean(yp[mask])) if mask.any() else 0.0
    if denom <= 0 or not np.isfinite(denom):
        return 1.0
    return float(np.mean(yt[mask])) / denom


def mse(pred: np.ndarray, truth: np.ndarray) -> float:
    """Mean squared error over every pixel and channel: ``mean((p - t)^2)``."""
    diff = np.asarray(pred, np.float64) - np.asarray(truth, np.float64)
    return float(np.mean(diff * diff))


def psnr_from_mse(error: float, peak: float = 1.0, cap_db: float = PSNR_CAP_DB) -> float:
    """``PSNR = 10 log10(peak^2 / MSE)`` in dB, capped at ``cap_db`` (MSE 0 -> cap)."""
    if error <= 0:
        return cap_db
    return float(min(cap_db, 10.0 * np.log10(peak * peak / error)))


def psnr(pred: np.ndarray, truth: np.ndarray, peak: float = 1.0,
         cap_db: float = PSNR_CAP_DB) -> float:
    """PSNR in dB of ``pred`` against ``truth`` for signals whose peak is ``peak``."""
    return psnr_from_mse(mse(pred, truth), peak, cap_db)


def _epsilon(truth_y: np.ndarray, relative: float) -> float:
    """A floor for logs and ratios: ``relative`` times the truth's mean luminance."""
    mean = float(np.mean(truth_y)) if truth_y.size else 0.0
    return max(relative * mean, 1e-12)


def log_luminance_rmse(pred: np.ndarray, truth: np.ndarray,
                       weights: np.ndarray | None = None, eps_relative: float = 1e-6) -> float:
    """RMSE of log2 luminance, in stops.

    ``sqrt(mean((log2(Y_p + e) - log2(Y_t + e))^2))`` with ``e`` = 1e-6 x the
    truth's mean luminance (keeps black pixels finite). The standard
    log-domain HDR error, here in base 2 so that a uniform exposure error of
    k stops reads as k (no published source needed: it is a plain RMSE).
    """
    yt, yp = luminance(truth, weights), luminance(pred, weights)
    e = _epsilon(yt, eps_relative)
    d = np.log2(np.maximum(yp, 0) + e) - np.log2(np.maximum(yt, 0) + e)
    return float(np.sqrt(np.mean(d * d)))


def relative_l1(pred: np.ndarray, truth: np.ndarray, eps_relative: float = 1e-6) -> float:
    """Mean per-sample relative absolute error ``mean(|p - t| / (|t| + e))``.

    ``e`` = 1e-6 x the truth's mean value. A prediction one stop too bright
    scores 1.0, one stop too dark 0.5. (The plain mean relative absolute
    error; scale-dependent by design, so align exposure first if needed.)
    """
    p = np.asarray(pred, np.float64)
    t = np.asarray(truth, np.float64)
    e = _epsilon(np.abs(t), eps_relative)
    return float(np.mean(np.abs(p - t) / (np.abs(t) + e)))


def angular_error_deg(pred: np.ndarray, truth: np.ndarray, min_norm: float = 1e-8) -> float:
    """Mean angle in degrees between RGB vectors of ``pred`` and ``truth``.

    ``mean(acos(p . t / (|p| |t|)))`` over pixels where both norms exceed
    ``min_norm`` (colour error independent of intensity; the angular error of
    colour-constancy work, Hordley & Finlayson 2006, used by GaSLight on
    relit renders). 0 when no pixel qualifies.
    """
    p = np.asarray(pred, np.float64).reshape(-1, 3)
    t = np.asarray(truth, np.float64).reshape(-1, 3)
    np_, nt = np.linalg.norm(p, axis=1), np.linalg.norm(t, axis=1)
    ok = (np_ > min_norm) & (nt > min_norm)
    if not ok.any():
        return 0.0
    cos = np.sum(p[ok] * t[ok], axis=1) / (np_[ok] * nt[ok])
    return float(np.degrees(np.mean(np.arccos(np.clip(cos, -1.0, 1.0)))))


def pu21_psnr(pred: np.ndarray, truth: np.ndarray, align: bool = True,
              white_nits: float = PU21_WHITE_NITS, variant: str = "banding_glare",
              weights: np.ndarray | None = None) -> float:
    """PSNR of PU21-encoded HDR images (Mantiuk & Azimi, PCS 2021), in dB.

    Mapping to absolute units: ``pred`` is first exposure-aligned to ``truth``
    (:func:`exposure_alignment_scale`) unless ``align=False``; then both are
    multiplied by ``white_nits`` (relative 1.0, the photo's white, becomes 100
    cd/m^2, an SDR display's white, so the photo's range fills the encoding's
    SDR part and highlights up to 100x brighter keep their detail until the
    10000 cd/m^2 clamp). RGB channels are PU21-encoded independently and PSNR
    uses the peak :data:`~gaslight_usd.evaluation.pu21.PSNR_PEAK` = 256 of the
    authors' ``pu21_metric``. Capped at :data:`PSNR_CAP_DB`.
    """
    scale = exposure_alignment_scale(pred, truth, weights=weights) if align else 1.0
    p = pu21_encode(np.asarray(pred, np.float64) * scale * white_nits, variant)
    t = pu21_encode(np.asarray(truth, np.float64) * white_nits, variant)
    return psnr(p, t, peak=PSNR_PEAK)


def pu21_psnr_peak(pred: np.ndarray, truth: np.ndarray, align: bool = False,
                   peak_nits: float = PU21_PEAK_NITS, variant: str = "banding_glare",
                   weights: np.ndarray | None = None) -> float:
    """PU21-PSNR with display-referred scaling: the truth's peak luminance -> ``peak_nits``.

    The second common way to give relative HDR images absolute units (HDR
    reconstruction evaluations normalise by the reference's maximum and show
    it on an HDR display, here 1000 cd/m^2): one scale, from the truth, for
    both images. Unlike :func:`pu21_psnr` (white at 100 cd/m^2) it does not
    depend on where the photo's white sits, only on the scene's own range, so
    a room whose lamp is 2000x its walls puts the walls near 0.5 cd/m^2, where
    PU21 is flatter. Which convention a quoted number uses matters: the
    bundled example's probes blurred by 5 px score 17.8-19.7 dB with white at
    100 cd/m^2 and 24.6-29.3 dB here (``gaslight2usd bench --suite fit``
    prints both). ``align``: exposure-align ``pred`` first (off by default:
    probes are compared in absolute units).
    """
    p = np.asarray(pred, np.float64)
    t = np.asarray(truth, np.float64)
    if align:
        p = p * exposure_alignment_scale(p, t, weights=weights)
    top = float(luminance(t, weights).max()) if t.size else 0.0
    if top <= 0:
        raise ValueError("pu21_psnr_peak needs a truth with some positive luminance")
    scale = peak_nits / top
    return psnr(pu21_encode(p * scale, variant), pu21_encode(t * scale, variant),
                peak=PSNR_PEAK)


def light_source_errors(pred: np.ndarray, truth: np.ndarray, stops_below_peak: float = 2.0,
                        weights: np.ndarray | None = None,
                        pixel_weights: np.ndarray | None = None) -> dict[str, float]:
    """Accuracy of the brightest region: its total power and peak radiance, in stops.

    The region ``R`` is every pixel whose truth luminance is within
    ``stops_below_peak`` of the truth's peak (``Y_t >= peak * 2^-stops``);
    both images are measured on the same ``R``:

    - ``power_err_stops = log2(sum_R w Y_p / sum_R w Y_t)`` (``w``: per-pixel
      solid angle when given, else 1; the sum is the region's radiant power
      up to a constant),
    - ``peak_err_stops = log2(max_R Y_p / max_R Y_t)``.

    Negative errors mean the prediction is too dark (a clipped lamp reads as
    many stops negative). No alignment is applied: align first if the
    prediction's scale is arbitrary. Also returns ``region_pixels`` and the
    truth's ``peak`` luminance.
    """
    yt, yp = luminance(truth, weights), luminance(pred, weights)
    w = np.ones_like(yt) if pixel_weights is None else np.broadcast_to(pixel_weights, yt.shape)
    peak = float(yt.max()) if yt.size else 0.0
    if peak <= 0:
        nan = float("nan")
        return {"power_err_stops": nan, "peak_err_stops": nan, "region_pixels": 0.0,
                "peak": peak}
    region = yt >= peak * 2.0 ** (-stops_below_peak)
    tiny = 1e-30
    power_t = float(np.sum(w[region] * yt[region]))
    power_p = float(np.sum(w[region] * np.maximum(yp[region], 0)))
    peak_p = float(np.max(yp[region]))
    return {
        "power_err_stops": float(np.log2(max(power_p, tiny) / power_t)),
        "peak_err_stops": float(np.log2(max(peak_p, tiny) / peak)),
        "region_pixels": float(np.count_nonzero(region)),
        "peak": peak,
    }


def hdr_errors(pred: np.ndarray, truth: np.ndarray, align: bool = True,
               weights: np.ndarray | None = None) -> dict[str, float]:
    """The plain HDR errors of ``pred`` after optional exposure alignment.

    Returns ``exposure_scale`` (the factor applied), ``log_lum_rmse_stops``,
    ``relative_l1``, ``pu21_psnr`` and the light-source errors (after the same
    alignment).
    """
    scale = exposure_alignment_scale(pred, truth, weights=weights) if align else 1.0
    aligned = np.asarray(pred, np.float64) * scale
    light = light_source_errors(aligned, truth, weights=weights)
    return {
        "exposure_scale": scale,
        "log_lum_rmse_stops": log_luminance_rmse(aligned, truth, weights),
        "relative_l1": relative_l1(aligned, truth),
        "pu21_psnr": pu21_psnr(aligned, truth, align=False, weights=weights),
        "light_power_err_stops": light["power_err_stops"],
        "light_peak_err_stops": light["peak_err_stops"],
    }
