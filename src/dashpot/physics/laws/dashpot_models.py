"""The five dashpot models (Ia, Ib, IIa, IIb, hybrid) as restitution laws with a contact
duration.

ε from :func:`dashpot.physics.models.collide` (exact method) at ṽ = v/v*, v* = g/ω0 [1]_. The
slope dε/dṽ is analytic: the rebound state w at the end condition τ(ṽ) is differentiated
implicitly, with the trajectory's sensitivity to ṽ equal to −S(t) (the fundamental solution of
:mod:`dashpot.physics.contact`): Ib: dτ/dṽ = S/w, dw/dṽ = −(1 + 2ζw)·S/w − S'; IIb (released
at F = 0 with ξ'' = −1): dτ/dṽ = (S + 2ζS')/(w − 2ζ), dw/dṽ = −dτ/dṽ − S'; hybrid:
v1 = √(w² − 4ζw), dv1/dṽ = (w − 2ζ)/v1·dw/dṽ, climbing for w − v1 more; Ia, IIa: ε does not
depend on ṽ. All evaluated at τ, S' = C − ζS. :func:`dashpot_contact_time` gives the contact
duration in s with its slope, for ``TrainModel.contact_time``.

Besides ε each law carries what a fit needs of a contact model: the contact duration
(``contact``, from the same collision as ε), v* from a known stiffness and mass
(``scene_prior``), ω0 = g/v* and β = ζω0 (``derived``), and its place on the selection ladder
(Ia and IIa add a contact duration to the constant law; Ib adds gravity in contact to Ia, IIb
and hybrid to IIa).

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   sections 3-4 (models Ia, Ib, IIa, IIb, hybrid).
"""

from __future__ import annotations

import math

import numpy as np

from ..._validation import check_nonnegative
from ..contact import Damping, basis
from ..models import MODELS, collide
from .base import Derived, RestitutionLaw, finite, no_flag, parameter

__all__ = ["LAW_SPECS", "dashpot_contact_time", "dashpot_step"]


def _dashpot_state(model, zeta, vtilde, level="exact"):
    """ε, dw/dṽ (w = εṽ), contact time ω0τ and dτ/dṽ of a dashpot model (dimensionless), from
    the exact collision or (level "fast", "standard") its certified surrogate tables."""
    vtilde = np.maximum(vtilde, np.finfo(float).tiny)  # ṽ = 0: the limit, captured or not
    if level == "exact":
        hit = collide(model, zeta, vtilde)
    else:
        # Imported here: the surrogate loads numba tables that only these levels need.
        from ..surrogate import surrogate_collide

        hit = surrogate_collide(model, zeta, vtilde, level=level)
    eps, tau = hit.eps, hit.contact_time
    w_slope = eps.copy()
    tau_slope = np.zeros(eps.shape)
    rebound = ~hit.captured
    if model in ("Ib", "IIb", "hybrid") and np.any(rebound):
        z, v = zeta[rebound], vtilde[rebound]
        vf = hit.release_speed[rebound]
        t = tau[rebound]
        if model == "hybrid":
            v1 = eps[rebound] * v
            t = t - (vf - v1)  # the climb from the release depth takes vf − v1 (g = 1)
        c, s = basis(Damping(z), t)
        s_slope = c - z * s
        if model == "Ib":
            dt = s / vf
            dw = -(1.0 + 2.0 * z * vf) * dt - s_slope
        else:
            dt = (s + 2.0 * z * s_slope) / (vf - 2.0 * z)
            dw = -dt - s_slope
        if model == "hybrid":
            dv1 = (vf - 2.0 * z) / v1 * dw
            dt, dw = dt + dw - dv1, dv1
        w_slope[rebound], tau_slope[rebound] = dw, dt
    w_slope = np.where(rebound, w_slope, 0.0)
    tau_slope = np.where(rebound, tau_slope, 0.0)
    return eps, w_slope, tau, tau_slope


def _dashpot_law(model):
    def function(speed, zeta, v_star):
        if np.any(zeta < 0.0) or np.any(v_star <= 0.0):
            raise ValueError(f"model {model}: zeta must be >= 0 and v_star > 0; got "
                             f"zeta={zeta!r}, v_star={v_star!r}")
        shape = speed.shape
        eps, w_slope, _, _ = _dashpot_state(model, zeta.ravel(), (speed / v_star).ravel())
        # ṽ·dε/dṽ = dw/dṽ − ε.
        return eps.reshape(shape), (w_slope - eps).reshape(shape), no_flag(shape)

    function.__name__ = f"dashpot_{model}"
    function.__doc__ = f"ε of dashpot model {model} at ṽ = v/v* (exact, analytic slope)."
    return function


def dashpot_contact_time(model, speed, zeta, v_star, g):
    """Contact duration of a dashpot model in s and its slope, for ``TrainModel.contact_time``.

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    speed : array_like
        Impact speed v in m/s, >= 0.
    zeta : array_like
        Damping ratio ζ = β/ω0.
    v_star : array_like
        v* = g/ω0 in m/s, > 0.
    g : float or array_like
        Acceleration g (g_eff) in m/s², > 0.

    Returns
    -------
    duration, slope : ndarray
        τ in s (inf where captured) and dτ/dv in s²/m (0 where captured).
    """
    speed = check_nonnegative("speed", speed)
    speed, zeta, v_star, g = np.broadcast_arrays(speed, finite("zeta", zeta),
                                                 finite("v_star", v_star), finite("g", g))
    if np.any(v_star <= 0.0) or np.any(g <= 0.0):
        raise ValueError(f"v_star and g must be > 0; got v_star={v_star!r}, g={g!r}")
    shape = speed.shape
    _, _, tau, tau_slope = _dashpot_state(model, zeta.ravel(), (speed / v_star).ravel())
    omega0 = g.ravel() / v_star.ravel()
    # τ = (ω0τ)/ω0 and dτ/dv = (dω0τ/dṽ)·(1/ω0)·(1/v*) = (dω0τ/dṽ)/g.
    return (tau / omega0).reshape(shape), (tau_slope / g.ravel()).reshape(shape)


def dashpot_step(model, speed, zeta, v_star, g, level="exact"):
    """Rebound speed and contact duration of a dashpot model with their slopes, from one
    evaluation of the collision (``rebound`` and :func:`dashpot_contact_time` each make one).

    Parameters
    ----------
    model, speed, zeta, v_star, g
        As in :func:`dashpot_contact_time`.
    level : {"exact", "fast", "standard"}, default "exact"
        The exact collision, or the surrogate tables of that level
        (:func:`dashpot.physics.surrogate.surrogate_collide`: certified relative errors of
        ε, 1 − ε and the contact time about 1e-6 and 1e-9; the slopes follow from their
        contact time and release speed by the same formulas).

    Returns
    -------
    rebound, rebound_slope : ndarray
        R(v) = ε·v in m/s and dR/dv = dw/dṽ (dimensionless): as ``LAWS[model].rebound``.
    duration, duration_slope : ndarray
        τ in s (inf where captured) and dτ/dv in s²/m: as :func:`dashpot_contact_time`.
    """
    speed = check_nonnegative("speed", speed)
    speed, zeta, v_star, g = np.broadcast_arrays(speed, finite("zeta", zeta),
                                                 finite("v_star", v_star), finite("g", g))
    if np.any(zeta < 0.0) or np.any(v_star <= 0.0) or np.any(g <= 0.0):
        raise ValueError(f"model {model}: zeta must be >= 0, v_star and g > 0; got "
                         f"zeta={zeta!r}, v_star={v_star!r}, g={g!r}")
    shape = speed.shape
    eps, w_slope, tau, tau_slope = _dashpot_state(model, zeta.ravel(),
                                                  (speed / v_star).ravel(), level)
    omega0 = g.ravel() / v_star.ravel()
    return ((eps * speed.ravel()).reshape(shape), w_slope.reshape(shape),
            (tau / omega0).reshape(shape), (tau_slope / g.ravel()).reshape(shape))


def _contact(model):
    def contact(speed, zeta, v_star, *, g, level="exact"):
        return dashpot_step(model, speed, zeta, v_star, g, level)

    return contact


def _scene_prior(stiffness, mass, g):
    """v* = g/√(k/m) from a known stiffness and mass: fixed where both are exact, else a
    Gaussian prior (v* ∝ (m/k)^(1/2): relative sd half the relative sd of k/m)."""
    if stiffness is None or mass is None:
        return None
    v_star = g / math.sqrt(stiffness.value / mass.value)
    if stiffness.uncertainty is None and mass.uncertainty is None:
        return "v_star", v_star, None, "stiffness and mass known exactly: v* = g/sqrt(k/m) fixed"
    relative = 0.5 * math.hypot((stiffness.uncertainty or 0.0) / stiffness.value,
                                (mass.uncertainty or 0.0) / mass.value)
    return ("v_star", v_star, v_star * relative,
            "prior on omega0 from the known stiffness and mass")


def _derived(values, g):
    """ω0 = g/v* (intervals mapped from v*'s) and β = ζω0 (linear propagation, >= 0)."""
    zeta, v_star = values["zeta"], values["v_star"]
    omega0 = g / v_star

    def through(v):
        with np.errstate(divide="ignore"):
            return float(g / np.float64(v)) if v > 0 else math.inf

    return (
        Derived("omega0", "rad/s", omega0, {"v_star": -omega0 / v_star},
                "omega0 = g/v_star (intervals from v_star's)", interval_of="v_star",
                through=through, decreasing=True),
        Derived("beta", "1/s", zeta * omega0,
                {"zeta": omega0, "v_star": -zeta * omega0 / v_star},
                "beta = zeta * omega0 (linear propagation)", lower=0.0),
    )


_SIMPLER = {"Ia": "constant", "IIa": "constant", "Ib": "Ia", "IIb": "IIa", "hybrid": "IIa"}
_EFFECT = {"Ia": "contact duration", "IIa": "contact duration", "Ib": "gravity in contact",
           "IIb": "gravity in contact", "hybrid": "gravity in contact"}

LAW_SPECS = tuple(
    RestitutionLaw(
        model, f"ε of dashpot model {model} at ṽ = v/v*",
        (parameter("zeta", "", 0.0, 10.0, 0.1, "damping ratio β/ω0"),
         parameter("v_star", "m/s", 1e-6, 100.0, 1e-3, "speed unit g/ω0")),
        _dashpot_law(model), "Bartz, sections 3-4", contact=_contact(model),
        contact_model=model, scene_prior=_scene_prior, derived=_derived,
        effect=_EFFECT[model], simpler=_SIMPLER[model])
    for model in MODELS)
"""The five dashpot models, in the order of :data:`dashpot.physics.models.MODELS` (collected in
:data:`dashpot.physics.laws.LAWS`)."""
