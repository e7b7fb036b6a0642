"""Scenes fitted in chunks (issue 16): the same files whatever the chunk size, a broken scene
fails alone inside its chunk, chunk membership stays put when a scene is added, and the
command's help starts without the scientific stack."""

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from dashpot.batch import auto_chunk_size, chunks, plots_wanted
from workflow_run import snakemake as _snakemake

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "cluster"))
from compare_results import compare_hdf5  # noqa: E402

HEAVY = ("scipy", "numba", "lmfit", "matplotlib", "pandas")


def test_help_imports_no_heavy_module():
    code = ("import sys, json\n"
            "from dashpot.cli import main\n"
            "for argv in (['--help'], ['fit', '--help'], ['analyze', '--help']):\n"
            "    try:\n"
            "        main(argv)\n"
            "    except SystemExit:\n"
            "        pass\n"
            f"print(json.dumps([m for m in {list(HEAVY)!r} if m in sys.modules]),"
            " file=sys.stderr)\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert json.loads(run.stderr.strip().splitlines()[-1]) == []
    assert "analyze" in run.stdout


def test_help_constants_are_the_librarys():
    from dashpot import cli
    from dashpot.physics.models import MODELS
    from dashpot.scene import STANDARD_GRAVITY

    assert tuple(cli.MODELS) == tuple(MODELS)
    assert cli.STANDARD_GRAVITY == STANDARD_GRAVITY


def test_adding_a_scene_moves_no_other_scene():
    names = [f"scene-{i:04d}" for i in range(1000)]
    size = auto_chunk_size(len(names))
    assert size == 150
    before = chunks(names, size)
    assert len(before) <= 50  # at most 50 jobs for 1,000 scenes
    after = chunks([*names, "one-more"], size)
    changed = [chunk for chunk in after if after[chunk] != before.get(chunk)]
    assert len(changed) == 1 and "one-more" in after[changed[0]]
    assert sorted(n for members in after.values() for n in members) == sorted([*names,
                                                                              "one-more"])


def test_automatic_sizes():
    assert [auto_chunk_size(n) for n in (1, 8, 9, 20, 200, 10_000)] == [1, 1, 5, 10, 100, 150]
    assert chunks(["a", "b"], 1) == {"scene-a": ["a"], "scene-b": ["b"]}
    assert plots_wanted("auto", 100) and not plots_wanted("auto", 101)
    assert plots_wanted(True, 10_000) and not plots_wanted(False, 1)


# Four tiny synthetic scenes (one model each, few impacts), and a folder scene whose
# recording cannot be read.
SYNTHETIC = {
    f"tiny-{k}": {"kind": "timestamps", "model": model, "beta": beta, "omega0": omega0,
                  "g": 9.80665, "v0": v0, "n_max": 8, "seed": 20261125 + k,
                  "options": {"uncertainty": 1.0e-5},
                  "scene": {"models": [model], "apparatus": {"gravity": 9.80665}}}
    for k, (model, beta, omega0, v0) in enumerate([("Ib", 22.0, 2600.0, 1.3),
                                                  ("IIb", 35.0, 2800.0, 1.4),
                                                  ("hybrid", 30.0, 3000.0, 1.2),
                                                  ("Ib", 15.0, 2000.0, 1.1)])
}
BROKEN = "broken-table"
# Every job but the theory curves and figures, which no scene's chunk, file or summary uses
# (a job of several CPU seconds in each run).
WITHOUT_THEORY = ("--keep-going", "--omit-from", "theory")


def _workflow(workdir, chunk_size, *, broken=False):
    workdir.mkdir(parents=True)
    (workdir / "Snakefile").write_bytes((REPO / "Snakefile").read_bytes())
    subprocess.run(["cp", "-r", str(REPO / "workflow"), str(workdir / "workflow")], check=True)
    (workdir / "config").mkdir()
    config = {"scenes_dir": "scenes", "real_data": False, "synthetic": SYNTHETIC,
              "scene_plots": False, "chunk_size": chunk_size,
              "theory": {"speeds": [5], "zeta_max": 1.0, "points": 3}}
    (workdir / "config" / "config.yaml").write_text(yaml.safe_dump(config))
    if broken:
        folder = workdir / "scenes" / BROKEN
        folder.mkdir(parents=True)
        (folder / "times.csv").write_text("time\nnot a number\n")
        (folder / "scene.yaml").write_text("recording: times.csv\nsensor: timestamps\n")
    return _snakemake(workdir, *WITHOUT_THEORY)


@pytest.mark.slow
def test_chunk_size_changes_no_result_and_a_broken_scene_fails_alone(tmp_path):
    single = _workflow(tmp_path / "single", 1)
    assert single.returncode == 0, single.stdout[-2000:] + single.stderr[-2000:]
    # All five scenes in one chunk: the broken one shares its process with the others.
    assert len(chunks([*SYNTHETIC, BROKEN], 8)) == 1
    chunked = _workflow(tmp_path / "chunked", 8, broken=True)
    output = chunked.stdout + chunked.stderr
    assert chunked.returncode != 0  # the failed scene is reported as failed
    assert "rule fit_chunk" in output and output.count("rule fit_chunk:") == 1
    for name in SYNTHETIC:
        first = tmp_path / "single" / "results" / f"{name}.h5"
        second = tmp_path / "chunked" / "results" / f"{name}.h5"
        assert second.is_file(), name
        assert compare_hdf5(first, second, {"created"}) is None, name
        assert (tmp_path / "chunked" / "results" / "truth" / f"{name}.csv").read_bytes() == \
            (tmp_path / "single" / "results" / "truth" / f"{name}.csv").read_bytes()
    results = tmp_path / "chunked" / "results"
    assert not (results / f"{BROKEN}.h5").exists()
    log = (results / "logs" / "fit" / f"{BROKEN}.log").read_text()
    errors = [line.split(" ERROR ", 1)[1] for line in log.splitlines() if " ERROR " in line]
    assert len(errors) == 1 and f"scenes/{BROKEN}/times.csv" in errors[0], log
    assert errors[0] in output
    assert not list(results.rglob("*.partial"))
    # Each scene's log is its own: the others' logs hold no word of the broken scene.
    for name in SYNTHETIC:
        assert BROKEN not in (results / "logs" / "fit" / f"{name}.log").read_text()
    # Rerun: nothing is fitted again; the failing scene is reported again.
    again = _snakemake(tmp_path / "chunked", *WITHOUT_THEORY)
    assert again.returncode != 0
    assert "rule fit_chunk:" not in again.stdout + again.stderr
    assert errors[0] in again.stdout + again.stderr
    before = {name: (results / f"{name}.h5").stat().st_mtime_ns for name in SYNTHETIC}
    summary = (results / "summary.csv").read_text()
    assert BROKEN in summary and "failed" in summary
    assert before == {name: (results / f"{name}.h5").stat().st_mtime_ns for name in SYNTHETIC}
    # What each written file was made from is kept beside its log; none for the broken one.
    made = sorted(path.stem for path in (results / "logs" / "fit").glob("*.fingerprint"))
    assert made == sorted(SYNTHETIC)
    # A scene added to the chunk: the chunk runs again, fits the new scene and skips the
    # others, whose files stay as they were.
    digests = {name: hashlib.sha256((results / f"{name}.h5").read_bytes()).hexdigest()
               for name in SYNTHETIC}
    config_path = tmp_path / "chunked" / "config" / "config.yaml"
    config = yaml.safe_load(config_path.read_text())
    config["synthetic"]["tiny-new"] = {**SYNTHETIC["tiny-1"], "seed": 20261125 + 9}
    config_path.write_text(yaml.safe_dump(config))
    added = _snakemake(tmp_path / "chunked", *WITHOUT_THEORY)
    assert added.returncode != 0  # the broken scene still fails
    assert (results / "tiny-new.h5").is_file()
    assert digests == {name: hashlib.sha256((results / f"{name}.h5").read_bytes()).hexdigest()
                       for name in SYNTHETIC}
    chunk_log = next((results / "logs" / "fit_chunk").glob("*.log")).read_text()
    assert all(f"{name}: up to date" in chunk_log for name in SYNTHETIC), chunk_log[-2000:]
    assert "tiny-new: fitted" in chunk_log and f"{BROKEN}: failed" in chunk_log


def test_config_noise_fits_every_scene_under_the_noise_model(tmp_path):
    """The workflow's `noise: true` reaches a scene whose scene.yaml leaves noise at its
    default (auto, which would not fit it on a clean train)."""
    import logging

    import h5py

    from dashpot.batch import fit_scene
    from dashpot.pipeline import write_synthetic_scene

    spec = {**SYNTHETIC["tiny-1"], "seed": 20261125 + 11}
    write_synthetic_scene(tmp_path / "scene", spec, name="noisy")
    written = {}
    for noise in (False, True):
        output = tmp_path / f"noise-{noise}.h5"
        fit_scene({"name": "noisy", "scene_input": str(tmp_path / "scene"), "noise": noise},
                  output, logging.getLogger("test"))
        with h5py.File(output, "r") as source:
            written[noise] = "noise_fits" in source
    assert written == {False: False, True: True}
