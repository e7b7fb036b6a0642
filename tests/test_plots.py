"""Figures: labelled axes, no captured point drawn, inf handled, atomic deterministic saving."""

import io
import os

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D, _get_dash_pattern
from matplotlib.transforms import Bbox

import dashpot
from dashpot import plots


def _render(fig):
    """Draw the figure (all artists, layout) and return the PNG bytes."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=40)
    return buffer.getvalue()


def _model_lines(ax):
    """The model curves of an axes, keyed by model (their gid)."""
    return {line.get_gid(): line for line in ax.get_lines() if line.get_gid() in dashpot.MODELS}


def _legend_texts(fig):
    """Every legend entry's text, a wrapped one joined back into one line."""
    return [" ".join(text.get_text().split())
            for legend in fig.legends + [ax.get_legend() for ax in fig.axes]
            if legend is not None for text in legend.get_texts()]


def _legend(fig, gid):
    (legend,) = [legend for legend in fig.legends if legend.get_gid() == gid]
    return legend


def _scene():
    n = np.arange(1, 21)
    observed = 0.5 * 0.9 ** n
    sigma = np.full(n.size, 1e-4)
    predictions = {"Ia": 0.5 * 0.905 ** n,
                   "Ib": 0.5 * 0.9 ** n[:15],                       # captures earlier
                   "IIb": np.where(n % 5 == 0, np.nan, 0.5 * 0.899 ** n),
                   "hybrid": 0.5 * 0.9 ** n}
    return n, observed, sigma, predictions


def _detection_inputs(n=600_000, rate=44_100.0):
    time_s = np.arange(n) / rate
    impacts = 0.2 + np.cumsum(0.5 * 0.85 ** np.arange(30))
    impacts = impacts[impacts < time_s[-1]]
    envelope = np.full(n, 0.01)
    for k, t in enumerate(impacts):
        i = int(t * rate)
        envelope[i:i + 200] += 0.8 * 0.95 ** k * np.exp(-np.arange(min(200, n - i)) / 50.0)
    return time_s, envelope, impacts


BUILDERS = {
    "contact_time": lambda: plots.contact_time_figure(points=61),
    "restitution": lambda: plots.restitution_figure(speeds=(15, 5), points=61),
    "critical_speed": lambda: plots.critical_speed_figure(points=61),
    "restitution_vs_speed": lambda: plots.restitution_vs_speed_figure(zetas=(0.2,), points=60),
    "detection": lambda: plots.detection_figure(*_detection_inputs(20_000)),
    "intervals": lambda: plots.intervals_figure(*_scene(), failed=("IIa",)),
    "restitution_speed": lambda: plots.restitution_speed_figure(
        [0.5, 1.0, 2.0], [0.7, 0.8, 0.85], [0.01, 0.02, 0.04], [0.02, 0.02, 0.02],
        {"Ib": (np.linspace(0.1, 2.5, 50), np.linspace(0.0, 0.88, 50))}),
    "selection": lambda: plots.selection_figure(dashpot.MODELS, [0.1, 0.4, np.nan, 0.05, 0.45],
                                                [2.9, 0.2, np.nan, 4.4, 0.0]),
}


@pytest.mark.parametrize("name", sorted(BUILDERS))
def test_figure_has_labelled_axes_and_renders(name):
    fig = BUILDERS[name]()
    assert isinstance(fig, Figure)
    assert fig.axes
    for ax in fig.axes:
        assert ax.get_xlabel().strip(), f"{name}: axes without x label"
        assert ax.get_ylabel().strip(), f"{name}: axes without y label"
    assert _render(fig).startswith(b"\x89PNG")


def test_models_keep_one_style_and_paper_label_everywhere():
    assert plots.MODEL_LABELS == {"Ia": "Ia (A)", "Ib": "Ib (B)", "IIa": "IIa (C)",
                                  "IIb": "IIb (D)", "hybrid": "hybrid"}
    assert set(plots.MODEL_STYLES) == set(dashpot.MODELS)
    colours = {style["color"] for style in plots.MODEL_STYLES.values()}
    assert len(colours) == len(dashpot.MODELS)
    theory = plots.restitution_figure(speeds=(10,), points=31)
    scene = plots.intervals_figure(*_scene())
    for fig in (theory, scene):
        for model, line in _model_lines(fig.axes[0]).items():
            assert line.get_color() == plots.MODEL_STYLES[model]["color"]
            assert line._unscaled_dash_pattern == _get_dash_pattern(
                plots.MODEL_STYLES[model]["linestyle"])
            assert line.get_label() == plots.MODEL_LABELS[model]


def test_restitution_curves_stop_where_capture_sets_in():
    """No drawn point is captured (recomputed with collide); gravity curves end at the onset."""
    speeds = (23, 15, 5)
    fig = plots.restitution_figure(speeds=speeds)
    assert len(fig.axes) == len(speeds)
    for ax, vtilde in zip(fig.axes, speeds):
        lines = _model_lines(ax)
        assert set(lines) == set(dashpot.MODELS)
        for model, line in lines.items():
            zeta, eps = (np.asarray(a, dtype=float) for a in line.get_data())
            drawn = np.isfinite(eps)
            result = dashpot.collide(model, zeta, np.full(zeta.shape, float(vtilde)))
            assert not result.captured[drawn].any(), f"{model} at ṽ={vtilde}: captured drawn"
            assert result.captured[~drawn].all(), f"{model} at ṽ={vtilde}: rebound not drawn"
            np.testing.assert_array_equal(eps[drawn], result.eps[drawn])
            if model in ("Ib", "IIb", "hybrid"):
                last = zeta[drawn].max()
                assert eps[drawn][np.argmax(zeta[drawn])] > 0.0
                # Below the onset, and within 1e-4 of it: the curve reaches the capture.
                assert dashpot.critical_velocity(model, last) < vtilde
                assert dashpot.critical_velocity(model, last + 1e-4) >= vtilde
                assert np.all(zeta[~drawn] > last)
        # Every curve from ζ = 0, where ε = 1 exactly.
        for line in lines.values():
            assert line.get_xdata()[0] == 0.0 and line.get_ydata()[0] == 1.0


def test_ib_and_hybrid_restitution_fall_toward_zero_at_capture():
    fig = plots.restitution_figure(speeds=(5,), points=101)
    lines = _model_lines(fig.axes[0])
    for model in ("Ib", "hybrid"):
        eps = np.asarray(lines[model].get_ydata(), dtype=float)
        assert np.nanmin(eps) < 2e-3  # the paper: ε → 0 at the critical speed
    iib = np.asarray(lines["IIb"].get_ydata(), dtype=float)
    assert np.nanmin(iib) > 0.1  # the paper: IIb terminates at a finite ε


def test_speed_curves_start_at_the_critical_speed():
    zetas = (0.05, 0.5)
    fig = plots.restitution_vs_speed_figure(zetas=zetas, vtilde_range=(0.5, 100.0), points=80)
    for ax, zeta in zip(fig.axes, zetas):
        assert ax.get_xscale() == "log"
        for model, line in _model_lines(ax).items():
            vtilde, eps = (np.asarray(a, dtype=float) for a in line.get_data())
            drawn = np.isfinite(eps)
            captured = dashpot.collide(model, np.full(vtilde.shape, zeta), vtilde).captured
            assert not captured[drawn].any() and captured[~drawn].all()
            if model in ("Ib", "IIb", "hybrid"):
                first = vtilde[drawn].min()
                critical = dashpot.critical_velocity(model, zeta)
                assert critical < first <= critical * (1 + 1e-4)


def test_contact_time_curves_are_finite_and_ia_leaves_the_top():
    fig = plots.contact_time_figure()
    ax = fig.axes[0]
    top = ax.get_ylim()[1]
    for model, line in _model_lines(ax).items():
        tau = np.asarray(line.get_ydata(), dtype=float)
        assert not np.isinf(tau).any()
        if model != "Ia":
            assert np.nanmax(tau) < top
    assert np.nanmax(_model_lines(ax)["Ia"].get_ydata()) > top  # diverges as ζ → 1


def test_critical_speed_ib_runs_off_the_top_without_inf():
    fig = plots.critical_speed_figure()
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    lines = _model_lines(ax)
    assert set(lines) == {"Ib", "IIb", "hybrid"}
    bottom, top = ax.get_ylim()
    for model, line in lines.items():
        zeta, vc = (np.asarray(a, dtype=float) for a in line.get_data())
        assert not np.isinf(vc).any()
        drawn = np.isfinite(vc)
        np.testing.assert_allclose(vc[drawn], dashpot.critical_velocity(model, zeta[drawn]))
        if model == "Ib":
            assert np.nanmax(vc) > top
        else:
            assert np.nanmax(vc) < top and np.nanmin(vc) >= bottom
    assert any("every" in text for text in _legend_texts(fig))  # the shaded Ib band
    # Drawing the log axis with NaN and 1e300 values: test_figure_has_labelled_axes_and_renders.


def test_detection_figure_decimates_600k_points():
    # Its speed is measured in benchmarks/bench_plots.py.
    time_s, envelope, impacts = _detection_inputs(600_000)
    fig = plots.detection_figure(time_s, envelope, impacts, sample_time=time_s,
                                 samples=envelope - 0.01, tail_count=8)
    _render(fig)
    overview, close = fig.axes
    drawn = [line for line in overview.get_lines() if line.get_label() == "envelope"][0]
    assert len(drawn.get_ydata()) <= 5000
    assert np.max(drawn.get_ydata()) == envelope.max()  # min/max decimation keeps the peaks
    lo, hi = close.get_xlim()
    assert lo <= impacts[-8] and hi >= impacts[-1] and lo > impacts[-9]


def test_detection_figure_with_few_or_no_impacts():
    time_s, envelope, impacts = _detection_inputs(5_000, rate=1000.0)
    for subset in (impacts[:2], impacts[:1]):
        fig = plots.detection_figure(time_s, envelope, subset, tail_count=8)
        lo, hi = fig.axes[1].get_xlim()
        assert lo < subset[0] and hi > subset[-1]
    _render(plots.detection_figure(time_s, envelope, impacts[:0]))
    with pytest.raises(ValueError, match="both"):
        plots.detection_figure(time_s, envelope, impacts, samples=envelope)


def test_detection_figure_marks_the_runs_of_a_recording_of_several_drops():
    rate = 2000.0
    time_s = np.arange(int(9.0 * rate)) / rate
    envelope = np.full(time_s.size, 0.01)
    drops = [0.3 + np.cumsum(0.4 * 0.8 ** np.arange(n)) for n in (14, 11)]
    drops[1] = drops[1] + 5.0
    impacts = np.concatenate(drops)
    runs = np.repeat([0, 1], [drops[0].size, drops[1].size])
    shuffled = np.random.default_rng(20501001).permutation(impacts.size)  # any row order
    fig = plots.detection_figure(time_s, envelope, impacts[shuffled], runs=runs[shuffled],
                                 tail_count=8)
    _render(fig)
    overview, close = fig.axes
    assert overview.get_title().endswith("25 detected impacts in 2 runs")
    between = [line for line in overview.collections if line.get_label() == "between runs (drops)"]
    assert len(between) == 1
    (segment,) = between[0].get_segments()
    assert drops[0][-1] < segment[0][0] < drops[1][0]
    labels = [text.get_text() for text in overview.texts]
    assert labels == ["run 0", "run 1"]
    # The close-up holds the last 8 impacts of run 1, numbered 4 to 11 within it.
    lo, hi = close.get_xlim()
    assert lo < drops[1][-8] and hi > drops[1][-1] and lo > drops[1][-9]
    assert [text.get_text() for text in close.texts] == [str(n) for n in range(4, 12)]
    assert close.get_title() == "Close-up: last 8 of 11 impacts of run 1"
    # A last run shorter than the close-up: only its own impacts.
    fig = plots.detection_figure(time_s, envelope, impacts[:17], runs=runs[:17])
    lo, hi = fig.axes[1].get_xlim()
    assert drops[0][-1] < lo < drops[1][0] and hi > drops[1][2]
    with pytest.raises(ValueError, match="run of each impact"):
        plots.detection_figure(time_s, envelope, impacts, runs=runs[:-1])


def test_intervals_figure_with_failed_model_and_nan_predictions():
    n, observed, sigma, predictions = _scene()
    predictions["IIa"] = 0.5 * 0.91 ** n  # given, but the fit failed: must not be drawn
    fig = plots.intervals_figure(n, observed, sigma, predictions, failed=("IIa", "Ia"))
    top, residual, in_time = fig.axes
    drawn = _model_lines(top)
    assert set(drawn) == {"Ib", "IIb", "hybrid"}
    assert len(drawn["Ib"].get_xdata()) == 15
    assert np.isnan(drawn["IIb"].get_ydata()).sum() == 4
    texts = _legend_texts(fig)
    assert any(t.startswith("IIa (C)") and "failed" in t for t in texts)
    assert any(t.startswith("Ia (A)") and "failed" in t for t in texts)
    assert "sigma" in residual.get_ylabel()
    np.testing.assert_allclose(_model_lines(residual)["hybrid"].get_ydata(), 0.0, atol=1e-9)
    # The same residuals in time units beside them: Ib's are 0, IIb's observed − predicted.
    assert "ms" in in_time.get_ylabel()
    iib = _model_lines(in_time)["IIb"].get_ydata()
    expected = 1e3 * (observed - np.where(n % 5 == 0, np.nan, 0.5 * 0.899 ** n))
    np.testing.assert_allclose(iib, expected, rtol=1e-12)
    # Without usable uncertainties the residuals are in time units only.
    fig = plots.intervals_figure(n, observed, None, predictions)
    assert len(fig.axes) == 2 and "ms" in fig.axes[1].get_ylabel()


def test_interval_residuals_take_the_unit_of_their_size():
    """Microsecond residuals are shown in µs, not as 0.00x ms; bounce numbers are integers."""
    n = np.arange(1, 9)
    observed = 0.3 * 0.95 ** n
    fig = plots.intervals_figure(n, observed, np.full(n.size, 2e-6),
                                 {"Ia": observed + 5e-6 * (-1.0) ** n})
    in_time = fig.axes[2]
    assert "µs" in in_time.get_ylabel()
    np.testing.assert_allclose(np.abs(_model_lines(in_time)["Ia"].get_ydata()), 5.0)
    for ax in fig.axes:
        ticks = [t for t in ax.get_xticks() if n.min() - 0.5 <= t <= n.max() + 0.5]
        assert ticks and all(float(t).is_integer() for t in ticks), ticks


def test_restitution_limits_follow_the_data_and_the_curves():
    """ε near 0.94 is not squeezed into [0, 1], nothing sits on an edge, and a capture drop
    inside the measured speed range widens the range to show it."""
    speed = np.linspace(0.2, 2.0, 12)
    eps = 0.94 + 0.004 * np.sin(7.0 * speed)
    flat = {"Ia": (np.linspace(0.0, 2.1, 50), np.full(50, 0.942))}
    ax = plots.restitution_speed_figure(speed, eps, None, np.full(12, 0.002), flat).axes[0]
    bottom, top = ax.get_ylim()
    assert 0.9 < bottom < eps.min() - 0.002 and eps.max() + 0.002 < top < 0.98
    left, right = ax.get_xlim()
    assert left == 0.0 and 2.0 < right < 2.2
    curve_speed = np.linspace(0.01, 2.1, 200)
    dropping = {"hybrid": (curve_speed, 0.94 - 0.6 * np.exp(-curve_speed / 0.05))}
    ax = plots.restitution_speed_figure(speed, eps, None, None, dropping).axes[0]
    shown = dropping["hybrid"][1][curve_speed <= ax.get_xlim()[1]]
    assert ax.get_ylim()[0] <= shown.min() < eps.min()


def test_restitution_speeds_all_fast_are_not_squeezed_against_zero():
    """A train of a few fast bounces (0.85-1.5 m/s, a phyphox or timestamp scene): the speed
    axis starts just below the slowest, not at 0, where the points filled the right 45 %."""
    speed = np.linspace(0.85, 1.5, 14)
    eps = 0.969 + 1e-4 * np.sin(5.0 * speed)
    flat = {"Ia": (speed, np.full(speed.size, 0.969))}
    left, right = plots.restitution_speed_figure(speed, eps, np.full(14, 0.01), None,
                                                 flat).axes[0].get_xlim()
    assert 0.7 < left < 0.85 - 0.01 and 1.5 + 0.01 < right < 1.65
    assert (speed.max() - speed.min()) / (right - left) > 0.8


def test_restitution_speed_curve_hides_captured_speeds():
    speed = np.linspace(0.1, 2.0, 20)
    eps = np.where(speed < 0.5, 0.0, 0.8)
    fig = plots.restitution_speed_figure([1.0], [0.8], None, None, {"hybrid": (speed, eps)})
    line = _model_lines(fig.axes[0])["hybrid"]
    assert np.all(np.isnan(np.asarray(line.get_ydata())[speed < 0.5]))
    assert "m/s" in fig.axes[0].get_xlabel()


def test_selection_figure_annotates_delta_aic():
    fig = plots.selection_figure(["Ib", "hybrid"], [0.3, 0.7], [1.7, 0.0])
    ax = fig.axes[0]
    assert len(ax.patches) == 2
    notes = [t.get_text() for t in ax.texts]
    assert any("1.7" in t for t in notes) and any("0.0" in t for t in notes)


def _small_figure():
    fig = Figure(figsize=(2.0, 1.5))
    ax = fig.add_subplot()
    ax.plot([0.0, 1.0], [1.0, 0.5])
    ax.set_xlabel("x (s)")
    ax.set_ylabel("y (m)")
    return fig


def test_save_figure_writes_png_and_pdf_atomically_and_deterministically(tmp_path):
    fig = _small_figure()
    paths = plots.save_figure(fig, tmp_path / "out" / "scene.v1")
    assert sorted(os.listdir(tmp_path / "out")) == ["scene.v1.pdf", "scene.v1.png"]
    first = [p.read_bytes() for p in paths]
    assert first[0].startswith(b"\x89PNG") and first[1].startswith(b"%PDF")
    plots.save_figure(fig, tmp_path / "out" / "scene.v1", overwrite=True)
    assert [p.read_bytes() for p in paths] == first  # no dates: reruns give the same bytes
    assert sorted(os.listdir(tmp_path / "out")) == ["scene.v1.pdf", "scene.v1.png"]


def test_failed_save_leaves_nothing_behind(tmp_path, monkeypatch):
    fig = _small_figure()
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    with pytest.raises(OSError):
        plots.save_figure(fig, blocker / "scene")  # the directory cannot be created
    assert sorted(os.listdir(tmp_path)) == ["file"]

    # Old results stay intact when writing the second format fails half way.
    target = tmp_path / "results"
    target.mkdir()
    (target / "scene.png").write_bytes(b"old png")
    original = fig.savefig

    def failing_savefig(handle, *, format, **kwargs):
        if format == "pdf":
            handle.write(b"%PDF-partial")
            raise RuntimeError("disk full")
        return original(handle, format=format, **kwargs)

    monkeypatch.setattr(fig, "savefig", failing_savefig)
    with pytest.raises(RuntimeError, match="disk full"):
        plots.save_figure(fig, target / "scene", overwrite=True)
    assert sorted(os.listdir(target)) == ["scene.png"]
    assert (target / "scene.png").read_bytes() == b"old png"


def test_restitution_figure_with_drag_corrected_points():
    """Corrected points beside the uncorrected ones: two labelled point sets (in the legend
    first, as the containers ``ax.containers`` hold them), each rung's and model's curve, and
    a y range that shows both sets with their error bars."""
    speed = np.linspace(0.5, 2.5, 10)
    apparent = 0.95 - 0.012 * speed  # what interval ratios show under drag
    corrected = {"speed": 0.97 * speed, "eps": np.full(10, 0.95),
                 "speed_uncertainty": np.full(10, 0.01), "eps_uncertainty": np.full(10, 0.004),
                 "label": "drag-corrected ($k_d$ = 0.125 1/m, noise fit constant+drag)"}
    grid = np.linspace(0.3, 2.6, 40)
    fig = plots.restitution_speed_figure(
        speed, apparent, None, np.full(10, 0.001), {"Ia": (grid, np.full(40, 0.93))},
        {"constant+drag": (grid, np.full(40, 0.95)), "linear": (grid, 0.95 - 0.012 * grid)},
        corrected=corrected, measured_label="interval ratios (no drag correction)")
    ax = fig.axes[0]
    labels = [container.get_label() for container in ax.containers]
    assert labels == ["interval ratios (no drag correction)", corrected["label"]]
    x, y = ax.containers[1].lines[0].get_data()
    np.testing.assert_array_equal(x, corrected["speed"])
    np.testing.assert_array_equal(y, corrected["eps"])
    assert ax.containers[1].has_xerr and ax.containers[1].has_yerr
    assert ax.containers[1].lines[0].get_marker() == "D"
    # The uncorrected points are open markers beside the corrected ones.
    assert ax.containers[0].lines[0].get_markerfacecolor() == "none"
    assert {line.get_gid() for line in ax.get_lines() if line.get_gid()} == {
        "Ia", "noise:constant+drag", "noise:linear"}
    assert _legend_texts(fig)[:2] == labels  # the k_d and its source named in full
    assert [text.get_text() for text in _legend(fig, "noise").get_texts()] == [
        "constant+drag", "linear"]
    assert "dash-dot" in _legend(fig, "noise").get_title().get_text()
    assert "Ia (A)" in [text.get_text() for text in _legend(fig, "models").get_texts()]
    bottom, top = ax.get_ylim()
    assert bottom < 0.95 - 0.012 * 2.5 - 0.001 and 0.95 + 0.004 < top < 0.97
    _render(fig)
    # Without corrected points the measured ones keep their old look and name.
    plain = plots.restitution_speed_figure(speed, apparent, None, None, {})
    assert [c.get_label() for c in plain.axes[0].containers] == ["measured"]
    with pytest.raises(ValueError, match="same length"):
        plots.restitution_speed_figure(speed, apparent, None, None, {},
                                       corrected={**corrected, "eps": [0.95]})


def test_restitution_figure_names_failed_fits_in_its_legend():
    """Every fitted model and rung is accounted for: a failed one has no curve, and says so."""
    grid = np.linspace(0.3, 2.6, 40)
    fig = plots.restitution_speed_figure(
        [1.0, 2.0], [0.9, 0.89], None, None, {"Ia": (grid, np.full(40, 0.9))},
        {"constant": (grid, np.full(40, 0.9))}, failed=("Ib",),
        failed_noise=("hunt-crossley",))
    ax = fig.axes[0]
    assert {line.get_gid() for line in ax.get_lines() if line.get_gid()} == {
        "Ia", "noise:constant"}
    assert "Ib (B): fit failed, not drawn" in _legend_texts(fig)
    assert "hunt-crossley: fit failed, not drawn" in [
        text.get_text() for text in _legend(fig, "noise").get_texts()]


@pytest.mark.parametrize("entries", [5, 17, 40])
def test_a_long_legend_goes_below_the_axes_and_leaves_them_their_width(entries):
    # 17 entries: the five contact models, their noise fits and seven noise models, beside
    # the data; beside the axes such a legend took half the figure's width.
    fig = Figure(figsize=(9.5, 7.0), layout="constrained")
    ax = fig.subplots()
    labels = ["interval ratios (no drag correction)"] + [
        f"noise: model {k}" for k in range(entries - 1)]
    handles = [ax.plot([0, 1], [k, k], label=label)[0] for k, label in enumerate(labels)]
    plots._figure_legend(fig, handles)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    figure_box = fig.bbox
    axes_box = ax.get_window_extent(renderer)
    legend_box = fig.legends[0].get_window_extent(renderer)
    # Nothing of the legend outside the figure, nor over the axes.
    assert figure_box.x0 - 1 <= legend_box.x0 and legend_box.x1 <= figure_box.x1 + 1
    assert figure_box.y0 - 1 <= legend_box.y0 and legend_box.y1 <= figure_box.y1 + 1
    assert not axes_box.overlaps(legend_box)
    if entries <= 8:
        assert legend_box.x0 >= axes_box.x1  # short: beside the axes
    else:
        assert legend_box.y1 <= axes_box.y0  # long: below them, in columns
        assert axes_box.width >= 0.8 * figure_box.width
        assert axes_box.height >= 0.4 * figure_box.height


def test_selection_figure_with_many_noise_fits_is_at_most_12_inches_wide():
    # The real recordings' noise panel: seven restitution laws, the drag rung and the five
    # contact models, with the list of effects tried. It was 22 in wide (3315 px), its text
    # tiny in the report.
    names = ["constant", "constant+drag", "linear", "quadratic", "power",
             "viscoelastic-hertz", "hunt-crossley", *dashpot.MODELS]
    weights = np.r_[0.0, 1.0, np.zeros(len(names) - 2)]
    delta = np.r_[43.6, 0.0, np.linspace(13.7, 116.1, len(names) - 2)]
    steps = [("drag", "constant+drag", "constant", 41.7, True, ""),
             ("speed term", "quadratic", "constant", 27.9, True, ""),
             ("contact duration", "IIa", "constant", 0.3, False, ""),
             ("gravity in contact", "Ib", "constant", 1.5, False, "")]
    fig = plots.selection_figure(dashpot.MODELS, [0.33, 0.06, 0.33, 0.23, 0.05],
                                 [0.0, 3.4, 0.0, 0.7, 3.6], criterion="QAIC",
                                 noise=(names, weights, delta, "AIC"), noise_steps=steps,
                                 noise_kept=[True] * 7 + [False] * 5)
    assert fig.get_size_inches()[0] <= 12.0
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    (legend,) = fig.legends
    legend_box = legend.get_window_extent(renderer)
    figure_box = fig.bbox
    assert figure_box.x0 - 1 <= legend_box.x0 and legend_box.x1 <= figure_box.x1 + 1
    assert figure_box.y0 - 1 <= legend_box.y0 and legend_box.y1 <= figure_box.y1 + 1
    for ax in fig.axes:
        # Neither over a panel nor beside it, taking its width: below the lowest one.
        assert not ax.get_window_extent(renderer).overlaps(legend_box)
        assert legend_box.y1 <= ax.get_tightbbox(renderer).y0 + 1
        assert ax.get_window_extent(renderer).width >= 0.8 * figure_box.width
    # The crowded panel's tick labels are tilted, not run into each other; the five
    # models' stay level.
    assert {tick.get_rotation() for tick in fig.axes[1].get_xticklabels()} == {30}
    assert {tick.get_rotation() for tick in fig.axes[0].get_xticklabels()} == {0}


def test_restitution_limits_hug_a_narrow_spread_of_eps():
    """ε between 0.9590 and 0.9594 (a synthetic scene's) fills the axes: padded by 5 % of its
    span, not by a fixed 5e-4 that left two thirds of the axes empty, and labelled without an
    offset."""
    speed = np.linspace(0.8, 2.0, 12)
    eps = 0.9590 + 0.0004 * np.linspace(0.0, 1.0, 12)
    flat = {"Ia": (np.linspace(0.7, 2.0, 50), np.full(50, 0.9592))}
    fig = plots.restitution_speed_figure(speed, eps, None, None, flat)
    ax = fig.axes[0]
    bottom, top = ax.get_ylim()
    assert bottom < eps.min() and eps.max() < top
    assert top - bottom <= 1.2 * (eps.max() - eps.min())
    _render(fig)
    assert ax.yaxis.get_offset_text().get_text() == ""


def test_restitution_limits_of_equal_values_are_not_empty():
    fig = plots.restitution_speed_figure([1.0, 2.0], [0.8, 0.8], None, None, {})
    bottom, top = fig.axes[0].get_ylim()
    assert bottom < 0.8 < top and top - bottom < 0.05


def test_coinciding_gravity_free_curves_both_show():
    """Ia and IIa often give the same constant ε (Ia was drawn, then hidden under IIa's
    dashes): both are dashed, with dashes as long as their gaps, IIa's in Ia's gaps."""
    speed = np.linspace(0.5, 2.0, 20)
    curves = {model: (speed, np.full(speed.size, 0.95)) for model in ("Ia", "IIa")}
    fig = plots.restitution_speed_figure(speed, np.full(speed.size, 0.95), None, None, curves)
    lines = _model_lines(fig.axes[0])
    (ia_offset, (ia_on, ia_off)), (iia_offset, (iia_on, iia_off)) = (
        lines[model]._unscaled_dash_pattern for model in ("Ia", "IIa"))
    assert ia_on == ia_off == iia_on == iia_off > 0
    assert (iia_offset - ia_offset) % (2 * ia_on) == pytest.approx(ia_on)
    assert lines["Ia"].get_linewidth() == lines["IIa"].get_linewidth()


def test_capture_onsets_on_the_axes_edge_are_whole_circles():
    """Ib's and the hybrid's ε fall to 0 at capture, on the lower edge of the ε axes: their
    onset circles are drawn whole, not clipped to their upper half."""
    fig = plots.restitution_vs_speed_figure(zetas=(0.2,), points=60)
    onsets = [line for line in fig.axes[0].get_lines()
              if str(line.get_gid()).endswith(" onset")]
    at_edge = [line for line in onsets
               if np.asarray(line.get_ydata(), float)[0] <= fig.axes[0].get_ylim()[0] + 1e-3]
    assert at_edge
    assert not any(line.get_clip_on() for line in onsets)


def test_restitution_figure_draws_each_models_predicted_interval_ratios():
    """Beside a model's ε(v), its own predicted T_{n+1}/T_n at the measured speeds: its
    markers, open, in its colour, in the order of speed, inside the y range; the two are told
    apart in the legend."""
    speed = np.array([1.4, 1.0, 0.6])
    ratio = np.array([0.9514, 0.9518, 0.9526])  # above ε(v): each interval holds a contact
    grid = np.linspace(0.5, 1.5, 20)
    fig = plots.restitution_speed_figure(speed, ratio + 1e-5, None, None,
                                         {"Ib": (grid, np.full(20, 0.95))},
                                         predicted_ratios={"Ib": (speed, ratio)})
    ax = fig.axes[0]
    line = next(line for line in ax.get_lines() if line.get_gid() == "ratio:Ib")
    np.testing.assert_array_equal(line.get_xdata(), speed[::-1])
    np.testing.assert_array_equal(line.get_ydata(), ratio[::-1])
    assert line.get_color() == plots.MODEL_STYLES["Ib"]["color"]
    assert line.get_marker() == plots.MODEL_STYLES["Ib"]["marker"]
    assert line.get_markerfacecolor() == "none"
    assert ax.get_ylim()[0] < 0.95 and ratio.max() < ax.get_ylim()[1]
    # One legend entry for both, its title telling them apart.
    legend = _legend(fig, "models")
    assert [text.get_text() for text in legend.get_texts()].count("Ib (B)") == 1
    title = legend.get_title().get_text()
    assert r"$\varepsilon(v)$ (line)" in title
    assert r"predicted $T_{n+1}/T_n$ (open markers)" in title
    with pytest.raises(ValueError, match="lengths differ"):
        plots.restitution_speed_figure(speed, ratio, None, None,
                                       {"Ib": (grid, np.full(20, 0.95))},
                                       predicted_ratios={"Ib": (speed, ratio[:2])})


def _full_restitution_scene():
    """Every layer of a scene's restitution figure: 40 interval ratios with their drag-corrected
    points, the five contact models' ε(v) and predicted ratios, and fits under the noise model
    of the seven laws and the five models (as a real recording's file holds them)."""
    rng = np.random.default_rng(20260518)
    speed = np.sort(rng.uniform(0.05, 3.7, 40))
    apparent = 0.93 - 0.02 * speed + rng.normal(0.0, 0.004, speed.size)
    corrected = {"speed": speed, "eps": apparent + 0.02 * speed,
                 "speed_uncertainty": np.full(speed.size, 0.01),
                 "eps_uncertainty": np.full(speed.size, 0.005),
                 "label": "drag-corrected ($k_d$ = 0.156 1/m, noise fit constant+drag)"}
    grid = np.linspace(0.04, 3.8, 120)
    curves = {model: (grid, 0.92 + 0.002 * k - 0.01 * np.exp(-grid / (0.1 + 0.1 * k)))
              for k, model in enumerate(dashpot.MODELS)}
    ratios = {model: (speed, np.interp(speed, *curves[model]) + 2e-4) for model in curves}
    laws = ["constant", "constant+drag", "linear", "quadratic", "power", "viscoelastic-hertz",
            "hunt-crossley"]
    noise = {law: (grid, 0.93 - 0.003 * k * grid) for k, law in enumerate(laws)}
    noise.update({model: (grid, curve + 0.001) for model, (_, curve) in curves.items()})
    fig = plots.restitution_speed_figure(
        speed, apparent, np.full(speed.size, 0.01), np.full(speed.size, 0.004), curves, noise,
        corrected=corrected, measured_label="interval ratios (no drag correction)",
        predicted_ratios=ratios)
    return fig, corrected["label"], laws


def test_full_restitution_legend_names_each_model_once_beside_its_layers():
    """Five models with their predicted ratios and noise fits, seven laws and two sets of
    points (27 drawn layers): one entry per model whose handle holds its curve and its
    ratios' open markers, both in its colour, one per law, one for the models under the noise
    model; no model named twice; the k_d of the corrected points named."""
    fig, drag_label, laws = _full_restitution_scene()
    ax = fig.axes[0]
    layers = len([line for line in ax.get_lines() if line.get_gid()]) + len(ax.containers)
    assert layers == 2 + 5 + 5 + 7 + 5
    texts = _legend_texts(fig)
    assert len(texts) <= 15 < layers
    for model in dashpot.MODELS:
        label = plots.MODEL_LABELS[model]
        assert sum(label in text for text in texts) == 1, (label, texts)
    models = _legend(fig, "models")
    assert [" ".join(text.get_text().split()) for text in models.get_texts()] == [
        "interval ratios (no drag correction)", drag_label,
        *(plots.MODEL_LABELS[model] for model in dashpot.MODELS)]
    noise = _legend(fig, "noise")
    assert [text.get_text() for text in noise.get_texts()][:len(laws)] == laws
    assert len(noise.get_texts()) == len(laws) + 1
    legend_lines = models.findobj(Line2D)
    for model in dashpot.MODELS:
        style = plots.MODEL_STYLES[model]
        lines = {line.get_gid(): line for line in ax.get_lines()}
        curve, ratio = lines[model], lines[f"ratio:{model}"]
        # The markers are open: their edge is what shows.
        assert curve.get_color() == ratio.get_markeredgecolor() == style["color"]
        assert ratio.get_marker() == style["marker"] and ratio.get_markerfacecolor() == "none"
        assert lines[f"noise:{model}"].get_color() == style["color"]
        # In the legend: the model's curve and its open markers, in the one colour.
        drawn = [line for line in legend_lines if line.get_color() == style["color"]]
        assert any(line.get_linestyle() == curve.get_linestyle() for line in drawn), model
        assert any(line.get_marker() == style["marker"] and line.get_markerfacecolor() == "none"
                   for line in drawn), model


def test_full_restitution_legends_cover_neither_the_points_nor_the_axes():
    """Drawn, the two legends lie inside the figure, outside the axes and away from the
    points with their error bars; the axes keep at least 60 % of the figure's width and
    height."""
    fig, _, _ = _full_restitution_scene()
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    ax = fig.axes[0]
    # The points and the caps of their error bars (a LineCollection of bars has no extent).
    points = Bbox.union([artist.get_window_extent(renderer)
                         for container in ax.containers for artist in container.get_children()
                         if isinstance(artist, Line2D)])
    axes_box = ax.get_window_extent(renderer)
    figure_box = fig.bbox
    assert len(fig.legends) == 2
    for legend in fig.legends:
        box = legend.get_window_extent(renderer)
        assert not box.overlaps(points), legend.get_gid()
        assert not box.overlaps(axes_box), legend.get_gid()
        assert figure_box.x0 - 1 <= box.x0 and box.x1 <= figure_box.x1 + 1
        assert figure_box.y0 - 1 <= box.y0 and box.y1 <= figure_box.y1 + 1
    assert _legend(fig, "models").get_window_extent(renderer).x0 >= axes_box.x1
    assert _legend(fig, "noise").get_window_extent(renderer).y1 <= axes_box.y0
    assert axes_box.width >= 0.6 * figure_box.width
    assert axes_box.height >= 0.6 * figure_box.height
