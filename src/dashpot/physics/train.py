"""A whole train of impacts in a few vectorized calls, for fitting (dimensionless units).

:func:`dashpot.bounce_sequence` applies the bounce map one impact at a time, as the paper does:
clear, but each call of :func:`collide` costs about a millisecond of fixed overhead whatever
the number of points it gets, so a 40-impact train costs 40 calls. A fit evaluates hundreds of
nearby trains. Here the speeds of all impacts are unknowns of one nonlinear system,

    u_{k+1} = ε(u_k)·u_k,   k = 0 … n − 2,   u_0 = ṽ0,

solved by Newton's method with every ε (and its slope) evaluated in ONE vectorized call per
iteration — for many trains (parameter sets) at once. Started from the train of a nearby
parameter set (the previous evaluation of a fit), one or two iterations reach machine
precision; without a start, or where Newton stalls, the map is applied impact by impact
(vectorized over the trains), so the result is always the exact train.

Speeds are in units of v* = g/ω0, times in units of 1/ω0. The interval after impact k is
τ_k + 2u_{k+1}: contact duration plus the flight at the rebound speed (for IIa and IIb the
release speed at F = 0, for the hybrid with the climb back to z = R already in τ; see
:func:`dashpot.bounce_sequence`).

With a :class:`TrackFlight` (air drag, or a cart's two accelerations on its track) the ball
leaves at r_k = ε(u_k)·u_k, flies T(r_k) and lands at u_{k+1} = L(r_k)
(:func:`dashpot.physics.flight.track_flight`); the map is then u_{k+1} = L(ε(u_k)u_k) and the
interval τ_k + T(r_k). Contact is under g (the unit of the accelerations); drag during the
contact is neglected, as in :func:`dashpot.bounce_sequence`.

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

from .flight import _track
from .models import GRAVITY_MODELS, collide

__all__ = ["ImpactTrain", "ImpactTrains", "TrackFlight", "impact_train", "impact_trains"]

# Relative step of the central differences for d(εu)/du and its curvature: truncation ∝ step²
# against rounding ∝ 1e-16/step.
SLOPE_STEP = 1e-5
MAX_NEWTON = 6


@dataclass(frozen=True)
class TrackFlight:
    """The flight between impacts of each train, dimensionless (one value per train).

    Attributes
    ----------
    up : ndarray, shape (trains,)
        Deceleration moving away from the surface, a_up/g (1 for a ball; g is the
        acceleration of the contact, the unit of v* = g/ω0).
    down : ndarray, shape (trains,)
        Acceleration on the way back, a_down/g.
    drag : ndarray, shape (trains,)
        Drag constant k_d·v*²/g (k_d in 1/m).

    With up = down = 1 and drag = 0 the flight is gravity's, 2r, landing at r.
    """

    up: np.ndarray
    down: np.ndarray
    drag: np.ndarray

    @classmethod
    def of(cls, up, down, drag, trains):
        """Broadcast to `trains` values each (float arrays)."""
        return cls(*(np.broadcast_to(np.asarray(value, float), (trains,)).copy()
                     for value in (up, down, drag)))

    def take(self, rows):
        """The flights of the trains `rows` (an index array or mask)."""
        return TrackFlight(self.up[rows], self.down[rows], self.drag[rows])

    def _per_train(self, shape):
        extra = (1,) * (len(shape) - 1)
        return (self.up.reshape(-1, *extra), self.down.reshape(-1, *extra),
                self.drag.reshape(-1, *extra))

    def landing(self, rebound):
        """Landing speed L(r) of rebound speeds r, one row (first axis) per train."""
        return _track(rebound, *self._per_train(rebound.shape))[1]

    def duration(self, rebound):
        """Flight duration T(r) of rebound speeds r, one row (first axis) per train."""
        return _track(rebound, *self._per_train(rebound.shape))[0]


@dataclass(frozen=True)
class ImpactTrains:
    """Many dimensionless impact trains (speeds in v* = g/ω0, times in 1/ω0), one per row.

    Attributes
    ----------
    speeds : ndarray, shape (trains, count)
        Impact speed u_k of each impact; 0 past the last impact of a captured train.
    restitution : ndarray, shape (trains, count)
        ε of each impact (0 for a final captured one and past it).
    contact_times : ndarray, shape (trains, count)
        Dimensionless contact duration ω0·τ_k (inf for a final captured impact, 0 past it).
    impacts : ndarray of int, shape (trains,)
        Number of impacts that happen (< count where the ball is captured first).
    error_bound : ndarray, shape (trains,)
        Largest relative defect |u_{k+1} − ε(u_k)u_k|/u_{k+1} of the speeds returned, or the
        bound on the error left by an accepted Newton step; 0 for the impact-by-impact map.
    evaluations : int
        Number of vectorized :func:`collide` calls used.
    flight : TrackFlight or None
        The flight between impacts (None: gravity's).
    """

    speeds: np.ndarray
    restitution: np.ndarray
    contact_times: np.ndarray
    impacts: np.ndarray
    error_bound: np.ndarray
    evaluations: int
    flight: TrackFlight | None = None

    @property
    def intervals(self):
        """ω0·(t_{k+1} − t_k) = τ_k + T(ε_k u_k) (gravity: τ_k + 2u_{k+1}), shape
        (trains, count − 1); 0 past capture."""
        exists = np.arange(1, self.speeds.shape[1]) < self.impacts[:, None]
        with np.errstate(invalid="ignore"):
            if self.flight is None:
                flights = 2.0 * self.speeds[:, 1:]
            else:
                flights = self.flight.duration(self.restitution[:, :-1] * self.speeds[:, :-1])
            return np.where(exists, self.contact_times[:, :-1] + flights, 0.0)


@dataclass(frozen=True)
class ImpactTrain:
    """One dimensionless impact train, cut at its last impact (see :class:`ImpactTrains`).

    Attributes
    ----------
    speeds, restitution, contact_times : ndarray
        Per impact that happens.
    intervals : ndarray
        τ_k + 2u_{k+1} (length: impacts − 1).
    captured : bool
        True if the last impact does not rebound (fewer impacts than requested).
    error_bound : float
    evaluations : int
    """

    speeds: np.ndarray
    restitution: np.ndarray
    contact_times: np.ndarray
    intervals: np.ndarray
    captured: bool
    error_bound: float
    evaluations: int


def _cut_at_capture(speeds, restitution, contact_times, captured):
    """Zero everything past each train's first capture; count the impacts that happen."""
    n = speeds.shape[1]
    stops = captured.any(axis=1)
    impacts = np.where(stops, np.argmax(captured, axis=1) + 1, n)
    past = np.arange(n)[None, :] >= impacts[:, None]
    return (np.where(past, 0.0, speeds), np.where(past, 0.0, restitution),
            np.where(past, 0.0, contact_times), impacts)


def _landing(flight, rows, rebound):
    """Landing speeds of the rebound speeds of trains `rows` (gravity: the rebound speed)."""
    return rebound if flight is None else flight.take(rows).landing(rebound)


def _sequential(model, zeta, vtilde0, count, solver=collide, flight=None):
    """The bounce map applied one impact at a time, vectorized over the trains (exact)."""
    trains = zeta.size
    speeds = np.zeros((trains, count))
    restitution = np.zeros((trains, count))
    contact_times = np.zeros((trains, count))
    captured = np.zeros((trains, count), bool)
    speed = vtilde0.astype(float)
    alive = np.ones(trains, bool)
    evaluations = 0
    for k in range(count):
        if not alive.any():
            break
        outcome = solver(model, zeta[alive], speed[alive])
        evaluations += 1
        speeds[alive, k] = speed[alive]
        restitution[alive, k] = outcome.eps
        contact_times[alive, k] = outcome.contact_time
        # ε underflows to 0 for Ia as ζ -> 1⁻: a train also ends where the speed vanishes.
        ends = outcome.captured | (outcome.eps * speed[alive] == 0.0)
        captured[alive, k] = ends
        speed[alive] = _landing(flight, alive, outcome.eps * speed[alive])
        alive[np.flatnonzero(alive)[ends]] = False
    speeds, restitution, contact_times, impacts = _cut_at_capture(speeds, restitution,
                                                                  contact_times, captured)
    return ImpactTrains(speeds, restitution, contact_times, impacts, np.zeros(trains),
                        evaluations, flight)


def _linear_recurrence(factor, forcing):
    """x_0 = 0, x_{k+1} = factor_k·x_k + forcing_k along axis 1, in closed form.

    x_{k+1} = P_{k+1}·Σ_{j<=k} forcing_j/P_{j+1} with P_{k+1} = Π_{i<=k} factor_i: cumulative
    products instead of a loop over the train. None where that is not finite (a vanishing or
    extreme factor), for the caller to fall back to the loop.
    """
    with np.errstate(all="ignore"):
        products = np.cumprod(factor, axis=1)
        values = products * np.cumsum(forcing / products, axis=1)
    if not np.all(np.isfinite(values)):
        return None
    return np.concatenate([np.zeros((factor.shape[0], 1)), values], axis=1)


def _newton_step(slope, defect, curvature, spacing, active):
    """Newton's correction of every speed, and a bound on what the step leaves.

    δ_{k+1} = slope_k·δ_k − defect_k with δ_0 = 0, and alongside it the Taylor remainder
    ½|f''|δ² plus the central slope's error (~|f''|h·u, generously) times |δ|, carried through
    the same recurrence with |slope|. Closed form where it is well conditioned, else the loop
    along the train (vectorized over the trains).
    """
    factor = np.where(active, slope[:, :-1], 0.0)
    step = _linear_recurrence(np.where(active, factor, 1.0), -defect)
    if step is not None:
        step = np.where(np.concatenate([np.zeros((active.shape[0], 1), bool), active], axis=1),
                        step, 0.0)
        previous = np.abs(step[:, :-1])
        local = curvature[:, :-1] * previous * (0.5 * previous + spacing[:, :-1])
        left = _linear_recurrence(np.abs(slope[:, :-1]), local)
        if left is not None:
            return step, left
    step = np.zeros_like(slope)
    left = np.zeros_like(slope)
    correction = np.zeros(slope.shape[0])
    remainder = np.zeros(slope.shape[0])
    for k in range(slope.shape[1] - 1):
        local = curvature[:, k] * np.abs(correction) * (0.5 * np.abs(correction)
                                                        + spacing[:, k])
        correction = np.where(active[:, k], slope[:, k] * correction - defect[:, k], 0.0)
        remainder = np.abs(slope[:, k]) * remainder + local
        step[:, k + 1], left[:, k + 1] = correction, remainder
    return step, left


def _newton(model, zeta, speeds, rtol, solver=collide, flight=None):
    """Newton iterations on every train at once from the start `speeds` (trains × count).

    Returns the trains and a mask of those that converged (the others are left to the
    impact-by-impact map).
    """
    trains, n = speeds.shape
    out_speeds, out_eps = np.zeros_like(speeds), np.zeros_like(speeds)
    out_tau, out_bound = np.zeros_like(speeds), np.zeros(trains)
    out_captured = np.zeros((trains, n), bool)
    done = np.zeros(trains, bool)
    failed = np.zeros(trains, bool)
    factors = np.array([1.0, 1.0 + SLOPE_STEP, 1.0 - SLOPE_STEP])
    evaluations = 0
    for _ in range(MAX_NEWTON):
        todo = np.flatnonzero(~done & ~failed)
        if todo.size == 0:
            break
        evaluations += 1
        u = speeds[todo]
        # ε·u and τ at u and u(1 ± h), in one call: central slopes and the curvature that
        # bounds what a Newton step leaves.
        probe = solver(model, zeta[todo, None, None], u[:, None, :] * factors[None, :, None])
        rebound = probe.eps * u[:, None, :] * factors[None, :, None]
        # The map is the landing speed of the rebound (the rebound itself under gravity).
        mapped = _landing(flight, todo, rebound)
        spacing = SLOPE_STEP * u
        slope = (mapped[:, 1] - mapped[:, 2]) / (2.0 * spacing)  # d(L(εu))/du
        rebound_slope = (slope if flight is None
                         else (rebound[:, 1] - rebound[:, 2]) / (2.0 * spacing))
        curvature = np.abs(mapped[:, 1] - 2.0 * mapped[:, 0] + mapped[:, 2]) / spacing ** 2
        captured = probe.captured[:, 0]
        # Only impacts up to a train's first capture exist; later entries are not unknowns.
        stops = captured.any(axis=1)
        last = np.where(stops, np.argmax(captured, axis=1), n - 1)
        active = np.arange(n - 1)[None, :] < last[:, None]
        defect = np.where(active, u[:, 1:] - mapped[:, 0, :-1], 0.0)
        defect_size = np.max(np.abs(defect) / u[:, 1:], axis=1, initial=0.0)
        step, left = _newton_step(slope, defect, curvature, spacing, active)
        updated = u + step
        positive = np.all((updated > 0.0) | ~np.concatenate(
            [np.ones((todo.size, 1), bool), active], axis=1), axis=1)
        # Rounding in the central slope (~1e-16/h relative) is covered by the factor 10.
        with np.errstate(invalid="ignore", divide="ignore"):
            bound = 10.0 * np.max(np.where(active, (left[:, 1:] + 1e-9 * np.abs(step[:, 1:]))
                                           / np.abs(updated[:, 1:]), 0.0), axis=1, initial=0.0)
        converged = defect_size <= rtol
        # Accept a small enough step without another evaluation (not next to a capture, where
        # ε has a square-root edge), carrying ε and τ to the new speeds along their slopes.
        accepted = ~converged & (bound <= rtol) & ~stops & positive
        tau = probe.contact_time
        with np.errstate(invalid="ignore"):  # inf − inf at a captured impact, not used
            tau_slope = (tau[:, 1] - tau[:, 2]) / (2.0 * spacing)
        with np.errstate(invalid="ignore"):  # rows with a capture are not accepted below
            accepted_tau = tau[:, 0] + tau_slope * step
        for mask, speed_rows, eps_rows, tau_rows, bound_rows in (
                (converged, u, probe.eps[:, 0], tau[:, 0], defect_size),
                (accepted, updated, (rebound[:, 0] + rebound_slope * step) / updated,
                 accepted_tau, bound)):
            rows = todo[mask]
            out_speeds[rows], out_eps[rows] = speed_rows[mask], eps_rows[mask]
            out_tau[rows], out_bound[rows] = tau_rows[mask], bound_rows[mask]
            out_captured[rows] = captured[mask]
            done[rows] = True
        # A step that makes a speed non-positive cannot be taken: leave that train to the
        # impact-by-impact map.
        failed[todo[~(converged | accepted) & ~positive]] = True
        moving = ~(converged | accepted) & positive
        # Past a capture the guess carries no information: continue geometrically.
        last_moving = last[moving, None]
        ratio = np.clip(np.take_along_axis(probe.eps[moving, 0],
                                           np.maximum(last_moving - 1, 0), axis=1), 1e-3, 1.0)
        anchor = np.take_along_axis(updated[moving], last_moving, axis=1)
        tail = np.arange(n)[None, :] - last_moving
        speeds[todo[moving]] = np.where(tail > 0, anchor * ratio ** np.maximum(tail, 0),
                                        updated[moving])
    speeds_out, eps_out, tau_out, impacts = _cut_at_capture(out_speeds, out_eps, out_tau,
                                                            out_captured)
    return (ImpactTrains(speeds_out, eps_out, tau_out, impacts, out_bound, evaluations, flight),
            done)


def _constant_restitution_speeds(eps, vtilde0, count, flight):
    """Impact speeds of trains with one ε each (Ia, IIa), in closed form.

    Under gravity u_k = ṽ0·ε^k. With a track flight L(r) = r·s/√(1 + c r²) (s = √(down/up),
    c = drag/up), x_k = 1/u_k² obeys the linear recurrence x_{k+1} = a·x_k + b with
    a = 1/(εs)², b = c/s², so x_k = a^k x_0 + b(a^k − 1)/(a − 1).
    """
    powers = np.arange(count, dtype=float)[None, :]
    ratio = 1.0 if flight is None else np.sqrt(flight.down / flight.up)
    with np.errstate(under="ignore"):
        # Without drag the speeds are geometric: u_k = ṽ0·(εs)^k (s = 1 under gravity).
        geometric = vtilde0[:, None] * (eps * ratio)[:, None] ** powers
    if flight is None or not np.any(flight.drag > 0.0):
        return geometric
    log_a = (-2.0 * (np.log(eps) + np.log(ratio)))[:, None]
    b = (flight.drag / flight.up / ratio ** 2)[:, None]
    with np.errstate(all="ignore"):
        # (a^k − 1)/(a − 1) = expm1(k ln a)/expm1(ln a), → k as a → 1.
        growth = np.where(log_a != 0.0, np.expm1(powers * log_a) / np.expm1(log_a), powers)
        inverse_square = np.exp(powers * log_a) / vtilde0[:, None] ** 2 + b * growth
        speeds = 1.0 / np.sqrt(inverse_square)
    speeds[:, 0] = vtilde0
    # A speed too small to represent (or ε = 0) ends the train, as under gravity.
    return np.where((flight.drag > 0.0)[:, None], np.where(np.isfinite(speeds), speeds, 0.0),
                    geometric)


def impact_trains(model, zeta, vtilde0, count, *, start=None, rtol=1e-13, solver=collide,
                  flight=None):
    """Speeds, contact times and intervals of the first `count` impacts of many trains.

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    zeta : array_like, shape (trains,)
        Damping ratio ζ = β/ω0 of each train (dimensionless), >= 0.
    vtilde0 : array_like, shape (trains,)
        First impact speed ṽ0 = v0/v* of each train (dimensionless), > 0.
    count : int
        Number of impacts wanted (fewer happen where the ball is captured first).
    start : array_like, shape (trains, count), optional
        Guess of the speeds relative to the first, u_k/u_0 (e.g. the previous evaluation's).
        Without it the trains are built impact by impact.
    rtol : float, default 1e-13
        Largest accepted relative defect of the speeds in the bounce map.
    solver : callable, default :func:`collide`
        ``solver(model, zeta, vtilde)`` returning a :class:`Collision` (e.g. a surrogate of
        chosen accuracy); the trains are exact for that map.
    flight : TrackFlight, optional
        The flight between impacts of each train (default: gravity's).

    Returns
    -------
    ImpactTrains

    Notes
    -----
    Ia and IIa do not depend on the impact speed [1]_: u_k = ṽ0·ε^k in closed form (with a
    track flight, the closed form of :func:`_constant_restitution_speeds`). For the
    gravity models Newton's method [2]_ solves all the map's equations at once; trains where
    it does not converge in a few iterations are built impact by impact.
    """
    count = int(count)
    if count < 1:
        raise ValueError(f"count must be a positive integer; got {count!r}")
    zeta, vtilde0 = (np.atleast_1d(np.asarray(value, dtype=float)) for value in (zeta, vtilde0))
    zeta, vtilde0 = np.broadcast_arrays(zeta, vtilde0)
    if model not in GRAVITY_MODELS:
        outcome = solver(model, zeta, vtilde0)
        eps = outcome.eps[:, None]
        speeds = _constant_restitution_speeds(outcome.eps, vtilde0, count, flight)
        # ε underflows to 0 for Ia as ζ -> 1⁻: a train ends where the speed vanishes.
        ends = np.zeros((zeta.size, count), bool)
        ends[:, :-1] = speeds[:, 1:] == 0.0
        speeds, restitution, contact_times, impacts = _cut_at_capture(
            speeds, np.broadcast_to(eps, speeds.shape),
            np.broadcast_to(outcome.contact_time[:, None], speeds.shape), ends)
        return ImpactTrains(speeds, restitution, contact_times, impacts, np.zeros(zeta.size), 1,
                            flight)
    if start is None:
        return _sequential(model, zeta, vtilde0, count, solver, flight)
    guess = vtilde0[:, None] * np.asarray(start, dtype=float).reshape(zeta.size, count)
    guess[:, 0] = vtilde0
    usable = np.all(np.isfinite(guess) & (guess > 0.0), axis=1)
    trains, converged = _newton(model, zeta, np.where(usable[:, None], guess, 1.0), rtol,
                                solver, flight)
    converged &= usable
    if converged.all():
        return trains
    rest = np.flatnonzero(~converged)
    fallback = _sequential(model, zeta[rest], vtilde0[rest], count, solver,
                           None if flight is None else flight.take(rest))
    fields = {name: getattr(trains, name).copy() for name in
              ("speeds", "restitution", "contact_times", "impacts", "error_bound")}
    for name in fields:
        fields[name][rest] = getattr(fallback, name)
    return ImpactTrains(**fields, evaluations=trains.evaluations + fallback.evaluations,
                        flight=flight)


def impact_train(model, zeta, vtilde0, count, *, start=None, rtol=1e-13, solver=collide,
                 flight=None):
    """One train: :func:`impact_trains` for a single (ζ, ṽ0), cut at its last impact.

    Parameters are those of :func:`impact_trains` as scalars (`start` of length `count`;
    `flight` a :class:`TrackFlight` of one train).

    Returns
    -------
    ImpactTrain
    """
    trains = impact_trains(model, [zeta], [vtilde0], count,
                           start=None if start is None else np.asarray(start)[None, :],
                           rtol=rtol, solver=solver, flight=flight)
    impacts = int(trains.impacts[0])
    return ImpactTrain(trains.speeds[0, :impacts], trains.restitution[0, :impacts],
                       trains.contact_times[0, :impacts], trains.intervals[0, :impacts - 1],
                       bool(impacts < count or trains.restitution[0, impacts - 1] == 0.0),
                       float(trains.error_bound[0]), trains.evaluations)
