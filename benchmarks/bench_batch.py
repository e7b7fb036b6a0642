"""Wall time of the whole workflow on a batch of small synthetic scenes, at 1 and 2 cores.

Writes a config with N small synthetic scenes (timestamp tables of 8 impacts, parameters
spread over a range of damping and stiffness, all five models fitted) into a temporary copy
of the workflow, runs it once per core count in a fresh copy (Snakemake's progress lines are
shown), and prints a table of wall times and the speed-up. Per-scene figures are off by
default (``--plots`` draws them too); real data are off.

Run with ``make bench`` (200 scenes; several minutes) or
``python benchmarks/bench_batch.py --scenes 20 --cores 1 2`` for a quick look.
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = Path(sys.executable).with_name("snakemake")
WORKFLOW_FILES = ("Snakefile", "config", "workflow")


def batch_config(count, *, plots=False):
    """The workflow config of `count` small synthetic scenes (deterministic)."""
    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text(encoding="utf-8"))
    models = ("Ib", "IIb", "hybrid")
    scenes = {}
    for i in range(count):
        fraction = i / max(count - 1, 1)
        omega0 = 1000.0 * 10.0 ** fraction  # 1000 to 10 000 rad/s
        zeta = 0.005 * 4.0 ** ((i * 7 % count) / max(count, 1))  # 0.005 to 0.02
        scenes[f"batch-{i:03d}"] = {
            "kind": "timestamps", "model": models[i % len(models)],
            "beta": round(zeta * omega0, 6), "omega0": round(omega0, 6), "g": 9.80665,
            "v0": round(1.0 + 0.5 * math.sin(i), 6), "n_max": 8, "seed": i,
            "options": {"uncertainty": 2.0e-5},
            "scene": {"apparatus": {"gravity": 9.80665}},
        }
    config.update({"synthetic": scenes, "real_data": False, "scenes": {},
                   "scene_plots": bool(plots), "scenes_dir": "no-scene-folders"})
    return config


def prepare(folder, config):
    """A copy of the workflow in `folder` with `config` as its config.yaml."""
    folder.mkdir(parents=True)
    for name in WORKFLOW_FILES:
        source = ROOT / name
        if source.is_dir():
            shutil.copytree(source, folder / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(source, folder / name)
    (folder / "config" / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False),
                                                   encoding="utf-8")
    return folder


def snapshot_package(folder):
    """A copy of the dashpot sources, so that edits made during a long run cannot break it."""
    shutil.copytree(ROOT / "src" / "dashpot", folder / "dashpot",
                    ignore=shutil.ignore_patterns("__pycache__"))
    environment = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(folder), *filter(None, [os.environ.get("PYTHONPATH")])])}
    check = ("import tempfile, dashpot.plots\n"
             "from dashpot.pipeline import write_synthetic_scene, workflow_scene\n"
             "from dashpot.analysis import analyze\n"
             "with tempfile.TemporaryDirectory() as d:\n"
             "    spec = dict(kind='timestamps', model='IIb', beta=30.0, omega0=3000.0,"
             " g=9.81, v0=1.5, n_max=6)\n"
             "    scene = workflow_scene('check', scene_file=write_synthetic_scene(d, spec,"
             " name='check'))\n"
             "    analyze(scene.recording, scene, models=['IIb'])\n")
    subprocess.run([sys.executable, "-c", check], env=environment, check=True)
    return environment


def run(folder, cores, environment=None):
    """Run the workflow in `folder` on `cores` cores, echoing progress; returns wall seconds."""
    command = [str(SNAKEMAKE), "--snakefile", str(folder / "Snakefile"), "--directory",
               str(folder), "--cores", str(cores), "--quiet", "rules"]
    start = time.perf_counter()
    with subprocess.Popen(command, cwd=folder, stdout=subprocess.PIPE, env=environment,
                          stderr=subprocess.STDOUT, text=True) as process:
        for line in process.stdout:
            if "steps (" in line or "Error" in line:
                print(f"  [{cores} core{'s' if cores > 1 else ''}] {line.strip()}", flush=True)
        status = process.wait()
    elapsed = time.perf_counter() - start
    if status != 0:
        raise SystemExit(f"bench_batch: the workflow failed at {cores} core(s) (exit {status})")
    return elapsed


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=200, help="synthetic scenes (200)")
    parser.add_argument("--cores", type=int, nargs="+", default=[1, 2],
                        help="core counts to time (1 2)")
    parser.add_argument("--plots", action="store_true", help="also draw per-scene figures")
    args = parser.parse_args(argv)
    config = batch_config(args.scenes, plots=args.plots)
    times = {}
    with tempfile.TemporaryDirectory(prefix="dashpot-bench-batch-") as temporary:
        environment = snapshot_package(Path(temporary) / "src")
        for cores in args.cores:
            folder = prepare(Path(temporary) / f"cores{cores}", config)
            print(f"bench_batch: {args.scenes} scenes, {cores} core(s) in {folder}", flush=True)
            times[cores] = run(folder, cores, environment)
            print(f"bench_batch: {cores} core(s): {times[cores]:.1f} s", flush=True)
    base = times.get(1, times[args.cores[0]])
    print(f"\nWorkflow on {args.scenes} small synthetic scenes (simulate + fit 5 models + "
          f"summary{' + figures' if args.plots else ''}; theory included), "
          f"{os.cpu_count()} CPUs available\n")
    print("| cores | wall time (s) | per scene (s) | speed-up |")
    print("|---|---|---|---|")
    for cores, seconds in sorted(times.items()):
        print(f"| {cores} | {seconds:.1f} | {seconds / args.scenes:.2f} | "
              f"{base / seconds:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
