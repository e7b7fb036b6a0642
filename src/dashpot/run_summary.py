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


def summary_by_run(table, paths, records=None):
    """The summary `table` with a column ``run`` after ``scene``, one row per run and model.

    Parameters
    ----------
    table : pandas.DataFrame
        :func:`dashpot.summary.summary_from_files` of `paths` (columns
        :data:`dashpot.summary.SUMMARY_COLUMNS`).
    paths : sequence of str or os.PathLike
        The scene files it was built from, each named by its stem as in the table.
    records : dict of str -> dict, optional
        Scene -> the file already read (:func:`dashpot.summary.read_summary_record` or
        :func:`dashpot.store.read_fit`); else each file of a scene in the table is read.

    Returns
    -------
    pandas.DataFrame
        ``run`` (int64): for a multi-run scene, its rows for each run (each run's own fits,
        selection and verdict; status and problem as the scene's); for a single-run scene
        the run number of its impacts (0 where the recording has no runs, and for scenes
        without a usable file). Row order: scenes as in `table`, runs in increasing number.
        Linear in the rows: a multi-run scene's rows are the only ones rebuilt.
    """
    from .summary import read_summary_record, summary_from_records

    scenes = list(pd.unique(table["scene"]))
    if records is None:
        wanted, records = set(scenes), {}
        for path in paths:
            scene = Path(path).stem
            if scene not in wanted:
                continue
            try:
                records[scene] = read_summary_record(path)
            except (OSError, RuntimeError, KeyError, ValueError, TypeError):
                continue  # already an "unreadable" row of the table
    status = table.groupby("scene", sort=False)["status"].first()
    number, per_run = {}, {}
    for scene in scenes:
        record = records.get(scene)
        if record is not None and "runs" in record and status[scene] in ("ok", "stale"):
            per_run[scene] = record
            continue
        impacts = None if record is None else record["impacts"]
        number[scene] = (int(impacts["run"].iloc[0]) if impacts is not None and len(impacts)
                         and "run" in impacts else 0)
    out = table[~table["scene"].isin(list(per_run))]
    out = out.assign(run=out["scene"].map(number).fillna(0).astype(np.int64))
    if per_run:
        parts = [out]
        for scene, record in per_run.items():
            rows = table[table["scene"] == scene]
            for run_number, run in sorted(record["runs"].items()):
                view = {"attrs": {"verdict": run["attrs"].get("verdict", "")},
                        "fits": run["fits"], "selection": run["selection"],
                        **{key: run[key] for key in ("noise_fits", "noise_selection",
                                                     "noise_verdict") if key in run}}
                rows_of_run = summary_from_records({scene: view})
                rows_of_run["status"] = rows["status"].iloc[0]
                rows_of_run["problem"] = rows["problem"].iloc[0]
                parts.append(rows_of_run.assign(run=run_number))
        out = pd.concat(parts, ignore_index=True)
        # Back into the table's scene order (stable: runs stay in increasing order).
        order = {scene: position for position, scene in enumerate(scenes)}
        out = out.iloc[np.argsort(out["scene"].map(order).to_numpy(), kind="stable")]
    out = out.reset_index(drop=True)
    out["run"] = out["run"].astype(np.int64)
    return out[_order(table)]


def _order(table):
    """The table's columns with ``run`` after ``scene``."""
    columns = [column for column in table.columns if column != "run"]
    at = columns.index("scene") + 1
    return columns[:at] + ["run"] + columns[at:]
