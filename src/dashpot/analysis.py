"""One recording from file to fitted models: the steps the command line and the workflow share.

Nothing here prints: the steps are logged to the ``dashpot.analysis`` logger (INFO: impacts
read, each model fitted; the command line shows them with ``-v``).

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface".
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

from .errors import InputError
from .plausibility import check_bounce_train
from .ingest import read_impacts
from .ingest.tables import is_impact_table, read_impact_table
from .scene import Scene

__all__ = ["read_impact_table", "scene_impacts", "recording_note", "analyze", "analyze_runs"]

logger = logging.getLogger(__name__)


def scene_impacts(path, scene=None):
    """Impact table of a recording (any reader) or of an impact table already extracted.

    Parameters
    ----------
    path : str or os.PathLike
    scene : Scene, optional
        Its ``sensor`` and ``reader`` options choose and configure the reader of a recording.

    Returns
    -------
    pandas.DataFrame

    Notes
    -----
    An impact table written by ``dashpot impacts`` is read as an impact table whatever the
    scene's ``sensor`` says: the sensor describes the scene's recording, from which the table
    was made (``dashpot impacts rec.wav -o imp.csv`` then ``dashpot fit imp.csv --scene
    scene.yaml``).
    """
    scene = scene or Scene()
    if is_impact_table(path):
        impacts = read_impact_table(path)
        if scene.sensor is not None:
            impacts.attrs["notes"].append(
                f"read as an impact table; the scene's sensor '{scene.sensor}' describes the "
                f"recording it was made from")
    else:
        impacts = read_impacts(path, kind=scene.sensor, **scene.reader)
    logger.info("%s: %d impacts (%s)", path, len(impacts), impacts.attrs.get("sensor", "?"))
    for note in impacts.attrs.get("notes", []):
        logger.debug("%s: %s", path, note)
    return impacts


def recording_note(path, scene):
    """Plain-words note when the file analysed is not the scene's ``recording``, else None.

    Parameters
    ----------
    path : str or os.PathLike
        The file actually read (a recording or an impact table).
    scene : Scene or None

    Returns
    -------
    str or None
    """
    if scene is None or scene.recording is None:
        return None
    if Path(path).resolve() == Path(scene.recording).resolve():
        return None
    return (f"fitted {path}; the scene's recording {scene.recording} was not read (the HDF5 "
            f"file records {Path(path).name} as input_file)")



def _fit_reporter(steps, progress):
    """Called with each fit's name as it is done: logs it with the CPU time so far and passes
    step 2 ... 1 + `steps` of 1 + `steps` to `progress` (step 1 is reading the impacts)."""
    done = iter(range(2, 2 + steps))
    started = time.process_time()

    def report(model):
        step = next(done, steps + 1)
        logger.info("fitted %s (%d of %d, %.2g s of CPU so far)", model, step - 1, steps,
                    time.process_time() - started)
        if progress is not None:
            progress(step, 1 + steps, f"fitted {model}")

    return report

def analyze(path, scene=None, *, models=None, progress=None, noise=None):
    """Impacts and every requested model fitted, for one recording.

    Parameters
    ----------
    path : str or os.PathLike
        Recording or impact table.
    scene : Scene, optional
    models : sequence of str, optional
    progress : callable, optional
        Called as ``progress(step, total, text)`` after reading the impacts and after each
        model's fit (``total`` = 1 + number of models, and of the noise fits where made).
    noise : bool, optional
        Also fit under the noise model (:func:`dashpot.fit.fit_scene`); default the scene's
        ``noise`` key.

    Returns
    -------
    impacts : pandas.DataFrame
    scene_fit : dashpot.fit.SceneFit

    Raises
    ------
    InputError
        The recording cannot be read or holds too few impacts to fit.

    Notes
    -----
    Of a multi-run recording (Capstone's "Run #1, Run #2, ...", phyphox's several runs, an
    impact table with a ``run`` column) only the first run is fitted here (the data's notes
    say so): :func:`analyze_runs` fits every run, and the runs jointly.
    """
    from .fit import fit_scene
    from .fit.settings import NOISE_LAWS

    impacts = scene_impacts(path, scene)
    if "run" in impacts and impacts["run"].nunique() > 1:
        logger.warning("%s: %d runs; fitted the first only (analyze_runs fits every run, and "
                       "the runs jointly)", path, impacts["run"].nunique())
    if len(impacts) < 3:
        raise InputError(path, f"only {len(impacts)} impact(s) found; fitting needs three")
    check_bounce_train(impacts, path)  # random clicks or times are not fitted as bounces
    models = tuple(models or (scene or Scene()).models)
    noise = (scene or Scene()).noise if noise is None else noise
    steps = len(models) + (len(dict.fromkeys(NOISE_LAWS + models)) if noise else 0)
    if progress is not None:
        progress(1, 1 + steps, f"{len(impacts)} impacts")
    report = _fit_reporter(steps, progress)

    logger.info("fitting %s%s", ", ".join(models),
                " and the fits under the noise model" if noise else "")
    try:
        scene_fit = fit_scene(impacts, scene, models, progress=report, noise=noise)
    except ValueError as error:
        raise InputError(path, str(error)) from None
    return impacts, scene_fit


def analyze_runs(path, scene=None, *, models=None, progress=None, noise=None):
    """Impacts and every requested model fitted to every run of a recording, and jointly.

    Parameters
    ----------
    path : str or os.PathLike
        Recording or impact table; several runs where the reader gives a ``run`` column.
    scene : Scene, optional
    models : sequence of str, optional
    progress : callable, optional
        As in :func:`analyze`, counting the fits of every run and the joint fits.
    noise : bool, optional
        As in :func:`analyze`, for each run.

    Returns
    -------
    impacts : pandas.DataFrame
        Every run's impacts.
    runs_fit : dashpot.fit.RunsFit
        ``runs``: each run's own SceneFit (:func:`dashpot.fit.fit_scene` of its impacts
        alone); ``joint``: each model fitted to all runs at once, sharing ζ and ω0
        (:func:`dashpot.fit.fit_joint`; empty for one run). With one run, ``runs`` holds the
        fit :func:`analyze` makes.

    Raises
    ------
    InputError
        The recording cannot be read, or a run holds fewer than three impacts or is no bounce
        train (the message names the run).
    """
    from .fit.joint_fit import fit_runs, split_runs
    from .fit.settings import NOISE_LAWS

    scene = scene or Scene()
    impacts = scene_impacts(path, scene)
    parts = split_runs(impacts)
    several = len(parts) > 1
    for run, table in parts.items():
        where = f"run {run}: " if several else ""
        if len(table) < 3:
            raise InputError(path, f"{where}only {len(table)} impact(s) found; fitting needs "
                                   f"three")
        try:
            check_bounce_train(table, path)
        except InputError as error:
            raise InputError(path, where + error.problem) from None
    models = tuple(models or scene.models)
    noise = scene.noise if noise is None else noise
    per_run = len(models) + (len(dict.fromkeys(NOISE_LAWS + models)) if noise else 0)
    steps = len(parts) * per_run + (len(models) if several else 0)
    if progress is not None:
        progress(1, 1 + steps, f"{len(impacts)} impacts in {len(parts)} run(s)")
    report = _fit_reporter(steps, progress)

    logger.info("fitting %s%s%s", ", ".join(models),
                " and the fits under the noise model" if noise else "",
                f" to each of {len(parts)} runs and to all jointly" if several else "")
    try:
        runs_fit = fit_runs(impacts, scene, models, progress=report, noise=noise)
    except ValueError as error:
        raise InputError(path, str(error)) from None
    return impacts, runs_fit
