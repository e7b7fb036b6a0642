"""Rolling friction in flight on an incline: a cart decelerates at a_away = g_eff + f moving
away from the bumper and accelerates at a_toward = g_eff − f on its way back.

Both g_eff (the mean acceleration of the flights: g·sin θ on an incline, with the scene's prior
from the stated angle, or held at a stated g_eff) and the friction deceleration f ≥ 0 are
fitted; the rung ``constant+friction`` is tried on cart and incline scenes
(:attr:`dashpot.scene.Scene.tries_friction`). From impact times alone f is nearly degenerate
with the restitution (both scale each flight's speed): the prior on g_eff and a known first
impact speed separate them. Flight law: :func:`dashpot.physics.flight.track_flight` (the
incline row of :mod:`dashpot.physics.flight`, S. P. Bartz).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .base import Column, DerivedQuantity, EffectParameter, EffectSetup, FlightEffect

__all__ = ["EFFECT_SPECS", "FRICTION_START", "FRICTION_UPPER"]

FRICTION_START, FRICTION_UPPER = 1e-3, 0.5
"""Start of f and its upper bound, as fractions of g_eff (a_toward = g_eff − f > 0)."""


def _enter(track, g_eff, friction):
    return dataclasses.replace(track, gravity=g_eff, away=track.away + friction,
                               toward=track.toward + friction)


def _setup(scene, g, requested):
    if not requested:
        return None
    known = scene.flight_acceleration
    exact = known.uncertainty is None
    fitted = "rolling friction in flight: a_away = g_eff + friction, a_toward = g_eff - friction "
    return EffectSetup(
        (Column("g_eff", known.value, 0.5 * known.value, 2.0 * known.value,
                prior=known.uncertainty, fixed=exact, reason="the scene's g_eff"),
         # Started off zero: the fast optimizer's difference steps are relative to the value.
         Column("friction", FRICTION_START * known.value, 0.0, FRICTION_UPPER * known.value)),
        fitted + "fitted" + (" (g_eff fixed at the scene's)" if exact
                             else " (the scene's g_eff a prior)"),
        model_note=fitted + "fitted" + ("" if exact
                                        else " (the scene's incline angle a prior on g_eff)"))


# The two accelerations of the flight, reported by the dashpot models' fits with friction.
_ACCELERATIONS = (
    DerivedQuantity("a_away", "m/s^2", "a_away = g_eff + friction",
                    lambda p: p["g_eff"] + p["friction"],
                    lambda p: {"g_eff": 1.0, "friction": 1.0}),
    DerivedQuantity("a_toward", "m/s^2", "a_toward = g_eff - friction",
                    lambda p: p["g_eff"] - p["friction"],
                    lambda p: {"g_eff": 1.0, "friction": -1.0}))


def _tried(scene):
    return bool(getattr(scene, "tries_friction", False))


def _speed_start(launch, landing, duration, columns):
    """Start values of g_eff and f from measured flights (None unless they give them).

    A flight after rebound speed v_n (decelerating at a_away = g_eff + f) returns at
    u_{n+1} = ρ·v_n, ρ = √(a_toward/a_away), and lasts T_n = v_n/a_away + u_{n+1}/a_toward
    = v_n(1 + ρ)/(ρ·a_away) (:func:`dashpot.physics.flight.track_flight` without drag): ρ
    and K = T_n/v_n by least squares through the origin over the flights, then
    a_away = (1 + ρ)/(ρK), g_eff = a_away(1 + ρ²)/2 and f = a_away(1 − ρ²)/2, f kept between
    its own start value and half its upper bound (the fit starts inside them)."""
    ratio = float(np.sum(landing * launch) / np.sum(launch * launch))
    per_speed = float(np.sum(duration * launch) / np.sum(launch * launch))
    if not (0.0 < ratio and per_speed > 0.0):
        return None
    ratio = min(ratio, 1.0)
    away = (1.0 + ratio) / (ratio * per_speed)
    g_eff = 0.5 * away * (1.0 + ratio * ratio)
    _, low, high = columns["g_eff"]
    if not low < g_eff < high:
        return None
    start, _, upper = columns["friction"]
    friction = float(np.clip(0.5 * away * (1.0 - ratio * ratio), start, 0.5 * upper))
    return {"g_eff": g_eff, "friction": friction}


EFFECT_SPECS = (FlightEffect(
    "friction", "∓f against the motion, g_eff fitted (rolling friction on an incline)",
    (EffectParameter("g_eff", "m/s^2", "mean acceleration of the flights"),
     EffectParameter("friction", "m/s^2", "friction deceleration of the flights")),
    _enter,
    "S. P. Bartz, \"Coefficient of restitution of a linear dashpot on a rigid surface\", "
    "section \"Modeling experimental data\"",
    setup=_setup,
    tried=_tried,
    caveat="friction from impact times alone is nearly degenerate with the restitution (both "
           "scale each flight's speed); the scene's prior on g_eff and a known first impact "
           "speed are what separate them",
    meaning="rolling friction",
    derived=_ACCELERATIONS,
    stepped=_tried,
    speed_start=_speed_start),)
