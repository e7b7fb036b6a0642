"""Model selection: which contact model do a scene's data prefer, and how strongly.

References
----------
.. [1] K. P. Burnham and D. R. Anderson, *Model Selection and Multimodel Inference*, 2nd ed.,
   Springer (2002): Akaike weights w_i = exp(−Δ_i/2)/Σ exp(−Δ_j/2) (sec. 2.9), the rule of
   thumb Δ < 2 substantial support, 4–7 considerably less, > 10 essentially none (sec. 2.6),
   and QAIC = χ²/ĉ + 2K for data scattered ĉ times more than their stated errors allow
   (sec. 2.5), so that ΔQAIC = ΔAIC/ĉ between models with the same number of parameters.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

__all__ = ["selection_table", "summary_table", "SELECTION_COLUMNS"]

SELECTION_COLUMNS = ("model", "success", "nvarys", "ndata", "chisqr", "redchi", "aic", "bic",
                     "delta_aic", "delta_bic", "delta_qaic", "akaike_weight", "rank")


def _misfit_scale(rows, sigma_known):
    """ĉ, the factor by which the best model's χ² exceeds what the stated errors allow, or 1.

    ĉ is the best model's reduced χ² when the timing errors are known and its χ² lies beyond
    3σ of its χ² distribution (ν + 3√(2ν)); otherwise 1 (the errors are fitted, or the fit
    describes the data) [1]_.
    """
    usable = np.flatnonzero(rows["success"])
    if not sigma_known or usable.size == 0:
        return 1.0
    best = usable[np.argmin(rows["aic"][usable])]
    dof = max(int(rows["ndata"][best] - rows["nvarys"][best]), 1)
    redchi = float(rows["redchi"][best])
    return redchi if redchi * dof > dof + 3.0 * math.sqrt(2.0 * dof) else 1.0


def _verdict(rows, c_hat):
    """Plain-words reading of a selection table (Burnham & Anderson's thresholds [1]_).

    `rows` are the table's columns as arrays (dict), in the table's order; `c_hat` the misfit
    scale of :func:`_misfit_scale`. Where the best model misfits (ĉ > 1) the reading is on
    ΔQAIC and never calls a model preferred: the data say which model misfits least, not
    which describes them.
    """
    usable = np.flatnonzero(rows["success"])
    if usable.size == 0:
        return "no model could be fitted to these data"
    # Best first; AICs equal to 0.1 in the table's order (models as close as Ia and IIa
    # would swap places with the platform's rounding).
    gap = np.round(rows["aic"][usable] - rows["aic"][usable].min(), 1)
    usable = usable[np.argsort(gap, kind="stable")]
    if c_hat == 1.0:
        return _preference(rows, usable)
    return (f"not selectable: none describes the data within their uncertainties (best "
            f"reduced chi-square {c_hat:.3g}): effects the models leave out dominate; on the "
            f"scale of that misfit (QAIC) {_least_misfit(rows, usable)}")


def _preference(rows, usable):
    """Which model the information criterion prefers, and how strongly (`usable`: row
    indices of the fitted models, best first)."""
    model, delta, weight = rows["model"], rows["delta_aic"], rows["akaike_weight"]
    best = usable[0]
    if usable.size == 1:
        return f"only {model[best]} could be fitted; no comparison possible"
    runner = usable[1]
    gap = delta[runner]
    if gap > 10:
        return (f"{model[best]} is clearly preferred (Akaike weight {weight[best]:.2f}; "
                f"next best {model[runner]} has ΔAIC = {gap:.1f})")
    if gap > 4:
        return (f"{model[best]} is preferred (weight {weight[best]:.2f}); "
                f"{model[runner]} has considerably less support (ΔAIC = {gap:.1f})")
    close = [model[i] for i in usable if delta[i] < 2]
    if len(close) > 1:
        return (f"the data do not distinguish {', '.join(close)} (ΔAIC < 2); "
                f"{model[best]} fits marginally best")
    return (f"{model[best]} fits best but {model[runner]} is not excluded "
            f"(ΔAIC = {gap:.1f})")


def _least_misfit(rows, usable):
    """Which model misfits least on the QAIC scale (`usable`: fitted rows, best first)."""
    model, delta = rows["model"], rows["delta_qaic"]
    best = usable[0]
    if usable.size == 1:
        return f"only {model[best]} could be fitted"
    close = [model[i] for i in usable if delta[i] < 2]
    if len(close) > 1:
        return f"the data do not distinguish {', '.join(close)} (ΔQAIC < 2)"
    runner = usable[1]
    return (f"{model[best]} misfits least (next {model[runner]} has "
            f"ΔQAIC = {delta[runner]:.1f})")


def selection_table(results, *, sigma_known=True):
    """ΔAIC, ΔBIC and Akaike weights of the models fitted to one scene.

    Parameters
    ----------
    results : dict of str -> FitResult
    sigma_known : bool, default True
        Whether the timing uncertainties were known (then a reduced χ² far above 1 means no
        model describes the data, and the verdict says so).

    Returns
    -------
    table : pandas.DataFrame
        One row per model, columns ``SELECTION_COLUMNS``; failed fits have ΔAIC = inf,
        weight 0 and no rank (0). ``delta_qaic`` is ΔAIC/ĉ, where ĉ is the best model's
        reduced χ² if the timing errors are known and that χ² lies beyond 3σ of its
        distribution, else 1 (then ΔQAIC = ΔAIC); the Akaike weights are computed from it, so
        a misfit the models share does not make one of them look certain [1]_.
    verdict : str
        Plain-words reading of the table.
    """
    fits = list(results.values())
    success = np.array([bool(fit.success) for fit in fits], dtype=bool)
    rows = {"model": np.array(list(results), dtype=object), "success": success,
            "nvarys": np.array([fit.nvarys for fit in fits], dtype=int),
            "ndata": np.array([fit.ndata for fit in fits], dtype=int),
            "chisqr": np.array([fit.chisqr for fit in fits], dtype=float),
            "redchi": np.array([fit.redchi for fit in fits], dtype=float)}
    for criterion in ("aic", "bic"):
        values = np.array([getattr(fit, criterion) for fit in fits], dtype=float)
        values = np.where(success, values, math.inf)
        finite = np.isfinite(values)
        best = values[finite].min() if finite.any() else math.inf
        rows[criterion] = values
        with np.errstate(invalid="ignore"):  # inf − inf where no model was fitted
            rows[f"delta_{criterion}"] = np.where(finite, values - best, math.inf)
    c_hat = _misfit_scale(rows, sigma_known)
    rows["delta_qaic"] = rows["delta_aic"] / c_hat
    finite = np.isfinite(rows["delta_qaic"])
    relative = np.where(finite, np.exp(-0.5 * np.where(finite, rows["delta_qaic"], 0.0)), 0.0)
    total = relative.sum()
    rows["akaike_weight"] = relative / total if total > 0 else np.zeros(len(fits))
    # Rank 1 = lowest AIC (ties in the table's order); failed fits 0.
    order = np.argsort(np.where(np.isfinite(rows["aic"]), rows["aic"], math.inf), kind="stable")
    rank = np.empty(len(fits), dtype=int)
    rank[order] = np.arange(1, len(fits) + 1)
    rows["rank"] = np.where(np.isfinite(rows["aic"]), rank, 0)
    table = pd.DataFrame({name: rows[name] for name in SELECTION_COLUMNS})
    return table, _verdict(rows, c_hat)


def summary_table(scene_fits):
    """One row per scene and model: β, k, ω0, ζ, v0 with errors, and the selection figures.

    Parameters
    ----------
    scene_fits : dict of str -> SceneFit
        Keyed by scene name.

    Returns
    -------
    pandas.DataFrame
        Columns ``scene``, ``model``, ``success``, ``selected``, ``akaike_weight``,
        ``delta_aic``, ``delta_qaic`` (ΔAIC/ĉ, the Δ the Akaike weight is computed from: equal
        to ΔAIC where the fits describe the data, ĉ = 1), ``delta_bic``, ``redchi``, and for
        each of ``beta`` (1/s), ``k`` (N/m), ``omega0`` (rad/s), ``zeta``, ``v0`` (m/s) its
        value and ``*_stderr`` (NaN where the scene does not give it, e.g. k without a mass),
        ``beta_note`` and ``k_note`` (empty, or why β or k is NaN: "no mass given: ..." for k
        without the ball's mass; "not determined (<the data's 95 % bound>; <why>)" where the
        data do not determine ω0, see
        :func:`dashpot.fit.observability.not_determined`), ``omega0_note`` (empty, or the same
        words on ω0 itself where the data do not determine it: its value is where the fit
        ended and its error often infinite, see
        :func:`dashpot.fit.observability.omega0_note`), plus ``verdict``; then
        ``sigma_eps`` (1), ``sigma_j`` (s) and ``noise_verdict``. A scene fitted under the
        noise model as well (``noise_results``) adds one row per noise fit, model
        ``"noise:<law>"``, with its selection figures from ``noise_selection``, ``redchi`` of
        its standardized innovations and its fitted σ_ε and σ_j; every row of that scene
        carries its ``noise_verdict``. Without noise fits these three columns are empty
        (NaN, NaN, "").
    """
    from .fit.observability import not_determined

    rows = []
    for name, scene_fit in scene_fits.items():
        first = len(rows)
        selection = scene_fit.selection.set_index("model")
        for model, fit in scene_fit.results.items():
            row = {"scene": name, "model": model, "success": fit.success,
                   "selected": bool(selection.loc[model, "rank"] == 1),
                   "akaike_weight": selection.loc[model, "akaike_weight"],
                   "delta_aic": selection.loc[model, "delta_aic"],
                   "delta_qaic": _delta_qaic(selection, model),
                   "delta_bic": selection.loc[model, "delta_bic"], "redchi": fit.redchi}
            row.update(_contact_columns(fit, not_determined))
            row["verdict"] = scene_fit.verdict
            rows.append(row)
        noise_results = getattr(scene_fit, "noise_results", None) or {}
        noise_verdict = getattr(scene_fit, "noise_verdict", "") if noise_results else ""
        for row in rows[first:]:
            row.update(sigma_eps=math.nan, sigma_j=math.nan, noise_verdict=noise_verdict)
        if noise_results:
            rows += _noise_rows(name, scene_fit, noise_results, noise_verdict, not_determined)
    return pd.DataFrame(rows)


def _delta_qaic(selection, model):
    """The Δ a model's Akaike weight is computed from: ΔQAIC (ΔAIC/ĉ), or ΔAIC for a table
    written before ΔQAIC was stored (then the weights were computed from ΔAIC)."""
    column = "delta_qaic" if "delta_qaic" in selection else "delta_aic"
    return selection.loc[model, column]


_NO_MASS = "no mass given: k = m omega0^2 needs the ball's mass (the scene's mass)"


def _contact_columns(fit, not_determined):
    """β, k, ω0, ζ, v0 of one fit with their errors, why β or k is empty where it is, and why
    ω0 is not determined where it is not."""
    from .fit.observability import omega0_note

    undetermined = not_determined(fit.estimates) if fit.success else {}
    # β and k have no number where ω0 is not determined; ω0 keeps the one the fit ended at
    # (often ± inf), and its note says that it is no measurement.
    # k = m ω0² is derived only where the scene gives the ball's mass.
    no_mass = fit.success and "k" not in fit.estimates
    notes = {"beta": undetermined.get("beta", ""),
             "k": _NO_MASS if no_mass else undetermined.get("k", ""),
             "omega0": omega0_note(fit.estimates.get("omega0")) if fit.success else ""}
    columns = {}
    for key in ("beta", "k", "omega0", "zeta", "v0"):
        estimate = fit.estimates.get(key)
        shown = estimate is not None and key not in undetermined
        columns[key] = estimate.value if shown else math.nan
        columns[f"{key}_stderr"] = estimate.stderr if shown else math.nan
        if key in notes:
            columns[f"{key}_note"] = notes[key]
    return columns


def _noise_rows(name, scene_fit, noise_results, noise_verdict, not_determined):
    """Summary rows of a scene's fits under the noise model, one per law or model."""
    selection = scene_fit.noise_selection.set_index("model")
    rows = []
    # In the selection table's order: a scene file may list its fits in another.
    for law in selection.index:
        fit = noise_results[law]
        row = {"scene": name, "model": f"noise:{law}", "success": bool(fit.success),
               "selected": bool(selection.loc[law, "selected"]),
               "akaike_weight": selection.loc[law, "akaike_weight"],
               "delta_aic": selection.loc[law, "delta_aic"],
               "delta_qaic": _delta_qaic(selection, law),
               "delta_bic": selection.loc[law, "delta_bic"], "redchi": fit.redchi}
        row.update(_contact_columns(fit, not_determined))
        row["verdict"] = scene_fit.verdict
        for key in ("sigma_eps", "sigma_j"):
            estimate = fit.estimates.get(key)
            row[key] = estimate.value if estimate is not None else math.nan
        row["noise_verdict"] = noise_verdict
        rows.append(row)
    return rows
