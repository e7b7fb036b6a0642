"""The ``dashpot`` command: one recording analysed without Snakemake.

Every failure is one line on standard error naming the file and the problem, with exit status
2, and no output file is left behind: outputs are written to a temporary name and renamed.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from .errors import InputError
from .physics.models import MODELS


def _write_csv_atomically(table, output, inputs):
    """Write `table` to `output` via a temporary file; never over one of the inputs."""
    output = Path(output)
    for source in inputs:
        if output.resolve() == Path(source).resolve():
            raise InputError(output, "refusing to overwrite the input with the output")
    output.parent.mkdir(parents=True, exist_ok=True)
    temporary = output.with_name(f".{output.name}.partial")
    try:
        table.to_csv(temporary, index=False, float_format="%.10g")
        os.replace(temporary, output)
    finally:
        temporary.unlink(missing_ok=True)


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
    import pandas as pd

    from .bounces import bounce_table

    try:
        impacts = pd.read_csv(args.impacts)
    except (OSError, ValueError) as error:
        raise InputError(args.impacts, f"cannot read the impact table ({error})") from error
    if "time" not in impacts:
        raise InputError(args.impacts, "no 'time' column: write it with `dashpot impacts`")
    try:
        table = bounce_table(impacts, g=args.g, contact_duration=args.contact_duration)
    except ValueError as error:
        raise InputError(args.impacts, str(error)) from error
    _write_csv_atomically(table, args.output, [args.impacts])
    flagged = int((table["flag"] != "ok").sum())
    print(f"{args.impacts}: {len(table)} bounces, {flagged} flagged -> {args.output}")


def _fit(args):
    from .analysis import analyze
    from .scene import Scene, load_scene
    from .store import write_scene_fit

    scene = load_scene(args.scene) if args.scene else Scene()
    inputs = [args.impacts] + ([args.scene] if args.scene else [])
    if Path(args.output).resolve() in {Path(source).resolve() for source in inputs}:
        raise InputError(args.output, "refusing to overwrite the input with the output")
    if Path(args.output).is_dir():
        raise InputError(args.output, "is a folder; give the HDF5 file to write")
    impacts, scene_fit = analyze(args.impacts, scene, models=args.models)
    try:
        write_scene_fit(args.output, scene_fit, impacts, input_path=args.impacts,
                        config={"models": list(scene_fit.results)})
    except OSError as error:
        raise InputError(args.output, f"cannot write the output ({error.strerror or error})") \
            from None
    print(f"{args.impacts}: {len(impacts)} impacts; {scene_fit.verdict} -> {args.output}")
    for model, fit in scene_fit.results.items():
        beta = fit.estimates.get("beta")
        state = (f"beta = {beta.value:.4g} ± {beta.stderr:.2g} 1/s" if fit.success and beta
                 else f"failed: {fit.message}")
        print(f"  {model:>6}: {state}")


def build_parser():
    parser = argparse.ArgumentParser(prog="dashpot", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    impacts = commands.add_parser("impacts", help="find the impacts in a recording or table")
    impacts.add_argument("recording", help="audio file (WAV/FLAC/OGG) or lab table (CSV/XLSX)")
    impacts.add_argument("-o", "--output", required=True, help="impact table to write (CSV)")
    impacts.add_argument("--kind", choices=["audio", "phyphox", "timestamps", "motion_sensor",
                                            "photogate"], help="reader (default: detected)")
    impacts.add_argument("--flag-length", type=float, help="photogate flag length in m")
    impacts.add_argument("--gate-distance", type=float,
                         help="photogate distance from the bumper in m (exact impact times)")
    impacts.add_argument("--unit", choices=["s", "ms"], help="time unit of a timestamp table")
    impacts.add_argument("--bumper-position", type=float,
                         help="bumper position in m (motion sensor; default inferred)")
    impacts.set_defaults(run=_impacts)
    bounces = commands.add_parser("bounces", help="intervals, speeds and ε from an impact table")
    bounces.add_argument("impacts", help="impact table written by `dashpot impacts`")
    bounces.add_argument("-o", "--output", required=True, help="bounce table to write (CSV)")
    bounces.add_argument("--g", type=float, default=9.81,
                         help="acceleration towards the surface in m/s² (default 9.81)")
    bounces.add_argument("--contact-duration", type=float, default=0.0,
                         help="contact duration in s, if known (default 0)")
    bounces.set_defaults(run=_bounces)
    fit = commands.add_parser("fit", help="fit β and k under every contact model; HDF5 out")
    fit.add_argument("impacts", help="impact table from `dashpot impacts`, or a recording")
    fit.add_argument("-o", "--output", required=True, help="HDF5 file to write")
    fit.add_argument("--scene", help="scene.yaml: what is known of the apparatus")
    fit.add_argument("--models", nargs="+", choices=list(MODELS),
                     help="models to fit (default: the scene's, else all five)")
    fit.set_defaults(run=_fit)
    return parser


def main(argv=None):
    """Entry point of the ``dashpot`` command; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        args.run(args)
    except InputError as error:
        print(f"dashpot {args.command}: error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
