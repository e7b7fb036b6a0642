"""What a fit takes and gives: the prepared impact data, estimates with their intervals, one
model's fit and a scene's fits. Types only; the fit's modules build them.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import scipy.linalg

from ..scene import Scene


def _without_reasons(line):
    """``fit_line`` text with each "not determined (<bound>; <why>)" cut to "not determined"."""
    parts = line.split(" not determined (")
    kept = [parts[0]]
    for part in parts[1:]:
        depth, end = 1, len(part)  # to the parenthesis that closes the reason (units hold some)
        for position, character in enumerate(part):
            depth += {"(": 1, ")": -1}.get(character, 0)
            if depth == 0:
                end = position + 1
                break
        kept.append(part[end:])
    return " not determined".join(kept)


@dataclass(frozen=True)
class FitData:
    """Impact data ready for fitting (SI units).

    Attributes
    ----------
    times : ndarray
        Impact times used in s, counted from `time_origin`.
    sigma : ndarray
        1σ uncertainty of each time in s.
    index : ndarray of int
        Position of each used impact in the predicted train (an impact missed by the sensor
        leaves a gap).
    impact_speed, rebound_speed, speed_sigma : ndarray
        Measured speeds in m/s and their 1σ (NaN where not measured).
    g : float
        Driving acceleration in m/s².
    sigma_known : bool
        Whether the timing uncertainties are known (else estimated from the fit's scatter).
    excluded : ndarray of int
        Rows of the impact table not used (spurious impacts).
    bounces : pandas.DataFrame
        The bounce table of :func:`dashpot.bounces.bounce_table` with its flags.
    notes : list of str
    time_origin : float
        Time of the first impact of the table in s, subtracted from `times`: the fit works
        with times since the first impact, so that a clock far from zero (Unix-epoch times
        near 1.7e9 s resolve only 0.24 µs) costs no precision in its arithmetic.
    speed_errors : SpeedErrors or None
        The measured speeds' correlated errors where the table states them (a motion
        sensor's); None where it gives one independent σ per value (`speed_sigma`).
    """

    times: np.ndarray
    sigma: np.ndarray
    index: np.ndarray
    impact_speed: np.ndarray
    rebound_speed: np.ndarray
    speed_sigma: np.ndarray
    g: float
    sigma_known: bool
    excluded: np.ndarray
    bounces: pd.DataFrame
    notes: list = field(default_factory=list)
    time_origin: float = 0.0
    speed_errors: object = None

    @property
    def count(self):
        """Number of impacts the predicted train must have."""
        return int(self.index[-1]) + 1

    @property
    def has_speeds(self):
        return bool(np.any(np.isfinite(self.impact_speed)))

    @functools.cached_property
    def speed_whitening(self):
        """W = L⁻¹ with L Lᵀ the covariance of the measured speeds' errors in the order the
        fit's residuals take them (every measured impact speed, then every measured rebound
        speed); None where the speeds' errors are independent (no `speed_errors`)."""
        if self.speed_errors is None:
            return None
        return self.speed_errors.whitening(np.isfinite(self.impact_speed),
                                           np.isfinite(self.rebound_speed))

    @functools.cached_property
    def interval_flags(self):
        """The bounce table's flag of each interval (read once: every model's fit uses it)."""
        return self.bounces["flag"].to_numpy()


FLIGHT_CORRELATION_LIMIT = 0.95
"""Largest correlation of one flight's own errors a fit takes (5 % of each own variance kept
independent; see SpeedErrors)."""


@dataclass(frozen=True)
class SpeedErrors:
    """Correlated errors of one run's measured speeds, as a motion reader states them.

    The error of the impact speed of impact n is Σ_j shared_in[n, j]·z_j + own_in[n]·e_n and
    that of its rebound speed Σ_j shared_out[n, j]·z_j + own_out[n]·e'_n, with z_j ~ N(0, 1)
    the run's shared errors (e.g. its fitted leg accelerations and bumper position) and the
    own errors e, e' ~ N(0, 1) independent but for one flight's: e'_n (the rebound speed of
    impact n) and e_{n+1} (the impact speed of the next) have correlation `correlation[n]`,
    both being read from the parabola of the flight between them.

    Attributes
    ----------
    shared_in, shared_out : ndarray, shape (impacts, r)
        Speed shift in m/s per +1σ of each shared error (0 where it has none).
    own_in, own_out : ndarray, shape (impacts,)
        1σ of each speed's own error in m/s.
    correlation : ndarray, shape (impacts,)
        Correlation of own_out[n] with own_in[n + 1] (0 where none). Taken at most
        FLIGHT_CORRELATION_LIMIT in size: to first order both speeds are √(2a·h) of the
        flight's apex height h (a motion reader states 1), which would leave the speeds'
        covariance singular and a fit weighing exactly the combinations in which the two
        legs' fitted accelerations cancel.
    """

    shared_in: np.ndarray
    shared_out: np.ndarray
    own_in: np.ndarray
    own_out: np.ndarray
    correlation: np.ndarray

    @property
    def flight_correlation(self):
        """`correlation` within ±FLIGHT_CORRELATION_LIMIT (see the class docstring)."""
        return np.clip(self.correlation, -FLIGHT_CORRELATION_LIMIT, FLIGHT_CORRELATION_LIMIT)

    def covariance(self, impact_rows, rebound_rows):
        """Covariance (m²/s²) of the errors of the impact speeds at `impact_rows` then the
        rebound speeds at `rebound_rows` (boolean masks over the impacts)."""
        impact_rows, rebound_rows = np.asarray(impact_rows, bool), np.asarray(rebound_rows, bool)
        shared = np.concatenate([self.shared_in[impact_rows], self.shared_out[rebound_rows]])
        own = np.concatenate([self.own_in[impact_rows], self.own_out[rebound_rows]])
        cov = shared @ shared.T + np.diag(own ** 2)
        # Rebound speed n and impact speed n + 1: one flight's own error.
        position_in = np.cumsum(impact_rows) - 1
        position_out = int(impact_rows.sum()) + np.cumsum(rebound_rows) - 1
        n = np.flatnonzero(rebound_rows[:-1] & impact_rows[1:] & (self.correlation[:-1] != 0))
        pair = self.flight_correlation[n] * self.own_out[n] * self.own_in[n + 1]
        cov[position_out[n], position_in[n + 1]] += pair
        cov[position_in[n + 1], position_out[n]] += pair
        return cov

    def whitening(self, impact_rows, rebound_rows):
        """W = L⁻¹, L the lower Cholesky factor of :meth:`covariance`: W·e has independent
        unit-variance entries, and |W·e|² = eᵀC⁻¹e (generalized least squares)."""
        cov = self.covariance(impact_rows, rebound_rows)
        if cov.size == 0:
            return np.zeros((0, 0))
        factor = np.linalg.cholesky(cov)
        return scipy.linalg.solve_triangular(factor, np.eye(cov.shape[0]), lower=True)


@dataclass(frozen=True)
class Estimate:
    """A fitted or derived quantity with its 1σ error and central 68.27 % / 95.45 % intervals.

    ``status`` is "fitted", "fixed", "prior" or "derived"; ``note`` says why.
    """

    value: float
    stderr: float
    low68: float
    high68: float
    low95: float
    high95: float
    unit: str
    status: str
    note: str = ""


@dataclass
class FitResult:
    """One model fitted to one scene. See :func:`fit_model`."""

    model: str
    success: bool
    message: str
    estimates: dict
    varied: tuple
    correlation: np.ndarray
    chisqr: float
    redchi: float
    aic: float
    bic: float
    ndata: int
    nvarys: int
    nfev: int
    time_residuals: np.ndarray
    normalized_residuals: np.ndarray
    predicted: dict
    eps_curve: dict
    notes: list
    numerical_tolerance: float
    error_bound: float
    intervals: dict = field(default_factory=dict)
    accuracy: str = ""

    def __repr__(self) -> str:
        """One line: the model, its quantities rounded to their errors, the ε range and χ²/ν
        (:func:`dashpot.fit_report.fit_line`, a quantity the data do not determine said so
        without its bound), or why it failed."""
        from ..fit_report import fit_line

        return f"<FitResult {self.model}: {_without_reasons(fit_line(self))}>"


@dataclass
class SceneFit:
    """Every requested model fitted to one scene, with the model-selection table.

    ``noise_results``, ``noise_selection`` and ``noise_verdict`` hold the fits under the noise
    model (:func:`dashpot.fit.noise_scene.fit_noise_scene`) where they were asked for: empty,
    None and "" otherwise.
    """

    scene: Scene
    data: FitData
    results: dict
    selection: pd.DataFrame
    verdict: str
    noise_results: dict = field(default_factory=dict)
    noise_selection: pd.DataFrame | None = None
    noise_verdict: str = ""

    def report(self, *, verbose: bool = False) -> str:
        """The text summary ``dashpot fit`` and ``dashpot analyze`` print, in the spirit of
        lmfit's ``fit_report``.

        Parameters
        ----------
        verbose : bool, default False
            Also the notes on how each fit was made (accuracy level, start values).

        Returns
        -------
        str
            One line per model (ζ, β in 1/s, k in N/m, each rounded to two significant digits
            of its 1σ error; the ε range of its train; χ²/ν) with its notes beneath, what the
            models the data cannot tell apart agree on, the selection's verdict and the
            scene's notes (:func:`dashpot.fit_report.report_text`).
        """
        from ..fit_report import report_text

        return report_text(self, verbose=verbose)

    @property
    def parameters(self) -> pd.DataFrame:
        """Every estimate of every fit as a table: one row per model and parameter.

        Columns ``model, parameter, value, stderr, low68, high68, low95, high95, unit, status,
        note`` in SI units (β in 1/s, k in N/m, ω0 in rad/s, v0 in m/s; σ_j in s), the rows of
        ``<name>-parameters.csv`` (:func:`dashpot.fit_report.parameter_table`); computed anew
        on each access.
        """
        from ..fit_report import parameter_table

        return parameter_table(self)

    def __repr__(self) -> str:
        """One line: the scene, the impacts fitted, each model's outcome, the noise fits."""
        fitted = [model for model, fit in self.results.items() if fit.success]
        failed = [model for model in self.results if model not in fitted]
        parts = [f"{len(self.data.times)} impacts",
                 f"fitted {', '.join(fitted) or 'none'}"]
        if failed:
            parts.append(f"failed {', '.join(failed)}")
        if self.noise_results:
            parts.append(f"{len(self.noise_results)} fits under the noise model")
        return f"<SceneFit {self.scene.name!r}: {'; '.join(parts)}; .report() for the summary>"
