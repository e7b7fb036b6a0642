"""The workflow never loses results, and one broken scene fails alone (issue 12: 1, 10, 11, 17).

One small run (a synthetic timestamp scene and a folder scene with its own recording, small
theory curves) is shared; each test works in a copy of it, so it only runs the jobs it is
about.
"""

import hashlib
import os
import signal
import subprocess
import time
from pathlib import Path

import h5py
import pandas as pd
import pytest
import yaml

from dashpot.store import csv_header
from dashpot.synth.scene import write_scene
from workflow_run import SNAKEMAKE, copy_run, run_once, workflow_copy
from workflow_run import snakemake as _snakemake

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
PROFILE = "workflow/profiles/default"

CONFIG = {
    "scenes_dir": "scenes",
    "real_data": False,
    "synthetic": {
        "table-a": {"kind": "timestamps", "model": "Ib", "beta": 22.0, "omega0": 2600.0,
                    "g": 9.80665, "v0": 1.3, "n_max": 8, "seed": 7,
                    "options": {"uncertainty": 1.0e-5},
                    "scene": {"models": ["Ib"], "apparatus": {"gravity": 9.80665}}},
    },
    "scene_plots": True,
    "theory": {"speeds": [5], "zeta_max": 1.0, "points": 3},
}
FOLDER_SCENE = "recording: timestamps.csv\nsensor: timestamps\nmodels: [IIb]\n" \
               "timing_resolution: 1.0e-5\n"


def _folder_scene(workdir, name, seed):
    folder = workdir / "scenes" / name
    write_scene(folder, "timestamps", model="IIb", beta=35.0, omega0=2800.0, g=9.81, v0=1.4,
                n_max=8, seed=seed)
    (folder / "scene.yaml").write_text(FOLDER_SCENE)
    return folder


@pytest.fixture(scope="session")
def small_run(tmp_path_factory):
    """The small workflow run once (under a file lock shared by pytest-xdist workers)."""
    def run(workdir):
        workflow_copy(workdir, CONFIG)
        _folder_scene(workdir, "folder-b", seed=913)
        return _snakemake(workdir)

    return run_once(tmp_path_factory, "workflow-small-run", run)


@pytest.fixture
def run_copy(small_run, tmp_path):
    """A copy of the finished small run, for tests that run the workflow again."""
    return copy_run(small_run, tmp_path)


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _errors(log):
    """The ERROR lines of a job log, without their time stamps."""
    return [line.split(" ERROR ", 1)[1] for line in log.read_text().splitlines()
            if " ERROR " in line]


def _summary(workdir):
    table = pd.read_csv(workdir / "results" / "summary.csv", keep_default_na=False)
    with h5py.File(workdir / "results" / "summary.h5", "r") as source:
        assert source.attrs["format"] == "dashpot-summary-1"
        # The CSV's headers are the HDF5 columns with their units: "beta [1/s]".
        assert [csv_header(c) for c in source["summary"].attrs["columns"]] == list(table.columns)
    return table.groupby("scene").first()


def test_missing_recording_keeps_the_scenes_results(run_copy):
    results = run_copy / "results"
    kept = [results / "folder-b.h5", *sorted((results / "plots" / "folder-b").iterdir())]
    assert len(kept) == 7
    before = {path: (_digest(path), path.stat().st_mtime_ns) for path in kept}
    recording = run_copy / "scenes" / "folder-b" / "timestamps.csv"
    recording.rename(run_copy / "moved-away.csv")
    done = _snakemake(run_copy, "--keep-going")
    output = done.stdout + done.stderr
    assert done.returncode != 0
    assert {path: (_digest(path), path.stat().st_mtime_ns) for path in kept} == before
    errors = _errors(results / "logs" / "fit" / "folder-b.log")
    assert len(errors) == 1 and "scenes/folder-b/timestamps.csv: no such file" in errors[0]
    assert errors[0] in output
    summary = _summary(run_copy)
    assert summary.loc["folder-b", "status"] == "stale"
    assert "scenes/folder-b/timestamps.csv" in summary.loc["folder-b", "problem"]
    assert summary.loc["folder-b", "model"] == "IIb"  # the earlier run's rows are kept
    assert summary.loc["table-a", "status"] == "ok"
    assert "scene folder-b (stale)" in (results / "logs" / "summary.log").read_text()
    # With the recording back, nothing of the scene is recomputed; only the summary changes.
    (run_copy / "moved-away.csv").rename(recording)
    again = _snakemake(run_copy)
    assert again.returncode == 0, again.stderr[-2000:]
    assert {path: (_digest(path), path.stat().st_mtime_ns) for path in kept} == before
    assert (_summary(run_copy)["status"] == "ok").all()


def test_a_failed_rerun_restores_the_scenes_results(run_copy):
    """A recording replaced by an unreadable one reruns the fit, which fails: the earlier
    results/<scene>.h5 is put back (and marked stale), never deleted."""
    results = run_copy / "results"
    result = results / "folder-b.h5"
    before = _digest(result)
    recording = run_copy / "scenes" / "folder-b" / "timestamps.csv"
    original = recording.read_bytes()
    recording.write_text("time\nnot a number\n")
    done = _snakemake(run_copy, "--keep-going")
    assert done.returncode != 0
    assert _digest(result) == before
    errors = _errors(results / "logs" / "fit" / "folder-b.log")
    assert len(errors) == 1 and "timestamps.csv" in errors[0]
    # The summary is rebuilt in a later run (it waited for the failing fit in this one); the
    # fit is not tried again until the recording changes, and every run says so.
    again = _snakemake(run_copy, "--keep-going")
    assert again.returncode == 0, again.stderr[-2000:]
    assert f"results/folder-b.h5 is stale: its last fit failed: {errors[0]}" in again.stderr
    assert _digest(result) == before
    summary = _summary(run_copy)
    assert summary.loc["folder-b", "status"] == "stale"
    assert errors[0] in summary.loc["folder-b", "problem"]
    assert summary.loc["folder-b", "model"] == "IIb"
    assert summary.loc["table-a", "status"] == "ok"
    # The recording mended, the scene is fitted again and is up to date.
    recording.write_bytes(original)
    mended = _snakemake(run_copy)
    assert mended.returncode == 0, mended.stderr[-2000:]
    assert "is stale" not in mended.stderr
    assert (_summary(run_copy)["status"] == "ok").all()
    assert _errors(results / "logs" / "fit" / "folder-b.log") == []


BROKEN_SCENES = {
    "audio-without-recording": ("sensor: audio\n", "no recording given"),
    "recording-not-a-string": ("sensor: audio\nrecording: [a.wav, b.wav]\n", "invalid scene"),
    "duplicate-key": ("recording: timestamps.csv\nmodels: [Ib]\nmodels: [IIb]\n", "duplicate"),
    "alias-bomb": ("a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [*{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, "
        f"*{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, "
        f"*{chr(97 + i)}, *{chr(97 + i)}]\n" for i in range(8)), "alias"),
    "summary": (FOLDER_SCENE, "reserved"),
    "Theory": (FOLDER_SCENE, "reserved"),
}


def test_incomplete_scenes_fail_alone(run_copy):
    for name, (text, _) in BROKEN_SCENES.items():
        folder = _folder_scene(run_copy, name, seed=431)
        (folder / "scene.yaml").write_text(text)
    _folder_scene(run_copy, "fresh-c", seed=577)
    done = _snakemake(run_copy, "--keep-going", "--config", "scene_plots=False")
    output = done.stdout + done.stderr
    assert done.returncode != 0
    for crash in ("Traceback", "TypeError", "AmbiguousRuleException", "RecursionError"):
        assert crash not in output
    logs = run_copy / "results" / "logs" / "fit"
    summary = _summary(run_copy)
    for name, (_, problem) in BROKEN_SCENES.items():
        errors = _errors(logs / f"{name}.log")
        assert len(errors) == 1 and problem in errors[0], (name, errors)
        assert errors[0].startswith(f"scenes/{name}/scene.yaml"), errors[0]
        assert errors[0] in output
        assert summary.loc[name, "status"] == "failed"
        assert summary.loc[name, "problem"] == errors[0]
        assert not (run_copy / "results" / f"{name}.h5").exists() or name == "summary"
    # The good scenes complete, and the summary is the workflow's own.
    assert (run_copy / "results" / "fresh-c.h5").is_file()
    assert summary.loc[["table-a", "folder-b", "fresh-c"], "status"].eq("ok").all()


def test_damaged_scene_file_is_named_and_recomputed_once_deleted(run_copy):
    results = run_copy / "results"
    damaged = results / "table-a.h5"
    damaged.write_bytes(damaged.read_bytes()[:2000])  # a truncated write
    done = _snakemake(run_copy, "--keep-going")
    output = done.stdout + done.stderr
    assert done.returncode != 0
    assert "Nothing to be done" not in output and "Traceback" not in output
    errors = _errors(results / "logs" / "fit" / "table-a.log")
    assert len(errors) == 1 and errors[0].startswith("results/table-a.h5: ")
    assert "delete it" in errors[0]
    summary = _summary(run_copy)
    assert summary.loc["table-a", "status"] == "unreadable"
    assert summary.loc["table-a", "problem"].startswith("results/table-a.h5: ")
    assert summary.loc["folder-b", "status"] == "ok"
    assert "results/table-a.h5" in (results / "logs" / "summary.log").read_text()
    damaged.unlink()
    again = _snakemake(run_copy)
    assert again.returncode == 0, again.stderr[-2000:]
    assert (_summary(run_copy)["status"] == "ok").all()
    with h5py.File(damaged, "r") as source:
        assert source.attrs["format"] == "dashpot-scene-1"


def test_summary_is_rebuilt_while_a_fit_keeps_failing(run_copy):
    folder = run_copy / "scenes" / "bad-audio"
    folder.mkdir()
    (folder / "rec.wav").write_bytes(b"RIFF this is not a recording\n")
    (folder / "scene.yaml").write_text("recording: rec.wav\n")
    first = _snakemake(run_copy, "--keep-going", "--config", "scene_plots=False")
    assert first.returncode != 0
    _folder_scene(run_copy, "fresh-d", seed=268)
    second = _snakemake(run_copy, "--keep-going", "--config", "scene_plots=False")
    assert second.returncode != 0
    summary = _summary(run_copy)
    assert summary.loc["fresh-d", "status"] == "ok"
    assert summary.loc["bad-audio", "status"] == "failed"
    assert "scenes/bad-audio/rec.wav" in summary.loc["bad-audio", "problem"]
    # The failing fit is tried again each run, but the summary is not redone for it.
    third = _snakemake(run_copy, "--keep-going", "--config", "scene_plots=False", "--dry-run")
    assert "rule summary:" not in third.stdout + third.stderr


def test_make_run_loads_the_default_profile():
    plan = subprocess.run(["make", "-n", "run"], cwd=REPO, capture_output=True, text=True,
                          timeout=60)
    assert plan.returncode == 0, plan.stderr
    # The workflow, then its report: both with the profile (the report must see the same
    # configuration as the run it reports).
    command = [line for line in plan.stdout.splitlines() if "snakemake" in line]
    assert len(command) == 2 and all(f"--profile {PROFILE}" in line for line in command)
    assert "--report" not in command[0] and "--report results/report.html" in command[1]
    profile = yaml.safe_load((REPO / PROFILE / "config.yaml").read_text())
    assert profile["rerun-incomplete"] is True and profile["keep-going"] is True
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert f"--profile {PROFILE} --unlock" in readme and "--rerun-incomplete" in readme


def test_recovery_after_kill_is_unlock_then_run(run_copy):
    _folder_scene(run_copy, "fresh-e", seed=352)
    log = run_copy / "results" / "logs" / "fit" / "fresh-e.log"
    command = [str(SNAKEMAKE), "--snakefile", str(run_copy / "Snakefile"), "--directory",
               str(run_copy), "--profile", PROFILE, "--cores", "2"]
    run = subprocess.Popen(command, cwd=run_copy, stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + 120
    while not log.exists() and run.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert run.poll() is None, "the run ended before it could be killed"
    os.killpg(run.pid, signal.SIGKILL)
    run.wait()
    locked = _snakemake(run_copy, "--profile", PROFILE)
    assert locked.returncode != 0 and "--unlock" in locked.stdout + locked.stderr
    assert _snakemake(run_copy, "--profile", PROFILE, "--unlock").returncode == 0
    done = _snakemake(run_copy, "--profile", PROFILE)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    with h5py.File(run_copy / "results" / "fresh-e.h5", "r") as source:
        assert source.attrs["format"] == "dashpot-scene-1"
    assert (_summary(run_copy)["status"] == "ok").all()
