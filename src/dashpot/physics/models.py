"""The five linear-dashpot contact models: restitution, contact time, capture.

Models (the paper's table letters in brackets):

======  ==================  =====================  ==========================================
model   gravity in contact  contact ends           rebound speed
======  ==================  =====================  ==========================================
Ia (A)  no                  ξ returns to 0         ξ' there
Ib (B)  yes                 ξ returns to 0         ξ' there
IIa (C) no                  F = 0                  ξ' there
IIb (D) yes                 F = 0                  ξ' there (ball still below z = R)
hybrid  yes                 F = 0, as IIb          speed on regaining z = R: √(vf² − 2|ξ_f|)
======  ==================  =====================  ==========================================

All quantities are dimensionless: time in 1/ω0, speed in v* = g/ω0, length in g/ω0².

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   sections 3-4 (models Ia, Ib, IIa, IIb, hybrid; capture).
.. [2] T. Schwager and T. Pöschel, "Coefficient of restitution and linear-dashpot model
   revisited", Granular Matter 9, 465-469 (2007) (model IIa).
.. [3] M. Nagurka and S. Huang, "A mass-spring-damper model of a bouncing ball",
   Proc. American Control Conference 2004, 499-504 (model Ia).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import elementwise

from .._validation import check_model, check_nonnegative, check_positive
from .contact import Damping, basis, derivative, first_zero

__all__ = ["MODELS", "Collision", "collide", "critical_velocity"]

MODELS = ("Ia", "Ib", "IIa", "IIb", "hybrid")
"""Names of the contact models, in the paper's table order (A, B, C, D, hybrid)."""

GRAVITY_MODELS = ("Ib", "IIb", "hybrid")

# Relative accuracy the exact method achieves against the 40-digit reference across the tested
# range (ε, 1 − ε, contact time), away from the ill-conditioned neighbourhood of the critical speed.
EXACT_RTOL = 1e-13

LOG_FLOAT_MAX = np.log(np.finfo(float).max)


@dataclass(frozen=True)
class Collision:
    """Outcome of one impact under a contact model (dimensionless; arrays broadcast).

    Attributes
    ----------
    model : str
        Contact model name.
    eps : ndarray
        Coefficient of restitution ε = rebound speed / impact speed; 0 where captured.
    one_minus_eps : ndarray
        1 − ε, computed without cancellation (keeps its digits for nearly elastic contacts).
    contact_time : ndarray
        Dimensionless contact duration ω0·τ: time of nonzero compression (Ia, Ib, hybrid) or of
        nonzero force (IIa, IIb); inf where captured.
    captured : ndarray of bool
        True where the ball does not rebound (inelastic capture).
    release_depth : ndarray
        Compression ξ at the end of the contact in units of g/ω0² (<= 0): 0 for Ia and Ib;
        the depth where the force vanishes for IIa, IIb and the hybrid (ξ = −2ζ·release_speed).
        Where the ball is captured without release it settles at rest at the static
        equilibrium: −1 with gravity, 0 without.
    release_speed : ndarray
        ξ' at the end of the contact in units of v* (the speed where the force vanishes for the
        force-ending models and the hybrid, ε·ṽ for Ia and Ib); 0 where captured without release.
    method : str
        "exact" or "ode".
    rtol : float
        Relative accuracy of the method: the tested bound for "exact", the integration tolerance
        for "ode".
    """

    model: str
    eps: np.ndarray
    one_minus_eps: np.ndarray
    contact_time: np.ndarray
    captured: np.ndarray
    release_depth: np.ndarray
    release_speed: np.ndarray
    method: str
    rtol: float


def _find_root(func, lower, upper, args):
    """Vectorized bracketed root at machine precision (Chandrupatla, scipy elementwise)."""
    if lower.size == 0:
        return lower.copy()
    result = elementwise.find_root(func, (lower, upper), args=args)
    return result.x


def _halley_in_bracket(value_and_slope, lower, upper, args, *, increasing, start,
                       max_iter=200):
    """Root of a function monotone on [lower, upper], by Halley steps kept inside the bracket.

    The hot path of :func:`collide`. With slope and curvature available in closed form,
    Halley's iteration converges cubically from a good start (typically 2 evaluations,
    against ~17 for Chandrupatla's derivative-free method), which is what makes 10⁶ impacts
    per second possible. Any step leaving the current bracket is replaced by bisection, so
    convergence is guaranteed. Iteration stops when f is at its rounding level, when the step
    is below 4 ulp, when the bracket closes, or when the step just taken leaves an estimated
    error 4|f''²/4f'² − f'''/6f'|·|δ|³ below one ulp of the root.

    Parameters
    ----------
    value_and_slope : callable
        ``value_and_slope(t, *args) -> (f, f', f'', f''', scale)`` on arrays, where `scale` is
        the size of the terms summed in f (its rounding error is a few ulp of `scale`).
    lower, upper : ndarray
        Bracket with sign(f(lower)) = −sign(f(upper)).
    args : tuple of ndarray
        Per-point parameters, the shape of `lower`.
    increasing : bool
        Whether f rises across the bracket.
    start : ndarray
        First iterate, inside the bracket.
    """
    root = start.copy()
    # The working set shrinks as points converge; it is compacted once per iteration rather
    # than gathered from the full arrays.
    active = np.arange(root.size)
    t, lo, hi = start, lower, upper
    sign = 1.0 if increasing else -1.0
    tiny = np.finfo(float).eps
    for _ in range(max_iter):
        if active.size == 0:
            break
        value, slope, curvature, third, scale = value_and_slope(t, *args)
        value, slope, curvature, third = sign * value, sign * slope, sign * curvature, sign * third
        below = value < 0.0
        lo = np.where(below, t, lo)
        hi = np.where(below, hi, t)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            newton = value / slope
            # Halley's correction uses the closed-form curvature: cubic convergence.
            bend = 0.5 * curvature / slope
            correction = 1.0 - newton * bend
            step = np.where(correction > 0.5, newton / correction, newton)
            # Error left after this step: Halley's e' = (f''²/4f'² − f'''/6f')·e³, with a
            # safety factor of 4.
            remaining = 4.0 * np.abs(bend * bend - third / (6.0 * slope)) * np.abs(step) ** 3
        candidate = t - step
        inside = (candidate > lo) & (candidate < hi) & np.isfinite(candidate)
        # A step below a few ulp means the root is found to the precision of f itself;
        # testing the step, not the new iterate, avoids bisecting on rounding noise.
        converged = ((np.abs(value) <= 4.0 * tiny * scale)
                     | (np.abs(step) <= 4.0 * tiny * np.abs(t))
                     | (inside & (remaining <= tiny * np.abs(candidate))))
        new = np.where(converged, np.where(value == 0.0, t, candidate),
                       np.where(inside, candidate, 0.5 * (lo + hi)))
        done = converged | (hi - lo <= 4.0 * tiny * np.abs(t))
        root[active[done]] = new[done]
        keep = ~done
        active, t, lo, hi = active[keep], new[keep], lo[keep], hi[keep]
        args = tuple(a[keep] for a in args)
    root[active] = t
    return root


def _start_guess(lower, upper, value_upper, gravity_free_time, vtilde, value_at):
    """First iterate for Halley's method inside [lower, upper].

    At high impact speed gravity is a small correction, O(1/ṽ), and the gravity-free twin's
    closed-form end time is nearly the root. Otherwise, between consecutive extrema an
    oscillation is close to a half cosine wave: with end values a and b, rising or falling, the
    root is at the fraction arccos((a + b)/(b − a))/π of the bracket. ``value_at(index)``
    gives a = f(lower) of the points in `index`; it is called only where it is needed.
    """
    start = gravity_free_time.copy()
    slow = np.flatnonzero((vtilde <= 20.0) | (gravity_free_time <= lower)
                          | (gravity_free_time >= upper))
    a, b, lo = value_at(slow), value_upper[slow], lower[slow]
    phase = np.arccos(np.clip((a + b) / (b - a), -1.0, 1.0)) / np.pi
    start[slow] = lo + np.clip(phase, 0.05, 0.95) * (upper[slow] - lo)
    return start


def _from_invariant(eps, vtilde):
    """Where the restitution from the decay of the invariant beats the rebound slope ξ'(τ)."""
    return (eps > 0.5) | (vtilde * eps < 4.0 / vtilde)


def _invariant_roots(zeta, vtilde, tau):
    """Restitution from the decay of the quadratic invariant over the contact.

    With Y = X/ṽ² = (1 − 2ζ/ṽ)e^{−2ζτ} + expm1(−2ζτ)/ṽ² and a = ζ/ṽ, the rebound state solves
    ε² − 2σaε = Y. For the models ending at ξ = 0 (σ = −1, Ib) ε = Y/(a + √(a² + Y)); for a
    release at F = 0 (σ = +1, IIb), where the invariant is vf² − 2ζvf + 1, ε = a + √(a² + Y),
    or, where Y < 0 leaves two positive roots, possibly the smaller −Y/(a + √(a² + Y)).
    Written without cancellation except the one inherent in Y near capture.

    Returns
    -------
    y : ndarray
        Y.
    small, large : ndarray
        Y/(a + √(a² + Y)) and a + √(a² + Y).
    """
    decay = np.exp(-2.0 * zeta * tau)
    ratio = zeta / vtilde
    y = (1.0 - 2.0 * ratio) * decay + np.expm1(-2.0 * zeta * tau) / vtilde / vtilde
    root = np.sqrt(np.maximum(ratio * ratio + y, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        small = np.where(ratio + root > 0.0, y / (ratio + root), 0.0)
    return y, small, ratio + root


def _stable_p0_over_v(zeta, omega2, vtilde):
    """(ṽ² − 2ζṽ + 1)/ṽ = ((ṽ − ζ)² + 1 − ζ²)/ṽ, without overflow or cancellation."""
    shifted = vtilde - zeta
    return shifted * (shifted / vtilde) + omega2 / vtilde


# --- model Ia and IIa: closed forms, gravity-free -------------------------------------------

def _model_ia(zeta, vtilde):
    d = Damping(zeta)
    safe_omega = np.where(d.under, d.omega, 1.0)
    tau = np.where(d.under, np.pi / safe_omega, np.inf)
    exponent = np.where(d.under, zeta * np.pi / safe_omega, np.inf)
    eps = np.exp(-exponent)
    one_minus = -np.expm1(-exponent)
    captured = ~d.under
    return dict(eps=eps, one_minus_eps=one_minus, contact_time=tau, captured=captured,
                release_depth=np.zeros_like(eps), release_speed=eps * vtilde)


def _iia_contact_time(d: Damping):
    """ω0·τ of model IIa: 2·arccos(ζ)/√(1 − ζ²), continued through ζ = 1.

    Below ζ = 1 the paper's arccos(2ζ² − 1)/ω equals 2φ/ω with φ = atan2(ω, ζ) (no
    cancellation at either end); above, 2ψ/s with ψ = arccosh ζ = log1p(ζ − 1 + s); exactly 2 at
    ζ = 1 [2]_.
    """
    safe_omega = np.where(d.under, d.omega, 1.0)
    safe_s = np.where(d.over, d.s, 1.0)
    t_under = 2.0 * np.arctan2(d.omega, d.zeta) / safe_omega
    t_over = 2.0 * np.log1p(np.where(d.over, (d.zeta - 1.0) + d.s, 0.0)) / safe_s
    return np.where(d.under, t_under, np.where(d.over, t_over, 2.0))


def _model_iia(zeta, vtilde):
    d = Damping(zeta)
    tau = _iia_contact_time(d)
    eps = np.exp(-zeta * tau)
    # ξ'(τ) = −(C − ζS)·ṽ reduces to ε·ṽ: at ωτ = 2φ the oscillation factor is exactly −1.
    release_speed = eps * vtilde
    return dict(eps=eps, one_minus_eps=-np.expm1(-zeta * tau), contact_time=tau,
                captured=np.zeros(eps.shape, bool), release_depth=-2.0 * zeta * release_speed,
                release_speed=release_speed)


# --- model Ib: ξ returns to zero, with gravity ----------------------------------------------

def _ib_excess(t, zeta, vtilde):
    """ξ(t) with gravity: η(t) − 1 where η = C + (ζ − ṽ)S is the homogeneous part ξ + 1."""
    d = Damping(zeta)
    # ξ = (C − 1) + (ζ − ṽ)S: near the critical speed ξ returns to ~0 at C ≈ 1, so C − 1 must
    # keep its digits (it decides capture at |ṽ/ṽc − 1| ~ 1e-9).
    _, S, offset = basis(d, t, offset=True)
    return offset + (zeta - vtilde) * S


def _ib_excess_and_slope(t, zeta, vtilde):
    """ξ(t), ξ'(t) = −ṽC + (ζṽ − 1)S, ξ'' and ξ''' with gravity, from one evaluation of C, S."""
    d = Damping(zeta)
    c, S, offset = basis(d, t, offset=True)
    drop = (zeta - vtilde) * S
    excess = offset + drop
    slope = -vtilde * c + (zeta * vtilde - 1.0) * S
    # ξ'' = −1 − ξ − 2ζξ' from the equation of motion.
    curvature = -1.0 - excess - 2.0 * zeta * slope
    third = -slope - 2.0 * zeta * curvature
    return excess, slope, curvature, third, np.abs(offset) + np.abs(drop)


def _ib_bracket(zeta, vtilde):
    """Bracket [t_min, t_max] of Ib's return root and the compression ξ(t_max) deciding capture.

    ξ falls to its minimum at the first zero of ξ' (closed form) and then rises monotonically to
    the next maximum, half a damped period later. The ball rebounds iff ξ(t_max) > 0; over- and
    critically damped, ξ has no second extremum and never returns (capture at every speed).
    """
    d = Damping(zeta)
    slope_p, slope_q = derivative(d, 1.0, zeta - vtilde)
    t_min = first_zero(d, slope_p, slope_q)
    t_max = t_min + d.half_period
    finite = np.isfinite(t_max)
    xi_max = np.full(zeta.shape, -np.inf)
    xi_max[finite] = _ib_excess(t_max[finite], zeta[finite], vtilde[finite])
    return t_min, t_max, xi_max


def _model_ib(zeta, vtilde):
    t_min, t_max, xi_max = _ib_bracket(zeta, vtilde)
    rebound = xi_max > 0.0
    tau = np.full(zeta.shape, np.inf)
    lo, hi = t_min[rebound], t_max[rebound]
    args = (zeta[rebound], vtilde[rebound])
    start = _start_guess(lo, hi, xi_max[rebound], np.pi / Damping(args[0]).omega, args[1],
                         lambda i: _ib_excess(lo[i], *(a[i] for a in args)))
    tau[rebound] = _halley_in_bracket(_ib_excess_and_slope, lo, hi, args, increasing=True,
                                      start=start)
    eps = np.zeros(zeta.shape)
    one_minus = np.ones(zeta.shape)
    z, v, t = zeta[rebound], vtilde[rebound], tau[rebound]
    dr = Damping(z)
    c, S = basis(dr, t)
    # ε = ξ'(τ)/ṽ with ξ' = −ṽC + (ζṽ − 1)S; clip the last ulp of a near-tangent return.
    direct = np.maximum(-c + z * S - S / v, 0.0)
    # The quadratic invariant P = η'² + 2ζηη' + η² of the homogeneous part η = ξ + 1 decays as
    # P(τ) = P(0)e^{−2ζτ}. With η = 1 at both ends, w = ṽε solves w² + 2ζw = X with
    # X = ṽ(ṽ − 2ζ)e^{−2ζτ} + expm1(−2ζτ): hardly sensitive to the last ulp of τ, unlike
    # ξ'(τ), whose error |ξ''|·δτ with δτ ~ ulp/ξ'(τ) is ~ulp/(ṽ²ε²) relative. Taken where
    # ε > ½ or ṽ²ε < 4 (slow impacts); scaled by ṽ² so that nothing overflows.
    e = np.where(_from_invariant(direct, v), np.maximum(_invariant_roots(z, v, t)[1], 0.0),
                 direct)
    # 1 − ε from the same decay: ṽ(1 − ε) = 2ζ + P(0)(1 − e^{−2ζτ})/(ṽ(1 + ε)). All terms
    # are positive: no cancellation for nearly elastic balls.
    dissipated = _stable_p0_over_v(z, -dr.s2, v) * (-np.expm1(-2.0 * z * t))
    deficit = (2.0 * z + dissipated / (1.0 + e)) / v
    eps[rebound] = e
    one_minus[rebound] = deficit
    return dict(eps=eps, one_minus_eps=one_minus, contact_time=tau, captured=~rebound,
                release_depth=np.where(rebound, 0.0, -1.0), release_speed=eps * vtilde)


# --- model IIb: force returns to zero, with gravity -----------------------------------------

# Above this damping ratio IIb's functions are evaluated in the overdamped eigenmodes: the slow
# mode of ξ'' is smaller than the fast one by ~1/(16ζ⁴), so in the C, S form it would be lost to
# rounding; below it the eigenmode amplitudes (∝ 1/s) would cancel instead.
MODAL_ZETA = 1.25


def _iib_force_coefficients(d: Damping, vtilde):
    """f(t) = 1 + P·C + Q·S: dimensionless contact force F/(mg) = 1 + ξ''.

    ξ'' solves the homogeneous equation with ξ''(0) = 2ζṽ − 1 and ξ'''(0) = ṽ(1 − 4ζ²) + 2ζ,
    hence P = 2ζṽ − 1 and Q = ξ'''(0) + ζP = ζ + ṽ(1 − 2ζ²).
    """
    zeta = d.zeta
    return 2.0 * zeta * vtilde - 1.0, zeta + vtilde * (1.0 - 2.0 * zeta * zeta)


def _eigenmodes(zeta, vtilde):
    """Overdamped decay rates and amplitudes of η = ξ + 1 = a·e^{−λs·t} + b·e^{−λf·t}.

    λf = ζ + s, λs = 1/λf (= ζ − s without cancellation), a = (λf − ṽ)/(2s),
    b = (ṽ − λs)/(2s), from η(0) = 1, η'(0) = −ṽ. The k-th derivative multiplies a by (−λs)^k
    and b by (−λf)^k.
    """
    s = np.sqrt((zeta - 1.0) * (zeta + 1.0))
    fast = zeta + s
    slow = 1.0 / fast
    return slow, fast, (fast - vtilde) / (2.0 * s), (vtilde - slow) / (2.0 * s)


def _force_and_slope_cs(t, zeta, start_force, p, q, slope_p, slope_q):
    """f = 2ζṽ + p(C − 1) + qS of model IIb, its first three derivatives and rounding scale.

    Written with C − 1 (1 + p = 2ζṽ) so that f keeps its digits where it touches zero at C ≈ 1
    (slow, lightly damped impacts near the critical speed). For ζ < MODAL_ZETA.
    """
    d = Damping(zeta)
    c, S, offset = basis(d, t, offset=True)
    spring, damper = p * offset, q * S
    value = start_force + spring + damper
    slope = slope_p * c + slope_q * S
    # f − 1 = ξ'' solves the homogeneous equation: (f − 1)'' = −(f − 1) − 2ζ(f − 1)'.
    curvature = 1.0 - value - 2.0 * zeta * slope
    third = -slope - 2.0 * zeta * curvature
    return value, slope, curvature, third, start_force + np.abs(spring) + np.abs(damper)


def _force_and_slope_modal(t, slow, fast, slow_amplitude, fast_amplitude):
    """f = 1 + A·e^{−λs·t} + B·e^{−λf·t} of model IIb and its derivatives (ζ >= MODAL_ZETA)."""
    slow_part = slow_amplitude * np.exp(-slow * t)
    fast_part = fast_amplitude * np.exp(-fast * t)
    return (1.0 + slow_part + fast_part, -slow * slow_part - fast * fast_part,
            slow**2 * slow_part + fast**2 * fast_part, -(slow**3) * slow_part - fast**3 * fast_part,
            1.0 + np.abs(slow_part) + np.abs(fast_part))


def _iib_cs(zeta, vtilde):
    """Bracket and force evaluator of IIb for ζ < MODAL_ZETA (C, S form).

    The force first rises or falls (sign of f'(0), or of the next coefficient where f'(0) = 0);
    its first minimum follows the first maximum by half a damped period, or is the first
    extremum itself. Between them f is monotone, and later minima are shallower (the
    oscillation decays), so the ball is released iff f(t_hi) < 0. A critically or over-damped
    force has at most one extremum: if it rises first it never returns below f(0) = 2ζṽ > 0.

    Returns
    -------
    t_lo, t_hi : ndarray
        Bracket of the release (t_hi = inf where there is no force minimum).
    evaluate : callable
        ``evaluate(t, mask)`` -> (f, f', f'', scale) at times `t` of the points in `mask`.
    args : tuple
        Per-point coefficients for ``_force_and_slope_cs``.
    """
    d = Damping(zeta)
    p, q = _iib_force_coefficients(d, vtilde)
    slope_p, slope_q = derivative(d, p, q)
    falls_first = (slope_p < 0.0) | ((slope_p == 0.0) & (slope_q < 0.0))
    t_first = first_zero(d, slope_p, slope_q)
    t_lo = np.where(falls_first, 0.0, t_first)
    t_hi = np.where(falls_first, t_first, t_first + d.half_period)
    return t_lo, t_hi, _force_and_slope_cs, (zeta, 2.0 * zeta * vtilde, p, q, slope_p, slope_q)


def _iib_modal(zeta, vtilde):
    """Bracket and force evaluator of IIb for ζ >= MODAL_ZETA (eigenmode form).

    The force has at most one extremum; if it falls first, its minimum is at
    e^{2st} = −λf³b/(λs³a), which needs a and b of opposite signs. See :func:`_iib_cs`.
    """
    slow, fast, a, b = _eigenmodes(zeta, vtilde)
    falls_first = slow**3 * a + fast**3 * b > 0.0
    opposite = falls_first & ((a < 0.0) != (b < 0.0)) & (a != 0.0) & (b != 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_min = (np.log(np.abs(b)) - np.log(np.abs(a)) + 6.0 * np.log(fast)) / (fast - slow)
    t_hi = np.where(opposite & (t_min > 0.0), t_min, np.inf)
    return (np.zeros(zeta.shape), t_hi, _force_and_slope_modal,
            (slow, fast, slow * slow * a, fast * fast * b))


def _iib_release(zeta, vtilde, *, solve=True):
    """Bracket, force minimum and (if `solve`) release time of IIb, by regime.

    Returns
    -------
    t_lo, t_hi : ndarray
        Bracket of the release root.
    force_min : ndarray
        f(t_hi), or min(f(0), 1) = min(2ζṽ, 1) where the force has no minimum; the ball is
        released iff it is negative.
    tau : ndarray
        Release time where released, inf elsewhere (only computed if `solve`).
    """
    modal = zeta >= MODAL_ZETA
    t_lo, t_hi = np.zeros(zeta.shape), np.full(zeta.shape, np.inf)
    force_min = np.minimum(2.0 * zeta * vtilde, 1.0)
    tau = np.full(zeta.shape, np.inf)
    for group, regime in ((~modal, _iib_cs), (modal, _iib_modal)):
        if not group.any():
            continue
        idx = np.flatnonzero(group)
        lo, hi, evaluate, args = regime(zeta[idx], vtilde[idx])
        t_lo[idx], t_hi[idx] = lo, hi
        finite = np.flatnonzero(np.isfinite(hi))
        f_hi = evaluate(hi[finite], *(a[finite] for a in args))[0]
        force_min[idx[finite]] = f_hi
        if not solve:
            continue
        keep = finite[f_hi < 0.0]
        lo_r, hi_r = lo[keep], hi[keep]
        z_r, v_r = zeta[idx[keep]], vtilde[idx[keep]]

        def force_at_lower(i):
            # 2ζṽ at impact, else one more evaluation.
            value = 2.0 * z_r[i] * v_r[i]
            later = np.flatnonzero(lo_r[i] > 0.0)
            value[later] = evaluate(lo_r[i][later], *(a[keep[i][later]] for a in args))[0]
            return value

        start = _start_guess(lo_r, hi_r, f_hi[f_hi < 0.0], _iia_contact_time(Damping(z_r)),
                             v_r, force_at_lower)
        tau[idx[keep]] = _halley_in_bracket(evaluate, lo_r, hi_r, tuple(a[keep] for a in args),
                                            increasing=False, start=start)
    return t_lo, t_hi, force_min, tau


def _iib_bracket(zeta, vtilde):
    """Bracket [t_lo, t_hi] of IIb's release root and the force minimum f(t_hi)."""
    t_lo, t_hi, force_min, _ = _iib_release(zeta, vtilde, solve=False)
    return t_lo, t_hi, force_min


def _eta_slope(t, zeta, vtilde):
    """ξ'(t) with gravity: −ṽC + (ζṽ − 1)S, or −λs·a·e^{−λs·t} − λf·b·e^{−λf·t}."""
    modal = zeta >= MODAL_ZETA
    out = np.empty(t.shape)
    cs = ~modal
    c, S = basis(Damping(zeta[cs]), t[cs])
    out[cs] = -vtilde[cs] * c + (zeta[cs] * vtilde[cs] - 1.0) * S
    slow, fast, a, b = _eigenmodes(zeta[modal], vtilde[modal])
    out[modal] = -slow * a * np.exp(-slow * t[modal]) - fast * b * np.exp(-fast * t[modal])
    return out


def _release_state(zeta, vtilde):
    """IIb's release: (released mask, τ, release speed vf, 1 − vf/ṽ), vf = ξ'(τ) at F = 0."""
    _, _, force_min, tau = _iib_release(zeta, vtilde)
    released = force_min < 0.0
    z, v, t = zeta[released], vtilde[released], tau[released]
    # At F = 0, ξ = −2ζξ' makes the invariant P(τ) = vf² − 2ζvf + 1: vf follows from its decay
    # where that beats ξ'(τ) (see _model_ib), and (ṽ − vf)(ṽ + vf − 2ζ) = P(0)(1 − e^{−2ζτ})
    # gives 1 − ε where the second factor keeps its digits. Where the invariant has a single
    # positive root in the range where it is the better estimate, ξ'(τ) is not needed at all.
    y, small, large = _invariant_roots(z, v, t)
    vf = v * large
    check = np.flatnonzero(~((y >= 0.0) & _from_invariant(large, v)))
    direct = _eta_slope(t[check], z[check], v[check])
    invariant = np.where((y[check] >= 0.0) | (direct > z[check]), large[check], -small[check])
    vf[check] = np.where(_from_invariant(direct / v[check], v[check]), v[check] * invariant,
                         direct)
    dissipated = _stable_p0_over_v(z, (1.0 - z) * (1.0 + z), v) * (-np.expm1(-2.0 * z * t))
    denominator = v + vf - 2.0 * z
    usable = denominator > 0.5 * (v + vf)
    relative = dissipated / np.where(usable, denominator, 1.0)
    deficit_ = np.where(usable, relative, 1.0 - vf / v)
    speed = np.zeros(zeta.shape)
    speed[released] = vf
    deficit = np.full(zeta.shape, np.nan)
    deficit[released] = deficit_
    return released, tau, speed, deficit


def _model_iib(zeta, vtilde):
    released, tau, vf, deficit = _release_state(zeta, vtilde)
    eps = np.where(released, vf / vtilde, 0.0)
    one_minus = np.where(released, deficit, 1.0)
    return dict(eps=eps, one_minus_eps=one_minus, contact_time=tau, captured=~released,
                release_depth=np.where(released, -2.0 * zeta * vf, -1.0), release_speed=vf)


def _model_hybrid(zeta, vtilde):
    released, tau_force, vf, deficit = _release_state(zeta, vtilde)
    # Climbing |ξ_f| = 2ζvf under gravity: v1² = vf² − 4ζvf; rebound only if vf > 4ζ.
    rebound = released & (vf > 4.0 * zeta)
    v1 = vf * np.sqrt(np.where(rebound, 1.0 - 4.0 * zeta / np.where(rebound, vf, 1.0), 0.0))
    # Climb time (vf − v1)/g rationalised: 4ζvf/(vf + v1), no cancellation at large ṽ.
    climb = np.where(rebound, 4.0 * zeta * vf / np.where(rebound, vf + v1, 1.0), 0.0)
    eps = v1 / vtilde
    # 1 − ε = ((ṽ − vf) + (vf − v1))/ṽ: both terms >= 0 where ṽ >= vf; elsewhere ε is far from 1.
    summed = deficit + climb / vtilde
    one_minus = np.where(rebound & (deficit >= 0.0), summed, 1.0 - eps)
    one_minus = np.where(rebound, one_minus, 1.0)
    return dict(eps=eps, one_minus_eps=one_minus,
                contact_time=np.where(rebound, tau_force + climb, np.inf), captured=~rebound,
                release_depth=np.where(released, -2.0 * zeta * vf, -1.0), release_speed=vf)


_EXACT = {"Ia": _model_ia, "Ib": _model_ib, "IIa": _model_iia, "IIb": _model_iib,
          "hybrid": _model_hybrid}


def collide(model, zeta, vtilde, *, method="exact", rtol=None):
    """Restitution, contact time and capture of one impact under a linear-dashpot model.

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
        Contact model (see module docstring).
    zeta : array_like
        Damping ratio ζ = β/ω0 (dimensionless), finite and >= 0.
    vtilde : array_like
        Impact speed ṽ = v0/v* with v* = g/ω0 (dimensionless), finite and > 0. Broadcast
        against `zeta`. Ia and IIa do not depend on it except through the release speed.
    method : {"exact", "ode"}, default "exact"
        "exact": closed-form trajectories with vectorized bracketed root finding at machine
        precision (relative error below ``EXACT_RTOL`` = 1e-13 in ε, 1 − ε and contact time
        against a 40-digit reference, except within ~1e-6 of the critical speed where ε ∝
        √(ṽ − ṽc) is ill-conditioned). "ode": direct integration of the equation of motion with
        scipy.integrate.solve_ivp at relative tolerance `rtol`.
    rtol : float, optional
        Integration tolerance for ``method="ode"`` (default 1e-9). Not used by "exact".

    Returns
    -------
    Collision
        ε, 1 − ε, contact time, capture flags, release depth and speed, arrays of the broadcast
        shape.

    Raises
    ------
    ValueError
        Unknown model or method, ζ negative or non-finite, ṽ non-positive or non-finite.

    Notes
    -----
    In contact, ξ'' = −1 − ξ − 2ζξ' (gravity) or ξ'' = −ξ − 2ζξ' (none) with ξ(0) = 0,
    ξ'(0) = −ṽ, and F/(mg) = −ξ − 2ζξ' [1]_. The first end-condition root is bracketed between
    closed-form extrema of ξ (Ib) or F (IIb): capture is decided from the sign there, which is
    exact at the tangency that a grid scan would miss.

    Examples
    --------
    >>> import dashpot
    >>> res = dashpot.collide("Ib", 0.1, [5.0, 23.0])
    >>> bool(res.eps[0] < res.eps[1])  # restitution grows with impact speed under gravity
    True
    """
    model = check_model(model, MODELS)
    zeta = check_nonnegative("zeta", zeta)
    vtilde = check_positive("vtilde", vtilde)
    zeta, vtilde = np.broadcast_arrays(zeta, vtilde)
    shape = zeta.shape
    zeta_flat, vtilde_flat = zeta.ravel().astype(float), vtilde.ravel().astype(float)
    if method == "exact":
        if rtol is not None:
            raise ValueError("rtol is only used by method='ode'; the exact method is always "
                             f"at machine precision (relative error < {EXACT_RTOL:g})")
        fields = _EXACT[model](zeta_flat, vtilde_flat)
        accuracy = EXACT_RTOL
    elif method == "ode":
        from .ode import integrate_collision

        accuracy = 1e-9 if rtol is None else float(rtol)
        if not (1e-13 <= accuracy < 1.0):
            raise ValueError(f"rtol must be in [1e-13, 1), got {rtol!r}")
        fields = integrate_collision(model, zeta_flat, vtilde_flat, accuracy)
    else:
        raise ValueError(f"method must be 'exact' or 'ode', got {method!r}")
    reshaped = {name: np.asarray(value).reshape(shape) for name, value in fields.items()}
    return Collision(model=model, method=method, rtol=accuracy, **reshaped)


# --- critical (capture) speed ---------------------------------------------------------------

def _ib_phase_mismatch(log_v, zeta):
    """Tangency condition of model Ib in y = ln ṽ (ζ < 1); zero at the critical speed.

    At the critical speed ξ returns to 0 with zero velocity at some T. In the rotating frame
    u = η, w = (η' + ζη)/ω of the homogeneous part η = ξ + 1, the flow turns clockwise at rate ω
    and shrinks as e^{−ζt}. From (1, (ζ − ṽ)/ω) at impact to (1, ζ/ω) at T:
    ζT = ½ ln(ω² + (ṽ − ζ)²) and ωT = 2π − atan2(ṽ − ζ, ω) − atan2(ζ, ω). Eliminating T
    leaves this function, strictly increasing in ṽ (derivative ṽ/(ω² + (ṽ − ζ)²)).
    """
    d = Damping(zeta)
    omega = d.omega
    large = log_v > 20.0
    v = np.exp(np.where(large, 0.0, log_v))
    inv_v = np.exp(-np.where(large, log_v, 0.0))
    # ½ ln(ω² + (ṽ − ζ)²) = ½ ln(1 + ṽ(ṽ − 2ζ)); for huge ṽ in terms of 1/ṽ (no overflow).
    shrink_small = 0.5 * np.log1p(v * (v - 2.0 * zeta))
    rest = 1.0 - zeta * inv_v
    shrink_large = log_v + np.log1p(-zeta * inv_v) + 0.5 * np.log1p((omega * inv_v / rest) ** 2)
    shrink = np.where(large, shrink_large, shrink_small)
    turn_small = np.arctan2(v - zeta, omega)
    turn_large = 0.5 * np.pi - np.arctan2(omega * inv_v, rest)
    turn = np.where(large, turn_large, turn_small)
    rotation = 2.0 * np.pi - turn - np.arctan2(zeta, omega)
    return shrink - zeta / omega * rotation


def _critical_ib(zeta):
    out = np.where(zeta < 1.0, 0.0, np.inf)
    active = (zeta > 0.0) & (zeta < 1.0)
    z = zeta[active]
    d = Damping(z)
    ratio = z / d.omega
    lower = np.log(0.5 * np.sqrt(np.pi * ratio))
    upper = np.logaddexp(np.log1p(z), 2.5 * np.pi * ratio) + 1e-3
    log_vc = _find_root(_ib_phase_mismatch, lower, upper, (z,))
    out[active] = np.where(log_vc < LOG_FLOAT_MAX, np.exp(np.minimum(log_vc, LOG_FLOAT_MAX)),
                           np.inf)
    return out


def _iib_margin(log_v, zeta):
    """−f at IIb's force minimum as a function of ln ṽ: > 0 where the ball is released."""
    _, _, force_min = _iib_bracket(zeta, np.exp(log_v))
    return -force_min


def _hybrid_margin(log_v, zeta):
    """Release speed minus the 4ζ needed to climb back to z = R (> 0: hybrid rebounds)."""
    released, _, vf, _ = _release_state(zeta, np.exp(log_v))
    return np.where(released, vf - 4.0 * zeta, -4.0 * zeta)


def _solve_in_log_speed(margin, zeta, log_start, log_min):
    """Root of a margin increasing in ln ṽ: bracket outward from `log_start`, then refine."""
    if zeta.size == 0:
        return zeta.copy()
    bracket = elementwise.bracket_root(margin, log_start, log_start + 1.0, xmin=log_min,
                                       xmax=np.full_like(zeta, 700.0), args=(zeta,))
    found = bracket.success
    log_vc = np.full(zeta.shape, np.inf)
    if np.any(found):
        log_vc[found] = _find_root(margin, bracket.bracket[0][found], bracket.bracket[1][found],
                                   (zeta[found],))
    return log_vc


def _critical_force_models(model, zeta):
    out = np.zeros(zeta.shape)
    active = zeta > 0.0
    z = zeta[active]
    # Start near the small-ζ asymptote ṽc ~ √ζ and where large ζ needs ṽ ~ ζ.
    log_start = np.log(np.sqrt(z) + z)
    log_min = np.full(z.shape, np.log(np.finfo(float).tiny))
    log_iib = _solve_in_log_speed(_iib_margin, z, log_start, log_min)
    if model == "hybrid":
        # The hybrid needs IIb's release and enough speed to climb: search above IIb's ṽc.
        above = np.nextafter(log_iib, np.inf)
        already = _hybrid_margin(above, z) >= 0.0
        log_h = _solve_in_log_speed(_hybrid_margin, z, above + 1e-12, above)
        log_iib = np.where(already, log_iib, log_h)
    out[active] = np.where(log_iib < LOG_FLOAT_MAX, np.exp(np.minimum(log_iib, LOG_FLOAT_MAX)),
                           np.inf)
    return out


def critical_velocity(model, zeta):
    """Dimensionless critical impact speed ṽc below which the ball is captured.

    Parameters
    ----------
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    zeta : array_like
        Damping ratio ζ = β/ω0, finite and >= 0.

    Returns
    -------
    ndarray
        ṽc = vc/v* (v* = g/ω0): 0 where the model always rebounds (Ia for ζ < 1, IIa always,
        every model at ζ = 0), inf where it never does (Ia and Ib for ζ >= 1, and Ib just below
        ζ = 1 where ṽc exceeds the float64 range).

    Notes
    -----
    Ib: closed-form tangency condition solved in ln ṽ (see ``_ib_phase_mismatch``); it grows
    like exp(πζ/√(1 − ζ²)) and diverges as ζ → 1⁻, so Ib captures at every speed from ζ = 1 on
    ([1]_, section "Inelastic capture"). IIb: the speed at which the force minimum touches zero.
    Hybrid: the speed at which IIb's release speed vf equals 4ζ, i.e. just enough to climb the
    release depth |ξ_f| = 2ζvf back to the undeformed position.
    """
    model = check_model(model, MODELS)
    zeta = check_nonnegative("zeta", zeta)
    flat = np.asarray(zeta, dtype=float).ravel()
    if model == "Ia":
        out = np.where(flat < 1.0, 0.0, np.inf)
    elif model == "IIa":
        out = np.zeros(flat.shape)
    elif model == "Ib":
        out = _critical_ib(flat)
    else:
        out = _critical_force_models(model, flat)
    return out.reshape(np.shape(zeta))
