"""Running the Snakemake workflow from the workflow tests, in temporary folders."""

import fcntl
import os
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

SNAKEMAKE = Path(sys.executable).with_name("snakemake")
REPO = Path(__file__).resolve().parents[1]


def workflow_copy(workdir, config):
    """Put the repository's Snakefile and workflow folder (without caches) in `workdir`, with
    `config` (a dict) as its config/config.yaml."""
    shutil.copy2(REPO / "Snakefile", workdir / "Snakefile")
    shutil.copytree(REPO / "workflow", workdir / "workflow",
                    ignore=shutil.ignore_patterns("__pycache__"))
    (workdir / "config").mkdir()
    (workdir / "config" / "config.yaml").write_text(yaml.safe_dump(config))


def snakemake(workdir, *args, timeout=300):
    """Run the workflow in `workdir` on two cores; returns the CompletedProcess."""
    command = [str(SNAKEMAKE), "--snakefile", str(workdir / "Snakefile"),
               "--directory", str(workdir), "--cores", "2", *args]
    return subprocess.run(command, cwd=workdir, capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "PYTHONWARNINGS": "ignore"})


def run_once(tmp_path_factory, name, run):
    """The folder of a workflow run shared by every pytest-xdist worker, made once.

    The first worker calls ``run(workdir)`` (which must return the CompletedProcess of its
    Snakemake run) under a file lock; the others wait for it and reuse the folder. A failed
    run fails every test that uses it, with the end of Snakemake's output.
    """
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent
    workdir = root / name / "repo"
    marker = root / f"{name}.status"
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not marker.exists():
            shutil.rmtree(workdir.parent, ignore_errors=True)
            workdir.mkdir(parents=True)
            done = run(workdir)
            marker.write_text("ok" if done.returncode == 0 else
                              done.stdout[-3000:] + done.stderr[-3000:])
    status = marker.read_text()
    assert status == "ok", status
    return workdir


def copy_run(finished, tmp_path):
    """A copy of a finished run's folder (results and .snakemake metadata, mtimes kept), for a
    test that runs the workflow again without touching the shared run."""
    workdir = tmp_path / "repo"
    shutil.copytree(finished, workdir, symlinks=True)
    return workdir
