"""Uncertainty from the fit's covariance: Gaussian intervals of the fitted parameters, and
intervals of derived quantities from seeded draws of that Gaussian.

References
----------
Numbered as in :mod:`dashpot.fit`.

.. [4] P. R. Bevington and D. K. Robinson, *Data Reduction and Error Analysis for the Physical
   Sciences*, 3rd ed. (2003), sec. 3.2 (propagation of errors).
"""

from __future__ import annotations

import math

import numpy as np

from .results import Estimate
from .settings import INTERVAL_SEED, QUANTILES, Z68, Z95


def _draws(values, varied, cov, count):
    """Seeded draws of every parameter from the fit's Gaussian approximation (fixed ones
    constant); all equal to the best fit where the covariance is not available."""
    out = {name: np.full(count, float(value)) for name, value in values.items()}
    if varied and np.all(np.isfinite(cov)):
        mean = np.array([values[name] for name in varied])
        sample = _gaussian_draws(mean, cov, count, np.random.default_rng(INTERVAL_SEED))
        for i, name in enumerate(varied):
            out[name] = sample[:, i]
    return out


def _gaussian_draws(mean, cov, count, rng):
    """`count` draws of N(mean, cov), shape (count, mean.size), as numpy's
    multivariate_normal(method="eigh") without its checks (a third of the cost); a singular
    covariance (a direction the data fix exactly) is allowed."""
    eigenvalues, vectors = np.linalg.eigh(cov)
    factor = vectors * np.sqrt(np.abs(eigenvalues))
    return rng.standard_normal((count, mean.size)) @ factor.T + mean


def _sampled(value, stderr, draws, unit, status, note=""):
    """Estimate with 68.27 % and 95.45 % intervals from the central quantiles of its draws."""
    if status == "fixed":
        return Estimate(value, 0.0, value, value, value, value, unit, status, note)
    if not np.isfinite(stderr):
        return Estimate(value, math.inf, 0.0, math.inf, 0.0, math.inf, unit, status, note)
    draws = np.where(np.isnan(draws), np.inf, draws)
    low68, high68, low95, high95 = _central_quantiles(draws)
    return Estimate(value, stderr, float(low68), float(high68), float(low95), float(high95),
                    unit, status, note)


def _central_quantiles(draws):
    """QUANTILES of `draws`: the smallest draw whose empirical CDF reaches each level
    (numpy's method="inverted_cdf"), by one partial sort."""
    ranks = np.clip(np.ceil(draws.size * np.asarray(QUANTILES)).astype(int) - 1, 0,
                    draws.size - 1)
    return np.partition(draws, ranks)[ranks]


def _linear_estimate(value, sd, unit, status, note=""):
    return Estimate(value, sd, value - Z68 * sd, value + Z68 * sd, value - Z95 * sd,
                    value + Z95 * sd, unit, status, note)


def _interval_row(estimate):
    return {"low68": estimate.low68, "high68": estimate.high68, "low95": estimate.low95,
            "high95": estimate.high95}
