"""Cross-scene summary from stored scene files (``results/<scene>.h5``).

:func:`dashpot.select.summary_table` takes fitted :class:`~dashpot.fit.SceneFit` objects; the
workflow's summary step only has the scene files. :func:`summary_from_records` rebuilds from
:func:`dashpot.store.read_fit` dicts exactly what ``summary_table`` reads (each fit's success,
reduced χ² and estimates, the selection table and the verdict) and calls it, so the summary
of stored files and of fits in memory are the same table.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import pandas as pd

from .select import summary_table
from .store import read_fit

__all__ = ["SUMMARY_COLUMNS", "summary_from_records", "summary_from_files"]

SUMMARY_COLUMNS = ("scene", "model", "success", "selected", "akaike_weight", "delta_aic",
                   "delta_bic", "redchi", "beta", "beta_stderr", "k", "k_stderr", "omega0",
                   "omega0_stderr", "zeta", "zeta_stderr", "v0", "v0_stderr", "verdict")
"""Columns of the summary table, in order (units in :data:`dashpot.store.SUMMARY_UNITS`)."""


def _fit_view(fit):
    """What summary_table reads of a FitResult, from one ``read_fit()['fits'][model]``."""
    estimates = {name: SimpleNamespace(value=float(row["value"]), stderr=float(row["stderr"]))
                 for name, row in fit["parameters"].iterrows()}
    attrs = fit["attrs"]
    redchi = float(attrs.get("redchi", math.nan))
    return SimpleNamespace(success=bool(attrs.get("success", False)), redchi=redchi,
                           estimates=estimates)


def _scene_view(record):
    """What summary_table reads of a SceneFit, from one ``read_fit()`` dict."""
    return SimpleNamespace(results={model: _fit_view(fit) for model, fit in
                                    record["fits"].items()},
                           selection=record["selection"],
                           verdict=str(record["attrs"].get("verdict", "")))


def summary_from_records(records):
    """One row per scene and model, from stored scene files read with ``read_fit``.

    Parameters
    ----------
    records : dict of str -> dict
        Scene name -> :func:`dashpot.store.read_fit` of its file, in the order of the rows.

    Returns
    -------
    pandas.DataFrame
        Columns :data:`SUMMARY_COLUMNS` (as :func:`dashpot.select.summary_table`): scene,
        model, success, selected (rank 1 by AIC), akaike_weight, delta_aic, delta_bic,
        redchi, β (1/s), k (N/m, NaN without a mass), ω0 (rad/s), ζ, v0 (m/s) each with its
        ``*_stderr``, and the scene's verdict. No scenes give an empty table with these
        columns.
    """
    table = summary_table({name: _scene_view(record) for name, record in records.items()})
    if table.empty:
        return pd.DataFrame({column: pd.Series(dtype=object if column in
                                               ("scene", "model", "verdict") else float)
                             for column in SUMMARY_COLUMNS})
    return table[list(SUMMARY_COLUMNS)].reset_index(drop=True)


def summary_from_files(paths):
    """:func:`summary_from_records` of scene files, each named by its file stem.

    Parameters
    ----------
    paths : sequence of str or os.PathLike
        Scene files written by :func:`dashpot.store.write_scene_fit`.
    """
    from pathlib import Path

    return summary_from_records({Path(path).stem: read_fit(path) for path in paths})
