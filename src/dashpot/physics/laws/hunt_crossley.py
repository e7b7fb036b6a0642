"""The Hunt–Crossley law: ε at d = χ·v from ln((1 + d)/(1 − dε)) = d(1 + ε) (Hunt and
Crossley [1]_).

The contact m·ξ'' = −k·ξ^n − λ·ξ^n·ξ' [1]_ has a first integral: with y = ξ',
y·dy/dξ = −(k/m)ξ^n(1 + χy), so y/χ − ln(1 + χy)/χ² + (k/m)ξ^(n+1)/(n + 1) is conserved.
Between ξ = 0 at impact (y = v) and at separation (y = −εv) it gives the implicit relation
above, exact for every exponent n. It is solved as ε² = ψ(d)/ψ(−dε) with
ψ(x) = (ln(1 + x) − x)/x² (a series near 0, so nothing cancels for nearly elastic contacts)
for d <= 1, and in u = −ln(1 − dε) above, where 1 − dε is exponentially small, both by
safeguarded Newton steps (:func:`hunt_crossley_restitution`, compiled in
:mod:`dashpot.physics.law_kernels`); for small d, 1 − ε ≈ 2d/3.

References
----------
.. [1] K. H. Hunt and F. R. E. Crossley, "Coefficient of restitution interpreted as damping in
   vibroimpact", J. Appl. Mech. 42, 440-445 (1975).
"""

from __future__ import annotations

import numpy as np

from ..._validation import check_nonnegative
from .base import RestitutionLaw, no_flag, parameter

__all__ = ["LAW_SPECS", "hunt_crossley", "hunt_crossley_restitution"]


def hunt_crossley_restitution(damping):
    """ε of the Hunt–Crossley contact and dε/dd, at the dimensionless damping d = χ·v.

    Parameters
    ----------
    damping : array_like
        d = (λ/k)·v >= 0, finite.

    Returns
    -------
    eps, slope : ndarray
        ε(d) in (0, 1] solving ln((1 + d)/(1 − dε)) = d(1 + ε), and dε/dd.

    Notes
    -----
    For d <= 1 the root is found as ε² = ψ(d)/ψ(−dε) on ε ∈ [0, 1] (no cancellation as d → 0),
    starting from 1 − 2d/3. For d > 1, 1 − dε is exponentially small (e^(−d) roughly) and would
    be lost to rounding: there the unknown is u = −ln(1 − dε), which solves the convex
    u + e^(−u) − 1 = d − ln(1 + d) on [0, d − ln(1 + d) + 1], and ε = (1 − e^(−u))/d. Both by
    safeguarded Newton steps (5-8 evaluations), point by point in a compiled loop.
    """
    # Imported here: numba compiles (or loads) the kernels only when the law is first used.
    from ..law_kernels import hunt_crossley_many

    d = check_nonnegative("damping", damping).astype(float)
    flat = np.ascontiguousarray(d).ravel()
    eps, slope = np.empty(flat.size), np.empty(flat.size)
    hunt_crossley_many(flat, eps, slope)
    return eps.reshape(d.shape), slope.reshape(d.shape)


def hunt_crossley(speed, chi):
    """ε of the Hunt–Crossley law at d = χ·v (χ = λ/k in s/m)."""
    if np.any(chi < 0.0):
        raise ValueError(f"chi must be >= 0 (no energy gain in contact); got {chi!r}")
    damping = chi * speed
    eps, slope = hunt_crossley_restitution(damping)
    return eps, damping * slope, no_flag(speed.shape)


def _start(eps, typical):
    """χ from the small-damping limit 1 − ε ≈ 2χv/3 at the train's typical speed."""
    return {"chi": 1.5 * (1.0 - eps) / typical}


LAW_SPECS = (
    RestitutionLaw(
        "hunt-crossley", "ln((1 + χv)/(1 − χvε)) = χv(1 + ε)",
        (parameter("chi", "s/m", 0.0, 10.0, 0.05, "λ/k: Hunt–Crossley damping per stiffness"),),
        hunt_crossley, "Hunt & Crossley, J. Appl. Mech. 42, 440 (1975)", start=_start),
)
"""The law this module defines (collected in :data:`dashpot.physics.laws.LAWS`)."""
