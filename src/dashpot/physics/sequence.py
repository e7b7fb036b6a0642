"""Successive bounces of a ball (or cart) until capture, in SI units.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   section "Modeling experimental data" (recursive use of each model).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validation import check_model, check_nonnegative, check_positive
from .flight import drag_flight
from .models import MODELS, collide

__all__ = ["BounceSequence", "bounce_sequence"]


@dataclass(frozen=True)
class BounceSequence:
    """A train of impacts predicted by one contact model (SI units).

    Attributes
    ----------
    model : str
    impact_times : ndarray
        Time of each impact in s, the first at t = 0.
    impact_speeds : ndarray
        Normal impact speed of each impact in m/s.
    restitution : ndarray
        ε of each impact (dimensionless); 0 for a final captured impact.
    contact_durations : ndarray
        Contact duration of each impact in s (per-model convention, see ``collide``); inf for
        a final captured impact.
    flight_times : ndarray
        Free flight after each rebound in s (length: number of impacts − 1).
    intervals : ndarray
        Time from each impact to the next in s, contact plus flight (length: impacts − 1).
    stop_reason : str
        "captured" (the last impact does not rebound), "v_min" (the next impact speed would be
        below `v_min`) or "n_max" (the requested number of impacts was reached).
    """

    model: str
    impact_times: np.ndarray
    impact_speeds: np.ndarray
    restitution: np.ndarray
    contact_durations: np.ndarray
    flight_times: np.ndarray
    intervals: np.ndarray
    stop_reason: str


def bounce_sequence(model, *, beta, omega0, g, v0, n_max=200, v_min=0.0, method="exact",
                    rtol=None, drag=0.0):
    """Impact times, speeds, contact durations and flight times of successive bounces.

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    beta : float
        Damping rate β = γ/(2m) in 1/s, >= 0.
    omega0 : float
        Undamped angular frequency ω0 = √(k/m) of the contact in rad/s, > 0.
    g : float
        Acceleration driving the ball back to the surface in m/s² (g·sin θ on an incline), > 0.
    v0 : float
        Speed of the first impact in m/s, > 0.
    n_max : int, default 200
        Largest number of impacts returned.
    v_min : float, default 0
        Stop before an impact slower than this (m/s).
    method, rtol
        Passed to :func:`collide`.
    drag : float, default 0
        Quadratic air-drag constant k_d in 1/m (:mod:`dashpot.physics.flight`; `g` is then
        the effective gravity, buoyancy and added mass included). With drag the ball leaves
        at u_n = ε_n·v_n, flies T(u_n) and lands at v_{n+1} = L(u_n) < u_n; drag during the
        millisecond of contact is neglected. 0 gives the gravity-only train exactly.

    Returns
    -------
    BounceSequence

    Notes
    -----
    Per impact n at speed v_n the next impact speed is v_{n+1} = ε(ζ, v_n/v*)·v_n, with v* = g/ω0:
    the rebound speed at ξ = 0 for Ia, Ib and the hybrid, the release speed at F = 0 for IIa and
    IIb (the paper takes it as the next impact speed). The interval is the contact duration plus
    the flight 2v_{n+1}/g; for the hybrid the contact duration already holds the climb back to
    z = R, τ_IIb + (vf − v1)/g [1]_.
    """
    model = check_model(model, MODELS)
    beta = float(check_nonnegative("beta", beta))
    omega0 = float(check_positive("omega0", omega0))
    g = float(check_positive("g", g))
    v0 = float(check_positive("v0", v0))
    v_min = float(check_nonnegative("v_min", v_min))
    drag = float(check_nonnegative("drag", drag))
    if int(n_max) != n_max or n_max < 1:
        raise ValueError(f"n_max must be a positive integer; got {n_max!r}")
    zeta = beta / omega0
    v_star = g / omega0
    speeds, restitution, contacts, drag_flights = [], [], [], []
    speed = v0
    stop_reason = "n_max"
    # The map is sequential: each impact speed depends on the previous rebound.
    for _ in range(int(n_max)):
        outcome = collide(model, zeta, speed / v_star, method=method, rtol=rtol)
        speeds.append(speed)
        restitution.append(float(outcome.eps))
        contacts.append(float(outcome.contact_time) / omega0)
        if outcome.captured:
            stop_reason = "captured"
            break
        speed = float(outcome.eps) * speed
        if drag:
            flight = drag_flight(speed, g, drag)
            drag_flights.append(float(flight.duration))
            speed = float(flight.landing_speed)
        if speed < v_min or speed == 0.0:
            stop_reason = "v_min"
            break
    speeds = np.array(speeds)
    restitution = np.array(restitution)
    contacts = np.array(contacts)
    # With drag, the flight after the last impact was drawn only for the v_min check.
    flights = np.array(drag_flights[:speeds.size - 1]) if drag else 2.0 * speeds[1:] / g
    intervals = contacts[:-1] + flights
    times = np.concatenate([[0.0], np.cumsum(intervals)])
    return BounceSequence(model=model, impact_times=times, impact_speeds=speeds,
                          restitution=restitution, contact_durations=contacts,
                          flight_times=flights, intervals=intervals, stop_reason=stop_reason)
