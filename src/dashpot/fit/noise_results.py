"""The result of a fit under the noise model (:mod:`dashpot.fit.noise_fit`), and that of a fit
that could not be made.

At the bottom of the noise fit's imports beside :mod:`dashpot.fit.noise_settings`: it imports
only :mod:`dashpot.fit.results`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import lmfit
import numpy as np

from .results import FitResult

__all__ = ["NoiseFitResult", "failed_noise_fit"]


@dataclass
class NoiseFitResult(FitResult):
    """A :class:`FitResult` of the noise model, with what only this likelihood has.

    Attributes
    ----------
    neg2_log_likelihood : float
        −2 ln L at the likelihood's maximum (σ_ε at its maximum-likelihood value, or 0),
        priors included, start time integrated out: that of the criteria. The reported
        parameters are those at the adjusted σ_ε (module notes, *Noise estimates*).
    params : lmfit.Parameters or None
        The fitted parameters (natural units; σ_ε and σ_j, not their logarithms) with their
        bounds and standard errors.
    outliers : ndarray of int
        Positions in the data (``FitData.times``) of innovations with |z| > 4.
    timing_sigma : ndarray
        Total 1σ timing noise of each impact in s, √(σ_i² + σ_j²).
    """

    neg2_log_likelihood: float = math.nan
    params: lmfit.Parameters | None = None
    outliers: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    timing_sigma: np.ndarray = field(default_factory=lambda: np.zeros(0))


def failed_noise_fit(data, law, message, notes=()):
    """A noise fit that could not be made, with its reason: the layout of any other, with
    ``success`` false, criteria inf and nothing predicted.

    Parameters
    ----------
    data : FitData
    law : str
    message : str
        Why the fit failed (also the last note).
    notes : sequence of str
        Notes gathered before the failure.
    """
    empty = np.full(data.times.size, np.nan)
    nothing = np.zeros(0)
    return NoiseFitResult(
        model=law, success=False, message=message, estimates={}, varied=(),
        correlation=np.zeros((0, 0)), chisqr=math.inf, redchi=math.inf, aic=math.inf,
        bic=math.inf, ndata=int(data.times.size), nvarys=0, nfev=0, time_residuals=empty,
        normalized_residuals=empty,
        predicted={"times": nothing, "speeds": nothing, "restitution": nothing,
                   "contact_durations": nothing, "at_data": empty},
        eps_curve={"speed": nothing, "eps": nothing, "captured": np.zeros(0, bool)},
        notes=list(notes) + [message], numerical_tolerance=math.nan, error_bound=math.nan,
        neg2_log_likelihood=math.inf)
