"""Accuracy levels of the noise model's filter: the tabulated step map against the direct
evaluation of the law, contact time and flight at every step.

The references are the direct evaluation (:meth:`TrainModel.step`, :meth:`TrainModel.filter`),
which the table must approach as the fourth power of its node spacing, and the fits at the
exact level, from which the fast and standard fits must differ by far less than their own
statistical errors. Trains are drawn by :meth:`TrainModel.simulate` with seeds chosen once.
"""

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dashpot.fit import prepare_data
from dashpot.fit.noise_fit import fit_noise_model, fit_noise_models
from dashpot.likelihood import TrainModel
from dashpot.physics.flight import drag_flight, gravity_flight
from dashpot.physics.laws import LAWS, dashpot_contact_time, dashpot_step
from dashpot.scene import Scene

G = 9.80665  # the default scene's g
DETECTOR, JITTER, SCATTER = 10e-6, 20e-6, 0.003
RECORDING = Path(__file__).resolve().parents[1].parent / "shared" / "data" / \
    "pingpong-erickson" / "pingpong.wav"
# Agreement asked of every level with the exact one: −2 ln L within 0.01 and each fitted
# parameter within 0.01 of its standard error.
LIKELIHOOD_TOLERANCE, SHIFT_TOLERANCE = 0.01, 0.01


def law_model(law, *params, flight=None):
    """TrainModel of a law of the registry with per-set parameters (dashpot models with their
    contact time)."""
    params = [np.asarray(p, dtype=float) for p in params]
    flight = flight or (lambda v: gravity_flight(v, G))
    contact = None
    if law in ("Ia", "Ib", "IIa", "IIb", "hybrid"):
        def contact(speed):
            return dashpot_contact_time(law, speed, *params, G)
    return TrainModel(LAWS[law].bind(*params), flight, contact)


def quarter_points(nodes):
    left, right = nodes[:-1], nodes[1:]
    return np.concatenate([left + f * (right - left) for f in (0.25, 0.5, 0.75)])


@pytest.mark.parametrize("law, params, drag", [
    ("hunt-crossley", (0.08,), 0.2),
    ("viscoelastic-hertz", (0.04,), 0.0),
    ("hybrid", (0.03, 0.004), 0.0),
    ("IIb", (0.5, 0.002), 0.2),
])
def test_the_tabulated_step_converges_as_the_fourth_power_of_the_spacing(law, params, drag):
    model = law_model(law, *params, flight=lambda v: drag_flight(v, G, drag))
    errors = []
    for log_step in (1 / 8, 1 / 16):
        table = model.tabulate(0.05, 3.0, log_step)
        probes = quarter_points(table.nodes)
        exact = model.step(probes)
        approx = table.interpolate(probes)
        errors.append(max(np.max(np.abs(approx[q] - exact[q]) / np.abs(exact[q]))
                          for q in (0, 1)))
    assert errors[0] < 1e-5
    # Fourth order: halving the spacing divides the error by about 16.
    assert 8.0 < errors[0] / errors[1] < 32.0


def test_a_map_linear_in_speed_is_tabulated_exactly():
    """Constant ε under gravity: D(u) = 2εu/g and L(u) = εu are cubic polynomials in u."""
    eps = np.array([0.9, 0.95])
    model = law_model("constant", eps)
    table = model.tabulate(0.01, 4.0, 1 / 4)
    probes = quarter_points(table.nodes)
    approx = table.interpolate(probes[:, None], np.arange(2))
    np.testing.assert_allclose(approx[0], 2.0 * eps * probes[:, None] / G, rtol=1e-12)
    np.testing.assert_allclose(approx[1], eps * probes[:, None], rtol=1e-12)
    np.testing.assert_allclose(approx[2], np.broadcast_to(2.0 * eps / G, approx[2].shape),
                               rtol=1e-10)


@pytest.fixture(scope="module")
def drawn():
    """Two trains of 30 impacts of the hybrid model under drag, seeds chosen once."""
    model = law_model("hybrid", 0.02, 0.003, flight=lambda v: drag_flight(v, G, 0.15))
    return model, model.simulate(30, np.random.default_rng(20261125), start_time=0.0,
                                 start_speed=np.array([2.0, 1.5]), process_sigma=SCATTER,
                                 jitter=JITTER, detector_sigma=DETECTOR)


def test_the_tabulated_filter_matches_the_direct_one(drawn):
    model, train = drawn
    arguments = dict(start_time=None, start_speed=np.array([2.0, 1.5]),
                     process_sigma=SCATTER, jitter=JITTER, detector_sigma=DETECTOR)
    direct = model.filter(train.times, **arguments)
    for log_step, tolerance in ((1 / 8, 1e-3), (1 / 32, 1e-5)):
        table = model.tabulate(0.05, 3.0, log_step)
        tabulated, off_grid, _ = table.filter(train.times, **arguments)
        assert not off_grid.any()
        np.testing.assert_allclose(tabulated.neg2_log_likelihood, direct.neg2_log_likelihood,
                                   rtol=0.0, atol=tolerance)
        np.testing.assert_allclose(tabulated.predicted_times, direct.predicted_times,
                                   rtol=0.0, atol=1e-3 * JITTER)
        np.testing.assert_array_equal(tabulated.scored, direct.scored)


def test_a_filter_leaving_the_grid_is_reported_not_extrapolated(drawn):
    model, train = drawn
    table = model.tabulate(0.05, 1.8, 1 / 8)  # the first train starts at 2 m/s, above it
    result, off_grid, stop = table.filter(train.times, start_time=None,
                                          start_speed=np.array([2.0, 1.5]),
                                          process_sigma=SCATTER, jitter=JITTER)
    assert off_grid.tolist() == [True, False]
    assert stop[0] == pytest.approx(2.0) and np.isnan(stop[1])
    assert np.isnan(result.neg2_log_likelihood[0]) and np.isfinite(result.neg2_log_likelihood[1])
    # The step it stopped at, evaluated directly and patched in: the row runs on, as the
    # direct filter does.
    step = model.step(np.array([stop[0]]))
    patched, off_grid, _ = table.filter(
        train.times[:1], start_time=None, start_speed=2.0, process_sigma=SCATTER,
        jitter=JITTER, patches=(stop[:1, None], np.stack(step[:6], axis=-1)[:, None, :],
                                np.array([1])))
    direct = model.filter(train.times[:1], start_time=None, start_speed=2.0,
                          process_sigma=SCATTER, jitter=JITTER)
    assert not off_grid[0]
    assert patched.neg2_log_likelihood[0] == pytest.approx(direct.neg2_log_likelihood[0],
                                                           abs=1e-3)


def test_a_table_at_uneven_speeds_reproduces_the_step_there(drawn):
    """Nodes anywhere (here the speeds a filter passed through): the step is exact at them,
    and a filter through them matches the direct one."""
    model, train = drawn
    arguments = dict(start_time=None, start_speed=np.array([2.0, 1.5]),
                     process_sigma=SCATTER, jitter=JITTER, detector_sigma=DETECTOR)
    direct = model.filter(train.times, **arguments)
    speeds = np.unique(np.concatenate([direct.filtered_speeds.ravel(), [0.9 * 0.1, 2.2]]))
    table = model.tabulate_at(speeds)
    approx = table.interpolate(speeds)
    exact = model.step(speeds)
    for q in (0, 1):
        np.testing.assert_allclose(approx[q], exact[q], rtol=1e-13)
    replayed, off_grid, _ = table.filter(train.times, **arguments)
    assert not off_grid.any()
    np.testing.assert_allclose(replayed.neg2_log_likelihood, direct.neg2_log_likelihood,
                               rtol=0.0, atol=1e-7)
    with pytest.raises(ValueError, match="increasing"):
        model.tabulate_at(speeds[::-1])
    with pytest.raises(ValueError, match="member"):
        table.interpolate(speeds, 1)  # one parameter set tabulated: member 0 only


@pytest.mark.parametrize("model_name", ["Ib", "IIb", "hybrid"])
def test_the_table_is_nan_free_at_the_extremes_of_damping(model_name):
    """ζ → 0, ζ = 1, ζ ≫ 1 and speeds down into capture: every node is finite or marked
    unusable, and a filter through it ends finite, inf (captured) or reported off the grid."""
    zeta = np.array([1e-9, 1.0, 8.0, 0.3])
    v_star = np.array([0.01, 0.01, 0.01, 0.2])  # the last captures below about 0.3 m/s
    contact = lambda u: dashpot_step(model_name, u, zeta, v_star, G)[2:]  # noqa: E731
    model = TrainModel(LAWS[model_name].bind(zeta, v_star), lambda v: gravity_flight(v, G),
                       contact)
    table = model.tabulate(0.01, 5.0, 1 / 8)
    usable = ~table.unusable
    assert np.all(np.isfinite(table.values[usable])) and np.all(np.isfinite(table.slopes[usable]))
    times = np.cumsum(np.full(30, 0.2))
    result, off_grid, _ = table.filter(times, start_time=None, start_speed=2.0,
                                       process_sigma=SCATTER, jitter=JITTER)
    finite_or_inf = ~np.isnan(result.neg2_log_likelihood)
    assert np.all(finite_or_inf | off_grid)


# --- fits at every level against the exact one --------------------------------------------------

def as_data(times):
    return prepare_data(pd.DataFrame({"time": times, "time_uncertainty": DETECTOR}), Scene())


def assert_levels_agree(fits, names):
    """Every level's −2 ln L and parameters against the exact level's, in its standard errors."""
    for level in ("fast", "standard"):
        for exact, other in zip(fits["exact"], fits[level]):
            assert other.accuracy == level and exact.accuracy == "exact"
            assert abs(other.neg2_log_likelihood - exact.neg2_log_likelihood) \
                <= LIKELIHOOD_TOLERANCE
            for name in names:
                reference = exact.estimates[name]
                if not (math.isfinite(reference.stderr) and reference.stderr > 0.0):
                    continue
                shift = abs(other.estimates[name].value - reference.value) / reference.stderr
                assert shift <= SHIFT_TOLERANCE, (level, name, shift)
            assert 0.0 <= other.error_bound < 1e-5
            assert any(note.startswith(f"accuracy {level}:") for note in other.notes)


@pytest.fixture(scope="module")
def hybrid_fits(drawn):
    _, train = drawn
    # Fitted without drag in the scene: the level's accuracy, not the model's truth, is tested.
    datasets = [as_data(times) for times in train.times]
    return {level: fit_noise_models(datasets, "hybrid", accuracy=level, profile=False)
            for level in ("exact", "standard", "fast")}


def test_dashpot_fits_agree_with_the_exact_level(hybrid_fits):
    assert_levels_agree(hybrid_fits, ("zeta", "v_star", "v0", "sigma_eps", "sigma_j"))


def test_ladder_fits_agree_with_the_exact_level():
    model = law_model("hunt-crossley", 0.1)
    train = model.simulate(40, np.random.default_rng(1125), start_time=0.0,
                           start_speed=np.array([2.5, 1.8]), process_sigma=SCATTER,
                           jitter=JITTER, detector_sigma=DETECTOR)
    datasets = [as_data(times) for times in train.times]
    fits = {level: fit_noise_models(datasets, "hunt-crossley", accuracy=level, profile=False)
            for level in ("exact", "standard", "fast")}
    assert_levels_agree(fits, ("chi", "v0", "sigma_eps", "sigma_j"))


def test_auto_takes_the_fast_level_where_it_is_accurate_enough(hybrid_fits, drawn):
    _, train = drawn
    result = fit_noise_model(as_data(train.times[0]), "constant", accuracy="auto")
    assert result.accuracy == "fast"
    assert result.numerical_tolerance == pytest.approx(result.error_bound * 40)


def test_an_unknown_accuracy_is_refused(drawn):
    _, train = drawn
    with pytest.raises(ValueError, match="accuracy must be"):
        fit_noise_model(as_data(train.times[0]), "constant", accuracy="rough")


def test_pingpong_recording_fits_agree_across_levels():
    if not RECORDING.exists():
        pytest.skip(f"real recording {RECORDING} not present (shared data not checked out)")
    from dashpot.analysis import scene_impacts

    data = prepare_data(scene_impacts(RECORDING), Scene())
    fits = {level: [fit_noise_model(data, "linear", accuracy=level, profile=False)]
            for level in ("exact", "standard", "fast")}
    assert_levels_agree(fits, ("e0", "alpha", "v0", "sigma_eps", "sigma_j"))


def test_fits_with_drag_and_friction_agree_with_the_exact_level():
    """The flight's own parameters (a free k_d; g_eff and a friction deceleration) in the
    tabulated step map: a drag train fitted with its drag rung, a cart-like train (two
    accelerations, track_flight) with friction, and a constant fitted with k_d under the C_d
    prior of a ball scene."""
    from dashpot.physics.flight import track_flight

    drag = law_model("constant", 0.95, flight=lambda v: drag_flight(v, G, 0.18))
    train = drag.simulate(40, np.random.default_rng(4411), start_time=0.0,
                          start_speed=np.array([2.5, 1.8]), process_sigma=SCATTER,
                          jitter=JITTER, detector_sigma=DETECTOR)
    datasets = [as_data(times) for times in train.times]
    fits = {level: fit_noise_models(datasets, "constant", accuracy=level, profile=False,
                                    effects=("drag",))
            for level in ("exact", "standard", "fast")}
    assert_levels_agree(fits, ("e", "k_d", "v0", "sigma_eps", "sigma_j"))

    # An incline of 6°: g_eff = g sin θ ≈ 1.03 m/s² with the angle's prior; friction
    # 0.04 m/s².
    scene = Scene(incline_angle=6.0, friction=True)
    g_eff = scene.flight_acceleration.value
    cart = TrainModel(LAWS["constant"].bind(np.full(2, 0.9)),
                      lambda v: track_flight(v, g_eff + 0.04, g_eff - 0.04))
    train = cart.simulate(25, np.random.default_rng(8127), start_time=0.0,
                          start_speed=np.array([0.5, 0.4]), process_sigma=SCATTER,
                          jitter=JITTER, detector_sigma=DETECTOR)
    datasets = [prepare_data(pd.DataFrame({"time": times, "time_uncertainty": DETECTOR}),
                             scene) for times in train.times]
    fits = {level: fit_noise_models(datasets, "constant", scene, accuracy=level,
                                    profile=False, effects=("friction",))
            for level in ("exact", "standard", "fast")}
    assert all("g_eff" in f.estimates for f in fits["fast"])
    assert_levels_agree(fits, ("g_eff", "v0", "sigma_eps", "sigma_j"))
    # From the times alone, friction and ε are one: a flight's legs (uniform deceleration
    # g_eff + f up, acceleration g_eff − f down) scale the speed by √((g_eff − f)/(g_eff + f)),
    # which multiplies ε in every interval ratio. The fit says so (friction undetermined),
    # and along that ridge the levels may stop at different points of one likelihood: what
    # they must agree on is the product.
    def seen(fit):
        value = {name: fit.estimates[name].value for name in ("e", "g_eff", "friction")}
        return value["e"] * math.sqrt((value["g_eff"] - value["friction"])
                                      / (value["g_eff"] + value["friction"]))

    for level in ("fast", "standard"):
        for exact, other in zip(fits["exact"], fits[level]):
            assert not math.isfinite(exact.estimates["friction"].stderr)
            assert abs(seen(other) - seen(exact)) <= SHIFT_TOLERANCE * exact.estimates["e"].stderr
