"""Air drag where the scene needs it: scene keys, drag-true synthetic trains, drag-corrected ε.

The references are independent of the code under test: k_d and g_eff written out by hand from
ρ C_d A/(2(m + ρV/2)) and g(m − ρV)/(m + ρV/2), flights integrated numerically with solve_ivp,
and the fall from rest under drag from its textbook closed form.
"""

import json
import math

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import solve_ivp

import dashpot
from dashpot.bounces import BOUNCE_COLUMNS, DRAG_COLUMNS, bounce_table, launch_speed
from dashpot.cli import main
from dashpot.errors import InputError
from dashpot.physics.flight import drag_flight
from dashpot.scene import Known, Scene, scene_from_mapping
from dashpot.synth.scene import write_scene
from dashpot.synth.train import air_drag

PING_PONG = {"mass": 0.0027, "diameter": 0.040, "drag_coefficient": 0.45}
G = 9.80665


def _hand_drag(mass, diameter, cd, rho, g=G):
    """k_d (1/m) and g_eff (m/s²) of a sphere, written out by hand."""
    volume = math.pi * diameter ** 3 / 6
    inertia = mass + 0.5 * rho * volume  # added mass: half the displaced air
    return (rho * cd * math.pi * diameter ** 2 / 4 / (2 * inertia),
            g * (mass - rho * volume) / inertia)


def _ia_beta(eps, omega0):
    """β of model Ia (ε = exp(−πζ/√(1 − ζ²)), speed-independent) giving `eps`."""
    log = -math.log(eps)
    return omega0 * log / math.hypot(math.pi, log)


# ------------------------------------------------------------------------------ scene keys

def test_drag_constant_and_effective_gravity_from_the_scene_keys():
    scene = scene_from_mapping({"apparatus": {
        "mass": {"value": 0.0027, "uncertainty": 0.0001}, "diameter": 0.040,
        "air_density": 1.18, "drag_coefficient": {"value": 0.5, "uncertainty": 0.04}}})
    assert scene.needs_drag
    k_d, g_eff = _hand_drag(0.0027, 0.040, 0.5, 1.18)
    drag = scene.drag
    assert drag.drag_constant.value == pytest.approx(k_d, rel=1e-12)
    assert drag.effective_gravity.value == pytest.approx(g_eff, rel=1e-12)
    assert scene.driving_acceleration == pytest.approx(g_eff, rel=1e-12)
    assert drag.terminal_speed == pytest.approx(math.sqrt(g_eff / k_d), rel=1e-12)
    # k_d ∝ C_d/m_eff and g_eff ∝ (m − ρV)/m_eff: first-order uncertainties by hand.
    volume = math.pi * 0.040 ** 3 / 6
    inertia = 0.0027 + 0.5 * 1.18 * volume
    k_by_mass = -k_d / inertia
    g_by_mass = G * (inertia - (0.0027 - 1.18 * volume)) / inertia ** 2
    assert drag.drag_constant.uncertainty == pytest.approx(
        math.hypot(k_d / 0.5 * 0.04, k_by_mass * 0.0001), rel=1e-6)
    assert drag.effective_gravity.uncertainty == pytest.approx(abs(g_by_mass) * 0.0001,
                                                               rel=1e-6)
    # Only the mass is uncertain in both (C_d enters k_d alone): their correlation.
    share = k_by_mass * 0.0001 / drag.drag_constant.uncertainty
    assert drag.correlation == pytest.approx(share * np.sign(g_by_mass), rel=1e-6)


def test_defaults_are_sea_level_air_and_the_smooth_sphere_prior():
    scene = scene_from_mapping({"apparatus": {"mass": 0.0027, "diameter": 0.040}})
    k_d, g_eff = _hand_drag(0.0027, 0.040, 0.45, 1.204)
    assert scene.drag.drag_constant == Known(pytest.approx(k_d, rel=1e-12),
                                             pytest.approx(k_d * 0.05 / 0.45, rel=1e-6))
    # g_eff does not depend on C_d; the air density is exact by default.
    assert scene.drag.effective_gravity == Known(pytest.approx(g_eff, rel=1e-12), None)
    # About 2 % of g for a ping-pong ball (buoyancy and added mass).
    assert 0.015 < 1 - g_eff / G < 0.03
    record = json.loads(json.dumps(scene.as_dict()))
    assert record["drag_coefficient"] == {"value": 0.45, "uncertainty": 0.05}
    assert record["air_density"] == {"value": 1.204, "uncertainty": None}
    assert record["drag"]["drag_constant"]["value"] == pytest.approx(k_d, rel=1e-12)
    assert record["driving_acceleration"] == pytest.approx(g_eff, rel=1e-12)


def test_drop_height_under_drag_gives_the_fall_speed():
    scene = scene_from_mapping({"apparatus": {"mass": 0.0027, "diameter": 0.040,
                                              "drop_height": 0.9}})
    k_d, g_eff = _hand_drag(0.0027, 0.040, 0.45, 1.204)
    # From rest: v(h)² = (g/k)(1 − e^{−2kh}), integrated numerically here.
    fall = solve_ivp(lambda t, y: [y[1], g_eff - k_d * y[1] ** 2], (0, 5), [0.0, 0.0],
                     events=lambda t, y: y[0] - 0.9, rtol=1e-12, atol=1e-14)
    assert scene.known_impact_speed.value == pytest.approx(fall.y_events[0][0][1], rel=1e-9)
    # Slower than in vacuum, by about 3 % here.
    assert scene.known_impact_speed.value < math.sqrt(2 * g_eff * 0.9)
    # The C_d prior carries to the speed: dv/dk at fixed h, by a finite difference here.
    speed = lambda k: math.sqrt(g_eff / k * -math.expm1(-2 * k * 0.9))  # noqa: E731
    slope = (speed(k_d * 1.001) - speed(k_d * 0.999)) / (0.002 * k_d)
    assert scene.known_impact_speed.uncertainty == pytest.approx(
        abs(slope) * k_d * 0.05 / 0.45, rel=1e-4)


def test_scenes_without_mass_and_diameter_model_no_drag():
    keys = {"name", "sensor", "recording", "models", "gravity", "incline_angle", "g_eff",
            "mass", "stiffness", "first_impact_speed", "drop_height", "contact_time",
            "timing_resolution", "reader", "accuracy", "driving_acceleration"}
    for apparatus in ({}, {"mass": 0.0027, "drop_height": 0.3}, {"mass": 0.5, "g_eff": 2.9}):
        scene = scene_from_mapping({"apparatus": apparatus})
        assert not scene.needs_drag and scene.drag is None
        assert set(scene.as_dict()) == keys
        assert scene.driving_acceleration == apparatus.get("g_eff", G)
    scene = scene_from_mapping({"apparatus": {"drop_height": 0.3}})
    assert scene.known_impact_speed == Known(math.sqrt(2 * G * 0.3))


@pytest.mark.parametrize("apparatus,key,problem", [
    ({"diameter": 0.04}, "apparatus/diameter", "apparatus.mass missing"),
    ({"mass": 0.0027, "drag_coefficient": 0.5}, "apparatus/drag_coefficient",
     "apparatus.diameter missing"),
    ({"air_density": 1.1}, "apparatus/air_density", "mass and apparatus.diameter missing"),
    ({"mass": 0.0027, "diameter": 1.5}, "apparatus/diameter", "maximum of 1"),
    ({"mass": 0.0027, "diameter": 0.0005}, "apparatus/diameter", "minimum of 0.001"),
    ({"mass": 0.0027, "diameter": 0.04, "air_density": 2.5}, "apparatus/air_density", "2"),
    ({"mass": 0.0027, "diameter": 0.04, "air_density": 0}, "apparatus/air_density", "0"),
    ({"mass": 0.0027, "diameter": 0.04, "drag_coefficient": {"value": 0.4, "uncertainty": 5}},
     "apparatus/drag_coefficient/uncertainty", "maximum of 2"),
    ({"mass": 1e-5, "diameter": 0.5}, "apparatus/diameter", "no denser"),
])
def test_bad_drag_keys_give_one_line_naming_the_key(apparatus, key, problem):
    with pytest.raises(InputError) as error:
        scene_from_mapping({"apparatus": apparatus}, source="lab/scene.yaml")
    message = str(error.value)
    assert len(message.splitlines()) == 1
    assert message.startswith("lab/scene.yaml") and key in message and problem in message


# ---------------------------------------------------------------------- synthetic trains

def _integrated_flight(speed, g, k_d):
    """Duration and landing speed of one flight, integrated numerically."""
    def motion(t, y):
        return [y[1], -g - k_d * y[1] * abs(y[1])]

    def lands(t, y):
        return y[0]
    lands.terminal, lands.direction = True, -1
    solution = solve_ivp(motion, (0, 4 * speed / g + 1), [0.0, speed], events=lands,
                         method="DOP853", rtol=1e-13, atol=1e-15)
    return solution.t_events[0][0], -solution.y_events[0][0][1]


@pytest.mark.parametrize("model", ["Ib", "hybrid"])
def test_drag_train_flights_match_a_direct_integration(model):
    drag = air_drag(G, ball=PING_PONG)
    seq = dashpot.bounce_sequence(model, beta=35.0, omega0=2 * math.pi * 700,
                                  g=drag["effective_gravity"], drag=drag["drag_constant"],
                                  v0=4.0, n_max=15)
    launches = seq.restitution[:-1] * seq.impact_speeds[:-1]
    for index, speed in enumerate(launches):
        duration, landing = _integrated_flight(speed, drag["effective_gravity"],
                                               drag["drag_constant"])
        assert seq.flight_times[index] == pytest.approx(duration, rel=1e-9)
        assert seq.impact_speeds[index + 1] == pytest.approx(landing, rel=1e-9)
    np.testing.assert_allclose(np.diff(seq.impact_times),
                               seq.contact_durations[:-1] + seq.flight_times, rtol=1e-12)
    # Drag shortens the flights and slows the landings.
    assert np.all(seq.flight_times < 2 * launches / drag["effective_gravity"])
    assert np.all(seq.impact_speeds[1:] < launches)


@pytest.mark.parametrize("model", dashpot.MODELS)
def test_vanishing_drag_tends_to_the_gravity_only_train(model):
    """The drag flights (closed forms) at k_d = 1e-12 1/m reproduce the gravity-only
    train's 2v/g flights: the two paths of bounce_sequence agree in the limit."""
    settings = dict(beta=60.0, omega0=900.0, g=9.81, v0=1.7, n_max=40, v_min=0.2)
    drag = dashpot.bounce_sequence(model, drag=1e-12, **settings)
    plain = dashpot.bounce_sequence(model, **settings)
    assert drag.stop_reason == plain.stop_reason and drag.model == plain.model
    for name in ("impact_times", "impact_speeds", "restitution", "contact_durations",
                 "flight_times", "intervals"):
        np.testing.assert_allclose(getattr(drag, name), getattr(plain, name), rtol=1e-10,
                                   err_msg=name)


def test_write_scene_with_zero_drag_writes_the_same_recording(tmp_path):
    settings = dict(beta=20.0, omega0=2 * math.pi * 500, g=9.81, v0=2.0, n_max=12, seed=41)
    for kind in ("audio", "timestamps"):
        plain = write_scene(tmp_path / f"{kind}-plain", kind, **settings)
        zero = write_scene(tmp_path / f"{kind}-zero", kind, drag=0.0, **settings)
        assert zero.read_bytes() == plain.read_bytes()
        plain_truth = json.loads((plain.parent / "truth.json").read_text())
        zero_truth = json.loads((zero.parent / "truth.json").read_text())
        assert "drag" not in plain_truth and "drag_constant" not in plain_truth["units"]
        assert zero_truth.pop("drag")["drag_constant"] == 0.0
        for name in ("drag_constant", "effective_gravity", "terminal_speed", "gravity", "mass",
                     "diameter", "air_density"):
            zero_truth["units"].pop(name)
        assert zero_truth == plain_truth


def test_write_scene_with_a_ball_records_the_drag_in_truth(tmp_path):
    recording = write_scene(tmp_path, "timestamps", model="Ia", beta=30.0, omega0=2e4,
                            g=G, v0=2.5, n_max=20, seed=52, ball=PING_PONG)
    truth = json.loads((tmp_path / "truth.json").read_text())
    k_d, g_eff = _hand_drag(0.0027, 0.040, 0.45, 1.204)
    assert truth["drag"]["drag_constant"] == pytest.approx(k_d, rel=1e-12)
    assert truth["drag"]["effective_gravity"] == pytest.approx(g_eff, rel=1e-12)
    assert truth["drag"]["air_density"] == 1.204 and truth["units"]["drag_constant"] == "1/m"
    times = np.array(truth["sequence"]["impact_times"])
    speeds = np.array(truth["sequence"]["impact_speeds"])
    launch = np.array(truth["sequence"]["restitution"][:-1]) * speeds[:-1]
    flights = np.diff(times) - np.array(truth["sequence"]["contact_durations"][:-1])
    for index in (0, 9, 18):
        duration, landing = _integrated_flight(launch[index], g_eff, k_d)
        assert flights[index] == pytest.approx(duration, rel=1e-9)
        assert speeds[index + 1] == pytest.approx(landing, rel=1e-9)
    # The file holds the drag train's times, to the microseconds it is written with.
    written = pd.read_csv(recording).iloc[:, 0].to_numpy()
    np.testing.assert_allclose(written, times, rtol=0, atol=5.1e-7)


@pytest.mark.parametrize("kind", ["motion_sensor", "photogate"])
def test_drag_for_a_cart_recording_is_refused_before_writing(tmp_path, kind):
    with pytest.raises(ValueError, match="cart"):
        write_scene(tmp_path / "cart", kind, beta=2.0, omega0=22.0, g=2.9, v0=1.0, drag=0.1,
                    flag_length=0.02)
    assert not (tmp_path / "cart").exists()


@pytest.mark.parametrize("spec,problem", [
    ({"drag": 0.1, "ball": PING_PONG}, "not both"),
    ({"ball": {"mass": 0.0027}}, "diameter"),
    ({"ball": {**PING_PONG, "colour": "white"}}, "colour"),
    ({"drag": -0.1}, "drag"),
    ({"ball": {"mass": 1e-6, "diameter": 0.5}}, "no denser"),
])
def test_bad_drag_specs_raise_value_errors(spec, problem):
    with pytest.raises(ValueError, match=problem):
        air_drag(G, **spec)


# ------------------------------------------------------------------------- bounce table

def test_launch_speed_inverts_the_drag_flight_time():
    speeds = np.array([0.0, 1e-9, 1e-3, 0.7, 2.3, 9.0, 40.0, 1e3, 1e6])
    for k_d in (0.0, 1e-9, 0.125, 3.0):
        durations = drag_flight(speeds, 9.6, k_d).duration
        np.testing.assert_allclose(launch_speed(durations, 9.6, k_d), speeds, rtol=1e-13)
    assert np.array_equal(launch_speed([0.1, 0.3], 9.6, 0.0), 0.5 * 9.6 * np.array([0.1, 0.3]))


def _ping_pong_train(v0, n_max, seed_free_eps=0.96):
    drag = air_drag(G, ball=PING_PONG)
    omega0 = 2 * math.pi * 3000  # contact 0.17 ms
    seq = dashpot.bounce_sequence("Ia", beta=_ia_beta(seed_free_eps, omega0), omega0=omega0,
                                  g=drag["effective_gravity"], drag=drag["drag_constant"],
                                  v0=v0, n_max=n_max)
    return seq, drag


def test_apparent_ratio_falls_with_speed_and_the_corrected_eps_is_constant():
    """The issue's ping-pong numbers: ε = 0.96 shows as 0.930 / 0.950 / 0.957 at a launch
    speed of 2.3 / 1.3 / 0.7 m/s; the drag-corrected column gives 0.96 back."""
    seq, drag = _ping_pong_train(v0=2.3 / 0.96, n_max=30)
    impacts = pd.DataFrame({"time": seq.impact_times, "time_uncertainty": 1e-5})
    table = bounce_table(impacts, g=drag["effective_gravity"],
                         contact_duration=seq.contact_durations[0],
                         drag_constant=drag["drag_constant"])
    assert list(table.columns) == list(BOUNCE_COLUMNS + DRAG_COLUMNS)
    # The rebound speeds are the train's launch speeds, the landing speeds its next impacts.
    np.testing.assert_allclose(table["rebound_speed"], seq.restitution[:-1]
                               * seq.impact_speeds[:-1], rtol=1e-10)
    np.testing.assert_allclose(table["landing_speed"], seq.impact_speeds[1:], rtol=1e-10)
    assert table["rebound_speed"].iloc[0] == pytest.approx(2.3, rel=1e-9)
    speeds = table["rebound_speed"].to_numpy()[:-1][::-1]
    apparent = table["restitution"].to_numpy()[:-1][::-1]
    for speed, expected in ((2.3, 0.930), (1.3, 0.950), (0.7, 0.957)):
        assert np.interp(speed, speeds, apparent) == pytest.approx(expected, abs=1.5e-3)
    corrected = table["restitution_corrected"].to_numpy()
    np.testing.assert_allclose(corrected[:-1], 0.96, rtol=1e-9)
    assert np.isnan(corrected[-1])
    # Without the correction the ratio is biased low by far more than its uncertainty.
    assert np.all(0.96 - apparent > 5 * table["restitution_uncertainty"].to_numpy()[:-1][::-1])


def test_corrected_eps_uncertainty_matches_finite_differences():
    seq, drag = _ping_pong_train(v0=3.0, n_max=8)
    sigma = np.array([1e-5, 3e-5, 2e-5, 5e-5, 1e-5, 4e-5, 2e-5, 3e-5])
    settings = dict(g=drag["effective_gravity"], drag_constant=drag["drag_constant"])
    table = bounce_table(pd.DataFrame({"time": seq.impact_times, "time_uncertainty": sigma}),
                         **settings)
    variance = np.zeros(len(table))
    for index in range(seq.impact_times.size):
        moved = []
        for step in (1e-7, -1e-7):
            times = seq.impact_times.copy()
            times[index] += step
            moved.append(bounce_table(pd.DataFrame({"time": times}), **settings)
                         ["restitution_corrected"].to_numpy())
        variance += ((moved[0] - moved[1]) / 2e-7 * sigma[index]) ** 2
    np.testing.assert_allclose(table["restitution_corrected_uncertainty"][:-1],
                               np.sqrt(variance[:-1]), rtol=1e-5)


def test_zero_drag_columns_reduce_to_the_gravity_estimates():
    times = np.concatenate([[0.0], np.cumsum(0.5 * 0.9 ** np.arange(12))])
    impacts = pd.DataFrame({"time": times, "time_uncertainty": 1e-5})
    plain = bounce_table(impacts, g=9.81, contact_duration=0.01)
    zero = bounce_table(impacts, g=9.81, contact_duration=0.01, drag_constant=0.0)
    assert list(plain.columns) == list(BOUNCE_COLUMNS)
    pd.testing.assert_frame_equal(zero[list(BOUNCE_COLUMNS)], plain)
    flights = np.diff(times) - 0.01
    np.testing.assert_allclose(zero["restitution_corrected"][:-1], flights[1:] / flights[:-1],
                               rtol=1e-13)
    np.testing.assert_array_equal(zero["landing_speed"], zero["rebound_speed"])


def test_cli_bounces_with_a_drag_constant(tmp_path, capsys):
    seq, drag = _ping_pong_train(v0=2.0, n_max=12)
    impacts = tmp_path / "impacts.csv"
    pd.DataFrame({"time": seq.impact_times}).to_csv(impacts, index=False)
    output = tmp_path / "bounces.csv"
    assert main(["bounces", str(impacts), "-o", str(output),
                 "--g", repr(drag["effective_gravity"]),
                 "--drag-constant", repr(drag["drag_constant"])]) == 0
    table = pd.read_csv(output)
    # Zero contact duration assumed: ε within the contact's share of the flight (~1e-3).
    np.testing.assert_allclose(table["restitution_corrected"][:-1], 0.96, rtol=2e-3)
    assert "air drag" in capsys.readouterr().out
    with pytest.raises(SystemExit) as stop:  # argparse refuses it before main's handling
        main(["bounces", str(impacts), "-o", str(tmp_path / "bad.csv"), "--drag-constant", "-1"])
    assert stop.value.code == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "--drag-constant" in error
    assert not (tmp_path / "bad.csv").exists()


def test_a_drag_scene_is_fitted_with_drag_and_says_so():
    """A scene that gives mass and diameter is fitted with the drag flight: k_d is a fitted
    parameter under the scene's prior, and the fit's notes say so; a scene without the
    diameter has neither (drag fits themselves: tests/test_flight_fits.py)."""
    from dashpot.fit import fit_model, prepare_data

    times = np.cumsum(np.r_[0.0, 0.3 * 0.95 ** np.arange(12)])
    impacts = pd.DataFrame({"time": times, "time_uncertainty": np.full(times.size, 1e-5)})
    apparatus = {"mass": 0.0027, "diameter": 0.04}
    scene = scene_from_mapping({"apparatus": apparatus}, source="scene.yaml", base=".")
    fit = fit_model(prepare_data(impacts, scene), "Ia", scene)
    notes = [note for note in fit.notes if "air drag" in note]
    assert len(notes) == 1 and "k_d fitted" in notes[0]
    assert f"{scene.drag.drag_constant.value:.3g} +- " in notes[0]
    assert fit.estimates["k_d"].status == "prior" and "k_d" in fit.varied
    plain = scene_from_mapping({"apparatus": {"mass": 0.0027}}, source="scene.yaml", base=".")
    fit = fit_model(prepare_data(impacts, plain), "Ia", plain)
    assert not [note for note in fit.notes if "drag" in note]
    assert "k_d" not in fit.estimates and "k_d" not in fit.varied
