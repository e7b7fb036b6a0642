"""Trajectory of one linear spring-dashpot contact, in every damping regime.

In the units of the design notes (time in 1/ω0, speed in v* = g/ω0, length in g/ω0²) the
compression during contact obeys ξ'' = −1 − ξ − 2ζξ' with gravity and ξ'' = −ξ − 2ζξ' without.
Both are built from the two fundamental solutions of the damped oscillator x'' + 2ζx' + x = 0,

.. math::

    C(t) = e^{-\\zeta t}\\cosh(st), \\qquad S(t) = e^{-\\zeta t}\\frac{\\sinh(st)}{s},
    \\qquad s^2 = \\zeta^2 - 1,

with C(0) = 1, C'(0) = −ζ, S(0) = 0, S'(0) = 1. Both are entire functions of s², real on either
side of ζ = 1 (cos/sin of ωt with ω² = 1 − ζ² below, S = t e^{−t} at ζ = 1 exactly), so one
formulation covers the under-, critically and over-damped regimes. Every function used here is a
combination ``x(t) = P·C(t) + Q·S(t)``; its derivative is again of that form (see
:func:`derivative`), which is what makes extrema and brackets available in closed form.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface"
   (the paper this project grew from), eq. (2)-(4).
.. [2] T. Schwager and T. Pöschel, "Coefficient of restitution and linear-dashpot model
   revisited", Granular Matter 9, 465-469 (2007).
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

__all__ = ["Damping", "basis", "combination", "derivative", "first_zero"]


class Damping:
    """Regime quantities of the damping ratio ζ, computed on first use without cancellation.

    Parameters
    ----------
    zeta : array_like
        Damping ratio ζ = β/ω0 (dimensionless), ζ >= 0.

    Attributes
    ----------
    s2 : ndarray
        s² = ζ² − 1, computed as (ζ − 1)(ζ + 1) so that it keeps its digits near ζ = 1.
    omega : ndarray
        Dimensionless damped frequency ω/ω0 = √(1 − ζ²) where ζ < 1, else 0.
    s : ndarray
        √(ζ² − 1) where ζ > 1, else 0.
    under, critical, over : ndarray of bool
        Regime masks.
    half_period : ndarray
        π/ω where ζ < 1, else inf.
    """

    def __init__(self, zeta):
        self.zeta = np.asarray(zeta, dtype=float)
        self.s2 = (self.zeta - 1.0) * (self.zeta + 1.0)

    @cached_property
    def under(self):
        return self.s2 < 0.0

    @cached_property
    def over(self):
        return self.s2 > 0.0

    @cached_property
    def critical(self):
        return self.s2 == 0.0

    @cached_property
    def omega(self):
        return np.sqrt(np.maximum(-self.s2, 0.0))

    @cached_property
    def s(self):
        return np.sqrt(np.maximum(self.s2, 0.0))

    @cached_property
    def half_period(self):
        # π/ω of the underdamped oscillation; inf where there is no oscillation.
        return np.where(self.under, np.pi / np.where(self.under, self.omega, 1.0), np.inf)


def basis(damping: Damping, t, *, offset=False):
    """Fundamental solutions C(t) and S(t) of x'' + 2ζx' + x = 0, and optionally C(t) − 1.

    Parameters
    ----------
    damping : Damping
        Damping ratio and its regime quantities.
    t : array_like
        Dimensionless time ω0·t >= 0, finite.
    offset : bool, default False
        Also return C(t) − 1 computed without cancellation (C ≈ 1 near t = 0 and t = 2π/ω,
        where a slow, lightly damped impact ends and capture is decided).

    Returns
    -------
    C, S : ndarray
        C(0) = 1, C'(0) = −ζ; S(0) = 0, S'(0) = 1.
    C_minus_one : ndarray
        Only if `offset`.

    Notes
    -----
    Underdamped: C = e^{−ζt}cos ωt, S = e^{−ζt}sin(ωt)/ω, where sin(ωt)/ω keeps full relative
    accuracy even for tiny ω; C − 1 = expm1(−ζt)·cos ωt − 2 sin²(ωt/2). Overdamped:
    C = ½e^{−λt}(1 + e^{−2st}), S = e^{−λt}(1 − e^{−2st})/(2s), C − 1 = expm1(−λt) +
    ½e^{−λt}·expm1(−2st), with the slow rate λ = ζ − s written as 1/(ζ + s) (no cancellation
    at large ζ) and 1 − e^{−2st} as −expm1(−2st) (none near ζ = 1⁺). Critical: C = e^{−t},
    S = t·e^{−t}, C − 1 = expm1(−t). Each regime is evaluated only on its own points.
    """
    t = np.broadcast_to(np.asarray(t, dtype=float), damping.zeta.shape)
    if damping.under.all():  # the common case in root finding: skip the masking
        values = _basis_under(damping.zeta, damping.omega, t, offset)
        return values if offset else values[:2]
    out = tuple(np.empty(t.shape) for _ in range(3 if offset else 2))
    under, over, critical = damping.under, damping.over, damping.critical
    for target, value in zip(out, _basis_under(damping.zeta[under], damping.omega[under],
                                               t[under], offset)):
        target[under] = value
    zeta, s, t_over = damping.zeta[over], damping.s[over], t[over]
    rate_t = t_over / (zeta + s)
    slow = np.exp(-rate_t)
    fast_minus_one = np.expm1(-2.0 * s * t_over)
    out[0][over] = 0.5 * slow * (2.0 + fast_minus_one)
    out[1][over] = slow * (-fast_minus_one) / (2.0 * s)
    t_critical = t[critical]
    decay = np.exp(-t_critical)
    out[0][critical] = decay
    out[1][critical] = t_critical * decay
    if offset:
        out[2][over] = np.expm1(-rate_t) + 0.5 * slow * fast_minus_one
        out[2][critical] = np.expm1(-t_critical)
    return out


def _basis_under(zeta, omega, t, offset):
    decay = np.exp(-zeta * t)
    if not offset:
        phase = omega * t
        return decay * np.cos(phase), decay * np.sin(phase) / omega
    # Half-angle forms: two trigonometric calls instead of three, and 1 − cos ωt = 2 sin²(ωt/2)
    # without cancellation.
    half = 0.5 * omega * t
    sin_half, cos_half = np.sin(half), np.cos(half)
    versine = 2.0 * sin_half * sin_half
    cosine = 1.0 - versine
    return (decay * cosine, decay * (2.0 * sin_half * cos_half) / omega,
            np.expm1(-zeta * t) * cosine - versine)


def combination(damping: Damping, p, q, t):
    """Evaluate x(t) = p·C(t) + q·S(t).

    Parameters
    ----------
    damping : Damping
    p, q : array_like
        Coefficients; p = x(0) and q + ... follow from the initial state (dimensionless).
    t : array_like
        Dimensionless time, finite and >= 0.

    Returns
    -------
    ndarray
    """
    c, S = basis(damping, t)
    return p * c + q * S


def derivative(damping: Damping, p, q):
    """Coefficients of x'(t) for x(t) = p·C(t) + q·S(t).

    Uses C' = −ζC + s²S and S' = C − ζS.

    Returns
    -------
    dp, dq : ndarray
        x'(t) = dp·C(t) + dq·S(t).
    """
    zeta = damping.zeta
    return q - zeta * p, damping.s2 * p - zeta * q


def first_zero(damping: Damping, p, q):
    """Smallest t > 0 with p·C(t) + q·S(t) = 0, in closed form; inf where there is none.

    Parameters
    ----------
    damping : Damping
    p, q : array_like
        Coefficients of the combination (not both zero).

    Returns
    -------
    ndarray
        Dimensionless time of the first zero. Subsequent zeros of an underdamped combination
        follow at intervals of π/ω (``damping.half_period``); critically and over-damped
        combinations have at most one.

    Notes
    -----
    With the sign normalised so that p >= 0 (and q > 0 where p = 0), the zero solves
    S/C = p/(−q). Below ζ = 1, S/C = tan(ωt)/ω, so ωt = atan2(ωp, −q) when q < 0 and
    π − atan2(ωp, q) otherwise; at ζ = 1, S/C = t; above, S/C = tanh(st)/s, which takes values
    in [0, 1/s) only. None of the forms divides by a small ω or s.
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    flip = (p < 0.0) | ((p == 0.0) & (q < 0.0))
    p = np.where(flip, -p, p)
    q = np.where(flip, -q, q)
    falling = q < 0.0
    abs_q = np.abs(q)
    omega = damping.omega
    safe_omega = np.where(damping.under, omega, 1.0)
    angle = np.arctan2(safe_omega * p, abs_q)
    t_under = np.where(falling, angle, np.pi - angle) / safe_omega
    safe_q = np.where(falling, abs_q, 1.0)
    t_critical = np.where(falling, p / safe_q, np.inf)
    safe_s = np.where(damping.over, damping.s, 1.0)
    ratio = safe_s * p / safe_q
    reachable = falling & (ratio < 1.0)
    t_over = np.where(reachable, np.arctanh(np.where(reachable, ratio, 0.0)) / safe_s, np.inf)
    return np.where(damping.under, t_under, np.where(damping.over, t_over, t_critical))
