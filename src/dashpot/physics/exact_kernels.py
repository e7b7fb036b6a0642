"""Compiled end-of-contact root finding of the gravity models Ib and IIb (and so the hybrid).

One loop over the points, compiled with numba, does per point what
:func:`dashpot.physics.brackets._ib_solve` and :func:`~dashpot.physics.brackets._iib_release`
describe (their docstrings document the regimes and the iteration): the closed-form bracket
between extrema of ξ (Ib) or of the force (IIb), the capture decision from the sign at the
bracket's end, the first iterate, and the bracketed Halley iteration with its stopping rules.
The oscillator basis and its first zero are those of :func:`dashpot.physics.contact.basis` and
:func:`~dashpot.physics.contact.first_zero`, written for one point at a time with the same
operations in the same order.

This replaces a vectorized numpy form of the same iteration (up to commit 3830686), which
agreed with it to a few ulp: compiled per point because the iteration count differs from point
to point (2-4 Halley steps for most, bisections for a few), where numpy spent most of its time
compacting the working set and re-evaluating masks. This module imports numba; it is imported
only when a gravity model is first solved, so that importing the models does not load it. The
compiled code is cached on disk (``cache=True``): compiling it takes a few seconds once, loading
it from the cache a fraction of a second.

All quantities are dimensionless: time in 1/ω0, speed in v* = g/ω0.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   sections 3-4 (models Ib, IIb, hybrid; capture).
.. [2] E. Halley, "Methodus nova accurata & facilis inveniendi radices aequationum
   quarumcumque generaliter, sine praevia reductione", Phil. Trans. 18, 136-148 (1694);
   see also A. S. Householder, "The numerical treatment of a single nonlinear equation" (1970),
   section 4.4 (cubic convergence and the error constant f''²/4f'² − f'''/6f').
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .brackets import MODAL_ZETA

__all__ = ["ib_solve", "iib_solve"]

_EPS = float(np.finfo(float).eps)
_MAX_ITER = 200
# Above this impact speed IIb's force is evaluated in units of ṽ (its terms are O(ṽ) and would
# overflow near the float maximum); below it in units of mg, as the array forms.
_HUGE_SPEED = 1e300
# Evaluators of the Halley iteration (see _evaluate).
_IB, _IIB_CS, _IIB_MODAL = 0, 1, 2

# Float division by zero gives inf/nan as in numpy (the iteration tests for it) instead of
# raising; no fastmath, so that comparisons with inf and nan keep their IEEE meaning.
_jit = numba.njit(cache=True, error_model="numpy")


@_jit
def _basis(zeta, t):
    """C(t), S(t) and C(t) − 1 at one point, as :func:`dashpot.physics.contact.basis`."""
    s2 = (zeta - 1.0) * (zeta + 1.0)
    if s2 < 0.0:
        omega = math.sqrt(-s2)
        decay = math.exp(-zeta * t)
        half = 0.5 * omega * t
        sin_half, cos_half = math.sin(half), math.cos(half)
        versine = 2.0 * sin_half * sin_half
        cosine = 1.0 - versine
        return (decay * cosine, decay * (2.0 * sin_half * cos_half) / omega,
                math.expm1(-zeta * t) * cosine - versine)
    if s2 > 0.0:
        s = math.sqrt(s2)
        rate_t = t / (zeta + s)
        slow = math.exp(-rate_t)
        fast_minus_one = math.expm1(-2.0 * s * t)
        return (0.5 * slow * (2.0 + fast_minus_one), slow * (-fast_minus_one) / (2.0 * s),
                math.expm1(-rate_t) + 0.5 * slow * fast_minus_one)
    decay = math.exp(-t)
    return decay, t * decay, math.expm1(-t)


@_jit
def _first_zero(zeta, p, q):
    """Smallest t > 0 with p·C + q·S = 0 (:func:`dashpot.physics.contact.first_zero`)."""
    if p < 0.0 or (p == 0.0 and q < 0.0):
        p, q = -p, -q
    falling = q < 0.0
    abs_q = abs(q)
    s2 = (zeta - 1.0) * (zeta + 1.0)
    if s2 < 0.0:
        omega = math.sqrt(-s2)
        angle = math.atan2(omega * p, abs_q)
        return (angle if falling else math.pi - angle) / omega
    if s2 > 0.0:
        if not falling:
            return math.inf
        s = math.sqrt(s2)
        ratio = s * p / abs_q
        return math.atanh(ratio) / s if ratio < 1.0 else math.inf
    return p / abs_q if falling else math.inf


@_jit
def _half_period(zeta):
    """π/ω below ζ = 1, else inf."""
    s2 = (zeta - 1.0) * (zeta + 1.0)
    return math.pi / math.sqrt(-s2) if s2 < 0.0 else math.inf


@_jit
def _iia_contact_time(zeta):
    """ω0·τ of model IIa (:func:`dashpot.physics.brackets._iia_contact_time`)."""
    s2 = (zeta - 1.0) * (zeta + 1.0)
    if s2 < 0.0:
        omega = math.sqrt(-s2)
        return 2.0 * math.atan2(omega, zeta) / omega
    if s2 > 0.0:
        s = math.sqrt(s2)
        return 2.0 * math.log1p((zeta - 1.0) + s) / s
    return 2.0


@_jit
def _evaluate(kind, t, a0, a1, a2, a3, a4, a5, a6):
    """End condition f(t), f', f'', f''' and the rounding scale of f at one point.

    kind _IB: ξ = (C − 1) + (ζ − ṽ)S of model Ib, args (ζ, ṽ); _IIB_CS: force of IIb in the
    C, S form f = u·(1 + ξ'') = 2ζṽu + pu(C − 1) + quS, args (ζ, 2ζṽu, pu, qu, p'u, q'u, u);
    _IIB_MODAL: force of IIb in eigenmodes f = u + A·e^{−λs·t} + B·e^{−λf·t}, args
    (λs, λf, A, B, 0, 0, u). The unit u is 1, or 1/ṽ for impact speeds so large that the
    O(ṽ) terms would overflow (see :func:`dashpot.physics.brackets._iib_release`).
    """
    if kind == _IB:
        zeta, vtilde = a0, a1
        c, S, offset = _basis(zeta, t)
        drop = (zeta - vtilde) * S
        excess = offset + drop
        slope = -vtilde * c + (zeta * vtilde - 1.0) * S
        # ξ'' = −1 − ξ − 2ζξ' from the equation of motion.
        curvature = -1.0 - excess - 2.0 * zeta * slope
        third = -slope - 2.0 * zeta * curvature
        return excess, slope, curvature, third, abs(offset) + abs(drop)
    if kind == _IIB_CS:
        zeta, start_force, p, q, slope_p, slope_q, unit = a0, a1, a2, a3, a4, a5, a6
        c, S, offset = _basis(zeta, t)
        spring, damper = p * offset, q * S
        value = start_force + spring + damper
        slope = slope_p * c + slope_q * S
        # f − 1 = ξ'' solves the homogeneous equation.
        curvature = unit - value - 2.0 * zeta * slope
        third = -slope - 2.0 * zeta * curvature
        return value, slope, curvature, third, start_force + abs(spring) + abs(damper)
    slow, fast, slow_amplitude, fast_amplitude, unit = a0, a1, a2, a3, a6
    slow_part = slow_amplitude * math.exp(-slow * t)
    fast_part = fast_amplitude * math.exp(-fast * t)
    return (unit + slow_part + fast_part, -slow * slow_part - fast * fast_part,
            slow * slow * slow_part + fast * fast * fast_part,
            -(slow * slow * slow) * slow_part - fast * fast * fast * fast_part,
            unit + abs(slow_part) + abs(fast_part))


@_jit
def _phase_start(lower, upper, value_lower, value_upper):
    """First iterate away from high speed: between consecutive extrema the end condition is close to a half cosine wave with end values a and b, whose
    root is at the fraction arccos((a + b)/(b − a))/π of the bracket."""
    ratio = min(max((value_lower + value_upper) / (value_upper - value_lower), -1.0), 1.0)
    phase = min(max(math.acos(ratio) / math.pi, 0.05), 0.95)
    start = lower + phase * (upper - lower)
    # An end value that overflowed leaves no phase: start in the middle rather than at NaN.
    return start if lower < start < upper else 0.5 * (lower + upper)


@_jit
def _halley(kind, a0, a1, a2, a3, a4, a5, a6, lower, upper, start, sign):
    """Root of the end condition in [lower, upper], rising (`sign` = 1) or falling (−1).

    Halley steps, replaced by bisection where a step leaves the current bracket; stops when f
    is at its rounding level (4 ulp of `scale`), when the step is below 4 ulp, when the bracket
    closes, or when the estimated error left by the step is below one ulp of the root (see
    :func:`dashpot.physics.brackets._iib_release`).
    """
    t, lo, hi = start, lower, upper
    for _ in range(_MAX_ITER):
        value, slope, curvature, third, scale = _evaluate(kind, t, a0, a1, a2, a3, a4, a5, a6)
        value, slope, curvature, third = sign * value, sign * slope, sign * curvature, sign * third
        if value < 0.0:
            lo = t
        else:
            hi = t
        newton = value / slope
        bend = 0.5 * curvature / slope
        correction = 1.0 - newton * bend
        step = newton / correction if correction > 0.5 else newton
        # Error left after this step: e' = (f''²/4f'² − f'''/6f')·e³, safety factor 4 [2]_.
        remaining = 4.0 * abs(bend * bend - third / (6.0 * slope)) * abs(step) ** 3
        candidate = t - step
        inside = candidate > lo and candidate < hi and math.isfinite(candidate)
        converged = (abs(value) <= 4.0 * _EPS * scale or abs(step) <= 4.0 * _EPS * abs(t)
                     or (inside and remaining <= _EPS * abs(candidate)))
        if converged:
            new = t if value == 0.0 else candidate
        elif inside:
            new = candidate
        else:
            new = 0.5 * (lo + hi)
        if converged or hi - lo <= 4.0 * _EPS * abs(t):
            return new
        t = new
    return t


@_jit
def ib_solve(zeta, vtilde, solve):
    """Bracket, capture margin and return time of model Ib, point by point.

    Parameters
    ----------
    zeta, vtilde : ndarray of float64
        Damping ratio ζ >= 0 and impact speed ṽ > 0 (dimensionless), same shape, 1-d.
    solve : bool
        Whether to find the return time (else only the bracket and ξ(t_max)).

    Returns
    -------
    t_min, t_max : ndarray
        Bracket of the return root: the minimum of ξ and the next maximum (inf if none).
    xi_max : ndarray
        ξ(t_max), −inf where there is no maximum; the ball rebounds iff it is positive.
    tau : ndarray
        Contact time ω0·τ where it rebounds (if `solve`), inf elsewhere.
    rebound_ratio : ndarray
        ξ'(τ)/ṽ = −C + ζS − S/ṽ at τ where it rebounds (if `solve`), 0 elsewhere.
    """
    n = zeta.size
    t_min, t_max = np.empty(n), np.empty(n)
    xi_max, tau = np.full(n, -np.inf), np.full(n, np.inf)
    rebound_ratio = np.zeros(n)
    for i in range(n):
        z, v = zeta[i], vtilde[i]
        s2 = (z - 1.0) * (z + 1.0)
        # ξ' = (ζ − ṽ − ζ)C + (s² − ζ(ζ − ṽ))S (contact.derivative of ξ = C − 1 + (ζ − ṽ)S).
        low = _first_zero(z, (z - v) - z, s2 - z * (z - v))
        high = low + _half_period(z)
        t_min[i], t_max[i] = low, high
        if not math.isfinite(high):
            continue
        top = _evaluate(_IB, high, z, v, 0.0, 0.0, 0.0, 0.0, 0.0)[0]
        xi_max[i] = top
        if not (solve and top > 0.0):
            continue
        # At high speed gravity is a small correction: Ia's end time is nearly the root.
        start = math.pi / math.sqrt(-s2)
        if not (v > 20.0 and low < start < high):
            bottom = _evaluate(_IB, low, z, v, 0.0, 0.0, 0.0, 0.0, 0.0)[0]
            start = _phase_start(low, high, bottom, top)
        root = _halley(_IB, z, v, 0.0, 0.0, 0.0, 0.0, 0.0, low, high, start, 1.0)
        tau[i] = root
        c, S, _ = _basis(z, root)
        rebound_ratio[i] = -c + z * S - S / v
    return t_min, t_max, xi_max, tau, rebound_ratio


@_jit
def iib_solve(zeta, vtilde, solve):
    """Bracket, force minimum and release time of model IIb, point by point.

    Below ζ = MODAL_ZETA the force is f = 2ζṽ + p(C − 1) + qS, above it the eigenmode form
    (see :func:`dashpot.physics.brackets._iib_release` for the brackets).

    Parameters
    ----------
    zeta, vtilde : ndarray of float64
        Damping ratio ζ >= 0 and impact speed ṽ > 0 (dimensionless), same shape, 1-d.
    solve : bool
        Whether to find the release time.

    Returns
    -------
    t_lo, t_hi : ndarray
        Bracket of the release root (t_hi = inf where the force has no minimum).
    force_min : ndarray
        f(t_hi), or min(2ζṽ, 1) where there is no minimum; released iff negative.
    tau : ndarray
        Release time where released (if `solve`), inf elsewhere.
    release_slope : ndarray
        ξ'(τ) where released (if `solve`), 0 elsewhere.
    """
    n = zeta.size
    t_lo, t_hi = np.zeros(n), np.full(n, np.inf)
    force_min, tau = np.empty(n), np.full(n, np.inf)
    release_slope = np.zeros(n)
    for i in range(n):
        z, v = zeta[i], vtilde[i]
        start_force = 2.0 * z * v
        force_min[i] = min(start_force, 1.0)
        unit, rescale = 1.0, 1.0
        slow = fast = a = b = 0.0
        if z >= MODAL_ZETA:
            kind = _IIB_MODAL
            # Eigenmodes (brackets._eigenmodes): η = a·e^{−λs·t} + b·e^{−λf·t}.
            s = math.sqrt((z - 1.0) * (z + 1.0))
            fast = z + s
            slow = 1.0 / fast
            a, b = (fast - v) / (2.0 * s), (v - slow) / (2.0 * s)
            falls_first = slow * slow * slow * a + fast * fast * fast * b > 0.0
            low, high = 0.0, math.inf
            if falls_first and ((a < 0.0) != (b < 0.0)) and a != 0.0 and b != 0.0:
                t_min = (math.log(abs(b)) - math.log(abs(a)) + 6.0 * math.log(fast)) / (fast - slow)
                if t_min > 0.0:
                    high = t_min
            a0, a1, a2, a3 = slow, fast, slow * slow * a, fast * fast * b
            a4, a5, a6 = 0.0, 0.0, 1.0
        else:
            kind = _IIB_CS
            if v > _HUGE_SPEED:
                # f/ṽ: the same root and iteration, without overflow of the O(ṽ) terms.
                unit, rescale = 1.0 / v, v
                start_force = 2.0 * z
                p = 2.0 * z - unit
                q = z * unit + (1.0 - 2.0 * z * z)
            else:
                p = 2.0 * z * v - 1.0
                q = z + v * (1.0 - 2.0 * z * z)
            slope_p, slope_q = q - z * p, (z - 1.0) * (z + 1.0) * p - z * q
            falls_first = slope_p < 0.0 or (slope_p == 0.0 and slope_q < 0.0)
            first = _first_zero(z, slope_p, slope_q)
            if falls_first:
                low, high = 0.0, first
            else:
                low, high = first, first + _half_period(z)
            a0, a1, a2, a3, a4, a5, a6 = z, start_force, p, q, slope_p, slope_q, unit
        t_lo[i], t_hi[i] = low, high
        if not math.isfinite(high):
            continue
        bottom_force = _evaluate(kind, high, a0, a1, a2, a3, a4, a5, a6)[0]
        force_min[i] = bottom_force * rescale
        if not (solve and bottom_force < 0.0):
            continue
        # At high speed gravity is a small correction: IIa's end time is nearly the root.
        start = _iia_contact_time(z)
        if not (v > 20.0 and low < start < high):
            # f at the bracket's lower end: 2ζṽ at impact, else one more evaluation.
            top_force = start_force
            if low > 0.0:
                top_force = _evaluate(kind, low, a0, a1, a2, a3, a4, a5, a6)[0]
            start = _phase_start(low, high, top_force, bottom_force)
        root = _halley(kind, a0, a1, a2, a3, a4, a5, a6, low, high, start, -1.0)
        tau[i] = root
        # ξ'(τ) = −ṽC + (ζṽ − 1)S, or −λs·a·e^{−λs·τ} − λf·b·e^{−λf·τ} in eigenmodes.
        if kind == _IIB_MODAL:
            release_slope[i] = (-slow * a * math.exp(-slow * root)
                                - fast * b * math.exp(-fast * root))
        else:
            c, S, _ = _basis(z, root)
            if rescale == 1.0:
                release_slope[i] = -v * c + (z * v - 1.0) * S
            else:
                release_slope[i] = v * (z * S - c) - S  # ζṽ alone could overflow
    return t_lo, t_hi, force_min, tau, release_slope
