"""A scene fitted under the noise model as an option: the law ladder and the models beside the
deterministic fits, the nested-steps selection, the HDF5 groups, the command's flag, and the
filter that keeps a batch going when one parameter set breaks.

Trains are drawn by the noise model's own simulator (:meth:`TrainModel.simulate`) with seeds
chosen once: 40 impacts from 2 m/s, rebound scatter σ_ε = 0.3 %, a detector stating 10 µs and a
further jitter of 17 µs.
"""

import dataclasses
import json
import math
import re
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest

import dashpot
from cli_run import run_cli
from dashpot.errors import InputError
from dashpot.fit import fit_model, fit_scene, prepare_data
from dashpot.fit.noise_fit import fit_noise_model
from dashpot.fit.noise_scene import fit_noise_scene
from dashpot.likelihood import TrainModel
from dashpot.noise_selection import NESTED_STEP_BIC, NOISE_SELECTION_COLUMNS
from dashpot.physics.flight import gravity_flight
from dashpot.physics.laws import LAWS, dashpot_contact_time
from dashpot.scene import Scene, load_scene, scene_from_mapping
from dashpot.store import read_fit, write_scene_fit

G = 9.80665  # the default scene's g
DETECTOR, JITTER, SCATTER = 10e-6, 17e-6, 0.003
DOCS = Path(__file__).resolve().parents[1] / "docs" / "hdf5-layout.md"
REPO = Path(__file__).resolve().parents[1]
RECORDING = REPO.parent / "shared" / "data" / "pingpong-erickson" / "pingpong.wav"


def impact_table(law, params, seed, count=40):
    """Impact table of one train of `law` (no contact duration) drawn from the noise model."""
    model = TrainModel(LAWS[law].bind(*params), lambda v: gravity_flight(v, G))
    drawn = model.simulate(count, np.random.default_rng(seed), start_time=0.4, start_speed=2.0,
                           process_sigma=SCATTER, jitter=JITTER, detector_sigma=DETECTOR)
    return pd.DataFrame({"time": drawn.times, "time_uncertainty": DETECTOR})


@pytest.fixture(scope="module")
def constant_train():
    """A constant-ε train fitted with and without the noise model (full ladder, model Ia)."""
    impacts = impact_table("constant", (0.95,), seed=81123)
    with np.errstate(over="raise", divide="raise", invalid="raise", under="ignore"):
        plain = fit_scene(impacts, Scene(), ("Ia",), noise=False)
        noisy = fit_scene(impacts, Scene(), ("Ia",), noise=True)
    return impacts, plain, noisy


def test_the_filter_gives_a_broken_parameter_set_infinite_likelihood_and_keeps_the_others():
    """A batch of two dashpot parameter sets, the second captured after its first bounce
    (infinite contact time): before, the filter raised ValueError for the whole batch."""
    zeta, v_star = np.array([0.02, 0.3]), np.array([1e-3, 0.2])
    times = 0.1 + np.concatenate([[0.0], np.cumsum(2.0 * 0.95 ** np.arange(1, 12) / G)])

    def model(zeta, v_star):
        return TrainModel(LAWS["IIb"].bind(zeta, v_star), lambda v: gravity_flight(v, G),
                          lambda u: dashpot_contact_time("IIb", u, zeta, v_star, G))

    batch = model(zeta, v_star).filter(times, start_time=None, start_speed=1.0,
                                       process_sigma=0.003, jitter=1e-5)
    alone = model(zeta[:1], v_star[:1]).filter(times, start_time=None, start_speed=1.0,
                                               process_sigma=0.003, jitter=1e-5)
    assert batch.neg2_log_likelihood.shape == (2,)
    assert np.isposinf(batch.neg2_log_likelihood[1])
    assert np.isfinite(batch.neg2_log_likelihood[0])
    assert batch.neg2_log_likelihood[0] == alone.neg2_log_likelihood[0]
    np.testing.assert_array_equal(batch.innovations[0], alone.innovations[0])


def test_a_constant_train_needs_no_speed_term_and_its_scatter_is_covered(constant_train):
    _, _, fit = constant_train
    table = fit.noise_selection.set_index("model")
    assert list(fit.noise_selection.columns) == list(NOISE_SELECTION_COLUMNS)
    # The whole ladder (with the drag rung: the scene gives no mass and diameter), then the
    # requested model, all fitted.
    assert list(table.index) == ["constant", "constant+drag", "linear", "quadratic", "power",
                                 "viscoelastic-hertz", "hunt-crossley", "Ia"]
    assert table["success"].all()
    assert not table.loc[table["effect"] == "speed term", "kept"].any()
    assert table.loc["constant+drag", "effect"] == "drag"
    assert table.loc["constant+drag", "simpler"] == "constant"
    assert table["selected"].sum() == 1 and table.loc["constant", "selected"]
    assert "the data required no effect beyond a constant restitution" in fit.noise_verdict
    assert "noise model: constant selected" in fit.noise_verdict
    # The criteria are those of −2 ln L, and each step is measured against its rung.
    np.testing.assert_allclose(table["aic"], table["neg2_log_likelihood"] + 2 * table["nvarys"])
    np.testing.assert_allclose(table["bic"], table["neg2_log_likelihood"]
                               + table["nvarys"] * np.log(table["ndata"]))
    assert table.loc["linear", "simpler"] == "constant"
    assert table.loc["linear", "bic_gain"] == pytest.approx(
        table.loc["constant", "bic"] - table.loc["linear", "bic"])
    assert table["akaike_weight"].sum() == pytest.approx(1.0)
    constant = fit.noise_results["constant"]
    scatter = constant.estimates["sigma_eps"]
    assert scatter.low95 <= SCATTER <= scatter.high95, scatter
    e = constant.estimates["e"]
    assert e.low95 <= 0.95 <= e.high95, e
    assert abs(constant.redchi - 1.0) < 3.0 * math.sqrt(2.0 / constant.ndata)


def test_a_speed_dependent_train_keeps_its_speed_term():
    """ε = 0.97 − 0.015·v from 2 m/s down: ε changes by about 0.025 along the train, 8σ of
    the bounce-to-bounce scatter."""
    impacts = impact_table("linear", (0.97, 0.015), seed=52904)
    fit = fit_scene(impacts, Scene(), ("Ia",), noise=True,
                    noise_laws=("constant", "linear", "quadratic"))
    table = fit.noise_selection.set_index("model")
    assert list(table.index) == ["constant", "constant+drag", "linear", "quadratic", "Ia"]
    assert table.loc["linear", "kept"]
    assert table.loc["linear", "bic_gain"] >= NESTED_STEP_BIC
    assert not table.loc["constant", "selected"]
    selected = table.index[table["selected"]][0]
    # Without the ball's mass and diameter a free drag mimics a restitution rising as the
    # ball slows: either may be selected, and the verdict says they are degenerate.
    assert table.loc[selected, "effect"] in ("speed term", "drag")
    assert "degenerate with a speed-dependent restitution" in fit.noise_verdict
    assert "the data required " in fit.noise_verdict
    assert re.search(r"speed term \((linear|quadratic): ΔBIC = ", fit.noise_verdict.split(
        "not required")[0]), fit.noise_verdict
    linear = fit.noise_results["linear"].estimates
    assert linear["e0"].low95 <= 0.97 <= linear["e0"].high95, linear["e0"]
    assert linear["alpha"].low95 <= 0.015 <= linear["alpha"].high95, linear["alpha"]


def test_without_noise_nothing_changes(constant_train):
    """The deterministic fits and their selection are the same with and without the noise
    fits, and a fit without them has none."""
    _, plain, noisy = constant_train
    assert plain.noise_results == {} and plain.noise_selection is None
    assert plain.noise_verdict == ""
    assert noisy.verdict == plain.verdict
    pd.testing.assert_frame_equal(noisy.selection, plain.selection)
    for model, fit in plain.results.items():
        assert noisy.results[model].estimates == fit.estimates
        assert noisy.results[model].notes == fit.notes


def _documented_blocks(heading="## Everything in the file"):
    """The text blocks of a section of the layout document (by default "Everything in the
    file"): path -> unit."""
    section = DOCS.read_text().split(heading, 1)[1].split("\n## ", 1)[0]
    blocks = []
    for block in re.findall(r"```text\n(.*?)```", section, flags=re.S):
        tree = {}
        for line in block.splitlines():
            path, _, rest = line.partition(" ")
            rest = rest.strip()
            tree[path] = None if path.endswith("/") else (
                "see column 'unit'" if rest.startswith("see column") else rest.split()[0])
        blocks.append(tree)
    return blocks


def _file_tree(path):
    """Every group and dataset of a file, generic (<model>, <law>): path -> unit."""
    found = {"/": None}

    def generic(name):
        parts = name.split("/")
        if parts[0] == "fits" and len(parts) > 1:
            parts[1] = "<model>"
        if parts[0] == "noise_fits" and len(parts) > 1:
            parts[1] = "<law>"
        return "/" + "/".join(parts)

    with h5py.File(path, "r") as source:
        def visit(name, item):
            if isinstance(item, h5py.Group):
                found[generic(name) + "/"] = None
            else:
                found[generic(name)] = item.attrs["units"]
        source.visititems(visit)
    return found


def test_the_noise_fits_round_trip_through_hdf5_as_documented(constant_train, tmp_path):
    impacts, plain, noisy = constant_train
    base, optional = _documented_blocks()
    # The impact table's columns are those the recording has (here time and its uncertainty).
    base = {path: unit for path, unit in base.items() if not path.startswith("/impacts/")
            or path == "/impacts/"
            or path.rsplit("/", 1)[1] in {*impacts.columns, "used_in_fit"}}
    without, with_noise = tmp_path / "plain.h5", tmp_path / "noise.h5"
    write_scene_fit(without, plain, impacts, config={"models": ["Ia"]})
    write_scene_fit(with_noise, noisy, impacts, config={"models": ["Ia"]})
    # Without the noise fits: exactly the documented base layout, nothing optional. With
    # them, the noise groups, and the bounce table's drag-corrected columns of the drag rung.
    (drag_columns,) = _documented_blocks("## `bounces`")
    assert "constant+drag" in noisy.noise_results
    assert _file_tree(without) == base
    assert _file_tree(with_noise) == {**base, **optional, **drag_columns}
    with h5py.File(with_noise, "r") as source:
        assert set(source["noise_fits"]) == set(noisy.noise_results)
        documented = DOCS.read_text()
        for law in source["noise_fits"]:
            for key in source["noise_fits"][law].attrs:
                assert f"`{key}`" in documented, key
        group = source["noise_fits/constant"]
        scatter = noisy.noise_results["constant"].estimates["sigma_eps"]
        assert group.attrs["sigma_eps"] == scatter.value
        assert list(group.attrs["sigma_eps_interval95"]) == [scatter.low95, scatter.high95]
        assert group.attrs["neg2_log_likelihood"] == \
            noisy.noise_results["constant"].neg2_log_likelihood
        # The step map's accuracy as the fit measured it, never the "exact" it is not.
        constant = noisy.noise_results["constant"]
        assert group.attrs["accuracy"] == constant.accuracy in ("fast", "standard", "exact")
        assert group.attrs["error_bound"] == constant.error_bound
        assert group.attrs["numerical_tolerance"] == constant.numerical_tolerance
        assert (constant.error_bound == 0.0) == (constant.accuracy == "exact")
        assert source["noise_selection"].attrs["verdict"] == noisy.noise_verdict
        columns = list(source["noise_selection"].attrs["columns"])
        assert columns == list(NOISE_SELECTION_COLUMNS)
        # The deterministic part of both files holds the same numbers.
        with h5py.File(without, "r") as other:
            def same(name, item):
                if isinstance(item, h5py.Dataset):
                    np.testing.assert_array_equal(item[()], source[name][()], err_msg=name)
            other.visititems(same)
    record = read_fit(with_noise)
    assert "noise_fits" not in read_fit(without)
    pd.testing.assert_frame_equal(record["noise_selection"], noisy.noise_selection,
                                  check_dtype=False)
    for law, fit in noisy.noise_results.items():
        stored = record["noise_fits"][law]
        assert stored["parameters"].loc["sigma_eps", "value"] == fit.estimates["sigma_eps"].value
        np.testing.assert_array_equal(stored["residuals"]["normalized"],
                                      fit.normalized_residuals)
        np.testing.assert_array_equal(stored["outliers"], fit.outliers)
        assert json.loads(stored["attrs"]["notes"]) == fit.notes


def test_the_scene_key_turns_the_noise_fits_on_and_is_recorded_only_then(tmp_path):
    scene = scene_from_mapping({"noise": True}, source="scene.yaml")
    assert scene.noise and scene.as_dict()["noise"] is True
    assert "noise" not in Scene().as_dict()
    path = tmp_path / "scene.yaml"
    path.write_text("noise: yes please\n")
    with pytest.raises(InputError) as error:
        load_scene(path)
    assert "noise" in str(error.value) and len(str(error.value).splitlines()) == 1
    impacts = impact_table("constant", (0.95,), seed=60217, count=15)
    fit = fit_scene(impacts, scene, ("Ia",), noise_laws=("constant",))
    assert list(fit.noise_results) == ["constant", "constant+drag", "Ia"]
    assert not fit_scene(impacts, scene, ("Ia",), noise=False).noise_results


def test_fit_and_analyze_take_the_noise_flag(tmp_path):
    impacts = impact_table("constant", (0.95,), seed=33471, count=20)
    table = tmp_path / "impacts.csv"
    impacts.to_csv(table, index=False)
    status, out, err = run_cli(["fit", str(table), "-o", str(tmp_path / "noise.h5"),
                                "--models", "Ia", "--noise"])
    assert status == 0, err
    lines = out.splitlines()
    noise_lines = [line for line in lines if line.startswith("  noise ")]
    # One line per noise fit (the ladder, its drag rung and Ia), then the verdict.
    assert len(noise_lines) == 6 + 1 + 1 + 1
    constant = next(line for line in noise_lines if re.match(r"\s+noise\s+constant:", line))
    assert re.search(r"e = 0\.9\d+ ± ", constant)
    # Each amplitude as a value ± σ, or as its 95 % upper limit where consistent with 0.
    assert re.search(r"σ_ε [=<] ", constant) and re.search(r"σ_j [=<] ", constant)
    assert "χ²/ν = " in constant
    assert noise_lines[-1].startswith("  noise selection: noise model: ")
    with h5py.File(tmp_path / "noise.h5", "r") as source:
        assert "noise_fits" in source and "noise_selection" in source
        assert json.loads(source.attrs["config"])["noise"] == list(source["noise_selection"][
            "model"].asstr()[()])
    status, out, err = run_cli(["fit", str(table), "-o", str(tmp_path / "plain.h5"),
                                "--models", "Ia", "--no-noise"])
    assert status == 0, err
    assert "noise" not in out
    with h5py.File(tmp_path / "plain.h5", "r") as source:
        assert "noise_fits" not in source and "noise" not in json.loads(source.attrs["config"])
    status, out, err = run_cli(["analyze", str(table), "-o", str(tmp_path / "analyzed"),
                                "--models", "Ia", "--noise"])
    assert status == 0, err
    assert "  noise selection: noise model: " in out
    with h5py.File(tmp_path / "analyzed" / "impacts.h5", "r") as source:
        assert "noise_fits" in source


def test_a_drag_scene_fits_k_d_with_the_scenes_prior_and_has_no_drag_rung():
    times = np.cumsum(np.r_[0.0, 0.3 * 0.95 ** np.arange(12)])
    impacts = pd.DataFrame({"time": times, "time_uncertainty": np.full(times.size, 1e-5)})
    scene = scene_from_mapping({"apparatus": {"mass": 0.0027, "diameter": 0.04}},
                               source="scene.yaml")
    data = prepare_data(impacts, scene)
    assert not [note for note in data.notes if "drag" in note]
    result = fit_noise_model(data, "constant", scene, profile=False)
    assert [note for note in result.notes
            if note.startswith("air drag: k_d fitted with the scene's prior")]
    k_d, prior = result.estimates["k_d"], scene.drag.drag_constant
    assert k_d.status == "prior" and k_d.unit == "1/m"
    # Twelve drag-free bounces say little of drag: the prior keeps k_d near it.
    assert abs(k_d.value - prior.value) < 3.0 * prior.uncertainty
    assert 0.0 < k_d.stderr < math.inf and k_d.low95 <= prior.value <= k_d.high95
    results, table, verdict = fit_noise_scene(data, scene, (), laws=("constant", "linear"))
    assert list(results) == ["constant", "linear"]
    assert "with the scene's C_d prior" in verdict


@pytest.mark.skipif(not RECORDING.is_file(), reason=f"real recording absent: {RECORDING}")
def test_pingpong_recording_under_the_noise_model():
    """The real ping-pong recording (the ladder and model Ia): the selected noise fit's χ²/ν
    in [0.7, 1.5] and its standardized innovations N(0, 1) by a KS test at 1 % (the issue's
    targets), where the deterministic fit's χ²/ν is in the thousands."""
    from scipy import stats

    from dashpot.analysis import analyze

    # Without the ball's diameter (the scene gives it), so that drag is a rung of its own.
    scene = dataclasses.replace(load_scene(REPO / "data" / "pingpong-erickson" / "scene.yaml"),
                                diameter=None)
    _, fit = analyze(RECORDING, scene, models=("Ia",), noise=True)
    assert fit.noise_selection["success"].all()
    selected = fit.noise_selection.loc[fit.noise_selection["selected"], "model"].iloc[0]
    chosen = fit.noise_results[selected]
    assert 0.7 <= chosen.redchi <= 1.5
    z = chosen.normalized_residuals[np.isfinite(chosen.normalized_residuals)]
    assert z.size > 40 and stats.kstest(z, "norm").pvalue > 0.01
    assert fit.results["Ia"].redchi > 100 * chosen.redchi
    assert fit.noise_verdict.startswith(f"noise model: {selected} selected")
    # The verdict names each effect tried, drag among them, as required or not, with its BIC
    # step.
    assert "the data required " in fit.noise_verdict
    for effect in ("drag", "speed term", "contact duration"):
        assert re.search(rf"{effect} \((carried by \w+; )?[\w+-]+: ΔBIC = -?\d",
                         fit.noise_verdict), (effect, fit.noise_verdict)
    drag = fit.noise_results["constant+drag"].estimates["k_d"]
    assert drag.unit == "1/m" and 0.0 <= drag.low95 <= drag.value <= drag.high95


def test_auto_fits_the_noise_model_only_where_the_deterministic_fits_miss():
    """noise: auto (the default) lets the deterministic fits decide: a train with 0.3 %
    rebound scatter misses every deterministic fit by far more than its stated 10 µs (the
    noise fits are made, and a note says why), a train without scatter or jitter does not
    (none are made, and a note says so); an explicit False never fits them."""
    scattered = impact_table("constant", (0.95,), seed=20261125 + 41, count=30)
    fit = fit_scene(scattered, Scene(), ("Ia",), noise_laws=("constant",))
    assert Scene().noise == "auto"
    assert "constant" in fit.noise_results and "Ia" in fit.noise_results
    assert any(note.startswith("noise model fitted (noise: auto): every deterministic fit "
                               "misses") for note in fit.data.notes), fit.data.notes
    assert fit.results["Ia"].chisqr > 30 * fit.results["Ia"].ndata  # the size of that misfit
    sequence = dashpot.bounce_sequence("Ia", beta=5.0, omega0=500.0, g=G, v0=2.0, n_max=25)
    clean = pd.DataFrame({"time": 0.4 + sequence.impact_times
                          + np.random.default_rng(20261125 + 42).normal(0.0, DETECTOR, 25),
                          "time_uncertainty": DETECTOR})
    plain = fit_scene(clean, Scene(), ("Ia",), noise_laws=("constant",))
    assert not plain.noise_results and plain.noise_selection is None
    assert any(note.startswith("noise model not fitted (noise: auto): the deterministic "
                               "train describes") for note in plain.data.notes)
    assert not fit_scene(scattered, Scene(), ("Ia",), noise=False).noise_results
    # Without stated uncertainties χ² cannot show a misfit: kept deterministic, and said so.
    unstated = fit_scene(scattered.drop(columns="time_uncertainty"), Scene(), ("Ia",),
                         noise_laws=("constant",))
    assert not unstated.noise_results
    assert any("state no uncertainties" in note for note in unstated.data.notes)
