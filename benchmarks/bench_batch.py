"""Wall time of the whole workflow on batches of small synthetic scenes (issue 16's table).

Writes a config with N small synthetic scenes (timestamp tables of 8 to 40 impacts,
parameters spread over a range of damping and stiffness, all five models fitted, the noise
model and the restitution-law ladder where a scene's fits need it, or on every scene with
``--noise``) into a temporary copy of the workflow, runs it per scene count and core count in
a fresh copy (Snakemake's progress lines are shown), then runs it again (a no-op rerun:
nothing to do), and prints a table: wall time, per scene, the no-op rerun, the fit chunks
(jobs) and the peak memory of any job (max RSS from Snakemake's benchmark files), against the
baseline: the workflow before chunking (one job per scene, commit 2ec3d7b), measured with this
script on this machine on scenes of 8 impacts, the cheapest here (issue 16: 20 scenes 57 s
and 200 scenes 859 s at 2 cores; 1,000 extrapolated, 45 min). Per-scene figures are off by
default (``--plots`` draws them too); real data are off.

``make bench-batch`` runs 20 and 200 scenes at 2 cores (a few minutes);
``python benchmarks/bench_batch.py --scenes 1000`` the 1,000-scene row (minutes),
``--scenes 20 --cores 1 2`` a quick look at both core counts, and ``--slurm`` the same scenes
through the SLURM profile on the local test cluster of ``make cluster-test`` (started by
cluster/start.sh, root only; stopped again if this run started it), counting the SLURM jobs.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import resource
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


# Issue 16's baseline: (scenes, cores) -> wall seconds before chunking, and the targets.
BASELINE = {(20, 2): 57.0, (200, 2): 859.0, (1000, 2): 45 * 60.0}
TARGETS = {20: "<= 10 s", 1000: "<= 180 s"}
SLURM_TARGETS = {1000: "<= 300 s, <= 50 jobs"}
NO_OP_TARGET = 10.0  # s, for 1,000 scenes
MEMORY_TARGET = 1024.0  # MB, any job


def batch_config(count, *, plots=False, chunk_size="auto", noise=False):
    """The workflow config of `count` small synthetic scenes (deterministic): 8 to 40
    impacts, the five dashpot models fitted; the noise model with the restitution-law ladder
    where a scene's fits need it (the scenes' default, ``noise: auto``), or on every scene
    (`noise` true, the config key)."""
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
            "v0": round(1.0 + 0.5 * math.sin(i), 6), "n_max": 8 + (13 * i) % 33, "seed": i,
            "options": {"uncertainty": 2.0e-5},
            "scene": {"apparatus": {"gravity": 9.80665}},
        }
    config.update({"synthetic": scenes, "real_data": False, "scenes": {},
                   "scene_plots": bool(plots), "scenes_dir": "no-scene-folders",
                   "chunk_size": chunk_size, "noise": bool(noise)})
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
    """A copy of the dashpot sources, so that edits made during a long run cannot break it,
    with its compiled kernels warmed by one small scene fitted with every model (numba caches
    them beside the copy), so that no row pays for compiling them."""
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
             "    analyze(scene.recording, scene)\n")
    subprocess.run([sys.executable, "-c", check], env=environment, check=True)
    return environment


def _children_cpu():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run(folder, cores, environment=None, cpu=None, slurm=False):
    """Run the workflow in `folder` on `cores` cores (or through the SLURM profile), echoing
    progress; returns wall seconds and the number of SLURM jobs submitted (and appends the
    CPU seconds of the run and its local jobs to the list `cpu`)."""
    cpu_start = _children_cpu()
    if slurm:
        # As cluster/test.sh submits: squeue for the status (the test cluster keeps no
        # accounting), first checked 2 s after submission.
        options = ["--profile", str(folder / "workflow" / "profiles" / "slurm"),
                   "--slurm-status-command", "squeue",
                   "--slurm-init-seconds-before-status-checks", "2"]
    else:
        # As `make run` runs it: with the default profile (its scheduler), on `cores` cores.
        options = ["--profile", str(folder / "workflow" / "profiles" / "default"),
                   "--cores", str(cores)]
    command = [str(SNAKEMAKE), "--snakefile", str(folder / "Snakefile"), "--directory",
               str(folder), *options, "--quiet", "rules"]
    label = "slurm" if slurm else f"{cores} core{'s' if cores > 1 else ''}"
    submitted = 0
    start = time.perf_counter()
    with subprocess.Popen(command, cwd=folder, stdout=subprocess.PIPE, env=environment,
                          stderr=subprocess.STDOUT, text=True) as process:
        for line in process.stdout:
            submitted += "has been submitted with SLURM jobid" in line
            if "steps (" in line or "Error" in line:
                print(f"  [{label}] {line.strip()}", flush=True)
        status = process.wait()
    elapsed = time.perf_counter() - start
    if cpu is not None:
        cpu.append(_children_cpu() - cpu_start)
    if status != 0:
        raise SystemExit(f"bench_batch: the workflow failed ({label}, exit {status})")
    return elapsed, submitted


def slurm_environment(environment):
    """Start the local test cluster (cluster/start.sh); its environment for the workflow and
    whether this call started it (then :func:`stop_cluster` stops it)."""
    cluster = ROOT / "cluster"
    started = subprocess.run(["bash", str(cluster / "start.sh")], check=True, text=True,
                             stdout=subprocess.PIPE).stdout.strip() == "started"
    settings = subprocess.run(["bash", "-c", f"source {cluster / 'env.sh'} && "
                               "printf '%s\\n%s' \"$CLUSTER_DIR\" \"$SLURM_CONF\""],
                              check=True, text=True, stdout=subprocess.PIPE).stdout.split("\n")
    cluster_dir, slurm_conf = settings[0], settings[1]
    path = os.pathsep.join([f"{cluster_dir}/bin", str(SNAKEMAKE.parent),
                            environment.get("PATH", os.environ["PATH"])])
    return {**environment, "PATH": path, "SLURM_CONF": slurm_conf}, started


def stop_cluster():
    subprocess.run(["bash", str(ROOT / "cluster" / "stop.sh")], check=False)


def peak_memory(folder):
    """Largest max RSS (MB) of any job, from the benchmark files Snakemake wrote."""
    peak = 0.0
    for path in (folder / "results" / "benchmarks").rglob("*.tsv"):
        with open(path, newline="", encoding="utf-8") as handle:
            for row in csv.DictReader(handle, delimiter="\t"):
                try:
                    peak = max(peak, float(row["max_rss"]))
                except (KeyError, ValueError):
                    continue
    return peak


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, nargs="+", default=[20, 200],
                        help="synthetic scene counts (20 200)")
    parser.add_argument("--cores", type=int, nargs="+", default=[2],
                        help="core counts to time (2)")
    parser.add_argument("--chunk-size", default="auto", help="config chunk_size (auto)")
    parser.add_argument("--plots", action="store_true", help="also draw per-scene figures")
    parser.add_argument("--noise", action="store_true",
                        help="fit the noise model and the restitution-law ladder on every "
                             "scene (config noise: true), not only where a scene needs it")
    parser.add_argument("--slurm", action="store_true",
                        help="run through the SLURM profile on the local test cluster")
    args = parser.parse_args(argv)
    chunk_size = args.chunk_size if args.chunk_size == "auto" else int(args.chunk_size)
    rows = []
    started = False
    with tempfile.TemporaryDirectory(prefix="dashpot-bench-batch-") as temporary:
        environment = snapshot_package(Path(temporary) / "src")
        if args.slurm:
            environment, started = slurm_environment(environment)
        try:
            for count in args.scenes:
                config = batch_config(count, plots=args.plots, chunk_size=chunk_size,
                                      noise=args.noise)
                for cores in [None] if args.slurm else args.cores:
                    folder = prepare(Path(temporary) / f"scenes{count}-cores{cores}", config)
                    print(f"bench_batch: {count} scenes in {folder}", flush=True)
                    cpu = []
                    seconds, submitted = run(folder, cores, environment, cpu, args.slurm)
                    rerun, _ = run(folder, cores, environment, slurm=args.slurm)
                    chunks = len(list((folder / "results" / "benchmarks" / "fit_chunk")
                                      .glob("*.tsv")))
                    rows.append((count, cores, seconds, cpu[0], rerun, chunks,
                                 peak_memory(folder), submitted))
                    print(f"bench_batch: {count} scenes: {seconds:.1f} s, "
                          f"no-op rerun {rerun:.1f} s", flush=True)
                    shutil.rmtree(folder, ignore_errors=True)
        finally:
            if started:
                stop_cluster()
    if args.slurm:
        print_slurm_table(rows)
        return 0
    ladder = "the ladder on every scene" if args.noise else "the ladder where needed"
    print(f"\nWorkflow on small synthetic scenes (simulate + fit 5 models, {ladder} + summary"
          f"{' + figures' if args.plots else ''}; theory included), chunk_size {args.chunk_size},"
          f" {os.cpu_count()} CPUs available. Baseline: the workflow before chunking (one job "
          f"per scene, commit 2ec3d7b), issue 16's figures on this machine.\n")
    # CPU: of Snakemake and every job; on a machine shared with other work the wall time
    # grows, the CPU time much less.
    print("| scenes | cores | fit chunks | wall (s) | CPU (s) | per scene (s) | baseline (s) | "
          "baseline / now | target | no-op rerun (s) | peak job memory (MB) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for count, cores, seconds, cpu_seconds, rerun, chunks, memory, _ in rows:
        baseline = BASELINE.get((count, cores))
        print(f"| {count} | {cores} | {chunks} | {seconds:.1f} | {cpu_seconds:.0f} | "
              f"{seconds / count:.3f} | "
              f"{baseline if baseline is not None else '-'} | "
              f"{f'{baseline / seconds:.1f}' if baseline else '-'} | "
              f"{TARGETS.get(count, '-')} | {rerun:.1f} | {memory:.0f} |")
    print(f"\nTargets (issue 16): no-op rerun of 1,000 scenes <= {NO_OP_TARGET:.0f} s; peak "
          f"memory of any job <= {MEMORY_TARGET:.0f} MB.")
    return 0


def print_slurm_table(rows):
    print("\nWorkflow on small synthetic scenes through the SLURM profile on the local test "
          "cluster (one node, the CPUs of this machine); SLURM jobs counted as submitted.\n")
    print("| scenes | fit chunks | SLURM jobs | wall (s) | per scene (s) | target | "
          "no-op rerun (s) | peak job memory (MB) |")
    print("|---|---|---|---|---|---|---|---|")
    for count, _, seconds, _, rerun, chunks, memory, submitted in rows:
        print(f"| {count} | {chunks} | {submitted} | {seconds:.1f} | {seconds / count:.3f} | "
              f"{SLURM_TARGETS.get(count, '-')} | {rerun:.1f} | {memory:.0f} |")


if __name__ == "__main__":
    sys.exit(main())
