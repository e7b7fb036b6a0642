"""Model selection: which contact model do a scene's data prefer, and how strongly.

References
----------
.. [1] K. P. Burnham and D. R. Anderson, *Model Selection and Multimodel Inference*, 2nd ed.,
   Springer (2002): Akaike weights w_i = exp(−Δ_i/2)/Σ exp(−Δ_j/2) (sec. 2.9) and the rule of
   thumb Δ < 2 substantial support, 4–7 considerably less, > 10 essentially none (sec. 2.6).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

__all__ = ["selection_table", "summary_table", "SELECTION_COLUMNS"]

SELECTION_COLUMNS = ("model", "success", "nvarys", "ndata", "chisqr", "redchi", "aic", "bic",
                     "delta_aic", "delta_bic", "akaike_weight", "rank")


def _verdict(table, sigma_known):
    """Plain-words reading of a selection table (Burnham & Anderson's thresholds [1]_)."""
    usable = table[table["success"]].sort_values("aic")
    if usable.empty:
        return "no model could be fitted to these data"
    verdict = _preference(usable)
    best = usable.iloc[0]
    dof = max(int(best["ndata"] - best["nvarys"]), 1)
    if sigma_known and best["redchi"] * dof > dof + 3.0 * math.sqrt(2.0 * dof):
        verdict += (f"; but none describes the data within their uncertainties (best reduced "
                    f"chi-square {best['redchi']:.3g}): effects the models leave out dominate")
    return verdict


def _preference(usable):
    """Which model the information criterion prefers, and how strongly."""
    best = usable.iloc[0]
    if len(usable) == 1:
        return f"only {best['model']} could be fitted; no comparison possible"
    runner = usable.iloc[1]
    gap = runner["delta_aic"]
    if gap > 10:
        return (f"{best['model']} is clearly preferred (Akaike weight {best['akaike_weight']:.2f}; "
                f"next best {runner['model']} has ΔAIC = {gap:.1f})")
    if gap > 4:
        return (f"{best['model']} is preferred (weight {best['akaike_weight']:.2f}); "
                f"{runner['model']} has considerably less support (ΔAIC = {gap:.1f})")
    close = usable[usable["delta_aic"] < 2]["model"].tolist()
    if len(close) > 1:
        return (f"the data do not distinguish {', '.join(close)} (ΔAIC < 2); "
                f"{best['model']} fits marginally best")
    return (f"{best['model']} fits best but {runner['model']} is not excluded "
            f"(ΔAIC = {gap:.1f})")


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
        weight 0 and no rank (0).
    verdict : str
        Plain-words reading of the table.
    """
    rows = [{"model": model, "success": bool(fit.success), "nvarys": fit.nvarys,
             "ndata": fit.ndata, "chisqr": fit.chisqr, "redchi": fit.redchi,
             "aic": fit.aic if fit.success else math.inf,
             "bic": fit.bic if fit.success else math.inf}
            for model, fit in results.items()]
    table = pd.DataFrame(rows, columns=SELECTION_COLUMNS[:8])
    for criterion in ("aic", "bic"):
        finite = np.isfinite(table[criterion])
        best = table.loc[finite, criterion].min() if finite.any() else math.inf
        table[f"delta_{criterion}"] = np.where(finite, table[criterion] - best, math.inf)
    relative = np.where(np.isfinite(table["delta_aic"]), np.exp(-0.5 * table["delta_aic"]
                                                                .where(np.isfinite(
                                                                    table["delta_aic"]), 0.0)),
                        0.0)
    total = relative.sum()
    table["akaike_weight"] = relative / total if total > 0 else 0.0
    order = table["aic"].rank(method="first").where(np.isfinite(table["aic"]), 0)
    table["rank"] = order.astype(int)
    table = table[list(SELECTION_COLUMNS)]
    return table, _verdict(table, sigma_known)


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
        ``delta_aic``, ``delta_bic``, ``redchi``, and for each of ``beta`` (1/s), ``k`` (N/m),
        ``omega0`` (rad/s), ``zeta``, ``v0`` (m/s) its value and ``*_stderr`` (NaN where the
        scene does not give it, e.g. k without a mass), plus ``verdict``.
    """
    rows = []
    for name, scene_fit in scene_fits.items():
        selection = scene_fit.selection.set_index("model")
        for model, fit in scene_fit.results.items():
            row = {"scene": name, "model": model, "success": fit.success,
                   "selected": bool(selection.loc[model, "rank"] == 1),
                   "akaike_weight": selection.loc[model, "akaike_weight"],
                   "delta_aic": selection.loc[model, "delta_aic"],
                   "delta_bic": selection.loc[model, "delta_bic"], "redchi": fit.redchi}
            for key in ("beta", "k", "omega0", "zeta", "v0"):
                estimate = fit.estimates.get(key)
                row[key] = estimate.value if estimate else math.nan
                row[f"{key}_stderr"] = estimate.stderr if estimate else math.nan
            row["verdict"] = scene_fit.verdict
            rows.append(row)
    return pd.DataFrame(rows)
