"""Where a contact ends: brackets of the end-of-contact root of models Ib, IIa and IIb, and the
bracketed Halley iteration that :mod:`dashpot.physics.models` solves in them.

Shared by the closed forms of :mod:`dashpot.physics.models` and the direct integration of
:mod:`dashpot.physics.ode` (which takes its integration windows from these brackets), so that
neither imports the other. All quantities are dimensionless: time in 1/ω0, speed in v* = g/ω0.

The brackets of Ib and IIb, the capture decision and the Halley iteration run point by point in
a loop compiled with numba (:mod:`dashpot.physics.exact_kernels`, imported on first use so that
``import dashpot`` does not load numba); this module gives them their array interface and
documents the regimes and the iteration.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   sections 3-4 (models Ia, Ib, IIa, IIb, hybrid; capture).
.. [2] T. Schwager and T. Pöschel, "Coefficient of restitution and linear-dashpot model
   revisited", Granular Matter 9, 465-469 (2007) (model IIa).
"""

from __future__ import annotations

import numpy as np

from .contact import Damping

# The models with gravity in contact (see the table of dashpot.physics.models).
GRAVITY_MODELS = ("Ib", "IIb", "hybrid")


# --- the compiled solvers ----------------------------------------------------------------------

def _kernels():
    """The compiled solvers, imported on first use (numba loads only when a gravity model is
    solved)."""
    from . import exact_kernels

    return exact_kernels


def _flat_pair(zeta, vtilde):
    """ζ and ṽ as contiguous 1-d float64 arrays of their broadcast shape, and that shape."""
    zeta, vtilde = np.broadcast_arrays(np.asarray(zeta, dtype=float),
                                       np.asarray(vtilde, dtype=float))
    return (np.ascontiguousarray(zeta.ravel()), np.ascontiguousarray(vtilde.ravel()),
            zeta.shape)


# --- model IIa: contact time, gravity-free -----------------------------------------------------

def _iia_contact_time(d: Damping):
    """ω0·τ of model IIa: 2·arccos(ζ)/√(1 − ζ²), continued through ζ = 1.

    Below ζ = 1 the paper's arccos(2ζ² − 1)/ω equals 2φ/ω with φ = atan2(ω, ζ) (no
    cancellation at either end); above, 2ψ/s with ψ = arccosh ζ = log1p(ζ − 1 + s); exactly 2 at
    ζ = 1 [2]_. Above ζ = HUGE_ZETA, where ζ² overflows, s = ζ√((1 − 1/ζ)(1 + 1/ζ)) and
    ψ = ln ζ + log1p(s/ζ).
    """
    safe_omega = np.where(d.under, d.omega, 1.0)
    over = d.over & (d.zeta <= HUGE_ZETA)
    safe_s = np.where(over, d.s, 1.0)
    t_under = 2.0 * np.arctan2(d.omega, d.zeta) / safe_omega
    t_over = 2.0 * np.log1p(np.where(over, (d.zeta - 1.0) + d.s, 0.0)) / safe_s
    huge_zeta = np.where(d.zeta > HUGE_ZETA, d.zeta, 2.0 * HUGE_ZETA)
    inverse = 1.0 / huge_zeta
    huge_s = huge_zeta * np.sqrt((1.0 - inverse) * (1.0 + inverse))
    t_huge = 2.0 * (np.log(huge_zeta) + np.log1p(huge_s * inverse)) / huge_s
    return np.where(d.under, t_under,
                    np.where(over, t_over, np.where(d.zeta > HUGE_ZETA, t_huge, 2.0)))


# Above this damping ratio ζ² (and s² = ζ² − 1) overflow.
HUGE_ZETA = 1e150


# --- model Ib: ξ returns to zero, with gravity ----------------------------------------------

def _ib_solve(zeta, vtilde, *, solve=True):
    """Bracket [t_min, t_max] of Ib's return root, ξ(t_max) deciding capture, and the return time.

    ξ falls to its minimum at the first zero of ξ' (closed form) and then rises monotonically to
    the next maximum, half a damped period later. The ball rebounds iff ξ(t_max) > 0; over- and
    critically damped, ξ has no second extremum and never returns (capture at every speed).
    ξ(t) = (C − 1) + (ζ − ṽ)S is evaluated with C − 1 kept to its digits: near the critical
    speed ξ returns to ~0 at C ≈ 1, and that decides capture at |ṽ/ṽc − 1| ~ 1e-9. Where the
    ball rebounds (and `solve`), the return time is found in the bracket by Halley's iteration
    (see :func:`_iib_release`); above ṽ = 20 its first step is taken in closed form from Ia's
    end time π/ω, where ξ = −(1 + ε_Ia), ξ' = ṽε_Ia (a lower bound of the root), and the
    rebound is decided without evaluating ξ(t_max) where ṽ(ṽ − 2ζ)ε_Ia⁴ > 2, sufficient for
    ṽ above the critical speed (see :func:`dashpot.physics.models._ib_phase_mismatch`).

    Returns
    -------
    t_min, t_max : ndarray
        Bracket of the return root (inf where ξ has no maximum).
    xi_max : ndarray
        ξ(t_max), −inf where there is no maximum.
    tau : ndarray
        Contact time where the ball rebounds (if `solve`), inf elsewhere.
    rebound_ratio : ndarray
        ξ'(τ)/ṽ = −C + ζS − S/ṽ where the ball rebounds (if `solve`), 0 elsewhere.
    """
    zeta, vtilde, shape = _flat_pair(zeta, vtilde)
    return tuple(out.reshape(shape) for out in _kernels().ib_solve(zeta, vtilde, solve))


def _ib_bracket(zeta, vtilde):
    """Bracket [t_min, t_max] of Ib's return root and ξ(t_max) (see :func:`_ib_solve`)."""
    return _ib_solve(zeta, vtilde, solve=False)[:3]


# --- model IIb: force returns to zero, with gravity -----------------------------------------

# Above this damping ratio IIb's functions are evaluated in the overdamped eigenmodes: the slow
# mode of ξ'' is smaller than the fast one by ~1/(16ζ⁴), so in the C, S form it would be lost to
# rounding; below it the eigenmode amplitudes (∝ 1/s) would cancel instead.
MODAL_ZETA = 1.25


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


def _iib_release(zeta, vtilde, *, solve=True):
    """Bracket, force minimum and (if `solve`) release time of IIb, by regime.

    The contact force is f = F/(mg) = 1 + ξ'', where ξ'' solves the homogeneous equation with
    ξ''(0) = 2ζṽ − 1 and ξ'''(0) = ṽ(1 − 4ζ²) + 2ζ: f = 1 + pC + qS with p = 2ζṽ − 1 and
    q = ζ + ṽ(1 − 2ζ²), evaluated as 2ζṽ + p(C − 1) + qS so that f keeps its digits where it
    touches zero at C ≈ 1 (slow, lightly damped impacts near the critical speed) [1]_.

    Below ζ = MODAL_ZETA the force first rises or falls (sign of f'(0), or of the next
    coefficient where f'(0) = 0); its first minimum follows the first maximum by half a damped
    period, or is the first extremum itself. Between them f is monotone, and later minima are
    shallower (the oscillation decays), so the ball is released iff f(t_hi) < 0. A critically
    or over-damped force has at most one extremum: if it rises first it never returns below
    f(0) = 2ζṽ > 0. From ζ = MODAL_ZETA on, f = 1 + A·e^{−λs·t} + B·e^{−λf·t} in the
    eigenmodes of :func:`_eigenmodes` (A = λs²a, B = λf²b); if it falls first, its minimum is
    at e^{2st} = −λf³b/(λs³a), which needs a and b of opposite signs.

    The release time is the root of f in [t_lo, t_hi], found by Halley's iteration. At high
    speed (ṽ > 20) gravity is an O(1/ṽ) correction and it starts from IIa's end time 2φ/ω,
    where f = 1 + ε_IIa and f' = −ṽε_IIa in closed form, so that the first step costs no
    evaluation (below ζ = MODAL_ZETA); there a bound on f'' after 2φ/ω decides most releases
    without evaluating f(t_hi) (see :func:`dashpot.physics.exact_kernels._iib_point`);
    otherwise, between consecutive extrema f is close to a half cosine wave, and with end values
    a and b it starts at the fraction arccos((a + b)/(b − a))/π of the bracket. With slope and
    curvature in closed form Halley converges cubically (typically 2 evaluations, against ~17
    for Chandrupatla's derivative-free method). Any step leaving the current bracket is replaced
    by bisection, so convergence is guaranteed. Iteration stops when f is at its rounding level
    (a few ulp of the sum of the magnitudes of its terms), when the step is below 4 ulp, when
    the bracket closes, or when the step just taken leaves an estimated error
    4|f''²/4f'² − f'''/6f'|·|δ|³ below one ulp of the root. Ib's return time is found the same
    way (increasing ξ instead of decreasing f).

    Returns
    -------
    t_lo, t_hi : ndarray
        Bracket of the release root.
    force_min : ndarray
        f(t_hi), or min(f(0), 1) = min(2ζṽ, 1) where the force has no minimum; the ball is
        released iff it is negative.
    tau : ndarray
        Release time where released, inf elsewhere (only computed if `solve`).
    release_slope : ndarray
        ξ'(τ) = −ṽC + (ζṽ − 1)S (or its eigenmode form) where released (if `solve`), 0
        elsewhere.
    """
    zeta, vtilde, shape = _flat_pair(zeta, vtilde)
    return tuple(out.reshape(shape) for out in _kernels().iib_solve(zeta, vtilde, solve))


def _iib_bracket(zeta, vtilde):
    """Bracket [t_lo, t_hi] of IIb's release root and the force minimum f(t_hi)."""
    return _iib_release(zeta, vtilde, solve=False)[:3]
