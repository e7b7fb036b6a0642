"""The registry of flight effects: an effect defined here joins through its registry entry alone,
is fitted by the noise fit and by the dashpot models' deterministic fits, gets its rung on a
scene's ladder and in the noise selection like the built-in drag and friction, and its nested
step in the dashpot models' fits where its spec asks; taking it out leaves the registry as it
was.

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

from dashpot.fit import fit_joint, fit_model, prepare_data
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


# ------------------------------------------------ the toy in the dashpot models' fits

OMEGA0, TIMING = 3000.0, 10e-6  # rad/s of the Ia contact; s, timing noise of the drawn trains
DASHPOT_SEED = 20261125 + 60  # a fresh block of seeds, not tuned on


def _ia_train(seed, c=DECELERATION):
    """Impact times (s) of a linear dashpot without gravity in contact (model Ia) flying the
    toy's flight, in closed form: ε = exp(−πζ/√(1 − ζ²)) and contact time π/(ω0√(1 − ζ²))
    for every impact (J. Schäfer, S. Dippel and D. E. Wolf, J. Phys. I France 6, 5, 1996),
    flights of :func:`coulomb_flight` at deceleration c, and Gaussian timing noise."""
    zeta = -math.log(EPS) / math.sqrt(math.pi ** 2 + math.log(EPS) ** 2)
    contact = math.pi / (OMEGA0 * math.sqrt(1.0 - zeta ** 2))
    up, down = G + c, G - c
    rebound = EPS * SPEED * (math.sqrt(down / up) * EPS) ** np.arange(BOUNCES - 1)
    flights = rebound * (1.0 / up + 1.0 / math.sqrt(up * down))
    times = 0.2 + np.concatenate([[0.0], np.cumsum(contact + flights)])
    noise = np.random.default_rng(seed).normal(0.0, TIMING, times.size)
    return pd.DataFrame({"time": times + noise, "time_uncertainty": TIMING})


def test_the_ia_closed_form_is_the_models_contact():
    """The closed forms the toy trains use are the package's Ia contact (ε and ω0·τ)."""
    from dashpot.physics.models import collide

    zeta = -math.log(EPS) / math.sqrt(math.pi ** 2 + math.log(EPS) ** 2)
    contact = collide("Ia", np.array([zeta]), 100.0)
    assert contact.eps[0] == pytest.approx(EPS, rel=1e-12)
    assert contact.contact_time[0] == pytest.approx(math.pi / math.sqrt(1.0 - zeta ** 2),
                                                    rel=1e-12)


def test_registered_effect_is_fitted_by_a_dashpot_model(toy, scene):
    """The toy asked for by a deterministic fit (``effects``): its column set up from its
    spec, its flight entered through its Track into the train solver; c recovered within its
    interval on trains drawn from it (each 95.45 % interval holds the truth; at least 2 of 3
    must, a miss of 2 or more 0.6 % of the time), and c = 0 excluded (measured: c = 0.490 ±
    0.017 m/s² on each of the three trains, truth 0.4903, so c is ~28σ from zero)."""
    fits = [fit_model(prepare_data(_ia_train(DASHPOT_SEED + k), scene), "Ia", scene,
                      effects=(toy.name,)) for k in range(3)]
    assert all(fit.success for fit in fits), [fit.message for fit in fits]
    estimates = [fit.estimates["c_toy"] for fit in fits]
    assert all(e.unit == "m/s^2" and e.status == "fitted" for e in estimates), estimates
    assert all(e.note == "constant deceleration against the motion" for e in estimates)
    assert all("c_toy" in fit.varied for fit in fits)
    inside = sum(e.low95 <= DECELERATION <= e.high95 for e in estimates)
    assert inside >= 2, estimates
    assert all(e.low95 > 0.0 for e in estimates), estimates
    zeta = -math.log(EPS) / math.sqrt(math.pi ** 2 + math.log(EPS) ** 2)
    assert sum(f.estimates["zeta"].low95 <= zeta <= f.estimates["zeta"].high95
               for f in fits) >= 2
    # Without the toy the same trains miss by far (the effect is seen, not absorbed).
    plain = fit_model(prepare_data(_ia_train(DASHPOT_SEED), scene), "Ia", scene)
    assert plain.chisqr > fits[0].chisqr + 100.0
    with pytest.raises(ValueError, match="unknown flight effect"):
        fit_model(prepare_data(_ia_train(DASHPOT_SEED), scene), "Ia", scene,
                  effects=("no-such-effect",))


def test_a_stepped_effect_is_kept_by_the_dashpot_models_nested_step(scene):
    """A toy whose spec asks the dashpot models' fits to try it (``stepped``) is fitted again
    with the model and kept by ΔBIC, as rolling friction on a cart, with no fit asking
    (measured: ΔBIC = 722)."""
    stepped = dataclasses.replace(TOY, name="toy-stepped", meaning="the toy's deceleration",
                                  stepped=lambda scene: True)
    register(stepped)
    try:
        fit = fit_model(prepare_data(_ia_train(DASHPOT_SEED + 3), scene), "Ia", scene)
    finally:
        unregister(stepped.name)
    assert fit.success, fit.message
    assert any(note.startswith("the toy's deceleration kept: BIC without it minus BIC with it")
               for note in fit.notes), fit.notes
    c = fit.estimates["c_toy"]
    assert c.low95 <= DECELERATION <= c.high95, c


def test_an_effect_in_every_fit_is_shared_by_a_joint_fit(scene):
    """A toy the scene puts in every fit (``in_scene``) is carried by each run's dashpot-model
    fit and shared by the runs of a joint fit (one column for all, its default start and
    bounds, fitted free); the joint c holds the truth in its 95.45 % interval (measured:
    0.490 ± 0.012 m/s² from the two runs, each run's own ± 0.017)."""
    shared = dataclasses.replace(TOY, name="toy-shared", in_scene=lambda scene: True)
    register(shared)
    try:
        datas = {run: prepare_data(_ia_train(DASHPOT_SEED + 4 + run), scene) for run in (1, 2)}
        starts = {run: fit_model(data, "Ia", scene) for run, data in datas.items()}
        joint = fit_joint(datas, "Ia", scene, starts)
    finally:
        unregister(shared.name)
    assert all("c_toy" in fit.varied for fit in starts.values())
    assert joint.success, joint.message
    c = joint.estimates["c_toy"]
    assert (c.status, c.unit, c.note) == ("fitted", "m/s^2",
                                          "constant deceleration against the motion, shared")
    assert list(joint.varied).count("c_toy") == 1
    assert c.low95 <= DECELERATION <= c.high95, c
    assert any(note.startswith("toy-shared in flight shared by every run: c_toy fitted free")
               for note in joint.notes), joint.notes
