"""Whole impact trains from the surrogate tables in one compiled pass (the fast and standard
levels' train solver).

:func:`dashpot.physics.train.impact_trains` solves a train with a few vectorized calls of the
collision map (Newton's method over all impacts at once). With the surrogate as the map each
call still costs ~0.2 ms of numpy overhead plus ~1 µs per point, and a fit needs dozens of
trains. Here the bounce map u_{k+1} = ε(u_k)·u_k is applied impact by impact, as in the paper
[1]_, in a loop compiled with numba, evaluating the same quintic-spline tables inline: about
0.1 µs per impact, so a whole train of 40 impacts costs less than one numpy call.

The numbers are those of :func:`dashpot.physics.surrogate.surrogate_collide` to rounding (the
same tables, coordinates, formulas and compiled spline helpers). A train that reaches
a point the table does not serve (ζ outside the table, ṽ above it, or the thin band around the
critical speed where the exact solver decides capture) is computed instead by
:func:`impact_trains` with ``surrogate_collide`` as its map, which passes those points to the
exact solver: the trains are always those of the surrogate's map.

A :class:`~dashpot.physics.train.TrackFlight` (air drag, a cart's two accelerations) enters
the loop as the landing speed L(r) = r·√(down/up)/√(1 + drag·r²/up) of each rebound r
(:func:`dashpot.physics.flight.track_flight`); the intervals follow from the trains
(:attr:`~dashpot.physics.train.ImpactTrains.intervals`).

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   section "Modeling experimental data" (the bounce map).
.. [2] C. de Boor, *A Practical Guide to Splines*, rev. ed., Springer (2001), ch. IX (B-splines).
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

from .surrogate import (CAPTURE_BAND, S_MIN, ZETA_MAX, ZETA_MIN, _add_patch, _quintic_weights,
                        _spline_1d_at, load_surrogate, surrogate_collide)
from .train import ImpactTrains, impact_trains

__all__ = ["surrogate_trains"]

# Row outcomes of the compiled loop.
_DONE, _OFF_TABLE = 0, 1


@numba.njit(cache=True)
def _trains_kernel(zeta, vtilde0, count, coef, x_start, x_step, y_start, y_step, crit_coef,
                   crit_start, crit_step, zeta_max, y_max, is_ib, root_capture, up, down,
                   drag, has_flight):
    """The bounce map applied impact by impact to every train (see the module docstring).

    `up`, `down`, `drag` are the trains' flights (used where `has_flight`).

    Returns speeds, restitution, contact times (trains × count), the number of impacts of each
    train, and each train's outcome (_DONE, or _OFF_TABLE for the caller to recompute).
    """
    trains = zeta.size
    speeds = np.zeros((trains, count))
    restitution = np.zeros((trains, count))
    contact_times = np.zeros((trains, count))
    impacts = np.full(trains, count, dtype=np.int64)
    outcome = np.full(trains, _DONE, dtype=np.int64)
    nx, ny = coef.shape[0], coef.shape[1]
    wx = np.empty(6)
    wy = np.empty(6)
    fields = np.empty(2)  # logit of ε (less ½ ln s where ε ∝ √s) and ln τ
    for row in range(trains):
        z = zeta[row]
        if not (ZETA_MIN <= z <= zeta_max):
            outcome[row] = _OFF_TABLE
            continue
        # Per train: the ζ coordinate, its weights and the critical speed.
        x = math.log(z) - 0.5 * math.log1p(-z * z) if is_ib else math.log(z)
        log_critical = _spline_1d_at(crit_coef, crit_start, crit_step, x, wy)
        cell_x = _quintic_weights((x - x_start) / x_step, nx - 4, wx)
        if has_flight:
            landing_ratio = math.sqrt(down[row] / up[row])
            drag_over_up = drag[row] / up[row]
        speed = vtilde0[row]
        for k in range(count):
            s = math.log(speed) - log_critical
            speeds[row, k] = speed
            if s < -CAPTURE_BAND:
                # Well below the critical speed: captured (ε = 0, no release).
                contact_times[row, k] = math.inf
                impacts[row] = k + 1
                break
            y = math.log(s) + s if s >= S_MIN else math.inf
            if y > y_max:
                outcome[row] = _OFF_TABLE
                break
            cell_y = _quintic_weights((y - y_start) / y_step, ny - 4, wy)
            fields[0] = fields[1] = 0.0
            _add_patch(coef, cell_x, wx, cell_y, wy, fields)
            logit = fields[0] + 0.5 * math.log(s) if root_capture else fields[0]
            eps = 1.0 / (1.0 + math.exp(-logit))
            restitution[row, k] = eps
            contact_times[row, k] = math.exp(fields[1])
            speed = eps * speed
            if has_flight:
                speed = speed * landing_ratio / math.sqrt(1.0 + drag_over_up * speed * speed)
            if speed == 0.0:
                # ε·u underflowed: the train ends here, as in the impact-by-impact map.
                impacts[row] = k + 1
                break
    return speeds, restitution, contact_times, impacts, outcome


def surrogate_trains(model, zeta, vtilde0, count, *, level="fast", start=None, rtol=None,
                     directory=None, flight=None):
    """:func:`~dashpot.physics.train.impact_trains` with the surrogate of `level` as the map.

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    zeta : array_like, shape (trains,)
        Damping ratio ζ (dimensionless), >= 0.
    vtilde0 : array_like, shape (trains,)
        First impact speed ṽ0 = v0/v* (dimensionless), > 0.
    count : int
        Number of impacts wanted.
    level : {"fast", "standard"}
        Surrogate table (:data:`dashpot.physics.surrogate.LEVELS`).
    start : array_like, optional
        Speeds relative to the first, for the Newton solve of the trains the tables do not
        serve (see :func:`impact_trains`); unused otherwise.
    rtol : float, optional
        Newton's tolerance for those trains (default that of :func:`impact_trains`).
    directory : path-like, optional
        Cache directory of the tables (see :func:`~dashpot.physics.surrogate.load_surrogate`).
    flight : TrackFlight, optional
        The flight between impacts of each train (default: gravity's).

    Returns
    -------
    ImpactTrains
        ``error_bound`` is 0 for the trains computed here (the map is applied exactly);
        ``evaluations`` counts the compiled pass as one.
    """
    solver = functools.partial(surrogate_collide, level=level, directory=directory)
    options = {} if rtol is None else {"rtol": rtol}
    options["flight"] = flight
    zeta, vtilde0 = (np.atleast_1d(np.asarray(value, dtype=float)) for value in (zeta, vtilde0))
    if zeta.shape != vtilde0.shape:
        zeta, vtilde0 = np.broadcast_arrays(zeta, vtilde0)
    if model not in ZETA_MAX:
        return impact_trains(model, zeta, vtilde0, count, solver=solver, **options)
    count = int(count)
    if count < 1:
        raise ValueError(f"count must be a positive integer; got {count!r}")
    table = load_surrogate(model, level, directory=directory)
    speeds, restitution, contact_times, impacts, outcome = _trains_kernel(
        np.ascontiguousarray(zeta), np.ascontiguousarray(vtilde0), count, table.coef,
        table.x_start, table.x_step, table.y_start, table.y_step, table.critical_coef,
        table.critical_start, table.critical_step, ZETA_MAX[model], table.y_max,
        model == "Ib", model != "IIb", *_flight_arrays(flight))
    error_bound = np.zeros(zeta.size)
    evaluations = 1
    rest = np.flatnonzero(outcome != _DONE)
    if rest.size:
        if start is not None:
            start = np.broadcast_to(np.asarray(start, dtype=float),
                                    (zeta.size, count))[rest]
        options["flight"] = None if flight is None else flight.take(rest)
        fallback = impact_trains(model, zeta[rest], vtilde0[rest], count, start=start,
                                 solver=solver, **options)
        for name, array in (("speeds", speeds), ("restitution", restitution),
                            ("contact_times", contact_times), ("impacts", impacts),
                            ("error_bound", error_bound)):
            array[rest] = getattr(fallback, name)
        evaluations += fallback.evaluations
    return ImpactTrains(speeds, restitution, contact_times, impacts, error_bound, evaluations,
                        flight)


_NO_FLIGHT = np.zeros(0)  # the kernel's flight arrays where it flies gravity's flight


def _flight_arrays(flight):
    """The kernel's flight arguments: contiguous (up, down, drag) and whether to use them
    (empty arrays, not read, under gravity: nothing allocated per call)."""
    if flight is None:
        return _NO_FLIGHT, _NO_FLIGHT, _NO_FLIGHT, False
    return (*(np.ascontiguousarray(value, dtype=float)
              for value in (flight.up, flight.down, flight.drag)), True)
