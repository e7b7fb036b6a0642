"""The cross-scene summary with one row per run: a multi-run scene's rows (from the first run,
as a single-run file is read) replaced by its runs' own, each with its run number.

The rows are those of :func:`dashpot.summary.summary_from_records`, built from each run's fits
stored under ``runs/<run>`` (``docs/hdf5-layout.md``); the other columns are unchanged.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["summary_by_run"]


def summary_by_run(table, paths):
    """The summary `table` with a column ``run`` after ``scene``, one row per run and model.

    Parameters
    ----------
    table : pandas.DataFrame
        :func:`dashpot.summary.summary_from_files` of `paths` (columns
        :data:`dashpot.summary.SUMMARY_COLUMNS`).
    paths : sequence of str or os.PathLike
        The scene files it was built from, each named by its stem as in the table.

    Returns
    -------
    pandas.DataFrame
        ``run`` (int64): for a multi-run scene, its rows for each run (each run's own fits,
        selection and verdict; status and problem as the scene's); for a single-run scene
        the run number of its impacts (0 where the recording has no runs, and for scenes
        without a usable file). Row order: scenes as in `table`, runs in increasing number.
    """
    from .store import read_fit
    from .summary import summary_from_records

    runs_of = {}
    for path in paths:
        scene = Path(path).stem
        if scene not in set(table["scene"]):
            continue
        try:
            record = read_fit(path)
        except (OSError, RuntimeError, KeyError, ValueError, TypeError):
            continue  # already an "unreadable" row of the table
        runs_of[scene] = record
    parts = []
    for scene, rows in table.groupby("scene", sort=False):
        record = runs_of.get(scene)
        if record is None or "runs" not in record or rows["status"].iloc[0] not in (
                "ok", "stale"):
            impacts = None if record is None else record["impacts"]
            number = (int(impacts["run"].iloc[0]) if impacts is not None and len(impacts)
                      and "run" in impacts else 0)
            parts.append(rows.assign(run=number))
            continue
        for number, run in sorted(record["runs"].items()):
            view = {"attrs": {"verdict": run["attrs"].get("verdict", "")},
                    "fits": run["fits"], "selection": run["selection"],
                    **{key: run[key] for key in ("noise_fits", "noise_selection",
                                                 "noise_verdict") if key in run}}
            per_run = summary_from_records({scene: view})
            per_run["status"] = rows["status"].iloc[0]
            per_run["problem"] = rows["problem"].iloc[0]
            parts.append(per_run.assign(run=number))
    if not parts:
        return table.assign(run=np.zeros(len(table), dtype=np.int64))[_order(table)]
    out = pd.concat(parts, ignore_index=True)
    out["run"] = out["run"].astype(np.int64)
    return out[_order(table)]


def _order(table):
    """The table's columns with ``run`` after ``scene``."""
    columns = [column for column in table.columns if column != "run"]
    at = columns.index("scene") + 1
    return columns[:at] + ["run"] + columns[at:]
