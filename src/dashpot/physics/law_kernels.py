"""Compiled kernels of the Hunt–Crossley law
(:func:`dashpot.physics.laws.hunt_crossley.hunt_crossley_restitution`).

Kept apart from :mod:`dashpot.physics.laws` so that importing the laws does not import numba:
this module is loaded the first time the law is evaluated.

References
----------
.. [1] K. H. Hunt and F. R. E. Crossley, "Coefficient of restitution interpreted as damping in
   vibroimpact", J. Appl. Mech. 42, 440-445 (1975).
"""

from __future__ import annotations

import math

import numba

__all__ = ["hunt_crossley_many"]

# |x| below which ψ(x) = (ln(1 + x) − x)/x² is summed as a series: 13 terms leave an error
# below |x|¹³/15 < 1e-17 there; above, the direct form loses at most ulp/|x| ≈ 5e-15.
_SERIES_LIMIT = 0.05
_SERIES_TERMS = 13

@numba.njit(cache=True)
def _psi(x):
    """ψ(x) = (ln(1 + x) − x)/x² and ψ'(x), for x > −1 (series where |x| is small)."""
    if abs(x) < _SERIES_LIMIT:
        # ψ = Σ_k (−1)^(k+1) x^k/(k + 2), ψ' = Σ_k (−1)^(k+1) k x^(k−1)/(k + 2), by Horner.
        value = 0.0
        slope = 0.0
        for k in range(_SERIES_TERMS - 1, -1, -1):
            sign = -1.0 if k % 2 == 0 else 1.0
            value = value * x + sign / (k + 2)
            if k >= 1:
                slope = slope * x + sign * k / (k + 2)
        return value, slope
    direct = (math.log1p(x) - x) / (x * x)
    return direct, -1.0 / (x * (1.0 + x)) - 2.0 * direct / x


@numba.njit(cache=True)
def _mismatch(kind, x, a, b):
    """The increasing function whose root is sought, and its slope: kind 0 is
    ψ(d) − ε²ψ(−dε) in x = ε (a = d, b = ψ(d)), for 0 < d <= 1; kind 1 is
    u + e^(−u) − 1 − (d − ln(1 + d)) in x = u = −ln(1 − dε) (a = d − ln(1 + d))."""
    if kind == 0:
        psi_e, dpsi_e = _psi(-a * x)
        return b - x * x * psi_e, a * x * x * dpsi_e - 2.0 * x * psi_e
    return x + math.expm1(-x) - a, -math.expm1(-x)


@numba.njit(cache=True)
def _newton_in_bracket(kind, lower, upper, start, a, b):
    """Root of an increasing function on [lower, upper] by Newton steps kept in the bracket.

    A step that leaves the current bracket is replaced by bisection, so the iteration always
    converges; it stops at a step below 4 ulp of the iterate or a closed bracket. (The contact
    models' :func:`dashpot.physics.exact_kernels._halley` needs f'' and f''' in closed
    form for its steps and its stopping estimate; the functions here have only f'.)
    """
    tiny = 2.220446049250313e-16
    x, lo, hi = start, lower, upper
    for _ in range(100):
        value, slope = _mismatch(kind, x, a, b)
        if value < 0.0:
            lo = x
        elif value > 0.0:
            hi = x
        candidate = x - value / slope if slope != 0.0 else math.nan
        new = candidate if (candidate >= lo and candidate <= hi) else 0.5 * (lo + hi)
        if (value == 0.0 or abs(new - x) <= 4.0 * tiny * abs(x)
                or hi - lo <= 4.0 * tiny * abs(hi)):
            return new
        x = new
    return x


@numba.njit(cache=True)
def hunt_crossley_many(damping, eps, slope):
    """ε(d) and dε/dd of :func:`hunt_crossley_restitution` at every d of `damping` (>= 0)."""
    for i in range(damping.size):
        d = damping[i]
        if d == 0.0:
            eps[i], slope[i] = 1.0, -2.0 / 3.0
        elif d <= 1.0:
            psi_d, dpsi_d = _psi(d)
            e = _newton_in_bracket(0, 0.0, 1.0, 1.0 - 2.0 * d / 3.0, d, psi_d)
            psi_e, dpsi_e = _psi(-d * e)
            # Implicit slope of G(ε, d) = ε²ψ(−dε) − ψ(d) = 0.
            g_eps = 2.0 * e * psi_e - d * e * e * dpsi_e
            g_d = -e ** 3 * dpsi_e - dpsi_d
            eps[i], slope[i] = e, -g_d / g_eps
        else:
            excess = d - math.log1p(d)
            u = _newton_in_bracket(1, 0.0, excess + 1.0, excess + 1.0, excess, 0.0)
            gap = -math.expm1(-u)  # 1 − e^(−u) = dε
            # du/dd = (d/(1 + d))/(1 − e^(−u)); ε = (1 − e^(−u))/d.
            du = d / (1.0 + d) / gap
            eps[i] = gap / d
            slope[i] = (math.exp(-u) * du - gap / d) / d
