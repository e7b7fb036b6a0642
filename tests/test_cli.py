"""The dashpot command: outputs, one-line errors with exit status 2, nothing half written."""

import numpy as np
import pandas as pd
import pytest

from dashpot.cli import main
from dashpot.synth.scene import write_scene

BALL = dict(beta=20.0, omega0=2 * np.pi * 500, g=9.81, v0=2.0, n_max=30)


def test_impacts_then_bounces(tmp_path, capsys):
    recording = write_scene(tmp_path, "timestamps", **BALL)
    impacts = tmp_path / "out" / "impacts.csv"
    assert main(["impacts", str(recording), "-o", str(impacts)]) == 0
    table = pd.read_csv(impacts)
    assert len(table) == 30 and np.all(np.diff(table["time"]) > 0)
    bounces = tmp_path / "bounces.csv"
    assert main(["bounces", str(impacts), "-o", str(bounces), "--g", "9.81"]) == 0
    assert len(pd.read_csv(bounces)) == 29
    assert "30 impacts" in capsys.readouterr().out


@pytest.mark.parametrize("content,problem", [
    (b"", "empty"),
    (b"speed,height\n1,2\n3,4\n", "not a table of impacts"),
    (b"time (s)\n0.1\n0.5\n0.4\n", "row"),
])
def test_bad_tables_fail_cleanly(tmp_path, capsys, content, problem):
    source = tmp_path / "lab.csv"
    source.write_bytes(content)
    output = tmp_path / "impacts.csv"
    assert main(["impacts", str(source), "-o", str(output)]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and str(source) in error and problem in error
    assert not output.exists()
    assert not list(tmp_path.glob(".*partial"))


def test_missing_file_and_input_protection(tmp_path, capsys):
    assert main(["impacts", str(tmp_path / "nope.wav"), "-o", str(tmp_path / "x.csv")]) == 2
    assert "no such file" in capsys.readouterr().err
    recording = write_scene(tmp_path, "timestamps", **BALL)
    before = recording.read_bytes()
    assert main(["impacts", str(recording), "-o", str(recording)]) == 2
    assert "refusing to overwrite the input" in capsys.readouterr().err
    assert recording.read_bytes() == before


def test_bounces_needs_a_time_column(tmp_path, capsys):
    table = tmp_path / "t.csv"
    table.write_text("when\n1\n2\n3\n")
    assert main(["bounces", str(table), "-o", str(tmp_path / "b.csv")]) == 2
    assert "no 'time' column" in capsys.readouterr().err


def test_bounces_of_a_recording_says_to_find_its_impacts_first(tmp_path, capsys):
    recording = _write_wav(tmp_path / "drop.wav", np.zeros(44100))
    output = tmp_path / "b.csv"
    assert main(["bounces", str(recording), "-o", str(output)]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and str(recording) in error
    assert f"dashpot impacts {recording} -o impacts.csv" in error
    assert not output.exists()


def _write_wav(path, samples, rate=44100):
    from dashpot.synth.audio import write_audio

    write_audio(path, samples, rate)
    return path


@pytest.mark.parametrize("case", ["empty", "not audio", "truncated", "silence", "noise",
                                  "single impact"])
def test_bad_recordings_fail_cleanly(tmp_path, capsys, case):
    from dashpot.synth.audio import impact_sound

    source = tmp_path / "drop.wav"
    rng = np.random.default_rng(0)
    if case == "empty":
        source.write_bytes(b"")
    elif case == "not audio":
        source.write_text("time,height\n1,2\n")
    elif case == "truncated":
        samples, _ = impact_sound(np.array([0.0, 0.3, 0.55]), np.array([2.0, 1.8, 1.6]))
        _write_wav(source, samples)
        source.write_bytes(source.read_bytes()[: 44 + 2000])
    elif case == "silence":
        _write_wav(source, np.zeros(44100))
    elif case == "noise":
        _write_wav(source, 0.05 * rng.standard_normal(44100))
    else:
        samples, _ = impact_sound(np.array([0.0]), np.array([2.0]), duration=1.0)
        _write_wav(source, samples)
    output = tmp_path / "impacts.csv"
    assert main(["impacts", str(source), "-o", str(output)]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and str(source) in error
    assert not output.exists() and not list(tmp_path.glob(".*partial"))


@pytest.mark.parametrize("command", ["impacts", "bounces", "fit", "analyze"])
def test_a_folder_given_as_the_input_is_named_as_one(tmp_path, capsys, command):
    """A folder named like a table was reported as "no such file"."""
    folder = tmp_path / "impacts.csv"
    folder.mkdir()
    output = tmp_path / "out"
    assert main([command, str(folder), "-o", str(output)]) == 2
    assert capsys.readouterr().err == (f"dashpot {command}: error: {folder}: is a folder, "
                                       f"not a file\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["impacts.csv"]


@pytest.mark.parametrize("command", ["impacts", "bounces", "fit"])
def test_a_table_that_cannot_be_read_fails_cleanly(tmp_path, capsys, monkeypatch, command):
    """A table the system refuses to read (no permission, a failing disk) raised a traceback."""
    from pathlib import Path

    source = tmp_path / "impacts.csv"
    source.write_text("time,time_uncertainty\n0.0,1e-5\n0.3,1e-5\n0.585,1e-5\n")
    read_bytes = Path.read_bytes

    def refused(path):
        if path == source:
            raise PermissionError(13, "Permission denied")
        return read_bytes(path)

    monkeypatch.setattr(Path, "read_bytes", refused)
    output = tmp_path / "out.csv"
    assert main([command, str(source), "-o", str(output)]) == 2
    assert capsys.readouterr().err == (f"dashpot {command}: error: {source}: cannot read the "
                                       f"file (Permission denied)\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["impacts.csv"]


@pytest.mark.parametrize("command", ["bounces", "fit"])
def test_a_run_number_too_large_to_read_exactly_is_refused(tmp_path, capsys, command):
    """A run of 1e30 was written as run -9223372036854775808."""
    source = tmp_path / "impacts.csv"
    times = np.cumsum(np.r_[0.0, 0.3 * 0.95 ** np.arange(9)])
    source.write_text("time,time_uncertainty,run\n"
                      + "".join(f"{float(t)!r},1e-5,{'1e30' if k else 0}\n" for k, t in enumerate(times)))
    output = tmp_path / "out"
    assert main([command, str(source), "-o", str(output)]) == 2
    assert capsys.readouterr().err == (
        f"dashpot {command}: error: {source}, row 2, column 'run': run '1e30' is too large "
        f"(runs are numbered from 0 to 9007199254740991)\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["impacts.csv"]
