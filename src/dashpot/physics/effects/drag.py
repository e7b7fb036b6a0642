"""Quadratic air drag in flight: a deceleration k_d·v|v| against the motion.

With the ball's mass and diameter in the scene, k_d = ρC_dA/(2m_eff) and the buoyancy and added
mass of g_eff come from them (:attr:`dashpot.scene.Scene.drag`, :func:`~dashpot.physics.flight.
drag_constant`, :func:`~dashpot.physics.flight.effective_gravity`): every fit then carries k_d,
under the scene's prior from C_d (or held fixed where the scene states it exactly), and there
is no rung. Without them the rung ``constant+drag`` fits k_d free (≥ 0), and drag is then
degenerate with a speed-dependent restitution (ε = e0 − c·v² fits about as well). The flight
law with drag is :func:`dashpot.physics.flight.track_flight` (closed forms of Timmerman & van
der Weele).
"""

from __future__ import annotations

import dataclasses

from .base import Column, EffectParameter, EffectSetup, FlightEffect

__all__ = ["DRAG_START", "DRAG_UPPER", "EFFECT_SPECS"]

DRAG_UPPER, DRAG_START = 10.0, 0.05
"""Upper bound of a free k_d in 1/m (a terminal speed of 1 m/s at g) and its start (a stencil
needs room above the bound at 0)."""


def _enter(track, drag):
    return dataclasses.replace(track, drag=track.drag + drag)


def _setup(scene, g, requested):
    drag = scene.drag if getattr(scene, "needs_drag", False) else None
    if drag is not None:
        known = drag.drag_constant
        bounds = (0.0, max(DRAG_UPPER, 10.0 * known.value))
        if known.uncertainty is None:
            return EffectSetup((Column("k_d", known.value, *bounds, fixed=True,
                                       reason="drag constant known exactly from the scene"),),
                               f"air drag: k_d = {known.value:.4g} 1/m from the scene, held "
                               f"fixed; g_eff = {g:.5g} m/s²", model_note="")
        # A dashpot model's fit has the scene's flight notes on drag already
        # (:func:`dashpot.fit.data.flight_notes`): no note of its own.
        return EffectSetup((Column("k_d", known.value, *bounds, prior=known.uncertainty),),
                           f"air drag: k_d fitted with the scene's prior {known.value:.4g} ± "
                           f"{known.uncertainty:.2g} 1/m (C_d prior); g_eff = {g:.5g} m/s²",
                           model_note="")
    if not requested:
        return None
    free = ("air drag: k_d fitted free (>= 0), the scene gives no mass and diameter; without "
            "them drag is degenerate with a speed-dependent restitution (e = e0 - c v^2 fits "
            "about as well)")
    return EffectSetup((Column("k_d", DRAG_START, 0.0, DRAG_UPPER),),
                       free + ": its rung says whether the data need either, not which",
                       model_note=free)


def _carried(fit, name):
    k_d = fit.estimates.get("k_d")
    if k_d is None or k_d.status != "prior":
        return None
    return (f"air drag in every fit with the scene's C_d prior (k_d = {k_d.value:.3g} ± "
            f"{k_d.stderr:.2g} 1/m in {name})")


EFFECT_SPECS = (FlightEffect(
    "drag", "−k_d·v|v| (quadratic air drag)",
    (EffectParameter("k_d", "1/m", "quadratic drag constant of the flight",
                     0.0, DRAG_UPPER, DRAG_START, detail="deceleration k_d v^2",
                     # about the C_d prior's sd for a ping-pong ball (0.02 1/m)
                     step=1e-2),),
    _enter,
    "P. Timmerman and J. P. van der Weele, Am. J. Phys. 67, 538-546 (1999)",
    setup=_setup,
    in_scene=lambda scene: bool(getattr(scene, "needs_drag", False)),
    caveat="drag without the ball's mass and diameter is degenerate with a speed-dependent "
           "restitution (e = e0 - c v^2 fits about as well)",
    carried=_carried,
    meaning="air drag"),)
