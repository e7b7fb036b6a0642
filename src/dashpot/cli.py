"""The dashpot command: one recording analysed without Snakemake.

Every failure is one line on standard error naming the file and the problem, with exit status
2, and no output file is left behind: outputs are written to a temporary name and renamed.
``-o -`` writes a table to standard output (the command's own lines then go to standard
error). ``-v`` shows what the library logs (the steps of an analysis, the notes on how each
fit was made), ``-q`` only errors. A run stopped by Ctrl-C, SIGTERM or SIGHUP removes what it
was writing and says so in one line, with exit status 128 + the signal's number.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import signal
import sys
import warnings
from contextlib import contextmanager
from pathlib import Path

from .errors import InputError, require_file

# The parser's choices and defaults, written out so that `dashpot --help` and a subcommand's
# argument errors import no scientific module (physics.models alone pulls in scipy.optimize);
# tests/test_batch.py checks them against dashpot.physics.MODELS and dashpot.scene.
MODELS = ("Ia", "Ib", "IIa", "IIb", "hybrid")  # as dashpot.physics.models.MODELS
STANDARD_GRAVITY = 9.80665  # m/s², as dashpot.scene.STANDARD_GRAVITY (CGPM 1901)

STDOUT = "-"  # the output name that means standard output
UNCERTAINTY_METHODS = ("covariance", "profile", "posterior")  # as dashpot.fit.settings
UNCERTAINTY_HELP = ("intervals of beta by these methods besides the covariance: profile "
                    "(profile likelihood) and posterior (emcee sampling; slow); as the scene "
                    "key uncertainty, which they replace")
NOISE_HELP = ("--noise also fits the restitution-law ladder and the models under "
              "bounce-to-bounce scatter and timing jitter, with their own selection (slower); "
              "--no-noise never does; default the scene key noise (auto: only where every "
              "deterministic fit misses the stated timing uncertainties)")


class _Console:
    """Where the command's own lines go: standard output, standard error where a table is
    written to standard output, nowhere under ``-q``."""

    def __init__(self, args):
        self.quiet = args.quiet
        self.verbose = args.verbose > 0
        self.stream = sys.stderr if getattr(args, "output", None) == STDOUT else sys.stdout

    def say(self, text):
        if not self.quiet and text:
            print(text, file=self.stream)

    def notes(self, notes):
        """One indented line per note (None and empty notes skipped)."""
        for note in notes:
            if note:
                self.say(f"  note: {note}")


def _cannot_write(path, error):
    """InputError for an output that could not be written (full disk, no permission, ...).

    h5py reports a failed write as RuntimeError (or an OSError whose text runs over several
    lines) rather than a plain OSError: the reason is the system's text for the error number
    where there is one, else the first line of the message.
    """
    number = getattr(error, "errno", None)
    lines = str(error).strip().splitlines()
    reason = os.strerror(number) if number else (lines[0] if lines else type(error).__name__)
    return InputError(path, f"cannot write the output ({reason})")


def _refuse_replacing_inputs(outputs, inputs):
    """Refuse to write any of `outputs` over one of `inputs` (under any spelling or link).

    Parameters
    ----------
    outputs : iterable of str or os.PathLike
        Every path the command is about to write (a file, or the folder of the figures).
    inputs : iterable of str or os.PathLike or None
        The files given, and the recording a scene names (None where there is none): the
        user's data, which a careless ``-o`` or scene name must never replace.

    Raises
    ------
    InputError
        Naming the first output that is an input.
    """
    sources = {Path(source).resolve() for source in inputs if source is not None}
    for output in outputs:
        if Path(output).resolve() in sources:
            raise InputError(output, "refusing to overwrite the input with the output")


def _refuse_existing_outputs(outputs, force):
    """Refuse to replace an output an earlier run (or the user) left, unless `force`.

    Called before any work is done, so that a refused run costs nothing and writes nothing:
    a result from an earlier run may be the only copy of hours of analysis, or a file of the
    user's that happens to carry the output's name.

    Parameters
    ----------
    outputs : iterable of str or os.PathLike
        Every path the command is about to write (a file, or the folder of the figures);
        ``-`` (standard output) is skipped.
    force : bool
        ``--force`` was given: existing outputs are replaced.

    Raises
    ------
    InputError
        Naming the first output that exists.
    """
    if force:
        return
    for output in outputs:
        if str(output) == STDOUT:
            continue
        path = Path(output)
        # A dangling link is an existing name too: replacing it would lose where it pointed.
        if path.exists() or path.is_symlink():
            raise InputError(path, "exists; pass --force to replace it")


def _check_outputs(outputs, inputs, force):
    """Refuse outputs that would replace an input (always), then existing ones (without
    ``--force``): before any work is done."""
    _refuse_replacing_inputs([output for output in outputs if str(output) != STDOUT], inputs)
    _refuse_existing_outputs(outputs, force)


def _write_csv_atomically(table, output, inputs, *, force):
    """Write `table` to `output` via a unique temporary file; never over one of the inputs.

    ``-`` writes to standard output. Floats are written in their shortest round-trip form, so
    they read back bit for bit (a fixed number of digits would round Unix-epoch times to whole
    seconds). Whether an existing `output` may be replaced is decided before the work, by
    :func:`_check_outputs`; without `force` (``--force``) an `output` that appeared since is
    refused all the same.
    """
    from .atomic import atomic_path

    if str(output) == STDOUT:
        table.to_csv(sys.stdout, index=False, lineterminator="\n")
        return
    output = Path(output)
    _refuse_replacing_inputs([output], inputs)
    try:
        with atomic_path(output, overwrite=force) as temporary:
            table.to_csv(temporary, index=False)
    except OSError as error:
        raise _cannot_write(output, error) from None


def _shown(output):
    """How an output is named in the command's lines."""
    return "standard output" if str(output) == STDOUT else str(output)


def _impacts(args, console):
    from .ingest import read_impacts

    _check_outputs([args.output], [args.recording], args.force)
    table = read_impacts(args.recording, kind=args.kind, flag_length=args.flag_length,
                         gate_distance=args.gate_distance, unit=args.unit,
                         bumper_position=args.bumper_position, track=args.track)
    _write_csv_atomically(table, args.output, [args.recording], force=args.force)
    notes = "; ".join(table.attrs.get("notes", []))
    console.say(f"{args.recording}: {len(table)} impacts -> {_shown(args.output)}"
                + (f" ({notes})" if notes else ""))


def _bounces(args, console):
    from .analysis import read_impact_table
    from .bounces import bounce_table
    from .ingest import AUDIO_SUFFIXES

    if Path(args.impacts).suffix.lower() in AUDIO_SUFFIXES:
        # A first try is often `bounces drop.wav`: say which command comes first, rather than
        # that the file is no table.
        raise InputError(args.impacts, f"a recording, not an impact table: find its impacts "
                                       f"first (dashpot impacts {args.impacts} -o impacts.csv)")
    _check_outputs([args.output], [args.impacts], args.force)
    impacts = read_impact_table(args.impacts)
    try:
        table = bounce_table(impacts, g=args.g, contact_duration=args.contact_duration,
                             drag_constant=args.drag_constant)
    except ValueError as error:
        raise InputError(args.impacts, str(error)) from None
    _write_csv_atomically(table, args.output, [args.impacts], force=args.force)
    flagged = int((table["flag"] != "ok").sum())
    console.say(f"{args.impacts}: {len(table)} bounces, {flagged} flagged -> "
                f"{_shown(args.output)}")
    # The table is written whatever the intervals look like (it is how one inspects them),
    # but a run that is no bounce train is said to be one, as `fit` refuses it.
    console.notes([*table.attrs.get("notes", []), *_not_bounce_trains(impacts)])


def _not_bounce_trains(impacts):
    """One warning per run of `impacts` whose intervals are not a ball bouncing to rest."""
    from .plausibility import NOT_A_BOUNCE_TRAIN, bounce_train_problem

    found = []
    for run, group in impacts.groupby("run", sort=False):
        problem = bounce_train_problem(group["time"].to_numpy(float),
                                       group["time_uncertainty"].to_numpy(float))
        if problem:
            where = f"run {run}: " if impacts["run"].nunique() > 1 else ""
            found.append(f"{where}{NOT_A_BOUNCE_TRAIN} ({problem}): `fit` refuses it")
    return found


def _refuse_standard_output(args, what):
    """`fit` and `analyze` write HDF5 files and figures, not a table: no ``-o -``."""
    if str(args.output) == STDOUT:
        raise InputError(STDOUT, f"standard output takes tables only (impacts, bounces); "
                                 f"give the {what} to write")


def _fit(args, console):
    from .analysis import analyze_runs, recording_note
    from .fit.data import flight_notes
    from .plausibility import acceleration_problem
    from .scene import Scene, load_scene
    from .store import write_scene_fit

    _refuse_standard_output(args, "HDF5 file")
    scene = load_scene(args.scene) if args.scene else Scene()
    _refuse_replacing_inputs([args.output], [args.impacts, args.scene, scene.recording])
    if Path(args.output).is_dir():
        raise InputError(args.output, "is a folder; give the HDF5 file to write")
    _refuse_existing_outputs([args.output], args.force)
    scene = _with_uncertainty(scene, args)
    impacts, runs_fit = analyze_runs(args.impacts, scene, models=args.models,
                                     noise=args.noise)
    scene_fit = runs_fit.first
    try:
        write_scene_fit(args.output, scene_fit, impacts, input_path=args.impacts,
                        config=_config(scene_fit), runs=runs_fit, overwrite=args.force)
    except (OSError, RuntimeError) as error:
        raise _cannot_write(args.output, error) from None
    console.say(f"{args.impacts}: {len(impacts)} impacts -> {args.output}")
    _say_reports(console, runs_fit, [recording_note(args.impacts, scene), *flight_notes(scene),
                                     acceleration_problem(impacts, scene.driving_acceleration),
                                     *impacts.attrs.get("warnings", [])])


def _analyze(args, console):
    import shutil
    import tempfile

    from tqdm import tqdm

    from .analysis import analyze_runs, recording_note
    from .atomic import atomic_path
    from .figures import load_record, save_scene_figures
    from .fit.data import flight_notes
    from .fit_report import parameter_table
    from .plausibility import acceleration_problem
    from .scene import Scene, load_scene
    from .store import write_scene_fit

    _refuse_standard_output(args, "folder")
    scene = load_scene(args.scene) if args.scene else None
    if args.recording is None:
        # The scene names its recording: a rerun needs nothing else.
        if scene is None:
            raise InputError("recording", "missing: give the recording to analyze, or a "
                                          "scene (--scene) that names one")
        if scene.recording is None:
            raise InputError(args.scene, "names no recording: give the recording to analyze")
        args.recording = str(scene.recording)
    recording = Path(args.recording)
    require_file(recording)
    scene = scene or Scene(name=recording.stem or "scene")
    scene = _with_uncertainty(scene, args)
    name = scene.name
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise InputError(out, "is a file; give the folder to write into")
    # The scene's name makes the output names: checked before the analysis, not after it.
    # The folder itself may exist (it holds other scenes' results); these three may not.
    _check_outputs([out / f"{name}.h5", out / f"{name}-parameters.csv", out / name],
                   [recording, args.scene, scene.recording], args.force)
    models = tuple(args.models or scene.models)
    with tqdm(total=1 + len(models) + 2, desc=recording.name, unit="step", leave=False,
              # -v logs each step on standard error: a bar there would break its lines.
              disable=True if console.quiet or console.verbose else None) as bar:
        def progress(step, total, text):
            bar.total = total + 2  # the fits (noise fits among them), then writing, figures
            bar.set_postfix_str(text)
            bar.update(step - bar.n)

        bar.set_postfix_str("finding impacts")
        impacts, runs_fit = analyze_runs(recording, scene, models=models, progress=progress,
                                         noise=args.noise)
        scene_fit = runs_fit.first
        bar.set_postfix_str("writing")
        created = not out.exists()
        try:
            out.mkdir(parents=True, exist_ok=True)
            # Staged in a hidden folder inside `out` (the same file system, so the final
            # renames are atomic) and renamed into place only once every file is complete.
            staging = Path(tempfile.mkdtemp(prefix=".dashpot-analyze-", dir=out))
        except OSError as error:
            raise _cannot_write(out, error) from None
        try:
            h5 = staging / f"{name}.h5"
            try:
                write_scene_fit(h5, scene_fit, impacts, input_path=recording,
                                config=_config(scene_fit), runs=runs_fit)
            except (OSError, RuntimeError) as error:
                raise _cannot_write(out / h5.name, error) from None
            parameters = f"{name}-parameters.csv"
            try:
                with atomic_path(staging / parameters) as temporary:
                    _parameter_rows(runs_fit, parameter_table).to_csv(temporary, index=False)
            except OSError as error:
                raise _cannot_write(out / parameters, error) from None
            bar.update(1)
            bar.set_postfix_str("figures")
            # The detection figure reads the sound itself: only where the impacts came from
            # the audio reader (an impact table made from it is no sound, whatever the
            # scene's sensor says).
            audio = impacts.attrs.get("sensor") == "audio"
            try:
                save_scene_figures(load_record(h5), staging / name,
                                   recording=recording if audio else None)
            except (OSError, RuntimeError) as error:
                raise _cannot_write(out / name, error) from None
            bar.update(1)
            _replace_figures(staging, out, name, force=args.force)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
            if created:
                _remove_if_empty(out)
    console.say(f"{recording}: {len(impacts)} impacts -> {out / f'{name}.h5'}, "
                f"{out / parameters}, figures in {out / name}/")
    _say_reports(console, runs_fit, [recording_note(recording, scene if args.scene else None),
                                     *flight_notes(scene),
                                     acceleration_problem(impacts, scene.driving_acceleration),
                                     *impacts.attrs.get("warnings", [])])


def _with_uncertainty(scene, args):
    """The scene with the methods of ``--uncertainty`` where given (they replace the scene's
    ``uncertainty`` key)."""
    from dataclasses import replace

    methods = getattr(args, "uncertainty", None)
    if not methods:
        return scene
    return replace(scene, uncertainty=tuple(dict.fromkeys(["covariance", *methods])))


def _parameter_rows(runs_fit, parameter_table):
    """The parameter table of every run (column ``run`` first where there are several), and
    the joint fits' rows (run ``joint``)."""
    import pandas as pd

    if len(runs_fit.runs) == 1:
        return parameter_table(runs_fit.first)
    tables = [parameter_table(fit).assign(run=str(run)) for run, fit in runs_fit.runs.items()]
    rows = []
    for model, fit in runs_fit.joint.items():
        for name, estimate in fit.estimates.items():
            rows.append({"model": model, "parameter": name, "value": estimate.value,
                         "stderr": estimate.stderr, "low68": estimate.low68,
                         "high68": estimate.high68, "low95": estimate.low95,
                         "high95": estimate.high95, "unit": estimate.unit,
                         "status": estimate.status, "run": "joint"})
    table = pd.concat(tables + [pd.DataFrame(rows)], ignore_index=True)
    return table[["run", *[column for column in table.columns if column != "run"]]]


def _say_reports(console, runs_fit, notes):
    """Each run's report (one run: as always), then the runs side by side with the joint
    fits."""
    from .fit_report import report_text

    several = len(runs_fit.runs) > 1
    for run, fit in runs_fit.runs.items():
        if several:
            console.say(f"run {run}:")
        console.say(report_text(fit, notes=notes, verbose=console.verbose))
    if several:
        console.say(joint_text(runs_fit, verbose=console.verbose))


def joint_text(runs_fit, verbose=False):
    """The contact parameters of each run's own fit beside those of the joint fit, per model.

    Parameters
    ----------
    runs_fit : dashpot.fit.RunsFit
    verbose : bool, default False
        Also the routine notes on how each joint fit was made (accuracy level, start values),
        as ``-v`` shows them for each run's fits.

    Returns
    -------
    str
        One line per model and quantity (ζ, ω0 in rad/s, β in 1/s, k in N/m where the mass
        is known): value ± 1σ of each run and of the joint fit, rounded to the uncertainty
        (:func:`dashpot.fit_report.format_measurement`), or "not determined" where the 1σ
        exceeds half the value (:data:`dashpot.fit.settings.WEAK_RELATIVE_ERROR`, as the fits'
        notes say); then the joint fits' notes
        (χ²/ν of the joint fit says whether the runs share one contact).
    """
    runs = list(runs_fit.runs)
    header = ["model", "quantity", *[f"run {run}" for run in runs], "joint (shared)"]
    lines = [header]

    from .fit.settings import WEAK_RELATIVE_ERROR
    from .fit_report import ROUTINE_PREFIXES, format_measurement

    def shown(estimate):
        if estimate is None:
            return "-"
        if not math.isfinite(estimate.stderr) or (
                estimate.stderr > WEAK_RELATIVE_ERROR * abs(estimate.value)):
            return f"{estimate.value:.3g} (not determined)"
        return format_measurement(estimate.value, estimate.stderr)

    for model, joint in runs_fit.joint.items():
        for name, label in (("zeta", "zeta"), ("omega0", "omega0 [rad/s]"),
                            ("beta", "beta [1/s]"), ("k", "k [N/m]")):
            if name not in joint.estimates and not any(
                    name in fit.results[model].estimates for fit in runs_fit.runs.values()):
                continue
            cells = []
            for fit in runs_fit.runs.values():
                result = fit.results[model]
                cells.append(shown(result.estimates.get(name)) if result.success
                             else "failed")
            cells.append(shown(joint.estimates.get(name)) if joint.success else "failed")
            lines.append([model, label, *cells])
    widths = [max(len(row[i]) for row in lines) for i in range(len(header))]
    text = ["runs side by side: each run's own fit, and the joint fit of all runs sharing "
            "zeta and omega0 (each run its own v0 and t0)"]
    text += ["  " + "  ".join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip()
             for row in lines]
    for model, joint in runs_fit.joint.items():
        text.append(f"  joint {model}: chi2/nu = {joint.redchi:.3g}"
                    + ("" if joint.success else f" ({joint.message})"))
        text += [f"    note: {note}" for note in joint.notes
                 if verbose or not note.startswith(ROUTINE_PREFIXES)]
    return "\n".join(text)


def _move_into_place(staging, out, *, force):
    """Rename every file under `staging` to the same place under `out` (same file system);
    over an existing file only with `force` (checked before the work: without it, a file that
    appeared since is refused, :func:`dashpot.atomic.move_into_place`)."""
    from .atomic import move_into_place, refuse_existing

    moves = [(source, out / source.relative_to(staging))
             for source in sorted(staging.rglob("*")) if source.is_file()]
    refuse_existing(*(target for _, target in moves), overwrite=force)  # before moving any
    try:
        for _, target in moves:
            if target.is_dir():
                raise IsADirectoryError(f"{target} is a folder")
            target.parent.mkdir(parents=True, exist_ok=True)
        for source, target in moves:
            move_into_place(source, target, overwrite=force)
    except OSError as error:
        raise _cannot_write(out, error) from None


def _replace_figures(staging, out, name, *, force):
    """Move the staged results into `out`, the figures' folder `name` as a whole.

    An earlier run's figures folder (there only with ``--force``) is set aside first and
    deleted once the new results are in place, so that no figure of that run the new one does
    not draw (a detection figure of a recording, where a table is analysed now) is left
    beside them as if it were theirs; if moving the new results fails, it is put back.
    """
    import shutil
    import tempfile

    figures = out / name
    aside = None
    if figures.is_dir() and not figures.is_symlink():
        aside = Path(tempfile.mkdtemp(prefix=".dashpot-replaced-", dir=out))
        os.replace(figures, aside / name)
    try:
        _move_into_place(staging, out, force=force)
    except BaseException:
        if aside is not None:
            shutil.rmtree(figures, ignore_errors=True)
            os.replace(aside / name, figures)
        raise
    finally:
        if aside is not None:
            shutil.rmtree(aside, ignore_errors=True)


def _remove_if_empty(folder):
    """Remove `folder` if nothing ended up in it (a run that made it and then failed)."""
    try:
        folder.rmdir()
    except OSError:
        pass


def _config(scene_fit):
    """The analysis configuration recorded in the scene file: the models, and the laws fitted
    under the noise model where they were."""
    config = {"models": list(scene_fit.results)}
    if scene_fit.noise_results:
        config["noise"] = list(scene_fit.noise_results)
    return config


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line like every other error of the command."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _number(low, high, *, unit, low_inclusive=False):
    """argparse type: a finite number in the physically sensible range (low, high] or
    [low, high], else the option's one-line error naming the range."""
    from ._validation import range_problem

    def number(text):
        problem = range_problem(text, low, high, unit=unit, low_inclusive=low_inclusive)
        if problem is not None:
            raise argparse.ArgumentTypeError(f"{problem}; got {text!r}")
        return float(text)

    return number


def _output_name(text):
    """argparse type of ``-o``: any name but the empty one (an unset shell variable), which
    names no file and would be taken for the current folder."""
    if not text:
        raise argparse.ArgumentTypeError("empty: give the name of the output")
    return text


# Help of each subcommand: (one-line help, description, example). Plain text: argparse shows
# it as it is, so no reST markup.
COMMANDS = {
    "impacts": (
        "find the impacts in a recording or lab table",
        "Find the impacts in a recording (WAV, FLAC, OGG, ...) or a lab export (phyphox, "
        "timestamp table, motion sensor, photogate) and write one row per impact: time, "
        "its 1-sigma uncertainty, amplitude and measured speeds where the sensor gives them.",
        ["dashpot impacts drop.wav -o impacts.csv",
         "dashpot impacts gate.csv --flag-length 0.02 -o -"]),
    "bounces": (
        "intervals, speeds and ε from an impact table",
        "Intervals, flight-time rebound speeds and per-bounce restitution ratios with their "
        "uncertainties, run by run, from an impact table; missed and spurious impacts are "
        "flagged, not dropped.",
        ["dashpot bounces impacts.csv -o bounces.csv",
         "dashpot bounces impacts.csv --g 2.90 -o -"]),
    "fit": (
        "fit β and k under every contact model; HDF5 out",
        "Fit the contact models (default: the scene's, else all five) to an impact table or "
        "a recording, compare them, write the HDF5 file and print each model's parameters "
        "rounded to their uncertainty, its notes and the selection's verdict. Every run of a "
        "multi-run file is fitted on its own, and all runs jointly sharing the contact "
        "parameters; both are printed side by side.",
        ["dashpot fit impacts.csv --scene scene.yaml -o fit.h5",
         "dashpot fit drop.wav --models Ib hybrid -o fit.h5",
         "dashpot fit impacts.csv --uncertainty profile posterior -o fit.h5"]),
    "analyze": (
        "one recording to an HDF5 file, a parameter table, figures and a summary",
        "Do for one recording what the workflow does for a scene, without Snakemake: write "
        "<name>.h5, <name>-parameters.csv (one row per model and parameter) and the figures "
        "<name>/*.png|pdf into the output folder, and print the summary of the fits (of "
        "every run of a multi-run file, and of the runs' joint fit).",
        ["dashpot analyze drop.wav --scene scene.yaml -o out/",
         "dashpot analyze --scene scene.yaml -o out/",
         "dashpot analyze drop.wav -o out/ --noise -v"]),
}


def _epilog(examples):
    """The examples under a help text (kept as written: the raw formatter does not wrap)."""
    examples = list(examples)
    return (f"example{'s' if len(examples) > 1 else ''}:\n"
            + "\n".join(f"  {example}" for example in examples))


def _wrapped(text):
    """A description wrapped as argparse would (the raw formatter keeps it as given)."""
    import textwrap

    return textwrap.fill(text, width=79)


def _verbosity_options(parser, default):
    """-q and -v, on the command and on each subcommand (``dashpot fit ... -v`` works)."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-q", "--quiet", action="store_true",
                       default=False if default else argparse.SUPPRESS,
                       help="print nothing but errors")
    group.add_argument("-v", "--verbose", action="count",
                       default=0 if default else argparse.SUPPRESS,
                       help="say what is done and how each fit was made (-vv: debugging)")


def _force_option(parser):
    """--force, on every subcommand that writes files."""
    parser.add_argument("--force", action="store_true",
                        help="replace outputs that already exist (default: refuse them, "
                             "writing nothing)")


def build_parser():
    """The command's argument parser (subcommands impacts, bounces, fit, analyze)."""
    from . import __version__
    from ._validation import (ACCELERATION_RANGE, BUMPER_POSITION_RANGE, FLAG_LENGTH_RANGE,
                              GATE_DISTANCE_RANGE)

    parser = _Parser(prog="dashpot", formatter_class=argparse.RawDescriptionHelpFormatter,
                     description=_wrapped("Bounce recordings to linear spring-dashpot "
                                          "contact physics: find the impacts, the bounces, "
                                          "fit the five contact models."),
                     epilog=_epilog(example for *_, examples in COMMANDS.values()
                                    for example in examples[:1]))
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    _verbosity_options(parser, default=True)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def command(name):
        summary, description, examples = COMMANDS[name]
        sub = commands.add_parser(name, help=summary, description=_wrapped(description),
                                  epilog=_epilog(examples),
                                  formatter_class=argparse.RawDescriptionHelpFormatter)
        _verbosity_options(sub, default=False)
        return sub

    impacts = command("impacts")
    impacts.add_argument("recording", help="audio file (WAV/FLAC/OGG/MP3) or lab table (CSV/XLSX)")
    impacts.add_argument("-o", "--output", required=True, type=_output_name,
                         help="impact table to write (CSV; - for standard output)")
    _force_option(impacts)
    impacts.add_argument("--kind", choices=["audio", "phyphox", "timestamps", "motion_sensor",
                                            "photogate"], help="reader (default: detected)")
    impacts.add_argument("--flag-length", type=_number(*FLAG_LENGTH_RANGE, unit="m"),
                         help="photogate flag length in m, in (%g, %g]" % FLAG_LENGTH_RANGE)
    impacts.add_argument("--gate-distance", type=_number(*GATE_DISTANCE_RANGE, unit="m"),
                         help="photogate distance from the bumper in m, in (%g, %g] (exact "
                              "impact times)" % GATE_DISTANCE_RANGE)
    impacts.add_argument("--unit", choices=["s", "ms"], help="time unit of a timestamp table")
    impacts.add_argument("--bumper-position",
                         type=_number(*BUMPER_POSITION_RANGE, unit="m", low_inclusive=True),
                         help="bumper position in m, in [%g, %g] (motion sensor; default "
                              "inferred)" % BUMPER_POSITION_RANGE)
    impacts.add_argument("--track", help="track of a Tracker export holding several (e.g. "
                                         "'mass A')")
    impacts.set_defaults(run=_impacts)
    bounces = command("bounces")
    bounces.add_argument("impacts", help="impact table written by dashpot impacts")
    bounces.add_argument("-o", "--output", required=True, type=_output_name,
                         help="bounce table to write (CSV; - for standard output)")
    _force_option(bounces)
    bounces.add_argument("--g", type=_number(*ACCELERATION_RANGE, unit="m/s²"),
                         default=STANDARD_GRAVITY,
                         help="acceleration towards the surface in m/s², in (%g, %g] "
                              "(default %s, standard gravity)"
                              % (*ACCELERATION_RANGE, STANDARD_GRAVITY))
    bounces.add_argument("--contact-duration",
                         type=_number(0.0, math.inf, unit="s", low_inclusive=True), default=0.0,
                         help="contact duration in s, if known; shorter than every interval "
                              "(default 0)")
    # A ping-pong ball has k_d ≈ 0.13 1/m; 100 1/m is a balloon-like ball slower than 0.3 m/s.
    bounces.add_argument("--drag-constant", type=_number(0.0, 100.0, unit="1/m",
                                                         low_inclusive=True),
                         help="air drag constant k_d = ρ C_d A/(2 m_eff) in 1/m, in [0, 100], "
                              "of a light ball (--g is then its effective gravity): speeds "
                              "from the drag flight and a drag-corrected ε column")
    bounces.set_defaults(run=_bounces)
    fit = command("fit")
    fit.add_argument("impacts", help="impact table from dashpot impacts, or a recording")
    fit.add_argument("-o", "--output", required=True, type=_output_name,
                     help="HDF5 file to write")
    _force_option(fit)
    fit.add_argument("--scene", help="scene.yaml: what is known of the apparatus")
    fit.add_argument("--models", nargs="+", choices=list(MODELS),
                     help="models to fit (default: the scene's, else all five)")
    fit.add_argument("--noise", action=argparse.BooleanOptionalAction, help=NOISE_HELP)
    fit.add_argument("--uncertainty", nargs="+", choices=list(UNCERTAINTY_METHODS),
                     help=UNCERTAINTY_HELP)
    fit.set_defaults(run=_fit)
    analyze = command("analyze")
    analyze.add_argument("recording", nargs="?",
                         help="audio file (WAV/FLAC/OGG/MP3) or lab table (CSV/XLSX); "
                              "default: the recording the scene names")
    analyze.add_argument("-o", "--output", required=True, type=_output_name,
                         help="folder to write <name>.h5, <name>-parameters.csv and the "
                              "figures <name>/*.png|pdf into")
    _force_option(analyze)
    analyze.add_argument("--scene", help="scene.yaml: what is known of the apparatus "
                                         "(its name names the outputs)")
    analyze.add_argument("--models", nargs="+", choices=list(MODELS),
                         help="models to fit (default: the scene's, else all five)")
    analyze.add_argument("--noise", action=argparse.BooleanOptionalAction, help=NOISE_HELP)
    analyze.add_argument("--uncertainty", nargs="+", choices=list(UNCERTAINTY_METHODS),
                         help=UNCERTAINTY_HELP)
    analyze.set_defaults(run=_analyze)
    return parser


# Signals that end a run as Ctrl-C does (kill, timeout, a closed terminal): SIGHUP is not on
# every platform.
_STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP")
                      if hasattr(signal, name))


class _Stopped(KeyboardInterrupt):
    """A stop signal other than SIGINT, raised as the KeyboardInterrupt SIGINT raises.

    Parameters
    ----------
    number : int
        The signal.
    """

    def __init__(self, number):
        super().__init__(signal.Signals(number).name)
        self.number = number


def _stop(number, frame):
    """Signal handler: raise :class:`_Stopped`."""
    raise _Stopped(number)


@contextmanager
def _stoppable():
    """Within the block SIGTERM and SIGHUP raise KeyboardInterrupt, as SIGINT does.

    Their default action ends the process at once, leaving the temporary files and the
    staging folder of the outputs under way behind; an exception unwinds through the writers,
    which remove them. The previous handlers are restored on leaving.
    """
    saved = {}
    for number in _STOP_SIGNALS:
        try:
            saved[number] = signal.signal(number, _stop)
        except ValueError:  # not the main thread: handlers can only be set there
            break
    try:
        yield
    finally:
        for number, handler in saved.items():
            signal.signal(number, handler)


def _log_level(args):
    """-q: errors only; default: warnings; -v: the steps (INFO); -vv: debugging."""
    if args.quiet:
        return logging.ERROR
    return {0: logging.WARNING, 1: logging.INFO}.get(args.verbose, logging.DEBUG)


def main(argv=None):
    """Entry point of the ``dashpot`` command; returns the exit status."""
    args = build_parser().parse_args(argv)
    # The library logs to the "dashpot" logger and never prints: the command shows its
    # records on standard error, as "dashpot <command>: <message>", for this run only.
    logger = logging.getLogger("dashpot")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter(f"dashpot {args.command}: %(message)s"))
    saved_level = logger.level
    logger.addHandler(handler)
    logger.setLevel(_log_level(args))

    def note(message, category, *_):
        # A warning (e.g. an unusable cache: results computed without it) is a note, one line.
        logger.warning("note: %s", message)

    try:
        with warnings.catch_warnings(), _stoppable():
            warnings.showwarning = note
            try:
                args.run(args, _Console(args))
            except InputError as error:
                from .atomic import EXISTS_PROBLEM

                if error.problem == EXISTS_PROBLEM:  # an output that appeared while we worked
                    error = InputError(error.path, "exists; pass --force to replace it")
                print(f"dashpot {args.command}: error: {error}", file=sys.stderr)
                return 2
            except KeyboardInterrupt as stop:
                # The writers removed what they had begun: one line, and the shell's status
                # for the signal (128 + its number) instead of a traceback.
                number = getattr(stop, "number", signal.SIGINT)
                print(f"dashpot {args.command}: interrupted ({signal.Signals(number).name}); "
                      f"unfinished outputs removed", file=sys.stderr)
                return 128 + number
            except BrokenPipeError:
                # The reader of `-o -` left (`| head`): no traceback, and nothing more to
                # stdout at exit (the Python documentation's recipe for SIGPIPE).
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
                return 1
    finally:
        logger.removeHandler(handler)
        logger.setLevel(saved_level)
    return 0


if __name__ == "__main__":
    sys.exit(main())
