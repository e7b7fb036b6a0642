"""A scene's figures say which scene they show (dashpot.figures, dashpot.plots.name_scene)."""

import json

import numpy as np
import pandas as pd
import pytest

from dashpot import plots
from dashpot.figures import load_record, scene_figures, scene_name
from dashpot.fit import fit_scene
from dashpot.likelihood import TrainModel
from dashpot.physics.flight import gravity_flight
from dashpot.physics.laws import LAWS
from dashpot.scene import Scene
from dashpot.store import write_scene_fit


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
