"""The public writers never replace a file unless asked to (``overwrite=True``).

Each writer of the Python API replaced whatever was at the path it was given: an earlier
result of hours of work, or a file of the user's that carried the output's name. Now an
existing destination is refused with one line naming it, left byte for byte as it was, with
no temporary beside it and none of the writer's other files written; ``overwrite=True``
replaces it. The final step of :func:`dashpot.atomic.atomic_path` does not clobber a file that
appeared while the output was being written either.
"""

import errno
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from cli_run import run_cli, timestamp_impacts
from write_races import race

import dashpot
from dashpot.analysis import analyze
from dashpot.atomic import atomic_path
from dashpot.errors import InputError
from dashpot.figures import load_record, save_scene_figures
from dashpot.pipeline import write_synthetic_scene
from dashpot.plots import save_figure
from dashpot.store import write_scene_fit, write_summary
from dashpot.synth.audio import write_audio
from dashpot.synth.scene import write_scene
from dashpot.synth.tables import (
    write_motion_sensor,
    write_phyphox_collision,
    write_phyphox_stopwatch,
    write_photogate,
    write_timestamps,
)
from dashpot.truth import truth_table, write_truth_csv

EARLIER = b"an earlier result the user wants to keep\n"
BALL = dict(model="IIb", beta=30.0, omega0=3000.0, g=9.81, v0=1.5)
CART = dict(model="hybrid", beta=2.0, omega0=22.0, g=2.9, v0=0.6, n_max=8)
TIMES = np.array([0.1, 0.4, 0.65, 0.85])  # s, impact times of the table writers
SPEC = {"kind": "timestamps", "model": "IIb", "beta": 30.0, "omega0": 3000.0, "g": 9.81,
        "v0": 1.5, "n_max": 12, "seed": 4, "options": {"uncertainty": 1e-5},
        "scene": {"models": ["IIb"]}}


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """A fitted timestamp train: (impact table, its scene fit, the record of its scene file)."""
    folder = tmp_path_factory.mktemp("fitted")
    _, table = timestamp_impacts(folder, 77, n_max=12, **BALL)
    impacts, scene_fit = analyze(table, models=("IIb",))
    write_scene_fit(folder / "scene.h5", scene_fit, impacts)
    return impacts, scene_fit, load_record(folder / "scene.h5")


def _figure():
    from matplotlib.figure import Figure

    figure = Figure(figsize=(2, 2))
    figure.add_subplot().plot([0, 1], [0, 1])
    return figure


def _cart():
    return dashpot.bounce_sequence(**CART)


def _writers(fitted):
    """name -> (write(folder, overwrite), the files it writes under folder)."""
    impacts, scene_fit, record = fitted
    summary = pd.DataFrame({"scene": ["a", "b"], "beta": [31.0, 29.5]})
    truth = truth_table({"model": "IIb", "beta": 30.0, "omega0": 3000.0, "g": 9.81, "v0": 1.5},
                        {})
    figures = [f"{name}.{fmt}" for name in ("intervals", "restitution", "selection")
               for fmt in ("png", "pdf")]
    return {
        "atomic_path": (lambda folder, **kw: _atomic_text(folder / "out.txt", **kw),
                        ["out.txt"]),
        "write_scene_fit": (lambda folder, **kw: write_scene_fit(folder / "fit.h5", scene_fit,
                                                                 impacts, **kw), ["fit.h5"]),
        "write_summary": (lambda folder, **kw: write_summary(folder / "summary.h5",
                                                             folder / "summary.csv", summary,
                                                             **kw),
                          ["summary.h5", "summary.csv"]),
        "save_scene_figures": (lambda folder, **kw: save_scene_figures(record, folder, **kw),
                               figures),
        "write_truth_csv": (lambda folder, **kw: write_truth_csv(folder / "truth.csv", truth,
                                                                 **kw), ["truth.csv"]),
        "save_figure": (lambda folder, **kw: save_figure(_figure(), folder / "fig", **kw),
                        ["fig.png", "fig.pdf"]),
        "write_audio": (lambda folder, **kw: write_audio(folder / "rec.wav",
                                                         np.full(800, 0.25), 8000, **kw),
                        ["rec.wav"]),
        "write_phyphox_stopwatch": (lambda folder, **kw: write_phyphox_stopwatch(
            folder / "clicks.csv", TIMES, **kw), ["clicks.csv"]),
        "write_phyphox_stopwatch_xlsx": (lambda folder, **kw: write_phyphox_stopwatch(
            folder / "clicks.xlsx", TIMES, excel=True, **kw), ["clicks.xlsx"]),
        "write_phyphox_collision_zip": (lambda folder, **kw: write_phyphox_collision(
            folder / "collision.zip", TIMES, zipped=True, **kw), ["collision.zip"]),
        "write_timestamps": (lambda folder, **kw: write_timestamps(folder / "times.csv", TIMES,
                                                                   **kw), ["times.csv"]),
        "write_motion_sensor": (lambda folder, **kw: write_motion_sensor(
            folder / "motion.csv", _cart(), **kw), ["motion.csv"]),
        "write_photogate": (lambda folder, **kw: write_photogate(
            folder / "gate.csv", _cart(), flag_length=0.02, **kw), ["gate.csv"]),
        "write_scene": (lambda folder, **kw: write_scene(folder, "timestamps", n_max=12,
                                                         **BALL, **kw),
                        ["timestamps.csv", "truth.json"]),
        "write_synthetic_scene": (lambda folder, **kw: write_synthetic_scene(
            folder, SPEC, name="synthetic", **kw), ["timestamps.csv", "truth.json",
                                                    "scene.yaml"]),
    }


def _atomic_text(path, **options):
    with atomic_path(path, **options) as temporary:
        temporary.write_text("the new output\n")


def _cases():
    names = list(_writers((None, None, None)))
    files = {name: spec[1] for name, spec in _writers((None, None, None)).items()}
    return [(name, existing) for name in names for existing in files[name]]


def _listing(folder):
    """Every name under `folder`, hidden ones (temporaries) included."""
    return sorted(str(path.relative_to(folder)) for path in Path(folder).rglob("*"))


@pytest.mark.parametrize("name, existing", _cases())
def test_an_existing_file_is_refused_and_left_as_it_was(fitted, tmp_path, name, existing):
    write, _ = _writers(fitted)[name]
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / existing).write_bytes(EARLIER)
    with pytest.raises(InputError) as refused:
        write(folder)
    assert str(refused.value) == f"{folder / existing}: exists; pass overwrite=True to replace it"
    assert len(str(refused.value).splitlines()) == 1
    assert (folder / existing).read_bytes() == EARLIER
    # No temporary, and none of the writer's other files: a refusal writes nothing.
    assert _listing(folder) == [existing]


@pytest.mark.parametrize("name, existing", _cases())
def test_overwrite_replaces_the_existing_file(fitted, tmp_path, name, existing):
    write, files = _writers(fitted)[name]
    fresh, folder = tmp_path / "fresh", tmp_path / "out"
    fresh.mkdir()
    folder.mkdir()
    write(fresh)
    (folder / existing).write_bytes(EARLIER)
    write(folder, overwrite=True)
    assert _listing(folder) == sorted(files)
    for file in files:
        if file.endswith(".h5"):  # HDF5: compared by content (a scene file holds its date)
            assert _h5_content(folder / file) == _h5_content(fresh / file), file
        else:
            assert (folder / file).read_bytes() == (fresh / file).read_bytes(), file


def _h5_content(path):
    import h5py

    items = {}
    with h5py.File(path, "r") as source:
        source.visititems(lambda key, item: items.__setitem__(
            key, repr(np.asarray(item[()]).tolist()) if isinstance(item, h5py.Dataset)
            else None))
        items["/"] = sorted(key for key in source.attrs if key != "created")
    return items


def test_a_dangling_link_is_an_existing_name(tmp_path):
    """Replacing a link to a missing file would lose where it pointed."""
    link = tmp_path / "times.csv"
    link.symlink_to(tmp_path / "elsewhere" / "times.csv")
    with pytest.raises(InputError, match="exists; pass overwrite=True"):
        write_timestamps(link, TIMES)
    assert link.is_symlink() and os.readlink(link) == str(tmp_path / "elsewhere" / "times.csv")
    assert _listing(tmp_path) == ["times.csv"]


def test_figures_are_refused_before_any_is_drawn(fitted, tmp_path, monkeypatch):
    """The decision comes before the work: drawing the figures is most of it."""
    import dashpot.figures

    def forbidden(*args, **kwargs):
        raise AssertionError("a figure was drawn")

    monkeypatch.setattr(dashpot.figures, "scene_figures", forbidden)
    (tmp_path / "selection.pdf").write_bytes(EARLIER)
    with pytest.raises(InputError, match="selection.pdf: exists"):
        save_scene_figures(fitted[2], tmp_path)
    monkeypatch.setattr(dashpot.plots, "selection_figure", forbidden)
    with pytest.raises(InputError, match="selection.pdf: exists"):
        save_figure(_figure(), tmp_path / "selection")
    assert _listing(tmp_path) == ["selection.pdf"]


# --- the final step: a file that appeared meanwhile is not clobbered ---------------------------

def test_a_file_that_appears_while_writing_is_kept(tmp_path):
    target = tmp_path / "out.csv"
    with pytest.raises(InputError, match="out.csv: exists; pass overwrite=True"):
        with atomic_path(target) as temporary:
            temporary.write_text("the new output\n")
            target.write_bytes(EARLIER)  # another program, between the check and the rename
    assert target.read_bytes() == EARLIER and _listing(tmp_path) == ["out.csv"]


@pytest.mark.parametrize("number", [errno.EPERM, errno.EOPNOTSUPP])
def test_without_hard_links_the_file_is_still_written_and_an_existing_one_refused(
        tmp_path, monkeypatch, number):
    """FAT and some network mounts have no hard links: the final step checks and renames."""
    def no_links(source, destination, **kwargs):
        raise OSError(number, os.strerror(number), str(source), None, str(destination))

    monkeypatch.setattr(os, "link", no_links)
    target = tmp_path / "out.txt"
    _atomic_text(target)
    assert target.read_text() == "the new output\n"
    target.write_bytes(EARLIER)
    with pytest.raises(InputError, match="exists"):
        _atomic_text(target)
    with pytest.raises(InputError, match="exists"):
        with atomic_path(tmp_path / "late.txt") as temporary:
            temporary.write_text("the new output\n")
            (tmp_path / "late.txt").write_bytes(EARLIER)
    assert target.read_bytes() == (tmp_path / "late.txt").read_bytes() == EARLIER
    _atomic_text(target, overwrite=True)
    assert target.read_text() == "the new output\n"
    assert _listing(tmp_path) == ["late.txt", "out.txt"]


def test_another_failure_of_the_link_is_the_write_s_own(tmp_path, monkeypatch):
    def broken_disk(source, destination, **kwargs):
        raise OSError(errno.EIO, os.strerror(errno.EIO), str(source), None, str(destination))

    monkeypatch.setattr(os, "link", broken_disk)
    with pytest.raises(OSError) as failed:
        _atomic_text(tmp_path / "out.txt")
    assert failed.value.errno == errno.EIO and failed.value.filename == str(tmp_path / "out.txt")
    assert _listing(tmp_path) == []


def test_two_writers_without_overwrite_one_wins_the_other_is_refused(tmp_path, monkeypatch):
    """Both are held just before their final step with all their bytes written: one file ends
    up in place whole, the other writer is told it exists (never a mix, never a clobber)."""
    target = tmp_path / "out.csv"
    outcomes = {variant: "written" if error is None
                else str(error) if isinstance(error, InputError) else repr(error)
                for variant, error in race(
                    monkeypatch, "link",
                    lambda variant: write_timestamps(target, TIMES + variant)).items()}
    assert sorted(outcomes.values()) == sorted(
        ["written", f"{target}: exists; pass overwrite=True to replace it"]), outcomes
    winner = next(variant for variant, outcome in outcomes.items() if outcome == "written")
    alone = tmp_path / "alone"
    alone.mkdir()
    write_timestamps(alone / "out.csv", TIMES + winner)
    assert target.read_bytes() == (alone / "out.csv").read_bytes()
    assert _listing(tmp_path) == ["alone", "alone/out.csv", "out.csv"]


# --- the command line: decided before the work; a file that appeared since is kept ------------

@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    return timestamp_impacts(tmp_path_factory.mktemp("recording"), 5, n_max=12, **BALL)[0]


def _appears_while_reading(monkeypatch, path):
    """Make the command's reader write `path` (another program) before it returns."""
    import dashpot.analysis
    import dashpot.ingest

    real = dashpot.ingest.read_impacts

    def reading(*args, **kwargs):
        path.write_bytes(EARLIER)
        return real(*args, **kwargs)

    monkeypatch.setattr(dashpot.ingest, "read_impacts", reading)
    monkeypatch.setattr(dashpot.analysis, "read_impacts", reading, raising=False)


def test_the_command_keeps_an_output_that_appeared_while_it_worked(recording, tmp_path,
                                                                   monkeypatch):
    output = tmp_path / "impacts.csv"
    _appears_while_reading(monkeypatch, output)
    status, printed, err = run_cli(["impacts", str(recording), "-o", str(output)])
    assert status == 2 and printed == ""
    assert err == f"dashpot impacts: error: {output}: exists; pass --force to replace it\n"
    assert output.read_bytes() == EARLIER and _listing(tmp_path) == ["impacts.csv"]


def test_analyze_keeps_an_output_that_appeared_while_it_worked(recording, tmp_path,
                                                               monkeypatch):
    """Nothing of the run is moved into place: not the files before the one that exists."""
    out = tmp_path / "out"
    out.mkdir()
    parameters = out / "timestamps-parameters.csv"
    _appears_while_reading(monkeypatch, parameters)
    status, _, err = run_cli(["analyze", str(recording), "-o", str(out), "--models", "IIb"])
    assert status == 2
    assert err == f"dashpot analyze: error: {parameters}: exists; pass --force to replace it\n"
    assert parameters.read_bytes() == EARLIER
    assert _listing(out) == ["timestamps-parameters.csv"]


def test_the_command_with_force_replaces(recording, tmp_path):
    output = tmp_path / "impacts.csv"
    output.write_bytes(EARLIER)
    status, _, err = run_cli(["impacts", str(recording), "-o", str(output), "--force"])
    assert status == 0, err
    assert output.read_bytes() != EARLIER and len(pd.read_csv(output)) > 2
