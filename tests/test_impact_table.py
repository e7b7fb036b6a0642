"""One impact-table reader for every command: dashpot's own impact table, however re-saved.

The impact tables here are written by ``dashpot impacts`` itself (from a timestamp list or a
two-run motion-sensor export), then re-saved the way Excel writes them: "CSV UTF-8" (a byte-order
mark), a European "CSV" (semicolons, decimal commas, CRLF, a byte-order mark) and "Unicode text"
(UTF-16 LE with a byte-order mark, tab separated, CRLF). Every bad cell must give one line naming
the file, the row and the column, exit status 2 and no output.
"""

from __future__ import annotations

import json
import struct

import h5py
import numpy as np
import pandas as pd
import pytest
import soundfile as sf

import dashpot
from cli_run import run_cli
from dashpot.analysis import scene_impacts
from dashpot.fit import prepare_data
from dashpot.ingest.audio import detect_impacts
from dashpot.scene import Scene
from dashpot.synth.audio import impact_sound, write_audio
from dashpot.synth.tables import write_motion_sensor, write_timestamps

BALL = dict(model="Ia", beta=20.0, omega0=2 * np.pi * 400, g=9.81, v0=2.0, n_max=20)
CART = dict(model="Ib", beta=8.0, omega0=300.0, g=0.5, v0=0.5, v_min=0.05)


@pytest.fixture(scope="module")
def ball():
    return dashpot.bounce_sequence(**BALL)


def _impact_table(folder, times, sigma=None):
    """An impact table written by ``dashpot impacts`` from a list of times (and their σ)."""
    source = folder / "times.csv"
    write_timestamps(source, times, uncertainty=sigma)
    output = folder / "imp.csv"
    status, _, err = run_cli(["impacts", str(source), "-o", str(output)])
    assert status == 0, err
    return output


def _edit_cell(path, row, column, text):
    """Replace one cell of a comma-separated table (row counted after the header, from 1)."""
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    fields = lines[row].split(",")
    fields[header.index(column)] = text
    lines[row] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")


def _error_line(err):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return lines[0]


# ------------------------------------------------------------------------ runs (point 3)

def test_bounces_are_computed_within_each_run(tmp_path):
    """Two PASCO runs interleave in time: intervals and ε come from each run on its own."""
    sequence = dashpot.bounce_sequence(**CART)
    recording = tmp_path / "cart.csv"
    write_motion_sensor(recording, sequence, runs=2, noise=1e-3, seed=23)
    impacts = tmp_path / "imp.csv"
    assert run_cli(["impacts", str(recording), "-o", str(impacts)])[0] == 0
    table = pd.read_csv(impacts)
    assert sorted(table["run"].unique()) == [0, 1]
    assert np.any(np.diff(table["run"]) < 0)  # in time order the runs interleave
    output = tmp_path / "bounces.csv"
    status, out, err = run_cli(["bounces", str(impacts), "-o", str(output), "--g", "0.5"])
    assert status == 0, err
    bounces = pd.read_csv(output)
    ratios = bounces["restitution"].dropna()
    assert ratios.between(0.3, 1.0).all(), ratios.describe()
    assert len(bounces) == len(table) - 2
    assert list(bounces.columns) == list(dashpot.bounces.BOUNCE_COLUMNS)
    for run in (0, 1):
        times = table.loc[table["run"] == run, "time"].to_numpy()
        mine = bounces[bounces["run"] == run]
        np.testing.assert_array_equal(mine["bounce"], np.arange(times.size - 1))
        np.testing.assert_allclose(mine["interval"], np.diff(times), rtol=1e-12)


def test_times_must_increase_within_a_run(tmp_path, ball):
    impacts = _impact_table(tmp_path, ball.impact_times + 1.0, sigma=np.full(20, 1e-5))
    _edit_cell(impacts, 5, "time", "1.0")
    output = tmp_path / "bounces.csv"
    status, _, err = run_cli(["bounces", str(impacts), "-o", str(output)])
    assert status == 2
    assert _error_line(err).startswith(f"dashpot bounces: error: {impacts}, row 5, column "
                                       f"'time': impact times must increase within a run: "
                                       f"1.0 s is not after")
    assert not output.exists()


# ------------------------------------------------------------- bad cells (points 3, 15)

BAD_CELLS = {
    "empty time": ("time", "", "impact time is empty"),
    "NaN time": ("time", "NaN", "impact time 'NaN' is not a finite number"),
    "inf time": ("time", "inf", "impact time 'inf' is not a finite number"),
    "text time": ("time", "1.2s", "'1.2s' is not a number"),
    "text sigma": ("time_uncertainty", "n.a.", "'n.a.' is not a number"),
    "negative sigma": ("time_uncertainty", "-1e-05", "'-1e-05' is negative"),
    "infinite sigma": ("time_uncertainty", "inf", "'inf' is infinite"),
    "fractional run": ("run", "0.5", "run '0.5' is not a whole number ≥ 0"),
}


@pytest.mark.parametrize("command", ["bounces", "fit"])
@pytest.mark.parametrize("case", BAD_CELLS)
def test_a_bad_cell_names_file_row_and_column(tmp_path, ball, command, case):
    column, text, problem = BAD_CELLS[case]
    impacts = _impact_table(tmp_path, ball.impact_times + 0.25, sigma=np.full(20, 1e-5))
    _edit_cell(impacts, 7, column, text)
    output = tmp_path / ("out.csv" if command == "bounces" else "out.h5")
    status, _, err = run_cli([command, str(impacts), "-o", str(output)])
    assert status == 2
    assert _error_line(err) == (f"dashpot {command}: error: {impacts}, row 7, column "
                                f"'{column}': {problem}")
    assert not output.exists()


def test_unknown_uncertainty_stays_unknown(tmp_path, ball):
    """A NaN σ is unknown: the intervals and ratios using that impact get NaN, never 0."""
    impacts = _impact_table(tmp_path, ball.impact_times, sigma=np.full(20, 2e-5))
    _edit_cell(impacts, 6, "time_uncertainty", "NaN")  # impact 5 (0-based)
    output = tmp_path / "bounces.csv"
    status, out, err = run_cli(["bounces", str(impacts), "-o", str(output)])
    assert status == 0, err
    bounces = pd.read_csv(output)
    interval_sigma = bounces["interval_uncertainty"].to_numpy()
    ratio_sigma = bounces["restitution_uncertainty"].to_numpy()[:-1]
    unknown_intervals = np.isin(np.arange(19), [4, 5])  # intervals 4 and 5 end/start at it
    assert np.all(np.isnan(interval_sigma[unknown_intervals]))
    assert np.all(interval_sigma[~unknown_intervals] > 0)
    unknown_ratios = np.isin(np.arange(18), [3, 4, 5])  # ratios using impact 5
    assert np.all(np.isnan(ratio_sigma[unknown_ratios]))
    assert np.all(ratio_sigma[~unknown_ratios] > 0)
    assert "without an uncertainty" in out


# ------------------------------------------------------------ one zero σ (point 8)

def test_one_zero_uncertainty_keeps_the_others(tmp_path, ball):
    rng = np.random.default_rng(20240917)
    sigma = rng.uniform(1e-5, 5e-5, 20)
    impacts = _impact_table(tmp_path, ball.impact_times, sigma=sigma)
    _edit_cell(impacts, 9, "time_uncertainty", "0")
    table = scene_impacts(impacts)
    data = prepare_data(table, Scene())
    assert data.sigma_known
    kept = np.arange(20) != 8
    np.testing.assert_array_equal(data.sigma[kept], table["time_uncertainty"].to_numpy()[kept])
    assert data.sigma[8] == table["time_uncertainty"].to_numpy()[kept].min()
    status, out, err = run_cli(["fit", str(impacts), "-o", str(tmp_path / "fit.h5"),
                                "--models", "Ia"])
    assert status == 0, err
    assert "note: 1 of 20 timing uncertainties zero or missing" in out


# ----------------------------------------------------- spreadsheet re-saves (point 15)

def _excel_utf8(text):
    return b"\xef\xbb\xbf" + text.replace("\n", "\r\n").encode()


def _excel_european(text):
    """Excel's "CSV" on a German/French system: ';', decimal commas, CRLF, a byte-order mark;
    numbers as the General format shows them (at most 10 significant digits)."""
    rows = [line.split(",") for line in text.strip().splitlines()]

    def cell(value):
        try:
            number = float(value)
        except ValueError:
            return value
        if value == "":
            return value
        return f"{number:.10g}".replace(".", ",")

    lines = [";".join(rows[0])] + [";".join(cell(v) for v in row) for row in rows[1:]]
    return b"\xef\xbb\xbf" + "\r\n".join(lines).encode() + b"\r\n"


def _excel_unicode_text(text):
    """Excel's "Unicode text": UTF-16 LE with a byte-order mark, tab separated, CRLF."""
    lines = [line.replace(",", "\t") for line in text.strip().splitlines()]
    return "\ufeff".encode("utf-16-le") + "\r\n".join(lines + [""]).encode("utf-16-le")


def _with_comment(text):
    return ("# impacts of drop 3, bench B; written by dashpot impacts\n" + text).encode()


def _trailing_separator(text):
    lines = text.strip().splitlines()
    lines[4] += ","
    return ("\n".join(lines) + "\n").encode()


RESAVES = {"excel-utf8-bom": (_excel_utf8, ".csv"),
           "excel-european": (_excel_european, ".csv"),
           "excel-unicode-text": (_excel_unicode_text, ".txt"),
           "comment-line": (_with_comment, ".csv"),
           "trailing-empty-field": (_trailing_separator, ".csv")}


@pytest.mark.parametrize("resave", RESAVES)
def test_resaved_impact_table_reads_as_the_original(tmp_path, ball, resave):
    original = _impact_table(tmp_path, ball.impact_times + 3.0, sigma=np.full(20, 1e-5))
    convert, suffix = RESAVES[resave]
    resaved = tmp_path / f"resaved{suffix}"
    resaved.write_bytes(convert(original.read_text()))
    want, got = scene_impacts(original), scene_impacts(resaved)
    assert got.attrs["sensor"] == "impact table"
    tolerance = 1e-9 if resave == "excel-european" else 0  # 10 digits, as Excel shows them
    np.testing.assert_allclose(got["time"], want["time"], rtol=tolerance, atol=0)
    np.testing.assert_allclose(got["time_uncertainty"], want["time_uncertainty"], rtol=1e-12)
    output = tmp_path / "bounces.csv"
    status, _, err = run_cli(["bounces", str(resaved), "-o", str(output)])
    assert status == 0, err
    assert len(pd.read_csv(output)) == 19


def test_european_excel_impact_table_is_fitted(tmp_path, ball):
    original = _impact_table(tmp_path, ball.impact_times + 3.0, sigma=np.full(20, 1e-5))
    resaved = tmp_path / "excel.csv"
    resaved.write_bytes(_excel_european(original.read_text()))
    status, out, err = run_cli(["fit", str(resaved), "-o", str(tmp_path / "fit.h5"),
                                "--models", "Ia"])
    assert status == 0, err
    assert "20 impacts" in out


def test_impacts_as_timestamps_on_its_own_output(tmp_path, ball):
    original = _impact_table(tmp_path, ball.impact_times + 3.0, sigma=np.full(20, 1e-5))
    again = tmp_path / "again.csv"
    status, _, err = run_cli(["impacts", "--kind", "timestamps", str(original), "-o",
                              str(again)])
    assert status == 0, err
    pd.testing.assert_frame_equal(pd.read_csv(again), pd.read_csv(original))


def test_a_row_with_an_extra_field_is_named(tmp_path, ball):
    impacts = _impact_table(tmp_path, ball.impact_times, sigma=np.full(20, 1e-5))
    lines = impacts.read_text().splitlines()
    lines[12] += ",7"
    impacts.write_text("\n".join(lines) + "\n")
    output = tmp_path / "bounces.csv"
    status, _, err = run_cli(["bounces", str(impacts), "-o", str(output)])
    assert status == 2
    assert _error_line(err) == (f"dashpot bounces: error: {impacts}, row 12: 8 fields where "
                                f"the header row has 7 (extra '7')")
    assert not output.exists()


# ------------------------------------------ the scene names another recording (15, 16)

def test_fit_an_impact_table_with_the_scene_of_its_recording(tmp_path, ball):
    """README: `dashpot impacts rec.wav -o imp.csv`, then `dashpot fit imp.csv --scene
    scene.yaml` whose recording is rec.wav and sensor audio."""
    impacts = _impact_table(tmp_path, ball.impact_times, sigma=np.full(20, 1e-5))
    (tmp_path / "scene.yaml").write_text("name: drop\nrecording: rec.wav\nsensor: audio\n"
                                         "apparatus:\n  gravity: 9.81\n")
    output = tmp_path / "fit.h5"
    status, out, err = run_cli(["fit", str(impacts), "--scene", str(tmp_path / "scene.yaml"),
                                "-o", str(output), "--models", "Ia"])
    assert status == 0, err
    notes = [line for line in out.splitlines() if "rec.wav" in line]
    assert len(notes) == 1 and f"fitted {impacts}" in notes[0] and "not read" in notes[0]
    with h5py.File(output, "r") as source:
        assert source.attrs["input_file"] == "imp.csv"
        assert not source.attrs["input_is_scene_recording"]
        assert json.loads(source.attrs["scene"])["recording"].endswith("rec.wav")


# ------------------------------------------------------ a crashed recorder (point 15)

@pytest.mark.parametrize("unset", [0, 0xFFFFFFFF], ids=["zero", "ffffffff"])
def test_wav_whose_header_never_got_its_sizes(tmp_path, unset):
    """A recorder writes the header first and fills in the sizes when it stops; if it
    crashes they stay 0 (or 0xFFFFFFFF when streaming) with every sample after them."""
    times = np.array([0.0, 0.2, 0.36, 0.49, 0.594])
    samples, _ = impact_sound(times, np.array([1.0, 0.9, 0.8, 0.72, 0.65]), snr_db=50,
                              seed=31)
    good = write_audio(tmp_path / "good.wav", samples, 44100, subtype="PCM_16")
    raw = bytearray(good.read_bytes())
    data = raw.index(b"data")
    raw[4:8] = struct.pack("<I", unset)
    raw[data + 4:data + 8] = struct.pack("<I", unset)
    crashed = tmp_path / "crashed.wav"
    crashed.write_bytes(bytes(raw))
    want, got = detect_impacts(good), detect_impacts(crashed)
    np.testing.assert_array_equal(got["time"], want["time"])
    assert sf.info(str(good)).frames == samples.shape[0]
    note = [n for n in got.attrs["notes"] if "WAV header" in n]
    assert len(note) == 1 and f"{2 * samples.shape[0]} bytes of samples" in note[0]
