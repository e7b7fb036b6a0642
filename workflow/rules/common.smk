# Scenes of the workflow: folders of scenes_dir, entries of `scenes:` and synthetic scenes.
#
# Every scene is checked here, before any job is built from it, and the check never raises:
# a scene that cannot run (a reserved name, an unreadable or invalid scene.yaml, no recording
# or a missing one, an unreadable results/<scene>.h5) gets a single `broken_scene` job that
# fails with one line naming the file in results/logs/fit/<scene>.log, and the other scenes
# run. A broken scene is left out of the `scene` wildcard of every other rule, so whatever an
# earlier run made of it (results/<scene>.h5, its figures) is a plain file that no job owns:
# Snakemake, which deletes a job's outputs before running it, never touches it, and the
# summary keeps the scene's old rows, marked stale.
import os
import re
import shlex
import sys
from pathlib import Path

import yaml

from dashpot.batch import auto_chunk_size, chunks, plots_wanted
from dashpot.errors import InputError
from dashpot.provenance import source_fingerprint

# dashpot.pipeline (the scene schema), dashpot.summary (h5py) are imported where first used:
# every run, a no-op one too, starts by building this module, so it imports only what the
# scenes at hand need (a batch of synthetic scenes needs neither until results exist).


def _reserved_names():
    """Names a scene may not have: the folders and files of results/ other rules write.

    The config schema's list (one list for config keys and folder names), lower-cased:
    on a case-insensitive file system `Summary` is `summary`.
    """
    schema = Path(workflow.basedir) / "workflow" / "schemas" / "config.schema.yaml"
    names = yaml.safe_load(schema.read_text(encoding="utf-8"))["definitions"]["name"]["not"]
    return frozenset(name.lower() for name in names["enum"])


RESERVED_NAMES = _reserved_names()


def _scene_problem(name, scene_file, mapping):
    """A folder or config scene's (scene, None) if it can run, else (None, one-line problem)."""
    source = scene_file or f"config.yaml: scenes/{name}"
    if name.lower() in RESERVED_NAMES:
        return None, (f"{source}: the scene name {name!r} is reserved for the workflow's "
                      f"own outputs ({', '.join(sorted(RESERVED_NAMES))}): rename the scene")
    from dashpot.pipeline import workflow_scene

    try:
        scene = workflow_scene(name, scene_file=scene_file, mapping=mapping)
    except InputError as error:
        return None, str(error)
    except Exception as error:  # noqa: BLE001 - one scene must never stop the DAG
        return None, f"{source}: cannot be read ({type(error).__name__}: {error})"
    if not os.path.isfile(scene.recording):
        recording = os.path.normpath(scene.recording)
        return None, f"{recording}: no such file (the recording of {source})"
    return scene, None


def _entry(source, scene_file, recording, audio, problem=None):
    return {"source": source, "scene_file": scene_file, "recording": recording, "audio": audio,
            "problem": problem}


def _checked(name, source, scene_file, mapping):
    scene, problem = _scene_problem(name, scene_file, mapping)
    if scene is None:
        return _entry(source, scene_file, None, False, problem)
    from dashpot.pipeline import is_audio

    return _entry(source, scene_file, os.path.normpath(scene.recording), is_audio(scene))


def _collect_scenes():
    scenes = {}
    real = set(config.get("real_scenes", []))
    use_real = config.get("real_data", True)
    shared = config.get("shared_data", "../shared/data")
    if use_real and not os.path.isdir(shared):
        print(f"dashpot: {shared} not found: skipping the real recordings "
              f"({', '.join(sorted(real))}); set real_data: false to silence this",
              file=sys.stderr)
        use_real = False
    for scene_file in sorted(Path(config.get("scenes_dir", "data")).glob("*/scene.yaml")):
        name = scene_file.parent.name
        if name in real and not use_real:
            continue
        if "{" in name or "}" in name:  # would read as a wildcard in every path: no job
            print(f"dashpot: {scene_file}: skipped: a scene name may not hold braces",
                  file=sys.stderr)
            continue
        scenes[name] = _checked(name, "folder", str(scene_file), None)
    for name, mapping in config.get("scenes", {}).items():
        if name in scenes:
            raise ValueError(f"config.yaml: scene {name!r} is both a folder and a config entry")
        scenes[name] = _checked(name, "config", None, mapping)
    for name, spec in config.get("synthetic", {}).items():
        if name in scenes:
            raise ValueError(f"config.yaml: synthetic scene {name!r} has the name of another scene")
        # Its recording is written by its chunk (dashpot.batch), which knows its name.
        scenes[name] = _entry("synthetic", None, None, spec["kind"] == "audio")
    for name, scene in scenes.items():
        # A damaged result would be taken as up to date ("Nothing to be done") and break the
        # summary: the scene stops with a line saying so, and deleting the file recomputes it.
        result = f"results/{name}.h5"
        if scene["problem"] is None and os.path.exists(result):
            from dashpot.summary import scene_file_problem

            problem = scene_file_problem(result)
            if problem is not None:
                scene["problem"] = f"{problem}: delete it to compute the scene again"
    return scenes


def _last_fit_error(name, scene):
    """The error line of the scene's last fit if it failed and nothing changed since, or None.

    A fit that fails at run time (an unreadable recording) leaves its log with an ERROR line
    and either no results/<scene>.h5 or the earlier one, put back (see rule fit). Until the
    scene's inputs change, its fit is expected to fail again, so the summary does not wait
    for it (see `summary_input`). A log without an ERROR line (a killed job, or a fit that
    succeeded) is not a failure. The first line of a fit's log is "fit scene <name>"
    (dashpot.joblog and workflow/scripts/fit.py).
    """
    log = Path(f"results/logs/fit/{name}.log")
    if not log.is_file():
        return None
    inputs = [scene["scene_file"], scene["recording"]]
    if scene["source"] == "synthetic":
        inputs = [f"results/synthetic/{name}"]
    try:
        logged = log.stat().st_mtime
        if any(os.path.getmtime(path) > logged for path in inputs
               if path and os.path.exists(path)):
            return None
        lines = log.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return None
    if not lines or not lines[0].endswith(f" INFO fit scene {name}"):
        return None  # the log of broken_scene (same path), not of a fit
    errors = [line.split(" ERROR ", 1)[1] for line in lines if " ERROR " in line]
    return f"its last fit failed: {errors[-1]}" if errors else None


def earlier_result(name):
    """A scene's results/<scene>.h5 from an earlier run, or "" (none, or the name is
    reserved: results/summary.h5 is the summary's, not a scene's)."""
    path = f"results/{name}.h5"
    return path if name.lower() not in RESERVED_NAMES and os.path.exists(path) else ""


SCENES = _collect_scenes()
BROKEN_SCENES = {name: scene["problem"] for name, scene in SCENES.items() if scene["problem"]}
RUNNABLE_SCENES = [name for name in SCENES if name not in BROKEN_SCENES]
FAILED_FITS = {name: error for name in RUNNABLE_SCENES
               if (error := _last_fit_error(name, SCENES[name]))}
for _name in FAILED_FITS:
    # Its earlier result, put back after the failed fit, is newer than the inputs and so is
    # not fitted again until they change: say so on every run, not only in the summary.
    if earlier_result(_name):
        print(f"dashpot: results/{_name}.h5 is stale: {FAILED_FITS[_name]} (kept from an "
              f"earlier run until the scene's recording or scene.yaml changes)", file=sys.stderr)
AUDIO_SCENES = [name for name in RUNNABLE_SCENES if SCENES[name]["audio"]]
SYNTHETIC_SCENES = [name for name in RUNNABLE_SCENES if SCENES[name]["source"] == "synthetic"]
SCENE_FIGURES = ["intervals", "restitution", "selection"]
# Scenes are fitted in chunks, one process per chunk (dashpot.batch): `chunk_size` scenes,
# "auto" 1 for a handful of scenes and up to 50 for hundreds. Membership is a hash of the
# name, so adding a scene reruns one chunk, in which the up-to-date scenes are skipped.
CHUNK_SIZE = config.get("chunk_size", "auto")
CHUNK_SIZE = auto_chunk_size(len(RUNNABLE_SCENES)) if CHUNK_SIZE == "auto" else int(CHUNK_SIZE)
CHUNKS = chunks(RUNNABLE_SCENES, CHUNK_SIZE)
CHUNK_OF = {name: chunk for chunk, names in CHUNKS.items() for name in names}
# Per-scene figures: on by default up to dashpot.batch.PLOTS_LIMIT scenes.
SCENE_PLOTS = plots_wanted(config.get("scene_plots", "auto"), len(RUNNABLE_SCENES))
THEORY_FIGURES = ["contact_time", "restitution", "critical_speed", "restitution_vs_speed"]
# The dashpot source the jobs compute with (a digest of its modules and scene schema): a
# parameter of every rule that computes with the library. Snakemake sees a rule's params and
# script, not the library it imports; a changed digest is a changed parameter, which reruns
# those rules (and so refits and redraws the scenes) on the next run.
DASHPOT_SOURCE = source_fingerprint()


def _names_pattern(names):
    return "|".join(re.escape(name) for name in names) or "(?!x)x"


# Only runnable scenes match {scene} in the rules that make or read a scene's results;
# `broken_scene` sets its own constraint (the broken ones).
wildcard_constraints:
    scene=_names_pattern(RUNNABLE_SCENES),


def scene_inputs(name):
    """A scene's input files: its scene.yaml and its recording (none for a synthetic scene,
    which its chunk writes from its config entry, a parameter of the chunk).

    The recording exists (a scene whose recording is missing is broken, see above), so it
    is demanded: a changed recording reruns the scene's chunk.
    """
    scene = SCENES[name]
    if scene["source"] == "synthetic":
        return []
    return [path for path in (scene["scene_file"], scene["recording"]) if path]


def chunk_input(wildcards):
    """The input files of every scene of a chunk."""
    return [path for name in CHUNKS[wildcards.chunk] for path in scene_inputs(name)]


def figure_paths(name):
    """A scene's figure files (PNG and PDF; an audio scene's detection figure too)."""
    figures = SCENE_FIGURES + (["detection"] if SCENES[name]["audio"] else [])
    return [f"results/plots/{name}/{figure}.{ext}" for figure in figures for ext in ("png", "pdf")]


def scene_task(name):
    """What a chunk's process needs of one scene (dashpot.batch.process_chunk)."""
    scene = SCENES[name]
    synthetic = scene["source"] == "synthetic"
    folder = f"results/synthetic/{name}"
    return {
        "name": name, "source": scene["source"], "scene_file": scene["scene_file"],
        "scene_input": folder if synthetic else scene["scene_file"],
        "recording": scene["recording"], "audio": scene["audio"],
        "mapping": config.get("scenes", {}).get(name),
        "spec": config["synthetic"][name] if synthetic else None,
        "folder": folder if synthetic else None,
        "truth": f"{folder}/truth.json" if synthetic else None,
        "uncertainty": config.get("uncertainty", ["covariance"]),
        "noise": config.get("noise", False),
        "result": f"results/{name}.h5", "done": f"results/logs/fit/{name}.fingerprint",
        "truth_csv": f"results/truth/{name}.csv" if synthetic else None,
        "figures": figure_paths(name), "log": f"results/logs/fit/{name}.log",
        "truth_log": f"results/logs/truth_table/{name}.log",
        "plots_log": f"results/logs/scene_plots/{name}.log",
    }


def chunk_tasks(wildcards):
    return [scene_task(name) for name in CHUNKS[wildcards.chunk]]


def chunk_folder(wildcards):
    """The staging folder of a scene's chunk (the output of its fit_chunk job)."""
    return f"results/chunks/fit/{CHUNK_OF[wildcards.scene]}"


def staged(wildcards):
    """Where the chunk put the scene's new files."""
    return f"{chunk_folder(wildcards)}/{wildcards.scene}"


def publish(step, what):
    """The shell command of a per-scene step (workflow/scripts/publish.sh): move the scene's
    files of this `step` (fit, truth, plots) from its chunk's staging folder into place
    (rename: atomic), or fail with the scene's error (on standard error and in the step's
    log). A file the chunk did not redo (up to date) is kept as it is."""
    # Relative to the working directory (the Snakefile's folder in every run here), so that
    # the command, which Snakemake compares with the last run's, stays the same in a copy.
    script = os.path.relpath(Path(workflow.basedir) / "workflow" / "scripts" / "publish.sh")
    return (f"bash {shlex.quote(script)} {step} {shlex.quote(what)} {{params.staged:q}} "
            "{log:q} {wildcards.scene:q} {output:q}")


def summary_input(wildcards):
    """The scene files the summary reads and waits for.

    Those of runnable scenes, which their fits make, except a scene whose last fit failed
    and whose inputs have not changed since: its fit runs again, but the summary does not
    wait for it, so that while one scene is broken the summary is still rebuilt for the
    others (it lists that scene as failed, or as stale with its earlier results, which
    `stale_results` passes on). A broken scene's earlier file, if there is one, is read as
    it is (no rule makes it). Only in the run where a fit fails for the first time does the
    summary wait (and, with --keep-going, is left for the next run).
    """
    names = [name for name in RUNNABLE_SCENES if name not in FAILED_FITS]
    names += [name for name in BROKEN_SCENES if earlier_result(name)]
    return [f"results/{name}.h5" for name in SCENES if name in names]


def stale_results(wildcards):
    """The earlier results/<scene>.h5 of scenes whose last fit failed (read, not waited for:
    as parameters, not inputs, since their fit job would make them)."""
    return [path for name in FAILED_FITS if (path := earlier_result(name))]


def summary_problems(wildcards):
    """Scene -> why it is not up to date (one line), for the summary's status column."""
    return {**BROKEN_SCENES, **FAILED_FITS}


def broken_scene_problem(wildcards):
    """The one-line problem of a broken scene."""
    return BROKEN_SCENES[wildcards.scene]


def all_outputs():
    """Every file of a full run: scene files, summary, synthetic scenes' truth tables,
    figures, theory; broken scenes' jobs."""
    outputs = expand("results/{scene}.h5", scene=RUNNABLE_SCENES)
    outputs += expand("results/logs/fit/{scene}.broken", scene=BROKEN_SCENES)
    outputs += ["results/summary.h5", "results/summary.csv"]
    outputs += expand("results/truth/{scene}.csv", scene=SYNTHETIC_SCENES)
    if SCENE_PLOTS:
        outputs += [path for name in RUNNABLE_SCENES for path in figure_paths(name)]
    outputs += expand("results/theory/{figure}.{ext}", figure=THEORY_FIGURES,
                      ext=["png", "pdf"])
    outputs += ["results/theory/critical_velocity.csv", "results/theory/restitution_vs_zeta.csv"]
    return outputs
