"""Drag-corrected restitution: the library function against flights integrated numerically, the
scene file's bounce table corrected with the fitted drag constant, and the restitution figure.

The references are independent of the code under test: ball flights under gravity and
quadratic drag integrated with solve_ivp (no closed form), the small-drag series of the
corrected ε written out by hand, and the true ε of each bounce of a simulated train. Seeds are
the date 20261125 plus a running number, not tuned.
"""

import functools
import json

import h5py
import numpy as np
import pandas as pd
import pytest
from scipy.integrate import solve_ivp
from scipy.stats import binom

from dashpot.analysis import bounce_drag, stored_bounces
from dashpot.bounces import DRAG_CORRECTION_COLUMNS, drag_correction
from dashpot.figures import drag_corrected_points, load_record, scene_figures
from dashpot.fit import fit_scene
from dashpot.likelihood import TrainModel
from dashpot.physics.flight import drag_flight
from dashpot.physics.laws import LAWS
from dashpot.scene import Known, Scene

G = 9.80665
PING_PONG_DRAG = 0.125  # 1/m: a 2.7 g, 40 mm ball with C_d 0.45 (terminal speed ~8.9 m/s)
EPS = 0.95
SEED = 20261125


def _ode_flight(speed, g, drag):
    """Launch at `speed` upward under dv/dt = −g − k_d·v|v|: (duration, landing speed),
    integrated numerically to the return to the launch height."""
    def rhs(_, state):
        return [state[1], -g - drag * state[1] * abs(state[1])]

    def back(_, state):
        return state[0]

    back.terminal, back.direction = True, -1
    solution = solve_ivp(rhs, (0.0, 4.0 * speed / g + 1.0), [0.0, speed], method="DOP853",
                         events=back, rtol=1e-12, atol=1e-14)
    return solution.t_events[0][0], -solution.y_events[0][0][1]


@functools.lru_cache(maxsize=None)
def _ode_train(first_speed=3.0, count=26, eps=EPS, g=G, drag=PING_PONG_DRAG):
    """Impact times, launch and landing speeds of a ball with a constant ε, flights from
    solve_ivp; read-only arrays."""
    times, launch, landing, speed = [0.0], [], [], first_speed
    for _ in range(count - 1):
        duration, landed = _ode_flight(speed, g, drag)
        times.append(times[-1] + duration)
        launch.append(speed)
        landing.append(landed)
        speed = eps * landed
    arrays = tuple(np.array(values) for values in (times, launch, landing))
    for array in arrays:
        array.flags.writeable = False
    return arrays


def test_exact_train_speeds_and_eps_match_the_integrated_flights():
    times, launch, landing = _ode_train()
    out = drag_correction(times, G, PING_PONG_DRAG)
    assert set(out) == set(DRAG_CORRECTION_COLUMNS)
    assert all(values.shape == (times.size - 1,) for values in out.values())
    np.testing.assert_allclose(out["launch_speed"], launch, rtol=1e-9)
    np.testing.assert_allclose(out["landing_speed"], landing, rtol=1e-9)
    np.testing.assert_allclose(out["restitution_corrected"][:-1], EPS, rtol=1e-9)
    assert np.isnan(out["restitution_corrected"][-1])
    # No uncertainties given: unknown, never 0.
    assert np.isnan(out["restitution_corrected_uncertainty"]).all()
    # The interval ratio of the same train rises toward ε as the ball slows down.
    ratio = np.diff(times)[1:] / np.diff(times)[:-1]
    assert np.all(np.diff(ratio) > 0) and ratio[0] < EPS - 0.02 and ratio[-1] < EPS


def test_corrected_eps_covers_the_constant_truth_where_the_ratio_shows_a_rising_trend():
    """400 timing-noise draws on one integrated train (σ_t = 50 µs): at a fast, a middle and a
    slow bounce the corrected ε lies within 1σ and 2σ of ε = 0.95 at the normal rates
    (binomial 99.9 % bounds), its slope against speed is nil on average, and the uncorrected
    ratio's slope is negative (ε rising as the ball slows) far beyond its spread."""
    times, _, landing = _ode_train()
    sigma, trials = 50e-6, 400
    noisy = times + sigma * np.random.default_rng(SEED).standard_normal((trials, times.size))
    out = drag_correction(noisy, G, PING_PONG_DRAG, time_uncertainty=sigma)
    eps, eps_sigma = out["restitution_corrected"][:, :-1], out[
        "restitution_corrected_uncertainty"][:, :-1]
    pulls = (eps - EPS) / eps_sigma
    for bounce in (0, pulls.shape[1] // 2, pulls.shape[1] - 1):
        for width, rate in ((1.0, 0.682689), (2.0, 0.954500)):
            inside = int(np.sum(np.abs(pulls[:, bounce]) < width))
            low, high = binom.interval(0.999, trials, rate)
            assert low <= inside <= high, (bounce, width, inside, (low, high))
    # Straight-line slopes dε/dv across the train, one per draw.
    speed = landing[:-1]
    centred = speed - speed.mean()

    def slopes(values):
        return (values - values.mean(axis=1, keepdims=True)) @ centred / (centred @ centred)

    intervals = np.diff(noisy, axis=1)
    corrected, apparent = slopes(eps), slopes(intervals[:, 1:] / intervals[:, :-1])
    spread = corrected.std(ddof=1) / np.sqrt(trials)
    assert abs(corrected.mean()) < 4 * spread
    assert apparent.mean() < -20 * apparent.std(ddof=1) / np.sqrt(trials)
    assert apparent.mean() < -0.005  # m/s⁻¹: ε seems to fall by 1 % per 2 m/s


def test_drag_uncertainty_follows_the_small_drag_series():
    """For small k_d·g·T², ε = (T_{n+1}/T_n)(1 + k_d g (T_n² + T_{n+1}²)/16) + O(k_d²)
    (expanding atan and asinh in the flight time), so dε/dk_d is the bracket's factor."""
    times, _, _ = _ode_train(first_speed=1.5, count=10, drag=0.01)
    drag, drag_sigma = 0.01, 1e-4
    out = drag_correction(times, G, drag, drag_uncertainty=drag_sigma)
    flights = np.diff(times)
    series = flights[1:] / flights[:-1] * G * (flights[1:] ** 2 + flights[:-1] ** 2) / 16
    np.testing.assert_allclose(out["restitution_corrected_drag_uncertainty"][:-1],
                               series * drag_sigma, rtol=5e-3)
    np.testing.assert_allclose(out["restitution_corrected"][:-1], EPS, rtol=1e-9)
    # k_d at its lower bound 0 with an uncertainty: the secant from 0, finite.
    zero = drag_correction(times, G, 0.0, drag_uncertainty=drag_sigma)
    assert np.all(np.isfinite(zero["restitution_corrected_drag_uncertainty"][:-1]))
    assert np.all(zero["restitution_corrected_drag_uncertainty"][:-1] > 0)


def test_leading_axes_are_independent_trains_and_no_drag_is_the_interval_ratio():
    times = np.asarray(_ode_train()[0])
    sigma = np.linspace(1e-5, 4e-5, times.size)
    batch = np.stack([times, 1.5 * times + 2.0])
    together = drag_correction(batch, G, PING_PONG_DRAG, time_uncertainty=sigma)
    for row in range(2):
        alone = drag_correction(batch[row], G, PING_PONG_DRAG, time_uncertainty=sigma)
        for name in DRAG_CORRECTION_COLUMNS:
            np.testing.assert_array_equal(together[name][row], alone[name])
    plain = drag_correction(times, G, 0.0, time_uncertainty=sigma, contact_duration=1e-3)
    flights = np.diff(times) - 1e-3
    np.testing.assert_allclose(plain["restitution_corrected"][:-1], flights[1:] / flights[:-1],
                               rtol=1e-13)
    np.testing.assert_allclose(plain["launch_speed"], 0.5 * G * flights, rtol=1e-13)


@pytest.mark.parametrize("times,kwargs,match", [
    ([0.0], {}, "at least two"),
    ([0.0, 0.5, 0.4], {}, "increase"),
    ([0.0, np.nan, 1.0], {}, "finite"),
    ([0.0, 0.5, 0.9], {"time_uncertainty": -1e-5}, "time_uncertainty"),
    ([0.0, 0.5, 0.9], {"contact_duration": 0.45}, "contact_duration"),
])
def test_bad_input_is_refused(times, kwargs, match):
    with pytest.raises(ValueError, match=match):
        drag_correction(times, G, PING_PONG_DRAG, **kwargs)
    with pytest.raises(ValueError, match="drag_constant"):
        drag_correction([0.0, 0.5, 0.9], G, -0.1)


# ------------------------------------------------------------ scene file and figure

@pytest.fixture(scope="module")
def drag_scene(tmp_path_factory):
    """A light ball's train with air drag (k_d = 0.125 1/m, ε = 0.95, 0.3 % bounce-to-bounce
    scatter, 30 µs timing noise) drawn by the noise model's simulator, fitted under the noise
    model (constant and linear laws, the drag rung, model Ia) and written to a scene file."""
    model = TrainModel(LAWS["constant"].bind(EPS),
                       lambda v: drag_flight(v, G, PING_PONG_DRAG))
    drawn = model.simulate(28, np.random.default_rng(SEED + 1), start_time=0.2,
                           start_speed=3.2, process_sigma=0.003, detector_sigma=30e-6)
    impacts = pd.DataFrame({"time": drawn.times, "time_uncertainty": 30e-6, "run": 0})
    scene_fit = fit_scene(impacts, Scene(), ("Ia",), noise=True,
                          noise_laws=("constant", "linear"))
    path = tmp_path_factory.mktemp("drag-scene") / "drag.h5"
    from dashpot.store import write_scene_fit

    write_scene_fit(path, scene_fit, impacts)
    return {"path": path, "scene_fit": scene_fit, "drawn": drawn}


def test_the_scene_file_stores_eps_corrected_with_the_fitted_drag_constant(drag_scene):
    scene_fit, drawn = drag_scene["scene_fit"], drag_scene["drawn"]
    assert "constant+drag" in scene_fit.noise_results
    record = load_record(drag_scene["path"])
    bounces = record["bounces"]
    source = bounces.attrs["drag_source"]
    # The k_d used is the fitted one of the fit the attributes name, which carries a drag
    # constant and is the selected fit where that one does.
    fitted = record["noise_fits"][source]["parameters"].loc["k_d"]
    assert bounces.attrs["drag_constant"] == fitted["value"]
    assert bounces.attrs["drag_constant_uncertainty"] == fitted["stderr"]
    selection = record["noise_selection"].set_index("model")
    if "k_d" in record["noise_fits"][selection.index[selection["selected"]][0]]["parameters"].index:
        assert selection.loc[source, "selected"]
    assert source in bounces.attrs["drag_note"] and "k_d" in bounces.attrs["drag_note"]
    with h5py.File(drag_scene["path"], "r") as handle:
        group = handle["bounces"]
        columns = list(group.attrs["columns"])
        units = {name: group[name].attrs["units"] for name in columns}
    assert columns[-len(DRAG_CORRECTION_COLUMNS):] == list(DRAG_CORRECTION_COLUMNS)
    assert units["landing_speed"] == "m/s" and units["restitution_corrected"] == "1"
    # Against each bounce's true ε (the simulator's rebound over impact speed): the
    # corrected values cover it, the uncorrected ratios fall short at the fast bounces.
    ok = (bounces["restitution_flag"] == "ok").to_numpy()
    truth = (drawn.rebound_speeds / drawn.impact_speeds)[1:len(bounces) + 1][ok]
    corrected = bounces["restitution_corrected"].to_numpy()[ok]
    total = np.hypot(bounces["restitution_corrected_uncertainty"].to_numpy()[ok],
                     bounces["restitution_corrected_drag_uncertainty"].to_numpy()[ok])
    inside = int(np.sum(np.abs(corrected - truth) < 2 * total))
    assert inside >= binom.ppf(0.001, ok.sum(), 0.9545), (inside, ok.sum())
    apparent = bounces["restitution"].to_numpy()[ok]
    apparent_sigma = bounces["restitution_uncertainty"].to_numpy()[ok]
    assert np.all((truth - apparent)[:5] > 5 * apparent_sigma[:5])
    # The in-memory table is the stored one, and the fit's own table is left as it was.
    pd.testing.assert_frame_equal(stored_bounces(scene_fit), bounces, check_like=False)
    assert "restitution_corrected" not in scene_fit.data.bounces


def test_restitution_figure_shows_corrected_points_and_every_fitted_rung(drag_scene):
    record = load_record(drag_scene["path"])
    figure = scene_figures(record)["restitution"]
    ax = figure.axes[0]
    points = {container.get_label(): container for container in ax.containers}
    assert len(points) == 2
    uncorrected = next(label for label in points if "no drag correction" in label)
    corrected = next(label for label in points if label.startswith("drag-corrected"))
    source = record["bounces"].attrs["drag_source"]
    assert source in corrected and "k_d" in corrected
    # The corrected points are the stored column's sound rows, at their landing speeds.
    expected = drag_corrected_points(record)
    x, y = points[corrected].lines[0].get_data()
    np.testing.assert_array_equal(y, expected["eps"])
    np.testing.assert_array_equal(x, expected["speed"])
    bounces = record["bounces"]
    ok = (bounces["restitution_flag"] == "ok").to_numpy()
    np.testing.assert_array_equal(x, bounces["landing_speed"][ok])
    np.testing.assert_array_equal(np.sort(y), np.sort(bounces["restitution_corrected"][ok]))
    assert points[corrected].has_yerr and points[uncorrected].has_yerr
    # Each corrected point's error bar is its whole 1σ: timing and k_d's share in quadrature.
    segments = points[corrected].lines[2][-1].get_segments()
    half = np.array([abs(segment[1][1] - segment[0][1]) / 2 for segment in segments])
    rows = bounces.set_index("landing_speed").loc[x]
    np.testing.assert_allclose(half, np.hypot(rows["restitution_corrected_uncertainty"],
                                              rows["restitution_corrected_drag_uncertainty"]),
                               rtol=1e-9)
    # One curve per fitted rung of the ladder and per model, each named in the legend; the
    # model's predicted ratios beside the uncorrected interval ratios they were fitted to.
    fitted = [name for name, fit in record["noise_fits"].items() if fit["attrs"]["success"]]
    assert {"constant", "constant+drag", "linear", "Ia"} <= set(fitted)
    curves = [line.get_gid() for line in ax.get_lines() if line.get_gid()]
    assert sorted(curves) == sorted(["Ia", "ratio:Ia", *(f"noise:{name}" for name in fitted)])
    beside, below = figure.legends  # the points and the models; the fits under the noise model
    # Wrapped beside the axes, the labels read as the points' own.
    legend = [" ".join(text.get_text().split()) for text in beside.get_texts()]
    assert legend[:2] == [uncorrected, corrected]
    assert "Ia (A)" in legend
    assert "noise model" in below.get_title().get_text()
    assert {"constant", "constant+drag", "linear"} <= {text.get_text()
                                                       for text in below.get_texts()}
    # The y range shows the corrected points with their error bars.
    bottom, top = ax.get_ylim()
    assert bottom < np.min(y) and np.max(y) < top


def test_a_scene_with_mass_and_diameter_corrects_with_its_prior_without_noise_fits(tmp_path):
    """No fit under the noise model: the scene's own k_d (mass, diameter, C_d prior)."""
    times = np.asarray(_ode_train(count=16)[0]) + 0.1
    impacts = pd.DataFrame({"time": times, "time_uncertainty": 20e-6, "run": 0})
    scene = Scene(mass=Known(0.0027), diameter=Known(0.040), models=("Ia",))
    scene_fit = fit_scene(impacts, scene, ("Ia",), noise=False)
    drag = bounce_drag(scene_fit)
    assert drag.source == "scene"
    assert drag.drag_constant == scene.drag.drag_constant.value
    assert drag.uncertainty == scene.drag.drag_constant.uncertainty
    from dashpot.store import write_scene_fit

    write_scene_fit(tmp_path / "prior.h5", scene_fit, impacts)
    bounces = load_record(tmp_path / "prior.h5")["bounces"]
    assert bounces.attrs["drag_source"] == "scene"
    # The scene's k_d (C_d 0.45, 1.204 kg/m³, buoyant g_eff) is near the train's 0.125 1/m:
    # the corrected ε is close to 0.95, the uncorrected ratios are not.
    corrected = bounces["restitution_corrected"].to_numpy()[:-1]
    assert np.all(np.abs(corrected - EPS) < 0.004)
    assert np.min(bounces["restitution"].to_numpy()[:-1]) < EPS - 0.02


def test_a_scene_without_drag_stores_and_draws_what_it_did(tmp_path):
    times = np.concatenate([[0.0], np.cumsum(0.6 * 0.9 ** np.arange(15))])
    impacts = pd.DataFrame({"time": times, "time_uncertainty": 20e-6, "run": 0})
    scene_fit = fit_scene(impacts, Scene(models=("Ia",)), ("Ia",), noise=False)
    assert bounce_drag(scene_fit) is None
    from dashpot.store import write_scene_fit

    write_scene_fit(tmp_path / "plain.h5", scene_fit, impacts)
    with h5py.File(tmp_path / "plain.h5", "r") as handle:
        assert "restitution_corrected" not in handle["bounces"]
        assert "drag_constant" not in handle["bounces"].attrs
    record = load_record(tmp_path / "plain.h5")
    assert drag_corrected_points(record) is None
    ax = scene_figures(record)["restitution"].axes[0]
    # The points are named for what they are: ratios of successive intervals.
    assert [container.get_label() for container in ax.containers] == [
        r"interval ratios $T_{n+1}/T_n$"]
    assert json.loads(json.dumps(list(record["bounces"].attrs))) == []
