"""Bounce trains of a ball in air: the contact models' restitution with drag-true flights.

A light ball (a ping-pong ball) loses speed to air drag in flight: its flights are shorter and
it lands slower than it left, so that successive intervals shrink faster than ε alone makes
them. :func:`air_drag` gives the drag constant and effective gravity of such a train (from k_d
or from the ball), which :func:`dashpot.bounce_sequence` (argument ``drag``) then draws with
drag-true flights.
"""

from __future__ import annotations

from .._validation import check_nonnegative, check_positive
from ..physics.flight import drag_constant, effective_gravity, terminal_speed
from ..scene import DEFAULT_AIR_DENSITY, DEFAULT_DRAG_COEFFICIENT

__all__ = ["air_drag"]

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
