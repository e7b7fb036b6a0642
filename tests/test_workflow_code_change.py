"""A rerun of the workflow after dashpot's code changed recomputes and redraws what the code
made (the digest of the source is a parameter of the rules that compute with it); without a
change nothing runs.

The workflow runs with a copy of the installed package first on PYTHONPATH: editing that copy
is a change of the code the jobs run, leaving the repository as it is."""

import shutil
from pathlib import Path

import h5py
import pytest

import dashpot
from dashpot.provenance import source_fingerprint
from test_workflow import _job_counts
from workflow_run import snakemake as _snakemake
from workflow_run import workflow_copy

pytestmark = pytest.mark.slow

# One small synthetic scene (two models), its figures, and few theory points.
CONFIG = {"scenes_dir": "scenes", "real_data": False, "scene_plots": True,
          "synthetic": {"tiny": {
              "kind": "timestamps", "model": "Ib", "beta": 20.0, "omega0": 2000.0,
              "g": 9.80665, "v0": 1.5, "n_max": 8, "seed": 3,
              "options": {"uncertainty": 1.0e-5},
              "scene": {"apparatus": {"gravity": 9.80665}, "models": ["Ib", "IIa"]}}},
          "theory": {"speeds": [5], "zeta_max": 1.0, "points": 3}}
OUTPUTS = ("results/tiny.h5", "results/summary.h5", "results/summary.csv",
           "results/truth/tiny.csv", "results/plots/tiny/restitution.png",
           "results/plots/tiny/intervals.pdf", "results/theory/contact_time.png")
NOTHING = "Nothing to be done"


def _run(workdir, *args):
    done = _snakemake(workdir, *args, timeout=600)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done.stdout + done.stderr


def _stored_fingerprints(workdir):
    found = {}
    for name in ("tiny", "summary"):
        with h5py.File(workdir / "results" / f"{name}.h5", "r") as f:
            found[name] = f.attrs["dashpot_source_sha256"]
    return found


def test_a_change_to_dashpots_code_reruns_what_it_computed(tmp_path, monkeypatch):
    workdir = tmp_path / "repo"
    workdir.mkdir()
    workflow_copy(workdir, CONFIG)
    package = tmp_path / "code" / "dashpot"
    shutil.copytree(Path(dashpot.__file__).parent, package,
                    ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setenv("PYTHONPATH", str(package.parent))
    before = source_fingerprint(package)
    assert before == source_fingerprint()  # the copy is the code under test, wherever it is

    _run(workdir)
    assert _stored_fingerprints(workdir) == {"tiny": before, "summary": before}
    assert NOTHING in _run(workdir, "--dry-run")  # unchanged: nothing reruns
    made = {path: (workdir / path).stat().st_mtime_ns for path in OUTPUTS}

    # A one-line change to the figures' module (a comment: the digest cannot tell).
    with open(package / "figures.py", "a", encoding="utf-8") as module:
        module.write("# changed\n")
    after = source_fingerprint(package)
    assert after != before
    plan = _run(workdir, "--dry-run")
    assert _job_counts(plan) == {"fit_chunk": 1, "fit": 1, "truth_table": 1, "scene_plots": 1,
                                 "summary": 1, "theory": 1, "all": 1}
    assert "Params have changed since last execution" in plan

    rerun = _run(workdir)
    # The chunk fitted the scene again (not skipped as up to date), and every output is new.
    log = (workdir / "results" / "logs" / "fit_chunk" / "scene-tiny.log").read_text()
    assert "tiny: fitted" in log and "up to date" not in log
    assert all((workdir / path).stat().st_mtime_ns > made[path] for path in OUTPUTS), rerun
    assert _stored_fingerprints(workdir) == {"tiny": after, "summary": after}
    assert NOTHING in _run(workdir, "--dry-run")
