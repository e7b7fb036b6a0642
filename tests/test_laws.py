"""The ladder of restitution laws: each against an independent reference, slopes, domain edges."""

import math

import mpmath
import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

from dashpot.likelihood import TrainModel
from dashpot.physics import collide
from dashpot.physics.flight import drag_flight
from dashpot.physics.laws import (
    LADDER,
    LAWS,
    VISCOELASTIC_C1,
    VISCOELASTIC_C2,
    VISCOELASTIC_DELTA_MAX,
    dashpot_contact_time,
    hunt_crossley_restitution,
    restitution,
)
from dashpot.physics.models import MODELS

RUNGS = ("constant", "linear", "power", "quadratic", "viscoelastic-hertz", "hunt-crossley")


def _contact_restitution(damping, force):
    """ε of a contact x'' = force(x, x') from x = 0, x' = 1 until x returns to 0 (solve_ivp)."""
    def motion(_, state):
        return [state[1], force(max(state[0], 0.0), state[1], damping)]

    def separation(_, state):
        return state[0]

    separation.terminal, separation.direction = True, -1
    solution = solve_ivp(motion, (0.0, 1e3), [0.0, 1.0], method="DOP853", events=separation,
                         rtol=1e-12, atol=1e-14, first_step=1e-6)
    return -solution.y_events[0][0][1]


def _viscoelastic_force(x, y, delta):
    return -x ** 1.5 - delta * math.sqrt(x) * y


def _hunt_crossley_force(exponent):
    return lambda x, y, d: -x ** exponent * (1.0 + d * y)


def _random_parameters(name, rng, size):
    """Parameter arrays drawn near each law's start values (within 5 % of the bound range)."""
    return [np.clip(p.start + (p.upper - p.lower) * rng.uniform(-0.05, 0.05, size), p.lower,
                    p.upper) for p in LAWS[name].parameters]


def test_registry_lists_every_law_with_complete_metadata():
    assert set(LADDER) == set(RUNGS)
    assert set(LAWS) == set(RUNGS) | set(MODELS)
    for name, law in LAWS.items():
        assert law.name == name and law.formula and law.reference
        assert law.parameters, name
        for p in law.parameters:
            assert p.name.isidentifier() and isinstance(p.unit, str) and p.description
            assert p.lower < p.upper and p.lower <= p.start <= p.upper, (name, p)
        start = [p.start for p in law.parameters]
        result = law(np.array([0.3, 1.0, 3.0]), *start)
        assert np.all((result.eps > 0.0) & (result.eps <= 1.0)), name
        assert not result.outside.any(), name


def test_closed_form_laws_match_their_formulas():
    rng = np.random.default_rng(20261125)
    speed = rng.uniform(0.05, 4.0, 50)
    e0, alpha, c = 0.93, 0.011, 0.0042
    assert_allclose(restitution("constant", speed, e0).eps, np.full(50, e0), rtol=0)
    assert_allclose(restitution("linear", speed, e0, alpha).eps,
                    [e0 - alpha * v for v in speed], rtol=1e-15)
    assert_allclose(restitution("quadratic", speed, e0, c).eps,
                    [e0 - c * v ** 2 for v in speed], rtol=1e-15)
    a, b = 0.8, 0.2  # ε = 1 below 0.8^5 = 0.33 m/s
    power = restitution("power", speed, a, b)
    expected = np.array([a / v ** b for v in speed])
    inside = expected <= 1.0
    assert_allclose(power.eps[inside], expected[inside], rtol=1e-14)
    assert np.all(power.eps[~inside] == 1.0) and np.all(power.outside == ~inside)
    assert (~inside).any() and inside.any()


def test_values_outside_zero_one_are_clipped_and_flagged():
    speed = np.array([0.5, 2.0, 10.0])
    over = restitution("constant", speed, 1.2)
    assert np.all(over.eps == 1.0) and over.outside.all() and np.all(over.speed_slope == 0.0)
    line = restitution("linear", speed, 0.9, 0.1)  # ε = 0 at 9 m/s
    assert_allclose(line.eps, [0.85, 0.7, 0.0])
    assert list(line.outside) == [False, False, True]
    assert line.speed_slope[2] == 0.0
    rising = restitution("quadratic", speed, 0.95, -0.01)  # ε = 1 at √5 m/s
    assert list(rising.outside) == [False, False, True] and rising.eps[2] == 1.0
    negative = restitution("power", speed, -0.5, 0.1)
    assert np.all(negative.eps == 0.0) and negative.outside.all()


def test_viscoelastic_series_agrees_with_the_integrated_hertz_contact():
    # Ramírez et al.'s C1 is the slope of 1 − ε against the δ of the Brilliantov contact.
    small = 1e-3
    slope = (1.0 - _contact_restitution(small, _viscoelastic_force)) / small
    assert slope == pytest.approx(1.15344, abs=1e-3)
    rng = np.random.default_rng(7093)
    kappa = rng.uniform(0.005, 0.07, 6)
    speed = rng.uniform(0.05, 5.0, 6)
    delta = kappa * speed ** 0.2
    law = restitution("viscoelastic-hertz", speed, kappa)
    reference = np.array([_contact_restitution(d, _viscoelastic_force) for d in delta])
    # Second-order series: 1 − C1·δ + C2·δ², off by about 0.5·δ³; the law by far less.
    series = 1.0 - VISCOELASTIC_C1 * delta + VISCOELASTIC_C2 * delta ** 2
    assert np.all(np.abs(series - reference) <= 0.6 * delta ** 3)
    assert np.all(np.abs(law.eps - reference) <= 1e-9)
    assert not law.outside.any()


@pytest.mark.parametrize("delta", [0.02, 0.1, 0.3, 0.6])
def test_viscoelastic_law_matches_direct_integration_at_large_damping(delta):
    """Where the truncated series is off by 4e-6 to 0.1 and turns back up (δ > 0.72), the
    law follows the integrated contact, and so does its speed slope."""
    speed = 2.0
    kappa = delta / speed ** 0.2
    law = restitution("viscoelastic-hertz", speed, kappa)
    assert law.eps == pytest.approx(_contact_restitution(delta, _viscoelastic_force), abs=1e-9)
    # v·dε/dv = (δ/5)·dε/dδ, against a central difference of integrated contacts.
    step = 1e-3 * delta
    difference = (_contact_restitution(delta + step, _viscoelastic_force)
                  - _contact_restitution(delta - step, _viscoelastic_force)) / (2.0 * step)
    assert law.speed_slope == pytest.approx(0.2 * delta * difference, abs=1e-6)
    assert not law.outside


def test_viscoelastic_law_flags_its_range_and_never_rises():
    speed = np.geomspace(1e-6, 1e9, 200)
    law = restitution("viscoelastic-hertz", speed, 0.2)
    delta = 0.2 * speed ** 0.2
    assert np.array_equal(law.outside, delta > VISCOELASTIC_DELTA_MAX)
    assert law.outside.any() and not law.outside.all()
    assert np.all(np.diff(law.eps) <= 0.0) and np.all(law.eps > 0.09)
    assert np.all(np.isfinite(law.speed_slope))
    assert np.all(law.speed_slope[law.outside] == 0.0)


@pytest.mark.parametrize("exponent", [1.5, 1.0])
def test_hunt_crossley_agrees_with_the_integrated_contact(exponent):
    # The first integral makes ε independent of the exponent: both are checked.
    rng = np.random.default_rng(313 + int(10 * exponent))
    damping = np.exp(rng.uniform(np.log(1e-3), np.log(20.0), 6))
    eps, _ = hunt_crossley_restitution(damping)
    reference = [_contact_restitution(d, _hunt_crossley_force(exponent)) for d in damping]
    assert_allclose(eps, reference, rtol=1e-8)


def test_hunt_crossley_solves_its_relation_to_forty_digits_at_the_extremes():
    damping = np.array([1e-9, 1e-4, 0.7, 1.0, 1.0 + 1e-12, 3.0, 40.0])
    eps, _ = hunt_crossley_restitution(damping)
    with mpmath.workdps(50):
        for d, value in zip(damping, eps):
            d = mpmath.mpf(float(d))

            def relation(e, d=d):
                return mpmath.log((1 + d) / (1 - d * e)) - d * (1 + e)

            # ε = −1 solves the relation too: bracket the physical root in (0, 1/d), where
            # 1 − dε ≈ (1 + d)e^(−d−1) > 1e-40 for every d here.
            upper = 1 if d < 1 else (1 - mpmath.mpf(10) ** -40) / d
            exact = mpmath.findroot(relation, (mpmath.mpf(0), upper), solver="anderson",
                                    tol=mpmath.mpf(10) ** -45)
            assert 0 < exact < min(1, 1 / d)
            assert float(value) == pytest.approx(float(exact), rel=2e-14), float(d)
    # Far beyond, 1 − dε ≈ (1 + d)e^(−d−1) underflows: ε = 1/d to the last digit.
    assert hunt_crossley_restitution(1e6)[0] * 1e6 == pytest.approx(1.0, rel=1e-15)


@pytest.mark.parametrize("name", RUNGS)
def test_speed_slopes_match_finite_differences(name):
    rng = np.random.default_rng(sum(map(ord, name)))
    params = _random_parameters(name, rng, 40)
    speed = rng.uniform(0.05, 3.0, 40)
    law = LAWS[name](speed, *params)
    keep = ~law.outside
    assert keep.sum() >= 10
    step = 1e-6 * speed
    numeric = (LAWS[name](speed + step, *params).eps
               - LAWS[name](speed - step, *params).eps) / (2.0 * step) * speed
    assert_allclose(law.speed_slope[keep], numeric[keep], rtol=1e-6, atol=1e-9)
    rebound, slope = LAWS[name].rebound(speed, *params)
    assert_allclose(rebound, law.eps * speed, rtol=1e-15)
    numeric_rebound = (LAWS[name].rebound(speed + step, *params)[0]
                       - LAWS[name].rebound(speed - step, *params)[0]) / (2.0 * step)
    assert_allclose(slope[keep], numeric_rebound[keep], rtol=1e-6, atol=1e-9)


def test_hunt_crossley_slope_is_continuous_where_the_solver_changes_variable():
    damping = np.array([1.0 - 1e-9, 1.0, 1.0 + 1e-9])
    eps, slope = hunt_crossley_restitution(damping)
    assert_allclose(eps, eps[1], rtol=1e-8)
    assert_allclose(slope, slope[1], rtol=1e-7)
    assert hunt_crossley_restitution(0.0)[1] == pytest.approx(-2.0 / 3.0)


@pytest.mark.parametrize("model", MODELS)
def test_dashpot_rungs_follow_collide_with_analytic_slopes(model):
    rng = np.random.default_rng(4242 + MODELS.index(model))
    zeta = rng.uniform(0.02, 1.6, 30)
    vtilde = np.exp(rng.uniform(np.log(2.0), np.log(2e3), 30))
    v_star = rng.uniform(1e-4, 1e-2, 30)
    speed = vtilde * v_star
    law = LAWS[model](speed, zeta, v_star)
    exact = collide(model, zeta, vtilde)
    assert_allclose(law.eps, exact.eps, rtol=1e-12)
    # Central differences of collide in ln ṽ: error ~ (h²·ε''' + 1e-13/h) with h = 1e-5.
    rebound = ~exact.captured
    up, down = collide(model, zeta, vtilde * (1 + 1e-5)), collide(model, zeta, vtilde * (1 - 1e-5))
    keep = rebound & ~up.captured & ~down.captured
    assert keep.sum() >= 10
    numeric = (up.eps - down.eps) / 2e-5
    assert_allclose(law.speed_slope[keep], numeric[keep], rtol=1e-5, atol=1e-7)
    assert np.all(law.speed_slope[~rebound] == 0.0)
    g = 9.81
    duration, slope = dashpot_contact_time(model, speed, zeta, v_star, g)
    assert_allclose(duration[rebound], exact.contact_time[rebound] * v_star[rebound] / g,
                    rtol=1e-12)
    tau_up, tau_down = (c.contact_time[keep] * v_star[keep] / g for c in (up, down))
    numeric_tau = (tau_up - tau_down) / (2e-5 * speed[keep])
    assert_allclose(slope[keep], numeric_tau, rtol=1e-5,
                    atol=1e-7 * np.max(np.abs(numeric_tau)))


@pytest.mark.parametrize("name", list(LAWS))
def test_edges_of_speed_and_parameters_give_no_nan(name):
    law = LAWS[name]
    speed = np.array([0.0, 1e-300, 1e-8, 1.0, 1e4, 1e12])
    corners = [[p.lower, p.upper, p.start] for p in law.parameters]
    for values in np.array(np.meshgrid(*corners)).reshape(len(corners), -1).T:
        if name in MODELS and values[1] <= 0.0:
            continue
        result = law(speed, *values)
        rebound, slope = law.rebound(speed, *values)
        for array in (result.eps, result.speed_slope, rebound, slope):
            assert np.all(np.isfinite(array)), (name, values, array)
        assert np.all((result.eps >= 0.0) & (result.eps <= 1.0))
        assert rebound[0] == 0.0


def test_bad_arguments_are_refused_with_one_clear_line():
    with pytest.raises(ValueError, match="takes 2 parameters"):
        LAWS["linear"](1.0, 0.9)
    with pytest.raises(ValueError, match="speed must be >= 0"):
        LAWS["constant"](-1.0, 0.9)
    with pytest.raises(ValueError, match="must be one of"):
        restitution("elastic", 1.0)
    with pytest.raises(ValueError, match="kappa must be >= 0"):
        LAWS["viscoelastic-hertz"](1.0, -0.1)
    with pytest.raises(ValueError, match="chi must be >= 0"):
        LAWS["hunt-crossley"](1.0, -0.1)
    with pytest.raises(ValueError, match="e must be finite"):
        LAWS["constant"](1.0, np.nan)
    with pytest.raises(ValueError, match="v_star > 0"):
        LAWS["Ib"](1.0, 0.1, 0.0)


@pytest.mark.parametrize("name", list(LAWS))
def test_every_law_simulates_and_filters_a_train(name):
    law = LAWS[name]
    rng = np.random.default_rng(90210 + len(name))
    params = [p.start for p in law.parameters]
    if name in MODELS:
        params = [0.05, 2e-3]  # ω0 ≈ 5000 rad/s: a ball bouncing tens of times from 1.5 m/s
    g = 9.81
    model = TrainModel(law.bind(*params), lambda v: drag_flight(v, g, 0.1),
                       (lambda u: dashpot_contact_time(name, u, *params, g))
                       if name in MODELS else None)
    train = model.simulate(25, rng, start_time=0.0, start_speed=1.5, process_sigma=0.003,
                           jitter=2e-5)
    assert np.all(np.isfinite(train.times)) and np.all(np.diff(train.true_times) > 0.0)
    result = model.filter(train.times, start_time=None, start_speed=1.5, process_sigma=0.003,
                          jitter=2e-5)
    assert np.isfinite(result.neg2_log_likelihood)
    scored = result.standardized[result.scored]
    assert scored.size == 24 and np.all(np.isfinite(scored))
    # The model that drew the train describes it: χ² within its 99.9 % range for 24 terms.
    assert 5.9 < result.chi_square < 51.2
