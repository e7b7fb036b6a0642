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
compacting the working set and re-evaluating masks.

:func:`ib_collide` and :func:`iib_collide` give ``collide`` every field of its result in the
same pass (ε and 1 − ε from the decay of the quadratic invariant, contact time, capture, release
state), without the numpy passes over the arrays that cost as much as the root finding at
10⁴-10⁵ points. Three things spare evaluations of the end condition (each one exp, sin and cos
and an expm1): above ṽ = 20 the first Halley step is taken in closed form from the
gravity-free end time (Ia's π/ω, IIa's 2φ/ω), where C and S reduce to multiples of the
gravity-free ε; the rebound (release) is decided there by a closed-form sufficient condition
where it holds, instead of evaluating the end condition at the bracket's end; and ξ'(τ) comes
from its Taylor series about the last iterate (which is within ~1e-5 of the root, so that the
series is exact to rounding) instead of one more evaluation. Mostly one evaluation per point
remains above ṽ = 20 (1-3 below, plus the bracket's ends). The results agree with the previous
form to a few ulp (not bit for bit), and as well with the 50-digit references.

This module imports numba; it is imported only when a gravity model is first solved, so that
importing the models does not load it. The compiled code is cached on disk (``cache=True``):
compiling it takes 15-20 s once, loading it from the cache a fraction of a second.

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

__all__ = ["ib_collide", "ib_solve", "iib_collide", "iib_solve"]

_EPS = float(np.finfo(float).eps)
_MAX_ITER = 200
# Above this impact speed IIb's force is evaluated in units of ṽ (its terms are O(ṽ) and would
# overflow near the float maximum); below it in units of mg, as the array forms.
_HUGE_SPEED = 1e300
# Evaluators of the Halley iteration (see _evaluate).
_IB, _IIB_CS, _IIB_MODAL = 0, 1, 2

# Float division by zero gives inf/nan as in numpy (the iteration tests for it) instead of
# raising; no fastmath, so that comparisons with inf and nan keep their IEEE meaning. numba's
# own inlining (inline="always") took a fifth off the time per point but made the first
# compile 20 s instead of 3.6 s (every new install, every fresh test run): not used.
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
def _evaluate(kind, t, a0, a1, a2, a3, a4, a5, a6, a7):
    """End condition f(t), f', f'', f''', the rounding scale of f and u·ξ'(t), at one point.

    kind _IB: ξ = (C − 1) + (ζ − ṽ)S of model Ib, args (ζ, ṽ); _IIB_CS: force of IIb in the
    C, S form f = u·(1 + ξ'') = 2ζṽu + pu(C − 1) + quS, args (ζ, 2ζṽu, pu, qu, p'u, q'u, u, ṽu);
    _IIB_MODAL: force of IIb in eigenmodes f = u + A·e^{−λs·t} + B·e^{−λf·t}, args
    (λs, λf, A, B, 0, 0, u, ṽu). The unit u is 1, or 1/ṽ for impact speeds so large that the
    O(ṽ) terms would overflow (see :func:`dashpot.physics.brackets._iib_release`); u = 1 for Ib.
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
        return excess, slope, curvature, third, abs(offset) + abs(drop), slope
    if kind == _IIB_CS:
        zeta, start_force, p, q, slope_p, slope_q, unit, speed = a0, a1, a2, a3, a4, a5, a6, a7
        c, S, offset = _basis(zeta, t)
        spring, damper = p * offset, q * S
        value = start_force + spring + damper
        slope = slope_p * c + slope_q * S
        # f − 1 = ξ'' solves the homogeneous equation.
        curvature = unit - value - 2.0 * zeta * slope
        third = -slope - 2.0 * zeta * curvature
        # ξ' = −ṽC + (ζṽ − 1)S, in units of 1/u.
        rate = speed * (zeta * S - c) - unit * S
        return value, slope, curvature, third, start_force + abs(spring) + abs(damper), rate
    slow, fast, slow_amplitude, fast_amplitude, unit = a0, a1, a2, a3, a6
    slow_part = slow_amplitude * math.exp(-slow * t)
    fast_part = fast_amplitude * math.exp(-fast * t)
    # ξ' = −λs·a·e^{−λs·t} − λf·b·e^{−λf·t}, with A = λs²a and B = λf²b.
    return (unit + slow_part + fast_part, -slow * slow_part - fast * fast_part,
            slow * slow * slow_part + fast * fast * fast_part,
            -(slow * slow * slow) * slow_part - fast * fast * fast * fast_part,
            unit + abs(slow_part) + abs(fast_part), -slow_part / slow - fast_part / fast)


@_jit
def _zeta_of(kind, a0, a1):
    """ζ from the evaluator's arguments: ζ itself, or (λs + λf)/2 in eigenmodes."""
    return 0.5 * (a0 + a1) if kind == _IIB_MODAL else a0


@_jit
def _phase_start(lower, upper, value_lower, value_upper):
    """First iterate away from high speed: between consecutive extrema the end condition is
    close to a half cosine wave with end values a and b, whose root is at the fraction
    arccos((a + b)/(b − a))/π of the bracket."""
    ratio = min(max((value_lower + value_upper) / (value_upper - value_lower), -1.0), 1.0)
    phase = min(max(math.acos(ratio) / math.pi, 0.05), 0.95)
    start = lower + phase * (upper - lower)
    # An end value that overflowed leaves no phase: start in the middle rather than at NaN.
    return start if lower < start < upper else 0.5 * (lower + upper)


@_jit
def _halley(kind, a0, a1, a2, a3, a4, a5, a6, a7, lower, upper, start, sign, known,
            known_value, known_slope, known_curvature, known_scale, known_rate):
    """Root of the end condition in [lower, upper], rising (`sign` = 1) or falling (−1).

    Halley steps, replaced by bisection where a step leaves the current bracket; stops when f
    is at its rounding level (4 ulp of `scale`), when the step is below 4 ulp, when the bracket
    closes, or when the estimated error left by the step is below one ulp of the root (see
    :func:`dashpot.physics.brackets._iib_release`). If `known`, f, f', f'', the rounding scale
    of f and u·ξ' at `start` are the `known_*` values (the closed form at the gravity-free end
    time) instead of an evaluation.

    Returns
    -------
    root : float
        The root.
    rate : float
        u·ξ' at the root (see :func:`_evaluate`), from its Taylor series to third order about
        the last point evaluated: the step from there is accepted only where it leaves an error
        below one ulp, at most ~1e-5 of the root, so that the series' remainder is below
        rounding.
    """
    t, lo, hi = start, lower, upper
    zeta = _zeta_of(kind, a0, a1)
    value = slope = curvature = third = rate = 0.0
    new = t
    done = False
    for iteration in range(_MAX_ITER):
        if iteration == 0 and known:
            value, slope, curvature = known_value, known_slope, known_curvature
            third = -slope - 2.0 * zeta * curvature
            scale, rate = known_scale, known_rate
        else:
            value, slope, curvature, third, scale, rate = _evaluate(kind, t, a0, a1, a2, a3,
                                                                    a4, a5, a6, a7)
        # Rising form of the end condition.
        rising, rising_slope = sign * value, sign * slope
        rising_curvature, rising_third = sign * curvature, sign * third
        if rising < 0.0:
            lo = t
        else:
            hi = t
        newton = rising / rising_slope
        bend = 0.5 * rising_curvature / rising_slope
        correction = 1.0 - newton * bend
        step = newton / correction if correction > 0.5 else newton
        # Error left after this step: e' = (f''²/4f'² − f'''/6f')·e³, safety factor 4 [2]_.
        remaining = 4.0 * abs(bend * bend - rising_third / (6.0 * rising_slope)) * abs(step) ** 3
        candidate = t - step
        inside = candidate > lo and candidate < hi and math.isfinite(candidate)
        converged = (abs(rising) <= 4.0 * _EPS * scale or abs(step) <= 4.0 * _EPS * abs(t)
                     or (inside and remaining <= _EPS * abs(candidate)))
        if converged:
            new = t if rising == 0.0 else candidate
        elif inside:
            new = candidate
        else:
            new = 0.5 * (lo + hi)
        if converged or hi - lo <= 4.0 * _EPS * abs(t):
            done = True
            break
        t = new
    if not done:
        return t, rate
    delta = new - t
    if delta == 0.0:
        return new, rate
    if not abs(delta) <= 1e-4 * abs(new):
        # Not reached by the stopping rules above; kept so that the series is never stretched.
        return new, _evaluate(kind, new, a0, a1, a2, a3, a4, a5, a6, a7)[5]
    # Derivatives of u·ξ' at t: Ib's end condition is ξ itself; IIb's is f = u(1 + ξ''),
    # so that u·ξ'' = f − u, u·ξ''' = f', u·ξ'''' = f''.
    if kind == _IB:
        second, third_rate = curvature, third
        fourth = -curvature - 2.0 * zeta * third
    else:
        second, third_rate, fourth = value - a6, slope, curvature
    return new, rate + delta * (second + delta * (0.5 * third_rate + delta * (fourth / 6.0)))


@_jit
def _ib_point(z, v, solve, need_top):
    """Bracket, ξ at its end, return time and ξ' there, of model Ib at one point.

    Returns (t_min, t_max, ξ(t_max), τ, ξ'(τ)): ξ(t_max) is −inf where ξ has no maximum, NaN
    where `need_top` is false and the rebound was decided without it; τ is inf where the ball
    does not rebound (or not `solve`).
    """
    s2 = (z - 1.0) * (z + 1.0)
    # ξ' = (ζ − ṽ − ζ)C + (s² − ζ(ζ − ṽ))S (contact.derivative of ξ = C − 1 + (ζ − ṽ)S).
    low = _first_zero(z, (z - v) - z, s2 - z * (z - v))
    high = low + _half_period(z)
    if not math.isfinite(high):
        return low, high, -math.inf, math.inf, 0.0
    # Ia's end time π/ω: at high speed gravity is a small correction and the root is near it.
    start = math.pi / math.sqrt(-s2)
    closed = v > 20.0 and low < start < high
    rebound = False
    decay = 0.0
    if closed:
        # Ia's ε = e^{−ζπ/ω}: C(π/ω) = −ε, S(π/ω) = 0.
        decay = math.exp(-z * start)
        # Sufficient for a rebound (with ṽ > ζ): ½ ln(1 + ṽ(ṽ − 2ζ)) > 2πζ/ω makes the phase
        # mismatch of models._ib_phase_mismatch positive (its rotation is below 2π), i.e. ṽ
        # above the critical speed; a factor 2 of margin keeps rounding out of the decision.
        rebound = v * (v - 2.0 * z) * (decay * decay) * (decay * decay) > 2.0
    top = math.nan
    if need_top or not rebound:
        top = _evaluate(_IB, high, z, v, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)[0]
        rebound = top > 0.0
    if not (solve and rebound):
        return low, high, top, math.inf, 0.0
    if closed:
        # The first Halley step from π/ω, in closed form: ξ = −(1 + ε), ξ' = ṽε,
        # ξ'' = −1 − ξ − 2ζξ'. ξ < 0 there: π/ω is also a lower bound of the root.
        slope = v * decay
        curvature = decay - 2.0 * z * slope
        root, rate = _halley(_IB, z, v, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, low, high, start, 1.0,
                             True, -(1.0 + decay), slope, curvature, 1.0 + decay, slope)
    else:
        bottom = _evaluate(_IB, low, z, v, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)[0]
        start = _phase_start(low, high, bottom, top)
        root, rate = _halley(_IB, z, v, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, low, high, start, 1.0,
                             False, 0.0, 0.0, 0.0, 0.0, 0.0)
    return low, high, top, root, rate


@_jit
def _iib_point(z, v, solve, need_top):
    """Bracket, force minimum, release time and ξ' there, of model IIb at one point.

    Returns (t_lo, t_hi, f(t_hi), τ, ξ'(τ)): f(t_hi) is min(2ζṽ, 1) where the force has no
    minimum, NaN where `need_top` is false and the release was decided without it; τ is inf
    where the ball is not released (or not `solve`).
    """
    start_force = 2.0 * z * v
    force_min = min(start_force, 1.0)
    unit, rescale, speed = 1.0, 1.0, v
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
        a4, a5, a6, a7 = 0.0, 0.0, 1.0, v
    else:
        kind = _IIB_CS
        if v > _HUGE_SPEED:
            # f/ṽ: the same root and iteration, without overflow of the O(ṽ) terms.
            unit, rescale, speed = 1.0 / v, v, 1.0
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
        a0, a1, a2, a3, a4, a5, a6, a7 = z, start_force, p, q, slope_p, slope_q, unit, speed
    if not math.isfinite(high):
        return low, high, force_min, math.inf, 0.0
    # IIa's end time 2φ/ω: at high speed gravity is a small correction and the root is near it.
    start = _iia_contact_time(z)
    near = v > 20.0 and low < start < high
    closed = near and kind == _IIB_CS
    released = False
    decay = 0.0
    if closed:
        # IIa's ε = e^{−2ζφ/ω}: C = ε(2ζ² − 1) and S = 2ζε there (over-damped too, with 2ψ/s),
        # so that f = u(1 + ε) and f' = −ṽuε.
        decay = math.exp(-z * start)
        if z < 1.0:
            # Sufficient for a release: after 2φ/ω, |f''| = u|ξ''''| <= M = √((1 + 4ζ²)P/(1 − ζ))
            # with P = u²(ξ'''² + 2ζξ''ξ''' + ξ''²) decaying (and P >= (1 − ζ)u²(ξ''² + ξ'''²)),
            # so that f < 0 somewhere after it, and hence at its first minimum, if f'² > 2Mf.
            # With a factor 2 of margin against rounding, in units of ṽu:
            # ṽε > 4(1 + ε)·√((1 + 4ζ²)((1 − ζ/ṽ)² + (1 − ζ²)/ṽ²)/(1 − ζ)).
            inverse = 1.0 / v
            shifted = 1.0 - z * inverse
            size = shifted * shifted + (1.0 - z) * (1.0 + z) * (inverse * inverse)
            bound = 4.0 * (1.0 + decay) * math.sqrt((1.0 + 4.0 * z * z) * size / (1.0 - z))
            released = v * decay > bound
    bottom_force = math.nan
    if need_top or not released:
        bottom_force = _evaluate(kind, high, a0, a1, a2, a3, a4, a5, a6, a7)[0]
        released = bottom_force < 0.0
    force_min = bottom_force * rescale
    if not (solve and released):
        return low, high, force_min, math.inf, 0.0
    if closed:
        # The first Halley step from 2φ/ω, in closed form; f > 0 there: 2φ/ω is also a lower
        # bound of the root. Rounding scale of f as in _evaluate: 2ζṽu + |pu(C − 1)| + |qu·S|.
        value = unit * (1.0 + decay)
        slope = -speed * decay
        curvature = unit - value - 2.0 * z * slope
        scale = (start_force + abs(a2 * (decay * (2.0 * z * z - 1.0) - 1.0))
                 + abs(a3 * (2.0 * z * decay)))
        # ξ' = ε(ṽ − 2ζ).
        rate = decay * (speed - 2.0 * z * unit)
        root, rate = _halley(kind, a0, a1, a2, a3, a4, a5, a6, a7, low, high, start, -1.0,
                             True, value, slope, curvature, scale, rate)
    else:
        if not near:
            # f at the bracket's lower end: 2ζṽ at impact, else one more evaluation.
            top_force = start_force
            if low > 0.0:
                top_force = _evaluate(kind, low, a0, a1, a2, a3, a4, a5, a6, a7)[0]
            start = _phase_start(low, high, top_force, bottom_force)
        root, rate = _halley(kind, a0, a1, a2, a3, a4, a5, a6, a7, low, high, start, -1.0,
                             False, 0.0, 0.0, 0.0, 0.0, 0.0)
    return low, high, force_min, root, rate * rescale


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
        ξ'(τ)/ṽ where it rebounds (if `solve`), 0 elsewhere.
    """
    n = zeta.size
    t_min, t_max, xi_max = np.empty(n), np.empty(n), np.empty(n)
    tau, rebound_ratio = np.empty(n), np.empty(n)
    for i in range(n):
        low, high, top, root, rate = _ib_point(zeta[i], vtilde[i], solve, True)
        t_min[i], t_max[i], xi_max[i], tau[i] = low, high, top, root
        rebound_ratio[i] = rate / vtilde[i]
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
    t_lo, t_hi, force_min = np.empty(n), np.empty(n), np.empty(n)
    tau, release_slope = np.empty(n), np.empty(n)
    for i in range(n):
        low, high, bottom, root, rate = _iib_point(zeta[i], vtilde[i], solve, True)
        t_lo[i], t_hi[i], force_min[i], tau[i], release_slope[i] = low, high, bottom, root, rate
    return t_lo, t_hi, force_min, tau, release_slope


# --- the end-of-contact state: restitution from the decay of the invariant ---------------------

@_jit
def _from_invariant(eps, vtilde):
    """Where the restitution from the decay of the invariant beats the rebound slope ξ'(τ)."""
    return eps > 0.5 or vtilde * eps < 4.0 / vtilde


@_jit
def _invariant_roots(zeta, vtilde, tau, loss):
    """Restitution from the decay of the quadratic invariant over the contact.

    With Y = X/ṽ² = (1 − 2ζ/ṽ)e^{−2ζτ} + expm1(−2ζτ)/ṽ² and a = ζ/ṽ, the rebound state solves
    ε² − 2σaε = Y. For the models ending at ξ = 0 (σ = −1, Ib) ε = Y/(a + √(a² + Y)); for a
    release at F = 0 (σ = +1, IIb), where the invariant is vf² − 2ζvf + 1, ε = a + √(a² + Y),
    or, where Y < 0 leaves two positive roots, possibly the smaller −Y/(a + √(a² + Y)).
    Written without cancellation except the one inherent in Y near capture. `loss` is
    expm1(−2ζτ).

    Returns
    -------
    y, small, large : float
        Y, Y/(a + √(a² + Y)) and a + √(a² + Y).
    """
    decay = math.exp(-2.0 * zeta * tau)
    ratio = zeta / vtilde
    y = (1.0 - 2.0 * ratio) * decay + loss / vtilde / vtilde
    large = ratio + math.sqrt(max(ratio * ratio + y, 0.0))
    return y, (y / large if large > 0.0 else 0.0), large


@_jit
def _dissipated(zeta, vtilde, loss):
    """P(0)(1 − e^{−2ζτ})/ṽ: the invariant lost over the contact, with
    P(0)/ṽ = ((ṽ − ζ)² + 1 − ζ²)/ṽ written without overflow or cancellation; `loss` is
    expm1(−2ζτ)."""
    shifted = vtilde - zeta
    start = shifted * (shifted / vtilde) + (1.0 - zeta) * (1.0 + zeta) / vtilde
    return start * (-loss)


@_jit
def ib_collide(zeta, vtilde):
    """Restitution, contact time and capture of model Ib, point by point.

    Parameters
    ----------
    zeta, vtilde : ndarray of float64
        Damping ratio ζ >= 0 and impact speed ṽ > 0 (dimensionless), same shape, 1-d.

    Returns
    -------
    eps, one_minus_eps, contact_time, captured, release_depth, release_speed : ndarray
        The fields of :class:`dashpot.physics.models.Collision`.
    """
    n = zeta.size
    eps, one_minus, contact_time = np.empty(n), np.empty(n), np.empty(n)
    captured, release_depth, release_speed = np.empty(n, np.bool_), np.empty(n), np.empty(n)
    for i in range(n):
        z, v = zeta[i], vtilde[i]
        tau, rate = _ib_point(z, v, True, False)[3:]
        contact_time[i] = tau
        if not math.isfinite(tau):
            eps[i], one_minus[i], captured[i] = 0.0, 1.0, True
            release_depth[i], release_speed[i] = -1.0, 0.0
            continue
        # ε = ξ'(τ)/ṽ; clip the last ulp of a near-tangent return.
        direct = max(rate / v, 0.0)
        # The quadratic invariant P = η'² + 2ζηη' + η² of the homogeneous part η = ξ + 1
        # decays as P(τ) = P(0)e^{−2ζτ}. With η = 1 at both ends, w = ṽε solves
        # w² + 2ζw = X with X = ṽ(ṽ − 2ζ)e^{−2ζτ} + expm1(−2ζτ): hardly sensitive to the last
        # ulp of τ, unlike ξ'(τ), whose error |ξ''|·δτ with δτ ~ ulp/ξ'(τ) is ~ulp/(ṽ²ε²)
        # relative. Taken where ε > ½ or ṽ²ε < 4 (slow impacts); scaled by ṽ² so that nothing
        # overflows.
        loss = math.expm1(-2.0 * z * tau)
        e = (max(_invariant_roots(z, v, tau, loss)[1], 0.0) if _from_invariant(direct, v)
             else direct)
        # 1 − ε from the same decay: ṽ(1 − ε) = 2ζ + P(0)(1 − e^{−2ζτ})/(ṽ(1 + ε)). All terms
        # are positive: no cancellation for nearly elastic balls.
        eps[i] = e
        one_minus[i] = (2.0 * z + _dissipated(z, v, loss) / (1.0 + e)) / v
        captured[i] = False
        release_depth[i], release_speed[i] = 0.0, e * v
    return eps, one_minus, contact_time, captured, release_depth, release_speed


@_jit
def iib_collide(zeta, vtilde, hybrid):
    """Restitution, contact time and capture of model IIb or of the hybrid, point by point.

    The hybrid is released as IIb, then climbs back to z = R under gravity.

    Parameters
    ----------
    zeta, vtilde : ndarray of float64
        Damping ratio ζ >= 0 and impact speed ṽ > 0 (dimensionless), same shape, 1-d.
    hybrid : bool
        The hybrid model instead of IIb.

    Returns
    -------
    eps, one_minus_eps, contact_time, captured, release_depth, release_speed : ndarray
        The fields of :class:`dashpot.physics.models.Collision`.
    """
    n = zeta.size
    eps, one_minus, contact_time = np.empty(n), np.empty(n), np.empty(n)
    captured, release_depth, release_speed = np.empty(n, np.bool_), np.empty(n), np.empty(n)
    for i in range(n):
        z, v = zeta[i], vtilde[i]
        tau, direct = _iib_point(z, v, True, False)[3:]
        if not math.isfinite(tau):
            eps[i], one_minus[i], contact_time[i], captured[i] = 0.0, 1.0, math.inf, True
            release_depth[i], release_speed[i] = -1.0, 0.0
            continue
        # At F = 0, ξ = −2ζξ' makes the invariant P(τ) = vf² − 2ζvf + 1: vf follows from its
        # decay where that beats ξ'(τ) (see ib_collide), and (ṽ − vf)(ṽ + vf − 2ζ) =
        # P(0)(1 − e^{−2ζτ}) gives 1 − ε where the second factor keeps its digits. Where the
        # invariant has a single positive root in the range where it is the better estimate,
        # ξ'(τ) is not needed.
        loss = math.expm1(-2.0 * z * tau)
        y, small, large = _invariant_roots(z, v, tau, loss)
        if y >= 0.0 and _from_invariant(large, v):
            vf = v * large
        else:
            invariant = large if (y >= 0.0 or direct > z) else -small
            vf = v * invariant if _from_invariant(direct / v, v) else direct
        # Halved (exactly) so that ṽ + vf cannot overflow near the float maximum.
        half_sum = 0.5 * v + 0.5 * vf
        denominator = half_sum - z
        if denominator > 0.5 * half_sum:
            deficit = (0.5 * _dissipated(z, v, loss)) / denominator
        else:
            deficit = 1.0 - vf / v
        release_depth[i], release_speed[i] = -2.0 * (z * vf), vf
        if not hybrid:
            eps[i], one_minus[i], contact_time[i], captured[i] = vf / v, deficit, tau, False
        elif vf > 4.0 * z:
            # Climbing |ξ_f| = 2ζvf under gravity: v1² = vf² − 4ζvf (rebound only if vf > 4ζ).
            v1 = vf * math.sqrt(1.0 - 4.0 * z / vf)
            # Climb time (vf − v1)/g rationalised: 4ζvf/(vf + v1), no cancellation at large ṽ;
            # the sum halved so that it cannot overflow.
            climb = 2.0 * z * (vf / (0.5 * vf + 0.5 * v1))
            e = v1 / v
            eps[i], contact_time[i], captured[i] = e, tau + climb, False
            # 1 − ε = ((ṽ − vf) + (vf − v1))/ṽ: both terms >= 0 where ṽ >= vf; elsewhere ε is
            # far from 1.
            one_minus[i] = deficit + climb / v if deficit >= 0.0 else 1.0 - e
        else:
            eps[i], one_minus[i], contact_time[i], captured[i] = 0.0, 1.0, math.inf, True
    return eps, one_minus, contact_time, captured, release_depth, release_speed
