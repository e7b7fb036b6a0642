"""The Snakemake workflow end to end, on the built-in synthetic scenes, in temporary copies.

One run of the default scenes (real data switched off) is shared by the tests of its outputs;
the tests that run the workflow again work in copies of that finished run, so they only run
the jobs they are about.
"""

import json
import re
import shutil
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest
import yaml

from dashpot.physics.models import MODELS
from dashpot.store import csv_header, read_fit
from dashpot.summary import SUMMARY_COLUMNS
from dashpot.synth.scene import write_scene
from workflow_run import copy_run, run_once
from workflow_run import snakemake as _snakemake

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "data"
WORKFLOW_FILES = ("Snakefile", "config", "workflow", "data")
SCENE_FIGURES = ("intervals", "restitution", "selection")
THEORY_FIGURES = ("contact_time", "restitution", "critical_speed", "restitution_vs_speed")


def _copy_repo(target):
    """The workflow's files (not results, not .snakemake) copied into `target`."""
    target.mkdir(parents=True, exist_ok=True)
    for name in WORKFLOW_FILES:
        source = REPO / name
        if source.is_dir():
            shutil.copytree(source, target / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(source, target / name)
    return target


def _synthetic(workdir):
    return yaml.safe_load((workdir / "config" / "config.yaml").read_text())["synthetic"]


@pytest.fixture(scope="session")
def default_run(tmp_path_factory):
    """The default scenes, real data off, run once in a clean copy of the repository.

    Shared by all pytest-xdist workers (the first one runs it under a file lock, the others
    wait and reuse it). Nothing runs in this folder afterwards: tests that run the workflow
    again work in copies (`run_copy`).
    """
    return run_once(tmp_path_factory, "workflow-default-run",
                    lambda workdir: _snakemake(_copy_repo(workdir), "--config",
                                               "real_data=False"))


def _expected_outputs(workdir):
    scenes = _synthetic(workdir)
    files = ["results/summary.h5", "results/summary.csv", "results/theory/critical_velocity.csv",
             "results/theory/restitution_vs_zeta.csv"]
    for name, spec in scenes.items():
        files += [f"results/{name}.h5", f"results/synthetic/{name}/truth.json",
                  f"results/synthetic/{name}/scene.yaml", f"results/truth/{name}.csv"]
        figures = SCENE_FIGURES + (("detection",) if spec["kind"] == "audio" else ())
        files += [f"results/plots/{name}/{f}.{ext}" for f in figures for ext in ("png", "pdf")]
        # A handful of scenes: each is its own chunk (one process each).
        files += [f"results/logs/fit/{name}.log", f"results/benchmarks/fit_chunk/scene-{name}.tsv"]
    files += [f"results/theory/{f}.{ext}" for f in THEORY_FIGURES for ext in ("png", "pdf")]
    return files


def test_default_run_writes_every_output(default_run):
    missing = [f for f in _expected_outputs(default_run) if not (default_run / f).is_file()]
    assert not missing
    assert not list((default_run / "results").rglob("*.partial"))
    kinds = {spec["kind"] for spec in _synthetic(default_run).values()}
    assert {"audio", "phyphox", "timestamps", "motion_sensor"} <= kinds


def _parse_block(block):
    """(path, unit, type) of each line of a listing (unit and type None for groups)."""
    items = []
    for line in block.strip().splitlines():
        path, _, rest = line.partition(" ")
        rest = rest.strip()
        if path.endswith("/"):
            items.append((path, None, None))
            continue
        unit = "see column 'unit'" if rest.startswith("see column") else rest.split()[0]
        items.append((path, unit, rest[len(unit):].split()[0]))
    return items


def _documented_layout():
    """Paths, units and types of docs/hdf5-layout.md's "Everything in the file" listing, and
    of the `truth` group's (synthetic scenes)."""
    text = (REPO / "docs" / "hdf5-layout.md").read_text(encoding="utf-8")
    block = text.split("## Everything in the file", 1)[1].split("```text", 1)[1].split("```")[0]
    truth = text.split("## `truth`", 1)[1].split("```text", 1)[1].split("```")[0]
    return _parse_block(block) + _parse_block(truth)


def _type_name(dataset):
    """A dataset's type as the layout writes it; `dimension` for a netCDF dimension."""
    if bytes(dataset.attrs.get("NAME", b"")).startswith(b"This is a netCDF dimension but not"):
        return "dimension"
    if h5py.check_string_dtype(dataset.dtype):
        return "string"
    return "bool" if dataset.dtype == bool else dataset.dtype.name


ROOT_ATTRIBUTES = ("format", "dashpot_version", "dashpot_source_sha256", "created", "scene",
                   "config", "input_file", "input_sha256", "verdict")


def test_scene_files_follow_the_documented_layout(default_run):
    layout = _documented_layout()
    assert len(layout) > 40
    for name in _synthetic(default_run):
        with h5py.File(default_run / "results" / f"{name}.h5", "r") as f:
            assert f.attrs["format"] == "dashpot-scene-1"
            assert set(ROOT_ATTRIBUTES) <= set(f.attrs)
            json.loads(f.attrs["scene"])
            assert set(f["fits"]) == set(MODELS)
            for path, unit, dtype in layout:
                models = MODELS if "<model>" in path else ("",)
                for model in models:
                    item = path.replace("<model>", model).rstrip("/") or "/"
                    assert item in f, f"{name}.h5 lacks {item}"
                    if unit is not None:
                        assert f[item].attrs["units"] == unit, item
                        assert _type_name(f[item]) == dtype, (name, item)
            # Only the root attribute `created` holds a time.
            for group in ("impacts", "bounces", "selection"):
                columns = list(f[group].attrs["columns"])
                lengths = {f[group][c].shape[0] for c in columns}
                assert len(lengths) == 1, group


def test_summary_has_one_row_per_scene_and_model(default_run):
    scenes = _synthetic(default_run)
    table = pd.read_csv(default_run / "results" / "summary.csv")
    # The summary's columns with `run` after `scene` (one row per run and model).
    columns = list(SUMMARY_COLUMNS)
    columns.insert(columns.index("scene") + 1, "run")
    assert list(table.columns) == [csv_header(column) for column in columns]
    # The synthetic recordings have one run each.
    assert (table.groupby("scene")["run"].nunique() == 1).all()
    assert {"beta [1/s]", "k [N/m]", "omega0 [rad/s]", "v0 [m/s]", "sigma_j [s]",
            "zeta"} <= set(table.columns)
    assert len(table) == len(scenes) * len(MODELS)
    assert set(table["scene"]) == set(scenes)
    assert (table.groupby("scene")["selected"].sum() == 1).all()
    assert (table["status"] == "ok").all() and table["problem"].isna().all()
    with h5py.File(default_run / "results" / "summary.h5", "r") as f:
        assert f.attrs["format"] == "dashpot-summary-1"
        assert list(f["summary"].attrs["columns"]) == columns
        assert f["summary"]["beta"].attrs["units"] == "1/s"
    # k only where the scene gives the mass: the cart.
    cart = table[table["scene"] == "paper-cart"]
    assert cart["k [N/m]"].notna().any()
    assert table[table["scene"] != "paper-cart"]["k [N/m]"].isna().all()
    # Every synthetic scene's rows carry its truth (from the config) and the pulls.
    for name, spec in scenes.items():
        rows = table[table["scene"] == name]
        assert np.allclose(rows["beta_truth [1/s]"], spec["beta"])
        assert np.allclose(rows["omega0_truth [rad/s]"], spec["omega0"])
        generating = rows[rows["model"] == spec["model"]].iloc[0]
        assert np.isfinite(generating["beta_pull"])


def test_truth_tables_compare_the_generating_fit_with_the_config(default_run):
    """results/truth/<scene>.csv (the report's table): truth from config.yaml, the fit's
    value and error from the scene file, pull (value - truth)/stderr."""
    for name, spec in _synthetic(default_run).items():
        table = pd.read_csv(default_run / "results" / "truth" / f"{name}.csv",
                            keep_default_na=False, na_values=[""]).set_index("parameter")
        assert set(table["model"]) == {spec["model"]}
        fit = read_fit(default_run / "results" / f"{name}.h5")["fits"][spec["model"]]
        beta = fit["parameters"].loc["beta"]
        row = table.loc["beta"]
        assert row["truth"] == spec["beta"] and row["unit"] == "1/s"
        assert row["pull"] == pytest.approx((beta["value"] - spec["beta"]) / beta["stderr"])


def test_fits_recover_the_generating_beta(default_run):
    for name in _synthetic(default_run):
        truth = json.loads((default_run / "results" / "synthetic" / name / "truth.json")
                           .read_text())["generator"]
        fit = read_fit(default_run / "results" / f"{name}.h5")["fits"][truth["model"]]
        assert fit["attrs"]["success"], (name, fit["attrs"]["message"])
        beta = fit["parameters"].loc["beta"]
        inside = beta["low95"] <= truth["beta"] <= beta["high95"]
        within = abs(beta["value"] - truth["beta"]) <= 3 * beta["stderr"]
        assert inside or within, (name, truth["beta"], beta.to_dict())




def _job_counts(output):
    """Rule -> job count from the "Job stats" table of a dry run."""
    stats = output.split("Job stats:", 1)[1]
    return {m.group(1): int(m.group(2))
            for m in re.finditer(r"^(\w+)\s+(\d+)\s*$", stats, flags=re.M)
            if m.group(1) != "total"}


@pytest.fixture
def run_copy(default_run, tmp_path):
    """A copy of the finished default run, for tests that run the workflow again."""
    return copy_run(default_run, tmp_path)


def test_second_run_does_nothing(run_copy):
    again = _snakemake(run_copy, "--config", "real_data=False")
    assert again.returncode == 0
    assert "Nothing to be done" in again.stdout + again.stderr


def test_lint_passes(run_copy):
    lint = _snakemake(run_copy, "--lint")
    assert lint.returncode == 0, lint.stdout + lint.stderr


def test_report_is_one_page_with_every_figure(run_copy):
    done = _snakemake(run_copy, "--report", "results/report.html")
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    page = (run_copy / "results" / "report.html").read_text(encoding="utf-8")
    figures = list((run_copy / "results").rglob("*.png"))
    assert len(figures) >= 4 * 3 + 1 + 4
    assert page.count("data:image/png") >= len(figures)  # every PNG embedded
    for caption in ("Akaike weight", "Bounce intervals", "Critical impact speed"):
        assert caption in page


def test_adding_a_scene_reruns_only_that_scene_and_the_summary(run_copy):
    folder = run_copy / "data" / "my-ball"
    write_scene(folder, "timestamps", model="IIb", beta=30.0, omega0=3000.0, g=9.81, v0=1.5,
                n_max=8)
    (folder / "scene.yaml").write_text("recording: timestamps.csv\nsensor: timestamps\n"
                                       "models: [IIb]\ntiming_resolution: 1.0e-5\n")
    plan = _snakemake(run_copy, "--config", "real_data=False", "--dry-run")
    assert plan.returncode == 0, plan.stderr
    assert _job_counts(plan.stdout + plan.stderr) == {"fit_chunk": 1, "fit": 1, "scene_plots": 1,
                                                       "summary": 1, "all": 1}
    assert "wildcards: scene=my-ball" in plan.stdout + plan.stderr


BROKEN = {
    "no-recording": ("recording: missing.wav\nsensor: audio\n", None, "no such file"),
    "bad-yaml": ("recording: rec.csv\nsensor: banana\n", "rec.csv", "invalid scene"),
    "bad-audio": ("recording: rec.wav\n", "rec.wav", "not a readable audio file"),
}


def test_broken_scenes_fail_alone_and_leave_no_partial_output(run_copy):
    for name, (scene, recording, _) in BROKEN.items():
        folder = run_copy / "data" / name
        folder.mkdir()
        (folder / "scene.yaml").write_text(scene)
        if recording:
            (folder / recording).write_bytes(b"this is not a recording\n")
    results = run_copy / "results"
    before = {p: p.stat().st_mtime_ns for p in results.glob("*.h5")}
    done = _snakemake(run_copy, "--config", "real_data=False", "--keep-going")
    output = done.stdout + done.stderr
    assert done.returncode != 0
    for name, (_, _, problem) in BROKEN.items():
        assert not (results / f"{name}.h5").exists()
        log = (results / "logs" / "fit" / f"{name}.log").read_text()
        assert problem in log, (name, log)
        assert f"data/{name}" in log
        assert problem in output  # the one-line message reaches the console
    # The other scenes' results are untouched, and nothing half-written is left anywhere.
    assert {p: p.stat().st_mtime_ns for p in before} == before
    assert not list(results.rglob("*.partial")) and not list(results.rglob(".*.tmp"))


def test_missing_shared_data_is_skipped_with_a_message(tmp_path):
    workdir = _copy_repo(tmp_path / "repo")  # no ../shared beside this copy
    plan = _snakemake(workdir, "--dry-run")
    assert plan.returncode == 0, plan.stderr
    assert "skipping the real recordings" in plan.stderr
    assert "pingpong-erickson" not in plan.stdout.split("Job stats:")[0].replace(
        "skipping", "")


@pytest.mark.skipif(not (SHARED / "pingpong-erickson" / "pingpong.wav").is_file(),
                    reason=f"real recordings not found at {SHARED} (see its README); "
                           "the real-data test needs ../shared/data beside the repository")
def test_real_recording_pingpong(tmp_path):
    workdir = _copy_repo(tmp_path / "repo")
    (tmp_path / "shared").symlink_to(SHARED.parent)
    done = _snakemake(workdir, "results/pingpong-erickson.h5",
                      "results/plots/pingpong-erickson/detection.png")
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    record = read_fit(workdir / "results" / "pingpong-erickson.h5")
    assert len(record["impacts"]) >= 25
    assert record["selection"]["success"].any()
    intervals = np.diff(record["impacts"]["time"].to_numpy(float))
    # The author's picks give interval ratios of about 0.946 throughout (shared/data/README).
    assert 0.92 < np.median(intervals[1:] / intervals[:-1]) < 0.97
