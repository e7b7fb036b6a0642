"""A scene's figures say which scene they show (dashpot.figures, dashpot.plots.name_scene);
where the restitution figure's points are interval ratios it draws each fit's own predicted
ratios, checked against trains integrated contact by contact (test_bounce_train)."""

import json

import numpy as np
import pandas as pd
import pytest
from test_bounce_train import simulate_train

import dashpot
from dashpot import plots
from dashpot.analysis import analyze
from dashpot.figures import (load_record, predicted_interval_ratios, restitution_points,
                             scene_figures, scene_name)
from dashpot.fit import fit_scene
from dashpot.likelihood import TrainModel
from dashpot.physics.flight import gravity_flight
from dashpot.physics.laws import LAWS
from dashpot.scene import Scene
from dashpot.store import write_scene_fit
from dashpot.synth.scene import write_scene


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    """A 15-impact train (ε = 0.9 from 1.5 m/s), fitted with Ia alone, in a scene named
    drop-7."""
    model = TrainModel(LAWS["constant"].bind(0.9), lambda v: gravity_flight(v, 9.80665))
    drawn = model.simulate(15, np.random.default_rng(7), start_time=0.2, start_speed=1.5,
                           process_sigma=0.0, jitter=0.0, detector_sigma=20e-6)
    impacts = pd.DataFrame({"time": drawn.times, "time_uncertainty": 20e-6,
                            "amplitude": np.nan, "impact_speed": np.nan,
                            "rebound_speed": np.nan, "speed_uncertainty": np.nan, "run": 0})
    fit = fit_scene(impacts, Scene(name="drop-7"), ("Ia",), noise=False)
    path = tmp_path_factory.mktemp("named-scene") / "drop-7.h5"
    write_scene_fit(path, fit, impacts)
    return path


def test_every_scene_figure_is_titled_with_the_scene_name(scene_file):
    record = load_record(scene_file)
    assert scene_name(record) == "drop-7"
    for name, figure in scene_figures(record).items():
        assert figure.get_suptitle() == "scene drop-7", name


def test_a_file_without_a_scene_name_leaves_the_figure_untitled():
    assert scene_name({"attrs": {}}) is None
    assert scene_name({"attrs": {"scene": "not json"}}) is None
    assert scene_name({"attrs": {"scene": json.dumps({"name": "a"})}}) == "a"
    figure = plots.name_scene(plots.selection_figure(["Ia"], [1.0], [0.0]), None)
    assert figure.get_suptitle() == ""


# --- the fits' own interval ratios in the restitution figure ---------------------------------

# A noise-free train of Ib (1.6 ms contacts, flights of 0.3 s down to 0.17 s): its interval
# ratios lie about 2e-4 above its ε(v), since each interval holds a contact.
IB_TRAIN = dict(model="Ib", beta=20.0, omega0=2000.0, g=9.80665, v0=1.5, n_max=20)


@pytest.fixture(scope="module")
def noise_free_record(tmp_path_factory):
    """Every model fitted to IB_TRAIN written as a table of times to 1e-10 s (noise free), with
    a stated 10 µs uncertainty."""
    folder = tmp_path_factory.mktemp("noise-free")
    recording = write_scene(folder / "ball", "timestamps", seed=0, uncertainty=1e-5,
                            decimals=10, **IB_TRAIN)
    impacts, fit = analyze(recording, Scene(name="noise-free"))
    write_scene_fit(folder / "noise-free.h5", fit, impacts)
    return load_record(folder / "noise-free.h5")


def test_each_model_predicts_the_interval_ratios_an_integrated_train_has(noise_free_record):
    """Each model's drawn ratios T_{n+1}/T_n are those of its own train at its fitted ζ, ω0
    and v0, integrated here contact by contact (solve_ivp, rtol 1e-12), to the accuracy the
    fit states for its predicted times."""
    ratios = predicted_interval_ratios(noise_free_record)
    assert set(ratios) == set(dashpot.MODELS)
    speed, _, _, _ = restitution_points(noise_free_record)
    bounces = noise_free_record["bounces"]
    assert speed.size == len(bounces) - 1  # every ratio of the noise-free train is sound
    g = IB_TRAIN["g"]
    lines = {line.get_gid(): line for line in
             scene_figures(noise_free_record)["restitution"].axes[0].get_lines()}
    for model, (drawn_speed, drawn_ratio) in ratios.items():
        np.testing.assert_array_equal(drawn_speed, speed)
        fit = noise_free_record["fits"][model]
        value = fit["parameters"]["value"]
        train = simulate_train(model, beta=value["zeta"] * value["omega0"],
                               omega0=value["omega0"], g=g, v0=value["v0"],
                               n_max=IB_TRAIN["n_max"])
        intervals = train.intervals
        expected = intervals[1:] / intervals[:-1]
        # Times good to numerical_tolerance of the train's span: a ratio of two intervals
        # to four such errors over the shortest interval; the integration adds ~1e-11.
        span = train.impact_times[-1]
        bound = 4.0 * fit["attrs"]["numerical_tolerance"] * span / intervals.min() + 1e-10
        np.testing.assert_allclose(drawn_ratio, expected, rtol=0, atol=bound, err_msg=model)
        # The figure draws exactly these, in the order of speed, in the model's colour.
        line = lines[f"ratio:{model}"]
        order = np.argsort(drawn_speed)
        np.testing.assert_array_equal(line.get_xdata(), drawn_speed[order])
        np.testing.assert_array_equal(line.get_ydata(), drawn_ratio[order])
        assert line.get_color() == plots.MODEL_STYLES[model]["color"]


def test_the_points_sit_on_the_generating_models_predicted_ratios_not_on_its_eps(
        noise_free_record):
    """The interval ratios of a noise-free train are what the generating model's fit
    predicts (to 1e-9), while its ε(v) lies ~2e-4 below them: the figure draws the
    former and says which is which."""
    speed, eps, _, _ = restitution_points(noise_free_record)
    drawn_speed, drawn_ratio = predicted_interval_ratios(noise_free_record)["Ib"]
    curve = noise_free_record["fits"]["Ib"]["eps_curve"]
    against_eps = eps - np.interp(speed, curve["speed"], curve["eps"])
    assert 1e-4 < against_eps.mean() < 4e-4  # the bias the ratios have against ε itself
    np.testing.assert_array_equal(drawn_speed, speed)
    assert abs(np.mean(eps - drawn_ratio)) < 1e-8
    assert np.max(np.abs(eps - drawn_ratio)) < 1e-8  # the times are written to 1e-10 s
    figure = scene_figures(noise_free_record)["restitution"]
    (legend,) = figure.legends
    texts = [text.get_text() for text in legend.get_texts()]
    assert texts == [r"interval ratios $T_{n+1}/T_n$",
                     *(plots.MODEL_LABELS[model] for model in dashpot.MODELS)]
    title = legend.get_title().get_text()
    assert r"$\varepsilon(v)$ (line)" in title
    assert r"predicted $T_{n+1}/T_n$ (open markers)" in title
