"""Selection that can fail: the generating rung is selected where its effect is observable, and a
gravity-free train is not handed to a gravity model.

* Under the noise model (:func:`dashpot.noise_selection.noise_selection_table`, the table
  ``fit_scene(..., noise=True)`` reports): a speed term (every law of the ladder: linear,
  power, quadratic, viscoelastic Hertz, Hunt–Crossley, each against the constant law), and
  gravity in contact (Ib, the hybrid and IIb against their gravity-free rungs Ia and IIa; Ib
  and the hybrid also flown with air drag, as is every speed term), each generating rung
  selected in >= 90 % of seeded trains when its effect is >= 5σ of the bounce-to-bounce
  scatter (the cases added last with 20 trains each, judged by a binomial tolerance: at least
  90 % less 3σ); a
  constant-ε train keeps no speed term (with air drag too, where the scene gives the ball), and
  Ia and IIa trains no gravity in contact (with air drag too), in >= 90 %.
* Deterministic fits (:func:`dashpot.fit.fit_scene`, all five models): an Ia train in the soft
  contact where gravity in contact is observable is not declared to prefer a gravity model
  (ΔAIC > 4 over the best gravity-free model, "preferred" in the verdict) in more than 10 % of
  trials. (That gravity trains are selected over Ia and IIa there is
  test_fit.test_gravity_model_beats_the_gravity_free_ones_where_gravity_in_contact_is_observable.)

Effect sizes are those of the noise-free train (the "Asimov" data set of the expected values,
Cowan et al., Eur. Phys. J. C 71, 1554 (2011)): with σ_ε and σ_j held at their true values,
√(−2 ln L of the simpler rung's best fit − that of the generating law's) is the significance
with which a typical trial separates the two, in σ. It is required to be ≥ 5 against every
rung the nested steps may compare the generator with, before the selection is judged.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

import dashpot
from dashpot.fit import fit_scene, prepare_data
from dashpot.fit.noise_fit import fit_noise_models
from dashpot.noise_selection import noise_selection_table
from dashpot.scene import Known, Scene
from test_noise_coverage import (BALL, BALL_DIAMETER, BALL_MASS, JITTER, SCATTER, SEED,
                                 neg2_log_likelihood_of_the_truth, simulated_trains)

G = 9.80665
TRIALS = 30
REQUIRED = 0.9
FEW_TRIALS = 20  # the cases added beside the first ones, judged with a binomial tolerance


def at_least(trials, rate=REQUIRED):
    """Fewest selections of the generator in `trials` still consistent with a selection rate
    of `rate`: the binomial mean less 3σ, trials·rate − 3√(trials·rate·(1 − rate)) (14 of
    20 at 90 %)."""
    return trials * rate - 3.0 * math.sqrt(trials * rate * (1.0 - rate))


def asimov_effect(law, params, rivals, *, count, speed, scene, scatter=SCATTER):
    """Significance (σ) with which the noise-free train of `law` tells it from each rival law,
    the noise parameters held at their true values (σ_ε = `scatter`): √(−2 ln L_rival −
    (−2 ln L_law)) at the best fits (see the module notes). The train flies in `scene`'s
    flight (with its drag where it gives the ball), as the trials do."""
    clean = simulated_trains(law, params, 1, count=count, speed=speed, seed=0, scatter=0.0,
                             jitter=0.0, scene=scene)
    fixed = {"sigma_eps": scatter, "sigma_j": JITTER}

    def best(name):
        return fit_noise_models(clean, name, scene, fixed=fixed,
                                profile=False)[0].neg2_log_likelihood

    # The generator at its truth bounds its own best fit (should that fit stop short).
    own = min(best(law), float(neg2_log_likelihood_of_the_truth(
        law, params, clean, speed=speed, scatter=scatter, scene=scene)[0]))
    return {rival: math.sqrt(max(best(rival) - own, 0.0)) for rival in rivals}


def selected(results_by_law):
    """The fit the nested-steps table selects, one trial at a time: results_by_law maps each
    law to its list of fits over the trials. (The fits are made without profile intervals:
    the selection reads only −2 ln L and the parameter counts.)"""
    names = list(results_by_law)
    chosen = []
    for fits in zip(*results_by_law.values()):
        table, _ = noise_selection_table(dict(zip(names, fits)))
        chosen.append(table.loc[table["selected"], "model"].iloc[0])
    return pd.Series(chosen)


# --- speed term --------------------------------------------------------------------------------

LINEAR = (0.97, 0.006)  # ε from 0.958 at 2 m/s to 0.967 at the last impact
# Without scatter only the 20 µs timing noise hides the term: a 600 times weaker one (ε from
# 0.96998 to 0.96999) is about as far above 5σ.
LINEAR_NO_SCATTER = (0.97, 1e-5)
SPEED_TRAIN = dict(count=40, speed=2.0)


@pytest.mark.parametrize("scatter", [SCATTER, 0.0], ids=["scatter", "no scatter"])
def test_a_speed_term_of_5_sigma_is_selected(scatter):
    params = LINEAR if scatter else LINEAR_NO_SCATTER
    effect = asimov_effect("linear", params, ("constant",), scene=Scene(), scatter=scatter,
                           **SPEED_TRAIN)["constant"]
    assert effect >= 5.0, effect
    data = simulated_trains("linear", params, TRIALS, seed=SEED + 10 + 100 * (scatter == 0.0),
                            scatter=scatter, **SPEED_TRAIN)
    fits = {law: fit_noise_models(data, law, profile=False) for law in ("constant", "linear")}
    chosen = selected(fits)
    share = float(np.mean(chosen == "linear"))
    print(f"\nspeed term of {effect:.1f} sigma: linear selected in {share:.2f} of {TRIALS}")
    assert share >= REQUIRED, chosen.value_counts().to_dict()


@pytest.mark.parametrize("drag", [False, True], ids=["no drag", "drag"])
def test_a_constant_train_keeps_no_speed_term(drag):
    """With drag (a table-tennis ball from 3 m/s, k_d and g_eff in the scene) the flights alone
    shorten the intervals faster than ε does, which a fit without drag would read as a speed
    term; the scene's drag must leave none."""
    scene = BALL if drag else Scene()
    train = dict(SPEED_TRAIN, speed=3.0) if drag else SPEED_TRAIN
    data = simulated_trains("constant", (0.95,), TRIALS, seed=SEED + 11 + drag, scene=scene,
                            **train)
    fits = {law: fit_noise_models(data, law, scene, profile=False)
            for law in ("constant", "linear")}
    chosen = selected(fits)
    assert float(np.mean(chosen == "constant")) >= REQUIRED, chosen.value_counts().to_dict()
    if drag:
        # The control: the same trains fitted without the drag do need a speed term.
        plain = [prepare_data(pd.DataFrame({"time": d.times, "time_uncertainty": d.sigma}),
                              Scene()) for d in data]
        fits = {law: fit_noise_models(plain, law, profile=False)
                for law in ("constant", "linear")}
        chosen = selected(fits)
        assert float(np.mean(chosen == "linear")) >= REQUIRED, chosen.value_counts().to_dict()


# The ladder's other speed terms as generators, each against the constant law (its simpler
# rung). ε over the 40 impacts from 2 m/s (the last one's speed in brackets): power 0.947 to
# 0.956 (0.29 m/s), quadratic 0.958 to 0.969 (0.52 m/s), viscoelastic Hertz 0.950 to 0.964
# (0.37 m/s), Hunt–Crossley 0.962 to 0.985 (0.78 m/s). Without
# scatter power and quadratic take a far weaker term (as LINEAR_NO_SCATTER); viscoelastic Hertz
# and Hunt–Crossley have one parameter that sets ε and its speed dependence together, so theirs
# stays, far above 5σ there.
SPEED_TERMS = {"power": ((0.95, 0.005), (0.95, 1e-5)),
               "quadratic": ((0.97, 0.003), (0.97, 5e-6)),
               "viscoelastic-hertz": ((0.0387,), (0.0387,)),
               "hunt-crossley": ((0.03,), (0.03,))}


@pytest.mark.parametrize("scatter", [SCATTER, 0.0], ids=["scatter", "no scatter"])
@pytest.mark.parametrize("law", list(SPEED_TERMS))
def test_each_speed_term_of_5_sigma_is_selected(law, scatter):
    params = SPEED_TERMS[law][scatter == 0.0]
    effect = asimov_effect(law, params, ("constant",), scene=Scene(), scatter=scatter,
                           **SPEED_TRAIN)["constant"]
    assert effect >= 5.0, effect
    data = simulated_trains(law, params, FEW_TRIALS, scatter=scatter,
                            seed=SEED + 60 + list(SPEED_TERMS).index(law)
                            + 100 * (scatter == 0.0), **SPEED_TRAIN)
    fits = {name: fit_noise_models(data, name, profile=False) for name in ("constant", law)}
    chosen = selected(fits)
    count = int(np.sum(chosen == law))
    print(f"\n{law}: speed term of {effect:.1f} sigma; selected in {count} of {FEW_TRIALS}")
    assert count >= at_least(FEW_TRIALS), chosen.value_counts().to_dict()


# The same laws flown with air drag: the table-tennis ball (BALL: k_d fitted in every fit with
# the prior of its C_d) from 3 m/s. A free k_d takes up part of a speed term (without the ball's
# mass and diameter the two are degenerate), so the linear, quadratic and power terms are
# taken about twice as strong as above to stay beyond 5σ.
DRAG_SPEED_TERMS = {"linear": (0.97, 0.012), "quadratic": (0.97, 0.005), "power": (0.95, 0.01),
                    "viscoelastic-hertz": (0.0387,), "hunt-crossley": (0.03,)}


@pytest.mark.parametrize("law", list(DRAG_SPEED_TERMS))
def test_each_speed_term_of_5_sigma_is_selected_with_drag(law):
    params, train = DRAG_SPEED_TERMS[law], dict(SPEED_TRAIN, speed=3.0)
    effect = asimov_effect(law, params, ("constant",), scene=BALL, **train)["constant"]
    assert effect >= 5.0, effect
    data = simulated_trains(law, params, FEW_TRIALS, scene=BALL,
                            seed=SEED + 90 + list(DRAG_SPEED_TERMS).index(law), **train)
    fits = {name: fit_noise_models(data, name, BALL, profile=False)
            for name in ("constant", law)}
    assert all("k_d" in fit.estimates for fit in fits[law])
    chosen = selected(fits)
    count = int(np.sum(chosen == law))
    print(f"\n{law} with drag: speed term of {effect:.1f} sigma; selected in {count} of "
          f"{FEW_TRIALS}")
    assert count >= at_least(FEW_TRIALS), chosen.value_counts().to_dict()


# --- gravity in contact under the noise model --------------------------------------------------

# The cart-like soft contact with its stiffness and mass known (ω0 = 150 rad/s fixed, as for the
# paper's cart): ṽ from 30 down to about 3 over 18 impacts. (With ω0 fitted as well, a
# gravity-free model's free contact time absorbs most of the effect at these speeds: 1.9σ
# against Ia for 15 impacts.)
SOFT = dict(zeta=0.04, omega0=150.0, speed=2.0, count=18)
MASS = 0.01
RUNG = {"Ib": "Ia", "hybrid": "IIa"}


@pytest.mark.parametrize("scatter", [SCATTER, 0.0], ids=["scatter", "no scatter"])
@pytest.mark.parametrize("generator", sorted(RUNG))
def test_gravity_in_contact_of_5_sigma_is_selected_over_its_gravity_free_rung(generator,
                                                                              scatter):
    zeta, omega0 = SOFT["zeta"], SOFT["omega0"]
    v_star = G / omega0
    scene = Scene(mass=Known(MASS), stiffness=Known(MASS * omega0 ** 2))
    # The nested steps compare with the gravity-free rung, or with the constant law where
    # that rung is not kept: the effect must show against both.
    effect = asimov_effect(generator, (zeta, v_star), ("constant", RUNG[generator]),
                           count=SOFT["count"], speed=SOFT["speed"], scene=scene,
                           scatter=scatter)
    assert min(effect.values()) >= 5.0, effect
    data = simulated_trains(generator, (zeta, v_star), TRIALS, count=SOFT["count"],
                            speed=SOFT["speed"], scatter=scatter,
                            seed=SEED + 20 + sorted(RUNG).index(generator)
                            + 100 * (scatter == 0.0))
    fits = {law: fit_noise_models(data, law, scene, profile=False)
            for law in ("constant", RUNG[generator], generator)}
    chosen = selected(fits)
    share = float(np.mean(chosen == generator))
    print(f"\n{generator}: gravity in contact of {effect} sigma; selected in {share:.2f} "
          f"of {TRIALS} ({chosen.value_counts().to_dict()})")
    assert share >= REQUIRED, chosen.value_counts().to_dict()


# IIb against IIa: its gravity in contact (the release where the spring force vanishes) shows
# less than Ib's before the train is captured; a more damped soft contact, ṽ from 30 down to
# about 9 over 15 impacts, is the one found above 5σ against IIa (with the stiffness and mass
# known, as SOFT).
SOFT_IIB = dict(zeta=0.06, omega0=150.0, speed=2.0, count=15)


@pytest.mark.parametrize("scatter", [SCATTER, 0.0], ids=["scatter", "no scatter"])
def test_iib_gravity_in_contact_of_5_sigma_is_selected_over_iia(scatter):
    zeta, omega0 = SOFT_IIB["zeta"], SOFT_IIB["omega0"]
    scene = Scene(mass=Known(MASS), stiffness=Known(MASS * omega0 ** 2))
    params, train = (zeta, G / omega0), dict(count=SOFT_IIB["count"], speed=SOFT_IIB["speed"])
    effect = asimov_effect("IIb", params, ("constant", "IIa"), scene=scene, scatter=scatter,
                           **train)
    assert min(effect.values()) >= 5.0, effect
    data = simulated_trains("IIb", params, FEW_TRIALS, scatter=scatter, scene=scene,
                            seed=SEED + 70 + 100 * (scatter == 0.0), **train)
    fits = {law: fit_noise_models(data, law, scene, profile=False)
            for law in ("constant", "IIa", "IIb")}
    chosen = selected(fits)
    count = int(np.sum(chosen == "IIb"))
    print(f"\nIIb: gravity in contact of {effect} sigma; selected in {count} of {FEW_TRIALS}")
    assert count >= at_least(FEW_TRIALS), chosen.value_counts().to_dict()


# Dashpot generators flown with air drag: the table-tennis ball's mass and diameter (k_d from
# the scene's C_d prior 0.45 ± 0.05, at its centre in the trains) with the soft contact's
# stiffness known. v* = g_eff/ω0: the fits fix v* from the stiffness and mass at the scene's
# g_eff (buoyancy and added mass in it), so the trains are drawn with that one.
DRAG_SOFT = dict(zeta=0.04, omega0=150.0, speed=2.0, count=18)


@pytest.mark.parametrize("generator", sorted(RUNG))
def test_gravity_in_contact_with_drag_of_5_sigma_is_selected(generator):
    zeta, omega0 = DRAG_SOFT["zeta"], DRAG_SOFT["omega0"]
    scene = Scene(mass=Known(BALL_MASS), diameter=Known(BALL_DIAMETER),
                  stiffness=Known(BALL_MASS * omega0 ** 2))
    assert scene.needs_drag
    params = (zeta, scene.drag.effective_gravity.value / omega0)
    train = dict(count=DRAG_SOFT["count"], speed=DRAG_SOFT["speed"])
    effect = asimov_effect(generator, params, ("constant", RUNG[generator]), scene=scene,
                           **train)
    assert min(effect.values()) >= 5.0, effect
    data = simulated_trains(generator, params, FEW_TRIALS, scene=scene,
                            seed=SEED + 80 + sorted(RUNG).index(generator), **train)
    fits = {law: fit_noise_models(data, law, scene, profile=False)
            for law in ("constant", RUNG[generator], generator)}
    assert all("k_d" in fit.estimates for fit in fits[generator])
    chosen = selected(fits)
    count = int(np.sum(chosen == generator))
    print(f"\n{generator} with drag: gravity in contact of {effect} sigma; selected in "
          f"{count} of {FEW_TRIALS}")
    assert count >= at_least(FEW_TRIALS), chosen.value_counts().to_dict()


GRAVITY = {rung: model for model, rung in RUNG.items()}


@pytest.mark.parametrize("generator", sorted(GRAVITY))
def test_a_gravity_free_train_keeps_no_gravity_in_contact(generator):
    """Ia and IIa trains of the same soft contact: their gravity counterpart is kept (ΔBIC >= 6
    against them) in at most 10 % of the trains."""
    zeta, omega0 = SOFT["zeta"], SOFT["omega0"]
    scene = Scene(mass=Known(MASS), stiffness=Known(MASS * omega0 ** 2))
    data = simulated_trains(generator, (zeta, G / omega0), TRIALS, count=SOFT["count"],
                            speed=SOFT["speed"], seed=SEED + 40 + sorted(GRAVITY).index(generator))
    fits = {law: fit_noise_models(data, law, scene, profile=False)
            for law in ("constant", generator, GRAVITY[generator])}
    chosen = selected(fits)
    share = float(np.mean(chosen == GRAVITY[generator]))
    print(f"\n{generator} train: {GRAVITY[generator]} selected in {share:.2f} of {TRIALS}")
    assert share <= 1.0 - REQUIRED, chosen.value_counts().to_dict()


@pytest.mark.parametrize("generator", sorted(GRAVITY))
def test_a_gravity_free_train_with_drag_keeps_no_gravity_in_contact(generator):
    """Ia and IIa trains of DRAG_SOFT flown with the ball's drag: their gravity counterpart is
    kept in at most 10 % of the trains (binomial tolerance: 10 % plus 3σ)."""
    zeta, omega0 = DRAG_SOFT["zeta"], DRAG_SOFT["omega0"]
    scene = Scene(mass=Known(BALL_MASS), diameter=Known(BALL_DIAMETER),
                  stiffness=Known(BALL_MASS * omega0 ** 2))
    params = (zeta, scene.drag.effective_gravity.value / omega0)
    data = simulated_trains(generator, params, FEW_TRIALS, count=DRAG_SOFT["count"],
                            speed=DRAG_SOFT["speed"], scene=scene,
                            seed=SEED + 95 + sorted(GRAVITY).index(generator))
    fits = {law: fit_noise_models(data, law, scene, profile=False)
            for law in ("constant", generator, GRAVITY[generator])}
    chosen = selected(fits)
    count = int(np.sum(chosen == GRAVITY[generator]))
    print(f"\n{generator} train with drag: {GRAVITY[generator]} selected in {count} of "
          f"{FEW_TRIALS}")
    assert count <= FEW_TRIALS - at_least(FEW_TRIALS), chosen.value_counts().to_dict()


# --- deterministic fits: a gravity-free train --------------------------------------------------

# The soft contact of test_fit's observable scene with ω0 fitted: ṽ from 7.6 over 10 impacts.
IA_TRAIN = dict(beta=0.04 * 150.0, omega0=150.0, v0=7.6 * G / 150.0, count=10, sigma=2e-5)
PREFERRED = 4.0  # ΔAIC beyond which the verdict calls the best model preferred


def test_a_gravity_free_train_is_not_handed_to_a_gravity_model():
    sequence = dashpot.bounce_sequence("Ia", beta=IA_TRAIN["beta"], omega0=IA_TRAIN["omega0"],
                                       g=G, v0=IA_TRAIN["v0"], n_max=IA_TRAIN["count"])
    assert sequence.impact_times.size == IA_TRAIN["count"]
    rng = np.random.default_rng([SEED, 30])
    wrongly, verdicts = 0, []
    for _ in range(TRIALS):
        noise = rng.normal(0.0, IA_TRAIN["sigma"], IA_TRAIN["count"])
        impacts = pd.DataFrame({"time": 0.25 + sequence.impact_times + noise,
                                "time_uncertainty": IA_TRAIN["sigma"]})
        result = fit_scene(impacts, Scene())
        table = result.selection.set_index("model")
        assert table["success"].all()
        free = table.loc[["Ia", "IIa"], "aic"].min()
        gravity = table.loc[["Ib", "IIb", "hybrid"], "aic"].min()
        if free - gravity > PREFERRED:
            wrongly += 1
            verdicts.append(result.verdict)
    print(f"\nIa train: a gravity model preferred in {wrongly} of {TRIALS} trials")
    assert wrongly <= (1.0 - REQUIRED) * TRIALS, verdicts


def test_the_scene_fit_reports_gravity_in_contact_as_required():
    """The same selection as the user gets it from ``fit_scene(..., noise=True)``: one Ib train
    of the soft contact, the deterministic fits and the noise fits (constant law, Ia, Ib)."""
    zeta, omega0 = SOFT["zeta"], SOFT["omega0"]
    scene = Scene(mass=Known(MASS), stiffness=Known(MASS * omega0 ** 2))
    train, = simulated_trains("Ib", (zeta, G / omega0), 1, count=SOFT["count"],
                              speed=SOFT["speed"], seed=SEED + 50)
    impacts = pd.DataFrame({"time": train.time_origin + train.times,
                            "time_uncertainty": train.sigma})
    result = fit_scene(impacts, scene, models=("Ia", "Ib"), noise=True,
                       noise_laws=("constant",))
    table = result.noise_selection.set_index("model")
    assert {"constant", "Ia", "Ib"} <= set(table.index)
    assert table.loc["Ib", "selected"] and table.loc["Ib", "kept"]
    assert result.noise_verdict.startswith("noise model: Ib selected")
    assert "the data required " in result.noise_verdict
    assert "gravity in contact (Ib: ΔBIC = " in result.noise_verdict.split("not required")[0]
