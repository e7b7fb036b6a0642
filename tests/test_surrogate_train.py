"""The compiled surrogate trains (dashpot.physics.surrogate_train) against two independent
references: the same tables evaluated by numpy (``surrogate_collide``, impact by impact) and
the exact solver's trains, within the tables' certified bound carried along the train.
"""

from __future__ import annotations

import numpy as np
import pytest

import dashpot
from dashpot.physics import surrogate as sg
from dashpot.physics.surrogate_train import surrogate_trains
from dashpot.physics.train import impact_trains

COUNT = 40


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    directory = tmp_path_factory.mktemp("dashpot-cache")
    sg.clear_memory_cache()
    yield directory
    sg.clear_memory_cache()


def numpy_trains(model, zeta, vtilde0, level, cache):
    """The bounce map impact by impact with the numpy evaluation of the same tables."""
    def solver(model, zeta, vtilde):
        return sg.surrogate_collide(model, zeta, vtilde, level=level, directory=cache)

    return impact_trains(model, zeta, vtilde0, COUNT, solver=solver)


def random_trains(model, n, seed):
    """(ζ, ṽ0) over the tables' ζ range, starting 10 to 1e6 times above capture, so that some
    trains are captured within COUNT impacts and some are not."""
    rng = np.random.default_rng(seed)
    zeta = np.exp(rng.uniform(np.log(sg.ZETA_MIN), np.log(sg.ZETA_MAX[model]), n))
    vtilde0 = dashpot.critical_velocity(model, zeta) * np.exp(rng.uniform(np.log(10.0),
                                                                           np.log(1e6), n))
    return zeta, vtilde0


def assert_same_trains(got, want, rtol):
    np.testing.assert_array_equal(got.impacts, want.impacts)
    for name in ("speeds", "restitution", "contact_times"):
        np.testing.assert_allclose(getattr(got, name), getattr(want, name), rtol=rtol, atol=0,
                                   err_msg=name)


@pytest.mark.parametrize("level", tuple(sg.LEVELS))
@pytest.mark.parametrize("model", sg.SURROGATE_MODELS)
def test_same_trains_as_the_numpy_evaluation_of_the_tables(cache, model, level):
    zeta, vtilde0 = random_trains(model, 300, seed=7)
    got = surrogate_trains(model, zeta, vtilde0, COUNT, level=level, directory=cache)
    want = numpy_trains(model, zeta, vtilde0, level, cache)
    # Some trains end in capture, some run the whole count.
    assert 0 < np.sum(want.impacts < COUNT) < zeta.size
    # Same formulas in another order of operations: rounding, grown along the train.
    assert_same_trains(got, want, rtol=1e-12)
    assert got.evaluations == 1 and np.all(got.error_bound == 0.0)


@pytest.mark.parametrize("model", sg.SURROGATE_MODELS)
def test_within_the_certified_bound_of_the_exact_trains(cache, model):
    zeta, vtilde0 = random_trains(model, 200, seed=11)
    got = surrogate_trains(model, zeta, vtilde0, COUNT, level="fast", directory=cache)
    exact = impact_trains(model, zeta, vtilde0, COUNT)
    bound = sg.load_surrogate(model, "fast", directory=cache).bound
    np.testing.assert_array_equal(got.impacts, exact.impacts)
    # Impacts far above capture (the speeds fall along a train, so all before them too):
    # near it ε ∝ √s amplifies the error carried in from the earlier impacts by 1/(2s).
    far = exact.speeds > 1e3 * dashpot.critical_velocity(model, zeta)[:, None]
    assert far.sum() > 1000
    # Speed k is a product of k restitutions, each within the bound (plus rounding).
    allowed = np.broadcast_to(np.arange(COUNT) * bound + 1e-13, far.shape)[far]
    speed_error = np.abs(got.speeds[far] / exact.speeds[far] - 1.0)
    assert np.all(speed_error <= 1.01 * allowed)
    tau_error = np.abs(got.contact_times[far] / exact.contact_times[far] - 1.0)
    assert np.all(tau_error <= 1.01 * (allowed + bound))


@pytest.mark.parametrize("model", sg.SURROGATE_MODELS)
def test_trains_off_the_table_fall_back_to_the_surrogate_map(cache, model):
    # ζ below and above the table, and a train that starts inside the band around capture
    # where the exact solver decides.
    above = 0.95 if model == "Ib" else 1.5 * sg.ZETA_MAX[model]  # Ib captures always at ζ >= 1
    zeta = np.array([0.5 * sg.ZETA_MIN, above, 0.05, 0.05])
    critical = dashpot.critical_velocity(model, zeta)
    vtilde0 = np.array([1e3, 50.0 * critical[1], critical[2] * np.exp(0.5 * sg.S_MIN),
                        1e4])
    got = surrogate_trains(model, zeta, vtilde0, COUNT, level="fast", directory=cache)
    want = numpy_trains(model, zeta, vtilde0, "fast", cache)
    assert_same_trains(got, want, rtol=1e-12)
    assert got.evaluations > 1  # the fallback was used


@pytest.mark.parametrize("model", ("Ia", "IIa"))
def test_gravity_free_models_are_the_closed_forms(cache, model):
    zeta, vtilde0 = np.array([0.01, 0.3, 2.0]), np.array([1.0, 100.0, 1e5])
    got = surrogate_trains(model, zeta, vtilde0, COUNT, directory=cache)
    assert_same_trains(got, impact_trains(model, zeta, vtilde0, COUNT), rtol=0)


def test_bad_count_is_refused(cache):
    with pytest.raises(ValueError, match="count"):
        surrogate_trains("Ib", [0.1], [100.0], 0, directory=cache)
