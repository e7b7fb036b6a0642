"""The workflow on a multi-run recording: one scene file holding every run's fits and the
joint fit, summary rows per run (column `run`), and the config's uncertainty methods reached."""

import h5py
import numpy as np
import pandas as pd
import pytest

from dashpot.physics.sequence import bounce_sequence
from dashpot.store import csv_header, read_fit
from dashpot.summary import SUMMARY_COLUMNS
from workflow_run import run_once, workflow_copy
from workflow_run import snakemake as _snakemake

pytestmark = pytest.mark.slow

SPEEDS = {1: 1.2, 2: 1.5, 3: 1.8}  # m/s, each run's first impact speed
SEED = 20261125  # the date this test was written
CONFIG = {"scenes_dir": "scenes", "real_data": False, "synthetic": {}, "scene_plots": False,
          "uncertainty": ["covariance", "profile"],
          "theory": {"speeds": [5], "zeta_max": 1.0, "points": 3}}


@pytest.fixture(scope="module")
def runs_run(tmp_path_factory):
    """A folder scene whose impact table holds three runs (as `dashpot impacts` writes a
    Capstone export's), run through the workflow up to the summary."""
    def run(workdir):
        workflow_copy(workdir, CONFIG)
        folder = workdir / "scenes" / "three-runs"
        folder.mkdir(parents=True)
        rng = np.random.default_rng(SEED)
        parts = []
        for number, v0 in SPEEDS.items():
            train = bounce_sequence("IIb", beta=30.0, omega0=3000.0, g=9.81, v0=v0, n_max=15)
            times = 0.3 + train.impact_times + 2e-5 * rng.standard_normal(15)
            parts.append(pd.DataFrame({"time": times, "time_uncertainty": 2e-5,
                                       "run": number}))
        pd.concat(parts).sort_values("time").to_csv(folder / "impacts.csv", index=False)
        (folder / "scene.yaml").write_text("recording: impacts.csv\nmodels: [IIb]\n"
                                           "apparatus: {gravity: 9.81}\n")
        return _snakemake(workdir, "results/summary.csv")

    return run_once(tmp_path_factory, "workflow-runs", run)


def test_scene_file_holds_every_run_and_the_joint_fit(runs_run):
    record = read_fit(runs_run / "results" / "three-runs.h5")
    assert sorted(record["runs"]) == [1, 2, 3]
    for number in SPEEDS:
        fit = record["runs"][number]["fits"]["IIb"]
        assert fit["attrs"]["success"]
        # The config's uncertainty methods reached every run's fit.
        assert list(fit["intervals"].index) == ["covariance", "profile"]
    joint = record["joint"]["IIb"]
    assert joint["attrs"]["success"] and list(joint["runs"]["run"]) == [1, 2, 3]
    with h5py.File(runs_run / "results" / "three-runs.h5", "r") as source:
        assert source["impacts/used_in_fit"][()].all()


def test_summary_has_one_row_per_run(runs_run):
    table = pd.read_csv(runs_run / "results" / "summary.csv")
    assert list(table["run"]) == [1, 2, 3]
    assert list(table["scene"]) == ["three-runs"] * 3 and set(table["model"]) == {"IIb"}
    expected = list(SUMMARY_COLUMNS)
    expected.insert(expected.index("scene") + 1, "run")
    assert list(table.columns) == [csv_header(column) for column in expected]
    with h5py.File(runs_run / "results" / "summary.h5", "r") as source:
        assert list(source["summary"].attrs["columns"]) == expected
        assert source["summary/run"].dtype == np.int64
    assert table["selected"].all() and (table["status"] == "ok").all()
    record = read_fit(runs_run / "results" / "three-runs.h5")
    for _, row in table.iterrows():
        # Each row is its own run's fit (the runs' first impact speeds differ).
        stored = record["runs"][row["run"]]["fits"]["IIb"]["parameters"]
        assert row["v0 [m/s]"] == pytest.approx(stored.loc["v0", "value"])
        assert row["v0 [m/s]"] == pytest.approx(SPEEDS[row["run"]], abs=0.01)
