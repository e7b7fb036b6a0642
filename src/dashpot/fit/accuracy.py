"""Accuracy levels of the predicted trains (fast and standard certified surrogates, or exact):
the level a scene needs and its train solver.
"""

from __future__ import annotations

import functools

import numpy as np

from ..physics.models import EXACT_RTOL, GRAVITY_MODELS
from ..physics.train import impact_trains
from .settings import ACCURACY_LEVELS


def _needed_accuracy(data):
    """Relative accuracy of ε and τ that keeps the model's timing error at 1 % of the noise.

    A relative error δ in ε and τ moves impact n by about n·δ of its time since the first,
    so over a train of N impacts spanning T the worst timing error is about N·δ·T.
    """
    span = data.times[-1] - data.times[0]
    return float(0.01 * np.min(data.sigma) / (span * data.count))


def choose_accuracy(data, requested="auto", model="hybrid"):
    """Accuracy level, its train solver and the bound it guarantees, for one scene and model.

    Parameters
    ----------
    data : FitData
    requested : {"auto", "fast", "standard", "exact"}
        "auto" takes the cheapest level whose certified relative error in ε and τ is at most
        :func:`_needed_accuracy` of the data (the model's timing error stays below 1 % of the
        timing noise); the others are taken as asked.
    model : str

    Returns
    -------
    level : str
    trains_solver : callable
        ``trains_solver(model, zeta, vtilde0, count, start=, rtol=)`` ->
        :class:`~dashpot.physics.train.ImpactTrains`: :func:`impact_trains` with the exact
        solver, or the compiled trains over the level's surrogate tables.
    bound : float
        Certified maximum relative error of ε and τ (EXACT_RTOL for the exact solver).
    reason : str
    """
    if requested not in ("auto", *ACCURACY_LEVELS):
        raise ValueError(f"accuracy must be auto, {', '.join(ACCURACY_LEVELS)}; got "
                         f"{requested!r}")
    needed = _needed_accuracy(data)
    levels = ACCURACY_LEVELS if requested == "auto" else (requested,)
    for level in levels:
        trains_solver, bound = _trains_solver(level, model)
        if requested != "auto" or bound <= needed or level == "exact":
            reason = (f"{level} (asked)" if requested != "auto" else
                      f"{level}: certified error {bound:.1e} <= {needed:.1e} needed by the "
                      f"timing noise" if bound <= needed else
                      f"exact: no faster level meets the {needed:.1e} the timing noise needs")
            return level, trains_solver, bound, reason
    raise AssertionError("unreachable: the exact level is always acceptable")


def _trains_solver(level, model):
    """The train solver of an accuracy level and its certified relative error."""
    if level == "exact" or model not in GRAVITY_MODELS:
        # Ia and IIa are closed forms: exact is also the fastest.
        return impact_trains, EXACT_RTOL
    # Imported here: the compiled train solver loads numba, which only these levels need.
    from ..physics.surrogate import load_surrogate
    from ..physics.surrogate_train import surrogate_trains

    return functools.partial(surrogate_trains, level=level), load_surrogate(model, level).bound
