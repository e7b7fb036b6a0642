"""One recording from file to fitted models: the steps the command line and the workflow share.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface".
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .errors import InputError
from .ingest import IMPACT_COLUMNS, read_impacts
from .scene import Scene

__all__ = ["read_impact_table", "scene_impacts", "analyze"]


def read_impact_table(path):
    """Read an impact table written by ``dashpot impacts`` (CSV with the ingest columns).

    Raises
    ------
    InputError
        Unreadable file, no ``time`` column, or times that are missing, not finite or not
        increasing (row named).
    """
    try:
        table = pd.read_csv(path)
    except (OSError, ValueError, UnicodeDecodeError) as error:
        raise InputError(path, f"cannot read the impact table ({error})") from None
    if "time" not in table:
        raise InputError(path, "no 'time' column: write it with `dashpot impacts`")
    times = pd.to_numeric(table["time"], errors="coerce").to_numpy(float)
    bad = np.flatnonzero(~np.isfinite(times))
    if bad.size:
        raise InputError(path, "impact time missing or not a number", row=int(bad[0]) + 1)
    backwards = np.flatnonzero(np.diff(times) <= 0)
    if backwards.size:
        raise InputError(path, "impact times must increase", row=int(backwards[0]) + 2)
    for column in IMPACT_COLUMNS:
        if column not in table:
            table[column] = 0 if column == "run" else np.nan
    table.attrs.update({"source": str(path), "sensor": "impact table", "notes": []})
    return table


def _is_impact_table(path):
    """True for a CSV whose header holds the ingest columns ``time`` and ``time_uncertainty``."""
    if Path(path).suffix.lower() != ".csv":
        return False
    try:
        with open(path, encoding="utf-8", errors="replace") as handle:
            header = handle.readline().strip().split(",")
    except OSError:
        return False
    return {"time", "time_uncertainty"} <= set(header)


def scene_impacts(path, scene=None):
    """Impact table of a recording (any reader) or of an impact table already extracted.

    Parameters
    ----------
    path : str or os.PathLike
    scene : Scene, optional
        Its ``sensor`` and ``reader`` options choose and configure the reader.

    Returns
    -------
    pandas.DataFrame
    """
    scene = scene or Scene()
    if scene.sensor is None and _is_impact_table(path):
        return read_impact_table(path)
    return read_impacts(path, kind=scene.sensor, **scene.reader)


def analyze(path, scene=None, *, models=None, progress=None):
    """Impacts and every requested model fitted, for one recording.

    Parameters
    ----------
    path : str or os.PathLike
        Recording or impact table.
    scene : Scene, optional
    models : sequence of str, optional
    progress : callable, optional
        Called as ``progress(step, total, text)`` after reading the impacts and after each
        model's fit (``total`` = 1 + number of models).

    Returns
    -------
    impacts : pandas.DataFrame
    scene_fit : dashpot.fit.SceneFit

    Raises
    ------
    InputError
        The recording cannot be read or holds too few impacts to fit.
    """
    from .fit import fit_scene

    impacts = scene_impacts(path, scene)
    if len(impacts) < 3:
        raise InputError(path, f"only {len(impacts)} impact(s) found; fitting needs three")
    models = tuple(models or (scene or Scene()).models)
    report = None
    if progress is not None:
        done = iter(range(2, 2 + len(models)))
        progress(1, 1 + len(models), f"{len(impacts)} impacts")

        def report(model):
            progress(next(done), 1 + len(models), f"fitted {model}")
    try:
        scene_fit = fit_scene(impacts, scene, models, progress=report)
    except ValueError as error:
        raise InputError(path, str(error)) from None
    return impacts, scene_fit
