"""The ``dashpot`` command: one recording analysed without Snakemake.

Every failure is one line on standard error naming the file and the problem, with exit status
2, and no output file is left behind: outputs are written to a temporary name and renamed.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import warnings
from pathlib import Path

from .errors import InputError
from .physics.models import MODELS

NOISE_HELP = ("also fit the restitution-law ladder and the models under bounce-to-bounce "
              "scatter and timing jitter, with their own selection (as the scene key "
              "noise: true; slower)")


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


def _write_csv_atomically(table, output, inputs):
    """Write `table` to `output` via a unique temporary file; never over one of the inputs.

    Floats are written in their shortest round-trip form, so they read back bit for bit
    (a fixed number of digits would round Unix-epoch times to whole seconds).
    """
    from .atomic import atomic_path

    output = Path(output)
    for source in inputs:
        if output.resolve() == Path(source).resolve():
            raise InputError(output, "refusing to overwrite the input with the output")
    try:
        with atomic_path(output) as temporary:
            table.to_csv(temporary, index=False)
    except OSError as error:
        raise _cannot_write(output, error) from None


def _impacts(args):
    from .ingest import read_impacts

    table = read_impacts(args.recording, kind=args.kind, flag_length=args.flag_length,
                         gate_distance=args.gate_distance, unit=args.unit,
                         bumper_position=args.bumper_position)
    _write_csv_atomically(table, args.output, [args.recording])
    notes = "; ".join(table.attrs.get("notes", []))
    print(f"{args.recording}: {len(table)} impacts -> {args.output}" + (f" ({notes})" if notes
                                                                           else ""))


def _bounces(args):
    from .analysis import read_impact_table
    from .bounces import bounce_table

    impacts = read_impact_table(args.impacts)
    try:
        table = bounce_table(impacts, g=args.g, contact_duration=args.contact_duration,
                             drag_constant=args.drag_constant)
    except ValueError as error:
        raise InputError(args.impacts, str(error)) from None
    _write_csv_atomically(table, args.output, [args.impacts])
    flagged = int((table["flag"] != "ok").sum())
    print(f"{args.impacts}: {len(table)} bounces, {flagged} flagged -> {args.output}")
    # The table is written whatever the intervals look like (it is how one inspects them),
    # but a run that is no bounce train is said to be one, as `fit` refuses it.
    _print_notes([*table.attrs.get("notes", []), *_not_bounce_trains(impacts)])


def _not_bounce_trains(impacts):
    """One warning per run of `impacts` whose intervals are not a ball bouncing to rest."""
    from .plausibility import NOT_A_BOUNCE_TRAIN, bounce_train_problem

    warnings = []
    for run, group in impacts.groupby("run", sort=False):
        problem = bounce_train_problem(group["time"].to_numpy(float),
                                       group["time_uncertainty"].to_numpy(float))
        if problem:
            where = f"run {run}: " if impacts["run"].nunique() > 1 else ""
            warnings.append(f"{where}{NOT_A_BOUNCE_TRAIN} ({problem}): `fit` refuses it")
    return warnings


def _fit(args):
    from .analysis import analyze, recording_note
    from .fit.data import flight_notes
    from .scene import Scene, load_scene
    from .store import write_scene_fit

    scene = load_scene(args.scene) if args.scene else Scene()
    inputs = [args.impacts] + ([args.scene] if args.scene else [])
    if Path(args.output).resolve() in {Path(source).resolve() for source in inputs}:
        raise InputError(args.output, "refusing to overwrite the input with the output")
    if Path(args.output).is_dir():
        raise InputError(args.output, "is a folder; give the HDF5 file to write")
    impacts, scene_fit = analyze(args.impacts, scene, models=args.models,
                                 noise=args.noise or None)
    try:
        write_scene_fit(args.output, scene_fit, impacts, input_path=args.impacts,
                        config=_config(scene_fit))
    except (OSError, RuntimeError) as error:
        raise _cannot_write(args.output, error) from None
    print(f"{args.impacts}: {len(impacts)} impacts; {scene_fit.verdict} -> {args.output}")
    _print_notes([recording_note(args.impacts, scene), *scene_fit.data.notes,
                  *flight_notes(scene)])
    for model, fit in scene_fit.results.items():
        beta = fit.estimates.get("beta")
        if fit.success and beta:
            state = _contact_text(fit.estimates, "beta", "beta", "1/s")
        else:
            state = f"failed: {fit.message}"
        print(f"  {model:>6}: {state}")
    _print_noise(scene_fit)


def _analyze(args):
    import shutil
    import tempfile
    from dataclasses import replace

    from tqdm import tqdm

    from .figures import load_record, save_scene_figures
    from .analysis import analyze, recording_note
    from .fit.data import flight_notes
    from .pipeline import is_audio
    from .scene import Scene, load_scene
    from .store import write_scene_fit

    recording = Path(args.recording)
    if not recording.is_file():
        raise InputError(recording, "no such file")
    scene = load_scene(args.scene) if args.scene else Scene(name=recording.stem or "scene")
    name = scene.name
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise InputError(out, "is a file; give the folder to write into")
    models = tuple(args.models or scene.models)
    with tqdm(total=1 + len(models) + 2, desc=recording.name, unit="step", leave=False,
              disable=None) as bar:
        def progress(step, total, text):
            bar.total = total + 2  # the fits (noise fits among them), then writing, figures
            bar.set_postfix_str(text)
            bar.update(step - bar.n)

        bar.set_postfix_str("finding impacts")
        impacts, scene_fit = analyze(recording, scene, models=models, progress=progress,
                                     noise=args.noise or None)
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
                                config=_config(scene_fit))
            except (OSError, RuntimeError) as error:
                raise _cannot_write(out / h5.name, error) from None
            bar.update(1)
            bar.set_postfix_str("figures")
            audio = impacts.attrs.get("sensor") == "audio" or is_audio(
                replace(scene, recording=recording))
            try:
                save_scene_figures(load_record(h5), staging / name,
                                   recording=recording if audio else None)
            except (OSError, RuntimeError) as error:
                raise _cannot_write(out / name, error) from None
            bar.update(1)
            _move_into_place(staging, out)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
            if created:
                _remove_if_empty(out)
    _print_summary(recording, impacts, scene_fit, out / f"{name}.h5", out / name)
    _print_notes([recording_note(recording, scene if args.scene else None),
                  *scene_fit.data.notes, *flight_notes(scene)])
    _print_noise(scene_fit)


def _move_into_place(staging, out):
    """Rename every file under `staging` to the same place under `out` (same file system)."""
    moves = [(source, out / source.relative_to(staging))
             for source in sorted(staging.rglob("*")) if source.is_file()]
    try:
        for _, target in moves:
            if target.is_dir():
                raise IsADirectoryError(f"{target} is a folder")
            target.parent.mkdir(parents=True, exist_ok=True)
        for source, target in moves:
            os.replace(source, target)
    except OSError as error:
        raise _cannot_write(out, error) from None


def _remove_if_empty(folder):
    """Remove `folder` if nothing ended up in it (a run that made it and then failed)."""
    try:
        folder.rmdir()
    except OSError:
        pass


def _print_notes(notes):
    """One indented line per note (None and empty notes skipped)."""
    for note in notes:
        if note:
            print(f"  note: {note}")


def _contact_text(estimates, key, label, unit):
    """'β = value ± error unit', or 'β not determined (reason)' where the data do not
    determine ω0 (:func:`dashpot.fit.observability.not_determined`)."""
    from .fit.observability import not_determined

    reason = not_determined(estimates).get(key)
    if reason:
        return f"{label} {reason}"
    estimate = estimates[key]
    return f"{label} = {estimate.value:.4g} ± {estimate.stderr:.2g} {unit}"


def _print_summary(recording, impacts, scene_fit, h5, figures):
    """β, k and the ε range per model, and the selection's verdict, in a few lines."""
    import numpy as np

    print(f"{recording}: {len(impacts)} impacts -> {h5}, figures in {figures}/")
    for model, fit in scene_fit.results.items():
        if not fit.success:
            print(f"  {model:>6}: failed: {fit.message}")
            continue
        parts = [_contact_text(fit.estimates, key, label, unit)
                 for key, label, unit in (("beta", "β", "1/s"), ("k", "k", "N/m"))
                 if key in fit.estimates]
        eps = np.asarray(fit.predicted.get("restitution", []), dtype=float)
        eps = eps[np.isfinite(eps) & (eps > 0)]
        if eps.size:
            parts.append(f"ε {eps.min():.4f}–{eps.max():.4f}")
        print(f"  {model:>6}: " + ", ".join(parts))
    print(f"  selection: {scene_fit.verdict}")


def _config(scene_fit):
    """The analysis configuration recorded in the scene file: the models, and the laws fitted
    under the noise model where they were."""
    config = {"models": list(scene_fit.results)}
    if scene_fit.noise_results:
        config["noise"] = list(scene_fit.noise_results)
    return config


def _print_noise(scene_fit):
    """One line per fit under the noise model and the noise verdict (nothing without them).

    Each line: the law's parameters (ζ, ω0 and the ε range of a dashpot model), σ_ε and σ_j
    with their 68 % intervals, and χ²/ν of the standardized innovations.
    """
    import numpy as np

    from .physics.laws import LAWS
    from .physics.models import MODELS

    for law, fit in scene_fit.noise_results.items():
        if not fit.success:
            print(f"  noise {law:>18}: failed: {fit.message}")
            continue
        names = ("zeta", "omega0") if law in MODELS else LAWS[law].parameter_names
        parts = []
        for name in names:
            estimate = fit.estimates[name]
            unit = "" if estimate.unit in ("", "1") else f" {estimate.unit}"
            parts.append(f"{name} = {estimate.value:.5g} ± {estimate.stderr:.2g}{unit}")
        if law in MODELS:
            eps = np.asarray(fit.predicted["restitution"], dtype=float)
            eps = eps[np.isfinite(eps) & (eps > 0)]
            if eps.size:
                parts.append(f"ε {eps.min():.4f}–{eps.max():.4f}")
        scatter, jitter = fit.estimates["sigma_eps"], fit.estimates["sigma_j"]
        parts.append(f"σ_ε = {100 * scatter.value:.2g} % [{100 * scatter.low68:.2g}, "
                     f"{100 * scatter.high68:.2g}]")
        parts.append(f"σ_j = {1e6 * jitter.value:.3g} µs [{1e6 * jitter.low68:.3g}, "
                     f"{1e6 * jitter.high68:.3g}]")
        parts.append(f"χ²/ν = {fit.redchi:.3g}")
        print(f"  noise {law:>18}: " + ", ".join(parts))
    if scene_fit.noise_results:
        print(f"  noise selection: {scene_fit.noise_verdict}")


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


def build_parser():
    from ._validation import (ACCELERATION_RANGE, BUMPER_POSITION_RANGE, FLAG_LENGTH_RANGE,
                              GATE_DISTANCE_RANGE)

    parser = _Parser(prog="dashpot", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    impacts = commands.add_parser("impacts", help="find the impacts in a recording or table")
    impacts.add_argument("recording", help="audio file (WAV/FLAC/OGG) or lab table (CSV/XLSX)")
    impacts.add_argument("-o", "--output", required=True, help="impact table to write (CSV)")
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
    impacts.set_defaults(run=_impacts)
    bounces = commands.add_parser("bounces", help="intervals, speeds and ε from an impact table")
    bounces.add_argument("impacts", help="impact table written by `dashpot impacts`")
    bounces.add_argument("-o", "--output", required=True, help="bounce table to write (CSV)")
    bounces.add_argument("--g", type=_number(*ACCELERATION_RANGE, unit="m/s²"), default=9.81,
                         help="acceleration towards the surface in m/s², in (%g, %g] "
                              "(default 9.81)" % ACCELERATION_RANGE)
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
    fit = commands.add_parser("fit", help="fit β and k under every contact model; HDF5 out")
    fit.add_argument("impacts", help="impact table from `dashpot impacts`, or a recording")
    fit.add_argument("-o", "--output", required=True, help="HDF5 file to write")
    fit.add_argument("--scene", help="scene.yaml: what is known of the apparatus")
    fit.add_argument("--models", nargs="+", choices=list(MODELS),
                     help="models to fit (default: the scene's, else all five)")
    fit.add_argument("--noise", action="store_true", help=NOISE_HELP)
    fit.set_defaults(run=_fit)
    analyze = commands.add_parser(
        "analyze", help="one recording to an HDF5 file, figures and a summary (no Snakemake)")
    analyze.add_argument("recording", help="audio file (WAV/FLAC/OGG) or lab table (CSV/XLSX)")
    analyze.add_argument("-o", "--output", required=True,
                         help="folder to write <name>.h5 and the figures <name>/*.png|pdf into")
    analyze.add_argument("--scene", help="scene.yaml: what is known of the apparatus "
                                         "(its name names the outputs)")
    analyze.add_argument("--models", nargs="+", choices=list(MODELS),
                         help="models to fit (default: the scene's, else all five)")
    analyze.add_argument("--noise", action="store_true", help=NOISE_HELP)
    analyze.set_defaults(run=_analyze)
    return parser


def main(argv=None):
    """Entry point of the ``dashpot`` command; returns the exit status."""
    args = build_parser().parse_args(argv)

    def note(message, category, *_):
        # A warning (e.g. an unusable cache: results computed without it) is a note, one line.
        print(f"dashpot {args.command}: note: {message}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.showwarning = note
        try:
            args.run(args)
        except InputError as error:
            print(f"dashpot {args.command}: error: {error}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
