"""The registry of restitution laws: a law defined here joins through its registry entry alone
and is fitted by the noise fit like a built-in one; taking it out leaves the registry as it was.

The toy law ε = e0·(1 − a·v) is the linear law reparametrized (α = e0·a): its train is drawn by
the noise model's own simulator, and its fit must find the truth and the same likelihood maximum
as the built-in linear law on the same data.
"""


import numpy as np
import pandas as pd
import pytest

from dashpot.fit import prepare_data
from dashpot.fit.noise_fit import fit_noise_model
from dashpot.fit.settings import NOISE_LAWS
from dashpot.likelihood import TrainModel
from dashpot.noise_selection import EFFECTS, SIMPLER
from dashpot.physics import laws
from dashpot.physics.flight import gravity_flight
from dashpot.physics.laws import LADDER, LAWS, LawParameter, RestitutionLaw, register, unregister
from dashpot.scene import Scene

G = 9.80665  # the default scene's g
DETECTOR, JITTER, SCATTER = 10e-6, 10e-6, 0.003
E0, SLOPE, SPEED, BOUNCES = 0.92, 0.02, 2.0, 40
SEED = 20261125 + 40  # a fresh block of seeds, not tuned on


def _relative_linear(speed, e0, a):
    """ε = e0·(1 − a·v) and v·dε/dv = −e0·a·v (a in s/m)."""
    return e0 * (1.0 - a * speed), -e0 * a * speed, np.zeros(speed.shape, bool)


TOY = RestitutionLaw(
    "toy-relative-linear", "ε = e0·(1 − a·v)",
    (LawParameter("e0", "", 0.0, 1.0, 0.9, "restitution extrapolated to v = 0"),
     LawParameter("a", "s/m", -0.2, 0.2, 0.0, "relative fall of ε per unit impact speed")),
    _relative_linear, "this test")


@pytest.fixture
def toy():
    before = list(LAWS.items())
    register(TOY)
    try:
        yield TOY
    finally:
        unregister(TOY.name)
    assert list(LAWS.items()) == before


@pytest.fixture(scope="module")
def train():
    """FitData of one train of the toy law under the noise model (σ_ε = 0.3 %, σ_t = 14 µs)."""
    model = TrainModel(TOY.bind(np.array([E0]), np.array([SLOPE])),
                       lambda v: gravity_flight(v, G))
    drawn = model.simulate(BOUNCES, np.random.default_rng(SEED), start_time=0.25,
                           start_speed=SPEED, process_sigma=SCATTER, jitter=JITTER,
                           detector_sigma=DETECTOR)
    return prepare_data(pd.DataFrame({"time": drawn.times[0], "time_uncertainty": DETECTOR}),
                        Scene())


def test_registered_law_is_fitted_and_finds_its_truth(toy, train):
    fit = fit_noise_model(train, toy.name)
    assert fit.success and fit.model == toy.name
    assert tuple(fit.estimates)[:2] == ("e0", "a")
    assert fit.estimates["a"].unit == "s/m"
    # Four parameters each checked at 99.73 % (1.5 times the 95.45 % interval's reach about
    # the estimate, 3σ where the profile is parabolic): a miss 1.1 % of the time at most.
    for name, truth in (("e0", E0), ("a", SLOPE), ("v0", SPEED), ("sigma_eps", SCATTER)):
        estimate = fit.estimates[name]
        low = estimate.value - 1.5 * (estimate.value - estimate.low95)
        high = estimate.value + 1.5 * (estimate.high95 - estimate.value)
        assert low <= truth <= high, (name, truth, estimate)
    # The speed term is seen: a = 0 lies outside the 95.45 % interval (ε rises by 3.6 % over
    # the train, from 0.883 at 2 m/s).
    assert fit.estimates["a"].low95 > 0.0
    # ε(v) reported on the law's own curve.
    curve = fit.eps_curve
    assert np.allclose(curve["eps"], fit.estimates["e0"].value * (
        1.0 - fit.estimates["a"].value * curve["speed"]), rtol=1e-12)


def test_registered_law_reaches_the_likelihood_maximum_of_its_reparametrization(toy, train):
    """ε = e0·(1 − a·v) is the built-in linear law with α = e0·a: one likelihood maximum."""
    fit = fit_noise_model(train, toy.name, profile=False)
    linear = fit_noise_model(train, "linear", profile=False)
    # Both stop where the Newton step gains less than 1e-6 in −2 ln L.
    assert fit.neg2_log_likelihood == pytest.approx(linear.neg2_log_likelihood, abs=1e-3)
    alpha = fit.estimates["e0"].value * fit.estimates["a"].value
    assert alpha == pytest.approx(linear.estimates["alpha"].value,
                                  abs=0.05 * linear.estimates["alpha"].stderr)


def test_registry_is_built_from_its_modules_in_order():
    names = [law.name for module in laws._MODULES for law in module.LAW_SPECS]
    assert list(LAWS) == names
    assert LADDER == tuple(n for n in names if LAWS[n].contact is None) == NOISE_LAWS
    # The selection's rungs are the registry's, beside the flight's own.
    for name, law in LAWS.items():
        assert SIMPLER.get(name) == law.simpler
        assert EFFECTS.get(name, "") == law.effect
    assert TOY.name not in LAWS


def test_register_rejects_a_taken_name_and_unregister_a_built_in_law(toy):
    with pytest.raises(ValueError, match="already registered"):
        register(TOY)
    with pytest.raises(ValueError, match="built-in"):
        unregister("linear")
    with pytest.raises(ValueError, match="no restitution law"):
        unregister("no-such-law")
    orphan = RestitutionLaw("orphan", "ε = e", TOY.parameters[:1], lambda v, e: (e, 0 * v, v < 0),
                            "this test", simpler="no-such-rung")
    with pytest.raises(ValueError, match="simpler rung"):
        register(orphan)
    assert "orphan" not in LAWS
