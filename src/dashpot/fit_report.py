"""A scene's fits as a physicist reads them: text and a parameter table, never printed here.

:func:`report_text` is the summary the command line prints after ``dashpot fit`` and
``dashpot analyze`` (the command prints it; this module only returns text), in the spirit of
lmfit's ``fit_report``: one line per model with ζ, β, k (or a restitution law's parameters),
σ_ε and σ_j under the noise model, the ε range of the predicted train and χ²/ν; the model's
notes beneath it; which quantities the models the data cannot tell apart agree on; the
selection's verdict. :func:`parameter_table` gives the same numbers as one row per model and
parameter, for ``<name>-parameters.csv``. Both take the deterministic fits and the fits under
the noise model alike (any result with ``model``, ``success``, ``message``, ``estimates``,
``notes``, ``predicted`` and ``redchi``).

Numbers are written as Particle Data Group style measurements [1]_: the uncertainty rounded to
two significant digits, the value to the same decimal place, and one notation per number
(a shared power of ten, ``k = (5.36 ± 0.52)e3 N/m``), by the ``uncertainties`` package [2]_.

A quantity the data do not determine is written as such, with the bound the data give (the
finite ends of its 95.45 % interval), not as a number:

* β, k and γ where ω0 is not determined (:func:`dashpot.fit.observability.not_determined`;
  a noise fit's ω0, derived from its fitted v* = g/ω0, is judged the same way);
* any other positive quantity (an interval not reaching below 0; t0 aside) whose relative
  error exceeds :data:`dashpot.fit.settings.WEAK_RELATIVE_ERROR`, or whose 95.45 % interval
  is unbounded, the rule of the fits' own identifiability notes;
* a noise amplitude σ_ε or σ_j, or v* = g/ω0, consistent with 0 (relative error above that
  limit) is an upper limit, ``σ_ε < 0.0049 % at 95 %``.

A signed quantity whose interval spans 0 (a law's speed term) stays a number with its error:
``α = (2.4 ± 2.2)e-5 s/m`` says it is consistent with 0.

References
----------
.. [1] R. L. Workman et al. (Particle Data Group), "Review of Particle Physics",
   Prog. Theor. Exp. Phys. 2022, 083C01, Introduction sec. 5.3 (rounding of errors).
.. [2] E. O. Lebigot, "Uncertainties: a Python package for calculations with uncertainties",
   https://uncertainties.readthedocs.io (format specification ``.2u``).
"""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np

__all__ = ["report_text", "parameter_table", "format_measurement", "undetermined",
           "PARAMETER_COLUMNS", "DETERMINED_SPREAD", "SUPPORTED_DELTA"]

# Column order of :func:`parameter_table` (and of `<name>-parameters.csv`).
PARAMETER_COLUMNS = ("model", "parameter", "value", "stderr", "low68", "high68", "low95",
                     "high95", "unit", "status", "note")
# Models within this ΔAIC (ΔQAIC where the best misfits) of the best have support in Burnham
# and Anderson's terms (> 10: essentially none): the data do not tell them apart.
SUPPORTED_DELTA = 10.0
# A quantity those models give within this relative spread is determined whatever the model.
DETERMINED_SPREAD = 0.10
# Symbols of the estimates' names (a restitution law's own names are used as they are).
SYMBOLS = {"zeta": "ζ", "beta": "β", "omega0": "ω0", "k": "k", "gamma": "γ", "v0": "v0",
           "t0": "t0", "v_star": "v*", "sigma_eps": "σ_ε", "sigma_j": "σ_j", "alpha": "α",
           "kappa": "κ", "chi": "χ"}
# Display scale and unit of the noise amplitudes (a relative scatter in %, a jitter in µs).
DISPLAY = {"sigma_eps": (100.0, "%"), "sigma_j": (1e6, "µs")}
CONTACT_NAMES = ("zeta", "beta", "k")  # what a dashpot model's line shows, in this order
NOISE_NAMES = ("sigma_eps", "sigma_j")
# Scales ≥ 0 whose value 0 is a physical limit (no scatter, no jitter, the gravity-free limit
# v* = g/ω0 → 0): consistent with 0, they are upper limits.
UPPER_LIMITS = frozenset({*NOISE_NAMES, "v_star"})
# Never on a line of their own: the start time, v0, and what β, k carry (ω0, v*, γ).
HIDDEN = frozenset({"t0", "v0", "omega0", "v_star", "gamma"})
# Notes on how a fit was made rather than on what the data say: shown with verbose=True.
ROUTINE_PREFIXES = ("accuracy ", "start: ", "noise model: rebound scatter",
                    "noise model not fitted (noise: auto)")


def _exponent(match):
    """'e+03' -> 'e3', 'e-05' -> 'e-5' (regex callback)."""
    sign, digits = match.group(1), match.group(2).lstrip("0") or "0"
    return f"e{'-' if sign == '-' else ''}{digits}"


def format_measurement(value, stderr, unit=""):
    """``value ± stderr unit``, rounded as a physicist writes a measurement.

    Parameters
    ----------
    value : float
        Best estimate, in `unit`.
    stderr : float
        Its 1σ uncertainty, in `unit` (0: exact; NaN or inf: unknown).
    unit : str, optional
        Appended after a space ("" or "1": dimensionless).

    Returns
    -------
    str
        ``"25.0 ± 8.5 1/s"``, ``"(5.36 ± 0.52)e3 N/m"``: two significant digits of the
        uncertainty, the value to the same decimal place, one power of ten shared by both
        (the ``uncertainties`` package's ``.2u`` format [2]_). An exact value is written to
        six significant digits with "(exact)", a value without a finite uncertainty to four
        with "(no uncertainty)".
    """
    from uncertainties import ufloat

    suffix = "" if unit in ("", "1") else f" {unit}"
    if not math.isfinite(value):
        return f"{value}{suffix}"
    if stderr == 0:
        return f"{value:.6g}{suffix} (exact)"
    if not math.isfinite(stderr) or stderr < 0:
        return f"{value:.4g}{suffix} (no uncertainty)"
    text = format(ufloat(value, stderr), ".2u").replace("+/-", " ± ")
    return re.sub(r"e([+-]?)(\d+)", _exponent, text) + suffix


def _number(value):
    """A bound or a range end, to three significant digits."""
    return re.sub(r"e([+-]?)(\d+)", _exponent, f"{value:.3g}")


def _scaled(name, estimate):
    """The estimate in its display unit (σ_ε in %, σ_j in µs; the rest as stored)."""
    scale, unit = DISPLAY.get(name, (1.0, estimate.unit))
    if scale == 1.0:
        return estimate
    return replace(estimate, value=estimate.value * scale, stderr=estimate.stderr * scale,
                   low68=estimate.low68 * scale, high68=estimate.high68 * scale,
                   low95=estimate.low95 * scale, high95=estimate.high95 * scale, unit=unit)


def _bound(symbol, estimate):
    """The bound the data give, from the finite ends of the 95.45 % interval (text)."""
    from .fit.observability import bound_text

    unit = "" if estimate.unit in ("", "1") else estimate.unit
    return bound_text(symbol, unit, estimate, _number)


def undetermined(fit):
    """What the data do not determine in one fit, each with the text to print instead.

    Parameters
    ----------
    fit : FitResult-like
        A deterministic fit (:class:`dashpot.fit.FitResult`) or one under the noise model.

    Returns
    -------
    dict of str -> str
        Estimate name -> ``"not determined (<bound>; <why>)"``, or for a noise amplitude
        consistent with 0 its upper limit ``"< 4.9e-05 at 95 %"`` (see the module notes).
        Fixed estimates never appear.
    """
    from .fit.observability import CONTACT_QUANTITIES, not_determined
    from .fit.settings import WEAK_RELATIVE_ERROR

    estimates = dict(fit.estimates)
    omega0 = estimates.get("omega0")
    if omega0 is not None and omega0.status == "derived":
        # A noise fit derives ω0 = g/v* from its fitted v*: as (un)determined as v* is.
        estimates["omega0"] = replace(omega0, status="fitted")
    reasons = dict(not_determined(estimates))
    for name, estimate in fit.estimates.items():
        if (name in reasons or name in CONTACT_QUANTITIES or name == "t0"
                or estimate.status == "fixed"):
            continue  # β, k and γ: ω0 decides, as everywhere else (summary.csv)
        shown = _scaled(name, estimate)
        symbol = SYMBOLS.get(name, name)
        value, stderr = shown.value, shown.stderr
        relative = stderr / abs(value) if value else math.inf
        weak = not relative <= WEAK_RELATIVE_ERROR or not math.isfinite(shown.high95)
        if name in UPPER_LIMITS:
            if weak and math.isfinite(shown.high95):
                reasons[name] = f"< {_number(shown.high95)} {shown.unit} at 95 %"
            continue
        if weak and value > 0 and not shown.low95 < 0:
            why = ("unbounded above at 95 %" if not math.isfinite(shown.high95)
                   else f"relative error {relative:.2g}")
            reasons[name] = f"not determined ({_bound(symbol, shown)}; {why})"
    return reasons


def _shown_names(fit):
    """Names of the estimates one fit's line shows, in order."""
    from .physics.laws import LAWS
    from .physics.models import MODELS

    estimates = fit.estimates
    if fit.model in MODELS:
        names = [name for name in CONTACT_NAMES if name in estimates]
    elif fit.model in LAWS:
        names = [name for name in LAWS[fit.model].parameter_names if name in estimates]
    else:
        names = [name for name in estimates if name not in HIDDEN and name not in NOISE_NAMES]
    return names + [name for name in NOISE_NAMES if name in estimates]


def _estimate_text(name, estimate, reason):
    """``ζ = 0.01814 ± 0.00025``, or the quantity with its reason where not determined."""
    symbol = SYMBOLS.get(name, name)
    if reason is not None:
        return f"{symbol} {reason}"
    shown = _scaled(name, estimate)
    return f"{symbol} = {format_measurement(shown.value, shown.stderr, shown.unit)}"


def _restitution_range(fit):
    """(lowest, highest) ε of the fit's predicted train, or None."""
    eps = np.asarray((fit.predicted or {}).get("restitution", []), dtype=float)
    eps = eps[np.isfinite(eps) & (eps > 0)]
    return (float(eps.min()), float(eps.max())) if eps.size else None


def fit_line(fit):
    """One fit in one line: its quantities, the ε range of its train and χ²/ν.

    Parameters
    ----------
    fit : FitResult-like

    Returns
    -------
    str
        E.g. ``"ζ = 0.01834 ± 0.00026, β = 9.54 ± 0.29 1/s, k = 730 ± 54 N/m, ε 0.7544–0.9432,
        χ²/ν = 2.3e4"``; ``"failed: <reason>"`` for a failed fit.
    """
    if not fit.success:
        return f"failed: {fit.message.removeprefix('fit failed: ')}"
    reasons = undetermined(fit)
    parts = [_estimate_text(name, fit.estimates[name], reasons.get(name))
             for name in _shown_names(fit)]
    eps = _restitution_range(fit)
    if eps is not None:
        low, high = f"{eps[0]:.4f}", f"{eps[1]:.4f}"
        parts.append(f"ε {low}" if low == high else f"ε {low}–{high}")
    if math.isfinite(fit.redchi):
        parts.append(f"χ²/ν = {_number(fit.redchi)}")
    return ", ".join(parts)


def _notes_by_fit(results, shared, verbose):
    """Each fit's notes less those said once for the group, and routine ones unless verbose."""
    notes = {}
    for model, fit in results.items():
        kept = []
        for note in fit.notes:
            if note in shared or note in kept or note.startswith("fit failed"):
                continue
            if not verbose and note.startswith(ROUTINE_PREFIXES):
                continue
            kept.append(note)
        notes[model] = kept
    return notes


def _common_notes(results):
    """Notes every fit of a group carries (said once for the group), in the first fit's order."""
    fits = [fit for fit in results.values() if fit.success]
    if len(fits) < 2:
        return []
    common = set(fits[0].notes).intersection(*(fit.notes for fit in fits[1:]))
    return [note for note in fits[0].notes if note in common]


def _criterion(selection):
    """The selection's column and symbol: ΔQAIC where the misfit scale made it differ from
    ΔAIC (:func:`dashpot.select.selection_table`), else ΔAIC."""
    table = selection.reset_index() if "model" not in selection.columns else selection
    if "delta_qaic" in table.columns:
        aic, qaic = table["delta_aic"].to_numpy(float), table["delta_qaic"].to_numpy(float)
        finite = np.isfinite(aic) & np.isfinite(qaic)
        if not np.allclose(aic[finite], qaic[finite]):
            return table, "delta_qaic", "ΔQAIC"
    return table, "delta_aic", "ΔAIC"


def _supported(selection):
    """Models within SUPPORTED_DELTA of the best, and the criterion's symbol."""
    table, column, symbol = _criterion(selection)
    keep = table["success"].astype(bool) & (table[column] < SUPPORTED_DELTA)
    return list(table.loc[keep, "model"]), symbol


def agreement_text(results, selection):
    """What the models the data cannot tell apart agree on, or None.

    Parameters
    ----------
    results : dict of str -> FitResult-like
    selection : pandas.DataFrame
        The selection table of :func:`dashpot.select.selection_table`.

    Returns
    -------
    str or None
        For the fitted models within ``SUPPORTED_DELTA`` of the best (at least two): the
        relative spread of ζ, β and k across them, and which of these the data determine
        whatever the model (spread at most ``DETERMINED_SPREAD``, and determined in every
        model), e.g. "across Ib, IIb, hybrid (ΔAIC < 10): ζ agrees to 2.1 %; β 9.54–17.4 1/s
        (spread 58 %), k 730–2.37e3 N/m: the data determine ζ, not β, k".
    """
    from .physics.models import MODELS

    if selection is None or len(selection) == 0:
        return None
    supported, criterion = _supported(selection)
    models = [model for model in supported
              if model in MODELS and model in results and results[model].success]
    if len(models) < 2:
        return None
    determined, not_determined, parts = [], [], []
    for name in CONTACT_NAMES:
        fits = [results[model] for model in models]
        if not all(name in fit.estimates for fit in fits):
            continue
        symbol = SYMBOLS[name]
        missing = [model for model, fit in zip(models, fits) if name in undetermined(fit)]
        if missing:
            not_determined.append(symbol)
            parts.append(f"{symbol} not determined ({', '.join(missing)})")
            continue
        values = np.array([fit.estimates[name].value for fit in fits])
        spread = (values.max() - values.min()) / abs(values.mean())
        if spread <= DETERMINED_SPREAD:
            determined.append(symbol)
            parts.append(f"{symbol} agrees to {100 * spread:.2g} %")
        else:
            not_determined.append(symbol)
            unit = fits[0].estimates[name].unit
            unit = "" if unit in ("", "1") else f" {unit}"
            parts.append(f"{symbol} {_number(values.min())}–{_number(values.max())}{unit} "
                         f"(spread {100 * spread:.2g} %)")
    if not parts:
        return None
    verdict = (f"the data determine {', '.join(determined) or 'none of these'} whatever the "
               f"model" + (f", not {', '.join(not_determined)}" if not_determined else ""))
    return (f"across {', '.join(models)} ({criterion} < {SUPPORTED_DELTA:g}): "
            f"{'; '.join(parts)}: {verdict}")


def _group_lines(results, selection, verdict, label, verbose, said):
    """Lines of one group of fits (deterministic, or under the noise model)."""
    lines = []
    common = [note for note in _common_notes(results) if note not in said]
    notes = _notes_by_fit(results, set(said) | set(common), verbose)
    width = max([6, *(len(model) for model in results)])
    prefix = f"{label} " if label else ""
    for model, fit in results.items():
        lines.append(f"  {prefix}{model:>{width}}: {fit_line(fit)}")
        lines.extend(f"  {' ' * (len(prefix) + width)}  note: {note}" for note in notes[model])
    lines.extend(f"  {prefix}note: {note}" for note in common if
                 verbose or not note.startswith(ROUTINE_PREFIXES))
    agreement = agreement_text(results, selection)
    if agreement:
        lines.append(f"  {prefix}{agreement}")
    if verdict:
        lines.append(f"  {prefix}selection: {verdict}")
    return lines


def report_text(scene_fit, *, notes=(), verbose=False):
    """The text summary of a scene's fits (what ``dashpot fit`` and ``analyze`` print).

    Parameters
    ----------
    scene_fit : dashpot.fit.SceneFit
    notes : sequence of str or None, optional
        Further notes on the scene (e.g. that the file fitted is not the scene's recording),
        printed with the data's notes; None and "" are skipped.
    verbose : bool, default False
        Also the notes on how each fit was made (accuracy level, start values).

    Returns
    -------
    str
        Lines without a trailing newline: one per model (:func:`fit_line`) with its own notes
        indented beneath, notes common to every model once, what the models the data cannot
        tell apart agree on (:func:`agreement_text`), the selection's verdict, the scene's
        notes, then the same for the fits under the noise model where there are any.
    """
    scene_notes = list(dict.fromkeys(note for note in [*notes, *scene_fit.data.notes]
                                     if note))
    lines = _group_lines(scene_fit.results, scene_fit.selection, scene_fit.verdict, "",
                         verbose, scene_notes)
    lines.extend(f"  note: {note}" for note in scene_notes)
    if scene_fit.noise_results:
        lines.extend(_group_lines(scene_fit.noise_results, scene_fit.noise_selection,
                                  scene_fit.noise_verdict, "noise", verbose, scene_notes))
    return "\n".join(lines)


def _rows(name, fit):
    """The rows of one fit in :func:`parameter_table`."""
    if not fit.success:
        return [{"model": name, "parameter": "", "status": "failed", "note": fit.message}]
    reasons = undetermined(fit)
    rows = []
    for parameter, estimate in fit.estimates.items():
        reason = reasons.get(parameter)
        row = {"model": name, "parameter": parameter, "value": estimate.value,
               "stderr": estimate.stderr, "low68": estimate.low68, "high68": estimate.high68,
               "low95": estimate.low95, "high95": estimate.high95, "unit": estimate.unit,
               "status": estimate.status, "note": estimate.note}
        if reason is not None and reason.startswith("not determined"):
            # No number where the data give none (as summary.csv leaves β and k empty).
            row.update(value=math.nan, stderr=math.nan, status="not determined", note=reason)
        elif reason is not None:
            row["note"] = f"upper limit: {SYMBOLS.get(parameter, parameter)} {reason}"
        rows.append(row)
    return rows


def parameter_table(scene_fit):
    """One row per model and parameter: value, σ, 68.27 / 95.45 % bounds, unit and status.

    Parameters
    ----------
    scene_fit : dashpot.fit.SceneFit

    Returns
    -------
    pandas.DataFrame
        Columns :data:`PARAMETER_COLUMNS`, in SI units as the fits store them (σ_ε
        dimensionless, σ_j in s). ``model`` is the model's name, or ``noise:<law>`` for a fit
        under the noise model. ``status`` is the estimate's ("fitted", "fixed", "prior",
        "derived"), "not determined" (value and stderr empty, the bound in ``note``; see the
        module notes) or "failed" (one row without a parameter, the reason in ``note``).
    """
    import pandas as pd

    rows = []
    for model, fit in scene_fit.results.items():
        rows.extend(_rows(model, fit))
    for law, fit in scene_fit.noise_results.items():
        rows.extend(_rows(f"noise:{law}", fit))
    table = pd.DataFrame(rows, columns=list(PARAMETER_COLUMNS))
    for column in PARAMETER_COLUMNS[2:8]:
        table[column] = table[column].astype(float)
    return table
