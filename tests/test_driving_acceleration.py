"""The driving acceleration the measured speeds and flight times imply, against the scene's.

A cart on an incline fitted under free fall misfits by orders of magnitude (χ²/ν of 10⁵ and
more) and its β and k mean nothing; `analyze` and `fit` say so beside the fits where a motion
sensor's speeds show it.
"""

import re

import numpy as np
import pandas as pd
from cli_run import run_cli

import dashpot
from dashpot.plausibility import acceleration_problem, implied_acceleration
from dashpot.synth.tables import write_motion_sensor


def _flights(launch, up, down, runs=None):
    """Impact table of flights leaving each impact at the speeds `launch` (m/s), decelerated
    at `up` and accelerated back at `down` (m/s²): closed-form kinematics."""
    landing = launch * np.sqrt(down / up)  # the same height up and down
    duration = launch / up + landing / down
    times = np.concatenate([[0.0], np.cumsum(duration)])
    return pd.DataFrame({"time": times,
                         "impact_speed": np.concatenate([[np.nan], landing]),
                         "rebound_speed": np.concatenate([launch, [np.nan]]),
                         "run": 0 if runs is None else runs})


def test_equal_legs_give_their_acceleration_exactly():
    launch = np.random.default_rng(20261126).uniform(0.2, 1.0, 12)
    acceleration, flights = implied_acceleration(_flights(launch, 0.5, 0.5))
    assert flights == 12
    np.testing.assert_allclose(acceleration, 0.5, rtol=1e-12)


def test_legs_differing_by_friction_give_a_mean_of_theirs():
    # The cart: 1.96 m/s² down, 2.05 up.
    acceleration, _ = implied_acceleration(_flights(np.linspace(0.3, 0.9, 8), 2.05, 1.96))
    assert 1.96 < acceleration < 2.05
    assert acceleration_problem(_flights(np.linspace(0.3, 0.9, 8), 2.05, 1.96), 2.0) == ""


def test_runs_are_kept_apart_and_unmeasured_speeds_skipped():
    first = _flights(np.linspace(0.3, 0.9, 5), 0.8, 0.8)
    second = _flights(np.linspace(0.4, 1.0, 5), 0.8, 0.8)
    second["run"] = 1
    second["time"] -= 0.05  # overlapping the first run in time: no flight between them
    table = pd.concat([first, second], ignore_index=True)
    table.loc[2, "rebound_speed"] = np.nan
    acceleration, flights = implied_acceleration(table)
    assert flights == 9
    np.testing.assert_allclose(acceleration, 0.8, rtol=1e-12)
    acceleration, flights = implied_acceleration(table.drop(columns=["impact_speed"]))
    assert np.isnan(acceleration) and flights == 0


def test_a_cart_under_free_fall_is_named():
    table = _flights(np.linspace(0.3, 0.9, 8), 0.5, 0.5)
    problem = acceleration_problem(table, 9.80665)
    assert "0.5 m/s²" in problem and "9.80665 m/s²" in problem and "g_eff" in problem
    assert acceleration_problem(table, 0.5) == ""
    assert acceleration_problem(table.iloc[:3], 9.80665) == ""  # two flights cannot tell


def test_analyze_says_so_for_a_cart_without_its_scene(tmp_path):
    sequence = dashpot.bounce_sequence("Ib", beta=8.0, omega0=300.0, g=0.5, v0=0.5,
                                       v_min=0.05)
    export = tmp_path / "cart.csv"
    write_motion_sensor(export, sequence, runs=1, sample_rate=50.0, seed=20261127)
    # --no-noise: the note comes from the impacts and the scene alone; without g_eff the fit
    # misses this cart's train, and the noise model (noise: auto) would be fitted too, at
    # most of this test's cost.
    status, printed, err = run_cli(["analyze", str(export), "--models", "Ia", "--no-noise",
                                    "-o", str(tmp_path / "free")])
    assert status == 0, err
    implied = re.search(r"imply a driving acceleration of ([0-9.]+) m/s²", printed)
    assert implied and abs(float(implied.group(1)) - 0.5) < 0.025
    scene = tmp_path / "scene.yaml"
    scene.write_text("name: cart\napparatus: {g_eff: 0.5}\n")
    status, printed, err = run_cli(["analyze", str(export), "--scene", str(scene), "--models",
                                    "Ia", "--no-noise", "-o", str(tmp_path / "given")])
    assert status == 0, err
    assert "driving acceleration" not in printed
