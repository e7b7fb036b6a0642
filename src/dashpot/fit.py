"""Fit the damping β and stiffness k of a linear spring-dashpot contact to a bounce train.

For each contact model the impact times of a scene are fitted with lmfit (Levenberg–Marquardt,
MINPACK) by the predicted train: parameters ζ and the characteristic speed v* = g/ω0 (in which
the misfit valley is nearly straight), the first impact speed v0 and the time t0 of the first
impact. Quantities the scene knows are fixed, or enter as a Gaussian prior when the scene gives
their uncertainty. Residuals are the impact-time misfits divided by their 1σ uncertainties,
plus the measured impact and rebound speeds where the sensor gives them (motion sensors,
photogates). The numerical accuracy of the predicted trains is a level (fast and standard
certified surrogates, or exact) chosen per scene or derived from its timing noise.

Start values come from the data (the interval ratios give ε and so ζ; the first interval or the
drop height gives v0; fits at fixed ω0 over a grid, batched, pick the stiffness), so fits need
no hand tuning. A fit that fails is returned with ``success=False`` and the reason; it never
raises for bad data and never returns NaN parameters as if they were results.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface"
   (the models and the recursive use of each model on experimental data).
.. [2] M. Newville et al., LMFIT: Non-Linear Least-Squares Minimization and Curve-Fitting for
   Python, Zenodo, doi:10.5281/zenodo.598352.
.. [3] K. P. Burnham and D. R. Anderson, *Model Selection and Multimodel Inference*, 2nd ed.,
   Springer (2002), sec. 2.2 (AIC with known variance: χ² + 2K) and 2.9 (Akaike weights).
.. [4] P. R. Bevington and D. K. Robinson, *Data Reduction and Error Analysis for the Physical
   Sciences*, 3rd ed. (2003), sec. 3.2 (propagation of errors).
.. [5] W. H. Press et al., *Numerical Recipes*, 3rd ed., Cambridge (2007), sec. 15.6
   (confidence regions from Δχ² = 1 and 4 for one parameter).
.. [6] D. Foreman-Mackey et al., "emcee: The MCMC Hammer", PASP 125, 306 (2013).
.. [7] D. W. Marquardt, "An algorithm for least-squares estimation of nonlinear parameters",
   J. SIAM 11, 431 (1963).
.. [8] H. B. Nielsen, "Damping parameter in Marquardt's method", IMM-REP-1999-05, Technical
   University of Denmark (1999).
.. [9] C. J. F. ter Braak and J. A. Vrugt, "Differential Evolution Markov Chain with snooker
   updater and fewer chains", Statistics and Computing 18, 435 (2008).
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, field

import lmfit
import numpy as np
import pandas as pd

from .bounces import bounce_table
from .physics.models import EXACT_RTOL, GRAVITY_MODELS, MODELS, collide
from .physics.train import impact_trains
from .physics.units import _zeta_for_restitution
from .scene import Scene

__all__ = ["FitData", "FitResult", "Estimate", "prepare_data", "fit_model", "fit_scene",
           "SceneFit", "choose_accuracy", "ACCURACY_LEVELS", "UNCERTAINTY_METHODS"]

Z68, Z95 = 1.0, 2.0  # normal quantiles of the central 68.27 % and 95.45 % intervals
OMEGA0_RANGE = (0.1, 1e7)  # rad/s searched and allowed for ω0
PROFILE_POINTS = 9
REJECTED = 1e12  # residual of a step outside the physical range
INTERVAL_SEED = 20261122
# Draws for the intervals of derived values, per level: the Monte Carlo error of a 95.45 %
# bound is about 0.02 (20 000 draws) or 0.05 (4 000) standard errors.
INTERVAL_DRAWS = {"fast": 4000, "standard": 20000, "exact": 20000}
UNCERTAINTY_METHODS = ("covariance", "profile", "posterior")
ACCURACY_LEVELS = ("fast", "standard", "exact")  # cheapest first
QUANTILES = (0.158655, 0.841345, 0.0227501, 0.9772499)  # central 68.27 % and 95.45 %
METHOD, OPTIONS = "leastsq", {"epsfcn": 1e-6}
PARAMETERS = ("zeta", "v_star", "v0", "t0")  # the fitted coordinates, in this order
# The fast level's optimizer stops once the Gauss–Newton step left is below this many standard
# errors (in the metric of the fit's own covariance), and differentiates with this step.
FAST_STEP_SE, FAST_JACOBIAN_STEP = 0.01, 1e-5
# Start values of the fast level: steps of the fits at fixed ω0, and the grid of ζ searched
# for the interval ratio (inside the surrogate tables' domain).
FAST_PROFILE_ITERATIONS = 3
ZETA_START_GRID = np.geomspace(1e-4, 0.9, 41)
ZETA_ELASTIC_GRID = np.geomspace(1e-12, 1e-4, 33)
# Relative errors above which a parameter is reported as not determined by the data.
WEAK_RELATIVE_ERROR = 0.5
STRONG_CORRELATION = 0.98


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

    @property
    def count(self):
        """Number of impacts the predicted train must have."""
        return int(self.index[-1]) + 1

    @property
    def has_speeds(self):
        return bool(np.any(np.isfinite(self.impact_speed)))

    @functools.cached_property
    def interval_flags(self):
        """The bounce table's flag of each interval (read once: every model's fit uses it)."""
        return self.bounces["flag"].to_numpy()


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


def _flight_ratio_start(intervals, flags):
    """ε from the median ratio of consecutive ok intervals (T_{n+1}/T_n ≈ ε)."""
    ok = (flags[:-1] == "ok") & (flags[1:] == "ok")
    ratios = intervals[1:][ok] / intervals[:-1][ok]
    if ratios.size == 0:
        ratios = intervals[1:] / intervals[:-1]
    return float(np.clip(np.median(ratios), 1e-3, 1.0 - 1e-9))


def prepare_data(impacts, scene):
    """Impact times, uncertainties and train positions for fitting, from an impact table.

    Parameters
    ----------
    impacts : pandas.DataFrame
        Impact table of :mod:`dashpot.ingest` (``time`` in s, optional ``time_uncertainty``,
        ``impact_speed``, ``rebound_speed``, ``speed_uncertainty``, ``run``).
    scene : Scene

    Returns
    -------
    FitData

    Notes
    -----
    Where the recording gives no timing uncertainty the scene's timing resolution r gives
    σ = r/√12 (uniform rounding); where neither is known σ is estimated from the scatter of
    the fit (and the information criteria use the unknown-variance form). Where only some
    uncertainties are zero or unknown, those are set to r/√12, or without r to the smallest
    positive σ of the table, and the others kept (noted). Impacts the bounce
    table flags as spurious are left out; an interval flagged as hiding a missed impact
    shifts the later impacts by one place in the train. Only the first run of a multi-run
    file is fitted.
    """
    table = impacts
    notes = []
    if "run" in table and table["run"].nunique() > 1:
        first = table["run"].min()
        notes.append(f"{table['run'].nunique()} runs in the file; fitted run {first} only")
        table = table[table["run"] == first]
    table = table.reset_index(drop=True)
    times = table["time"].to_numpy(float)
    if times.size < 3:
        raise ValueError(f"fitting needs at least three impacts; got {times.size}")
    sigma = table["time_uncertainty"].to_numpy(float) if "time_uncertainty" in table \
        else np.full(times.size, np.nan)
    usable = np.isfinite(sigma) & (sigma > 0)
    sigma_known = bool(np.all(usable))
    if usable.any() and not sigma_known:
        # A few zero or unknown σ must not discard the others: fill in those few.
        if scene.timing_resolution:
            fill, source = scene.timing_resolution / math.sqrt(12.0), \
                "the scene's timing resolution / sqrt(12)"
        else:
            fill, source = float(np.min(sigma[usable])), "the smallest timing uncertainty given"
        notes.append(f"{int(np.sum(~usable))} of {times.size} timing uncertainties zero or "
                     f"missing: set to {source} ({fill:.3g} s); the others kept")
        sigma = np.where(usable, sigma, fill)
        sigma_known = True
    if not sigma_known:
        if scene.timing_resolution:
            sigma = np.full(times.size, scene.timing_resolution / math.sqrt(12.0))
            sigma_known = True
            notes.append("timing uncertainty from the scene's timing resolution / sqrt(12)")
        else:
            sigma = np.ones(times.size)
            notes.append("no timing uncertainty given: estimated from the scatter of the fit")
    g = scene.driving_acceleration
    run = table["run"].to_numpy() if "run" in table else np.zeros(times.size, dtype=int)
    bounces = bounce_table(pd.DataFrame({"time": times, "time_uncertainty": sigma, "run": run}),
                           g=g)
    flags = bounces["flag"].to_numpy()
    # Interval n ends at impact n + 1: a "spurious" interval pair brackets one false impact.
    spurious_impacts = np.flatnonzero((flags[:-1] == "spurious") & (flags[1:] == "spurious")) + 1
    keep = np.ones(times.size, bool)
    keep[spurious_impacts] = False
    gaps = np.concatenate([[0], np.cumsum(flags == "missed")])
    index = np.arange(times.size) + gaps
    if spurious_impacts.size:
        notes.append(f"left out {spurious_impacts.size} impact(s) flagged as spurious")
    if np.any(flags == "missed"):
        notes.append(f"{int(np.sum(flags == 'missed'))} missed impact(s) bridged in the train")
    index = index[keep]
    index = index - index[0]

    def column(name):
        if name in table:
            return table[name].to_numpy(float)[keep]
        return np.full(int(keep.sum()), np.nan)

    speed_sigma = column("speed_uncertainty")
    has_speed = np.isfinite(column("impact_speed")) & np.isfinite(speed_sigma) & (speed_sigma > 0)
    if np.any(np.isfinite(column("impact_speed"))) and not np.any(has_speed):
        notes.append("measured speeds have no uncertainty: not used in the fit")
    rebound_speed = column("rebound_speed")
    origin = float(times[0])  # t - origin is exact for t up to twice the origin (Sterbenz)
    return FitData(times=times[keep] - origin, time_origin=origin, sigma=sigma[keep],
                   index=index,
                   impact_speed=np.where(has_speed, column("impact_speed"), np.nan),
                   rebound_speed=np.where(has_speed & np.isfinite(rebound_speed),
                                          rebound_speed, np.nan),
                   speed_sigma=np.where(has_speed, speed_sigma, np.nan), g=g,
                   sigma_known=sigma_known, excluded=np.flatnonzero(~keep), bounces=bounces,
                   notes=notes)


def _impact_times(trains, omega0):
    """Impact times in s from the first, one row per train (ω0 in rad/s per train); after a
    capture the ball rests on the surface, so later impacts keep the last time."""
    times = np.zeros(trains.speeds.shape)
    np.cumsum(trains.intervals, axis=1, out=times[:, 1:])
    return times / omega0[:, None]


class _TrainPredictor:
    """Predicted trains of one model for many parameter sets at once, each evaluation started
    from the previous one's train (Newton's start; see :func:`impact_trains`)."""

    def __init__(self, model, g, count, trains_solver=impact_trains):
        self.model, self.g, self.count = model, g, count
        self.trains_solver = trains_solver
        self.start = None
        self.error_bound = 0.0

    def __call__(self, zeta, omega0, v0):
        """Trains at arrays (or scalars) ζ, ω0 (rad/s), v0 (m/s), one row per parameter set.

        Returns
        -------
        trains : ImpactTrains
        times : ndarray, shape (sets, count)
            Impact times in s from the first; after a capture the ball rests on the surface,
            so later impacts keep the last time.
        speeds, rebound : ndarray, shape (sets, count)
            Impact and rebound speeds in m/s (0 after a capture).
        """
        zeta, omega0, v0 = (np.atleast_1d(np.asarray(value, float))
                            for value in (zeta, omega0, v0))
        if not zeta.shape == omega0.shape == v0.shape:
            zeta, omega0, v0 = np.broadcast_arrays(zeta, omega0, v0)
        v_star = self.g / omega0
        start = (None if self.start is None
                 else np.broadcast_to(self.start, (zeta.size, self.count)))
        trains = self.trains_solver(self.model, zeta, v0 / v_star, self.count, start=start,
                                    rtol=EXACT_RTOL)
        self.error_bound = max(self.error_bound, float(np.max(trains.error_bound)))
        first = int(trains.impacts[0])
        ratios = trains.speeds[0, :first] / trains.speeds[0, 0]
        if first < self.count:
            # Captured early: keep a usable start by continuing the last ratio geometrically.
            last = ratios[-1] * (ratios[-1] / ratios[-2] if first > 1 else 0.5) ** np.arange(
                1, self.count - first + 1)
            ratios = np.concatenate([ratios, np.maximum(last, 1e-300)])
        self.start = ratios
        times = _impact_times(trains, omega0)
        speeds = trains.speeds * v_star[:, None]
        return trains, times, speeds, trains.restitution * speeds


def _residual_rows(values, *, data, predictor, priors):
    """Normalized residuals, one row per parameter set (columns as in PARAMETERS).

    Impact-time misfits over their σ, then the measured impact and rebound speeds' misfits
    over theirs, then one row per Gaussian prior (name, centre, sd). A set outside the
    physical range (ζ < 0, ω0 above OMEGA0_RANGE, v0 <= 0) gets REJECTED everywhere.
    """
    g = data.g
    zeta, v_star, v0, t0 = values.T
    impact_rows = np.isfinite(data.impact_speed)
    rebound_rows = np.isfinite(data.rebound_speed)
    valid = (zeta >= 0.0) & (v_star > g / OMEGA0_RANGE[1]) & (v0 > 0.0)
    out = np.full((values.shape[0], _residual_size(data, priors)), REJECTED)
    if not valid.any():
        return out
    _, times, speeds, rebound = predictor(zeta[valid], g / v_star[valid], v0[valid])
    parts = [(data.times - t0[valid, None] - times[:, data.index]) / data.sigma]
    if impact_rows.any():
        parts.append((data.impact_speed[impact_rows] - speeds[:, data.index[impact_rows]])
                     / data.speed_sigma[impact_rows])
    if rebound_rows.any():
        parts.append((data.rebound_speed[rebound_rows] - rebound[:, data.index[rebound_rows]])
                     / data.speed_sigma[rebound_rows])
    for name, centre, sd in priors:
        parts.append((values[valid, PARAMETERS.index(name), None] - centre) / sd)
    out[valid] = np.concatenate(parts, axis=1)
    return out


def _residual_size(data, priors):
    """Number of residuals of :func:`_residual_rows`."""
    return (data.times.size + int(np.isfinite(data.impact_speed).sum())
            + int(np.isfinite(data.rebound_speed).sum()) + len(priors))


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
    from .physics.surrogate import load_surrogate
    from .physics.surrogate_train import surrogate_trains

    return functools.partial(surrogate_trains, level=level), load_surrogate(model, level).bound


def _train_times(model, data, zeta, omega0, v0, start=None, trains_solver=impact_trains):
    """Predicted times (s, from the first impact) of the observed impacts, many trains at once.

    A train captured before the last observed impact rests at its last one.

    Returns
    -------
    times : ndarray, shape (trains, observed impacts)
    trains : ImpactTrains
    """
    trains = trains_solver(model, zeta, v0 * omega0 / data.g, data.count, start=start)
    return _impact_times(trains, omega0)[:, data.index], trains


def _profile(model, data, zeta, omega0, v0, start, *, fit_v0=True, iterations=10, step=1e-6,
             trains_solver=impact_trains):
    """Best ζ (and v0) at each of many fixed ω0, by batched Levenberg–Marquardt, t0 profiled.

    Every iteration evaluates the trains at the current values and at a small step in each
    parameter (forward differences) for all ω0 at once; the time offset is eliminated as the
    weighted mean misfit. Used for start values: the misfit is flat along ω0 where gravity's
    effect is at the noise level, so a full fit started far away crawls along that valley,
    while at fixed ω0 the rest converges in a few steps.

    `start` (speeds relative to the first, one row per ω0 or one row for all) starts the
    trains' Newton iterations.

    Returns
    -------
    chisqr, zeta, v0, t0 : ndarray
        Per ω0, at the best values found.
    ratios : ndarray
        Relative speeds of the best train found (a start for further trains).
    """
    weights = data.sigma ** -2.0
    count = zeta.size
    names = 2 if fit_v0 else 1
    current = np.stack([zeta, v0], axis=1)
    best = current.copy()
    best_chisqr = np.full(count, np.inf)
    best_t0 = np.zeros(count)
    best_residual = np.zeros((count, data.times.size))
    best_jacobian = np.zeros((count, data.times.size, names))
    damping = np.full(count, 1e-3)
    start = np.broadcast_to(start, (names + 1, count, data.count)).reshape(-1, data.count)
    for _ in range(iterations):
        trial = np.repeat(current[None], names + 1, axis=0)
        for k in range(names):
            trial[k + 1, :, k] *= 1.0 + step
        trial = trial.reshape(-1, 2)
        times, trains = _train_times(model, data, trial[:, 0], np.tile(omega0, names + 1),
                                     trial[:, 1], start=start, trains_solver=trains_solver)
        misfit = data.times[None, :] - times
        t0 = np.sum(misfit * weights, axis=1) / weights.sum()
        residual = ((misfit - t0[:, None]) / data.sigma).reshape(names + 1, count, -1)
        chisqr = np.sum(residual[0] ** 2, axis=1)
        # Levenberg–Marquardt bookkeeping per ω0: keep a step that lowers χ², else retry
        # from the best point with more damping.
        improved = chisqr < best_chisqr
        if np.all(~improved | (chisqr > best_chisqr * (1.0 - 1e-9))):
            break  # converged everywhere: no step lowers χ² by more than rounding
        best[improved], best_chisqr[improved] = current[improved], chisqr[improved]
        best_t0[improved], best_residual[improved] = t0[:count][improved], residual[0][improved]
        best_jacobian[improved] = np.stack(
            [(residual[k + 1] - residual[0]) / (step * current[:, k:k + 1])
             for k in range(names)], axis=2)[improved]
        damping = np.where(improved, damping / 10.0, damping * 10.0)
        normal = np.einsum("gmi,gmj->gij", best_jacobian, best_jacobian)
        normal = normal + (damping[:, None] * np.einsum("gii->gi", normal))[:, :, None] * np.eye(
            names)[None]
        gradient = np.einsum("gmi,gm->gi", best_jacobian, best_residual)
        delta = -_solve_normal(normal, gradient)
        current = best.copy()
        current[:, :names] += np.where(np.isfinite(delta), delta, 0.0)
        current = np.where(current > 0.0, current, 0.5 * best)
        # The next trains start from these ones' speeds (captured ones from scratch).
        ratios = trains.speeds[:count] / trains.speeds[:count, :1]
        start = np.tile(np.where(trains.impacts[:count, None] == data.count, ratios, np.nan),
                        (names + 1, 1))
    winner = int(np.argmin(best_chisqr))
    return best_chisqr, best[:, 0], best[:, 1], best_t0, start[winner]


def _restitution(trains_solver, model, zeta, vtilde):
    """ε and the capture flag at (ζ, ṽ) (broadcast) from trains of one impact: the surrogate
    levels' compiled pass costs a fraction of a ``collide`` call on the tables for the few
    hundred points of a fit."""
    zeta, vtilde = np.broadcast_arrays(zeta, vtilde)
    trains = trains_solver(model, zeta.ravel(), vtilde.ravel(), 1)
    return (trains.restitution[:, 0].reshape(zeta.shape),
            np.isinf(trains.contact_times[:, 0]).reshape(zeta.shape))


def _zeta_on_grid(model, eps, vtilde, trains_solver, grid=None):
    """ζ at which `model` gives restitution `eps` at impact speeds ṽ, to about 1 % (a start).

    ε falls monotonically with ζ: it is evaluated on a logarithmic grid of ζ for every target
    in one call (trains of one impact by `trains_solver`, the compiled pass at the
    surrogate levels), and ln ζ interpolated linearly in logit ε between the grid points that
    bracket the target. Targets above the grid's first ε are looked for again on a grid of
    smaller ζ (nearly elastic balls). NaN where no grid point reaches it.
    """
    grid = ZETA_START_GRID if grid is None else grid
    restitution, _ = _restitution(trains_solver, model, grid[None, :], vtilde[:, None])
    below = restitution < eps[:, None]
    found = below.any(axis=1) & (restitution[:, 0] >= eps)
    upper = np.clip(np.argmax(below, axis=1), 1, grid.size - 1)
    rows = np.arange(eps.size)
    with np.errstate(divide="ignore", invalid="ignore"):
        logit = np.log(restitution) - np.log1p(-restitution)
        left, right = logit[rows, upper - 1], logit[rows, upper]
        fraction = np.clip((np.log(eps) - np.log1p(-eps) - left) / (right - left), 0.0, 1.0)
    log_zeta = np.log(grid)
    zeta = np.exp(log_zeta[upper - 1] + np.nan_to_num(fraction) * (log_zeta[upper]
                                                                   - log_zeta[upper - 1]))
    zeta = np.where(found, zeta, np.nan)
    elastic = restitution[:, 0] < eps
    if grid is ZETA_START_GRID and elastic.any():
        zeta[elastic] = _zeta_on_grid(model, eps[elastic], vtilde[elastic], trains_solver,
                                      ZETA_ELASTIC_GRID)
    return zeta


def _start_values(model, data, known_v0, known_omega0, *, fit_v0=True,
                  trains_solver=impact_trains, level="exact"):
    """Start values of ζ, ω0, v0 and t0 from the data, and a note on how they were found.

    The interval ratios give ε; the first interval (or the scene) gives v0; ζ follows from ε
    at a typical speed of the train; then the best ζ and v0 at each ω0 of a broad grid
    (:func:`_profile`) pick ω0, refined by the parabola through the best three. Without
    gravity ω0 enters only through the contact time: T_n = τ + 2v_{n+1}/g and v_{n+1} = εv_n
    give T_n = εT_{n−1} + τ(1 − ε), a straight line whose intercept gives τ and so the grid's
    centre. The fast level finds ζ on a grid
    (:func:`_zeta_on_grid`) and takes fewer steps at fixed ω0 (the fit refines them all).
    """
    if level == "fast":
        zeta_for = functools.partial(_zeta_on_grid, trains_solver=trains_solver)
        iterations = FAST_PROFILE_ITERATIONS
    else:
        zeta_for, iterations = _zeta_for_restitution, 10
    g = data.g
    intervals = np.diff(data.times) / np.diff(data.index)
    flags = data.interval_flags[: intervals.size]
    eps = _flight_ratio_start(intervals, flags)
    if data.has_speeds:
        measured = data.rebound_speed / data.impact_speed
        measured = measured[np.isfinite(measured) & (measured > 0) & (measured < 1)]
        if measured.size:
            eps = float(np.median(measured))
    if known_v0 is not None:
        v0 = known_v0
    elif data.has_speeds and np.isfinite(data.impact_speed[0]):
        v0 = float(data.impact_speed[0])
    else:
        # Rebound speed after the first impact from its flight, g·T/2, divided by ε.
        v0 = 0.5 * g * intervals[0] / eps
    if known_omega0 is not None:
        centre, spread = known_omega0, 1.0
    elif model in GRAVITY_MODELS:
        # Gravity matters from the capture speed (ṽ ~ 1) up to ṽ ~ 1e5 at the slowest impact.
        slowest = 0.5 * g * intervals[-1]
        centre, spread = math.sqrt(1e5) * g / slowest, math.sqrt(1e5)
    else:
        if intervals.size >= 3:
            slope, intercept = np.polyfit(intervals[:-1], intervals[1:], 1)
            contact = intercept / max(1.0 - slope, 1e-3)
        else:
            contact = 0.0
        contact = max(contact, 0.1 * float(np.median(data.sigma)))
        zeta = zeta_for(model, np.array([eps]), np.array([1.0]))
        centre = float(collide(model, np.nan_to_num(zeta, nan=0.1), 1.0).contact_time[0]
                       / contact)
        spread = 3.0
    points = PROFILE_POINTS if spread > 1.0 else 1
    # Newton starts the first trains from a geometric train (failures fall back to the map).
    ratios = eps ** np.arange(data.count, dtype=float)
    omega0 = np.clip(centre * spread ** np.linspace(-1.0, 1.0, points), *OMEGA0_RANGE)
    typical = np.maximum(v0 * omega0 / g * eps ** (0.5 * data.count), 1e-3)
    zeta = zeta_for(model, np.full(omega0.size, eps), typical)
    usable = np.isfinite(zeta)
    if not usable.any():
        return None, "no damping ratio reproduces the interval ratios at any stiffness tried"
    omega0 = omega0[usable]
    chisqr, zeta, v0_fit, t0, ratios = _profile(model, data, zeta[usable], omega0,
                                                np.full(omega0.size, v0), ratios,
                                                fit_v0=fit_v0, iterations=iterations,
                                                trains_solver=trains_solver)
    best = int(np.argmin(chisqr))
    centre = float(omega0[best])
    if (level != "fast" and 0 < best < omega0.size - 1
            and np.all(np.isfinite(chisqr[best - 1:best + 2]))
            and omega0[best - 1] < omega0[best] < omega0[best + 1]):
        # Vertex of the parabola through the best point and its neighbours, in ln ω0.
        x = np.log(omega0[best - 1:best + 2])
        y = chisqr[best - 1:best + 2]
        left, right = x[0] - x[1], x[2] - x[1]
        # Parabola through the three points: y = a·d² + b·d + y1 with d = x − x1.
        slope_left, slope_right = (y[0] - y[1]) / left, (y[2] - y[1]) / right
        curvature = (slope_right - slope_left) / (right - left)
        if curvature > 0:
            slope = slope_left - curvature * left
            centre = float(np.exp(x[1] + np.clip(-slope / (2 * curvature), left, right)))
    # ratios: relative speeds of the best train found, Newton's start for the fit's trains.
    start = {"zeta": float(zeta[best]), "omega0": centre, "v0": float(v0_fit[best]),
             "t0": float(t0[best]), "ratios": ratios}
    how = (f"start: median eps = {eps:.4g}; zeta = {start['zeta']:.4g}, v0 = {start['v0']:.4g} "
           f"m/s and omega0 = {centre:.4g} rad/s from fits at fixed omega0 on a grid")
    return start, how


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


def fit_model(data, model, scene=None, *, max_nfev=2000, uncertainty=("covariance",),
              seed=0, accuracy=None):
    """Fit one contact model to a scene's impacts.

    Parameters
    ----------
    data : FitData
        From :func:`prepare_data`.
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    scene : Scene, optional
        What is known of the apparatus (default: nothing but standard gravity).
    max_nfev : int, default 2000
        Largest number of model evaluations.
    uncertainty : sequence of {"covariance", "profile", "posterior"}
        Methods for the intervals of β, at increasing cost: the Gaussian approximation from
        the Jacobian (always computed; it fills ``estimates``), the profile likelihood (χ²
        minimised over the other parameters at fixed β; intervals where it rises by 1 and 4
        [5]_), and posterior sampling with emcee (flat priors, seeded by `seed`) [6]_. Each
        method's intervals of β (1/s) and its CPU time go to ``intervals``.
    seed : int, default 0
        Seed of the posterior sampler.
    accuracy : {"auto", "fast", "standard", "exact"}, optional
        Numerical accuracy of the predicted trains (default: the scene's); see
        :func:`choose_accuracy`. The level, its solver and the error it guarantees are
        recorded in ``accuracy``, ``notes`` and ``numerical_tolerance``.

    Returns
    -------
    FitResult
        ``estimates`` holds ``zeta`` (1), ``omega0`` (rad/s), ``beta`` (1/s), ``v0`` (m/s),
        ``t0`` (s), ``v_star`` (m/s), and with a known mass ``k`` (N/m) and ``gamma``
        (kg/s), each with its 1σ error by linear propagation [4]_ and central 68.27 % and
        95.45 % intervals: Gaussian for the fitted ζ, v*, v0 and t0, and for the derived ones
        the quantiles of seeded draws from that Gaussian (ω0 = g/v* is unbounded above where
        v* = 0 is inside). ``predicted`` holds the model's train (impact ``times`` in s,
        ``speeds`` m/s, ``restitution``, ``contact_durations`` s) and ``at_data`` (predicted
        times of the observed impacts); ``eps_curve`` ε against impact speed (m/s) over the
        predicted range. Information criteria follow [3]_: with known timing errors AIC =
        χ² + 2K and BIC = χ² + K ln N; otherwise N ln(χ²/N) + 2K and N ln(χ²/N) + K ln N.
    """
    scene = scene or Scene()
    if model not in MODELS:
        raise ValueError(f"model must be one of {', '.join(MODELS)}; got {model!r}")
    unknown = set(uncertainty) - set(UNCERTAINTY_METHODS)
    if unknown:
        raise ValueError(f"unknown uncertainty method {sorted(unknown)[0]!r}; use "
                         f"{', '.join(UNCERTAINTY_METHODS)}")
    notes = list(data.notes)
    try:
        return _fit(data, model, scene, notes, max_nfev, tuple(uncertainty), seed, accuracy)
    except (ValueError, ArithmeticError, RuntimeError, np.linalg.LinAlgError) as error:
        return _failed(model, f"fit failed: {error}", notes, data)


def _failed(model, message, notes, data):
    """A fit that could not be made: kept in the output with its reason, same layout."""
    empty = np.full(data.times.size, np.nan)
    nothing = np.zeros(0)
    return FitResult(model=model, success=False, message=message, estimates={}, varied=(),
                     correlation=np.zeros((0, 0)), chisqr=math.inf, redchi=math.inf,
                     aic=math.inf, bic=math.inf, ndata=int(data.times.size), nvarys=0, nfev=0,
                     time_residuals=empty, normalized_residuals=empty,
                     predicted={"times": nothing, "speeds": nothing, "restitution": nothing,
                                "contact_durations": nothing, "at_data": empty},
                     eps_curve={"speed": nothing, "eps": nothing,
                                "captured": np.zeros(0, bool)},
                     notes=notes + [message], numerical_tolerance=math.nan,
                     error_bound=math.nan)


def _fit(data, model, scene, notes, max_nfev, uncertainty, seed, accuracy):
    mass = scene.mass
    known_v0 = scene.known_impact_speed
    stiffness = scene.stiffness
    if stiffness is not None and mass is None:
        notes.append("stiffness known but mass not: omega0 = sqrt(k/m) needs both; omega0 fitted")
        stiffness = None
    fixed_omega0 = (math.sqrt(stiffness.value / mass.value)
                    if stiffness is not None and stiffness.uncertainty is None
                    and mass.uncertainty is None else None)
    fixed_v0 = known_v0.value if known_v0 is not None and known_v0.uncertainty is None else None
    unknowns = 2 + (fixed_omega0 is None) + (fixed_v0 is None)
    measured = data.times.size + int(np.isfinite(data.impact_speed).sum()
                                     + np.isfinite(data.rebound_speed).sum())
    if measured <= unknowns:
        return _failed(model, f"fit failed: {measured} measured values cannot determine "
                              f"{unknowns} unknowns (zeta, t0"
                              + (", omega0" if fixed_omega0 is None else "")
                              + (", v0" if fixed_v0 is None else "")
                              + "); give more impacts or known quantities in the scene",
                       notes, data)
    level, trains_solver, bound, reason = choose_accuracy(data, accuracy or scene.accuracy, model)
    notes.append(f"accuracy {reason}")
    known_omega0 = None if stiffness is None else math.sqrt(stiffness.value / mass.value)
    start, how = _start_values(model, data, None if known_v0 is None else known_v0.value,
                               known_omega0, fit_v0=fixed_v0 is None,
                               trains_solver=trains_solver,
                               level=level)
    if start is None:
        return _failed(model, f"fit failed: {how}", notes, data)
    notes.append(how)

    # Fitted as ζ and the characteristic speed v* = g/ω0: gravity's effect on ε grows like
    # v*/v and the contact time like 1/ω0 ∝ v*, so the misfit valley is nearly straight in
    # (ζ, v*); in (ln ζ, ln ω0) it is a banana along which Levenberg–Marquardt crawls.
    g = data.g
    params = lmfit.Parameters()
    # No bounds: lmfit maps bounded parameters through sqrt or sine transforms, which bend the
    # valley again (ζ ≈ u²/2 near 0). A step to a non-physical value is rejected instead, by
    # the residual function returning an enormous misfit there.
    params.add("zeta", value=start["zeta"])
    params.add("v_star", value=g / start["omega0"], vary=fixed_omega0 is None)
    params.add("v0", value=start["v0"], vary=fixed_v0 is None)
    params.add("t0", value=start["t0"])
    fixed = {}
    if fixed_omega0 is not None:
        fixed["omega0"] = "stiffness and mass known exactly: omega0 = sqrt(k/m)"
    if fixed_v0 is not None:
        fixed["v0"] = ("first impact speed known" if scene.first_impact_speed is not None
                       else "drop height known: v0 = sqrt(2 g_eff h)")
    priors = []
    if stiffness is not None and fixed_omega0 is None:
        sd = math.hypot(stiffness.uncertainty or 0.0,
                        stiffness.value * (mass.uncertainty or 0.0) / mass.value)
        prior_v_star = g / math.sqrt(stiffness.value / mass.value)
        priors.append(("v_star", prior_v_star, prior_v_star * 0.5 * sd / stiffness.value))
        notes.append("prior on omega0 from the known stiffness and mass")
    if known_v0 is not None and fixed_v0 is None:
        priors.append(("v0", known_v0.value, known_v0.uncertainty))
        notes.append("prior on v0 from the scene")

    # Each train is that of the level's map to machine precision (Newton's method, or the
    # compiled impact-by-impact pass over the surrogate tables): the finite-difference
    # Jacobians difference trains whose parameters differ by ~1e-8 to 1e-5.
    predictor = _TrainPredictor(model, data.g, data.count, trains_solver)
    predictor.start = start["ratios"]
    # What the fitted times can be off by, relative to the span of the train.
    tolerance = bound * data.count
    residual_rows = functools.partial(_residual_rows, data=data, predictor=predictor,
                                      priors=priors)

    def residual(p):
        """lmfit's residual function: one parameter set."""
        values = p.valuesdict()
        return residual_rows(np.array([[values[name] for name in PARAMETERS]]))[0]

    # ∂r/∂t0: the time offset enters linearly, only the impact-time rows.
    t0_column = np.zeros(_residual_size(data, priors))
    t0_column[: data.times.size] = -1.0 / data.sigma

    def minimize(start):
        if level == "fast":
            return _levenberg_marquardt(residual_rows, start, {"t0": t0_column},
                                        max_nfev=max_nfev, sigma_known=data.sigma_known)
        return lmfit.minimize(residual, start, method=METHOD, max_nfev=max_nfev, **OPTIONS,
                              scale_covar=not data.sigma_known)

    def captures(fitted):
        """True if the fitted train ends in capture before the last observed impact."""
        values = fitted.params.valuesdict()
        if not (values["zeta"] >= 0 and values["v_star"] > 0 and values["v0"] > 0):
            return True
        trains, *_ = predictor(values["zeta"], g / values["v_star"], values["v0"])
        return int(trains.impacts[0]) < data.count

    result = minimize(params)
    if model in GRAVITY_MODELS and fixed_omega0 is None and captures(result):
        # Ended where the model captures the ball before the data end: a local minimum, as
        # every gravity model reaches the gravity-free one when ω0 grows. Start again from
        # there (ṽ ≈ 1e4 at the slowest impact, ω0 held until the rest has settled).
        notes.append("first fit ended in capture; restarted from the gravity-free limit")
        restart = params.copy()  # the fast optimizer updates its start in place
        restart["v_star"].set(value=0.5 * g * np.min(np.diff(data.times)) * 1e-4, vary=False)
        limit = minimize(restart)
        limit.params["v_star"].set(vary=True)
        retry = minimize(limit.params)
        if retry.chisqr < result.chisqr or captures(result):
            result = retry
    values = result.params.valuesdict()
    if not np.all(np.isfinite(result.residual)):
        return _failed(model, "fit failed: the model gave non-finite residuals", notes, data)
    zeta, v_star = values["zeta"], values["v_star"]
    omega0 = g / v_star
    trains, times, speeds, _ = predictor(zeta, omega0, values["v0"])
    impacts = int(trains.impacts[0])
    times, speeds = times[0], speeds[0]
    message = result.message
    success = bool(result.success)
    if impacts < data.count:
        success = False
        message = (f"the model captures the ball after {impacts} impacts but the "
                   f"data have {data.count}")

    varied = tuple(name for name in result.var_names)
    cov = result.covar
    if cov is None:
        cov = np.full((len(varied), len(varied)), np.inf)
        notes.append("covariance not available (singular Jacobian): the data do not determine "
                     "every parameter; errors reported as infinite")
    dof = max(int(result.nfree), 1)
    # χ² is divided by this wherever it measures likelihood (the covariance carries it
    # already): the fit's χ²/ν where σ is unknown, or where the model misses the data.
    chisqr_scale = 1.0 if data.sigma_known else float(result.redchi)
    if data.sigma_known and result.chisqr > dof + 3.0 * math.sqrt(2.0 * dof):
        # χ² far beyond its distribution (> 3σ): the model does not describe the data within
        # their uncertainties. Errors are scaled by √(χ²/ν) (the Birge ratio) so that they
        # at least reflect the actual scatter.
        cov = cov * result.redchi
        chisqr_scale = float(result.redchi)
        notes.append(f"reduced chi-square {result.redchi:.3g} for {dof} degrees of freedom: "
                     f"the model misses the data by more than their uncertainties; errors "
                     f"scaled by sqrt(redchi) = {math.sqrt(result.redchi):.3g}")
    for name, centre, spread in priors:
        value = result.params[name].value
        if abs(value - centre) > 3.0 * spread:
            label = "omega0" if name == "v_star" else name
            shown = (g / value, g / centre) if name == "v_star" else (value, centre)
            notes.append(f"fitted {label} = {shown[0]:.4g} disagrees with the scene's "
                         f"{shown[1]:.4g} by more than 3 sigma of the prior")
    sd = {name: float(math.sqrt(cov[i, i])) if np.isfinite(cov[i, i]) and cov[i, i] >= 0
          else math.inf for i, name in enumerate(varied)}
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.sqrt(np.diag(cov))
        correlation = cov / np.outer(scale, scale)
    correlation = np.where(np.isfinite(correlation), correlation, np.nan)

    def log_sd(*weights_by_name):
        """sd of ln q from the covariance, given ∂ln q/∂p per parameter (fixed ones add 0)."""
        vector = np.zeros(len(varied))
        for name, weight in weights_by_name:
            if name in varied:
                vector[varied.index(name)] = weight
        if not vector.any():
            return 0.0
        used = vector != 0
        block = cov[np.ix_(used, used)]
        if not np.all(np.isfinite(block)):
            return math.inf
        variance = vector[used] @ block @ vector[used]
        return float(math.sqrt(variance)) if np.isfinite(variance) and variance >= 0 else math.inf

    def status(name, prior_name=None):
        if name in varied:
            return ("prior" if any(p[0] == (prior_name or name) for p in priors) else "fitted"), ""
        return "fixed", fixed.get({"v_star": "omega0"}.get(name, name), "")

    estimates = {}
    # Standard errors by linear propagation; intervals of the derived quantities from draws
    # of the Gaussian approximation in the fitted coordinates (ζ, v*, v0, t0), where the
    # likelihood is closest to Gaussian. ω0 = g/v* is unbounded above when v* = 0 (the
    # gravity-free limit) lies inside the interval, and the intervals say so.
    d_zeta, d_v_star = ("zeta", 1.0 / zeta), ("v_star", -1.0 / v_star)
    draws = _draws(values, varied, cov, INTERVAL_DRAWS[level])
    mass_draws = (1.0 if mass is None else mass.value + (mass.uncertainty or 0.0)
                  * np.random.default_rng(INTERVAL_SEED + 1).standard_normal(
                      INTERVAL_DRAWS[level]))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        omega_draws = np.where(draws["v_star"] > 0, g / draws["v_star"], np.inf)
        beta_draws = np.where(draws["zeta"] > 0, np.maximum(draws["zeta"], 0) * omega_draws,
                              0.0)
    st, why = status("zeta")
    estimates["zeta"] = _sampled(zeta, log_sd(d_zeta) * zeta, draws["zeta"], "1", st, why)
    st, why = status("v_star")
    estimates["omega0"] = _sampled(omega0, log_sd(d_v_star) * omega0, omega_draws, "rad/s",
                                   st, why)
    estimates["v_star"] = _linear_estimate(v_star, sd.get("v_star", 0.0), "m/s", st,
                                           why or "characteristic speed g/omega0")
    estimates["beta"] = _sampled(zeta * omega0, log_sd(d_zeta, d_v_star) * zeta * omega0,
                                 beta_draws, "1/s", "derived", "beta = zeta * omega0")
    st, why = status("v0")
    estimates["v0"] = _linear_estimate(values["v0"], sd.get("v0", 0.0), "m/s", st, why)
    # Times on output are on the table's clock again.
    estimates["t0"] = _linear_estimate(data.time_origin + values["t0"], sd.get("t0", 0.0), "s",
                                       "fitted")
    if mass is not None:
        mass_sd = (mass.uncertainty or 0.0) / mass.value
        k = mass.value * omega0 ** 2
        k_sd = math.hypot(log_sd(("v_star", -2.0 / v_star)), mass_sd) * k
        with np.errstate(over="ignore", invalid="ignore"):
            estimates["k"] = _sampled(k, k_sd, mass_draws * omega_draws ** 2, "N/m", "derived",
                                      "k = m * omega0^2")
            gamma = 2.0 * mass.value * zeta * omega0
            gamma_sd = math.hypot(log_sd(d_zeta, d_v_star), mass_sd) * gamma
            estimates["gamma"] = _sampled(gamma, gamma_sd, 2.0 * mass_draws * beta_draws,
                                          "kg/s", "derived", "gamma = 2 m beta")
    notes.extend(_identifiability_notes(estimates, varied, correlation, result.params))

    nvarys = len(varied)
    ndata = int(result.ndata)
    chisqr = float(result.chisqr)
    if data.sigma_known:
        aic, bic = chisqr + 2 * nvarys, chisqr + nvarys * math.log(ndata)
    else:
        aic, bic = float(result.aic), float(result.bic)
    predicted_at_data = values["t0"] + times[data.index]  # since the origin
    intervals = {"covariance": _interval_row(estimates["beta"])}
    for method in uncertainty:
        if method in ("profile", "posterior") and success:
            started = time.process_time()
            if method == "profile":
                intervals[method] = _profile_beta(residual, result, g, chisqr_scale)
            else:
                # The sampler runs on the fast level's trains, whatever the fit's level.
                sampled = _TrainPredictor(model, g, data.count,
                                          _trains_solver("fast", model)[0])
                sampled.start = predictor.start
                intervals[method] = _posterior_beta(
                    functools.partial(_residual_rows, data=data, predictor=sampled,
                                      priors=priors), result, g, seed, chisqr_scale)
                if not intervals[method]["converged"]:
                    notes.append("posterior chain shorter than 50 autocorrelation times: its "
                                 "intervals are rough")
            intervals[method]["cpu_seconds"] = time.process_time() - started
    v_star = data.g / omega0
    top = float(np.max(speeds))
    bottom = float(np.min(speeds[speeds > 0])) if np.any(speeds > 0) else top
    curve_speed = np.geomspace(bottom, top, 200) if top > bottom else np.array([top])
    curve_eps, curve_captured = _restitution(trains_solver, model, zeta,
                                             curve_speed / v_star)
    return FitResult(
        model=model, success=success, message=message, estimates=estimates, varied=varied,
        correlation=correlation, chisqr=chisqr, redchi=float(result.redchi), aic=aic, bic=bic,
        ndata=ndata, nvarys=nvarys, nfev=int(result.nfev),
        time_residuals=data.times - predicted_at_data,
        normalized_residuals=np.asarray(result.residual, float),
        predicted={"times": data.time_origin + (values["t0"] + times[:impacts]),
                   "speeds": speeds[:impacts],
                   "restitution": trains.restitution[0, :impacts],
                   "contact_durations": trains.contact_times[0, :impacts] / omega0,
                   "at_data": data.time_origin + predicted_at_data},
        eps_curve={"speed": curve_speed, "eps": curve_eps, "captured": curve_captured},
        notes=notes, numerical_tolerance=tolerance, error_bound=predictor.error_bound,
        intervals=intervals, accuracy=level)


def _solve_normal(normal, gradient):
    """x with normal·x = gradient, for one system or a stack of them (last axes).

    By LU where every system is regular, else by the pseudo-inverse: a singular system must
    not stop the rest. A parameter without any effect (a zero row and column, e.g. a train
    captured at every nearby value) gets no step, as the pseudo-inverse would give it, while
    LU still solves for the others.
    """
    inert = np.einsum("...ii->...i", normal) <= 0.0
    if inert.any():
        normal = normal + inert[..., None] * np.eye(normal.shape[-1])
        gradient = np.where(inert, 0.0, gradient)
    try:
        return np.linalg.solve(normal, gradient[..., None])[..., 0]
    except np.linalg.LinAlgError:
        with np.errstate(all="ignore"):
            return np.einsum("...ij,...j->...i", np.linalg.pinv(normal), gradient)


def _levenberg_marquardt(residual_rows, params, linear_columns, *, max_nfev, sigma_known):
    """Levenberg–Marquardt of the fast level: batched differences, stopped at a fraction of
    a standard error.

    Each iteration evaluates the trial point and the forward-difference steps of its Jacobian
    in ONE call of `residual_rows` (one batched train solve), and a parameter that enters
    linearly takes its exact column from `linear_columns`. The iteration stops once the
    Gauss–Newton step still to go, δ = −(JᵀJ)⁻¹Jᵀr, is shorter than FAST_STEP_SE standard
    errors in the fit's own metric: δᵀJᵀJδ <= FAST_STEP_SE² · s², with s² = max(1, χ²/ν)
    (χ²/ν where σ is unknown), the factor by which the covariance is scaled. Damping by the
    diagonal of JᵀJ as in Marquardt [7]_, updated by the gain ratio as in Nielsen [8]_;
    lmfit's leastsq (MINPACK) is the other levels' optimizer.

    Parameters
    ----------
    residual_rows : callable
        ``residual_rows(values)`` with values of shape (sets, len(PARAMETERS)) returns the
        normalized residuals, shape (sets, n).
    params : lmfit.Parameters
        Start values; which are varied. Updated in place to the fitted values and errors (and
        returned as the result's ``params``): copying lmfit parameters costs more than an
        iteration here.
    linear_columns : dict
        Parameter name -> its exact Jacobian column (for parameters entering linearly).
    max_nfev : int
        Largest number of parameter sets evaluated.
    sigma_known : bool
        Whether the residuals are normalized by known uncertainties (else the covariance is
        scaled by χ²/ν, as lmfit's ``scale_covar``).

    Returns
    -------
    lmfit.minimizer.MinimizerResult
        With the fields the fit reads: params (values and stderr), var_names, covar, chisqr,
        redchi, nfree, ndata, nfev, residual, success, message, aic, bic.
    """
    values = np.array([params[name].value for name in PARAMETERS], float)
    varied = [i for i, name in enumerate(PARAMETERS) if params[name].vary]
    differenced = [i for i in varied if PARAMETERS[i] not in linear_columns]

    def evaluate(point):
        """Residuals and Jacobian at `point` (one batched call)."""
        steps = FAST_JACOBIAN_STEP * np.maximum(np.abs(point[differenced]), 1e-12)
        sets = np.repeat(point[None], 1 + len(differenced), axis=0)
        sets[np.arange(1, sets.shape[0]), differenced] += steps
        rows = residual_rows(sets)
        jacobian = np.empty((rows.shape[1], len(varied)))
        for column, i in enumerate(varied):
            if i in differenced:
                k = differenced.index(i)
                jacobian[:, column] = (rows[1 + k] - rows[0]) / steps[k]
            else:
                jacobian[:, column] = linear_columns[PARAMETERS[i]]
        return rows[0], jacobian, sets.shape[0]

    residual, jacobian, nfev = evaluate(values)
    chisqr = float(residual @ residual)
    dof = max(residual.size - len(varied), 1)
    damping, growth = 1e-6, 2.0  # close to Gauss–Newton: the start is near the minimum
    success, message = False, "largest number of evaluations reached"
    while nfev < max_nfev:
        normal, gradient = jacobian.T @ jacobian, jacobian.T @ residual
        newton = -_solve_normal(normal, gradient)
        spread = chisqr / dof if not sigma_known else max(1.0, chisqr / dof)
        if not np.all(np.isfinite(newton)):
            message = "the Jacobian is not finite"
            break
        if newton @ normal @ newton <= FAST_STEP_SE ** 2 * spread:
            success = True
            message = f"converged: the step left is below {FAST_STEP_SE} standard error"
            break
        scale = np.maximum(np.diag(normal), 1e-300)
        try:
            step = np.linalg.solve(normal + damping * np.diag(scale), -gradient)
        except np.linalg.LinAlgError:
            step = newton
        trial = values.copy()
        trial[varied] += step
        trial_residual, trial_jacobian, cost = evaluate(trial)
        nfev += cost
        trial_chisqr = float(trial_residual @ trial_residual)
        # Gain ratio: actual against predicted decrease of χ² (Nielsen's damping update [8]_).
        predicted = -(2.0 * step @ gradient + step @ normal @ step)
        gain = (chisqr - trial_chisqr) / predicted if predicted > 0 else -1.0
        if trial_chisqr < chisqr:
            settled = chisqr - trial_chisqr <= FAST_STEP_SE ** 2 * spread
            values, residual, jacobian = trial, trial_residual, trial_jacobian
            chisqr = trial_chisqr
            if settled and predicted <= FAST_STEP_SE ** 2 * spread:
                # A flat valley (a parameter the data barely determine): χ² no longer moves
                # by what 0.01 standard error would change it.
                success, message = True, "converged: chi-square no longer changes"
                break
            damping *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
            growth = 2.0
        else:
            damping *= growth
            growth *= 2.0
            if damping > 1e12:
                # No step lowers χ² any more: at the minimum to rounding.
                success, message = True, "converged: no step lowers chi-square"
                break
    normal = jacobian.T @ jacobian
    covar = None
    if np.linalg.matrix_rank(normal) == len(varied):
        covar = np.linalg.inv(normal) * (1.0 if sigma_known else chisqr / dof)
    result = lmfit.minimizer.MinimizerResult()
    result.params = params
    for column, i in enumerate(varied):
        name = PARAMETERS[i]
        result.params[name].value = float(values[i])
        result.params[name].stderr = (float(math.sqrt(covar[column, column]))
                                      if covar is not None else None)
    ndata, nvarys = residual.size, len(varied)
    result.var_names = [PARAMETERS[i] for i in varied]
    result.covar, result.residual, result.nfev = covar, residual, int(nfev)
    result.chisqr, result.ndata, result.nvarys, result.nfree = chisqr, ndata, nvarys, dof
    result.redchi = chisqr / dof
    result.success, result.message = success, message
    with np.errstate(divide="ignore"):
        neg2_log_likelihood = ndata * np.log(chisqr / ndata)
    result.aic = float(neg2_log_likelihood + 2 * nvarys)
    result.bic = float(neg2_log_likelihood + np.log(ndata) * nvarys)
    return result


def _interval_row(estimate):
    return {"low68": estimate.low68, "high68": estimate.high68, "low95": estimate.low95,
            "high95": estimate.high95}


def _profile_beta(residual, result, g, chisqr_scale=1.0, points=17, span=4.0):
    """Profile likelihood of β: the best χ² over the other parameters at each fixed β.

    β is put in as a parameter (ζ = βv*/g) on a grid of ±`span` standard errors in ln β
    around the fit, each point started from its neighbour; the 68.27 % and 95.45 % intervals
    are where the profile, χ²/`chisqr_scale`, rises by 1 and 4 above its minimum (linear
    interpolation in ln β), unbounded where it does not within the grid [5]_.
    """
    params = result.params.copy()
    beta_hat = params["zeta"].value * g / params["v_star"].value
    params.add("beta", value=beta_hat, vary=False)
    params["zeta"].set(expr=f"beta * v_star / {g!r}")
    spread = math.hypot(*(result.params[name].stderr / result.params[name].value
                          if result.params[name].stderr else 0.0
                          for name in ("zeta", "v_star")))
    spread = min(max(spread, 1e-6), 2.0)
    offsets = np.linspace(-span, span, points) * spread
    profile = np.full(points, np.inf)
    centre = points // 2
    for order in (range(centre, points), range(centre, -1, -1)):
        trial = params.copy()
        for i in order:
            trial["beta"].set(value=beta_hat * math.exp(offsets[i]))
            fitted = lmfit.minimize(residual, trial, method=METHOD, max_nfev=400, **OPTIONS)
            profile[i] = fitted.chisqr
            trial = fitted.params
    rise = (profile - min(profile.min(), result.chisqr)) / chisqr_scale
    row = {}
    for level, label in ((1.0, "68"), (4.0, "95")):
        for side, key in ((-1, "low"), (1, "high")):
            row[key + label] = _crossing(offsets, rise, level, side, centre, beta_hat)
    return row


def _crossing(offsets, rise, level, side, centre, beta_hat):
    """β where the profile first rises past `level` going from the centre towards `side`."""
    index = range(centre, len(offsets)) if side > 0 else range(centre, -1, -1)
    previous = None
    for i in index:
        if rise[i] >= level and previous is not None:
            fraction = (level - rise[previous]) / (rise[i] - rise[previous])
            return beta_hat * math.exp(offsets[previous]
                                       + fraction * (offsets[i] - offsets[previous]))
        previous = i
    return 0.0 if side < 0 else math.inf


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
    columns = [PARAMETERS.index(name) for name in varied]
    best = np.array([result.params[name].value for name in PARAMETERS], float)

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


def _identifiability_notes(estimates, varied, correlation, params):
    """Plain-words warnings where the data do not pin a parameter down."""
    notes = []
    labels = {"zeta": "zeta", "v_star": "omega0 (and so k)", "v0": "v0", "t0": "t0"}
    for name in varied:
        param = params[name]
        if any(np.isfinite(bound) and abs(param.value - bound) <= 1e-3 * abs(bound)
               for bound in (param.min, param.max)):
            notes.append(f"{labels[name]} ended at its bound: not determined by these data")
    omega0 = estimates.get("omega0")
    if omega0 is not None and omega0.status != "fixed" and math.isinf(omega0.high95):
        notes.append("omega0 (and so k) is not bounded above at 95 %: the data are consistent "
                     "with the gravity-free limit (v* = g/omega0 -> 0)")
    for key, label in (("omega0", "omega0 (and so k)"), ("zeta", "zeta"), ("beta", "beta")):
        estimate = estimates.get(key)
        if estimate is not None and estimate.status != "fixed":
            relative = estimate.stderr / estimate.value if estimate.value else math.inf
            if not relative <= WEAK_RELATIVE_ERROR:
                notes.append(f"{label} is not determined by these data (relative error "
                             f"{relative:.2g})")
    for i, first in enumerate(varied):
        for j in range(i + 1, len(varied)):
            rho = correlation[i, j]
            if np.isfinite(rho) and abs(rho) > STRONG_CORRELATION:
                notes.append(f"{labels[first]} and {labels[varied[j]]} are strongly correlated "
                             f"(rho = {rho:.3f}): the data constrain a combination of them")
    return notes


@dataclass
class SceneFit:
    """Every requested model fitted to one scene, with the model-selection table."""

    scene: Scene
    data: FitData
    results: dict
    selection: pd.DataFrame
    verdict: str


def fit_scene(impacts, scene=None, models=None, *, progress=None):
    """Fit every requested model to a scene's impacts and compare them.

    Parameters
    ----------
    impacts : pandas.DataFrame
        Impact table of :mod:`dashpot.ingest`.
    scene : Scene, optional
    models : sequence of str, optional
        Default: the scene's models (all five unless it says otherwise).
    progress : callable, optional
        Called with each model's name once it is fitted.

    Returns
    -------
    SceneFit
    """
    from .select import selection_table

    scene = scene or Scene()
    models = tuple(models or scene.models)
    data = prepare_data(impacts, scene)
    results = {}
    for model in models:
        results[model] = fit_model(data, model, scene)
        if progress is not None:
            progress(model)
    selection, verdict = selection_table(results, sigma_known=data.sigma_known)
    return SceneFit(scene=scene, data=data, results=results, selection=selection,
                    verdict=verdict)
