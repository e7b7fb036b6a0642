"""Every writer of the project: a unique temporary beside the output, renamed into place only
when complete; nothing partial after a full disk, an unwritable path or two writers at once;
CSV floats that read back bit for bit, whatever the clock's offset."""

import os
import runpy
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from cli_run import run_cli, timestamp_impacts
from write_races import race

import dashpot
from dashpot.atomic import atomic_path
from dashpot.ingest import read_impacts
from dashpot.plots import save_figure
from dashpot.store import read_fit, write_summary
from dashpot.synth.audio import impact_sound, write_audio
from dashpot.synth.tables import write_timestamps

THEORY = Path(__file__).resolve().parents[1] / "workflow" / "scripts" / "theory.py"
BALL = dict(model="IIb", beta=30.0, omega0=3000.0, g=9.81, v0=1.5)
SIGMA = 1e-5  # s, timing noise of the synthetic trains
OFFSETS = (1e6, 1.7e9)  # s: a long-running clock and Unix-epoch time


def _temporaries(folder):
    return sorted(p.name for p in Path(folder).rglob(".*"))


def _bits(values):
    return np.asarray(values, dtype=float).view(np.uint64)


# --- the shared helper -------------------------------------------------------------------------

def test_temporaries_are_unique_and_get_the_usual_permissions(tmp_path):
    target = tmp_path / "out.csv"
    previous = os.umask(0o027)
    try:
        with atomic_path(target, overwrite=True) as first, \
                atomic_path(target, overwrite=True) as second:
            assert first != second and first.parent == second.parent == tmp_path
            assert first.name.startswith(".out.csv.") and first.name.endswith(".partial")
            first.write_text("first")
            second.write_text("second")
    finally:
        os.umask(previous)
    # 0o666 less the umask (not mkstemp's 0o600): a group may read the results.
    assert target.stat().st_mode & 0o777 == 0o640
    assert target.read_text() == "first" and _temporaries(tmp_path) == []


# --- two writers of one output at once ---------------------------------------------------------

def _figure(variant):
    from matplotlib.figure import Figure

    figure = Figure(figsize=(2, 2))
    figure.add_subplot().plot([0, 1], [variant, 1 - variant])
    return figure


def _write_csv(path, variant):
    from dashpot.cli import _write_csv_atomically

    _write_csv_atomically(pd.DataFrame({"time": np.arange(2000.0) + variant / 3}), path, [],
                          force=True)


# Each replaces what is there (the other writer's file): with overwrite=False one of two
# writers is refused instead (test_overwrite.py).
WRITERS = {
    "cli_csv": _write_csv,
    "summary": lambda path, variant: write_summary(
        path, path.with_suffix(".csv"), pd.DataFrame({"scene": ["a", "b"],
                                                      "beta": [variant + 0.1, 2000.0]}),
        overwrite=True),
    "figure": lambda path, variant: save_figure(_figure(variant), path, overwrite=True),
    "timestamps": lambda path, variant: write_timestamps(path, np.arange(1.0, 500.0) + variant,
                                                         overwrite=True),
    "audio": lambda path, variant: write_audio(path, np.full(4000, 0.1 + 0.1 * variant), 8000,
                                               overwrite=True),
}


def _outputs(path, name):
    if name == "figure":
        return [path.with_name(path.name + ".png"), path.with_name(path.name + ".pdf")]
    if name == "summary":
        return [path, path.with_suffix(".csv")]
    return [path]


@pytest.mark.parametrize("name", list(WRITERS))
def test_two_writers_of_one_output_never_mix(tmp_path, monkeypatch, name):
    """Both writers are held just before their rename, with all their bytes written: each
    must have its own temporary, and the output must be one writer's whole file."""
    write = WRITERS[name]
    suffix = {"audio": ".wav", "summary": ".h5", "figure": ""}.get(name, ".csv")
    alone = {}
    for variant in (0, 1):
        folder = tmp_path / f"alone{variant}"
        folder.mkdir()
        write(folder / f"out{suffix}", variant)
        alone[variant] = [p.read_bytes() for p in _outputs(folder / f"out{suffix}", name)]
    assert alone[0] != alone[1]

    shared = tmp_path / "shared"
    shared.mkdir()
    target = shared / f"out{suffix}"
    outcomes = race(monkeypatch, "replace", lambda variant: write(target, variant))
    assert outcomes == {0: None, 1: None}, outcomes
    for index, output in enumerate(_outputs(target, name)):
        assert output.read_bytes() in (alone[0][index], alone[1][index]), output.name
    assert _temporaries(shared) == []


# --- CSV floats read back bit for bit; the fit does not care where the clock starts -----------

def _train(count, seed):
    """Impact times (s) of a noisy train whose first impact is at 0.5 s."""
    sequence = dashpot.bounce_sequence(**BALL, n_max=count)
    noise = np.random.default_rng(seed).normal(0.0, SIGMA, sequence.impact_times.size)
    return 0.5 + sequence.impact_times + noise


def _impacts_beta_eps(folder, raw):
    """`dashpot impacts`, `fit` and `bounces` on a recording: impact table, β, ε."""
    impacts = folder / "impacts.csv"
    assert run_cli(["impacts", str(raw), "-o", str(impacts)])[0] == 0
    status, _, err = run_cli(["fit", str(impacts), "-o", str(folder / "fit.h5"), "--models",
                              "IIb"])
    assert status == 0, err
    beta = read_fit(folder / "fit.h5")["fits"]["IIb"]["parameters"].loc["beta"]
    status, _, err = run_cli(["bounces", str(impacts), "-o", str(folder / "bounces.csv")])
    assert status == 0, err
    return impacts, beta, pd.read_csv(folder / "bounces.csv")


def test_impact_tables_read_back_bit_for_bit_at_any_time_offset(tmp_path):
    """Impact times written with 10 significant digits lost 1 ms at 1e6 s and whole seconds
    at Unix-epoch times; a CSV must hold every bit, and β and ε must not move."""
    train = _train(40, seed=5150)
    results = {}
    for offset in (0.0, *OFFSETS):
        folder = tmp_path / f"offset{offset:g}"
        folder.mkdir()
        raw = folder / "times.csv"
        write_timestamps(raw, offset + train, uncertainty=SIGMA, decimals=9)
        impacts, beta, bounces = _impacts_beta_eps(folder, raw)
        in_memory = read_impacts(raw)
        back = pd.read_csv(impacts)
        assert list(back.columns) == list(in_memory.columns)
        for column in back.columns:
            assert np.array_equal(_bits(back[column]), _bits(in_memory[column]),
                                  equal_nan=True), (offset, column)
        results[offset] = beta, bounces
    beta0, bounces0 = results[0.0]
    for offset in OFFSETS:
        beta, bounces = results[offset]
        # The recordings differ only by the clock's rounding (≤ 0.12 µs, σ = 10 µs).
        assert abs(beta["value"] - beta0["value"]) < 0.01 * beta0["stderr"], offset
        assert beta["stderr"] == pytest.approx(beta0["stderr"], rel=1e-3)
        ok = bounces0["restitution_uncertainty"].to_numpy() > 0
        difference = np.abs(bounces["restitution"] - bounces0["restitution"]).to_numpy()
        assert np.all(difference[ok] < 0.05 * bounces0["restitution_uncertainty"][ok]), offset


def test_the_fit_is_the_same_wherever_the_clock_starts(tmp_path):
    """Times that are exact at every offset (multiples of 2⁻²²) must give the same fit bit
    for bit: the fit works with times since the first impact."""
    train = np.round(_train(40, seed=90210) * 2.0 ** 22) / 2.0 ** 22
    fits = {}
    for offset in (0.0, *OFFSETS):
        assert np.array_equal((offset + train) - offset, train)
        table = tmp_path / f"impacts{offset:g}.csv"
        pd.DataFrame({"time": offset + train, "time_uncertainty": SIGMA}).to_csv(table,
                                                                                 index=False)
        output = tmp_path / f"fit{offset:g}.h5"
        status, _, err = run_cli(["fit", str(table), "-o", str(output), "--models", "IIb",
                                  "Ia"])
        assert status == 0, err
        fits[offset] = read_fit(output)
    for offset in OFFSETS:
        for model in ("IIb", "Ia"):
            got, want = (fits[key]["fits"][model] for key in (offset, 0.0))
            assert got["attrs"]["chisqr"] == want["attrs"]["chisqr"], (offset, model)
            for name in ("beta", "omega0", "v0"):
                assert got["parameters"].loc[name, "value"] == \
                    want["parameters"].loc[name, "value"], (offset, model, name)
            # t0 and the predicted times are on the table's clock.
            t0 = got["parameters"].loc["t0", "value"]
            assert abs(t0 - offset - want["parameters"].loc["t0", "value"]) <= \
                np.spacing(offset + 1.0)
            assert abs(got["predicted"]["at_data"][0] - (offset + train[0])) < 5 * SIGMA
        assert fits[offset]["attrs"]["verdict"] == fits[0.0]["attrs"]["verdict"]


def test_twenty_minute_recording(tmp_path):
    """A bounce train 20 minutes into a recording: the impact table on disk is the one in
    memory, bit for bit, and fitting it gives the fit of the recording itself."""
    sequence = dashpot.bounce_sequence(**BALL, n_max=20)
    samples, onsets = impact_sound(sequence.impact_times, sequence.impact_speeds,
                                   sample_rate=8000, lead_in=1200.0, seed=31337)
    recording = write_audio(tmp_path / "long.wav", samples, 8000)
    del samples
    impacts = tmp_path / "impacts.csv"
    status, _, err = run_cli(["impacts", str(recording), "-o", str(impacts)])
    assert status == 0, err
    in_memory = read_impacts(recording)
    assert in_memory["time"].iloc[0] > 1199.0
    back = pd.read_csv(impacts)
    for column in in_memory.columns:
        assert np.array_equal(_bits(back[column]), _bits(in_memory[column]), equal_nan=True), \
            column
    betas = []
    for source in (recording, impacts):
        output = tmp_path / f"{Path(source).stem}.h5"
        status, _, err = run_cli(["fit", str(source), "-o", str(output), "--models", "IIb"])
        assert status == 0, err
        betas.append(read_fit(output)["fits"]["IIb"]["parameters"].loc["beta"])
    assert betas[0]["value"] == betas[1]["value"]
    assert abs(betas[1]["value"] - BALL["beta"]) < 4 * betas[1]["stderr"]


# --- a full disk ---------------------------------------------------------------------------

@pytest.fixture
def full_disk(tmp_path):
    """A 64 KiB tmpfs holding an old result and filled to the last byte."""
    mount = tmp_path / "full"
    mount.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mount)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs to fill ({done.stderr.strip() or 'mount'}"
                    "): the full-disk tests need root in a sandbox that allows mounts")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)


def _fill(folder, leave=0):
    """Take every free byte of the file system of `folder` but `leave` bytes."""
    filler = folder / "filler"
    with open(filler, "wb", buffering=0) as handle:
        for size in (4096, 1):
            try:
                while handle.write(b"\0" * size):
                    pass
            except OSError:
                pass
    os.truncate(filler, filler.stat().st_size - leave)


def _old_result(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"previous result")
    return path


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    """A timestamp recording of a train and its impact table."""
    return timestamp_impacts(tmp_path_factory.mktemp("ball"), 808, n_max=15, **BALL)


def _one_line_no_space(err, command, output):
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"dashpot {command}: error: {output}"), err
    assert "cannot write the output (No space left on device)" in err


def test_fit_on_a_full_disk(full_disk, ball):
    """HDF5 running out of space in the middle of a file crashed the process at exit (SIGSEGV,
    status 139) after many traceback lines: a separate process shows both."""
    output = _old_result(full_disk / "ball.h5")
    _fill(full_disk, leave=16384)  # room to start the file (about 50 kB), not to finish it
    done = subprocess.run([sys.executable, "-m", "dashpot.cli", "fit", str(ball[1]), "-o",
                           str(output), "--models", "IIb", "--force"], capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 2, done.stderr[-2000:]
    _one_line_no_space(done.stderr, "fit", output)
    assert output.read_bytes() == b"previous result"
    assert sorted(p.name for p in full_disk.iterdir()) == ["ball.h5", "filler"]


def test_impacts_on_a_full_disk(full_disk, ball):
    output = _old_result(full_disk / "impacts.csv")
    _fill(full_disk)
    status, out, err = run_cli(["impacts", str(ball[0]), "-o", str(output), "--force"])
    assert status == 2 and out == ""
    _one_line_no_space(err, "impacts", output)
    assert output.read_bytes() == b"previous result"
    assert sorted(p.name for p in full_disk.iterdir()) == ["filler", "impacts.csv"]


def test_analyze_on_a_full_disk(full_disk, ball):
    """Staged beside the destination: nothing is moved across file systems, nothing partial
    (once a truncated PDF) is left, the old result stays."""
    out = full_disk / "out"
    old = _old_result(out / "timestamps.h5")
    _fill(full_disk)
    status, printed, err = run_cli(["analyze", str(ball[0]), "-o", str(out), "--models", "IIb",
                                    "--force"])
    assert status == 2 and printed == ""
    _one_line_no_space(err, "analyze", out)
    assert old.read_bytes() == b"previous result"
    assert sorted(p.name for p in out.iterdir()) == ["timestamps.h5"]


def test_analyze_stages_inside_the_output_folder(tmp_path, ball, monkeypatch):
    """Every staged file is renamed (or, where it must not replace a file, hard-linked) within
    the output folder's file system, never copied."""
    renames = []
    real_replace, real_link = os.replace, os.link

    def recording(real):
        def move(source, destination, **kwargs):
            renames.append((Path(source), Path(destination)))
            real(source, destination, **kwargs)
        return move

    monkeypatch.setattr(os, "replace", recording(real_replace))
    monkeypatch.setattr(os, "link", recording(real_link))
    out = tmp_path / "out"
    status, _, err = run_cli(["analyze", str(ball[0]), "-o", str(out), "--models", "IIb"])
    assert status == 0, err
    moved = {destination for _, destination in renames}
    written = {p for p in out.rglob("*") if p.is_file()}
    assert written and written <= moved
    assert all(out in source.parents for source, _ in renames)
    assert _temporaries(out) == []


def test_theory_writer_on_a_full_disk(full_disk, tmp_path):
    """The workflow's theory script fails with one line and status 2 on a full disk, and
    leaves no temporary behind (it once left a .partial)."""
    critical = _old_result(full_disk / "critical.csv")
    _fill(full_disk)
    snakemake = SimpleNamespace(
        log=[str(tmp_path / "theory.log")],
        params=SimpleNamespace(zeta_max=1.0, points=200, speeds=[0.5, 2.0]),
        output=SimpleNamespace(critical=str(critical),
                               restitution=str(full_disk / "restitution.csv")))
    code = ("import runpy, sys, types\n"
            "ns = types.SimpleNamespace\n"
            f"snakemake = {_namespace_source(snakemake)}\n"
            f"runpy.run_path({str(THEORY)!r}, init_globals={{'snakemake': snakemake}})\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 2, done.stderr[-2000:]
    assert done.stderr == f"{critical}: cannot write the output (No space left on device)\n"
    assert critical.read_bytes() == b"previous result"
    assert sorted(p.name for p in full_disk.iterdir()) == ["critical.csv", "filler"]


def test_theory_writer_writes_whole_files(tmp_path):
    figures = ("contact_time", "restitution_figure", "critical_speed", "restitution_vs_speed")
    snakemake = SimpleNamespace(
        log=[str(tmp_path / "theory.log")],
        params=SimpleNamespace(zeta_max=1.0, points=50, speeds=[0.5]),
        output=SimpleNamespace(critical=str(tmp_path / "critical.csv"),
                               restitution=str(tmp_path / "restitution.csv"),
                               **{name: str(tmp_path / f"{name}.png") for name in figures}))
    runpy.run_path(str(THEORY), init_globals={"snakemake": snakemake})
    assert len(pd.read_csv(tmp_path / "critical.csv")) == 50
    for name in figures:  # the figures of the same job, PNG and PDF
        assert (tmp_path / f"{name}.png").stat().st_size > 0
        assert (tmp_path / f"{name}.pdf").stat().st_size > 0
    assert _temporaries(tmp_path) == []


def _namespace_source(value):
    if isinstance(value, SimpleNamespace):
        return "ns(" + ", ".join(f"{key}={_namespace_source(item)}"
                                 for key, item in vars(value).items()) + ")"
    return repr(value)


# --- an output path that cannot be written -------------------------------------------------

def _unwritable(tmp_path, kind, name):
    if kind == "proc":
        return Path("/proc/x") / name  # /proc takes no new folders, even from root
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    return blocker / name


@pytest.mark.parametrize("kind", ["proc", "under_a_file"])
@pytest.mark.parametrize("command", ["impacts", "bounces", "fit", "analyze"])
def test_unwritable_output_path(tmp_path, ball, command, kind):
    recording, table = ball
    name = {"impacts": "out.csv", "bounces": "out.csv", "fit": "out.h5", "analyze": "out"}
    output = _unwritable(tmp_path, kind, name[command])
    source = recording if command in ("impacts", "analyze") else table
    argv = [command, str(source), "-o", str(output)]
    if command in ("fit", "analyze"):
        argv += ["--models", "IIb"]
    status, out, err = run_cli(argv)
    assert status == 2 and out == ""
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"dashpot {command}: error: {output}: cannot write the output ("), err
    assert not output.exists()
    assert _temporaries(tmp_path) == []


def test_a_workflow_job_on_a_full_disk_fails_with_one_line(full_disk, tmp_path, ball):
    """A workflow job whose output cannot be written logs one line naming the output (not
    its temporary, not a traceback) and exits 1; the earlier result stays."""
    from dashpot.analysis import analyze
    from dashpot.joblog import job_log
    from dashpot.store import write_scene_fit

    _, table = ball
    impacts, scene_fit = analyze(table, models=("Ib",))
    output = _old_result(full_disk / "scene.h5")
    _fill(full_disk)
    log = tmp_path / "fit.log"
    with pytest.raises(SystemExit) as stopped:
        with job_log(log, "fit scene"):
            write_scene_fit(output, scene_fit, impacts, input_path=table, overwrite=True)
    assert stopped.value.code == 1
    errors = [line for line in log.read_text().splitlines() if " ERROR " in line]
    assert len(errors) == 1 and "Traceback" not in log.read_text()
    assert errors[0].endswith(f"{output}: No space left on device"), errors
    assert output.read_bytes() == b"previous result"
    assert _temporaries(full_disk) == []


def test_a_job_with_a_bad_input_says_one_line_on_stderr_and_in_its_log(tmp_path, capfd):
    """The job's error line goes through logging (no print in the library): one line naming
    the file on standard error, the same in the log, exit status 1, no traceback."""
    from dashpot.errors import InputError
    from dashpot.joblog import job_log

    log = tmp_path / "logs" / "job.log"
    with pytest.raises(SystemExit) as exit_info:
        with job_log(log, "fit scene demo"):
            raise InputError("scenes/demo/rec.wav", "not a readable audio file")
    assert exit_info.value.code == 1
    err = capfd.readouterr().err.strip().splitlines()
    assert err == ["dashpot (fit scene demo): error: scenes/demo/rec.wav: not a readable "
                   "audio file"]
    text = log.read_text()
    assert "not a readable audio file" in text and "Traceback" not in text
