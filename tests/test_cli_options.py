"""The command's conventions: `-o -`, --version, `python -m dashpot`, help texts with examples
and no reST markup, one default for g, and a library that logs instead of printing."""

import logging
import re
import shlex
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from cli_run import run_cli, timestamp_impacts

import dashpot
from dashpot.cli import COMMANDS, build_parser

BALL = dict(beta=20.0, omega0=2 * np.pi * 500, g=9.80665, v0=2.0, n_max=12)


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    """A timestamp table and the impact table `dashpot impacts` writes of it."""
    return timestamp_impacts(tmp_path_factory.mktemp("options"), 1126, **BALL)


@pytest.mark.parametrize("command", ["impacts", "bounces"])
def test_dash_writes_the_table_to_standard_output(table, tmp_path, monkeypatch, command):
    """`-o -` made a file named "-" before."""
    recording, impacts = table
    source = recording if command == "impacts" else impacts
    monkeypatch.chdir(tmp_path)
    written = tmp_path / "table.csv"
    status, _, err = run_cli([command, str(source), "-o", str(written)])
    assert status == 0 and err == ""
    status, printed, err = run_cli([command, str(source), "-o", "-"])
    assert status == 0
    assert printed == written.read_text()  # the table, byte for byte, and nothing else
    assert err.startswith(f"{source}: ") and "-> standard output" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table.csv"]
    status, printed, err = run_cli([command, str(source), "-o", "-", "-q"])
    assert status == 0 and printed == written.read_text() and err == ""


@pytest.mark.parametrize("command", ["fit", "analyze"])
def test_dash_is_refused_where_the_output_is_no_table(table, tmp_path, monkeypatch, command):
    monkeypatch.chdir(tmp_path)
    status, printed, err = run_cli([command, str(table[1]), "-o", "-"])
    assert status == 2 and printed == ""
    assert err == (f"dashpot {command}: error: -: standard output takes tables only "
                   f"(impacts, bounces); give the {'HDF5 file' if command == 'fit' else 'folder'}"
                   f" to write\n")
    assert list(tmp_path.iterdir()) == []


def test_version(capsys):
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out == f"dashpot {dashpot.__version__}\n"
    assert re.fullmatch(r"\d+\.\d+\.\d+\S*", dashpot.__version__)


def test_python_dash_m_runs_the_command(tmp_path):
    run = subprocess.run([sys.executable, "-m", "dashpot", "--version"], capture_output=True,
                         text=True, timeout=120, cwd=tmp_path)
    assert run.returncode == 0 and run.stdout == f"dashpot {dashpot.__version__}\n"
    missing = tmp_path / "nope.csv"
    run = subprocess.run([sys.executable, "-m", "dashpot", "bounces", str(missing), "-o",
                          "-"], capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr == f"dashpot bounces: error: {missing}: no such file\n"


def _help(argv, capsys):
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args([*argv, "--help"])
    assert stop.value.code == 0
    return capsys.readouterr().out


@pytest.mark.parametrize("command", [None, *COMMANDS])
def test_help_is_plain_text_with_examples_that_parse(command, capsys):
    text = _help([command] if command else [], capsys)
    for markup in ("``", ":func:", ":class:", ":mod:", ":data:", "`"):
        assert markup not in text, f"reST markup {markup!r} in the help"
    examples = text.split("\nexample", 1)[1].splitlines()[1:]
    assert examples and all(line.startswith("  dashpot ") for line in examples)
    if command:
        assert all(line.split()[1] == command for line in examples)
    for line in examples:
        args = build_parser().parse_args(shlex.split(line)[1:])
        assert args.command == line.split()[1]


def test_bounces_uses_standard_gravity_by_default(table, tmp_path):
    """One default g for every command: 9.80665 m/s² (bounces had 9.81)."""
    _, impacts = table
    output = tmp_path / "bounces.csv"
    assert run_cli(["bounces", str(impacts), "-o", str(output)])[0] == 0
    bounces = pd.read_csv(output)
    times = pd.read_csv(impacts)["time"].to_numpy()
    intervals = np.diff(times)
    np.testing.assert_allclose(bounces["interval"], intervals, rtol=1e-12)
    # Flight-time rebound speed v = g·T/2 of a ball flying under standard gravity (CGPM 1901).
    np.testing.assert_allclose(bounces["rebound_speed"], 9.80665 * intervals / 2, rtol=1e-12)
    assert dashpot.scene.Scene().gravity == dashpot.scene.STANDARD_GRAVITY == 9.80665


def test_the_library_logs_and_prints_nothing(table, capsys, caplog):
    from dashpot.analysis import analyze

    _, impacts = table
    with caplog.at_level(logging.INFO, logger="dashpot"):
        found, scene_fit = analyze(impacts, models=["Ia", "IIa"])
    assert capsys.readouterr() == ("", "")
    messages = [record.getMessage() for record in caplog.records
                if record.name == "dashpot.analysis"]
    assert messages[0] == f"{impacts}: {len(found)} impacts (impact table)"
    assert [message.split()[1] for message in messages[2:]] == ["Ia", "IIa"]
    assert set(scene_fit.results) == {"Ia", "IIa"}


@pytest.mark.parametrize("command", ["impacts", "bounces", "fit", "analyze"])
def test_an_empty_output_name_is_refused_by_name(table, tmp_path, monkeypatch, capsys,
                                                 command):
    """`-o ""` (an unset shell variable) was taken for the current folder: "cannot write
    the output (Device or resource busy)" naming ".", or ": is a folder"."""
    from dashpot.cli import main

    recording, impacts = table
    source = recording if command in ("impacts", "analyze") else impacts
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as stop:
        main([command, str(source), "-o", ""])
    assert stop.value.code == 2
    printed, err = capsys.readouterr()
    assert printed == ""
    assert err == (f"dashpot {command}: error: argument -o/--output: empty: give the name of "
                   f"the output (see dashpot {command} --help)\n")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("option", "value", "reader"), [
    ("--flag-length", "0.02", "photogate"), ("--gate-distance", "0.1", "photogate"),
    ("--bumper-position", "0.5", "motion-sensor"), ("--track", "mass A", "motion-sensor")])
def test_a_reader_option_for_another_kind_of_file_is_refused(tmp_path, option, value, reader):
    # Given for a timestamp table, these options were ignored without a word: the user took
    # them to apply.
    table = tmp_path / "impacts.csv"
    table.write_text("time\n0.1\n0.5\n0.82\n1.08\n1.29\n")
    written = tmp_path / "out.csv"
    status, _, err = run_cli(["impacts", str(table), option, value, "-o", str(written)])
    assert status == 2 and not written.exists()
    line = err.strip()
    assert "\n" not in line and str(table) in line
    assert f"({option}) is for {reader} files" in line and "read as timestamps" in line
    # The option of the reader that reads the file stays accepted.
    assert run_cli(["impacts", str(table), "--unit", "s", "-o", str(written)])[0] == 0
