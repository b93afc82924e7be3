"""What the lit surfaces say of the lights' factors: the albedos' evenness and level.

A matte point's albedo is ``pi L / E`` with ``E`` its irradiance, the lights' share of it
scaled by their factors; the right factors leave the albedos independent of how much of
each point's light is a light's (their evenness), and at a plausible level. The surface
points the photos only clipped count as bounds (a censored normal fit). Used by
:mod:`gaslight_usd.fit.power`, whose docstring gives the why.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import expit, log_ndtr

LOG2_K_RANGE = (-2.0, 16.0)
"""The factors searched (log2 over the fill). A bare bulb can be 15 stops over the
room's median, its fill a few over the white: the chain bench's ``bulb`` room needed
11-13, and a search that ran off its end at 12 left the lamp at its fill, 8 stops
short (``docs/measurements.md``, session 19)."""
ALBEDO_QUANTILE = 0.75
"""This share of the sampled albedos must stay at or under 1 for a factor to be possible
(a matte surface reflects at most what reaches it)."""
ALBEDO_PRIOR_MEDIAN = 0.3
"""What a room's surfaces reflect, before the photos say: a median albedo of 0.3
(interiors run from dark floors and wood near 0.1-0.2 to painted walls and ceilings near
0.5-0.8; 18 % is the photographer's average scene). It decides only where the albedos'
uniformity cannot: a bare bulb that lights every surface alike leaves the uniformity
flat over several stops, and its factor wandered with each draw of surface points
(``docs/measurements.md``, session 21)."""
ALBEDO_PRIOR_STOPS = 1.0
"""...within this many stops either way (1 sigma)."""
LEVEL_MEASURED_SHARE = 0.5
"""The albedos' level is weighed in only where the photos measured at least this share of
the surface points (the rest are bounds: clipped in every view). Around a shaded lamp
the photos clip most of them; the level a censored fit puts on the rest is then an
extrapolation, and on a held-out room it pulled an accurate uniformity stops over
(``docs/measurements.md``, session 21)."""
ALIKE_TOLERANCE = 0.05
"""Lights weighed together get one factor (over their own fills) where that scores within
this much (negative log-likelihood per point) of the best separate factors. Where the
surfaces see several lights alike they pin the sum of their light, not its split, and
the score is flat along the split: on the chain bench's ``panels`` room (seed 1) the
best split, (+3.5, -2.0) stops for two ceiling panels that each needed about +4, beat
one factor for both (+2.4) by 0.026; the coordinate search had given the first panel
all of it (``docs/measurements.md``, session 19). A tolerance, not calibrated further."""
MIN_SIGMA = 0.02
"""Least spread of the log2-albedos a fit may claim (stops)."""
FALSE_BOUND_SHARE = 0.05
"""Prior share of the clipped surface points whose bound is false (the pixel clipped
for a light in front of the surface): :func:`censored_fit`."""
GENUINE_LOGIT = math.log1p(-FALSE_BOUND_SHARE) - math.log(FALSE_BOUND_SHARE)
"""The prior log-odds that a bound is genuine."""


def _normal_logsf(a: np.ndarray) -> np.ndarray:
    """log P(Z > a) for a standard normal (``scipy.stats`` costs a second to import)."""
    return log_ndtr(-a)


def _normal_logpdf(a: np.ndarray) -> np.ndarray:
    return -0.5 * a * a - 0.5 * math.log(2.0 * math.pi)


def censored_fit(y: np.ndarray, c: np.ndarray, iterations: int = 25
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A normal fitted to each row of ``(G, P)`` samples, some of them only known to be
    at least ``c`` (right-censored; ``y`` NaN there, ``c`` NaN where ``y`` is known).

    Expectation-maximisation with the truncated normal's moments. A bound may be false
    (a surface seen through a clipped light in front of it): each is genuine with prior
    ``1 -`` :data:`FALSE_BOUND_SHARE`, else it says nothing, so no one bound can outweigh
    the measured points. Returns ``(mu, sigma, nll)`` with ``nll`` the mean negative
    log-likelihood over the points."""
    known = np.isfinite(y)
    cens = np.isfinite(c)
    yk = np.where(known, y, 0.0)
    n_known = np.maximum(known.sum(1), 1)
    mu = yk.sum(1) / n_known
    sigma = np.sqrt(np.maximum((((yk - mu[:, None]) ** 2) * known).sum(1) / n_known,
                               MIN_SIGMA ** 2))
    # the measured points' sums do not change between iterations; the bounds' terms are
    # drawn on the points bound in some row only (most points are measured: the
    # weighing's grid of factors x points ran the normal's tail on every point, 25 times)
    count, sum_y, sum_y2 = known.sum(1), yk.sum(1), ((yk ** 2) * known).sum(1)
    some = cens.any(0)
    cens_s = cens[:, some]
    cc = np.where(cens_s, c[:, some], 0.0)
    for _ in range(iterations if cens.any() else 1):
        a = (cc - mu[:, None]) / sigma[:, None]
        log_sf = _normal_logsf(a)
        genuine = np.where(cens_s, expit(log_sf + GENUINE_LOGIT), 0.0)
        lam = np.exp(_normal_logpdf(a) - log_sf)
        e1 = mu[:, None] + sigma[:, None] * lam
        e2 = sigma[:, None] ** 2 * np.maximum(1.0 + a * lam - lam ** 2, 0.0) + e1 ** 2
        n = count + genuine.sum(1)
        mu = (sum_y + (genuine * e1).sum(1)) / n
        second = sum_y2 + (genuine * e2).sum(1)
        sigma = np.sqrt(np.maximum(second / n - mu ** 2, MIN_SIGMA ** 2))
    z = (yk - mu[:, None]) / sigma[:, None]
    nll = (np.where(known, np.log(sigma[:, None]) + 0.5 * z ** 2, 0.0).sum(1)
           - np.where(cens_s, np.logaddexp(
               math.log1p(-FALSE_BOUND_SHARE) + _normal_logsf((cc - mu[:, None]) / sigma[:, None]),
               math.log(FALSE_BOUND_SHARE)), 0.0).sum(1))
    return mu, sigma, nll / np.maximum((known | cens).sum(1), 1)


def albedo_scores(totals: np.ndarray, radiance: np.ndarray, bound: np.ndarray,
                  trim: float = 0.1) -> np.ndarray:
    """How unlikely the log-albedos are, per row of irradiance ``totals`` ``(G, P)`` (one
    row per trial factor): the negative log-likelihood per point of a normal fitted to
    them, points the photos only clipped (``bound``) counting as at least their bound
    (:func:`censored_fit`), the ``trim`` share of the measured points farthest from
    their median left out (bounds are not trimmed: a false one is weighed down by
    :data:`FALSE_BOUND_SHARE` instead).
    With no clipped point it is the log of the spread (least variance, as before).
    Infinite where over a quarter of the albedos would exceed 1 (:data:`ALBEDO_QUANTILE`).

    Leaving clipped points out would select on brightness: near a clipped lamp, the
    surfaces it lights brightest clip, the darker ones stay, and the factor that makes
    them look like the rest falls short (1.2 stops on a ``balanced`` fit of ``room:11``,
    ``docs/measurements.md``)."""
    _, nll, over = albedo_fit(totals, radiance, bound, trim)
    return np.where(over, np.inf, nll)


def albedo_fit(totals: np.ndarray, radiance: np.ndarray, bound: np.ndarray,
               trim: float = 0.1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row of irradiance ``totals`` ``(G, P)``: the log2-albedos' fitted mean (their
    level), the negative log-likelihood per point (:func:`albedo_scores`) and whether
    over a quarter of the albedos exceed 1."""
    totals = np.maximum(np.atleast_2d(totals), 1e-12)
    known = np.isfinite(radiance)
    y = np.where(known, np.log2(math.pi * np.where(known, radiance, 1.0) / totals), np.nan)
    cens = np.isfinite(bound)
    c = np.where(cens, np.log2(math.pi * np.where(cens, bound, 1.0) / totals), np.nan)
    over = ((y > 0) | (c > 0)).sum(1) > (1.0 - ALBEDO_QUANTILE) * (known | cens).sum()
    ref = np.nanmedian(y, axis=1, keepdims=True)
    dev = np.abs(y - ref)
    keep = cens | (dev <= np.nanquantile(dev, 1.0 - trim, axis=1, keepdims=True))
    y, c = np.where(keep, y, np.nan), np.where(keep, c, np.nan)
    mu, _, nll = censored_fit(y, c)
    return mu, nll, over


def factor_grid(step: float) -> np.ndarray:
    """The ``log2 k`` searched: :data:`LOG2_K_RANGE`, ``step`` apart."""
    return np.arange(LOG2_K_RANGE[0], LOG2_K_RANGE[1] + 1e-9, step)


def totals_over(irr: np.ndarray, log2_k: np.ndarray, j: int, grid: np.ndarray) -> np.ndarray:
    """``(G, P)`` irradiance at each point with light ``j`` at each factor of ``grid``
    (log2) and the other lights at ``log2_k``."""
    others = irr[:, 0] + irr[:, 1:] @ (2.0 ** log2_k) - irr[:, 1 + j] * 2.0 ** log2_k[j]
    return others[None] + (2.0 ** grid)[:, None] * irr[None, :, 1 + j]


def solve_factors(radiance: np.ndarray, bound: np.ndarray, irr: np.ndarray,
                  grid_step: float = 0.125) -> np.ndarray:
    """``log2 k`` per light minimising :func:`albedo_scores` (coordinate grid search);
    for several lights, one factor for all of them where it scores within
    :data:`ALIKE_TOLERANCE` of that."""
    lights = irr.shape[1] - 1
    k = np.zeros(lights)
    grid = factor_grid(grid_step)
    for _ in range(3 if lights > 1 else 1):
        for j in range(lights):
            scores = albedo_scores(totals_over(irr, k, j, grid), radiance, bound)
            if np.isfinite(scores).any():
                k[j] = grid[int(np.argmin(scores))]
    if lights > 1:
        best = albedo_scores((irr[:, 0] + irr[:, 1:] @ (2.0 ** k))[None], radiance, bound)[0]
        shared = albedo_scores(irr[:, 0][None] + (2.0 ** grid)[:, None]
                               * irr[:, 1:].sum(1)[None], radiance, bound)
        if np.isfinite(shared).any() and shared.min() <= best + ALIKE_TOLERANCE:
            k[:] = grid[int(np.argmin(shared))]
    return k


def feasible(log2_k: np.ndarray, radiance: np.ndarray, bound: np.ndarray, irr: np.ndarray
             ) -> bool:
    """Whether factors ``2**log2_k`` keep the albedos under the cap (:func:`albedo_scores`)."""
    totals = irr[:, 0] + irr[:, 1:] @ (2.0 ** log2_k)
    return bool(np.isfinite(albedo_scores(totals[None], radiance, bound))[0])


def evenness_floor(log2_k: np.ndarray, radiance: np.ndarray, bound: np.ndarray,
                   irr: np.ndarray, grid_step: float = 0.125) -> np.ndarray:
    """Per light, where the uniformity's best factor ``log2_k`` is the search's top: the
    least factor that scores within :data:`ALIKE_TOLERANCE` of it, the others held at
    theirs (NaN for the other lights).

    A uniformity that keeps improving to the end of the search says "a light at least
    this bright", not a centre: there the rest of the room's gathered irradiance adds
    spread instead of explaining it, and the brighter the light the more it drowns that
    spread. Taken as a centre at the search's top it pulled the level's posterior stops
    over (``bulb`` seed 0 on the chain bench; ``docs/measurements.md``, session 22)."""
    grid = factor_grid(grid_step)
    out = np.full(len(log2_k), np.nan)
    for j in np.flatnonzero(log2_k >= LOG2_K_RANGE[1] - 1e-9):
        scores = albedo_scores(totals_over(irr, log2_k, j, grid), radiance, bound)
        finite = np.isfinite(scores)
        if finite.any():
            out[j] = grid[int(np.argmax(scores <= scores[finite].min() + ALIKE_TOLERANCE))]
    return out


def with_albedo_prior(log2_k: np.ndarray, sigma: np.ndarray, radiance: np.ndarray,
                      bound: np.ndarray, irr: np.ndarray, grid_step: float = 0.125,
                      at_least: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The factors (log2) and their spread (stops) once the albedos' *level* is weighed
    in beside their uniformity (module docstring): per light, the posterior over a grid
    of ``log2 k`` of a normal around the uniformity's estimate ``log2_k`` (``sigma``)
    and the prior that the surfaces' median albedo is near
    :data:`ALBEDO_PRIOR_MEDIAN` (:data:`ALBEDO_PRIOR_STOPS`); factors that push over a
    quarter of the albedos over 1 are impossible. Lights the uniformity weighed as one
    (:data:`ALIKE_TOLERANCE`) stay one. Coordinate-wise for several lights. Where the
    photos only bounded most of the points (:data:`LEVEL_MEASURED_SHARE`) the level is
    not measured and the uniformity's estimate is returned as it is, or its floor where
    it ran off.

    ``at_least``: per light, where the uniformity ran off the search's top
    (:func:`evenness_floor`; NaN elsewhere): there it only says "at least this", and
    only factors under it are penalised (with ``sigma``). With no level to say how much
    more, the floor itself is the factor, a lower bound: the search's top is no
    estimate, and left there the light kept its fill, a lower bound stops under the
    floor (a shaded lamp whose surroundings the photos clipped, 6.7 stops short:
    ``docs/measurements.md``, session 43)."""
    lights = len(log2_k)
    floors = np.full(lights, np.nan) if at_least is None else np.asarray(at_least, float)
    grid = factor_grid(grid_step)
    k, spread = log2_k.astype(np.float64).copy(), sigma.astype(np.float64).copy()
    measured = int(np.isfinite(radiance).sum())
    if measured < LEVEL_MEASURED_SHARE * (measured + int(np.isfinite(bound).sum())):
        ran_off = np.isfinite(floors)
        k[ran_off] = floors[ran_off]
        return k, spread
    groups = ([np.arange(lights)] if lights > 1 and np.ptp(log2_k) == 0
              else [np.array([j]) for j in range(lights)])
    level = math.log2(ALBEDO_PRIOR_MEDIAN)
    for _ in range(3 if len(groups) > 1 else 1):
        for g in groups:
            trial = np.repeat(k[None], len(grid), 0)
            trial[:, g] = grid[:, None]
            mu, _, over = albedo_fit(irr[:, 0][None] + (2.0 ** trial) @ irr[:, 1:].T,
                                     radiance, bound)
            centre, width = float(log2_k[g[0]]), float(sigma[g].max())
            off = (grid - centre if not np.isfinite(floors[g]).any()
                   else np.minimum(grid - float(np.nanmax(floors[g])), 0.0))
            log_post = (-0.5 * (off / width) ** 2
                        - 0.5 * ((mu - level) / ALBEDO_PRIOR_STOPS) ** 2)
            log_post[over] = -np.inf
            if not np.isfinite(log_post).any():
                continue
            weight = np.exp(log_post - log_post.max())
            mean = float(np.sum(weight * grid) / weight.sum())
            k[g] = grid[int(np.argmax(log_post))]
            spread[g] = math.sqrt(max(float(np.sum(weight * (grid - mean) ** 2)
                                            / weight.sum()), grid_step ** 2 / 12.0))
    return k, spread
