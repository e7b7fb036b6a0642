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


def _misfit_bound(dof):
    """χ² above which a fit with known timing errors misses its data: 3σ beyond the mean of
    the χ² distribution with `dof` (at least 1) degrees of freedom."""
    dof = max(int(dof), 1)
    return dof + 3.0 * math.sqrt(2.0 * dof)


def _scaled_covariance(result, sigma_known, notes, misfit_meaning):
    """The fit's covariance in its varied parameters, and the divisor of χ² where it measures
    likelihood.

    Where the Jacobian is singular the covariance is infinite (errors reported as such). Where
    the timing errors are known but χ² is beyond :func:`_misfit_bound`, the model misses the
    data by more than their uncertainties: the covariance is scaled by χ²/ν (the Birge ratio
    squared) so that the errors at least reflect the actual scatter [4]_. Where the errors are
    unknown, lmfit has scaled it already and χ²/ν is the divisor. A note says what was done;
    `misfit_meaning` words what a misfit means for this fit.

    Returns
    -------
    cov : ndarray, shape (len(result.var_names),) * 2
    chisqr_scale : float
    """
    varied = result.var_names
    cov = result.covar
    if cov is None:
        cov = np.full((len(varied), len(varied)), np.inf)
        notes.append("covariance not available (singular Jacobian): the data do not determine "
                     "every parameter; errors reported as infinite")
    dof = max(int(result.nfree), 1)
    chisqr_scale = 1.0 if sigma_known else float(result.redchi)
    if sigma_known and result.chisqr > _misfit_bound(dof):
        cov = cov * result.redchi
        chisqr_scale = float(result.redchi)
        notes.append(f"reduced chi-square {result.redchi:.3g} for {dof} degrees of freedom: "
                     f"{misfit_meaning}; errors scaled by sqrt(redchi) = "
                     f"{math.sqrt(result.redchi):.3g}")
    return cov, chisqr_scale


def _propagated_sd(cov, varied, gradient):
    """1σ of a quantity by linear propagation [4]_: √(gᵀ C g) over the varied parameters, with
    `gradient` {parameter: ∂q/∂p} (parameters not varied add nothing); inf where the
    covariance of the parameters it depends on is not finite."""
    vector = np.array([gradient.get(name, 0.0) for name in varied], float)
    if not vector.any():
        return 0.0
    used = vector != 0
    block = cov[np.ix_(used, used)]
    if not np.all(np.isfinite(block)):
        return math.inf
    variance = vector[used] @ block @ vector[used]
    return float(math.sqrt(variance)) if np.isfinite(variance) and variance >= 0 else math.inf
