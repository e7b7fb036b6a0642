"""Conversions between contact parameters: (m, k, γ), (β, ω0), (ζ, v*), and (τ, ε).

DEM codes offer the last conversion for model Ia only (k and γ from a target restitution and
contact time); here it works for every model, with gravity where the model has it.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   eq. (2)-(3): β = γ/(2m), ω0² = k/m; v* = g/ω0 (the paper's g√(k/m) is a misprint).
.. [2] M. Nagurka and S. Huang, "A mass-spring-damper model of a bouncing ball", Proc. ACC
   2004: model Ia, τ = π/ω, ε = exp(−βτ).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import elementwise

from .._validation import check_model, check_nonnegative, check_positive
from .models import MODELS, collide

__all__ = ["natural_parameters", "contact_coefficients", "dimensionless_parameters",
           "restitution_from_contact", "contact_from_restitution"]


def natural_parameters(mass, stiffness, damping):
    """(β, ω0) from mass, stiffness and damping coefficient.

    Parameters
    ----------
    mass : array_like
        Mass m in kg, > 0.
    stiffness : array_like
        Spring constant k in N/m, > 0.
    damping : array_like
        Dashpot coefficient γ in kg/s (N·s/m), >= 0.

    Returns
    -------
    beta : ndarray
        Damping rate β = γ/(2m) in 1/s.
    omega0 : ndarray
        Undamped angular frequency ω0 = √(k/m) in rad/s.
    """
    mass = check_positive("mass", mass)
    stiffness = check_positive("stiffness", stiffness)
    damping = check_nonnegative("damping", damping)
    return damping / (2.0 * mass), np.sqrt(stiffness / mass)


def contact_coefficients(mass, beta, omega0):
    """(k, γ) from mass, damping rate and undamped angular frequency.

    Parameters
    ----------
    mass : array_like
        Mass m in kg, > 0.
    beta : array_like
        Damping rate β in 1/s, >= 0.
    omega0 : array_like
        Undamped angular frequency ω0 in rad/s, > 0.

    Returns
    -------
    stiffness : ndarray
        k = m·ω0² in N/m.
    damping : ndarray
        γ = 2m·β in kg/s.
    """
    mass = check_positive("mass", mass)
    beta = check_nonnegative("beta", beta)
    omega0 = check_positive("omega0", omega0)
    return mass * omega0**2, 2.0 * mass * beta


def dimensionless_parameters(beta, omega0, g):
    """(ζ, v*) from β, ω0 and the driving acceleration.

    Parameters
    ----------
    beta : array_like
        Damping rate in 1/s, >= 0.
    omega0 : array_like
        Undamped angular frequency in rad/s, > 0.
    g : array_like
        Acceleration towards the surface in m/s² (g·sin θ on an incline), > 0.

    Returns
    -------
    zeta : ndarray
        Damping ratio ζ = β/ω0 (dimensionless).
    v_star : ndarray
        Characteristic speed v* = g/ω0 in m/s.
    """
    beta = check_nonnegative("beta", beta)
    omega0 = check_positive("omega0", omega0)
    g = check_positive("g", g)
    return beta / omega0, g / omega0


def restitution_from_contact(model, stiffness, damping, *, mass, v0, g):
    """Contact duration and restitution of one impact from the contact coefficients.

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    stiffness : array_like
        k in N/m, > 0.
    damping : array_like
        γ in kg/s, >= 0.
    mass : array_like
        m in kg, > 0.
    v0 : array_like
        Impact speed in m/s, > 0.
    g : array_like
        Acceleration towards the surface in m/s², > 0.

    Returns
    -------
    contact_time : ndarray
        Contact duration in s (inf where captured).
    eps : ndarray
        Coefficient of restitution (0 where captured).
    """
    beta, omega0 = natural_parameters(mass, stiffness, damping)
    zeta, v_star = dimensionless_parameters(beta, omega0, g)
    outcome = collide(model, zeta, check_positive("v0", v0) / v_star)
    return outcome.contact_time / omega0, outcome.eps


def _zeta_for_restitution(model, eps, vtilde):
    """ζ at which `model` gives restitution `eps` at impact speed ṽ (ε decreases with ζ)."""

    def mismatch(log_zeta, target, speed):
        return collide(model, np.exp(log_zeta), speed).eps - target

    lower = np.full(eps.shape, np.log(1e-12))
    upper = np.full(eps.shape, np.log(1e4))
    result = elementwise.find_root(mismatch, (lower, upper), args=(eps, vtilde))
    # Where ε cannot be reached at this speed there is no bracket: report NaN to the caller,
    # which turns it into a ValueError.
    return np.where(result.success, np.exp(result.x), np.nan)


def contact_from_restitution(model, contact_time, eps, *, mass, v0, g):
    """Stiffness k and damping γ that give a contact duration and restitution (every model).

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    contact_time : array_like
        Target contact duration τ in s (per-model convention of ``collide``), > 0.
    eps : array_like
        Target restitution ε, in (0, 1).
    mass : array_like
        m in kg, > 0.
    v0 : array_like
        Impact speed in m/s, > 0 (used by the gravity models only).
    g : array_like
        Acceleration towards the surface in m/s², > 0 (used by the gravity models only).

    Returns
    -------
    stiffness : ndarray
        k in N/m.
    damping : ndarray
        γ in kg/s.

    Raises
    ------
    ValueError
        Inputs out of range, or a (τ, ε) pair that the model cannot produce at this speed
        (for example ε above what gravity allows at a low impact speed).

    Notes
    -----
    Model Ia has the closed form k = m(π² + ln²ε)/τ², γ = −2m·ln ε/τ [2]_. Otherwise ε(ζ, ṽ)
    decreases with ζ, so for a trial ω0 (ṽ = v0·ω0/g) ζ follows by bracketed root finding, and
    ω0 solves ω0·τ = τ̃(ζ, ṽ), both vectorized (scipy.optimize.elementwise).
    """
    model = check_model(model, MODELS)
    contact_time = check_positive("contact_time", contact_time)
    eps = check_positive("eps", eps)
    if np.any(eps >= 1.0):
        raise ValueError(f"eps must be in (0, 1); got {eps!r}")
    mass = check_positive("mass", mass)
    v0 = check_positive("v0", v0)
    g = check_positive("g", g)
    contact_time, eps, mass, v0, g = np.broadcast_arrays(contact_time, eps, mass, v0, g)

    def time_mismatch(log_omega0, tau, target, speed, accel):
        omega0 = np.exp(log_omega0)
        vtilde = speed * omega0 / accel
        zeta = _zeta_for_restitution(model, target, vtilde)
        reached = np.isfinite(zeta)
        outcome = collide(model, np.where(reached, zeta, 0.0), vtilde)
        return np.where(reached, outcome.contact_time / omega0 - tau, np.nan)

    guess = np.log(np.pi / contact_time)
    bracket = elementwise.bracket_root(time_mismatch, guess - 0.5, guess + 0.5,
                                       args=(contact_time, eps, v0, g))
    if not np.all(bracket.success):
        raise ValueError(f"model {model} cannot produce contact time {contact_time!r} s with "
                         f"restitution {eps!r} at impact speed {v0!r} m/s")
    log_omega0 = elementwise.find_root(time_mismatch, bracket.bracket,
                                       args=(contact_time, eps, v0, g)).x
    omega0 = np.exp(log_omega0)
    zeta = _zeta_for_restitution(model, eps, v0 * omega0 / g)
    reached = np.isfinite(zeta)
    achieved = collide(model, np.where(reached, zeta, 0.0), v0 * omega0 / g)
    if not (np.all(reached) and np.allclose(achieved.eps, eps, rtol=1e-9, atol=0.0)):
        raise ValueError(f"model {model} cannot produce restitution {eps!r} with contact time "
                         f"{contact_time!r} s at impact speed {v0!r} m/s")
    return contact_coefficients(mass, zeta * omega0, omega0)
