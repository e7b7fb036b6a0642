"""The compiled end-of-contact solver of the gravity models (dashpot.physics.exact_kernels).

Roots are checked against the end condition evaluated with mpmath at 50 digits from its own
closed form (independent of the package): the end condition changes sign within the stated
accuracy of the returned contact time and keeps its sign before it. Also: no NaN and no
floating-point warning across the damping regimes and impact speeds up to the float maximum,
results independent of the batch a point is solved in, and the compiled module loaded only when
a gravity model is first solved.
"""

from __future__ import annotations

import subprocess
import sys
import warnings

import mpmath as mp
import numpy as np
import pytest

import dashpot
from dashpot.physics.brackets import _ib_solve, _iib_release

EPS = np.finfo(float).eps
# Damping ratios of every regime and regime boundary: ζ = 0, tiny, under-, critically and
# over-damped next to ζ = 1, both sides of the switch to eigenmodes at 1.25, heavy damping.
ZETAS = [0.0, 1e-9, 1e-3, 0.3, 0.9, 1 - 1e-12, 1.0, 1 + 1e-12, 1.1, float(np.nextafter(1.25, 0)),
         1.25, 3.0, 50.0, 1e4]
# Impact speeds: log-uniform over slow to very fast (seed drawn once), plus huge ones.
SPEEDS = np.concatenate([10 ** np.random.default_rng(20261125).uniform(-3, 12, 6),
                         [1e100, 1e300]])


def _mp_end_condition(model, zeta, vtilde, t):
    """ξ(t) (Ib) or F/(mg) = −ξ − 2ζξ' (IIb) at 50 digits, and the size of its terms.

    ξ = η − 1 with η = e^{−ζt}(cosh st + (ζ − ṽ) sinh(st)/s), s = √(ζ² − 1) (complex below
    ζ = 1; sinh(st)/s → t at ζ = 1), solving ξ'' = −1 − ξ − 2ζξ', ξ(0) = 0, ξ'(0) = −ṽ.
    """
    with mp.workdps(50):
        z, v, t = mp.mpf(zeta), mp.mpf(vtilde), mp.mpf(t)
        s = mp.sqrt(mp.mpc(z * z - 1))
        decay = mp.exp(-z * t)
        c = decay * mp.cosh(s * t)
        sine = decay * (mp.sinh(s * t) / s if s != 0 else t)
        c, sine = mp.re(c), mp.re(sine)
        xi = c - 1 + (z - v) * sine
        if model == "Ib":
            return xi, abs(c) + 1 + abs((z - v) * sine)
        slope = -v * c + (z * v - 1) * sine
        return -xi - 2 * z * slope, 1 + abs(c) + abs(v * c) + abs(v * sine) + abs(sine)


def _mp_slope(model, zeta, vtilde, t):
    """Derivative of the end condition at t, by a 50-digit central difference."""
    h = mp.mpf(t) * mp.mpf(10) ** -20
    with mp.workdps(50):
        up = _mp_end_condition(model, zeta, vtilde, mp.mpf(t) + h)[0]
        down = _mp_end_condition(model, zeta, vtilde, mp.mpf(t) - h)[0]
        return (up - down) / (2 * h)


@pytest.fixture(scope="module")
def solved():
    """Contact times of Ib and IIb on the ζ × ṽ grid, in one batch per model."""
    zeta, vtilde = (a.ravel() for a in np.meshgrid(ZETAS, SPEEDS, indexing="ij"))
    return {"Ib": (zeta, vtilde, _ib_solve(zeta, vtilde)[3]),
            "IIb": (zeta, vtilde, _iib_release(zeta, vtilde)[3])}


@pytest.mark.parametrize("model", ["Ib", "IIb"])
def test_contact_time_is_the_first_root_at_50_digits(solved, model):
    zeta, vtilde, tau = solved[model]
    finite = np.isfinite(tau)
    assert finite.sum() >= 25, "the grid should hold many rebounds"
    checked = 0
    for z, v, t in zip(zeta[finite], vtilde[finite], tau[finite]):
        value, scale = _mp_end_condition(model, z, v, t)
        slope = abs(_mp_slope(model, z, v, t))
        # Stated accuracy 1e-13, or the conditioning of the root where it is worse: a rounding
        # error of a few ulp of the terms' size moves a root by eps·scale/|f'|.
        tolerance = max(1e-13, 64 * EPS * float(scale / (slope * t)))
        before = _mp_end_condition(model, z, v, t * (1 - tolerance))[0]
        after = _mp_end_condition(model, z, v, t * (1 + tolerance))[0]
        rising = model == "Ib"
        assert (before < 0 < after) if rising else (before > 0 > after), (z, v, t, tolerance)
        # The first return: the end condition keeps its sign before τ.
        for fraction in np.linspace(0.02, 1 - 1e-6, 40):
            inner = _mp_end_condition(model, z, v, t * fraction)[0]
            assert (inner < 0) if rising else (inner > 0), (z, v, t, fraction)
        checked += 1 if tolerance == 1e-13 else 0
    # The stated accuracy, not a loosened one, applies to most of the grid.
    assert checked >= 0.8 * finite.sum()


EXTREME_ZETAS = ZETAS + [1e-300, 1 - 2**-53, 1 + 2**-52, 1e6, 1e150]
EXTREME_SPEEDS = [1e-300, 1e-8, 1e-3, 1.0, 1e3, 1e8, 1e150, 1e300, 1e307]


@pytest.mark.parametrize("model", ["Ib", "IIb", "hybrid"])
def test_no_nan_and_no_warning_at_the_extremes(model):
    zeta, vtilde = (a.ravel() for a in np.meshgrid(EXTREME_ZETAS, EXTREME_SPEEDS,
                                                    indexing="ij"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = dashpot.collide(model, zeta, vtilde)
    for name in ("eps", "one_minus_eps", "contact_time", "release_depth", "release_speed"):
        assert not np.isnan(getattr(result, name)).any(), name
    assert np.all((result.eps >= 0) & (result.eps <= 1))
    assert np.all((result.one_minus_eps >= 0) & (result.one_minus_eps <= 1))
    np.testing.assert_allclose(result.eps + result.one_minus_eps, 1.0, rtol=1e-12)
    # Finite contact exactly where the ball rebounds, and a positive duration.
    np.testing.assert_array_equal(np.isinf(result.contact_time), result.captured)
    assert np.all(result.contact_time > 0)


def test_release_near_the_float_maximum_is_the_gravity_free_one():
    """At ṽ = 1e307 gravity is a 1e-307 correction: IIb's release is IIa's, to rounding."""
    zeta = np.array([0.0, 0.3, 1 - 2**-53, 1.0, 1.2])
    iib = dashpot.collide("IIb", zeta, 1e307)
    iia = dashpot.collide("IIa", zeta, 1.0)
    assert not iib.captured.any()
    np.testing.assert_allclose(iib.eps, iia.eps, rtol=1e-13)
    np.testing.assert_allclose(iib.contact_time, iia.contact_time, rtol=1e-13)


@pytest.mark.parametrize("model", ["Ib", "IIb", "hybrid"])
def test_a_point_gets_the_same_result_alone_and_in_any_batch(model):
    rng = np.random.default_rng(7)
    zeta = 10 ** rng.uniform(-3, 1, 300)
    vtilde = 10 ** rng.uniform(-1, 6, 300)
    batch = dashpot.collide(model, zeta, vtilde)
    grid = dashpot.collide(model, zeta.reshape(20, 15), vtilde.reshape(20, 15))
    strided = dashpot.collide(model, np.repeat(zeta, 2)[::2], np.repeat(vtilde, 2)[::2])
    for i in range(0, 300, 37):
        alone = dashpot.collide(model, zeta[i], vtilde[i])
        for name in ("eps", "one_minus_eps", "contact_time", "release_speed"):
            assert getattr(alone, name) == getattr(batch, name)[i]
            assert getattr(grid, name).ravel()[i] == getattr(batch, name)[i]
            assert getattr(strided, name)[i] == getattr(batch, name)[i]


def test_compiled_solver_is_loaded_only_when_a_gravity_model_is_solved():
    """The compiled module (and with it numba, as far as this solver is concerned) is imported
    on the first gravity-model solve, not by the closed forms or by importing the models."""
    code = ("import sys\n"
            "from dashpot.physics.models import collide\n"
            "kernels = 'dashpot.physics.exact_kernels'\n"
            "assert kernels not in sys.modules, 'importing the models loaded the kernels'\n"
            "collide('Ia', 0.1, 1.0); collide('IIa', 0.1, 1.0)\n"
            "assert kernels not in sys.modules, 'a closed-form model loaded the kernels'\n"
            "collide('Ib', 0.1, 5.0)\n"
            "assert kernels in sys.modules and 'numba' in sys.modules\n")
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                               timeout=300)
    assert completed.returncode == 0, completed.stderr


@pytest.mark.parametrize("zeta", [3.0, 1e100, 1e151, 1e200, 1e300, 1.7e308])
def test_iia_contact_time_at_huge_damping(zeta):
    """2·arccosh(ζ)/√(ζ² − 1) at 40 digits, also where ζ² overflows (IIa; the gravity models'
    first iterate uses it too)."""
    with np.errstate(over="ignore"):
        result = dashpot.collide("IIa", zeta, 1.0)
    with mp.workdps(40):
        z = mp.mpf(zeta)
        reference = float(2 * mp.acosh(z) / mp.sqrt((z - 1) * (z + 1)))
    assert float(result.contact_time) == pytest.approx(reference, rel=1e-14)
    assert float(result.one_minus_eps) == 1.0 or zeta < 10
    assert not np.isnan(float(result.eps))
