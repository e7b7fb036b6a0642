"""Cross-scene summary from stored scene files (``results/<scene>.h5``).

:func:`dashpot.select.summary_table` takes fitted :class:`~dashpot.fit.SceneFit` objects; the
workflow's summary step only has the scene files. :func:`summary_from_records` rebuilds from
:func:`dashpot.store.read_fit` dicts exactly what ``summary_table`` reads (each fit's success,
reduced χ² and estimates, the selection table and the verdict) and calls it, so the summary
of stored files and of fits in memory are the same table; a stored synthetic scene adds its
truth and each fit's pulls against it (:mod:`dashpot.truth`), which only the file holds.

A workflow summary must also be honest about scenes it could not use: :func:`summary_from_files`
opens and checks every file (a damaged one becomes one row naming it, not a traceback) and
marks the scenes the workflow could not run, so the table says which rows are stale.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace

import h5py
import numpy as np
import pandas as pd

from .select import summary_table
from .store import FORMAT, read_fit
from .truth import TRUTH_PARAMETERS, pulls

__all__ = ["SUMMARY_COLUMNS", "TRUTH_SUMMARY_COLUMNS", "STATUSES", "summary_from_records",
           "summary_from_files", "scene_file_problem", "read_summary_record"]

TRUTH_SUMMARY_COLUMNS = tuple(f"{name}_{kind}" for name in TRUTH_PARAMETERS
                              for kind in ("truth", "pull"))
"""A synthetic scene's true parameters and each row's pulls against them."""

SUMMARY_COLUMNS = ("scene", "model", "success", "selected", "akaike_weight", "delta_aic",
                   "delta_qaic", "delta_bic", "redchi", "beta", "beta_stderr", "beta_note", "k",
                   "k_stderr", "k_note", "omega0", "omega0_stderr", "omega0_note", "zeta",
                   "zeta_stderr", "v0", "v0_stderr", "verdict", "sigma_eps", "sigma_j",
                   "noise_verdict", "notes", *TRUTH_SUMMARY_COLUMNS, "status", "problem")
"""Columns of the summary table, in order (units in :data:`dashpot.store.SUMMARY_UNITS`; the
CSV's headers carry them, :func:`dashpot.store.csv_header`)."""

STATUSES = {
    "ok": "fitted from the scene's current inputs",
    "stale": "the scene cannot run now (see `problem`); its rows are those of an earlier run",
    "failed": "the scene cannot run and has no earlier result: one row, no model",
    "unreadable": "its results/<scene>.h5 cannot be read: one row, no model",
}
"""Values of the ``status`` column and what each means."""

_TEXT_COLUMNS = ("scene", "model", "beta_note", "k_note", "omega0_note", "verdict",
                 "noise_verdict", "notes", "status", "problem")
# h5py raises all of these for a damaged or foreign file, depending on where the damage is.
_READ_ERRORS = (OSError, RuntimeError, KeyError, ValueError, TypeError)


def _fit_view(fit):
    """What summary_table reads of a FitResult, from one ``read_fit()['fits'][model]``."""
    estimates = {name: SimpleNamespace(value=float(row["value"]), stderr=float(row["stderr"]),
                                       low95=float(row["low95"]), high95=float(row["high95"]),
                                       status=str(row["status"]))
                 for name, row in fit["parameters"].iterrows()}
    attrs = fit["attrs"]
    redchi = float(attrs.get("redchi", math.nan))
    return SimpleNamespace(success=bool(attrs.get("success", False)), redchi=redchi,
                           estimates=estimates)


def _scene_view(record):
    """What summary_table reads of a SceneFit (with its fits under the noise model, where the
    file has them), from one ``read_fit()`` dict."""
    return SimpleNamespace(results={model: _fit_view(fit) for model, fit in
                                    record["fits"].items()},
                           selection=record["selection"],
                           verdict=str(record["attrs"].get("verdict", "")),
                           noise_results={law: _fit_view(fit) for law, fit in
                                          record.get("noise_fits", {}).items()},
                           noise_selection=record.get("noise_selection"),
                           noise_verdict=record.get("noise_verdict", ""))


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
        model, success, selected (rank 1 by AIC), akaike_weight, delta_aic, delta_qaic (the
        Δ akaike_weight is computed from: ΔAIC/ĉ where no model describes the data), delta_bic,
        redchi, β (1/s), k (N/m, NaN without a mass), ω0 (rad/s), ζ, v0 (m/s) each with its
        ``*_stderr``, ``beta_note`` and ``k_note`` (why β or k is empty although fitted: not
        determined by the data), ``omega0_note`` (why ω0's value is no measurement and its
        error often infinite: not determined by the data), the scene's verdict, then ``sigma_eps`` (1), ``sigma_j`` (s) and
        ``noise_verdict``: empty for the deterministic fits' rows, except the noise verdict of a
        scene with fits under the noise model, which also has one row per noise fit (model
        ``"noise:<law>"``); ``notes``, the row's fit notes in plain words joined by " | "
        (routine ones on the accuracy level and start values left out); then for a synthetic scene (its file holds the ``truth`` table)
        the true β (1/s), ω0 (rad/s), ζ and v0 (m/s) on each of its rows as ``*_truth`` and
        the pull of the row's fit against each as ``*_pull`` (NaN for fits under the noise
        model and where the fit's error is not finite and positive; see
        :mod:`dashpot.truth`). No scenes give an empty table with these columns.
    """
    table = summary_table({name: _scene_view(record) for name, record in records.items()})
    if table.empty:
        return _empty_table()
    table = table.assign(status="ok", problem="", notes=_notes_column(table, records),
                         **_truth_columns(table, records))
    return table[list(SUMMARY_COLUMNS)].reset_index(drop=True)


def _notes_column(table, records):
    """Each row's fit notes in plain words, joined by " | " (prior conflicts, restarts, strong
    correlations, what the data do not determine), less the routine ones on how the fit was
    made (accuracy level, start values), as `dashpot fit` prints them."""
    from .fit_report import ROUTINE_PREFIXES

    def notes(scene, model):
        group, name = (("noise_fits", model.split(":", 1)[1]) if model.startswith("noise:")
                       else ("fits", model))
        fit = records[scene].get(group, {}).get(name)
        if fit is None:
            return ""
        try:
            said = json.loads(fit["attrs"].get("notes", "[]"))
        except (TypeError, ValueError):
            return ""
        return " | ".join(note for note in said if not note.startswith(ROUTINE_PREFIXES))

    return [notes(scene, model) for scene, model in zip(table["scene"], table["model"])]


def _truth_columns(table, records):
    """The ``*_truth`` and ``*_pull`` columns of the summary rows `table` (NaN where none).

    Each scene's truth and each fit's estimates are looked up once (a summary of thousands
    of scenes stays linear in its rows).
    """
    columns = {name: np.full(len(table), np.nan) for name in TRUTH_SUMMARY_COLUMNS}
    truths, estimates_of = {}, {}
    for row, (scene, model) in enumerate(zip(table["scene"], table["model"])):
        if scene not in truths:
            truth = records[scene].get("truth")
            truths[scene] = (None if truth is None else
                             dict(zip(truth["parameter"], truth["truth"].astype(float))))
        true_values = truths[scene]
        if true_values is None:
            continue
        if (scene, model) not in estimates_of:
            fit = records[scene]["fits"].get(model)
            estimates_of[scene, model] = (
                None if fit is None else
                {name: (float(values["value"]), float(values["stderr"]))
                 for name, values in fit["parameters"][["value", "stderr"]].iterrows()})
        estimates = estimates_of[scene, model]
        for name in TRUTH_PARAMETERS:
            if name not in true_values:
                continue
            columns[f"{name}_truth"][row] = true_values[name]
            if estimates is not None and name in estimates:
                value, stderr = estimates[name]
                columns[f"{name}_pull"][row] = pulls(value, stderr, true_values[name])
    return columns


def _empty_table():
    return pd.DataFrame({column: pd.Series(dtype=object if column in _TEXT_COLUMNS else float)
                         for column in SUMMARY_COLUMNS})


def _fits_record(group):
    """Each fit of a ``fits`` or ``noise_fits`` group: its attributes and parameter table."""
    from .store import read_table

    return {name: {"attrs": dict(fit.attrs),
                   "parameters": read_table(fit["parameters"]).set_index("name")}
            for name, fit in group.items()}


def _noise_part(group):
    from .store import read_table

    if "noise_fits" not in group:
        return {}
    return {"noise_selection": read_table(group["noise_selection"]),
            "noise_verdict": str(group["noise_selection"].attrs.get("verdict", "")),
            "noise_fits": _fits_record(group["noise_fits"])}


def read_summary_record(path):
    """What the summary reads of a scene file, in the layout of :func:`dashpot.store.read_fit`.

    Only the parts the summary uses: the root attributes, the impacts' ``run`` column,
    ``selection``, each fit's attributes and parameter table (``fits``, and ``noise_fits``
    with ``noise_selection`` and ``noise_verdict``), ``truth``, and the same of each run
    under ``runs``. A small part of the file (no residuals, curves, bounces or intervals),
    so that a summary of thousands of scenes reads each file quickly, and once.

    Parameters
    ----------
    path : str or os.PathLike
        A scene file written by :func:`dashpot.store.write_scene_fit`.
    """
    from .store import read_table

    with h5py.File(path, "r") as source:
        impacts = source["impacts"]
        columns = list(impacts.attrs["columns"])
        runs = impacts["run"][()] if "run" in columns else None
        length = impacts[columns[0]].shape[0] if columns else 0
        out = {"attrs": dict(source.attrs),
               "impacts": (pd.DataFrame({"run": runs}) if runs is not None
                           else pd.DataFrame(index=range(length))),
               "selection": read_table(source["selection"]),
               "fits": _fits_record(source["fits"]), **_noise_part(source)}
        if "truth" in source:
            out["truth"] = read_table(source["truth"])
            out["truth"].attrs.update({key: str(source["truth"].attrs.get(key, ""))
                                       for key in ("model", "source")})
        if "runs" in source:
            out["runs"] = {int(number): {"attrs": dict(group.attrs),
                                         "selection": read_table(group["selection"]),
                                         "fits": _fits_record(group["fits"]),
                                         **_noise_part(group)}
                           for number, group in source["runs"].items()}
    return out


def scene_file_problem(path):
    """Why a stored scene file cannot be used, in one line naming it, or None if it can.

    A quick check (the file opens as HDF5, says it is a dashpot scene file and holds its
    groups); :func:`summary_from_files` reads each file whole as well.

    Parameters
    ----------
    path : str or os.PathLike
        A ``results/<scene>.h5`` written by :func:`dashpot.store.write_scene_fit`.
    """
    try:
        with h5py.File(path, "r") as source:
            found = source.attrs.get("format")
            if found != FORMAT:
                return f"{path}: not a dashpot scene file (format {found!r}, not {FORMAT!r})"
            missing = [group for group in ("impacts", "bounces", "selection", "fits")
                       if group not in source]
    except _READ_ERRORS as error:
        return f"{path}: not a readable HDF5 file ({_one_line(error)})"
    if missing:
        return f"{path}: damaged scene file (no {', '.join(missing)})"
    return None


def _one_line(error):
    return " ".join(str(error).split()) or type(error).__name__


def _scene_row(scene, status, problem):
    row = {column: math.nan for column in SUMMARY_COLUMNS}
    row.update(scene=scene, model="", success=False, selected=False, beta_note="", k_note="",
               omega0_note="", verdict="", noise_verdict="", notes="", status=status,
               problem=problem)
    return row


def summary_from_files(paths, problems=None, *, by_run=False, block=500):
    """:func:`summary_from_records` of scene files, each named by its file stem, with a status.

    Every file is read once (:func:`read_summary_record`); one that cannot be read gives one
    ``unreadable`` row naming it (and its problem) instead of stopping the summary.

    Parameters
    ----------
    paths : sequence of str or os.PathLike
        Scene files written by :func:`dashpot.store.write_scene_fit`.
    problems : dict of str -> str, optional
        Scene name -> why it cannot run now (one line). Such a scene's rows, from its file in
        `paths` (an earlier run), are marked ``stale``; one without a file gets one ``failed``
        row.
    by_run : bool, optional
        One row per run and model (:func:`dashpot.run_summary.summary_by_run`, from the
        records already read).
    block : int, optional
        Files read before their rows are made and their records let go (memory).

    Returns
    -------
    pandas.DataFrame
        Columns :data:`SUMMARY_COLUMNS` (with ``run`` after ``scene`` if `by_run`): the fit
        columns of :func:`summary_from_records`, then ``status`` (see :data:`STATUSES`) and
        ``problem`` (empty when ``ok``). Rows of fitted scenes first, in the order of
        `paths`, then one row per scene without a usable file.
    """
    problems = dict(problems or {})
    parts, unusable, seen = [], [], set()
    paths = list(paths)
    # A block of files at a time: its records (about 0.1 MB a scene) become summary rows and
    # are let go, so that memory stays flat however many scenes there are.
    for first in range(0, len(paths), block):
        records = {}
        for path in paths[first:first + block]:
            scene = Path(path).stem
            problem = scene_file_problem(path)
            if problem is None:
                try:
                    records[scene] = read_summary_record(path)
                except _READ_ERRORS as error:
                    problem = f"{path}: damaged scene file ({_one_line(error)})"
            if problem is not None:
                unusable.append(_scene_row(scene, "unreadable", problem))
                seen.add(scene)
        if records:
            part = summary_from_records(records)
            if by_run:
                from .run_summary import summary_by_run

                part = summary_by_run(part, paths[first:first + block], records=records)
            parts.append(part)
            seen |= set(records)
    table = (pd.concat(parts, ignore_index=True) if len(parts) > 1 else
             parts[0] if parts else _empty_table())
    if by_run and not parts:
        from .run_summary import _order

        table = table.assign(run=np.zeros(0, dtype=np.int64))
        table = table[_order(table)]
    stale = table["scene"].isin(list(problems))
    table.loc[stale, "status"] = "stale"
    table.loc[stale, "problem"] = table.loc[stale, "scene"].map(problems)
    unusable += [_scene_row(scene, "failed", problem) for scene, problem in problems.items()
                 if scene not in seen]
    if unusable:
        rows = pd.DataFrame(unusable, columns=list(SUMMARY_COLUMNS))
        if by_run:
            rows = rows.assign(run=np.zeros(len(rows), dtype=np.int64))[list(table.columns)]
        table = pd.concat([table, rows], ignore_index=True) if len(table) else rows
    return table
