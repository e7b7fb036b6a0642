"""The viscoelastic Hertz law: 1 − ε = C1·δ − C2·δ² + …, δ = κ·v^(1/5) (Ramírez et al. [1]_).

The contact m·ξ'' = −k·ξ^(3/2) − (3/2)·A·k·ξ^(1/2)·ξ' [2]_, ending where ξ returns to 0, scales
with ξ = L·x, t = (L/v)·s, L = (m v²/k)^(2/5) into x'' = −x^(3/2) − δ·x^(1/2)·x' with the single
number δ = (3/2)·A·(k/m)^(2/5)·v^(1/5) = κ·v^(1/5). Ramírez et al. [1]_ give
1 − ε = C1·δ − C2·δ² + …, C1 = 1.15344, C2 = 0.79826 (= 3C1²/5). Truncated at second order the
series is off by about 0.5·δ³ (4e-6 at δ = 0.02, 5e-4 at 0.1, 3.7e-3 at 0.2) and turns back up
beyond δ = C1/2C2 ≈ 0.72, so the law is ε = 1 − C1·δ + C2·δ² + δ·q(δ), with the remainder q
(which also absorbs the rounding of the published C1, about 1e-5) a Chebyshev interpolant [3]_
of degree 20 on [0, 2] of the contact integrated directly
(:func:`viscoelastic_contact_restitution`, solve_ivp to 1e-13) at its Chebyshev points, built
once per process when the law is first used (0.15 s). Against direct integration it is
accurate to about 1e-11 on 0 <= δ <= VISCOELASTIC_DELTA_MAX = 2 (ε from 1 down to 0.095), and
exact at δ = 0; beyond, ε is held at ε(2) and the points are flagged as outside.

References
----------
.. [1] R. Ramírez, T. Pöschel, N. V. Brilliantov and T. Schwager, "Coefficient of restitution
   of colliding viscoelastic spheres", Phys. Rev. E 60, 4465-4472 (1999).
.. [2] N. V. Brilliantov, F. Spahn, J.-M. Hertzsch and T. Pöschel, "Model for collisions in
   granular gases", Phys. Rev. E 53, 5382-5392 (1996).
.. [3] L. N. Trefethen, *Approximation Theory and Approximation Practice*, SIAM (2013),
   ch. 2-8 (interpolation in Chebyshev points and its convergence for analytic functions).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.integrate import solve_ivp

from .base import RestitutionLaw, parameter

__all__ = ["LAW_SPECS", "VISCOELASTIC_C1", "VISCOELASTIC_C2", "VISCOELASTIC_DELTA_MAX",
           "viscoelastic_contact_restitution", "viscoelastic_hertz"]

VISCOELASTIC_C1 = 1.15344
"""First coefficient of the viscoelastic series, Ramírez et al. (1999), eq. for γ1."""
VISCOELASTIC_C2 = 0.79826
"""Second coefficient of the viscoelastic series, Ramírez et al. (1999) (= 3C1²/5)."""
VISCOELASTIC_DELTA_MAX = 2.0
"""Largest δ = κv^(1/5) of the tabulated viscoelastic law (ε ≈ 0.095 there): beyond, ε is
held at its value there and the points are flagged as outside."""
_VISCOELASTIC_DEGREE = 20  # of the Chebyshev interpolant of the series' remainder


def viscoelastic_hertz(speed, kappa):
    """1 − ε = C1·δ − C2·δ² − δ·q(δ), δ = κ·v^(1/5), with the remainder q tabulated from the
    integrated contact (module notes)."""
    if np.any(kappa < 0.0):
        raise ValueError(f"kappa must be >= 0 (no energy gain in contact); got {kappa!r}")
    delta = kappa * speed ** 0.2
    outside = delta > VISCOELASTIC_DELTA_MAX
    held = np.minimum(delta, VISCOELASTIC_DELTA_MAX)
    table, table_slope = _viscoelastic_remainder_table()
    remainder, remainder_slope = table(held), table_slope(held)
    eps = 1.0 - VISCOELASTIC_C1 * held + VISCOELASTIC_C2 * held * held + held * remainder
    eps_slope = (-VISCOELASTIC_C1 + 2.0 * VISCOELASTIC_C2 * held + remainder
                 + held * remainder_slope)
    # v·dε/dv = (δ/5)·dε/dδ; held beyond the table, ε does not change.
    return eps, np.where(outside, 0.0, 0.2 * held * eps_slope), outside


def viscoelastic_contact_restitution(delta):
    """ε of the scaled viscoelastic Hertz contact x'' = −x^(3/2) − δ·x^(1/2)·x' by direct
    integration (solve_ivp, DOP853), from x = 0, x' = 1 until x returns to 0.

    Parameters
    ----------
    delta : float
        δ = κ·v^(1/5) >= 0 (dimensionless).

    Returns
    -------
    float
        ε = −x' at the end of the contact; absolute error about 1e-9 (the force is not
        smooth at x = 0, where the integration starts and ends).

    Notes
    -----
    The first microsecond of scaled time is taken from the start's expansion
    x = t − (4/15)·δ·t^(5/2), x' = 1 − (2/3)·δ·t^(3/2) (the Hertz term enters at t^(5/2) in x'),
    so that the integrator does not step across the square root at x = 0.
    """
    start = 1e-6

    def motion(_, state):
        x = max(state[0], 0.0)
        root = math.sqrt(x)
        return [state[1], -x * root - delta * root * state[1]]

    def separation(_, state):
        return state[0]

    separation.terminal, separation.direction = True, -1
    initial = [start - 4.0 / 15.0 * delta * start ** 2.5, 1.0 - 2.0 / 3.0 * delta * start ** 1.5]
    solution = solve_ivp(motion, (start, 1e4), initial, method="DOP853", events=separation,
                         rtol=1e-13, atol=1e-15, first_step=1e-6)
    return float(-solution.y_events[0][0][1])


@functools.lru_cache(maxsize=1)
def _viscoelastic_remainder_table():
    """Chebyshev interpolant [3]_ of q(δ) = (ε − 1 + C1·δ − C2·δ²)/δ on
    [0, VISCOELASTIC_DELTA_MAX] from the integrated contact at its Chebyshev points (which
    leave out δ = 0), and its derivative; built once per process (0.15 s)."""
    def remainder(delta):
        eps = np.array([viscoelastic_contact_restitution(float(d)) for d in np.ravel(delta)])
        return (eps - 1.0 + VISCOELASTIC_C1 * delta - VISCOELASTIC_C2 * delta * delta) / delta

    table = np.polynomial.Chebyshev.interpolate(remainder, _VISCOELASTIC_DEGREE,
                                                domain=[0.0, VISCOELASTIC_DELTA_MAX])
    return table, table.deriv()


def _start(eps, typical):
    """κ from the first-order series 1 − ε ≈ C1·κ·v^(1/5) at the train's typical speed."""
    return {"kappa": (1.0 - eps) / (VISCOELASTIC_C1 * typical ** 0.2)}


LAW_SPECS = (
    RestitutionLaw(
        "viscoelastic-hertz", "ε = 1 − C1·δ + C2·δ² + δ·q(δ), δ = κv^(1/5), q integrated",
        (parameter("kappa", "s^(1/5)/m^(1/5)", 0.0, 0.2, 0.03,
                   "(3/2)·A·(k/m)^(2/5): viscoelastic damping of a Hertz contact"),),
        viscoelastic_hertz, "Ramírez, Pöschel, Brilliantov, Schwager, PRE 60, 4465 (1999)",
        start=_start),
)
"""The law this module defines (collected in :data:`dashpot.physics.laws.LAWS`)."""
