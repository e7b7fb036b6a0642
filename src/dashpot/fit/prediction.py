"""Out-of-sample check of a noise-model fit: fit the start of a train, predict the rest.

A law is fitted under the noise model (:func:`dashpot.fit.noise_fit.fit_noise_model`) to the
first impacts of a train only (by default the first two thirds). The held-out intervals are then
predicted by simulation: many continuations of the train (:meth:`TrainModel.simulate`, all in
one batch) start at the last fitted impact, from the Kalman filter's estimate of its impact
speed E[u_N | y_0 … y_N], with the fitted bounce-to-bounce scatter σ_ε and timing noise
√(σ_i² + σ_j²) on every simulated time (the last fitted impact's included, since each held-out
interval is measured from it or a later impact). The 95 % prediction band of each held-out
interval is the central 95 % of the simulated ones; the check reports the fraction of the
measured intervals inside their band.

What the band includes: the process noise of every future bounce, the timing noise of both ends
of each interval and, by default, the uncertainty of every fitted parameter: the law's, v0 and
the noise parameters σ_ε and σ_j (each continuation draws them from the Gaussian of the fit's
Hessian in their reported errors, correlations included, and refilters the fitted part with
them, so the start speed moves with its parameters and each continuation scatters with its own
σ_ε and σ_j). A predicted interval is a mixture over the noise parameters, with heavier tails
than at one σ_ε (σ_ε is known to 13-26 % from the first 35 impacts of the two real recordings
of the tests, which widens their bands by 5-20 %). Not included: the filter's own
variance of u_N given the parameters (the simulation starts from its mean), whose relative 1σ
is below both one bounce's σ_ε and the last interval's √2·σ_t/T, so that it adds at most about
one bounce's scatter to the first held-out interval and a shrinking share to the later ones.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..scene import Scene
from .noise_fit import fit_noise_model
from .noise_likelihood import NoiseProblem

__all__ = ["PredictionCheck", "prediction_band"]


@dataclass(frozen=True)
class PredictionCheck:
    """Held-out intervals of a train against the prediction band of a fit to its start.

    Attributes
    ----------
    fit : NoiseFitResult
        The law fitted to the first impacts.
    fitted_impacts : int
        Number of detected impacts fitted.
    observed : ndarray
        Held-out intervals in s (between consecutive detected impacts, from the last fitted one).
    lower, upper : ndarray
        Prediction band of each held-out interval in s.
    median : ndarray
        Median of the simulated intervals in s.
    inside : ndarray of bool
        Whether each observed interval is inside its band.
    level : float
        Probability content of the band.
    """

    fit: object
    fitted_impacts: int
    observed: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    median: np.ndarray
    inside: np.ndarray
    level: float

    @property
    def coverage(self):
        """Fraction of the held-out intervals inside the band."""
        return float(np.mean(self.inside)) if self.inside.size else math.nan


def _head(data, count):
    """The first `count` detected impacts of a FitData."""
    per_impact = {f.name: getattr(data, f.name)[:count]
                  for f in dataclasses.fields(data)
                  if isinstance(getattr(data, f.name), np.ndarray)
                  and getattr(data, f.name).shape[:1] == (data.count,)
                  and f.name != "excluded"}
    return dataclasses.replace(data, **per_impact)


def prediction_band(data, law, scene=None, *, fitted_fraction=2.0 / 3.0, level=0.95,
                    draws=20000, parameter_uncertainty=True, seed=0, effects=()):
    """Fit `law` to the start of a train and check the rest against its prediction band.

    Parameters
    ----------
    data : FitData
        The whole train, from :func:`dashpot.fit.prepare_data`.
    law : str
        A key of :data:`dashpot.physics.laws.LAWS`.
    scene : Scene, optional
        Known quantities and air drag, as in :func:`fit_noise_model`.
    fitted_fraction : float
        Fraction of the detected impacts fitted (rounded to the nearest count, at least 3).
    level : float
        Probability content of the band (0.95 for 95 %).
    draws : int
        Number of simulated continuations.
    parameter_uncertainty : bool
        Draw the fitted parameters (the law's, v0, σ_ε and σ_j) from the fit's Gaussian (else
        hold them at the fit). σ_ε and σ_j are drawn as σ, in their reported errors; a draw
        below 0 is a continuation without that noise.
    seed : int
        Seed of the simulation.
    effects : tuple of str
        Flight effects of :data:`dashpot.physics.effects.FLIGHT_EFFECTS` fitted beside the law,
        as in :func:`fit_noise_model` (a ladder rung such as ``constant+drag`` is the law
        ``FlightEffect.extends`` with ``effects=(FlightEffect.name,)``); the
        continuations fly with the fitted (and, with `parameter_uncertainty`, drawn) ones.

    Returns
    -------
    PredictionCheck

    Raises
    ------
    ValueError
        Fewer than 2 held-out intervals, a level outside (0, 1), a fit that failed, or no
        simulated continuation that reaches the last held-out impact.
    """
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1); got {level!r}")
    scene = scene or Scene()
    fitted = max(3, int(round(fitted_fraction * data.count)))
    if data.count - fitted < 2:
        raise ValueError(f"{data.count} impacts leave fewer than 2 held-out intervals after "
                         f"fitting {fitted}")
    head = _head(data, fitted)
    fit = fit_noise_model(head, law, scene, profile=False, effects=effects)
    if not fit.success:
        raise ValueError(f"the fit of {law!r} to the first {fitted} impacts failed: "
                         f"{fit.message}")
    problem = NoiseProblem([head], law, scene, {}, effects=effects)
    rng = np.random.default_rng(seed)
    rows = np.tile(_natural_row(fit, problem), (draws, 1))
    if parameter_uncertainty:
        drawn = list(fit.varied)
        if drawn:
            where = [fit.varied.index(name) for name in drawn]
            sd = np.array([fit.estimates[name].stderr for name in drawn])
            correlation = np.nan_to_num(fit.correlation[np.ix_(where, where)])
            np.fill_diagonal(correlation, 1.0)
            cov = correlation * np.outer(sd, sd)
            columns = [problem.index(name) for name in drawn]
            centre = np.array([fit.estimates[name].value for name in drawn])
            natural = rng.multivariate_normal(centre, cov, size=draws, method="eigh")
            noise = np.isin(drawn, ("sigma_eps", "sigma_j"))
            # The noise parameters are drawn as σ, whose errors the fit reports, and enter
            # the simulation as ln σ (the problem's coordinates); a draw below 0 is none.
            natural[:, noise] = np.log(np.maximum(natural[:, noise], 1e-300))
            rows[:, columns] = natural
            # A draw outside the law's bounds is no parameter set of the law.
            rows[:, columns] = np.clip(rows[:, columns], problem.step_lower[columns],
                                       problem.step_upper[columns])
    broken = np.zeros(draws, bool)
    run = problem.run_filter(rows, np.zeros(draws, int), broken)
    last = int(head.index[-1])
    start_speed = np.maximum(run.filtered_speeds[:, last], 0.0)
    # The held-out impacts on the train's grid, from the last fitted one.
    positions = np.concatenate([[last], data.index[fitted:]]) - last
    detector = np.zeros(positions[-1] + 1)
    if data.sigma_known:
        detector[positions] = np.concatenate([[head.sigma[-1]], data.sigma[fitted:]])
    process, jitter = (np.exp(rows[:, problem.index(n)]) for n in ("sigma_eps", "sigma_j"))
    model = problem.model(rows, broken)
    with np.errstate(invalid="ignore", over="ignore"):
        simulated = model.simulate(positions[-1] + 1, rng, start_time=0.0,
                                   start_speed=start_speed, process_sigma=process,
                                   jitter=jitter, detector_sigma=detector)
    intervals = np.diff(simulated.times[:, positions], axis=1)
    intervals = intervals[~broken & np.all(np.isfinite(intervals), axis=1)]
    if not intervals.shape[0]:
        # Every continuation ended or broke down before the last held-out impact (a contact
        # model held at a limit where its flight cannot be continued): no band.
        raise ValueError(f"none of the {draws} continuations of the fit of {law!r} to the first "
                         f"{fitted} impacts reaches the last held-out impact")
    tail = (1.0 - level) / 2.0
    lower, median, upper = np.quantile(intervals, [tail, 0.5, 1.0 - tail], axis=0)
    observed = np.diff(np.concatenate([[head.times[-1]], data.times[fitted:]]))
    return PredictionCheck(fit=fit, fitted_impacts=fitted, observed=observed, lower=lower,
                           upper=upper, median=median,
                           inside=(observed >= lower) & (observed <= upper), level=level)


def _natural_row(fit, problem):
    """The fit's parameters in the coordinates of the fit's problem (σ's as ln σ)."""
    row = np.empty(len(problem.names))
    for i, name in enumerate(problem.names):
        value = fit.estimates[name].value
        row[i] = (math.log(value) if value > 0.0 else -math.inf) \
            if name in ("sigma_eps", "sigma_j") else value
    return row
