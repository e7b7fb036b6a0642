"""Bounce trains of a ball in air: the contact models' restitution with drag-true flights.

A light ball (a ping-pong ball) loses speed to air drag in flight: its flights are shorter and
it lands slower than it left, so that successive intervals shrink faster than ε alone makes
them. :func:`drag_bounce_sequence` draws such a train: at impact n with speed v_n the contact
model gives ε_n and the contact duration τ_n (as in :func:`dashpot.bounce_sequence`), the ball
leaves at u_n = ε_n·v_n, and its flight under gravity and quadratic drag
(:func:`dashpot.physics.flight.drag_flight`) lasts T(u_n) and ends at the next impact speed
v_{n+1} = L(u_n). Drag during the contact itself (a millisecond) is neglected. Without drag
(k_d = 0) the train is exactly that of :func:`dashpot.bounce_sequence`.
"""

from __future__ import annotations

import numpy as np

from .._validation import check_model, check_nonnegative, check_positive
from ..physics.flight import drag_constant, drag_flight, effective_gravity, terminal_speed
from ..physics.models import MODELS, collide
from ..physics.sequence import BounceSequence
from ..scene import DEFAULT_AIR_DENSITY, DEFAULT_DRAG_COEFFICIENT

__all__ = ["air_drag", "drag_bounce_sequence"]

BALL_KEYS = ("mass", "diameter", "drag_coefficient", "air_density")


def air_drag(g, *, drag=None, ball=None):
    """The drag constant and effective gravity of a synthetic train, from k_d or from a ball.

    Parameters
    ----------
    g : float
        Acceleration towards the surface in m/s²: the effective gravity itself when `drag` is
        given, the local gravity when `ball` is (buoyancy and added mass then lower it).
    drag : float, optional
        Drag constant k_d in 1/m.
    ball : dict, optional
        ``mass`` (kg) and ``diameter`` (m) of the ball, ``drag_coefficient`` (default 0.45)
        and ``air_density`` (kg/m³, default 1.204): k_d = ρ C_d A/(2 m_eff) and g_eff from
        :mod:`dashpot.physics.flight`.

    Returns
    -------
    dict or None
        None without drag (neither given); else ``drag_constant`` (1/m), ``effective_gravity``
        (m/s²), ``terminal_speed`` (m/s), ``gravity`` (the `g` given), and the ball's keys.

    Raises
    ------
    ValueError
        Both or a bad value given, an unknown ball key, or a ball no denser than the air.
    """
    g = float(check_positive("g", g))
    if drag is not None and ball is not None:
        raise ValueError("give either drag (the drag constant k_d) or ball (its mass, "
                         "diameter, ...), not both")
    if drag is None and ball is None:
        return None
    if drag is not None:
        k_d, g_eff, out = float(check_nonnegative("drag", drag)), g, {}
    else:
        unknown = sorted(set(ball) - set(BALL_KEYS))
        if unknown or not {"mass", "diameter"} <= set(ball):
            raise ValueError(f"ball needs mass and diameter, and may give drag_coefficient and "
                             f"air_density; got {sorted(ball)!r}")
        out = {"mass": ball["mass"], "diameter": ball["diameter"],
               "drag_coefficient": ball.get("drag_coefficient", DEFAULT_DRAG_COEFFICIENT.value),
               "air_density": ball.get("air_density", DEFAULT_AIR_DENSITY.value)}
        out = {key: float(value) for key, value in out.items()}
        k_d = float(drag_constant(out["mass"], out["diameter"], out["drag_coefficient"],
                                  out["air_density"]))
        g_eff = float(effective_gravity(g, out["mass"], out["diameter"], out["air_density"]))
        if g_eff <= 0.0:
            raise ValueError(f"a ball of {out['mass']:g} kg and {out['diameter']:g} m is no "
                             f"denser than air of {out['air_density']:g} kg/m³")
    return {"drag_constant": k_d, "effective_gravity": g_eff,
            "terminal_speed": float(terminal_speed(g_eff, k_d)), "gravity": g, **out}


def drag_bounce_sequence(model, *, beta, omega0, g, drag, v0, n_max=200, v_min=0.0,
                         method="exact", rtol=None):
    """Impact times, speeds, contact durations and flights of a ball bouncing in air.

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    beta : float
        Damping rate β in 1/s, >= 0.
    omega0 : float
        Undamped angular frequency ω0 of the contact in rad/s, > 0.
    g : float
        Effective gravity g_eff in m/s² (buoyancy and added mass included), > 0; it also sets
        the contact's v* = g/ω0.
    drag : float
        Drag constant k_d in 1/m, >= 0 (0: :func:`dashpot.bounce_sequence` exactly).
    v0 : float
        Speed of the first impact in m/s, > 0.
    n_max, v_min, method, rtol
        As in :func:`dashpot.bounce_sequence`.

    Returns
    -------
    BounceSequence
        ``flight_times`` T(u_n) from launch at u_n = ε_n v_n to the next impact; each next
        impact speed is the landing speed L(u_n).
    """
    model = check_model(model, MODELS)
    beta = float(check_nonnegative("beta", beta))
    omega0 = float(check_positive("omega0", omega0))
    g = float(check_positive("g", g))
    drag = float(check_nonnegative("drag", drag))
    v0 = float(check_positive("v0", v0))
    v_min = float(check_nonnegative("v_min", v_min))
    if int(n_max) != n_max or n_max < 1:
        raise ValueError(f"n_max must be a positive integer; got {n_max!r}")
    zeta, v_star = beta / omega0, g / omega0
    speeds, restitution, contacts, flights = [], [], [], []
    speed, stop_reason = v0, "n_max"
    # Sequential: each impact speed is the landing speed of the previous flight.
    for _ in range(int(n_max)):
        outcome = collide(model, zeta, speed / v_star, method=method, rtol=rtol)
        speeds.append(speed)
        restitution.append(float(outcome.eps))
        contacts.append(float(outcome.contact_time) / omega0)
        if outcome.captured:
            stop_reason = "captured"
            break
        flight = drag_flight(float(outcome.eps) * speed, g, drag)
        landing = float(flight.landing_speed)
        if landing < v_min or landing == 0.0:
            stop_reason = "v_min"
            break
        flights.append(float(flight.duration))
        speed = landing
    contacts = np.array(contacts)
    # At n_max the last impact's flight was drawn only for the v_min check.
    flights = np.array(flights[:len(speeds) - 1])
    intervals = contacts[:-1] + flights
    return BounceSequence(model=model, impact_times=np.concatenate([[0.0], np.cumsum(intervals)]),
                          impact_speeds=np.array(speeds), restitution=np.array(restitution),
                          contact_durations=contacts, flight_times=flights, intervals=intervals,
                          stop_reason=stop_reason)
