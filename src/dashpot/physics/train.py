"""A whole train of impacts in a few vectorized calls, for fitting (dimensionless units).

:func:`dashpot.bounce_sequence` applies the bounce map one impact at a time, as the paper does:
clear, but each call of :func:`collide` costs about a millisecond of fixed overhead whatever
the number of points it gets, so a 40-impact train costs 40 calls. A fit evaluates hundreds of
nearby trains. Here the speeds of all impacts are unknowns of one nonlinear system,

    u_{k+1} = ε(u_k)·u_k,   k = 0 … n − 2,   u_0 = ṽ0,

solved by Newton's method with every ε (and its slope) evaluated in ONE vectorized call per
iteration. Started from the train of a nearby parameter set (the previous evaluation of a fit),
one or two iterations reach machine precision; without a start, or if Newton stalls, the
impact-by-impact map is used, so the result is always the exact train.

Speeds are in units of v* = g/ω0, times in units of 1/ω0. The interval after impact k is
τ_k + 2u_{k+1}: contact duration plus the flight at the rebound speed (for IIa and IIb the
release speed at F = 0, for the hybrid with the climb back to z = R already in τ; see
:func:`dashpot.bounce_sequence`).

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   section "Modeling experimental data" (the bounce map).
.. [2] J. Nocedal and S. J. Wright, *Numerical Optimization*, 2nd ed., Springer (2006),
   ch. 11 (Newton's method for nonlinear equations).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .models import GRAVITY_MODELS, collide

__all__ = ["ImpactTrain", "impact_train"]

# Relative step of the finite-difference slope dε/du: balances truncation (∝ step) against
# rounding (∝ 1e-16/step); the slope only steers Newton, it does not enter the result.
SLOPE_STEP = 1e-7
MAX_NEWTON = 6


@dataclass(frozen=True)
class ImpactTrain:
    """Dimensionless impact train (speeds in v* = g/ω0, times in 1/ω0).

    Attributes
    ----------
    speeds : ndarray
        Impact speed u_k of each impact that happens (length <= requested count).
    restitution : ndarray
        ε of each of those impacts (0 for a final captured one).
    contact_times : ndarray
        Dimensionless contact duration ω0·τ_k of each impact (inf if captured).
    intervals : ndarray
        ω0·(t_{k+1} − t_k) = τ_k + 2u_{k+1} (length: impacts − 1).
    captured : bool
        True if the last impact does not rebound (fewer impacts than requested).
    error_bound : float
        Largest relative defect |u_{k+1} − ε(u_k)u_k|/u_{k+1} of the returned speeds, or the
        estimated relative error after an accepted Newton step.
    evaluations : int
        Number of vectorized :func:`collide` calls used.
    """

    speeds: np.ndarray
    restitution: np.ndarray
    contact_times: np.ndarray
    intervals: np.ndarray
    captured: bool
    error_bound: float
    evaluations: int


def _assemble(speeds, restitution, contact_times, captured, error_bound, evaluations):
    """Cut the train at the first capture and form the intervals."""
    stop = np.flatnonzero(captured)
    count = stop[0] + 1 if stop.size else speeds.size
    speeds, restitution = speeds[:count], restitution[:count]
    contact_times = contact_times[:count]
    intervals = contact_times[:-1] + 2.0 * speeds[1:]
    return ImpactTrain(speeds, restitution, contact_times, intervals, bool(stop.size),
                       float(error_bound), evaluations)


def _sequential(model, zeta, vtilde0, count):
    """The bounce map applied one impact at a time (exact; one collide call per impact)."""
    speeds, restitution, contact_times, captured = [], [], [], []
    speed = vtilde0
    for _ in range(count):
        outcome = collide(model, zeta, speed)
        speeds.append(speed)
        restitution.append(float(outcome.eps))
        contact_times.append(float(outcome.contact_time))
        captured.append(bool(outcome.captured))
        speed = float(outcome.eps) * speed
        if captured[-1] or speed == 0.0:
            captured[-1] = True
            break
    return _assemble(np.array(speeds), np.array(restitution), np.array(contact_times),
                     np.array(captured), 0.0, len(speeds))


def _newton(model, zeta, speeds, rtol):
    """Newton iterations on the whole train from the start `speeds`; None if it stalls."""
    n = speeds.size
    for evaluation in range(1, MAX_NEWTON + 1):
        probe = collide(model, zeta, np.concatenate([speeds, speeds * (1.0 + SLOPE_STEP)]))
        eps, eps_step = probe.eps[:n], probe.eps[n:]
        captured = probe.captured[:n]
        mapped = eps * speeds
        slope = (eps_step * (1.0 + SLOPE_STEP) - eps) / SLOPE_STEP  # d(εu)/du
        # Only the impacts up to the first capture exist; later entries are not unknowns.
        stop = np.flatnonzero(captured)
        last = stop[0] if stop.size else n - 1
        defect = speeds[1:last + 1] - mapped[:last]
        defect_size = np.max(np.abs(defect) / speeds[1:last + 1], initial=0.0)
        if defect_size <= rtol:
            return _assemble(speeds, eps, probe.contact_time[:n], captured, defect_size,
                             evaluation)
        # δ_{k+1} = slope_k·δ_k − defect_k with δ_0 = 0: a first-order recurrence, sequential
        # by nature and only as long as the train (floats, not array points).
        step = np.zeros(n)
        correction = 0.0
        for k in range(last):
            correction = slope[k] * correction - defect[k]
            step[k + 1] = correction
        updated = speeds + step
        if not np.all(updated[:last + 1] > 0.0):
            return None
        speeds = updated
        if stop.size:
            # Past a capture the guess carries no information: continue geometrically.
            tail = np.arange(1, n - last)
            speeds[last + 1:] = speeds[last] * max(eps[last - 1] if last else 0.5, 1e-3) ** tail
    return None


def impact_train(model, zeta, vtilde0, count, *, start=None, rtol=1e-13):
    """Speeds, contact times and intervals of the first `count` impacts of a train.

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    zeta : float
        Damping ratio ζ = β/ω0 (dimensionless), >= 0.
    vtilde0 : float
        First impact speed ṽ0 = v0/v* (dimensionless), > 0.
    count : int
        Number of impacts wanted (fewer are returned if the ball is captured first).
    start : array_like, optional
        Guess of the speeds relative to the first, u_k/u_0 (e.g. the previous evaluation's),
        length `count`. Without it the train is built impact by impact.
    rtol : float, default 1e-13
        Largest accepted relative defect of the speeds in the bounce map.

    Returns
    -------
    ImpactTrain

    Notes
    -----
    Ia and IIa do not depend on the impact speed [1]_: u_k = ṽ0·ε^k in closed form. For the
    gravity models Newton's method [2]_ solves all the map's equations at once.
    """
    count = int(count)
    if count < 1:
        raise ValueError(f"count must be a positive integer; got {count!r}")
    if model not in GRAVITY_MODELS:
        outcome = collide(model, zeta, vtilde0)
        eps = float(outcome.eps)
        with np.errstate(under="ignore"):
            speeds = vtilde0 * eps ** np.arange(count, dtype=float)
        # ε underflows to 0 for Ia as ζ -> 1⁻: the train ends where the speed vanishes.
        captured = speeds == 0.0
        if captured.any():
            captured[np.argmax(captured) - 1] = True
        return _assemble(speeds, np.full(count, eps), np.full(count, float(outcome.contact_time)),
                         captured, 0.0, 1)
    if start is None or len(start) != count:
        return _sequential(model, zeta, vtilde0, count)
    guess = vtilde0 * np.asarray(start, dtype=float)
    guess[0] = vtilde0
    if not np.all(guess > 0.0):
        return _sequential(model, zeta, vtilde0, count)
    train = _newton(model, zeta, guess, rtol)
    return train if train is not None else _sequential(model, zeta, vtilde0, count)
