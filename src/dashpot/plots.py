"""Figures: the contact models' theory curves and one scene's analysis, data in, Figure out.

Every function is pure: it takes plain numbers and arrays and returns a new
:class:`matplotlib.figure.Figure`, created directly (never through pyplot), so it needs no
display, keeps no global state and can run in several threads at once. :func:`save_figure`
writes a figure as PNG and PDF atomically.

Theory figures (dimensionless, section 3 of the paper [1]_):

- :func:`contact_time_figure` — ω0τ against ζ (the paper's figure "time"),
- :func:`restitution_figure` — ε against ζ at a few ṽ (figures "epsilon", "epsilon2",
  "epsilon3"), each curve ending where capture sets in,
- :func:`critical_speed_figure` — ṽc against ζ (figure "critical"),
- :func:`restitution_vs_speed_figure` — ε against ṽ at a few ζ (not in the paper).

Scene figures (SI units): :func:`detection_figure`, :func:`intervals_figure`,
:func:`restitution_speed_figure`, :func:`selection_figure`.

Each model has one colour, marker and line style in every figure (:data:`MODEL_STYLES`) and is
named as in the paper with its table letter (:data:`MODEL_LABELS`). Gravity-free models (Ia, IIa)
are drawn dashed, models with gravity solid.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface",
   sections 3-4 and its figures.
"""

from __future__ import annotations

import os
import re
import textwrap
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from ._validation import check_positive
from .atomic import atomic_path, refuse_existing
from .physics import MODELS, collide, critical_velocity
from .physics.models import GRAVITY_MODELS

__all__ = ["MODEL_LABELS", "MODEL_STYLES", "contact_time_figure", "critical_speed_figure",
           "detection_closeup", "detection_figure", "intervals_figure", "restitution_figure",
           "name_scene", "restitution_speed_figure", "restitution_vs_speed_figure",
           "save_figure", "selection_figure"]

MODEL_LABELS = {"Ia": "Ia (A)", "Ib": "Ib (B)", "IIa": "IIa (C)", "IIb": "IIb (D)",
                "hybrid": "hybrid"}
"""Legend name of each model: the paper's name with its table letter in brackets."""

# Okabe-Ito colours (distinguishable with the common colour-vision deficiencies); type I models
# in blues, type II in green/purple, the hybrid in vermillion. Dashed = no gravity in contact.
# The two dashed models often coincide (both have a constant ε, the same where the fits agree):
# their dashes are as long as their gaps and IIa's fall in Ia's gaps, so that where the curves
# lie on each other they alternate blue and green instead of IIa's hiding Ia's.
_DASH = 4.0  # points at linewidth 1
MODEL_STYLES = {
    "Ia": {"color": "#0072B2", "marker": "o", "linestyle": (0.0, (_DASH, _DASH))},
    "Ib": {"color": "#56B4E9", "marker": "s", "linestyle": "-"},
    "IIa": {"color": "#009E73", "marker": "^", "linestyle": (_DASH, (_DASH, _DASH))},
    "IIb": {"color": "#CC79A7", "marker": "D", "linestyle": "-"},
    "hybrid": {"color": "#D55E00", "marker": "v", "linestyle": "-"},
}
"""Colour, marker and line style of each model, shared by all figures."""

_FALLBACK_STYLE = {"color": "0.5", "marker": "x", "linestyle": ":"}
_DATA_COLOR = "0.1"  # measured points: near black, no model uses it
_UNCORRECTED_COLOR = "0.45"  # measured points beside their drag-corrected ones
_CORRECTED_COLOR = "#C0392B"  # drag-corrected points: a red no model or law uses

ZETA_LABEL = r"damping ratio $\zeta = \beta/\omega_0$ (dimensionless)"
EPS_LABEL = r"restitution $\varepsilon$ (dimensionless)"
TAU_LABEL = r"contact time $\omega_0\tau$ (dimensionless)"
VTILDE_LABEL = r"impact speed $\tilde v = v_0\,\omega_0/g$ (dimensionless)"
VC_LABEL = r"critical speed $\tilde v_c = v_c\,\omega_0/g$ (dimensionless)"

PNG_DPI = 150
# No dates: rerunning gives the same bytes. (PNG has no date unless asked for.)
_METADATA = {"png": {}, "pdf": {"CreationDate": None}}

_REFINE_ROUNDS = 3  # bracket refinements of a capture onset, each by a factor 32
_ONSET_POINTS = 24  # extra points crowding toward an onset (ε vanishes like a square root)


def _style(model):
    return MODEL_STYLES.get(model, _FALLBACK_STYLE)


def _label(model):
    return MODEL_LABELS.get(model, str(model))


# Laws of the restitution ladder fitted under the noise model: colours no model uses.
NOISE_LAW_COLORS = {"constant": "#000000", "linear": "#E69F00", "quadratic": "#8C564B",
                    "power": "#9467BD", "viscoelastic-hertz": "#17BECF",
                    "hunt-crossley": "#BCBD22", "constant+drag": "#A6761D",
                    "constant+friction": "#666666"}
"""Colour of each restitution law's ε(v) and bar where a scene has fits under the noise model
(a dashpot model fitted under the noise model keeps its own colour)."""


def _noise_color(name):
    return NOISE_LAW_COLORS.get(name, _style(name)["color"])


def _noise_label(name):
    return f"noise: {_label(name)}"


def _ordered(models):
    """Models in the paper's order, unknown names after them in their given order."""
    models = list(models)
    return [m for m in MODELS if m in models] + [m for m in models if m not in MODELS]


def _model_line(ax, model, x, y, *, markers=False, **kwargs):
    """Plot one model's curve in its style; the Line2D's gid is the model name."""
    style = _style(model)
    return ax.plot(x, y, color=style["color"], linestyle=style["linestyle"],
                   marker=style["marker"] if markers else None, label=_label(model),
                   gid=model, **kwargs)[0]


def _grid(name, upper, points, lower=0.0, log=False):
    upper = float(check_positive(name, upper))
    points = int(points)
    if points < 2:
        raise ValueError(f"points must be >= 2; got {points}")
    if log:
        return np.geomspace(lower, upper, points)
    return np.linspace(lower, upper, points)


# --- capture-aware curves -------------------------------------------------------------------

def _curve_without_capture(evaluate, grid):
    """A model quantity on `grid` with NaN where captured, the grid refined toward each onset.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(x) -> (value, captured)`` on an array of the grid variable.
    grid : ndarray
        Increasing grid.

    Returns
    -------
    x, value : ndarray
        The grid with points added inside each cell where capture switches on or off, crowding
        geometrically toward the onset (located to 32⁻³ of a cell), and the value there, NaN
        where captured. A NaN therefore separates separate rebound stretches, and no captured
        point is ever drawn.
    """
    value, captured = evaluate(grid)
    extra = []
    for i in np.flatnonzero(captured[1:] != captured[:-1]):
        free, held = (grid[i], grid[i + 1]) if not captured[i] else (grid[i + 1], grid[i])
        start = free
        for _ in range(_REFINE_ROUNDS):
            trial = free + (held - free) * np.linspace(0.0, 1.0, 34)[1:-1]
            hit = evaluate(trial)[1]
            if not hit.any():
                free = trial[-1]
                continue
            k = int(np.argmax(hit))  # first captured point going from `free` to `held`
            held = trial[k]
            if k > 0:
                free = trial[k - 1]
        extra.append(free + (start - free) * np.geomspace(1.0, 1e-4, _ONSET_POINTS))
        extra.append(np.array([free]))
    if extra:
        x = np.unique(np.concatenate([grid, *extra]))
        value, captured = evaluate(x)
    else:
        x = grid
    return x, np.where(captured, np.nan, value)


def _eps_against_zeta(model, vtilde):
    def evaluate(zeta):
        result = collide(model, zeta, np.full(zeta.shape, float(vtilde)))
        return result.eps, result.captured
    return evaluate


def _contact_time_against_zeta(model, vtilde):
    def evaluate(zeta):
        result = collide(model, zeta, np.full(zeta.shape, float(vtilde)))
        return result.contact_time, result.captured
    return evaluate


def _eps_against_speed(model, zeta):
    def evaluate(vtilde):
        result = collide(model, np.full(vtilde.shape, float(zeta)), vtilde)
        return result.eps, result.captured
    return evaluate


def _mark_end(ax, model, x, y, *, clip=True):
    """Open circle where a curve ends because capture sets in.

    ``clip=False`` for ε figures, whose axes hold every onset: the onsets of Ib and the hybrid
    lie at ε = 0, on the lower edge, where a clipped circle showed only its upper half. (The
    contact-time figure keeps clipping: Ia's onset lies far above its axes.) The unclipped
    circle is left out of the layout, as a clipped one is.
    """
    finite = np.flatnonzero(np.isfinite(y))
    if finite.size and finite[-1] < y.size - 1:
        ax.plot(x[finite[-1]], y[finite[-1]], marker="o", markersize=5, markerfacecolor="white",
                color=_style(model)["color"], linestyle="none", gid=f"{model} onset",
                label="_nolegend_", zorder=3, clip_on=clip)[0].set_in_layout(clip)
        return True
    return False


_ONSET_PROXY_LABEL = "capture sets in (curve ends)"


def _onset_proxy():
    return Line2D([], [], marker="o", markersize=5, markerfacecolor="white", color="0.3",
                  linestyle="none", label=_ONSET_PROXY_LABEL)


_LEGEND_BESIDE_AT_MOST = 8  # entries; a longer legend goes below the axes, in columns
_LEGEND_LINE_CHARACTERS = 16  # characters of a small-font legend per inch of figure width
_LEGEND_ROW_INCHES = 0.24  # height of one row of a small-font legend


def _legend_columns(labels, characters):
    """Most columns (at most 4) in which `labels`, filled column by column as matplotlib
    does, span at most `characters` (each entry takes its text and about 6 more for the
    handle and the gap)."""
    for columns in range(min(4, len(labels)), 1, -1):
        rows = -(-len(labels) // columns)
        width = sum(max(len(label) for label in labels[k:k + rows]) + 6
                    for k in range(0, len(labels), rows))
        if width <= characters:
            return columns
    return 1


def _figure_legend(fig, handles):
    """One legend for the whole figure, outside the axes (never over the data): beside them,
    or, where it is long (beside, it would take the axes' width), below them in columns, the
    figure made taller by its rows."""
    if len(handles) <= _LEGEND_BESIDE_AT_MOST:
        fig.legend(handles=handles, loc="outside right upper", frameon=False)
        return
    width, height = fig.get_size_inches()
    columns = _legend_columns([handle.get_label() for handle in handles],
                              _LEGEND_LINE_CHARACTERS * width)
    fig.set_size_inches(width, height + _LEGEND_ROW_INCHES * -(-len(handles) // columns))
    fig.legend(handles=handles, loc="outside lower center", ncols=columns, frameon=False,
               fontsize="small")


# --- theory figures -------------------------------------------------------------------------

def contact_time_figure(vtilde=23, zeta_max=1.5, points=301):
    """Dimensionless contact time ω0τ against damping ratio ζ for the five models.

    Recomputes the paper's figure "time" (which omits Ib as indistinguishable from the hybrid;
    all five are drawn here).

    Parameters
    ----------
    vtilde : float, default 23
        Dimensionless impact speed ṽ = v0·ω0/g (> 0).
    zeta_max : float, default 1.5
        Largest damping ratio ζ = β/ω0 shown (dimensionless, > 0).
    points : int, default 301
        Grid points in ζ (more are added near each capture onset).

    Returns
    -------
    matplotlib.figure.Figure
        One axes: ω0τ (dimensionless) against ζ. Ia, Ib and the hybrid give the duration of
        nonzero compression, IIa and IIb of nonzero force. Curves end where capture sets in
        (open circle). Ia's ω0τ = π/√(1 − ζ²) diverges as ζ → 1; the y range is set by the
        other models and Ia's curve leaves the top.
    """
    vtilde = float(check_positive("vtilde", vtilde))
    zeta = _grid("zeta_max", zeta_max, points)
    fig = Figure(figsize=(8.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    handles, curves, ended = [], {}, False
    for model in MODELS:
        x, tau = _curve_without_capture(_contact_time_against_zeta(model, vtilde), zeta)
        handles.append(_model_line(ax, model, x, tau))
        ended |= _mark_end(ax, model, x, tau)
        curves[model] = (x, tau)
    # Ia's π/√(1 − ζ²) diverges at ζ = 1: the other models set the range.
    bounded = [np.nanmax(t) for m, (_, t) in curves.items() if m != "Ia" and np.isfinite(t).any()]
    top = 1.1 * max(bounded + [np.pi])
    ax.set_ylim(0.0, top)
    ax.set_xlim(0.0, zeta[-1])
    ia_zeta, ia_tau = curves["Ia"]
    above = np.flatnonzero(ia_tau > top)
    if above.size:
        exit_zeta = ia_zeta[above[0]]
        ax.annotate(r"Ia (A): $\omega_0\tau = \pi/\sqrt{1 - \zeta^2} \to \infty$ as $\zeta \to 1$",
                    xy=(exit_zeta, 0.99 * top), xytext=(exit_zeta - 0.04 * zeta[-1], 0.93 * top),
                    fontsize="small", color=_style("Ia")["color"], ha="right", va="top",
                    arrowprops={"arrowstyle": "->", "color": _style("Ia")["color"]})
    ax.set_xlabel(ZETA_LABEL)
    ax.set_ylabel(TAU_LABEL)
    ax.set_title(rf"Contact time at $\tilde v = {vtilde:g}$")
    if ended:
        handles.append(_onset_proxy())
    _figure_legend(fig, handles)
    return fig


def restitution_figure(speeds=(23, 15, 5), zeta_max=1.5, points=301):
    """Restitution ε against damping ratio ζ, one panel per impact speed ṽ, five models.

    Recomputes the paper's figures "epsilon", "epsilon2" and "epsilon3" (ṽ = 23, 15, 5).

    Parameters
    ----------
    speeds : sequence of float, default (23, 15, 5)
        Dimensionless impact speeds ṽ = v0·ω0/g (> 0), one panel each, in this order.
    zeta_max : float, default 1.5
        Largest damping ratio ζ = β/ω0 shown (dimensionless, > 0).
    points : int, default 301
        Grid points in ζ (more are added near each capture onset).

    Returns
    -------
    matplotlib.figure.Figure
        One axes per speed: ε (dimensionless) against ζ. Each curve ends where the model
        captures the ball (open circle): captured points are not drawn, so there are no ε = 0
        lines. Ib and the hybrid end with ε → 0 like a square root, IIb at a finite ε; Ia's
        ε = exp(−πζ/√(1 − ζ²)) vanishes as ζ → 1 while it still rebounds.
    """
    speeds = np.atleast_1d(check_positive("speeds", speeds)).ravel()
    if speeds.size == 0:
        raise ValueError("speeds must hold at least one impact speed")
    zeta = _grid("zeta_max", zeta_max, points)
    fig = Figure(figsize=(4.0 * speeds.size + 2.2, 4.3), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, speeds.size, sharey=True, squeeze=False)[0])
    handles, ended = {}, False
    for index, (ax, vtilde) in enumerate(zip(axes, speeds)):
        for model in MODELS:
            x, eps = _curve_without_capture(_eps_against_zeta(model, vtilde), zeta)
            handles[model] = _model_line(ax, model, x, eps)
            ended |= _mark_end(ax, model, x, eps, clip=False)
        ax.set_xlim(0.0, zeta[-1])
        ax.set_ylim(0.0, 1.02)
        ax.set_xlabel(ZETA_LABEL)
        # sharey hides the tick labels of the inner panels, not their axis labels.
        ax.set_ylabel(EPS_LABEL if index == 0 else r"$\varepsilon$")
        ax.set_title(rf"$\tilde v = {vtilde:g}$")
        ax.grid(alpha=0.3)
    fig.suptitle("Coefficient of restitution against damping ratio")
    legend = list(handles.values()) + ([_onset_proxy()] if ended else [])
    _figure_legend(fig, legend)
    return fig


def critical_speed_figure(zeta_max=1.5, points=301):
    """Critical impact speed ṽc (log scale) against damping ratio ζ for the gravity models.

    Recomputes the paper's figure "critical". Below ṽc the ball is captured.

    Parameters
    ----------
    zeta_max : float, default 1.5
        Largest damping ratio ζ = β/ω0 shown (dimensionless, > 0).
    points : int, default 301
        Grid points in ζ.

    Returns
    -------
    matplotlib.figure.Figure
        One axes: ṽc = vc·ω0/g (dimensionless, log scale) against ζ for Ib, IIb and the hybrid.
        Ib's ṽc grows like exp(πζ/√(1 − ζ²)) and diverges as ζ → 1: its curve runs off the top
        of the axes, and where ṽc is infinite (Ib captures at every speed) the band is shaded.
        ṽc = 0 (ζ = 0) cannot be shown on a log axis and is left out. The gravity-free models
        have no critical speed (IIa never captures; Ia captures at every speed for ζ >= 1).
    """
    zeta = _grid("zeta_max", zeta_max, points)
    fig = Figure(figsize=(8.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    ax.set_yscale("log")
    handles, bounded, lowest = [], [], []
    never = None
    for model in GRAVITY_MODELS:
        vc = critical_velocity(model, zeta)
        shown = np.where(np.isfinite(vc) & (vc > 0.0), vc, np.nan)
        handles.append(_model_line(ax, model, zeta, shown))
        if np.isfinite(shown).any():
            lowest.append(np.nanmin(shown))
        if np.all(np.isfinite(vc)):
            bounded.append(np.nanmax(shown) if np.isfinite(shown).any() else 1.0)
        if model == "Ib" and np.isinf(vc).any():
            never = zeta[np.argmax(np.isinf(vc))]
    top = 10.0 ** np.ceil(np.log10(3.0 * max(bounded + [10.0])))
    bottom = 10.0 ** np.floor(np.log10(min(lowest + [1.0])))
    ax.set_ylim(bottom, top)
    ax.set_xlim(0.0, zeta[-1])
    if never is not None:
        handles.append(ax.axvspan(never, zeta[-1], color=_style("Ib")["color"], alpha=0.15,
                                  linewidth=0, label=r"Ib (B): captured at every $\tilde v$"))
    ax.set_xlabel(ZETA_LABEL)
    ax.set_ylabel(VC_LABEL)
    ax.set_title("Critical impact speed (captured below it)")
    ax.grid(alpha=0.3)
    _figure_legend(fig, handles)
    return fig


def restitution_vs_speed_figure(zetas=(0.05, 0.2, 0.5), vtilde_range=(0.5, 1e3), points=400):
    """Restitution ε against impact speed ṽ (log scale), one panel per damping ratio ζ.

    Not in the paper: it shows the speed dependence that gravity gives Ib, IIb and the hybrid,
    each tending to its gravity-free twin (Ia, IIa) at high speed, and falling to capture at ṽc.

    Parameters
    ----------
    zetas : sequence of float, default (0.05, 0.2, 0.5)
        Damping ratios ζ = β/ω0 (dimensionless, >= 0), one panel each, in this order.
    vtilde_range : (float, float), default (0.5, 1000)
        Smallest and largest dimensionless impact speed ṽ = v0·ω0/g, 0 < low < high.
    points : int, default 400
        Grid points in ṽ, logarithmically spaced (more are added near each capture onset).

    Returns
    -------
    matplotlib.figure.Figure
        One axes per ζ: ε (dimensionless) against ṽ (log scale). Captured speeds are not drawn;
        curves start at the critical speed (open circle).
    """
    zetas = np.atleast_1d(np.asarray(zetas, dtype=float)).ravel()
    if zetas.size == 0 or not np.all(np.isfinite(zetas)) or np.any(zetas < 0.0):
        raise ValueError(f"zetas must be finite damping ratios >= 0; got {zetas!r}")
    low, high = (float(v) for v in check_positive("vtilde_range", vtilde_range))
    if not low < high:
        raise ValueError(f"vtilde_range must be (low, high) with low < high; got {vtilde_range!r}")
    vtilde = _grid("vtilde_range", high, points, lower=low, log=True)
    fig = Figure(figsize=(4.0 * zetas.size + 2.2, 4.3), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, zetas.size, sharey=True, squeeze=False)[0])
    handles, started = {}, False
    for index, (ax, zeta) in enumerate(zip(axes, zetas)):
        ax.set_xscale("log")
        for model in MODELS:
            x, eps = _curve_without_capture(_eps_against_speed(model, zeta), vtilde)
            handles[model] = _model_line(ax, model, x, eps)
            # Reversed: the curve starts (not ends) where capture stops.
            started |= _mark_end(ax, model, x[::-1], eps[::-1], clip=False)
        ax.set_xlim(low, high)
        ax.set_ylim(0.0, 1.02)
        ax.set_xlabel(VTILDE_LABEL)
        ax.set_ylabel(EPS_LABEL if index == 0 else r"$\varepsilon$")
        ax.set_title(rf"$\zeta = {zeta:g}$")
        ax.grid(alpha=0.3, which="both")
    fig.suptitle("Coefficient of restitution against impact speed")
    legend = list(handles.values())
    if started:
        legend.append(Line2D([], [], marker="o", markersize=5, markerfacecolor="white",
                             color="0.3", linestyle="none",
                             label=r"critical speed $\tilde v_c$ (captured below)"))
    _figure_legend(fig, legend)
    return fig


# --- scene figures --------------------------------------------------------------------------

def _minmax_decimate(x, y, columns):
    """At most ~2·`columns` points drawing the same picture as (x, y) at that width.

    Splits the samples into `columns` runs of equal count and keeps each run's minimum and
    maximum, in time order, so peaks survive. NaN (a gap) is kept where a run holds one.
    """
    n = x.size
    if n <= 2 * columns:
        return x, y
    per = -(-n // columns)  # ceil: the leftover after the full runs is shorter than one run
    columns = n // per
    used = per * columns
    runs = y[:used].reshape(columns, per)
    low, high = np.argmin(runs, axis=1), np.argmax(runs, axis=1)
    base = np.arange(columns) * per
    index = np.stack([base + np.minimum(low, high), base + np.maximum(low, high)], axis=1).ravel()
    if used < n:
        rest = y[used:]
        index = np.concatenate([index, used + np.unique([np.argmin(rest), np.argmax(rest)])])
    return x[index], y[index]


def _window(x, y, start, stop, columns):
    i, j = np.searchsorted(x, [start, stop])
    i, j = max(i - 1, 0), min(j + 1, x.size)
    return _minmax_decimate(x[i:j], y[i:j], columns)


def _as_series(name, value):
    array = np.asarray(value, dtype=float).ravel()
    if array.size == 0:
        raise ValueError(f"{name} must not be empty")
    return array


def _last_run(impact_times, runs=None):
    """The impact times (s) of the last run (the run of the latest impact), in time order; all
    of them where `runs` (the run of each impact) is not given."""
    impacts = np.asarray(impact_times, dtype=float).ravel()
    if runs is not None and impacts.size:
        runs = np.asarray(runs).ravel()
        if runs.shape != impacts.shape:
            raise ValueError(f"runs must give the run of each impact; got {runs.size} runs "
                             f"for {impacts.size} impacts")
        impacts = impacts[runs == runs[np.argmax(impacts)]]
    return np.sort(impacts)


def detection_closeup(impact_times, start_time, end_time, *, tail_count=8, runs=None):
    """Span (s) of the close-up of :func:`detection_figure`: the last `tail_count` impacts (of
    the last run, where `runs` gives the run of each impact).

    Half the longest interval among them is added on either side (2 % of the recording for a
    single impact), within the recording from `start_time` to `end_time` (s) where that leaves
    a span; the whole recording without impacts. A caller can read just this span of a long
    recording at full resolution.

    Returns
    -------
    start, stop : float
    """
    tail = _last_run(impact_times, runs)[-int(tail_count):]
    if not tail.size:
        return start_time, end_time
    if tail.size >= 2:
        pad = 0.5 * np.max(np.diff(tail))
    else:
        pad = 0.02 * max(end_time - start_time, 1e-9)
    start, stop = max(tail[0] - pad, start_time), min(tail[-1] + pad, end_time)
    if not stop > start:
        start, stop = tail[0] - pad, tail[-1] + pad
    return start, stop


def detection_figure(time, envelope, impact_times, *, sample_time=None, samples=None,
                     tail_count=8, runs=None):
    """The recording's envelope with the detected impacts, and a close-up of the last bounces.

    Parameters
    ----------
    time : array_like
        Time of each envelope point in s, increasing.
    envelope : array_like
        Signal envelope in full-scale units (1 = the recorder's full scale), same length as
        `time`. Any length: it is reduced to the minimum and maximum per pixel column for
        drawing, so 10⁶ points draw in a fraction of a second.
    impact_times : array_like
        Detected impact times in s.
    sample_time, samples : array_like, optional
        Raw recording (times in s, samples in full-scale units), drawn behind the envelope in
        the close-up. Give both or neither. Only the close-up's span is drawn
        (:func:`detection_closeup`): the samples of that span suffice, whole or as the extremes
        of each pixel column (:func:`dashpot.envelope.channel_extremes`).
    tail_count : int, default 8
        Number of final impacts the close-up shows.
    runs : array_like, optional
        The run of each impact (a recording of several drops of the ball: the ``run`` column
        of the impact table). With more than one, each run is labelled over its impacts and
        a dotted line is drawn between runs, and the close-up shows the last run's impacts,
        numbered within it.

    Returns
    -------
    matplotlib.figure.Figure
        Top: the whole envelope against time (s), impacts marked by ticks above it and the
        close-up window shaded. Bottom: the close-up of the last `tail_count` impacts, numbered
        from 1 in time order, with the raw samples if given.
    """
    time, envelope = _as_series("time", time), _as_series("envelope", envelope)
    if time.shape != envelope.shape:
        raise ValueError(f"time and envelope must have the same length; got {time.size} and "
                         f"{envelope.size}")
    order = np.argsort(np.asarray(impact_times, dtype=float).ravel(), kind="stable")
    impacts = np.asarray(impact_times, dtype=float).ravel()[order]
    last_run = _last_run(impact_times, runs)
    run_labels = np.zeros(0) if runs is None else np.asarray(runs).ravel()[order]
    if (sample_time is None) != (samples is None):
        raise ValueError("give both sample_time and samples, or neither")
    tail_count = int(tail_count)
    if tail_count < 1:
        raise ValueError(f"tail_count must be >= 1; got {tail_count}")

    fig = Figure(figsize=(10.0, 6.5), layout="constrained")
    overview, close = fig.subplots(2, 1)
    ink = "0.25"
    mark = "#D55E00"

    x, y = _minmax_decimate(time, envelope, 2000)
    overview.plot(x, y, color=ink, linewidth=0.6, label="envelope")
    marks = overview.get_xaxis_transform()  # x in data, y in axes fraction
    overview.vlines(impacts, 0.0, 0.94, transform=marks, color=mark, linewidth=0.5, alpha=0.35)
    overview.plot(impacts, np.full(impacts.shape, 0.97), transform=marks, linestyle="none",
                  marker="v", markersize=4, color=mark,
                  label=f"detected impacts ({impacts.size})")
    # Runs in time order: where the run changes between two impacts, a dotted line midway.
    changes = np.flatnonzero(run_labels[1:] != run_labels[:-1]) + 1
    if changes.size:
        overview.vlines(0.5 * (impacts[changes - 1] + impacts[changes]), 0.0, 1.0,
                        transform=marks, color=ink, linewidth=0.8, linestyle=":",
                        label="between runs (drops)")
        for first_of_run in np.concatenate(([0], changes)):
            overview.annotate(f"run {run_labels[first_of_run]}",
                              xy=(impacts[first_of_run], 0.88), xycoords=marks,
                              xytext=(3, 0), textcoords="offset points", fontsize="x-small",
                              color=ink, ha="left", va="center",
                              bbox={"boxstyle": "square,pad=0.1", "facecolor": "white",
                                    "edgecolor": "none", "alpha": 0.8})

    tail = last_run[-tail_count:]
    start, stop = detection_closeup(impacts, time[0], time[-1], tail_count=tail_count,
                                    runs=None if runs is None else run_labels)
    if tail.size:
        overview.axvspan(start, stop, color="0.5", alpha=0.15, linewidth=0,
                         label="close-up below")
    overview.set_xlim(time[0], time[-1])
    overview.set_xlabel("time $t$ (s)")
    overview.set_ylabel("envelope (full scale)")
    overview.set_title(f"Recording with {impacts.size} detected impacts"
                       + (f" in {changes.size + 1} runs" if changes.size else ""))
    overview.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small",
                    frameon=False)
    # Leave room above the envelope for the impact ticks and the legend.
    ymin, ymax = overview.get_ylim()
    overview.set_ylim(ymin, ymin + 1.35 * (ymax - ymin))

    if samples is not None:
        st, sv = _as_series("sample_time", sample_time), _as_series("samples", samples)
        if st.shape != sv.shape:
            raise ValueError(f"sample_time and samples must have the same length; got "
                             f"{st.size} and {sv.size}")
        sx, sy = _window(st, sv, start, stop, 2000)
        close.plot(sx, sy, color="0.7", linewidth=0.5, label="raw samples")
    cx, cy = _window(time, envelope, start, stop, 2000)
    close.plot(cx, cy, color=ink, linewidth=0.9, label="envelope")
    first = last_run.size - tail.size
    for number, t in enumerate(tail, start=first + 1):
        close.axvline(t, color=mark, linewidth=0.9, linestyle="--")
        close.annotate(f"{number}", xy=(t, 1.0), xycoords=("data", "axes fraction"),
                       xytext=(2, -2), textcoords="offset points", fontsize="x-small",
                       color=mark, ha="left", va="top")
    if tail.size:
        close.plot([], [], color=mark, linewidth=0.9, linestyle="--",
                   label="detected impact (number)")
    close.set_xlim(start, stop)
    close.set_xlabel("time $t$ (s)")
    close.set_ylabel("signal (full scale)")
    close.set_title(f"Close-up: last {tail.size} of {last_run.size} impacts"
                    + (f" of run {run_labels[-1]}" if changes.size else ""))
    close.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small", frameon=False)
    ymin, ymax = close.get_ylim()
    close.set_ylim(ymin, ymin + 1.3 * (ymax - ymin))
    return fig


def intervals_figure(bounce_index, observed, observed_uncertainty, predictions, *, failed=()):
    """Bounce intervals T_n, observed and predicted by each fitted model, with residuals.

    Parameters
    ----------
    bounce_index : array_like
        Bounce number n of each interval (dimensionless).
    observed : array_like
        Observed intervals T_n in s (impact n to impact n + 1).
    observed_uncertainty : array_like or None
        1σ uncertainty of each T_n in s. If it is None or not finite and positive everywhere,
        residuals are shown in time units only.
    predictions : dict of str to array_like
        Model name -> predicted intervals in s, aligned with `observed` from its first entry.
        May be shorter (a model that captures the ball early predicts fewer bounces) or hold
        NaN; entries beyond `observed` are ignored.
    failed : collection of str, default ()
        Models whose fit failed: listed in the legend as failed, not drawn (even if they also
        appear in `predictions`).

    Returns
    -------
    matplotlib.figure.Figure
        Top: T_n (s) against n, observed with error bars, each model's prediction as a line.
        Below: residual observed − predicted in units of σ (dimensionless, ±1 band shaded)
        where every σ is usable, and always in time units (s, ms or µs, whichever suits the
        largest residual; σ drawn as error bars about 0). Bounce numbers are integer ticks.
    """
    n = _as_series("bounce_index", bounce_index)
    observed = np.asarray(observed, dtype=float).ravel()
    if observed.shape != n.shape:
        raise ValueError(f"observed must have one interval per bounce index; got "
                         f"{observed.size} for {n.size}")
    sigma = None
    if observed_uncertainty is not None:
        sigma = np.asarray(observed_uncertainty, dtype=float).ravel()
        if sigma.shape != n.shape:
            raise ValueError(f"observed_uncertainty must match observed; got {sigma.size} "
                             f"for {n.size}")
    in_sigma = sigma is not None and bool(np.all(np.isfinite(sigma) & (sigma > 0.0)))
    failed = set(failed)

    # Residuals in σ alone hide their size (4,000σ may be 70 ms or 70 µs): where they are
    # in σ, a third panel gives them in time units too.
    panels = 3 if in_sigma else 2
    fig = Figure(figsize=(9.5, 7.0 if panels == 2 else 8.5), layout="constrained")
    top, *residual_axes = fig.subplots(panels, 1, gridspec_kw={
        "height_ratios": (2.0,) + (1.0,) * (panels - 1)})
    in_time = residual_axes[-1]
    handles = [top.errorbar(n, observed, yerr=sigma, fmt="o", markersize=3.5, color=_DATA_COLOR,
                            elinewidth=1.0, capsize=2, label="observed", zorder=3)]
    residuals = {}
    for model in _ordered(set(predictions) | failed):
        if model in failed:
            style = _style(model)
            handles.append(Line2D([], [], color=style["color"], marker=style["marker"],
                                  linestyle="none", markerfacecolor="none", alpha=0.6,
                                  label=f"{_label(model)}: fit failed, not drawn"))
            continue
        predicted = np.asarray(predictions[model], dtype=float).ravel()[:n.size]
        handles.append(_model_line(top, model, n[:predicted.size], predicted, markers=True,
                                   markersize=3, linewidth=1.0, alpha=0.85))
        residuals[model] = observed[:predicted.size] - predicted
    scale, unit = _time_unit([*residuals.values(), sigma if sigma is not None else []])
    if in_sigma:
        residual_axes[0].axhspan(-1.0, 1.0, color="0.5", alpha=0.15, linewidth=0)
        residual_axes[0].set_ylabel(r"residual $(T_n - T_n^\mathrm{model})/\sigma_n$"
                                    "\n(dimensionless)")
    if sigma is not None:
        in_time.errorbar(n, np.zeros(n.shape), yerr=scale * sigma, fmt="none", color="0.6",
                         elinewidth=1.0, capsize=2)
    in_time.set_ylabel(rf"residual $T_n - T_n^\mathrm{{model}}$ ({unit})")
    for model, residual in residuals.items():
        m = residual.size
        if in_sigma:
            _model_line(residual_axes[0], model, n[:m], residual / sigma[:m], markers=True,
                        markersize=3, linewidth=0.8, alpha=0.85)
        _model_line(in_time, model, n[:m], scale * residual, markers=True, markersize=3,
                    linewidth=0.8, alpha=0.85)
    for ax in (top, *residual_axes):
        ax.set_xlabel("bounce number $n$")
        ax.set_xlim(n.min() - 0.5, n.max() + 0.5)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.grid(alpha=0.3)
    for ax in residual_axes:
        ax.axhline(0.0, color="0.3", linewidth=0.8)
    top.set_ylabel("interval $T_n$ (s)")
    top.set_title("Bounce intervals: observed and predicted")
    _figure_legend(fig, handles)
    return fig


def restitution_speed_figure(impact_speed, restitution, speed_uncertainty,
                             restitution_uncertainty, curves, noise_curves=None, *,
                             corrected=None, measured_label=None, failed=(),
                             failed_noise=(), predicted_ratios=None):
    """Measured restitution against impact speed, with each fitted model's ε(v).

    Parameters
    ----------
    impact_speed : array_like
        Impact speed of each measured bounce in m/s.
    restitution : array_like
        Measured coefficient of restitution ε of each bounce (dimensionless).
    speed_uncertainty, restitution_uncertainty : array_like or None
        1σ uncertainties of the speeds (m/s) and of ε (dimensionless); None for no error bar.
    curves : dict of str to (array_like, array_like)
        Model name -> (impact speed in m/s, ε). Points with ε <= 0 (the model captures the
        ball there) are not drawn.
    noise_curves : dict of str to (array_like, array_like), optional
        Law or model name -> (impact speed in m/s, ε) of each fit under the noise model, drawn
        dash-dotted (the Line2D's label is "noise: <name>", its gid "noise:<name>"): a law in
        its own colour, a contact model in that model's.
    corrected : dict, optional
        Drag-corrected points drawn beside the measured ones (filled diamonds): ``speed``
        (impact speeds in m/s), ``eps``, ``speed_uncertainty`` and ``eps_uncertainty`` (1σ,
        or None) and ``label`` (the legend's text, saying which k_d corrected them; wrapped
        in the legend).
    measured_label : str, optional
        Legend text of the measured points; default "measured", or with `corrected`
        "uncorrected (interval ratios)", drawn as open circles.
    failed, failed_noise : collection of str, default ()
        Models, and laws or models under the noise model, whose fit failed: listed in the
        legend as failed, without a curve.
    predicted_ratios : dict of str to (array_like, array_like), optional
        Model name -> (impact speed in m/s, T_{n+1}/T_n): where the points are interval
        ratios, each model's own predicted ratios at the measured speeds (what its fit
        compared with the data; :func:`dashpot.figures.predicted_interval_ratios`). Drawn
        as the model's open markers on a thin dotted line of its colour (the Line2D's label is
        "<model>: predicted T(n+1)/T(n)", its gid "ratio:<model>"; that model's curve is then
        labelled "<model>: ε(v)"), and in the legend beside the curve in the model's handle.

    Returns
    -------
    matplotlib.figure.Figure
        One axes: ε (dimensionless) against impact speed (m/s). The points are
        :class:`~matplotlib.container.ErrorbarContainer` objects of ``ax.containers``
        labelled as in the legend. Two figure legends, neither over the axes: beside them
        (gid "models") the points and one entry per contact model, its handle showing its
        curve and its predicted ratios side by side (the title says which is which); below
        them (gid "noise", where there are fits under the noise model) one entry per law,
        one for the contact models, each in its own colour, and each failed fit, under a
        title saying that dash-dot means the noise model. The figure is as much wider as
        the legend beside the axes is wide, and as much taller as the one below is high.

    Notes
    -----
    An interval T_n holds a contact as well as the flight, so T_{n+1}/T_n is not ε: where the
    contact lasts a millisecond in flights of a few hundred, the ratios of a model's own train
    lie 1e-4 or more off its ε(v). Only its predicted ratios can be read against the points.
    """
    speed = np.asarray(impact_speed, dtype=float).ravel()
    eps = np.asarray(restitution, dtype=float).ravel()
    if speed.shape != eps.shape:
        raise ValueError(f"impact_speed and restitution must have the same length; got "
                         f"{speed.size} and {eps.size}")
    xerr = None if speed_uncertainty is None else np.asarray(speed_uncertainty, float).ravel()
    yerr = None if restitution_uncertainty is None else np.asarray(restitution_uncertainty,
                                                                   float).ravel()
    fig = Figure(figsize=(_RESTITUTION_AXES_WIDTH, 5.0), layout="constrained")
    ax = fig.add_subplot()
    # Each model's layers (its ε(v), its predicted ratios) share one legend entry.
    model_layers = {}
    predicted_ratios = predicted_ratios or {}
    for model in _ordered(curves):
        curve_speed, shown = _sorted_curve(model, curves[model])
        model_layers[model] = [_model_line(ax, model, curve_speed, shown, linewidth=1.5)]
        if model in predicted_ratios:
            model_layers[model][0].set_label(rf"{_label(model)}: $\varepsilon(v)$")
            model_layers[model].append(_predicted_ratio_line(ax, model, predicted_ratios[model]))
    noise_lines = {}
    for name, curve in (noise_curves or {}).items():
        curve_speed, shown = _sorted_curve(name, curve)
        noise_lines[name] = ax.plot(curve_speed, shown, color=_noise_color(name),
                                    linestyle=_NOISE_LINESTYLE, linewidth=1.2,
                                    label=_noise_label(name), gid=f"noise:{name}")[0]
    points = [(speed, eps, xerr, yerr)]
    if corrected is None:
        data = [ax.errorbar(speed, eps, xerr=xerr, yerr=yerr, fmt="o", markersize=3.5,
                            color=_DATA_COLOR, elinewidth=0.8, capsize=2,
                            label=measured_label or "measured", zorder=3)]
    else:
        # Beside the corrected points the uncorrected ones step back: open and grey.
        data = [ax.errorbar(speed, eps, xerr=xerr, yerr=yerr, fmt="o", markersize=3.5,
                            color=_UNCORRECTED_COLOR, markerfacecolor="none", elinewidth=0.7,
                            capsize=2, label=measured_label or "uncorrected (interval ratios)",
                            zorder=3)]
        fixed = [np.asarray(corrected[key], dtype=float).ravel() for key in ("speed", "eps")]
        errors = [None if corrected.get(key) is None else
                  np.asarray(corrected[key], dtype=float).ravel()
                  for key in ("speed_uncertainty", "eps_uncertainty")]
        if fixed[0].shape != fixed[1].shape:
            raise ValueError(f"corrected speed and eps must have the same length; got "
                             f"{fixed[0].size} and {fixed[1].size}")
        data.append(ax.errorbar(*fixed, xerr=errors[0], yerr=errors[1], fmt="D",
                                markersize=3.5, color=_CORRECTED_COLOR, elinewidth=0.8,
                                capsize=2, label=corrected.get("label", "drag-corrected"),
                                zorder=4))
        points.append((*fixed, *errors))
    drawn = [line for layers in model_layers.values() for line in layers]
    drawn += list(noise_lines.values())
    ax.set_xlim(*_speed_limits(np.concatenate([p[0] for p in points]), _joined(points, 2)))
    ax.set_ylim(*_restitution_limits(ax.get_xlim(), np.concatenate([p[1] for p in points]),
                                     _joined(points, 3), drawn))
    # ε that spans a few 1e-4 would otherwise be labelled as an offset ("+9.59e-1") plus
    # ticks in units of its last digits.
    ax.ticklabel_format(axis="y", useOffset=False)
    ax.set_xlabel("impact speed $v$ (m/s)")
    ax.set_ylabel(EPS_LABEL)
    ax.set_title("Restitution against impact speed")
    ax.grid(alpha=0.3)
    _restitution_legends(fig, data, model_layers, _ordered(failed), noise_lines,
                         list(failed_noise))
    return fig


_RESTITUTION_AXES_WIDTH = 8.0  # inches of figure beside the legend: the axes and their labels
_NOISE_LINESTYLE = "-."  # every fit under the noise model, law or contact model
_BESIDE_CHARACTERS = 30  # a label beside the axes is wrapped at this many characters


def _failed_entry(color, label):
    return Line2D([], [], color=color, linestyle="none", marker="x", alpha=0.6,
                  label=f"{label}: fit failed, not drawn")


def _restitution_legends(fig, data, model_layers, failed, noise_lines, failed_noise):
    """The restitution figure's legends, neither over the axes.

    Beside the axes: the points, then one entry per contact model whose handle shows each of
    its layers side by side (its ε(v), then its predicted ratios where drawn), the title
    saying which is which. Below the axes, where the scene has fits under the noise model:
    one entry per restitution law, one for the contact models (each dash-dotted in its own
    colour, already named beside the axes), each failed fit, the title saying that dash-dot
    means the noise model. Labels beside the axes are wrapped, so that the axes keep most of
    the figure's width.
    """
    from matplotlib.legend_handler import HandlerTuple

    def wrapped(label):
        # A value stays on one line with its name and unit ("$k_d$ = 0.156 1/m").
        label = label.replace(" = ", "\u00a0=\u00a0")
        label = re.sub(r"(?<=\d) (?=1/m\b|m/s\b)", "\u00a0", label)
        return textwrap.fill(label, _BESIDE_CHARACTERS, break_long_words=False)

    layered = any(len(layers) > 1 for layers in model_layers.values())
    handles = list(data) + [tuple(layers) if len(layers) > 1 else layers[0]
                            for layers in model_layers.values()]
    labels = [wrapped(handle.get_label()) for handle in data]
    labels += [_label(model) for model in model_layers]
    for model in failed:
        handles.append(_failed_entry(_style(model)["color"], _label(model)))
        labels.append(wrapped(handles[-1].get_label()))
    beside = fig.legend(handles, labels, loc="outside right upper", frameon=False,
                        fontsize="small", title_fontsize="small", alignment="left",
                        handlelength=4.0 if layered else 2.0,
                        handler_map={tuple: HandlerTuple(ndivide=None, pad=0.4)},
                        title=(r"contact models: $\varepsilon(v)$ (line)," "\n"
                               r"predicted $T_{n+1}/T_n$ (open markers)" if layered else None))
    beside.set_gid("models")
    # The figure grows by the legend's width: the axes keep theirs.
    width, height = fig.get_size_inches()
    fig.set_size_inches(width + beside.get_window_extent().width / fig.dpi, height)
    if not noise_lines and not failed_noise:
        return beside, None
    laws = {name: line for name, line in noise_lines.items() if name not in MODEL_STYLES}
    models = [line for name, line in noise_lines.items() if name in MODEL_STYLES]
    handles, labels = list(laws.values()), list(laws)
    if models:
        handles.append(tuple(models))
        labels.append("contact model" + ("s, each" if len(models) > 1 else "") +
                      " in its colour")
    for name in failed_noise:
        handles.append(_failed_entry(_noise_color(name), _label(name)))
        labels.append(handles[-1].get_label())
    width, height = fig.get_size_inches()
    columns = _legend_columns(labels, _LEGEND_LINE_CHARACTERS * width)
    fig.set_size_inches(width, height + _LEGEND_ROW_INCHES * (-(-len(labels) // columns) + 1))
    below = fig.legend(handles, labels, loc="outside lower center", ncols=columns,
                       frameon=False, fontsize="small", title_fontsize="small",
                       handler_map={tuple: HandlerTuple(ndivide=None, pad=0.2)},
                       handlelength=max(2.0, 1.0 * len(models)),
                       title="fitted under the noise model (dash-dot)")
    below.set_gid("noise")
    return beside, below


def _predicted_ratio_line(ax, model, ratios):
    """A model's predicted interval ratios at the measured speeds: its markers, open, on a thin
    dotted line of its colour, in the order of speed."""
    speed, ratio = (np.asarray(a, dtype=float).ravel() for a in ratios)
    if speed.shape != ratio.shape:
        raise ValueError(f"predicted ratios of {model!r}: speed and ratio lengths differ "
                         f"({speed.size} and {ratio.size})")
    order = np.argsort(speed, kind="stable")
    style = _style(model)
    return ax.plot(speed[order], ratio[order], color=style["color"], linestyle=":",
                   linewidth=0.9, marker=style["marker"], markersize=6,
                   markerfacecolor="none", markeredgewidth=0.9,
                   label=f"{_label(model)}: predicted $T_{{n+1}}/T_n$", gid=f"ratio:{model}",
                   zorder=2)[0]


def _joined(points, index):
    """The error bars `index` of every set of points joined (0 where a set has none), or None
    where no set has any."""
    if all(p[index] is None for p in points):
        return None
    return np.concatenate([np.zeros(p[0].size) if p[index] is None else p[index]
                           for p in points])


def _time_unit(values):
    """(factor, unit) to show times of the size of the largest finite |value| (values in s)."""
    finite = np.concatenate([np.abs(np.asarray(v, dtype=float)).ravel() for v in values]
                            or [np.zeros(0)])
    finite = finite[np.isfinite(finite)]
    largest = float(finite.max()) if finite.size else 0.0
    if largest >= 1.0:
        return 1.0, "s"
    if largest >= 1e-3 or largest == 0.0:
        return 1e3, "ms"
    return 1e6, "µs"


def _speed_limits(speed, speed_error):
    """x range of the restitution figure: from 0 to past the fastest measured bounce, or,
    where every bounce is faster than half the fastest (a phyphox or timestamp train of a
    few fast bounces: 0.85-1.5 m/s), from just below the slowest: from 0 the points and
    curves would fill less than half the axes."""
    error = 0.0 if speed_error is None else np.nan_to_num(speed_error)
    upper, lower = speed + error, speed - error
    upper, lower = upper[np.isfinite(upper)], lower[np.isfinite(lower)]
    if not upper.size or upper.max() <= 0:
        return 0.0, 1.0
    high = 1.05 * float(upper.max())
    low = float(lower.min()) if lower.size else 0.0
    if low <= 0.5 * float(upper.max()):
        return 0.0, high
    return low - 0.05 * (high - low), high


def _restitution_limits(speed_range, eps, eps_error, lines):
    """y range of the restitution figure: the measured points with their error bars and every
    curve inside the speed range (a capture drop there included), padded by 5 % of their span
    (ε near 0.959 that varies by 0.0005 fills the axes, not a third of them), never beyond the
    physical range [0, 1] by more than the data themselves go."""
    error = 0.0 if eps_error is None else np.nan_to_num(eps_error)
    values = [eps - error, eps + error]
    for line in lines:
        x, y = (np.asarray(a, dtype=float) for a in line.get_data())
        values.append(y[(x >= speed_range[0]) & (x <= speed_range[1])])
    values = np.concatenate([np.ravel(v) for v in values])
    values = values[np.isfinite(values)]
    if not values.size:
        return 0.0, 1.02
    low, high = float(values.min()), float(values.max())
    # A single value (or all equal) has no span: then 1 % of the value, at least 1e-3.
    pad = 0.05 * (high - low) if high > low else max(0.01 * abs(high), 1e-3)
    return max(low - pad, min(low, 0.0)), high + pad


def _sorted_curve(name, curve):
    """A curve's speeds in increasing order and its ε there, NaN where the ball is captured."""
    curve_speed, curve_eps = (np.asarray(a, dtype=float).ravel() for a in curve)
    if curve_speed.shape != curve_eps.shape:
        raise ValueError(f"curve of {name!r}: speed and eps lengths differ "
                         f"({curve_speed.size} and {curve_eps.size})")
    order = np.argsort(curve_speed, kind="stable")
    curve_speed, curve_eps = curve_speed[order], curve_eps[order]
    return curve_speed, np.where(curve_eps > 0.0, curve_eps, np.nan)


def selection_figure(models, akaike_weights, delta_aic, *, criterion="AIC", noise=None,
                     noise_steps=None, noise_kept=None):
    """Akaike weight of each model as a bar, with its ΔAIC (or ΔQAIC) written above it.

    Parameters
    ----------
    models : sequence of str
        Model names, in the order to show.
    akaike_weights : array_like
        Akaike weight w_i = exp(−Δ_i/2)/Σ_j exp(−Δ_j/2) of each model (dimensionless,
        0 to 1). NaN for a failed fit: no bar, "fit failed" written instead.
    delta_aic : array_like
        Δ_i, the criterion of each model less the smallest (dimensionless).
    criterion : {"AIC", "QAIC"}, default "AIC"
        What Δ and the weights were computed from: "QAIC" where the models share a misfit
        and ΔAIC was divided by the best model's reduced χ² (:mod:`dashpot.select`).
    noise : tuple, optional
        ``(names, akaike_weights, delta, criterion)`` of the fits under the noise model (laws
        and models, as the first three parameters): drawn as a second panel below.
    noise_steps : sequence of tuple, optional
        The effects the nested steps of the noise selection tried
        (:func:`dashpot.figures.noise_effect_steps`), each ``(effect, fit, simpler, bic_gain,
        required, carrier)``: the effect's best fit, the simpler rung it was compared with, its
        ΔBIC against that rung (dimensionless), whether the data required the effect, and the
        kept fit carrying it from a simpler rung ("" where none). Listed beside the noise panel
        under a heading naming the required effects (an empty sequence: none was tried).
    noise_kept : sequence of bool, optional
        Per fit under the noise model, whether the nested steps kept it (:mod:`dashpot.
        noise_selection`): the bars of fits not kept are hatched.

    Returns
    -------
    matplotlib.figure.Figure
        One axes: Akaike weight (dimensionless) per model; a second one below it per fit
        under the noise model where `noise` is given, and where `noise_steps` is given the
        effects the data required in a figure legend (gid "noise-effects") below that. At
        most 12 in wide, tick labels tilted where they would run into each other.
    """
    models = [str(m) for m in models]
    weights, delta = _weights_and_delta(models, akaike_weights, delta_aic)
    panels = [(models, weights, delta, criterion)]
    if noise is not None:
        names, noise_weights, noise_delta, noise_criterion = noise
        names = [str(n) for n in names]
        panels.append((names, *_weights_and_delta(names, noise_weights, noise_delta),
                       noise_criterion))
    bars = max(len(panel[0]) for panel in panels)
    # At most _SELECTION_MAX_WIDTH wide (a report scales a wider figure's text down to
    # nothing): many bars get narrower, and the list of effects goes below the noise panel.
    fig = Figure(figsize=(min(1.3 * max(bars, 3) + 2.0, _SELECTION_MAX_WIDTH),
                          4.5 * len(panels)), layout="constrained")
    axes = fig.subplots(len(panels), 1, squeeze=False)[:, 0]
    model_colors = [_style(m)["color"] for m in models]
    _weight_bars(axes[0], models, weights, delta, criterion, model_colors,
                 [_label(m) for m in models])
    axes[0].set_xlabel("contact model")
    axes[0].set_title("Model selection: Akaike weights" + (
        "\non the misfit's scale (QAIC): no model describes the data" if criterion == "QAIC"
        else ""))
    if noise is not None:
        names, noise_weights, noise_delta, noise_criterion = panels[1]
        _weight_bars(axes[1], names, noise_weights, noise_delta, noise_criterion,
                     [_noise_color(n) for n in names], [_label(n) for n in names],
                     notes=None if noise_kept is None else
                     ["kept" if keep else "not kept" for keep in np.asarray(noise_kept, bool)])
        axes[1].set_xlabel("restitution law or contact model, fitted under the noise model")
        axes[1].set_title("Under the noise model (bounce-to-bounce scatter, timing jitter)" + (
            "\non the misfit's scale (QAIC)" if noise_criterion == "QAIC" else ""))
        if noise_kept is not None:
            _hatch_not_kept(axes[1], names, noise_kept)
        if noise_steps is not None:
            _effect_legend(fig, noise_steps, hatched=noise_kept is not None)
    for ax in axes:
        _tilt_crowded_labels(ax)
    return fig


_SELECTION_MAX_WIDTH = 12.0  # inches
_NOT_KEPT_HATCH = "//"
_TICK_CHARACTER_INCHES = 0.085  # width of a character of a tick label (10 pt), about
_SMALL_LINE_INCHES = 0.17  # height of a line of small-font legend text, with its spacing


def _tilt_crowded_labels(ax):
    """Tilt the tick labels of a bar panel where the longest is wider than a bar's slot
    (a noise panel of a dozen laws and models: "viscoelastic-hertz" ran into its
    neighbours)."""
    labels = [tick.get_text() for tick in ax.get_xticklabels()]
    if not labels:
        return
    figure_width = ax.get_figure().get_size_inches()[0]
    # The axes take about the figure's width less 1.2 in for the y label and ticks.
    slot = (figure_width - 1.2) / len(labels)
    if max(map(len, labels)) * _TICK_CHARACTER_INCHES > slot:
        ax.tick_params(axis="x", labelrotation=30)
        for tick in ax.get_xticklabels():
            tick.set_horizontalalignment("right")
            tick.set_rotation_mode("anchor")


def _hatch_not_kept(ax, names, kept):
    """Hatch the bars of the fits the nested steps did not keep (the bars' notes say it too:
    a bar of weight 0 shows no hatching)."""
    kept = np.asarray(kept, dtype=bool).ravel()
    if kept.size != len(names):
        raise ValueError(f"noise_kept must have one entry per fit under the noise model; got "
                         f"{kept.size} for {len(names)} fits")
    for bar, name, keep in zip(ax.patches, names, kept):
        bar.set_gid(f"noise:{name}")
        if not keep:
            bar.set_hatch(_NOT_KEPT_HATCH)


def _effect_legend(fig, steps, *, hatched):
    """Legend below the noise panel (the figure's lowest), in columns: which effects the
    data required (the heading), then each effect tried with its best fit's ΔBIC against
    its simpler rung. The figure is made taller by the legend's height, so that the panels
    keep theirs."""
    from matplotlib.patches import Patch

    from .noise_selection import NESTED_STEP_BIC

    steps = [tuple(step) for step in steps]
    required = [step[0] for step in steps if step[4]]
    heading = (textwrap.fill("the data required " + ", ".join(required), 42) if required
               else "the data required no effect beyond\na constant restitution")
    heading += (f"\n(an effect is kept where its fit's BIC is\n≥ {NESTED_STEP_BIC:g} below "
                "that of its simpler rung)")
    handles, labels = [], []
    for effect, fit, simpler, gain, needed, carrier in steps:
        word = "required" if needed else "not required"
        if needed and carrier:
            word += f", carried by {carrier}"
        handles.append(Patch(facecolor=_noise_color(fit), edgecolor="0.2",
                             hatch=None if needed else _NOT_KEPT_HATCH))
        labels.append(f"{effect}: {word}\n{fit}: ΔBIC = {gain:.1f} against {simpler}")
    if hatched:
        handles.append(Patch(facecolor="white", edgecolor="0.2", hatch=_NOT_KEPT_HATCH))
        labels.append("hatched bar: fit not kept")
    width, height = fig.get_size_inches()
    lines = [max(label.split("\n"), key=len) for label in labels]
    columns = _legend_columns(lines, _LEGEND_LINE_CHARACTERS * width)
    rows = -(-len(labels) // columns)
    text_lines = heading.count("\n") + 1 + 2 * rows  # every entry takes two lines
    fig.set_size_inches(width, height + _SMALL_LINE_INCHES * text_lines + 0.2)
    legend = fig.legend(handles, labels, title=heading, loc="outside lower center",
                        ncols=columns, fontsize="small", title_fontsize="small",
                        alignment="left", frameon=False)
    legend.set_gid("noise-effects")
    return legend


def _weights_and_delta(models, akaike_weights, delta_aic):
    weights = np.asarray(akaike_weights, dtype=float).ravel()
    delta = np.asarray(delta_aic, dtype=float).ravel()
    if not (weights.size == delta.size == len(models)):
        raise ValueError(f"models, akaike_weights and delta_aic must have the same length; got "
                         f"{len(models)}, {weights.size} and {delta.size}")
    return weights, delta


def _weight_bars(ax, models, weights, delta, criterion, colors, labels, notes=None):
    """One bar per model (its Akaike weight) with Δ and w written above it, and the bar's
    entry of `notes` below them where given."""
    position = np.arange(len(models))
    ok = np.isfinite(weights)
    heights = np.where(ok, weights, 0.0)
    bars = ax.bar(position, heights, width=0.65, color=colors, edgecolor="0.2", linewidth=0.6)
    for index, (bar, weight, d, good) in enumerate(zip(bars, weights, delta, ok)):
        if not good:
            text = "fit failed"
        elif np.isfinite(d):
            text = rf"$\Delta${criterion} = {d:.1f}" f"\nw = {weight:.2f}"
        else:
            text = rf"$\Delta${criterion} = ∞" f"\nw = {weight:.2f}"
        if notes is not None and good:
            text += f"\n{notes[index]}"
        ax.annotate(text, xy=(bar.get_x() + bar.get_width() / 2, bar.get_height()),
                    xytext=(0, 3), textcoords="offset points", ha="center", va="bottom",
                    fontsize="small")
    ax.set_xticks(position, labels)
    ax.set_ylim(0.0, 1.15 if notes is None else 1.25)  # room for the notes' third line
    ax.set_xlim(-0.6, len(models) - 0.4)
    ax.set_ylabel("Akaike weight (dimensionless)")
    ax.grid(axis="y", alpha=0.3)


def name_scene(figure, scene):
    """Name the scene a figure shows in a title above all its axes (the figure's suptitle).

    A figure copied out of the report, or opened from ``results/plots/<scene>/``, then still
    says which recording it is of.

    Parameters
    ----------
    figure : matplotlib.figure.Figure
        A scene figure.
    scene : str or None
        The scene's name; None or "" leaves the figure as it is.

    Returns
    -------
    matplotlib.figure.Figure
        `figure`, with the suptitle "scene <name>".
    """
    if scene:
        figure.suptitle(f"scene {scene}", fontweight="bold")
    return figure


# --- output ---------------------------------------------------------------------------------

def save_figure(figure, stem, *, overwrite=False):
    """Write `figure` as ``stem.png`` (150 dpi) and ``stem.pdf``, each atomically.

    Both files are first written to hidden temporary names in the target directory and only
    then renamed into place, so an error leaves neither a partial file nor a temporary one
    (and existing files untouched). The parent directory is created. No dates are written,
    so saving the same figure again gives the same bytes.

    Parameters
    ----------
    figure : matplotlib.figure.Figure
        Figure to save.
    stem : str or os.PathLike
        Output path without extension (``results/scene`` -> ``results/scene.png`` and
        ``results/scene.pdf``; any dots in the name are kept).
    overwrite : bool, default False
        Replace the PNG and the PDF if they exist. Without it, if either exists, neither is
        written.

    Returns
    -------
    tuple of pathlib.Path
        Paths of the PNG and the PDF.

    Raises
    ------
    InputError
        The PNG or the PDF exists and `overwrite` is false ("<path>: exists; pass
        overwrite=True to replace it"); both are left as they were.
    """
    stem = Path(stem)
    if not stem.name:
        raise ValueError(f"stem must name a file; got {os.fspath(stem)!r}")
    targets = {fmt: stem.with_name(f"{stem.name}.{fmt}") for fmt in ("png", "pdf")}
    refuse_existing(*targets.values(), overwrite=overwrite)  # before drawing either
    # Both renames happen only after both files are complete.
    with atomic_path(targets["png"], overwrite=overwrite) as png, \
            atomic_path(targets["pdf"], overwrite=overwrite) as pdf:
        for fmt, temporary in (("png", png), ("pdf", pdf)):
            with open(temporary, "wb") as handle:
                figure.savefig(handle, format=fmt, dpi=PNG_DPI, metadata=_METADATA[fmt])
    return tuple(targets.values())
