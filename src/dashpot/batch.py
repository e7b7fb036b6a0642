"""Workflow scenes fitted in chunks: one process fits several scenes, each to its own files.

Starting Python and importing the fitting stack costs seconds, a small scene's fit a tenth
of that; the workflow therefore hands each job a *chunk* of scenes (:func:`chunks`). The job
(:func:`process_chunk`) works through its scenes one by one, each under its own log, into a
staging folder; the workflow's per-scene steps then move each scene's files into place (a
rename, atomic) or report the scene's error. So a scene that fails does so alone: the others
of its chunk are written, and the failed scene's earlier results are left as they were.

Chunk membership is a hash of the scene's name, so adding a scene changes one chunk only;
within a chunk that runs again, a scene whose result is up to date (the same inputs, the same
settings, the same dashpot source, see :func:`scene_fingerprint`) is not fitted again.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import tempfile
import zlib
from dataclasses import replace
from pathlib import Path

__all__ = ["SMALL_BATCH", "LARGEST_CHUNK", "PLOTS_LIMIT", "auto_chunk_size", "chunks",
           "plots_wanted", "scene_fingerprint", "process_chunk", "fit_scene"]

SMALL_BATCH = 8
"""Scenes up to which every scene is its own chunk (one job each, as without chunks)."""

LARGEST_CHUNK = 150
"""Largest automatic chunk size: a chunk's scenes run one after the other in one process.
Each chunk pays Python's start-up once (about 1.5 s, a dozen small scenes' fits); 1,000
scenes make 8 chunks, few enough for that and enough to keep two cores busy to the end."""

PLOTS_LIMIT = 100
"""Scenes up to which per-scene figures are drawn by default (``scene_plots: auto``)."""

FIGURES = ("intervals", "restitution", "selection")
"""The figures of every scene (an audio scene also has ``detection``)."""


def auto_chunk_size(count):
    """Scenes per chunk for `count` scenes: 1 up to :data:`SMALL_BATCH`, then half of the
    scenes (two jobs keep two cores busy, each paying the start-up once), at most
    :data:`LARGEST_CHUNK`."""
    if count <= SMALL_BATCH:
        return 1
    return min(LARGEST_CHUNK, math.ceil(count / 2))


def chunks(names, size):
    """Chunk name -> its scenes (in the order of `names`).

    With `size` 1 every scene is its own chunk, ``scene-<name>``. Otherwise a scene goes to
    bucket ``crc32(name) mod n`` of ``n`` buckets, ``n`` the power of two at or above
    ``len(names) / size`` (so chunks hold `size` scenes or fewer on average): its chunk
    depends on its name and on ``n`` only, and adding a scene changes one chunk (all of them
    only where ``n`` doubles). Chunk names are ``<i>of<n>``; empty buckets are left out.
    """
    names = list(names)
    if size <= 1:
        return {f"scene-{name}": [name] for name in names}
    count = 1 << max(0, math.ceil(math.log2(max(1, math.ceil(len(names) / size)))))
    width = len(str(count - 1))
    buckets = {}
    for name in names:
        index = zlib.crc32(name.encode("utf-8")) % count
        buckets.setdefault(f"{index:0{width}d}of{count}", []).append(name)
    return dict(sorted(buckets.items()))


def plots_wanted(setting, count):
    """Whether per-scene figures are drawn: `setting` true/false, or ``"auto"`` (up to
    :data:`PLOTS_LIMIT` scenes)."""
    if setting == "auto":
        return count <= PLOTS_LIMIT
    return bool(setting)


def _stat(path):
    try:
        info = os.stat(path)
    except OSError:
        return None
    return [info.st_size, info.st_mtime_ns]


def scene_fingerprint(task):
    """A digest of what a scene's result depends on: its settings, its input files and the
    code.

    Parameters
    ----------
    task : dict
        A scene of a chunk (:func:`process_chunk`): ``name``, ``source``, ``scene_file``,
        ``recording``, ``mapping``, ``spec`` (synthetic), ``truth``, ``uncertainty``,
        ``noise``.

    Returns
    -------
    str
        Hex SHA-256 over those settings, the size and modification time of the scene file
        and recording (not for a synthetic scene, whose recording this step writes from its
        ``spec``), the package version and the digest of the dashpot source running
        (:func:`dashpot.provenance.source_fingerprint`: a changed module refits the scene).
    """
    from . import __version__
    from .provenance import source_fingerprint

    keys = ("name", "source", "scene_file", "recording", "mapping", "spec", "truth",
            "uncertainty", "noise")
    state = {key: task.get(key) for key in keys}
    state["version"] = __version__
    state["source"] = source_fingerprint()
    if task.get("source") != "synthetic":
        state["files"] = [_stat(path) for path in (task.get("scene_file"), task.get("recording"))
                          if path]
    text = json.dumps(state, sort_keys=True, default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _simulate(task):
    """Write a synthetic scene's folder (recording, truth.json, scene.yaml), replacing it
    whole: built beside it under a temporary name, then renamed."""
    from .pipeline import write_synthetic_scene

    target = Path(task["folder"])
    target.parent.mkdir(parents=True, exist_ok=True)
    building = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{target.name}.",
                                     suffix=".partial"))
    old = None
    try:
        write_synthetic_scene(building, task["spec"], name=task["name"])
        if target.exists():
            old = target.with_name(f".{target.name}.{os.getpid()}.old")
            os.replace(target, old)
        os.replace(building, target)
    finally:
        shutil.rmtree(building, ignore_errors=True)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


def fit_scene(task, output, log, *, overwrite=False):
    """Fit one scene (every run, and the runs jointly) and write its HDF5 file.

    Parameters
    ----------
    task : dict
        The scene (see :func:`process_chunk`).
    output : str or os.PathLike
        The HDF5 file to write (atomically).
    log : logging.Logger
        Where the steps, each model's result, the verdict and the summary go.
    overwrite : bool, default False
        Replace `output` if it exists (:func:`dashpot.store.write_scene_fit`).

    Returns
    -------
    pandas.DataFrame or None
        The truth table of a synthetic scene (:func:`dashpot.truth.truth_comparison`).
    """
    from .analysis import analyze_runs
    from .cli import joint_text
    from .pipeline import workflow_scene
    from .store import write_scene_fit
    from .truth import truth_comparison

    name = task["name"]
    scene = workflow_scene(name, scene_file=task.get("scene_input"), mapping=task.get("mapping"))
    log.info("recording %s, sensor %s, models %s", scene.recording, scene.sensor,
             ", ".join(scene.models))
    methods = task.get("uncertainty")
    if methods and scene.uncertainty == ("covariance",):
        # The config's methods, for every scene whose scene.yaml does not choose its own.
        scene = replace(scene, uncertainty=tuple(dict.fromkeys(["covariance", *methods])))
    if task.get("noise") is True and scene.noise is not True:
        # The config's noise model, for every scene (its scene.yaml's default "auto", which
        # fits it only where the data need it, included).
        scene = replace(scene, noise=True)
    impacts, runs_fit = analyze_runs(scene.recording, scene)
    scene_fit = runs_fit.first  # the first run's, at the root of the file
    if len(runs_fit.runs) > 1:
        log.info("%d runs: each fitted on its own, and jointly", len(runs_fit.runs))
        for run, fit in runs_fit.runs.items():
            for model, result in fit.results.items():
                log.info("run %s, %s: %s", run, model, result.message)
        log.info("%s", joint_text(runs_fit, verbose=True))  # as `dashpot fit -v` prints it
    for note in impacts.attrs.get("notes", []):
        log.info("reader: %s", note)
    for model, fit in scene_fit.results.items():
        log.info("%s: %s", model, fit.message)
    log.info("verdict: %s", scene_fit.verdict)
    log.info("summary, with each model's notes:\n%s", scene_fit.report())  # as `dashpot fit`
    truth = truth_comparison(task["truth"], scene_fit) if task.get("truth") else None
    if truth is not None:
        for row in truth.itertuples():
            log.info("truth %s = %.6g %s: pull %.2f %s", row.parameter, row.truth, row.unit,
                     row.pull, row.note)
    write_scene_fit(output, scene_fit, impacts, input_path=scene.recording,
                    config={"models": list(scene_fit.results),
                            "scene_source": task.get("scene_input") or "config.yaml"},
                    truth=truth, runs=runs_fit, overwrite=overwrite)
    return truth


def _error_line(log_path):
    """The last ERROR line of a job log (without its time stamp), or None."""
    try:
        lines = Path(log_path).read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return None
    errors = [line.split(" ERROR ", 1)[1] for line in lines if " ERROR " in line]
    return errors[-1] if errors else None


def _step(log_path, job, work):
    """Run ``work(log)`` under the job log `log_path`; None, or the error's one line.

    A bad input or a failed write is one ERROR line in the log (and on standard error); any
    other error is logged with its traceback. Either way only this scene's step fails.
    """
    from .joblog import job_log

    try:
        with job_log(log_path, job) as log:
            work(log)
    except SystemExit:  # job_log's exit after logging an InputError or OSError
        return _error_line(log_path) or f"{job} failed"
    except Exception as error:  # noqa: BLE001 - one scene must never stop its chunk
        return f"{job} failed ({type(error).__name__}: {error}; see {log_path})"
    return None


def _write_error(path, text):
    Path(path).write_text(text.rstrip("\n") + "\n", encoding="utf-8")


def _figures_missing(task):
    return any(not os.path.exists(path) for path in task["figures"])


def process_chunk(tasks, staging, *, plots):
    """Fit each scene of a chunk into `staging`, one after the other; never raises for a scene.

    Parameters
    ----------
    tasks : list of dict
        The chunk's scenes. Keys: ``name``; ``source`` (folder, config, synthetic);
        ``scene_input`` (the scene.yaml or synthetic folder, or None), ``scene_file``,
        ``recording``, ``mapping`` (a config entry), ``spec`` and ``folder`` (synthetic:
        its config entry and results/synthetic/<scene>), ``truth`` (its truth.json or None),
        ``uncertainty``, ``noise`` (the config's); ``audio``; the final files: ``result``
        (results/<scene>.h5), ``done`` (where the published fingerprint lives), ``truth_csv``
        (synthetic), ``figures`` (PNG and PDF paths), ``log``, ``plots_log``.
    staging : str or os.PathLike
        The chunk's folder: each scene's new files go to ``<staging>/<name>/`` under the
        base names of their final paths, with ``fingerprint.json``; a scene's failure to
        ``fit.error``, ``truth.error`` or ``plots.error`` there (one line).
    plots : bool
        Draw the scene figures (and an audio scene's detection figure).

    Returns
    -------
    dict of str -> str
        Scene -> ``fitted``, ``up to date`` or ``failed``.
    """
    staging = Path(staging)
    staging.mkdir(parents=True, exist_ok=True)
    status = {}
    for task in tasks:
        status[task["name"]] = _process_scene(task, staging / task["name"], plots=plots)
    return status


def _process_scene(task, stage, *, plots):
    stage.mkdir(parents=True, exist_ok=True)
    name = task["name"]
    fingerprint = scene_fingerprint(task)
    done = Path(task["done"])
    current = (os.path.exists(task["result"]) and done.is_file()
               and done.read_text(encoding="utf-8").strip() == fingerprint
               # a synthetic scene's folder deleted since: simulated (the same) and refitted
               and (task.get("spec") is None or os.path.exists(task["truth"])))
    record_path = task["result"]
    truth = None
    if not current:
        staged = stage / Path(task["result"]).name
        outcome = {}

        def fit(log):
            if task.get("spec") is not None:
                _simulate(task)
                log.info("simulated %s", task["folder"])
            # The staging folder is the chunk's own (a file there is a leftover of an
            # interrupted run of this chunk, never a result): replaced.
            outcome["truth"] = fit_scene(task, staged, log, overwrite=True)

        error = _step(task["log"], f"fit scene {name}", fit)
        if error is not None:
            _write_error(stage / "fit.error", error)
            return "failed"
        (stage / "fingerprint.json").write_text(fingerprint + "\n", encoding="utf-8")
        record_path, truth = staged, outcome.get("truth")
    if task.get("truth_csv") and (not current or not os.path.exists(task["truth_csv"])):
        error = _step(task["truth_log"], f"truth against fit of {name}",
                      lambda log: _truth_csv(record_path, truth,
                                             stage / Path(task["truth_csv"]).name, log))
        if error is not None:
            _write_error(stage / "truth.error", error)
    if plots and (not current or _figures_missing(task)):
        error = _step(task["plots_log"], f"figures of {name}",
                      lambda log: _figures(task, record_path, stage, log))
        if error is not None:
            _write_error(stage / "plots.error", error)
    return "up to date" if current else "fitted"


def _recording(task):
    """The scene's recording: a synthetic scene's in its folder, named after its kind."""
    if task.get("spec") is None:
        return task["recording"]
    from .synth.scene import RECORDING_NAMES

    return str(Path(task["folder"]) / RECORDING_NAMES[task["spec"]["kind"]])


def _truth_csv(record_path, truth, target, log):
    from .truth import write_truth_csv

    if truth is None:
        from .store import read_fit

        truth = read_fit(record_path)["truth"]
    write_truth_csv(target, truth, overwrite=True)  # into the chunk's staging folder
    for row in truth.itertuples():
        log.info("%s: truth %.6g, fit %.6g ± %.2g %s, pull %.2f", row.parameter, row.truth,
                 row.value, row.stderr, row.unit, row.pull)


def _figures(task, record_path, stage, log):
    from .figures import detection_figure, load_record, scene_figures
    from .plots import save_figure

    record = load_record(record_path)
    figures = scene_figures(record)
    if task.get("audio"):
        figures["detection"] = detection_figure(record, _recording(task))
    for name, figure in figures.items():
        written = save_figure(figure, stage / name, overwrite=True)  # staging, as above
        log.info("drew %s", ", ".join(path.name for path in written))
