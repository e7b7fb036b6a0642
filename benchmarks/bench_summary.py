"""Time of the workflow's cross-scene summary against the number of scenes (issue 16).

Fits one small synthetic scene, writes its file N times (scenes ``s00000`` ...), and times
:func:`dashpot.summary.summary_from_files` with ``by_run=True`` (what the workflow's summary
step runs: each file read once, only the parts the summary uses) at several N, and the
baseline: the summary of commit 2ec3d7b, which read every file whole with
:func:`dashpot.store.read_fit`, twice (the scene rows, then the run numbers), emulated here
by reading each file twice with ``read_fit`` (measured on fewer files: it is slow). Prints a
table of seconds and seconds per scene, the 10,000-scene time extrapolated from the largest
N (the per-scene time stays flat if the summary is linear), and the ratio against the
baseline.

    python benchmarks/bench_summary.py [--scenes 250 1000 2000] [--baseline-scenes 40]
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path


def scene_file(folder):
    """One fitted synthetic scene's HDF5 file (timestamps, 8 impacts, all five models)."""
    import logging

    from dashpot.batch import fit_scene
    from dashpot.pipeline import write_synthetic_scene

    spec = {"kind": "timestamps", "model": "IIb", "beta": 30.0, "omega0": 3000.0, "g": 9.80665,
            "v0": 1.5, "n_max": 8, "seed": 20261125, "options": {"uncertainty": 2.0e-5}}
    scene_folder = folder / "scene"
    write_synthetic_scene(scene_folder, spec, name="scene")
    output = folder / "scene.h5"
    fit_scene({"name": "scene", "scene_input": str(scene_folder),
               "truth": str(scene_folder / "truth.json")}, output, logging.getLogger("bench"))
    return output


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, nargs="+", default=[250, 1000, 2000])
    parser.add_argument("--baseline-scenes", type=int, default=40)
    args = parser.parse_args(argv)
    from dashpot.store import read_fit
    from dashpot.summary import summary_from_files

    rows = []
    with tempfile.TemporaryDirectory(prefix="dashpot-bench-summary-") as temporary:
        folder = Path(temporary)
        source = scene_file(folder)
        files = []
        for count in sorted(set(args.scenes) | {args.baseline_scenes}):
            while len(files) < count:
                target = folder / "results" / f"s{len(files):05d}.h5"
                target.parent.mkdir(exist_ok=True)
                shutil.copyfile(source, target)
                files.append(target)
            if count in args.scenes:
                start = time.perf_counter()
                table = summary_from_files(files[:count], by_run=True)
                seconds = time.perf_counter() - start
                assert table["scene"].nunique() == count
                rows.append((count, seconds))
                print(f"bench_summary: {count} scenes: {seconds:.2f} s", flush=True)
        start = time.perf_counter()
        for path in files[:args.baseline_scenes]:
            read_fit(path)
            read_fit(path)
        baseline = (time.perf_counter() - start) / args.baseline_scenes
    largest, largest_seconds = rows[-1]
    per_scene = largest_seconds / largest
    print("\nCross-scene summary of N copies of a small synthetic scene's file (5 models); "
          f"baseline: commit 2ec3d7b's reading (each file read whole, twice), "
          f"{baseline * 1e3:.1f} ms per scene on {args.baseline_scenes} files, reading alone\n")
    print("| scenes | summary (s) | per scene (ms) | baseline reading (s) | baseline / now |")
    print("|---|---|---|---|---|")
    for count, seconds in rows:
        print(f"| {count} | {seconds:.2f} | {seconds / count * 1e3:.1f} | "
              f"{baseline * count:.1f} | {baseline * count / seconds:.1f} |")
    print(f"| 10000 (extrapolated from {largest}) | {per_scene * 10000:.0f} | "
          f"{per_scene * 1e3:.1f} | {baseline * 10000:.0f} | {baseline / per_scene:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
