"""One recording from file to fitted models: the steps the command line and the workflow share.

Nothing here prints: the steps are logged to the ``dashpot.analysis`` logger (INFO: impacts
read, each model fitted; the command line shows them with ``-v``).

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface".
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .bounces import DRAG_CORRECTION_COLUMNS, drag_correction
from .errors import InputError
from .plausibility import acceleration_problem, check_bounce_train
from .ingest import read_impacts
from .ingest.tables import is_impact_table, read_impact_table
from .scene import Scene

__all__ = ["read_impact_table", "scene_impacts", "recording_note", "analyze", "analyze_runs",
           "BounceDrag", "bounce_drag", "stored_bounces"]

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



def _noise_step(noise):
    """What the log line on the fits says of the noise model (`noise`: True, False or
    "auto", which fits it only where the deterministic fits miss the data)."""
    if noise == "auto":
        return " and, if they miss the data (noise: auto), the fits under the noise model"
    return " and the fits under the noise model" if noise else ""


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

    logger.info("fitting %s%s", ", ".join(models), _noise_step(noise))
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
    # A cart fitted under free fall (or a ball under a cart's g_eff) misfits by orders of
    # magnitude: said beside the fits, where the measured speeds show it.
    problem = acceleration_problem(impacts, scene.driving_acceleration)
    if problem:
        logger.info("%s: %s", path, problem)
        impacts.attrs["notes"] = [*impacts.attrs.get("notes", []), problem]
    models = tuple(models or scene.models)
    noise = scene.noise if noise is None else noise
    per_run = len(models) + (len(dict.fromkeys(NOISE_LAWS + models)) if noise else 0)
    steps = len(parts) * per_run + (len(models) if several else 0)
    if progress is not None:
        progress(1, 1 + steps, f"{len(impacts)} impacts in {len(parts)} run(s)")
    report = _fit_reporter(steps, progress)

    logger.info("fitting %s%s%s", ", ".join(models), _noise_step(noise),
                f" to each of {len(parts)} runs and to all jointly" if several else "")
    try:
        runs_fit = fit_runs(impacts, scene, models, progress=report, noise=noise)
    except ValueError as error:
        raise InputError(path, str(error)) from None
    return impacts, runs_fit


@dataclass(frozen=True, eq=False)
class BounceDrag:
    """The air drag a scene's bounce table is corrected with (:func:`bounce_drag`).

    Attributes
    ----------
    drag_constant : float
        k_d in 1/m.
    uncertainty : float
        1σ of k_d in 1/m (0 where it is taken as exact).
    effective_gravity : float
        g_eff in m/s² of the same fit (or the scene's).
    source : str
        Where k_d comes from: the name of a fit under the noise model, or "scene".
    note : str
        The same in plain words, with the numbers.
    timing_sigma : ndarray or None
        Total 1σ timing noise in s of each impact the fit used (``FitData.times``): the
        detector's σ with the jitter σ_j the same noise fit found; None for the scene's prior.
    """

    drag_constant: float
    uncertainty: float
    effective_gravity: float
    source: str
    note: str
    timing_sigma: np.ndarray | None = None


def _estimate(fit, name):
    """(value, 1σ) of a fit's estimate, or None where it has none (or a non-finite value)."""
    estimate = fit.estimates.get(name)
    if estimate is None or not math.isfinite(estimate.value):
        return None
    error = estimate.stderr
    return float(estimate.value), float(error) if error is not None and math.isfinite(error) \
        else 0.0


def bounce_drag(scene_fit):
    """The drag constant that corrects a scene's bounce table, or None where nothing gives one.

    Parameters
    ----------
    scene_fit : dashpot.fit.SceneFit

    Returns
    -------
    BounceDrag or None
        Of the fits under the noise model that fitted a drag constant ``k_d`` (the drag rung
        ``constant+drag``; every fit where the scene gives the ball's mass and diameter): the
        selected one if it carries k_d, else the one of lowest BIC among them (the note then
        says so). Without such a fit, the scene's prior k_d
        (:attr:`dashpot.scene.Scene.drag`, from mass, diameter, C_d and air density); None
        where the scene models no drag either. g_eff is the same fit's where it fitted one,
        else the scene's driving acceleration; the timing noise is the same fit's.
    """
    carrying = {name: fit for name, fit in (scene_fit.noise_results or {}).items()
                if fit.success and _estimate(fit, "k_d") is not None}
    if carrying:
        table = scene_fit.noise_selection
        selected = ([] if table is None or "selected" not in table else
                    list(table["model"][table["selected"].to_numpy(bool)]))
        if selected and selected[0] in carrying:
            name, why = selected[0], "the selected fit under the noise model"
        else:
            name = min(carrying, key=lambda key: carrying[key].bic)
            why = ("the fit of lowest BIC among those under the noise model with air drag; "
                   + (f"the selected fit, {selected[0]}, has none" if selected else
                      "no fit was selected"))
        fit = carrying[name]
        value, error = _estimate(fit, "k_d")
        gravity = _estimate(fit, "g_eff")
        gravity = gravity[0] if gravity is not None else float(scene_fit.data.g)
        source, origin = name, f"{name} ({why})"
        timing_sigma = np.asarray(fit.timing_sigma, dtype=float)
        timing = f"the timing noise {name} fitted (the detector's σ with its jitter σ_j)"
    else:
        drag = scene_fit.scene.drag
        if drag is None:
            return None
        value = drag.drag_constant.value
        error = drag.drag_constant.uncertainty or 0.0
        gravity = drag.effective_gravity.value
        source, origin = "scene", "the scene's prior (ball mass, diameter, C_d, air density)"
        timing_sigma, timing = None, "the timing uncertainties the fits used"
    note = (f"restitution_corrected: ε corrected for air drag with k_d = {value:.4g} ± "
            f"{error:.2g} 1/m of {origin}, g_eff = {gravity:.6g} m/s², contact duration 0; "
            f"its uncertainty from {timing}, k_d's share apart "
            f"(restitution_corrected_drag_uncertainty)")
    return BounceDrag(drag_constant=value, uncertainty=error, effective_gravity=gravity,
                      source=source, note=note, timing_sigma=timing_sigma)


def stored_bounces(scene_fit):
    """The bounce table a scene file stores: the fit's, with the drag-corrected ε where the
    scene has a drag constant (:func:`bounce_drag`).

    Parameters
    ----------
    scene_fit : dashpot.fit.SceneFit

    Returns
    -------
    pandas.DataFrame
        ``scene_fit.data.bounces`` (its columns unchanged: ``rebound_speed`` stays the
        gravity estimate g_eff·T_n/2 that goes with the uncorrected ratio ``restitution``),
        with the columns :data:`dashpot.bounces.DRAG_CORRECTION_COLUMNS` of
        :func:`dashpot.bounces.drag_correction` added where a drag constant is known;
        ``attrs`` then hold ``drag`` (the :class:`BounceDrag`) and its note appended to
        ``notes``.

    Notes
    -----
    The timing errors are those of the noise fit k_d comes from (the detector's σ with the
    jitter σ_j it fitted: a one-sample σ alone is several times too small on real audio), else
    those the deterministic fits used; an impact the fit left out (spurious, inferred) or an
    unknown σ gives NaN uncertainties to the values involving it. The contact duration is
    taken as 0, as in the uncorrected ratios and the restitution laws' flights.
    """
    table = scene_fit.data.bounces.copy()
    drag = bounce_drag(scene_fit)
    if drag is None or table.empty:
        return table
    data = scene_fit.data
    times = np.append(table["start_time"].to_numpy(float),
                      table["start_time"].iloc[-1] + table["interval"].iloc[-1])
    sigma = np.full(times.size, np.nan)
    kept = np.ones(times.size, bool)
    kept[np.asarray(data.excluded, dtype=int)] = False
    if drag.timing_sigma is not None and drag.timing_sigma.size == kept.sum():
        sigma[kept] = drag.timing_sigma
    elif data.sigma_known and kept.sum() == np.size(data.sigma):
        sigma[kept] = data.sigma
    corrected = drag_correction(times, drag.effective_gravity, drag.drag_constant,
                                time_uncertainty=sigma, drag_uncertainty=drag.uncertainty)
    for name in DRAG_CORRECTION_COLUMNS:
        table[name] = corrected[name]
    table.attrs["notes"] = [*table.attrs.get("notes", []), drag.note]
    table.attrs["drag"] = drag
    return table
