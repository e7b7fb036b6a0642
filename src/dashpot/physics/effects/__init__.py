"""Effects on the flight between impacts beyond gravity, as entries of a registry.

Each effect changes the coefficients of the closed-form flight law
:func:`dashpot.physics.flight.track_flight` (deceleration a_up away from the surface,
acceleration a_down back, quadratic drag k_d; :class:`Track`), and the flight of a fit is that
law with every effect it carries entered in the registry's order (:func:`flight_map`; gravity's
flight where it carries none). The registry :data:`FLIGHT_EFFECTS` lists every effect with its
parameters, how a scene sets them up in a fit, and its rung on the selection ladder.

========  =====================================  ===================  ====================
effect    acceleration it adds                   parameters           rung
========  =====================================  ===================  ====================
drag      −k_d·v|v|                              k_d (1/m)            ``constant+drag``
friction  −f away, +f back; g_eff fitted         g_eff, f (m/s²)      ``constant+friction``
========  =====================================  ===================  ====================

Layout: one module per effect, each defining its effects as :class:`FlightEffect` specs in a
tuple ``EFFECT_SPECS``; :data:`FLIGHT_EFFECTS` is built from the modules listed in
``_MODULES`` (:mod:`.base` holds the types and knows no effect).

A new effect is one new module here that defines ``EFFECT_SPECS = (FlightEffect(...),)`` (its
name, the acceleration it adds, its parameters with units and default bounds and start, the
vectorized ``enter(track, *params) -> Track``, a reference; where it needs them the ``setup``
of its columns from scene keys (start, bounds, a prior or a fixed value, the fit's note),
``in_scene`` where a scene puts it in every fit, ``tried`` where only some scenes' ladders try
its rung, the law its rung ``extends`` and the verdict's ``caveat``; for the dashpot models'
fits its plain-words ``meaning``, the ``derived`` quantities they report and where they try it
as a nested step, ``stepped``), plus its module's name in ``_MODULES``. The noise fits
(:func:`dashpot.fit.fit_noise_model`, ``effects=(name,)``) then fit its parameters as columns
of the step map, every scene's noise fits (:func:`dashpot.fit.noise_scene.fit_noise_scene`) fit
its rung, and the noise selection (:mod:`dashpot.noise_selection`) compares the rung with the
law it extends; the dashpot models' fits (:func:`dashpot.fit.fit_model`, ``effects=(name,)``,
and :func:`dashpot.fit.fit_joint` where the scene puts it in every fit) fit its columns, their
trains flying the :class:`Track` it enters (:func:`flight_track`). :func:`register` adds an
effect at run time, and all of those see it.
"""

from __future__ import annotations

from ..._registry import LiveMapping
from ..._registry import unregister as _unregister
from ..flight import gravity_flight, track_flight
from . import drag as _drag
from . import friction as _friction
from .base import Column, DerivedQuantity, EffectParameter, EffectSetup, FlightEffect, Track

__all__ = ["FLIGHT_EFFECTS", "EFFECT_PARAMETERS", "Column", "DerivedQuantity", "EffectParameter",
           "EffectSetup", "FlightEffect", "Track", "flight_map", "flight_track", "register",
           "unregister"]

_MODULES = (_drag, _friction)
"""The modules whose ``EFFECT_SPECS`` make the registry, in its order (the order of the fit's
columns where a fit carries several)."""


def _check(effect, known):
    """ValueError where `effect` cannot join a registry holding the effects `known`."""
    if not isinstance(effect, FlightEffect):
        raise ValueError(f"a flight effect must be a FlightEffect; got {effect!r}")
    if effect.name in known:
        raise ValueError(f"flight effect {effect.name!r} is already registered")
    if "+" in effect.name or not effect.name:
        raise ValueError(f"flight effect name {effect.name!r} must be non-empty, without '+'")
    if not effect.parameters or not callable(effect.enter):
        raise ValueError(f"flight effect {effect.name!r} needs parameters and an enter function")
    taken = {name for other in known.values()
             for name in (*other.parameter_names, *(q.name for q in other.derived))}
    for q in effect.derived:
        if q.name in taken or q.name in effect.parameter_names:
            raise ValueError(f"flight effect {effect.name!r}: derived quantity {q.name!r} is "
                             f"already a parameter or another effect's")
    for p in effect.parameters:
        if p.name in taken:
            raise ValueError(f"flight effect {effect.name!r}: parameter {p.name!r} is another "
                             f"effect's")
        if not p.lower <= p.start <= p.upper:
            raise ValueError(f"flight effect {effect.name!r}: start of {p.name} outside its "
                             f"bounds [{p.lower}, {p.upper}]")
    return effect


def _registry(modules):
    effects = {}
    for module in modules:
        for effect in module.EFFECT_SPECS:
            effects[effect.name] = _check(effect, effects)
    return effects


FLIGHT_EFFECTS = _registry(_MODULES)
"""Every flight effect by name, in the order a fit's columns take them."""


EFFECT_PARAMETERS = LiveMapping(lambda: {
    parameter.name: (parameter.unit, parameter.description)
    for effect in FLIGHT_EFFECTS.values() for parameter in effect.parameters})
"""``name -> (unit, description)`` of every registered effect's parameters (read live)."""


def register(effect):
    """Add `effect` to :data:`FLIGHT_EFFECTS` at run time (an effect of its own module joins at
    import).

    Parameters
    ----------
    effect : FlightEffect
        A name not yet registered, parameters no other effect has, start values inside their
        bounds.

    Returns
    -------
    FlightEffect
        `effect`, now ``FLIGHT_EFFECTS[effect.name]``: the noise fits, the scenes' ladders and
        the noise selection see it from now on.

    Raises
    ------
    ValueError
        A name already taken or an incomplete effect.
    """
    FLIGHT_EFFECTS[effect.name] = _check(effect, FLIGHT_EFFECTS)
    return effect


def unregister(name):
    """Remove an effect added by :func:`register`; the modules' effects stay.

    Raises
    ------
    ValueError
        `name` is not registered, or is one of the modules' effects.
    """
    _unregister(FLIGHT_EFFECTS, name,
                {effect.name for module in _MODULES for effect in module.EFFECT_SPECS},
                "flight effect")


def flight_track(effects, g, columns):
    """The coefficients of the flight law of a fit: :class:`Track` at g with `effects` entered
    in order.

    Parameters
    ----------
    effects : sequence of FlightEffect
        The effects the fit carries, in the registry's order.
    g : float
        Acceleration towards the surface without them, in m/s².
    columns : dict of str -> float or ndarray
        Every effect's parameters by name (arrays: one value per parameter set).

    Returns
    -------
    Track
        Gravity's (g both ways, no drag) where `effects` is empty.
    """
    track = Track(g)
    for effect in effects:
        track = effect.enter(track, *(columns[name] for name in effect.parameter_names))
    return track


def flight_map(effects, g, columns):
    """The flight of a fit: ``flight(v) -> Flight`` with `effects` entered in order.

    Parameters
    ----------
    effects, g, columns
        As for :func:`flight_track`.

    Returns
    -------
    callable
        ``flight(v)`` of launch speeds v in m/s: :func:`~dashpot.physics.flight.gravity_flight`
        at g without effects, else :func:`~dashpot.physics.flight.track_flight` at the
        coefficients the effects give (:func:`flight_track`).
    """
    if not effects:
        return lambda v: gravity_flight(v, g)
    track = flight_track(effects, g, columns)
    up, down, drag = track.up, track.down, track.drag
    return lambda v: track_flight(v, up, down, drag)
