"""The oscillator basis C, S and the closed-form first zero, against mpmath at 50 digits."""

import mpmath as mp
import numpy as np
import pytest

from dashpot.physics.contact import Damping, basis, combination, first_zero

ZETAS = [0.0, 1e-8, 0.3, 0.9, 1 - 1e-9, 1.0, 1 + 1e-9, 1.1, 5.0, 1e3]
TIMES = [0.0, 1e-6, 0.01, 0.7, 3.0, 11.0]


def _mp_basis(zeta, t):
    """C, S from their definition with complex-safe mpmath: s = sqrt(ζ² − 1) may be imaginary."""
    with mp.workdps(50):
        z, t = mp.mpf(zeta), mp.mpf(t)
        s = mp.sqrt(mp.mpc(z * z - 1))
        decay = mp.exp(-z * t)
        c = decay * mp.cosh(s * t)
        S = decay * (mp.sinh(s * t) / s if s != 0 else t)
        return float(mp.re(c)), float(mp.re(S))


@pytest.mark.parametrize("zeta", ZETAS)
def test_basis_matches_definition(zeta):
    c, S = basis(Damping(np.full(len(TIMES), zeta)), np.array(TIMES))
    for t, c_got, s_got in zip(TIMES, c, S):
        c_ref, s_ref = _mp_basis(zeta, t)
        # Near a zero of cos(ωt) only absolute accuracy is possible: the rounding of ωt alone
        # moves the value by ~ulp(ωt). Hence a tolerance on the scale of the envelope e^{−ζt}.
        envelope = np.exp(-zeta * t) * (1.0 + t)
        assert c_got == pytest.approx(c_ref, rel=2e-14, abs=4e-16 * envelope)
        assert s_got == pytest.approx(s_ref, rel=2e-14, abs=4e-16 * envelope * (1.0 + t))


@pytest.mark.parametrize("zeta", [0.05, 0.5, 0.99, 1.0, 1.3, 4.0])
@pytest.mark.parametrize("p,q", [(1.0, -3.0), (1.0, 2.0), (-2.0, 0.5), (0.0, 1.0), (2.0, -0.1)])
def test_first_zero_is_first(zeta, p, q):
    """At the returned time the combination vanishes, and it keeps its sign before."""
    d = Damping(np.array([zeta]))
    t0 = first_zero(d, p, q)[0]
    if not np.isfinite(t0):
        # No zero: the sign must persist over a long horizon.
        grid = np.linspace(1e-9, 60.0, 20001)
        values = combination(Damping(np.full(grid.size, zeta)), p, q, grid)
        assert np.all(values * (p if p else q) > 0)
        return
    scale = abs(p) + abs(q)
    assert abs(combination(d, p, q, np.array([t0]))[0]) < 1e-14 * scale
    grid = np.linspace(0.0, t0, 2001)[1:-1]
    values = combination(Damping(np.full(grid.size, zeta)), p, q, grid)
    assert np.all(np.sign(values) == np.sign(values[0]))


@pytest.mark.parametrize("zeta", ZETAS)
def test_basis_minus_one_keeps_its_digits(zeta):
    """C − 1 near t = 0 and near a full damped period, where C ≈ 1, to relative accuracy."""
    d = Damping(np.array([zeta]))
    period = 2 * np.pi / d.omega[0] if d.under[0] else 1.0
    times = [1e-9, 1e-4, 0.3, period * (1 - 1e-5), period * (1 - 1e-3), period]
    for t in times:
        c, S, offset = basis(Damping(np.array([zeta])), np.array([t]), offset=True)
        with mp.workdps(60):
            c_ref = mp.mpf(_mp_basis_exact(zeta, t))
            reference = float(c_ref - 1)
        # Relative to the size of C − 1, up to the rounding of the phase ωt itself.
        phase_rounding = 4e-16 * t * abs(float(S[0])) + 1e-300
        assert offset[0] == pytest.approx(reference, rel=4e-15, abs=phase_rounding)
        assert c[0] == pytest.approx(1 + reference, rel=1e-15)


def _mp_basis_exact(zeta, t):
    """C(t) at 60 digits (mpf), for differences with 1."""
    with mp.workdps(60):
        z, t = mp.mpf(zeta), mp.mpf(t)
        s = mp.sqrt(mp.mpc(z * z - 1))
        return mp.re(mp.exp(-z * t) * mp.cosh(s * t))
