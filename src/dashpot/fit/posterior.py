"""Uncertainty from the posterior: quantiles of β from emcee's ensemble sampler (flat priors).

References
----------
Numbered as in :mod:`dashpot.fit`.

.. [6] D. Foreman-Mackey et al., "emcee: The MCMC Hammer", PASP 125, 306 (2013).
.. [9] C. J. F. ter Braak and J. A. Vrugt, "Differential Evolution Markov Chain with snooker
   updater and fewer chains", Statistics and Computing 18, 435 (2008).
"""

from __future__ import annotations

import math

import numpy as np

from .covariance import _central_quantiles, _gaussian_draws
from .settings import PARAMETERS, REJECTED


def _posterior_beta(residual_rows, result, g, seed, chisqr_scale=1.0, walkers=32,
                    first_steps=1000, max_steps=12000, lengths=50):
    """Posterior quantiles of β by emcee's ensemble sampler [6]_.

    Flat priors on the fitted parameters, likelihood exp(−χ²/(2·`chisqr_scale`)). Every
    half-ensemble update evaluates its walkers in one batched call of `residual_rows`
    (emcee's ``vectorize``), so long chains are affordable. Differential-evolution moves
    (80 %, with 20 % snooker updates) [9]_: on the curved, strongly correlated posterior of
    (ζ, v*) their autocorrelation time is about half that of the default stretch move. The
    chain is doubled in length from `first_steps` until it is `lengths` integrated
    autocorrelation times long (emcee's guidance [6]_) or `max_steps` is reached; the first
    5 autocorrelation times are discarded as burn-in. The walkers start from seeded draws of
    the fit's Gaussian approximation; the sampler is seeded by `seed`.

    Returns
    -------
    dict
        low68, high68, low95, high95 of β (1/s), the number of samples, the autocorrelation
        time in steps and whether the chain reached `lengths` of them.
    """
    import emcee

    varied = list(result.var_names)
    # PARAMETERS, then any further parameters of the fit (the flight's) in their order.
    names = PARAMETERS + tuple(name for name in result.params if name not in PARAMETERS)
    columns = [names.index(name) for name in varied]
    best = np.array([result.params[name].value for name in names], float)

    def log_probability(points):
        values = np.repeat(best[None], points.shape[0], axis=0)
        values[:, columns] = points
        residual = residual_rows(values)
        chisqr = np.einsum("ij,ij->i", residual, residual)
        # A step outside the physical range comes back as REJECTED: zero prior there.
        return np.where(np.all(residual != REJECTED, axis=1), -0.5 * chisqr / chisqr_scale,
                        -np.inf)

    rng = np.random.default_rng(seed)
    centre = best[columns]
    spread = np.abs(centre) * 1e-6 + 1e-12
    start = centre + spread * rng.standard_normal((walkers, centre.size))
    if result.covar is not None and np.all(np.isfinite(result.covar)):
        draws = _gaussian_draws(centre, result.covar, walkers, rng)
        # Walkers drawn outside the physical range start next to the best fit instead.
        start = np.where(np.isfinite(log_probability(draws))[:, None], draws, start)
    moves = [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]
    sampler = emcee.EnsembleSampler(walkers, centre.size, log_probability, moves=moves,
                                    vectorize=True)
    sampler.random_state = np.random.RandomState(seed).get_state()
    state, steps, autocorrelation = start, 0, math.nan
    while steps < max_steps:
        more = min(max(first_steps, steps), max_steps - steps)
        state = sampler.run_mcmc(state, more, progress=False)
        steps += more
        autocorrelation = float(np.max(sampler.get_autocorr_time(tol=0)))
        if steps >= lengths * autocorrelation:
            break
    burn = min(int(5 * autocorrelation) if np.isfinite(autocorrelation) else steps // 2,
               steps // 2)
    chain = sampler.get_chain(discard=burn, flat=True)
    zeta = chain[:, varied.index("zeta")] if "zeta" in varied else best[0]
    v_star = chain[:, varied.index("v_star")] if "v_star" in varied else best[1]
    with np.errstate(divide="ignore"):
        beta = np.where(v_star > 0, zeta * g / v_star, np.inf)
    low68, high68, low95, high95 = _central_quantiles(beta)
    return {"low68": float(low68), "high68": float(high68), "low95": float(low95),
            "high95": float(high95), "samples": int(beta.size),
            "autocorrelation_steps": autocorrelation,
            "converged": bool(steps >= lengths * autocorrelation)}
