"""The intervals of β a fit reports beyond its covariance's, one registered method each.

The covariance's Gaussian intervals are always computed (they fill the fit's estimates,
:mod:`dashpot.fit.covariance`). A further method is a function of :class:`IntervalInputs`
returning β's 68.27 % and 95.45 % bounds (1/s) as ``low68``, ``high68``, ``low95`` and
``high95`` (plus what else it reports); adding one is a module of its own and an entry in
:data:`INTERVAL_METHODS` and in ``settings.UNCERTAINTY_METHODS``.

References
----------
Numbered as in :mod:`dashpot.fit`.

.. [5] W. H. Press et al., *Numerical Recipes*, 3rd ed., Cambridge (2007), sec. 15.6
   (confidence regions from Δχ² = 1 and 4 for one parameter).
.. [6] D. Foreman-Mackey et al., "emcee: The MCMC Hammer", PASP 125, 306 (2013).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .accuracy import _trains_solver
from .posterior import _posterior_beta
from .profile_likelihood import _profile_beta
from .residuals import _residual_rows
from .trains import _TrainPredictor


@dataclass(frozen=True)
class IntervalInputs:
    """What an interval method may use of a finished fit.

    Attributes
    ----------
    model : str
        The contact model fitted.
    data : FitData
        The fitted impacts.
    result : lmfit.minimizer.MinimizerResult
        The best fit (its ``params`` in the fitted coordinates ζ, v*, v0, t0 and flight).
    residual : callable
        lmfit's residual function of one Parameters set at the fit's accuracy level.
    priors : list of (name, centre, sd)
        Gaussian priors the residual includes.
    start_ratios : ndarray
        The train predictor's start values (of the bounce map's speed ratios).
    seed : int
        Seed of any random draws.
    chisqr_scale : float
        Divisor of χ² where it measures likelihood (1, or χ²/ν under a misfit).
    notes : list of str
        The fit's notes; a method appends what a user must know of its intervals.
    flight_effects : tuple of FlightEffect
        The flight effects the fit carries (its flight columns are their parameters).
    """

    model: str
    data: object
    result: object
    residual: Callable
    priors: list
    start_ratios: np.ndarray
    seed: int
    chisqr_scale: float
    notes: list
    flight_effects: tuple = ()


def profile_interval(inputs: IntervalInputs) -> dict:
    """β's profile-likelihood interval: χ² minimised over the others at fixed β, bounds where
    it rises by 1 and 4 [5]_ (see :func:`dashpot.fit.profile_likelihood._profile_beta`)."""
    return _profile_beta(inputs.residual, inputs.result, inputs.data.g, inputs.chisqr_scale)


def posterior_interval(inputs: IntervalInputs) -> dict:
    """β's central posterior interval from emcee [6]_ with flat priors (the scene's Gaussian
    priors kept), sampled on the fast level's trains whatever the fit's level (see
    :func:`dashpot.fit.posterior._posterior_beta`)."""
    data = inputs.data
    sampled = _TrainPredictor(inputs.model, data.g, data.count,
                              _trains_solver("fast", inputs.model)[0], inputs.flight_effects)
    sampled.start = inputs.start_ratios
    row = _posterior_beta(functools.partial(_residual_rows, data=data, predictor=sampled,
                                            priors=inputs.priors),
                          inputs.result, data.g, inputs.seed, inputs.chisqr_scale)
    if not row["converged"]:
        inputs.notes.append("posterior chain shorter than 50 autocorrelation times: its "
                            "intervals are rough")
    return row


INTERVAL_METHODS: dict[str, Callable[[IntervalInputs], dict]] = {
    "profile": profile_interval,
    "posterior": posterior_interval,
}
"""The registered methods beyond the covariance, by the name the options use."""


def beta_intervals(methods, inputs: IntervalInputs, covariance_row: dict) -> dict:
    """β's intervals by the covariance (given) and each registered method in `methods`, each
    with the CPU time (s) it took; names not registered (the covariance) are skipped."""
    intervals = {"covariance": covariance_row}
    for method in methods:
        if method in INTERVAL_METHODS:
            started = time.process_time()
            intervals[method] = INTERVAL_METHODS[method](inputs)
            intervals[method]["cpu_seconds"] = time.process_time() - started
    return intervals
