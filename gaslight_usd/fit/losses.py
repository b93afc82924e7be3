"""Fitting losses and held-out errors.

Training loss (GaSLight, following 3DGS): L1 on the unclamped linear HDR image
plus ``ssim_weight`` x (1 - SSIM) on both images clamped to [0, 1]; an optional
``log_weight`` x L1 of log(1 + x) adds a term that sees the dark and the very
bright regions alike.

Clipped pixels are bounds, not targets: where the photo clipped (a view's clip
floor, :data:`gaslight_usd.poses.views.CLIP_FLOOR_CHANNEL`, is > 0) the photo only says
the luminance is at least the floor; the uplift's fill there is a guess. So in
those pixels the loss is ``relu(floor - Y(pred))`` (any radiance above what the
photo recorded is free) plus ``fill_weight`` x a pull in log radiance towards the
predictor's fill (:func:`fill_pull`). A view whose exposure saw the light
unclipped then pins its power, however many other views' fills guessed it lower:
a linear L1 pull from each of 15 clipped views (15 x 0.1) outweighed the one
measurement (1), and the fit settled on the guess (measured by
``gaslight2usd bench --suite chain --method "recursive + dark frames"``).

Pixels the photo crushed to black are bounds the other way: where a view's dark
ceiling (:data:`gaslight_usd.poses.views.DARK_CEILING_CHANNEL`) is > 0 the photo only
says the luminance is at most the ceiling, and the loss is ``relu(Y(pred) - ceiling)``.
A frame exposed for a light is black everywhere else; fitted as measured black, it
contradicts every other photo of the walls it saw. The SSIM term sees such a pixel as
the prediction itself, held under the ceiling (no gradient below it).

SSIM is Wang et al. 2004 with the usual 11x11 Gaussian window (sigma 1.5),
C1 = 0.01^2, C2 = 0.03^2.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

SSIM_WINDOW = 11
SSIM_SIGMA = 1.5
SSIM_C1 = 0.01 ** 2
SSIM_C2 = 0.03 ** 2


def _gauss_kernel(device) -> torch.Tensor:
    x = torch.arange(SSIM_WINDOW, dtype=torch.float32, device=device) - SSIM_WINDOW // 2
    g = torch.exp(-x * x / (2 * SSIM_SIGMA ** 2))
    return g / g.sum()


def _blur(x: torch.Tensor, g: torch.Tensor) -> torch.Tensor:
    """Separable Gaussian blur of each channel of (1, C, H, W), zero padding (as the
    3DGS SSIM). One depthwise convolution per axis over all channels: the SSIM's five
    blurred images of three channels each, as single-channel convolutions, took 2.3x as
    long with their gradients at the fit's image sizes."""
    pad, c = SSIM_WINDOW // 2, x.shape[1]
    x = F.conv2d(x, g.view(1, 1, 1, -1).expand(c, 1, 1, -1), padding=(0, pad), groups=c)
    return F.conv2d(x, g.view(1, 1, -1, 1).expand(c, 1, -1, 1), padding=(pad, 0), groups=c)


def ssim(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Mean SSIM of two (H, W, 3) images (values expected in [0, 1])."""
    g = _gauss_kernel(a.device)
    x = a.permute(2, 0, 1)[None]
    y = b.permute(2, 0, 1)[None]
    blurred = _blur(torch.cat([x, y, x * x, y * y, x * y], dim=1), g)[0]
    mx, my, bxx, byy, bxy = blurred.split(x.shape[1])
    sxx = bxx - mx * mx
    syy = byy - my * my
    sxy = bxy - mx * my
    num = (2 * mx * my + SSIM_C1) * (2 * sxy + SSIM_C2)
    den = (mx * mx + my * my + SSIM_C1) * (sxx + syy + SSIM_C2)
    return (num / den).mean()


def bounded_l1(pred: torch.Tensor, target: torch.Tensor, floor: torch.Tensor | None,
               y_weights: torch.Tensor | None = None, fill_weight: float = 0.1,
               ceiling: torch.Tensor | None = None) -> torch.Tensor:
    """Mean L1 over ``(H, W, 3)`` with the clip floor's and the dark ceiling's pixels as
    bounds (module docstring).

    ``floor``: ``(H, W)`` lower bounds on the luminance, 0 where measured (None: all
    measured); ``ceiling``: ``(H, W)`` upper bounds, 0 where measured (None: none);
    ``y_weights``: the working space's luminance weights ``(3,)``.
    """
    err = (pred - target).abs()
    if floor is None and ceiling is None:
        return err.mean()
    if y_weights is None:
        raise ValueError("a clip floor or dark ceiling needs the working space's "
                         "luminance weights")
    lum = pred @ y_weights
    if ceiling is not None:
        over = torch.relu(lum - ceiling)[..., None]
        err = torch.where((ceiling > 0)[..., None], over.expand_as(err), err)
    if floor is not None:
        short = torch.relu(floor - lum)[..., None]
        err = torch.where((floor > 0)[..., None], fill_weight * fill_pull(pred, target) + short,
                          err)
    return err.mean()


def under_ceiling(pred: torch.Tensor, target: torch.Tensor, ceiling: torch.Tensor | None,
                  y_weights: torch.Tensor | None) -> torch.Tensor:
    """``target`` with each dark-ceiling pixel replaced by the prediction held under the
    ceiling (scaled down to it where above; detached): what the SSIM term compares
    against there, so that it asks no more than the bound does."""
    if ceiling is None or y_weights is None:
        return target
    held = pred.detach()
    lum = (held @ y_weights).clamp_min(1e-12)
    held = held * torch.clamp(ceiling / lum, max=1.0)[..., None]
    return torch.where((ceiling > 0)[..., None], held, target)


def fill_pull(pred: torch.Tensor, fill: torch.Tensor) -> torch.Tensor:
    """``|log(1 + pred) - log(1 + fill)|``: a pull towards the fill in log radiance.

    Its slope, ``1 / (1 + pred)``, is below a measurement's (1) wherever the light is
    brighter than white, so however many clipped views guessed low, one view that
    measured the light is not held back at the guess (with an L1 pull, 15 guesses at
    weight 0.1 out-pulled one measurement and the fit stayed at the guess).
    """
    return (torch.log1p(pred.clamp_min(0)) - torch.log1p(fill.clamp_min(0))).abs()


def fit_loss(pred: torch.Tensor, target: torch.Tensor, ssim_weight: float = 0.2,
             log_weight: float = 0.0, floor: torch.Tensor | None = None,
             y_weights: torch.Tensor | None = None, fill_weight: float = 0.1,
             ceiling: torch.Tensor | None = None) -> torch.Tensor:
    """L1(HDR, clipped and crushed pixels as bounds) + ssim_weight (1 - SSIM(clamped))
    [+ log_weight L1(log1p)]."""
    loss = bounded_l1(pred, target, floor, y_weights, fill_weight, ceiling)
    target = under_ceiling(pred, target, ceiling, y_weights)
    if ssim_weight:
        loss = loss + ssim_weight * (1.0 - ssim(pred.clamp(0, 1), target.clamp(0, 1)))
    if log_weight:
        loss = loss + log_weight * (torch.log1p(pred.clamp_min(0)) -
                                    torch.log1p(target)).abs().mean()
    return loss


def elongation_penalty(log_scales: torch.Tensor, limit: float) -> torch.Tensor:
    """Mean excess of ``log(largest / middle scale)`` over ``log(limit)``.

    Few photos leave room for needles: a splat stretched along the rays of the
    views that see it looks small in each of them and smears across every new
    view (the probes' panoramas). Flat discs (one small axis) are not penalised.
    """
    if not len(log_scales):
        return log_scales.sum()
    top2 = torch.topk(log_scales, 2, dim=1).values
    return torch.relu(top2[:, 0] - top2[:, 1] - float(np.log(limit))).mean()


def held_out_errors(pred: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """HDR errors of a rendered view against its photo's HDR view (no exposure alignment).

    ``log_lum_rmse_stops`` and ``pu21_psnr`` from :mod:`gaslight_usd.evaluation`.
    """
    from ..evaluation.metrics import log_luminance_rmse, pu21_psnr

    return {"log_lum_rmse_stops": log_luminance_rmse(pred, truth),
            "pu21_psnr": pu21_psnr(pred, truth, align=False)}
