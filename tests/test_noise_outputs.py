"""Fits under the noise model in the cross-scene summary and in a scene's figures.

A scene file written with the noise fits gives one summary row per noise fit (model
``noise:<law>``) with its σ_ε, σ_j and χ²/ν of the innovations, and its figures draw each
noise fit's ε(v) and a second selection panel (with the effects the data required below it);
a scene file without them gives the summary and figures it gave before, plus the empty noise
columns. The train is drawn by the noise model's own simulator: 30 impacts from 2 m/s,
ε = 0.94 with 0.4 % bounce-to-bounce scatter.
"""

import math

import h5py
import numpy as np
import pandas as pd
import pytest

from dashpot.figures import load_record, scene_figures
from dashpot.fit import fit_scene
from dashpot.likelihood import TrainModel
from dashpot.physics.flight import drag_flight, gravity_flight
from dashpot.physics.laws import LAWS
from dashpot.scene import Scene
from dashpot.store import write_scene_fit, write_summary
from dashpot.summary import SUMMARY_COLUMNS, TRUTH_SUMMARY_COLUMNS, summary_from_records

G = 9.80665  # the default scene's g
DETECTOR = 10e-6  # s, the detector's stated timing error
# Columns of the summary before the noise fits were added to it.
COLUMNS_WITHOUT_NOISE = (
    "scene", "model", "success", "selected", "akaike_weight", "delta_aic", "delta_qaic",
    "delta_bic", "redchi",
    "beta", "beta_stderr", "beta_note", "k", "k_stderr", "k_note", "omega0", "omega0_stderr",
    "omega0_note", "zeta", "zeta_stderr", "v0", "v0_stderr", "verdict", "status", "problem")
NOISE_COLUMNS = ("sigma_eps", "sigma_j", "noise_verdict")


@pytest.fixture(scope="module")
def scene_files(tmp_path_factory):
    """One train written twice: fitted with model Ia only, and also under the noise model
    (constant law and Ia). Returns (plain file, noisy file, noisy SceneFit)."""
    model = TrainModel(LAWS["constant"].bind(0.94), lambda v: gravity_flight(v, G))
    drawn = model.simulate(30, np.random.default_rng(60417), start_time=0.3, start_speed=2.0,
                           process_sigma=0.004, jitter=20e-6, detector_sigma=DETECTOR)
    # A timing-only sensor's impact table (as the readers give it: no speeds).
    impacts = pd.DataFrame({"time": drawn.times, "time_uncertainty": DETECTOR,
                            "amplitude": np.nan, "impact_speed": np.nan,
                            "rebound_speed": np.nan, "speed_uncertainty": np.nan, "run": 0})
    folder = tmp_path_factory.mktemp("noise-outputs")
    plain_fit = fit_scene(impacts, Scene(), ("Ia",), noise=False)
    noisy_fit = fit_scene(impacts, Scene(), ("Ia",), noise=True, noise_laws=("constant",))
    write_scene_fit(folder / "plain.h5", plain_fit, impacts)
    write_scene_fit(folder / "noisy.h5", noisy_fit, impacts)
    return folder / "plain.h5", folder / "noisy.h5", noisy_fit


def test_summary_has_one_row_per_noise_fit_with_its_scatter_jitter_and_chi_square(scene_files):
    _, noisy_path, noisy_fit = scene_files
    table = summary_from_records({"noisy": load_record(noisy_path)})
    assert list(table.columns) == list(SUMMARY_COLUMNS)
    assert list(table["model"]) == ["Ia", *(f"noise:{law}" for law in
                                            noisy_fit.noise_selection["model"])]
    # The constant law, its drag rung (the scene gives no mass and diameter) and Ia.
    assert set(noisy_fit.noise_results) == {"constant", "constant+drag", "Ia"}
    rows = table.set_index("model")
    with h5py.File(noisy_path, "r") as source:
        for law in ("constant", "constant+drag", "Ia"):
            stored = source["noise_fits"][law].attrs
            row = rows.loc[f"noise:{law}"]
            assert row["sigma_eps"] == pytest.approx(stored["sigma_eps"], rel=1e-12)
            assert row["sigma_j"] == pytest.approx(stored["sigma_j"], rel=1e-12)
            assert row["redchi"] == pytest.approx(stored["redchi"], rel=1e-12)
            assert bool(row["success"]) == bool(stored["success"])
        selection = pd.DataFrame({name: source["noise_selection"][name][()]
                                  for name in ("model", "akaike_weight", "selected")})
        selection["model"] = [f"noise:{m.decode() if isinstance(m, bytes) else m}"
                              for m in selection["model"]]
        verdict = source["noise_selection"].attrs["verdict"]
    # The selected noise fit is the one the noise selection table marks, weights from it too.
    noise_rows = rows.loc[selection["model"]]
    assert list(noise_rows["selected"]) == list(selection["selected"].astype(bool))
    assert np.allclose(noise_rows["akaike_weight"], selection["akaike_weight"])
    # ζ and ω0 where the noise fit is of a dashpot model, none for the constant law.
    assert math.isnan(rows.loc["noise:constant", "omega0"])
    assert math.isfinite(rows.loc["noise:Ia", "zeta"])
    # Every row of the scene carries its noise verdict; the deterministic row has no σ's.
    assert verdict and (table["noise_verdict"] == verdict).all()
    assert math.isnan(rows.loc["Ia", "sigma_eps"]) and math.isnan(rows.loc["Ia", "sigma_j"])
    # Each row carries its own fit's notes in plain words, the routine ones left out.
    for model, fit in [*((m, noisy_fit.results[m]) for m in noisy_fit.results),
                       *((f"noise:{law}", f) for law, f in noisy_fit.noise_results.items())]:
        shown = rows.loc[model, "notes"].split(" | ") if rows.loc[model, "notes"] else []
        plain = [note for note in fit.notes
                 if not note.startswith(("accuracy ", "start: ", "noise model: rebound"))]
        assert shown == plain, model
    assert any(rows["notes"].str.len() > 0)
    # The summary of the file and of the fit in memory are the same rows.
    from dashpot.select import summary_table
    memory = summary_table({"noisy": noisy_fit})
    assert list(memory["model"]) == list(table["model"])
    assert np.allclose(memory["sigma_eps"], table["sigma_eps"], equal_nan=True)
    assert np.allclose(memory["redchi"], table["redchi"], equal_nan=True)


def test_summary_file_stores_the_jitter_in_seconds(scene_files, tmp_path):
    _, noisy_path, _ = scene_files
    table = summary_from_records({"noisy": load_record(noisy_path)})
    write_summary(tmp_path / "summary.h5", tmp_path / "summary.csv", table)
    with h5py.File(tmp_path / "summary.h5", "r") as source:
        assert source["summary"]["sigma_j"].attrs["units"] == "s"
        assert source["summary"]["sigma_eps"].attrs["units"] == "1"
    written = pd.read_csv(tmp_path / "summary.csv")
    assert sorted(written["model"]) == ["Ia", "noise:Ia", "noise:constant",
                                        "noise:constant+drag"]


def test_scene_without_noise_keeps_its_rows_and_gets_empty_noise_columns(scene_files):
    plain_path, _, _ = scene_files
    table = summary_from_records({"plain": load_record(plain_path)})
    assert list(table.columns) == [*COLUMNS_WITHOUT_NOISE[:-2], *NOISE_COLUMNS, "notes",
                                   *TRUTH_SUMMARY_COLUMNS, "status", "problem"]
    assert list(table["model"]) == ["Ia"]
    assert table["sigma_eps"].isna().all() and table["sigma_j"].isna().all()
    assert (table["noise_verdict"] == "").all()


def _effects_legend(figure):
    """The selection figure's list of the effects the noise selection tried, or None."""
    legends = [*figure.legends, *(ax.get_legend() for ax in figure.axes)]
    found = [legend for legend in legends
             if legend is not None and legend.get_gid() == "noise-effects"]
    assert len(found) <= 1
    return found[0] if found else None


def _lines_by_gid(figure):
    return {line.get_gid(): line for ax in figure.axes for line in ax.get_lines()
            if line.get_gid()}


def test_restitution_figure_draws_each_noise_fit_curve(scene_files):
    _, noisy_path, _ = scene_files
    record = load_record(noisy_path)
    lines = _lines_by_gid(scene_figures(record)["restitution"])
    # The noise fits' curves in the noise selection table's order, after the model's (and
    # its predicted interval ratios, the points being interval ratios).
    assert list(lines) == ["Ia", "ratio:Ia",
                           *(f"noise:{m}" for m in record["noise_selection"]["model"])]
    for law in ("constant", "Ia"):
        line = lines[f"noise:{law}"]
        assert line.get_label() == {"constant": "noise: constant", "Ia": "noise: Ia (A)"}[law]
        curve = record["noise_fits"][law]["eps_curve"]
        order = np.argsort(curve["speed"], kind="stable")
        assert np.allclose(line.get_xdata(), np.asarray(curve["speed"])[order])
        expected = np.asarray(curve["eps"])[order]
        assert np.allclose(line.get_ydata(), np.where(expected > 0, expected, np.nan),
                           equal_nan=True)
    # The constant law's curve is flat at its fitted ε.
    e = record["noise_fits"]["constant"]["parameters"].loc["e", "value"]
    assert np.allclose(lines["noise:constant"].get_ydata(), e)


def test_selection_figure_has_a_panel_of_the_noise_fits_weights(scene_files):
    _, noisy_path, _ = scene_files
    record = load_record(noisy_path)
    figure = scene_figures(record)["selection"]
    assert len(figure.axes) == 2
    noise_axes = figure.axes[1]
    heights = [bar.get_height() for bar in noise_axes.patches]
    weights = record["noise_selection"]["akaike_weight"].to_numpy(float)
    assert np.allclose(heights, np.where(record["noise_selection"]["success"], weights, 0.0))
    labels = {"constant": "constant", "constant+drag": "constant+drag", "Ia": "Ia (A)"}
    assert ([tick.get_text() for tick in noise_axes.get_xticklabels()]
            == [labels[m] for m in record["noise_selection"]["model"]])


@pytest.fixture(scope="module")
def drag_scene_file(tmp_path_factory):
    """A train with strong air drag (k_d = 0.5 1/m from 3 m/s: a flight at 2.8 m/s loses
    about 10 % of its speed, 30 times the 0.3 % scatter), fitted under the noise model with
    the constant law, its drag rung and Ia; the scene gives no mass and diameter."""
    model = TrainModel(LAWS["constant"].bind(0.95), lambda v: drag_flight(v, G, 0.5))
    drawn = model.simulate(30, np.random.default_rng(20261125 + 13), start_time=0.3,
                           start_speed=3.0, process_sigma=0.003, jitter=20e-6,
                           detector_sigma=DETECTOR)
    impacts = pd.DataFrame({"time": drawn.times, "time_uncertainty": DETECTOR})
    path = tmp_path_factory.mktemp("noise-drag") / "drag.h5"
    fit = fit_scene(impacts, Scene(), ("Ia",), noise=True, noise_laws=("constant",))
    write_scene_fit(path, fit, impacts)
    return path


def test_the_drag_train_loses_many_times_its_scatter_per_flight():
    """The drag scene qualifies: 1 − L/u at the fastest rebound, L the closed-form landing
    speed u/√(1 + k_d u²/g) (Timmerman and van der Weele, Am. J. Phys. 67, 538, 1999),
    against the 0.3 % scatter."""
    rebound = 0.95 * 3.0
    landing = rebound / math.sqrt(1.0 + 0.5 * rebound ** 2 / G)
    assert 1.0 - landing / rebound >= 10 * 0.003


@pytest.mark.parametrize("which", ["constant", "drag"])
def test_selection_figure_says_which_effects_the_data_required(which, scene_files,
                                                               drag_scene_file):
    """Below the noise panel a legend: its heading names the effects the data required (as
    the verdict does), one entry per effect tried with its best fit's ΔBIC against the
    simpler rung from the noise selection table; the bars of fits not kept are hatched and
    say "not kept"."""
    path = scene_files[1] if which == "constant" else drag_scene_file
    record = load_record(path)
    table, verdict = record["noise_selection"], record["noise_verdict"]
    figure = scene_figures(record)["selection"]
    noise_axes = figure.axes[1]
    legend = _effects_legend(figure)
    assert legend is not None
    heading = " ".join(legend.get_title().get_text().split())  # wrapped over lines
    entries = [text.get_text() for text in legend.get_texts()]
    # The verdict's split into required and not required effects.
    required_part = verdict.partition("the data required ")[2].partition("; not required")[0]
    tried = [e for e in dict.fromkeys(table["effect"]) if isinstance(e, str) and e]
    assert tried, table
    for effect in tried:
        rows = table[(table["effect"] == effect) & np.isfinite(table["bic_gain"])]
        best = rows.loc[rows["bic_gain"].idxmax()]
        required = bool(best["kept"])  # no gravity models here: nothing is carried
        assert (f"{effect} (" in required_part) == required, (effect, verdict)
        assert (effect in heading) == required, (effect, heading)
        entry = [text for text in entries if text.startswith(f"{effect}: ")]
        assert len(entry) == 1, (effect, entries)
        assert entry[0].startswith(f"{effect}: {'required' if required else 'not required'}")
        assert (f"{best['model']}: ΔBIC = {best['bic_gain']:.1f} against {best['simpler']}"
                in entry[0]), entry
    if "no effect beyond a constant restitution" in verdict:
        assert "no effect beyond" in heading
    if which == "drag":
        assert "drag" in heading and "drag (" in required_part
    # Bars: hatched and "not kept" exactly for the fits the nested steps did not keep.
    notes = [text.get_text() for text in noise_axes.texts]
    for bar, note, kept in zip(noise_axes.patches, notes, table["kept"].astype(bool)):
        assert (bar.get_hatch() == "//") == (not kept)
        assert note.endswith("\nnot kept" if not kept else "\nkept"), note
    assert len(noise_axes.patches) == len(table)


def test_figures_of_a_scene_without_noise_have_no_noise_curves_or_panel(scene_files):
    plain_path, _, _ = scene_files
    figures = scene_figures(load_record(plain_path))
    assert set(figures) == {"intervals", "restitution", "selection"}
    assert set(_lines_by_gid(figures["restitution"])) == {"Ia", "ratio:Ia"}
    assert len(figures["selection"].axes) == 1
    assert figures["selection"].axes[0].get_legend() is None
    assert _effects_legend(figures["selection"]) is None


def test_an_effect_carried_by_a_kept_fit_is_listed_as_required():
    """Ib kept on its step against the constant law (its rung Ia was not kept: ΔBIC 2):
    the contact duration Ib carries is required, carried by Ib, as the verdict says it."""
    from dashpot.figures import noise_effect_steps
    from dashpot.plots import selection_figure

    table = pd.DataFrame({"model": ["constant", "Ia", "Ib"],
                          "effect": ["", "contact duration", "gravity in contact"],
                          "simpler": ["", "constant", "constant"],
                          "bic_gain": [math.nan, 2.0, 9.5], "kept": [True, False, True],
                          "selected": [False, False, True]})
    steps = noise_effect_steps(table)
    assert steps == [("contact duration", "Ia", "constant", 2.0, True, "Ib"),
                     ("gravity in contact", "Ib", "constant", 9.5, True, "")]
    figure = selection_figure(["Ia"], [1.0], [0.0], noise=(["constant", "Ia", "Ib"],
                              [0.1, 0.2, 0.7], [3.0, 1.0, 0.0], "AIC"),
                              noise_steps=steps, noise_kept=table["kept"])
    legend = _effects_legend(figure)
    heading = " ".join(legend.get_title().get_text().split())  # wrapped over lines
    assert heading.startswith("the data required contact duration, gravity in contact (")
    entries = [text.get_text() for text in legend.get_texts()]
    assert entries[0] == ("contact duration: required, carried by Ib\n"
                          "Ia: ΔBIC = 2.0 against constant")
    # Drawn, the list sits inside the figure below the panel (the layout made room for it).
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    box = legend.get_window_extent(canvas.get_renderer())
    assert box.y1 <= figure.axes[1].get_window_extent().y0
    assert box.x0 >= figure.bbox.x0 and box.x1 <= figure.bbox.x1 and box.y0 >= figure.bbox.y0
    # Without the nested-steps columns (older files): no list, nothing hatched.
    assert noise_effect_steps(table.drop(columns="kept")) is None


def test_summary_gives_the_delta_each_akaike_weight_is_computed_from(scene_files):
    """Where no model describes the data the weights come from ΔQAIC = ΔAIC/ĉ: a row of
    ΔAIC 1.7e5 and weight 0.23 read as a contradiction without the ΔQAIC beside them."""
    _, noisy_path, _ = scene_files
    record = load_record(noisy_path)
    table = summary_from_records({"noisy": record})
    rows = table.set_index("model")
    stored = record["selection"].set_index("model")
    assert rows.loc["Ia", "delta_qaic"] == pytest.approx(stored.loc["Ia", "delta_qaic"])
    noise = record["noise_selection"].set_index("model")
    for law in noise.index:
        assert rows.loc[f"noise:{law}", "delta_qaic"] == pytest.approx(
            noise.loc[law, "delta_qaic"])
    finite = np.isfinite(table["delta_qaic"].to_numpy(float))
    weights = np.exp(-0.5 * table["delta_qaic"].to_numpy(float)[finite & ~table["model"]
                                                                 .str.startswith("noise:")])
    assert weights / weights.sum() == pytest.approx(
        table.loc[finite & ~table["model"].str.startswith("noise:"), "akaike_weight"])
