"""Where a contact ends: brackets of the end-of-contact root of models Ib, IIa and IIb, and the
bracketed Halley iteration that :mod:`dashpot.physics.models` solves in them.

Shared by the closed forms of :mod:`dashpot.physics.models` and the direct integration of
:mod:`dashpot.physics.ode` (which takes its integration windows from these brackets), so that
neither imports the other. All quantities are dimensionless: time in 1/ω0, speed in v* = g/ω0.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   sections 3-4 (models Ia, Ib, IIa, IIb, hybrid; capture).
.. [2] T. Schwager and T. Pöschel, "Coefficient of restitution and linear-dashpot model
   revisited", Granular Matter 9, 465-469 (2007) (model IIa).
"""

from __future__ import annotations

import numpy as np

from .contact import Damping, basis, derivative, first_zero

# The models with gravity in contact (see the table of dashpot.physics.models).
GRAVITY_MODELS = ("Ib", "IIb", "hybrid")


# --- root finding in a bracket ---------------------------------------------------------------

def _halley_in_bracket(value_and_slope, lower, upper, args, *, increasing, start,
                       max_iter=200):
    """Root of a function monotone on [lower, upper], by Halley steps kept inside the bracket.

    The hot path of :func:`dashpot.physics.models.collide`. With slope and curvature available
    in closed form, Halley's iteration converges cubically from a good start (typically 2
    evaluations, against ~17 for Chandrupatla's derivative-free method), which is what makes 10⁶
    impacts per second possible. Any step leaving the current bracket is replaced by bisection,
    so convergence is guaranteed. Iteration stops when f is at its rounding level, when the step
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


# --- model IIa: contact time, gravity-free -----------------------------------------------------

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


# --- model Ib: ξ returns to zero, with gravity ----------------------------------------------

def _ib_excess(t, zeta, vtilde):
    """ξ(t) with gravity: η(t) − 1 where η = C + (ζ − ṽ)S is the homogeneous part ξ + 1."""
    d = Damping(zeta)
    # ξ = (C − 1) + (ζ − ṽ)S: near the critical speed ξ returns to ~0 at C ≈ 1, so C − 1 must
    # keep its digits (it decides capture at |ṽ/ṽc − 1| ~ 1e-9).
    _, S, offset = basis(d, t, offset=True)
    return offset + (zeta - vtilde) * S


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
