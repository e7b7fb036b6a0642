"""`make run` runs the workflow with the default profile, then builds results/report.html.

Snakemake is replaced by a stand-in that records its arguments (the real run and its report are
tested in tests/test_workflow.py), so this checks the Makefile itself: the order of the two
commands, and that a failed workflow fails `make run` without a report built from it.
"""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
PROFILE = ["--profile", "workflow/profiles/default", "--snakefile", "Snakefile"]


def _make_run(tmp_path, workflow_status):
    """Calls the stand-in received from `make run`, and make's exit status."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    calls = tmp_path / "calls"
    fake = bin_dir / "snakemake"
    # Fails (with `workflow_status`) unless asked for the report, as a run with a broken scene.
    fake.write_text(f'#!/bin/sh\necho "$*" >> {calls}\ncase "$*" in *--report*) exit 0;; esac\n'
                    f"exit {workflow_status}\n")
    fake.chmod(0o755)
    stamp = tmp_path / "installed"
    stamp.touch()  # newer than pyproject.toml and constraints.txt: nothing to install
    run = subprocess.run(["make", "--no-print-directory", "run", f"BIN={bin_dir}",
                          f"STAMP={stamp}"], cwd=REPO, capture_output=True, text=True,
                         env={**os.environ, "MAKEFLAGS": ""})
    recorded = calls.read_text().splitlines() if calls.exists() else []
    return [line.split() for line in recorded], run.returncode


pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")


def test_run_builds_the_report_after_the_workflow(tmp_path):
    calls, status = _make_run(tmp_path, 0)
    assert status == 0
    assert calls == [PROFILE, [*PROFILE, "--report", "results/report.html"]]


def test_a_failed_workflow_fails_make_run_and_builds_no_report(tmp_path):
    calls, status = _make_run(tmp_path, 1)
    assert status != 0
    assert calls == [PROFILE]
