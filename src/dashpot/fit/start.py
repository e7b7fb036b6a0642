"""Start values of a fit from the data: ε from the interval ratios, v0 from the first interval
or the scene, ζ from ε, and ω0 from batched fits at fixed ω0 over a grid.
"""

from __future__ import annotations

import functools

import numpy as np

from ..physics.models import GRAVITY_MODELS, collide
from ..physics.train import impact_trains
from ..physics.units import _zeta_for_restitution
from .levenberg_marquardt import _solve_normal
from .settings import (FAST_PROFILE_ITERATIONS, GRAVITY_OMEGA0_SPREAD, OMEGA0_RANGE,
                       PROFILE_POINTS, ZETA_ELASTIC_GRID, ZETA_START_GRID)
from .trains import _restitution, _train_times


def _flight_ratio_start(intervals, flags):
    """ε from the median ratio of consecutive ok intervals (T_{n+1}/T_n ≈ ε)."""
    ok = (flags[:-1] == "ok") & (flags[1:] == "ok")
    ratios = intervals[1:][ok] / intervals[:-1][ok]
    if ratios.size == 0:
        ratios = intervals[1:] / intervals[:-1]
    return float(np.clip(np.median(ratios), 1e-3, 1.0 - 1e-9))


def _profile(model, data, zeta, omega0, v0, start, *, fit_v0=True, iterations=10, step=1e-6,
             trains_solver=impact_trains, flight=None):
    """Best ζ (and v0) at each of many fixed ω0, by batched Levenberg–Marquardt, t0 profiled.

    Every iteration evaluates the trains at the current values and at a small step in each
    parameter (forward differences) for all ω0 at once; the time offset is eliminated as the
    weighted mean misfit. Used for start values: the misfit is flat along ω0 where gravity's
    effect is at the noise level, so a full fit started far away crawls along that valley,
    while at fixed ω0 the rest converges in a few steps.

    `start` (speeds relative to the first, one row per ω0 or one row for all) starts the
    trains' Newton iterations. `flight` is the flight held fixed here, a
    :class:`~dashpot.physics.effects.Track` (SI; None: gravity's flight).

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
                                     trial[:, 1], start=start, trains_solver=trains_solver,
                                     flight=flight)
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
                  trains_solver=impact_trains, level="exact", omega0_spread=1.0, flight=None):
    """Start values of ζ, ω0, v0 and t0 from the data, and a note on how they were found.

    The interval ratios give ε; the first interval (or the scene) gives v0; ζ follows from ε
    at a typical speed of the train; then the best ζ and v0 at each ω0 of a broad grid
    (:func:`_profile`) pick ω0, refined by the parabola through the best three. Without
    gravity ω0 enters only through the contact time: T_n = τ + 2v_{n+1}/g and v_{n+1} = εv_n
    give T_n = εT_{n−1} + τ(1 − ε), a straight line whose intercept gives τ and so the grid's
    centre. The fast level finds ζ on a grid
    (:func:`_zeta_on_grid`) and takes fewer steps at fixed ω0 (the fit refines them all).
    With `known_omega0` the grid is that one value, or with `omega0_spread` > 1 the grid from
    `known_omega0` / `omega0_spread` to `known_omega0` · `omega0_spread` (rad/s). The fits
    at fixed ω0 fly the flight `flight` (the Track at its columns' start values, SI; see
    :func:`_profile`).
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
        centre, spread = known_omega0, omega0_spread
    elif model in GRAVITY_MODELS:
        # Gravity matters from the capture speed (ṽ ~ 1) up to ṽ ~ 1e5 at the slowest impact.
        slowest = 0.5 * g * intervals[-1]
        centre, spread = GRAVITY_OMEGA0_SPREAD * g / slowest, GRAVITY_OMEGA0_SPREAD
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
                                                trains_solver=trains_solver, flight=flight)
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
