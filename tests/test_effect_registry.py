"""The registry of flight effects: an effect defined here joins through its registry entry alone,
is fitted by the noise fit, gets its rung on a scene's ladder and in the noise selection like the
built-in drag and friction; taking it out leaves the registry as it was.

The toy effect is a constant deceleration c against the motion (a body sliding with Coulomb
friction at a known g): a_up = g + c away from the surface, a_down = g − c back. Its train is
drawn by the noise model's own simulator under the closed forms written out here (T(u) =
u/a_up + u/√(a_up a_down), L(u) = u√(a_down/a_up), S. P. Bartz's incline), not the registry's
flight map. From impact times alone c is degenerate with ε (both scale each flight's speed); a
first impact speed known to 0.1 % separates them: the first interval gives e·v0·(1 − c/2g)·2/g,
the ratio of intervals e·(1 − c/g), so c/g is measured to about the relative error of v0 and
of the first rebound (σ_ε), some 0.5 %, and c = 5 % of g is ~10σ.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import solve_ivp

from dashpot.fit import prepare_data
from dashpot.fit.noise_fit import fit_noise_models
from dashpot.fit.noise_scene import fit_noise_scene
from dashpot.likelihood import TrainModel
from dashpot.noise_selection import EFFECTS, SIMPLER
from dashpot.physics import effects
from dashpot.physics.effects import (
    EFFECT_PARAMETERS,
    FLIGHT_EFFECTS,
    EffectParameter,
    FlightEffect,
    flight_map,
    register,
    unregister,
)
from dashpot.physics.flight import Flight
from dashpot.physics.laws import LAWS
from dashpot.scene import Known, Scene

G = 9.80665  # the default scene's g
EPS, SPEED, SCATTER, BOUNCES = 0.9, 2.0, 0.002, 30
DETECTOR, JITTER = 10e-6, 10e-6
DECELERATION = 0.05 * G  # m/s², the toy's c
TRAINS = 3
SEED = 20261125 + 50  # a fresh block of seeds, not tuned on


def _enter(track, deceleration):
    return dataclasses.replace(track, away=track.away + deceleration,
                               toward=track.toward + deceleration)


TOY = FlightEffect(
    "toy-deceleration", "∓c against the motion",
    (EffectParameter("c_toy", "m/s^2", "constant deceleration against the motion",
                     0.0, 0.5 * G, 0.01),),
    _enter, "this test", caveat="the toy's caveat")


def coulomb_flight(speed, c=DECELERATION):
    """Closed form of the toy's flight at g (written out here, independent of the registry)."""
    speed = np.asarray(speed, dtype=float)
    up, down = G + c, G - c
    slope = 1.0 / up + 1.0 / math.sqrt(up * down)
    ratio = math.sqrt(down / up)
    return Flight(duration=speed * slope, landing_speed=speed * ratio,
                  duration_slope=np.full(speed.shape, slope),
                  landing_slope=np.full(speed.shape, ratio))


@pytest.fixture
def toy():
    before = list(FLIGHT_EFFECTS.items())
    ladder = dict(SIMPLER)
    register(TOY)
    try:
        yield TOY
    finally:
        unregister(TOY.name)
    assert list(FLIGHT_EFFECTS.items()) == before
    assert dict(SIMPLER) == ladder


@pytest.fixture(scope="module")
def scene():
    return Scene(first_impact_speed=Known(SPEED, 1e-3 * SPEED))


@pytest.fixture(scope="module")
def trains(scene):
    """FitData of TRAINS trains under the toy's flight (σ_ε = 0.2 %, σ_t = 14 µs)."""
    model = TrainModel(LAWS["constant"].bind(np.full(TRAINS, EPS)), coulomb_flight)
    drawn = model.simulate(BOUNCES, np.random.default_rng(SEED), start_time=0.2,
                           start_speed=SPEED, process_sigma=SCATTER, jitter=JITTER,
                           detector_sigma=DETECTOR)
    return [prepare_data(pd.DataFrame({"time": times, "time_uncertainty": DETECTOR}), scene)
            for times in drawn.times]


def test_the_toy_effect_is_many_times_the_scatter():
    """The scenario qualifies: per flight c takes 1 − √((g − c)/(g + c)) ≈ c/g of the speed,
    5 % against σ_ε = 0.2 %."""
    assert 1.0 - math.sqrt((G - DECELERATION) / (G + DECELERATION)) >= 5.0 * SCATTER


def test_registered_effect_joins_every_consumer_and_leaves_without_a_trace(toy):
    assert FLIGHT_EFFECTS[toy.name] is toy
    assert EFFECT_PARAMETERS["c_toy"] == ("m/s^2", "constant deceleration against the motion")
    assert SIMPLER["constant+toy-deceleration"] == "constant"
    assert EFFECTS["constant+toy-deceleration"] == toy.name
    with pytest.raises(ValueError, match="already registered"):
        register(TOY)
    with pytest.raises(ValueError, match="another effect's"):
        register(dataclasses.replace(TOY, name="toy-drag", parameters=(
            EffectParameter("k_d", "1/m", "a second drag constant"),)))
    with pytest.raises(ValueError, match="built-in"):
        unregister("drag")
    with pytest.raises(ValueError, match="no flight effect"):
        unregister("no-such-effect")


def test_registry_is_built_from_its_modules_in_order():
    names = [effect.name for module in effects._MODULES for effect in module.EFFECT_SPECS]
    assert list(FLIGHT_EFFECTS) == names == ["drag", "friction"]
    assert TOY.name not in FLIGHT_EFFECTS
    assert "constant+toy-deceleration" not in SIMPLER


def _ode_flight(speed, up, down, drag):
    """Duration and landing speed by direct integration (v positive away from the surface)."""
    def rhs(_, y):
        v = y[1]
        return [v, -(up if v > 0.0 else down) - drag * v * abs(v)]

    def landed(_, y):
        return y[0]
    landed.terminal, landed.direction = True, -1.0
    solution = solve_ivp(rhs, (0.0, 10.0), [0.0, speed], events=landed, rtol=1e-11,
                         atol=1e-13, first_step=1e-6)
    # The event at the launch itself (x = 0 rising) is not a crossing downwards.
    return solution.t_events[0][-1], -solution.y_events[0][-1][1]


def test_the_flight_map_enters_the_toy_with_drag_as_an_ode_integrates_them(toy):
    """Drag and the toy at once: a_up = g + c + k_d v², a_down = g − c − k_d v² (moving
    back), integrated directly."""
    speeds = np.array([0.5, 2.0, 6.0])
    k_d = np.full(speeds.size, 0.2)
    c = np.full(speeds.size, DECELERATION)
    flight = flight_map((FLIGHT_EFFECTS["drag"], toy), G, {"k_d": k_d, "c_toy": c})(speeds)
    for k, u in enumerate(speeds):
        duration, landing = _ode_flight(u, G + DECELERATION, G - DECELERATION, 0.2)
        assert flight.duration[k] == pytest.approx(duration, rel=1e-8)
        assert flight.landing_speed[k] == pytest.approx(landing, rel=1e-8)


def test_registered_effect_is_fitted_and_finds_its_truth(toy, trains, scene):
    fits = fit_noise_models(trains, "constant", scene, effects=(toy.name,))
    assert all(fit.success for fit in fits)
    assert all(fit.model == "constant+toy-deceleration" for fit in fits)
    estimates = [fit.estimates["c_toy"] for fit in fits]
    assert all(e.unit == "m/s^2" and e.status == "fitted" for e in estimates)
    # Each 95.45 % interval holds the truth; at least 2 of 3 must (a miss of 2 or more
    # 0.7 % of the time).
    inside = sum(e.low95 <= DECELERATION <= e.high95 for e in estimates)
    assert inside >= 2, estimates
    # The effect is seen: c = 0 lies outside every 95.45 % interval (c is ~10σ).
    assert all(e.low95 > 0.0 for e in estimates), estimates
    e = [fit.estimates["e"] for fit in fits]
    assert sum(x.low95 <= EPS <= x.high95 for x in e) >= 2, e


def test_registered_effect_has_its_rung_in_a_scenes_ladder_and_selection(toy, trains, scene):
    results, table, verdict = fit_noise_scene(trains[0], scene, (), laws=("constant",))
    assert list(results) == ["constant", "constant+toy-deceleration", "constant+drag"]
    row = table.set_index("model").loc["constant+toy-deceleration"]
    assert row["effect"] == toy.name and row["simpler"] == "constant"
    assert bool(row["kept"]) and bool(row["selected"])
    assert f"{toy.name} (constant+toy-deceleration: ΔBIC = " in verdict
    assert "the toy's caveat" in verdict
