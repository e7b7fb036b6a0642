"""Readers of lab tables against known truth: synthetic files and hand-written exports.

Round trips write a file with dashpot.synth.tables from a bounce train of known parameters and
check that the reader recovers the truth the writer returns: impact times to the file's
resolution (phyphox, time lists, photogate events), speeds within stated tolerances (motion
sensor fits), and no impact from a resting cart's noise. Hand-written files, typed here in the
layout of the real exports, are independent of the writers. Every bad-input case must raise
InputError naming the file (and the row where it applies).
"""

from __future__ import annotations

import numpy as np
import openpyxl
import pandas as pd
import pytest

from cli_run import run_cli
import dashpot
from dashpot.errors import InputError
from dashpot.ingest import IMPACT_COLUMNS, MOTION_SPEED_ERROR_COLUMNS
from dashpot.ingest.tables import (read_motion_sensor, read_photogate, read_phyphox,
                                   read_timestamps, sniff_table)
from dashpot.synth.tables import (write_motion_sensor, write_phyphox_collision,
                                  write_phyphox_stopwatch, write_photogate, write_timestamps)

# The paper's cart (soft spring bumper, contacts ~0.15 s) and a hard cart on a gentle slope.
PAPER = dict(model="hybrid", beta=1.87, omega0=(255 / 0.506) ** 0.5, g=2.90, v0=1.0)
STIFF = dict(model="Ib", beta=8.0, omega0=300.0, g=0.5, v0=0.5, v_min=0.05)
VARIANTS = [dict(), dict(delimiter="\t"), dict(delimiter=";"),
            dict(delimiter="\t", decimal=","), dict(delimiter=";", decimal=","),
            dict(excel=True), dict(zipped=True)]
VARIANT_IDS = ["comma", "tab", "semicolon", "tab-decimal-comma", "semicolon-decimal-comma",
               "excel", "zip"]


@pytest.fixture(scope="module")
def stiff():
    return dashpot.bounce_sequence(**STIFF)


@pytest.fixture(scope="module")
def paper():
    return dashpot.bounce_sequence(**PAPER)


def suffix(variant):
    return ".xlsx" if variant.get("excel") else ".zip" if variant.get("zipped") else ".csv"


def check_schema(frame, sensor):
    # The motion sensor states its speeds' correlated errors and grades its impacts in a last
    # 'flag' column; other readers do neither.
    flagged = MOTION_SPEED_ERROR_COLUMNS + ("flag",) if sensor == "motion_sensor" else ()
    assert tuple(frame.columns) == IMPACT_COLUMNS + flagged
    assert frame.attrs["sensor"] == sensor
    assert np.all(np.diff(frame["time"]) > 0) or frame["run"].nunique() > 1
    assert np.all(frame["time_uncertainty"] > 0)


# ------------------------------------------------------------------------------- phyphox

@pytest.mark.parametrize("variant", VARIANTS, ids=VARIANT_IDS)
@pytest.mark.parametrize("layout", ["clicks", "multiple"])
def test_phyphox_stopwatch_round_trip(tmp_path, stiff, variant, layout):
    path = tmp_path / f"stopwatch{suffix(variant)}"
    truth = write_phyphox_stopwatch(path, stiff.impact_times, layout=layout, **variant)
    frame = read_phyphox(path)
    check_schema(frame, "phyphox")
    expected = np.array(truth["impact_times"])
    assert len(frame) == (len(stiff.impact_times) if layout == "clicks" else 6)
    # Ten significant digits in the text variants; exact in Excel.
    assert np.allclose(frame["time"], expected, rtol=1e-9, atol=0)
    assert frame["impact_speed"].isna().all() and (frame["run"] == 0).all()
    notes = " ".join(frame.attrs["notes"])
    if not variant.get("excel"):
        assert ("decimal comma" if variant.get("decimal") == "," else "decimal point") in notes
        assert {"\t": "tab", ";": "semicolon"}.get(variant.get("delimiter"), "comma") in notes
    assert sniff_table(path) == "phyphox"


@pytest.mark.parametrize("variant", VARIANTS, ids=VARIANT_IDS)
def test_phyphox_collision_round_trip(tmp_path, paper, variant):
    path = tmp_path / f"collision{suffix(variant)}"
    truth = write_phyphox_collision(path, paper.impact_times[:4], **variant)
    frame = read_phyphox(path)
    check_schema(frame, "phyphox")
    assert np.allclose(frame["time"], truth["impact_times"], rtol=1e-9, atol=0)
    assert any("imply g = 9.81" in note for note in frame.attrs["notes"])


def test_hand_written_stock_stopwatch_with_untriggered_stops(tmp_path):
    # The "Multiple" set as phyphox writes it (semicolon, decimal comma): two stops heard.
    path = tmp_path / "Multiple.csv"
    path.write_text('"Start (s)";"Stop 1 (s)";"Stop 2 (s)";"Stop 3 (s)";"Stop 4 (s)";'
                    '"Stop 5 (s)"\n1,250000000E0;1,873541667E0;2,410000000E0;0,000000000E0;'
                    '0,000000000E0;0,000000000E0\n')
    frame = read_phyphox(path)
    assert frame["time"].tolist() == pytest.approx([1.25, 1.873541667, 2.41], abs=1e-12)
    assert any("3 stop(s) never triggered" in n for n in frame.attrs["notes"])
    # 1σ: one 48 kHz sample over √12 (the printed digits are finer).
    assert frame["time_uncertainty"].iloc[0] == pytest.approx(1 / 48000 / 12 ** 0.5, rel=1e-3)


def test_hand_written_collision_with_three_bounces_heard(tmp_path):
    path = tmp_path / "Energy.csv"
    h = lambda dt: 9.81 / 8 * dt ** 2  # noqa: E731 - the experiment's own formula
    cells = {"Bounce 0 (s)": 0.8, "Height 0 (m)": 0.5, "Bounce 1 (s)": 1.4,
             "Height 1 (m)": h(0.6), "Energy 1": 1, "Bounce 2 (s)": 1.88,
             "Height 2 (m)": h(0.48), "Energy 2": 0.64, "Bounce 3 (s)": 0,
             "Height 3 (m)": h(3.2), "Energy 3": 3.2 ** 2 / 0.36}
    for i in (4, 5):
        cells.update({f"Bounce {i} (s)": 0, f"Height {i} (m)": 0, f"Energy {i}": 0})
    path.write_text("\t".join(f'"{k}"' for k in cells) + "\n"
                    + "\t".join(f"{v:.9E}" for v in cells.values()) + "\n")
    frame = read_phyphox(path)
    assert frame["time"].tolist() == pytest.approx([0.8, 1.4, 1.88])


def test_phyphox_clicks_past_ten_seconds_agree_with_their_intervals(tmp_path):
    # phyphox writes ten significant digits: a click past 10 s (1.093691667E1) is written to
    # 1e-8 s, ten times coarser than the column's median cell, and its 'Interval' still agrees.
    times = 0.4 * np.cumsum(0.98 ** np.arange(40))
    path = tmp_path / "clicks.csv"
    truth = write_phyphox_stopwatch(path, times)
    assert truth["impact_times"][-1] > 10.0 and np.median(truth["impact_times"]) < 10.0
    frame = read_phyphox(path)
    assert np.allclose(frame["time"], truth["impact_times"], rtol=1e-9, atol=0)
    assert any("time to the next click" in note for note in frame.attrs["notes"])


def test_per_click_table_from_intervals_only(tmp_path):
    path = tmp_path / "clicks.csv"
    path.write_text('"Interval (s)"\n6.000000000E-1\n4.800000000E-1\n3.840000000E-1\nNaN\n')
    frame = read_phyphox(path)
    assert frame["time"].tolist() == pytest.approx([0.0, 0.6, 1.08, 1.464])
    assert any("first click at t = 0" in n for n in frame.attrs["notes"])


def test_phyphox_excel_with_both_stopwatch_sets_prefers_multiple(tmp_path, stiff):
    path = tmp_path / "sw.xlsx"
    truth = write_phyphox_stopwatch(path, stiff.impact_times, layout="multiple", excel=True)
    frame = read_phyphox(path)
    assert len(frame) == 6 and np.allclose(frame["time"], truth["impact_times"])
    assert any("'Multiple'" in n for n in frame.attrs["notes"])


def test_phyphox_workbook_click_on_a_round_time_keeps_its_uncertainty(tmp_path, stiff):
    """Clicks at whole 48 kHz samples in a phyphox workbook, the first at a round time: a
    workbook cell holds the float, whose shortest text ('1.0') says nothing about resolution.
    Every click gets the same 1σ, one audio sample over √12."""
    times = np.round(stiff.impact_times * 48000.0) / 48000.0 + 0.5
    path = tmp_path / "clicks.xlsx"
    truth = write_phyphox_stopwatch(path, times, layout="clicks", excel=True)
    assert float(truth["impact_times"][0]).is_integer()
    frame = read_phyphox(path)
    np.testing.assert_allclose(frame["time"], truth["impact_times"], rtol=1e-12)
    np.testing.assert_allclose(frame["time_uncertainty"], 1.0 / (48000.0 * 12 ** 0.5),
                               rtol=1e-6)


# ---------------------------------------------------------------------------- timestamps

@pytest.mark.parametrize("unit", ["s", "ms"])
@pytest.mark.parametrize("declared", ["header", "argument", "inferred"])
def test_timestamps_units(tmp_path, stiff, unit, declared):
    path = tmp_path / "t.csv"
    truth = write_timestamps(path, stiff.impact_times + 0.3, unit=unit,
                             declare_unit=declared == "header", delimiter=";", decimal=",")
    frame = read_timestamps(path, unit=unit if declared == "argument" else None)
    check_schema(frame, "timestamps")
    # Within the file's resolution (1 µs in both units here).
    assert np.max(np.abs(frame["time"] - truth["impact_times"])) <= truth["resolution"] / 2
    assert frame["time_uncertainty"].iloc[0] == pytest.approx(truth["resolution"] / 12 ** 0.5)
    if declared == "inferred":
        assert any("not declared" in n and f"read as {unit}" in n for n in frame.attrs["notes"])


def test_timestamps_resaved_by_a_spreadsheet_share_one_resolution(tmp_path, stiff):
    """Impact times to 0.1 ms saved again from a spreadsheet (shortest text: 1.25 for 1.2500,
    0.5 for 0.5000): the column's resolution is its digits' (0.1 ms), not one cell's, so every
    impact's 1σ is 0.1 ms/√12."""
    times = np.round(stiff.impact_times + 0.5, 4)
    assert times[0] == 0.5
    path = tmp_path / "resaved.csv"
    pd.DataFrame({"time (s)": times}).to_csv(path, index=False)
    assert "\n0.5\n" in path.read_text()
    frame = read_timestamps(path)
    np.testing.assert_allclose(frame["time_uncertainty"], 1e-4 / 12 ** 0.5, rtol=1e-9)


def test_timestamps_uncertainty_column_and_no_header(tmp_path):
    path = tmp_path / "t.txt"
    path.write_text("0.512\t0.002\n1.130\t0.003\n1.614\t0.002\n")
    frame = read_timestamps(path)
    assert frame["time"].tolist() == [0.512, 1.13, 1.614]
    assert frame["time_uncertainty"].tolist() == [0.002, 0.003, 0.002]
    path.write_text("t [ms],sigma [us]\n512,1500\n1130,2500\n")
    frame = read_timestamps(path)
    assert frame["time"].tolist() == pytest.approx([0.512, 1.13])
    assert frame["time_uncertainty"].tolist() == pytest.approx([1.5e-3, 2.5e-3])


@pytest.mark.parametrize("separator, decimal", [(",", "."), (";", ",")])
def test_timestamps_with_a_separator_after_every_field(tmp_path, stiff, separator, decimal):
    """A column of impact times saved from a spreadsheet that kept a formatted, empty column
    beside it (or from a logger ending each field with a separator): every line ends with a
    separator. The empty column is no column; every time is read."""
    times = np.round(stiff.impact_times + 0.5, 6)
    path = tmp_path / "times.csv"
    path.write_bytes(("time (s)" + separator + "\r\n" + "".join(
        f"{t:.6f}".replace(".", decimal) + separator + "\r\n" for t in times)).encode())
    assert sniff_table(path) == "timestamps"
    frame = dashpot.read_impacts(path)
    check_schema(frame, "timestamps")
    np.testing.assert_allclose(frame["time"], times, atol=5e-7)


@pytest.mark.parametrize("labels", ["numbered", "empty", "regions"])
def test_audacity_label_export(tmp_path, stiff, labels):
    """Impacts marked by hand in Audacity and exported as labels (start, end in s with six
    decimals, the label's text, tab-separated, no header): the starts are the impact times,
    in s whatever their spacing, to the written digits; an empty label text leaves a line
    ending in a tab, and its end column must not be read as the times' uncertainty."""
    times = np.round(stiff.impact_times + 0.5, 6)
    ends = times + (0.004 if labels == "regions" else 0.0)
    text = {"numbered": [str(k + 1) for k in range(times.size)],
            "empty": [""] * times.size, "regions": ["bounce"] * times.size}[labels]
    path = tmp_path / "labels.txt"
    path.write_text("".join(f"{t:f}\t{e:f}\t{x}\n" for t, e, x in zip(times, ends, text)))
    assert sniff_table(path) == "timestamps"
    frame = dashpot.read_impacts(path)
    check_schema(frame, "timestamps")
    np.testing.assert_allclose(frame["time"], times, atol=5e-7)
    np.testing.assert_allclose(frame["time_uncertainty"], 1e-6 / 12 ** 0.5, rtol=1e-6)
    assert any("Audacity" in note for note in frame.attrs["notes"])
    with pytest.raises(InputError, match=r"labels\.txt: .*Audacity.*unit='ms'"):
        read_timestamps(path, unit="ms")


@pytest.mark.parametrize("line_end", ["\n", "\r\n"])
def test_audacity_label_export_with_frequency_ranges(tmp_path, stiff, line_end):
    """Labels placed in Audacity's spectrogram view carry a frequency range, which its label
    export writes on a line of its own below the label: a backslash, then the low and the
    high frequency in Hz, tab-separated, six decimals each. Some labels have one,
    some not (a point label placed on the waveform); on Windows every line ends in CRLF.
    Every label's start is read as an impact time, none of the frequency lines."""
    times = np.round(stiff.impact_times + 0.5, 6)
    lines = []
    for k, t in enumerate(times):  # writing the fixture: a label per impact
        lines.append(f"{t:.6f}\t{t:.6f}\tbounce {k + 1}")
        if k % 3:
            lines.append(f"\\\t{100.0 + k:.6f}\t{4000.0 + 10 * k:.6f}")
    path = tmp_path / "labels.txt"
    path.write_bytes((line_end.join(lines) + line_end).encode())
    assert sniff_table(path) == "timestamps"
    frame = dashpot.read_impacts(path)
    check_schema(frame, "timestamps")
    np.testing.assert_allclose(frame["time"], times, atol=5e-7)
    assert any("Audacity" in note for note in frame.attrs["notes"])
    assert "frequency line(s)" in frame.attrs["notes"][0]


@pytest.mark.parametrize("suffix", [".srt", ".vtt"])
def test_audacity_labels_exported_as_subtitles(tmp_path, stiff, suffix):
    """Audacity exports its labels as SubRip or WebVTT cues when the file is named .srt or
    .vtt: per label its number, 'HH:MM:SS,mmm --> HH:MM:SS,mmm' (WebVTT: a period before the
    milliseconds, and 'WEBVTT' on the first line), its text (maybe empty) and a blank line.
    Every label's start is an impact time, to the millisecond written, also past a minute;
    on the command line too."""
    times = np.round(np.concatenate([stiff.impact_times + 0.5, [61.25, 3601.5]]), 3)
    mark = "," if suffix == ".srt" else "."

    def stamp(t):
        whole, ms = int(t), int(round((t - int(t)) * 1000))
        return (f"{whole // 3600:02d}:{whole // 60 % 60:02d}:{whole % 60:02d}"
                f"{mark}{ms:03d}")

    lines = ["WEBVTT", ""] if suffix == ".vtt" else []
    for k, t in enumerate(times):  # writing the fixture: a cue per label
        lines += [str(k + 1), f"{stamp(t)} --> {stamp(t)}", "" if k % 2 else "bounce", ""]
    path = tmp_path / f"labels{suffix}"
    path.write_bytes(("\r\n".join(lines) + "\r\n").encode())
    assert sniff_table(path) == "timestamps"
    frame = dashpot.read_impacts(path)
    check_schema(frame, "timestamps")
    np.testing.assert_allclose(frame["time"], times, atol=1e-9)
    np.testing.assert_allclose(frame["time_uncertainty"], 1e-3 / 12 ** 0.5, rtol=1e-6)
    assert "SubRip/WebVTT" in frame.attrs["notes"][0]
    output = tmp_path / "impacts.csv"
    status, _, err = run_cli(["impacts", str(path), "-o", str(output)])
    assert status == 0, err
    np.testing.assert_allclose(pd.read_csv(output)["time"], times, atol=1e-9)


def test_header_less_second_column_that_is_no_uncertainty_is_refused(tmp_path, stiff):
    """Instants exported by an annotation tool as 'time,label' with numbered labels (no
    header): the labels 1, 2, 3 ... are no 1σ of the times (an uncertainty as large as the
    interval between impacts would not tell them apart). One line naming the file, the row
    and the problem, exit 2, instead of a table with 1 s, 2 s, 3 s uncertainties."""
    times = np.round(stiff.impact_times + 0.5, 9)
    path = tmp_path / "instants.csv"
    path.write_text("".join(f"{t:.9f},{k + 1}\n" for k, t in enumerate(times)))
    with pytest.raises(InputError, match=r"instants\.csv, row 1: the second column \(no header\) "
                                         r"cannot be the times' uncertainties"):
        dashpot.read_impacts(path)
    status, _, err = run_cli(["impacts", str(path), "-o", str(tmp_path / "out.csv")])
    assert status == 2 and err.count("\n") == 1 and "instants.csv" in err
    assert not (tmp_path / "out.csv").exists()


@pytest.mark.parametrize("unit", ["s", "ms"])
def test_header_less_column_with_decimal_commas(tmp_path, stiff, unit):
    """One column of impact times without a header, saved by a spreadsheet on a system with
    a decimal comma: no separator at all, each line '1,234568'. It is one column of decimal
    numbers, not two comma-separated integers (which read as a time of 1 s with an
    uncertainty of 0.234568 s, or were refused as not increasing)."""
    scale, digits = (1.0, 6) if unit == "s" else (1e3, 3)
    times = np.round(stiff.impact_times + 0.5, 6)
    path = tmp_path / "times.csv"
    path.write_text("".join(f"{t * scale:.{digits}f}".replace(".", ",") + "\n" for t in times))
    frame = dashpot.read_impacts(path)
    check_schema(frame, "timestamps")
    np.testing.assert_allclose(frame["time"], times, atol=5e-7)
    assert frame["time_uncertainty"].max() < 1e-6


def test_two_tables_one_below_the_other_say_so(tmp_path, stiff):
    """phyphox's Acoustic Stopwatch sets 'Simple' and 'Multiple' written one below the other
    into one CSV: not one table. Refused in one line that says why (the numbers of fields
    differ), not 'no numeric data'; exit 2."""
    t = stiff.impact_times + 0.5
    number = lambda v: f"{v:.9E}".replace("E+0", "E").replace("E-0", "E-")  # noqa: E731
    path = tmp_path / "stopwatch.csv"
    path.write_text('"Start (s)","Stop (s)","Difference (s)"\n'
                    + ",".join(number(v) for v in (t[0], t[1], t[1] - t[0])) + "\n"
                    + '"Start (s)",' + ",".join(f'"Stop {k} (s)"' for k in range(1, 6)) + "\n"
                    + ",".join(number(v) for v in t[:6]) + "\n")
    problem = (r"stopwatch\.csv: not a table: its lines have different numbers of "
               r"comma-separated fields \(3 on the first non-blank line, 6 on the 3rd\)")
    with pytest.raises(InputError, match=problem):
        dashpot.read_impacts(path)
    status, _, err = run_cli(["impacts", str(path), "-o", str(tmp_path / "out.csv")])
    assert status == 2 and err.count("\n") == 1 and "6 on the 3rd" in err


@pytest.mark.parametrize("suffix", [".csv", ".xlsx"])
def test_title_rows_above_the_header(tmp_path, stiff, suffix):
    """A column of impact times under a title and a blank row, as a spreadsheet's author
    writes it (the title with a comma in it): the header is the row right above the first
    row of numbers; the title rows are skipped, and said to be."""
    times = np.round(stiff.impact_times + 0.5, 6)
    path = tmp_path / f"times{suffix}"
    if suffix == ".csv":
        path.write_text("Bouncing ball, group 3\n\nTime (s)\n"
                        + "".join(f"{t:.6f}\n" for t in times))
    else:
        book = openpyxl.Workbook()
        sheet = book.active
        sheet.append(["Bouncing ball, group 3"])
        sheet.append([])
        sheet.append(["Time (s)"])
        for t in times:  # writing the fixture
            sheet.append([float(t)])
        book.save(path)
    frame = dashpot.read_impacts(path)
    check_schema(frame, "timestamps")
    np.testing.assert_allclose(frame["time"], times, atol=5e-7)
    assert "title row(s) above the header skipped" in frame.attrs["notes"][0]


def test_timestamps_unit_argument_contradicting_header(tmp_path):
    path = tmp_path / "t.csv"
    write_timestamps(path, [0.0, 0.5], unit="ms")
    with pytest.raises(InputError, match=r"t\.csv.*'ms' but unit='s'"):
        read_timestamps(path, unit="s")
    with pytest.raises(ValueError, match="unit"):
        read_timestamps(path, unit="h")


# -------------------------------------------------------------------------- motion sensor

def match(found, true_times):
    """Index of the nearest true impact for each found time."""
    true_times = np.asarray(true_times)
    return np.abs(found[:, None] - true_times[None, :]).argmin(axis=1)


def check_motion(frame, truth_run, *, speed_tolerance, fast=0.0, z_max=4.0):
    """Found impacts against the truth of one run.

    Every impact: time and speeds within `z_max` of the reader's 1σ. Impacts faster than
    `fast` (m/s; long flights, many samples): speeds also within `speed_tolerance` (relative).
    """
    times = np.array(truth_run["impact_times"])
    speeds = np.array(truth_run["impact_speeds"])
    rebounds = np.array(truth_run["rebound_speeds"])
    found = frame["time"].to_numpy()
    nearest = match(found, times)
    # Every impact found is a true impact (one each), timed within a few stated 1σ (+1 ms for
    # the bumper compression stand-in's curvature, which the fits do not model).
    assert len(set(nearest)) == len(found)
    error = np.abs(found - times[nearest])
    assert np.all(error <= z_max * frame["time_uncertainty"] + 1e-3), error
    # Speeds: within the stated tolerance and within a few of the reader's own 1σ.
    sigma = frame["speed_uncertainty"].to_numpy()
    for measured, true in ((frame["impact_speed"].to_numpy(), speeds[nearest]),
                           (frame["rebound_speed"].to_numpy(), rebounds[nearest])):
        known = np.isfinite(measured)
        assert np.all(np.abs(measured - true)[known] <= z_max * sigma[known])
        well = known & (true > fast)
        assert np.all(np.abs(measured - true)[well] <= speed_tolerance * true[well])
    # No impact from the resting tail: nothing after the cart's last true contact.
    assert found.max() < times[-1] + 0.05
    return nearest


@pytest.mark.parametrize("vendor", ["pasco", "vernier"])
def test_motion_sensor_hard_cart_20_hz(tmp_path, stiff, vendor):
    path = tmp_path / "m.csv"
    truth = write_motion_sensor(path, stiff, vendor=vendor, sample_rate=20.0, noise=1e-3,
                                seed=11)
    frame = read_motion_sensor(path)
    check_schema(frame, "motion_sensor")
    # Impacts faster than 0.25 m/s have flights of 1 s (20 samples) or more on both sides.
    nearest = check_motion(frame, truth["runs"][0], speed_tolerance=0.01, fast=0.25)
    # All of those are resolved.
    assert set(np.flatnonzero(np.array(stiff.impact_speeds[1:]) > 0.25)) <= set(nearest)
    assert sniff_table(path) == "motion_sensor"


def test_motion_sensor_soft_bumper_two_runs_sensor_at_bumper(tmp_path, paper):
    path = tmp_path / "m.csv"
    truth = write_motion_sensor(path, paper, runs=2, sensor_at="bumper", noise=1e-3,
                                bumper_position=0.25, delimiter=";", decimal=",", seed=5)
    frame = read_motion_sensor(path)
    check_schema(frame, "motion_sensor")
    assert sorted(frame["run"].unique()) == [0, 1]
    for run, truth_run in enumerate(truth["runs"]):
        part = frame[frame["run"] == run]
        assert len(part) >= 3  # flights of 0.51, 0.37 and 0.25 s are resolved at 20 Hz
        check_motion(part, truth_run, speed_tolerance=0.05)
    assert any("run 1 = 'Run #2'" in n for n in frame.attrs["notes"])


def test_motion_sensor_from_an_excel_sheet(tmp_path, stiff):
    # The same export saved from a spreadsheet: numbers in cells, one sheet.
    truth = write_motion_sensor(tmp_path / "m.csv", stiff, vendor="vernier", seed=8)
    table = pd.read_csv(tmp_path / "m.csv")
    book = openpyxl.Workbook()
    book.active.title = "Data Set 1"
    book.active.append(list(table.columns))
    for row in table.itertuples(index=False):  # building the fixture, not reading it
        book.active.append([float(v) for v in row])
    book.save(tmp_path / "m.xlsx")
    frame = read_motion_sensor(tmp_path / "m.xlsx")
    check_motion(frame, truth["runs"][0], speed_tolerance=0.01, fast=0.25)
    assert sniff_table(tmp_path / "m.xlsx") == "motion_sensor"


def test_motion_sensor_velocity_only(tmp_path, stiff):
    path = tmp_path / "m.csv"
    truth = write_motion_sensor(path, stiff, quantities=("velocity",), seed=2)
    frame = read_motion_sensor(path)
    # The position comes from integrating the vendor's velocity: looser.
    check_motion(frame, truth["runs"][0], speed_tolerance=0.02, fast=0.25, z_max=6.0)
    assert len(frame) >= 10


def test_motion_sensor_given_bumper_position(tmp_path, stiff):
    path = tmp_path / "m.csv"
    truth = write_motion_sensor(path, stiff, bumper_position=0.9, noise=5e-4, seed=4)
    frame = read_motion_sensor(path, bumper_position=0.9)
    check_motion(frame, truth["runs"][0], speed_tolerance=0.01, fast=0.25)
    assert any("bumper position given" in n for n in frame.attrs["notes"])


def test_noisy_rest_gives_no_impact(tmp_path):
    # A cart resting against the bumper for 60 s under 3 mm sensor noise (Vernier layout).
    rng = np.random.default_rng(1)
    t = np.arange(0, 60, 0.05)
    x = 0.8 + 3e-3 * rng.standard_normal(t.size)
    v = np.gradient(x, t)
    pd.DataFrame({"Latest: Time (s)": t, "Latest: Position (m)": x,
                  "Latest: Velocity (m/s)": v}).to_csv(tmp_path / "rest.csv", index=False)
    frame = read_motion_sensor(tmp_path / "rest.csv")
    assert len(frame) == 0 and tuple(frame.columns) == (IMPACT_COLUMNS
                                                        + MOTION_SPEED_ERROR_COLUMNS + ("flag",))


def test_long_noisy_rest_tail_after_bouncing(tmp_path, stiff):
    path = tmp_path / "m.csv"
    truth = write_motion_sensor(path, stiff, rest_tail=60.0, noise=2e-3, seed=9)
    frame = read_motion_sensor(path)
    check_motion(frame, truth["runs"][0], speed_tolerance=0.02, fast=0.25)


def test_hand_written_pasco_file_in_cm(tmp_path):
    # A cart sliding down (a = 0.5 m/s²) hits the bumper at 200 cm at 0.5 m/s at t = 2 s and
    # leaves at 0.4 m/s, instantly; back at t = 3.6 s at 0.4 m/s, it leaves at 0.3 m/s and is
    # back to rest at t = 4.8 s. PASCO layout with position in cm, 10 Hz, no noise.
    t = np.round(np.arange(0.0, 7.0, 0.1), 1)
    before, after, second = 2.0 - t, t - 2.0, t - 3.6
    s = np.where(t < 1.0, 0.25, np.where(t <= 2.0, 0.5 * before - 0.25 * before ** 2,
                 np.where(t < 3.6, 0.4 * after - 0.25 * after ** 2,
                          np.where(t < 4.8, 0.3 * second - 0.25 * second ** 2, 0.0))))
    text = "Time (s) Run #1,Position (cm) Run #1\n" + "\n".join(
        f"{a:.1f},{200 - 100 * b:.4f}" for a, b in zip(t, s)) + "\n"
    (tmp_path / "cart.csv").write_text(text)
    frame = read_motion_sensor(tmp_path / "cart.csv")
    assert frame["time"].tolist() == pytest.approx([2.0, 3.6], abs=2e-3)
    assert frame["impact_speed"].tolist() == pytest.approx([0.5, 0.4], rel=5e-3)
    assert frame["rebound_speed"].tolist() == pytest.approx([0.4, 0.3], rel=5e-3)
    assert frame["flag"].tolist() == ["ok", "ok"]


# ------------------------------------------------------------------------------ photogate

@pytest.mark.parametrize("mode, initial_row", [("events", True), ("events", False),
                                               ("sampled", True)])
def test_photogate_with_gate_distance(tmp_path, stiff, mode, initial_row):
    # An event log with or without a first row of the state before the first change: the
    # first passage is an impact's either way.
    path = tmp_path / "g.csv"
    truth = write_photogate(path, stiff, flag_length=0.02, gate_distance=0.01, mode=mode,
                            initial_row=initial_row, sample_rate=2000.0)
    frame = read_photogate(path, flag_length=0.02, gate_distance=0.01)
    check_schema(frame, "photogate")
    n = len(frame)
    kinds = truth["passages"]["kind"]
    assert n == kinds.count("toward")  # every full toward passage is an impact
    times = np.array(truth["impact_times"][:n])
    # Event log: exact to the 1 µs clock; sampled at 2 kHz: a fraction of a sample.
    tolerance = 5e-6 if mode == "events" else 1e-3
    assert np.max(np.abs(frame["time"] - times)) < tolerance
    speed_tolerance = 1e-4 if mode == "events" else 0.01
    assert np.allclose(frame["impact_speed"], truth["impact_speeds"][:n], rtol=speed_tolerance)
    rebound = frame["rebound_speed"].to_numpy()
    assert np.isnan(rebound[-1])  # the last away passage turned inside the beam
    assert np.allclose(rebound[:-1], truth["rebound_speeds"][: n - 1], rtol=speed_tolerance)
    assert sniff_table(path) == "photogate"


@pytest.mark.parametrize("initial_row", [True, False])
def test_photogate_without_gate_distance(tmp_path, stiff, initial_row):
    path = tmp_path / "g.csv"
    truth = write_photogate(path, stiff, flag_length=0.02, gate_distance=0.01,
                            initial_row=initial_row)
    frame = read_photogate(path, flag_length=0.02)
    passages = pd.DataFrame(truth["passages"])
    toward = passages[passages["kind"] == "toward"]["mean_speed"].to_numpy()
    away = passages[passages["kind"] == "away"]["mean_speed"].to_numpy()
    n = len(frame)
    assert n == len(away)  # impacts need both passages
    assert np.allclose(frame["impact_speed"], toward[:n], rtol=1e-4)
    assert np.allclose(frame["rebound_speed"], away[:n], rtol=1e-4)
    # Splitting the gap as if the contact were instantaneous is late by at most the contact.
    late = frame["time"].to_numpy() - np.array(truth["impact_times"][:n])
    assert np.all(late > 0) and np.all(late < np.array(truth["contact_durations"][:n]))


def test_hand_written_vernier_gate_log_words(tmp_path):
    # Flag 5 cm; toward passage 0.1 s (0.5 m/s), away 0.125 s (0.4 m/s), then the cart
    # comes back through the gate at 0.4 m/s again and is caught.
    text = ("Latest: Time (s),Latest: GateState\n0,Unblocked\n1.0,Blocked\n1.1,Unblocked\n"
            "1.2,Blocked\n1.325,Unblocked\n2.925,Blocked\n3.05,Unblocked\n")
    (tmp_path / "gate.csv").write_text(text)
    frame = read_photogate(tmp_path / "gate.csv", flag_length=0.05)
    assert len(frame) == 1
    assert frame["impact_speed"].iloc[0] == pytest.approx(0.5)
    assert frame["rebound_speed"].iloc[0] == pytest.approx(0.4)
    # Gap 0.1 s split in the ratio of the speeds at the gate edge (constant-speed limit
    # is 0.1·0.4/0.9; gravity from the flight changes it slightly): between those bounds.
    assert 1.1 + 0.1 * 0.4 / 0.9 - 5e-3 < frame["time"].iloc[0] < 1.15


# ------------------------------------------------------------------------------- sniffing

def test_sniff_table_kinds_and_refusal(tmp_path, stiff):
    write_timestamps(tmp_path / "t.csv", stiff.impact_times)
    assert sniff_table(tmp_path / "t.csv") == "timestamps"
    (tmp_path / "x.csv").write_text("temperature (K),pressure (Pa)\n300,1e5\n301,1e5\n")
    with pytest.raises(InputError, match=r"x\.csv.*not a table of impacts"):
        sniff_table(tmp_path / "x.csv")


# ------------------------------------------------------------------------------ bad input

READERS = {
    "phyphox": read_phyphox,
    "timestamps": read_timestamps,
    "motion_sensor": read_motion_sensor,
    "photogate": lambda p: read_photogate(p, flag_length=0.02),
    "sniff": sniff_table,
}


@pytest.mark.parametrize("reader", READERS)
@pytest.mark.parametrize("content", [b"", b"  \n\n \t\n"], ids=["zero-bytes", "blank"])
def test_empty_file(tmp_path, reader, content):
    path = tmp_path / "empty.csv"
    path.write_bytes(content)
    with pytest.raises(InputError, match=r"empty\.csv: .*empty"):
        READERS[reader](path)


@pytest.mark.parametrize("reader", READERS)
@pytest.mark.parametrize("content", [
    b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00\x01\x00",
    "Dear lab team, the cart bounced nicely today.\nSee you tomorrow!\n".encode(),
    b"PK\x03\x04 not really a zip",
], ids=["binary", "prose", "broken-zip"])
def test_not_a_table(tmp_path, reader, content):
    path = tmp_path / "notes.dat"
    path.write_bytes(content)
    with pytest.raises(InputError, match=r"notes\.dat: .*(not a table|no time column|no "
                                         r"phyphox|not a table of impacts|no data rows)"):
        READERS[reader](path)


@pytest.mark.parametrize("codec, name", [("utf-16-le", "UTF-16LE"), ("utf-16-be", "UTF-16BE")])
def test_utf16_without_byte_order_mark_is_read(tmp_path, codec, name):
    """A Windows logger's "Unicode text" without the byte-order mark (tabs, CRLF, a comment
    line with a non-ASCII letter) was refused as binary data for its zero bytes."""
    text = ("# Messung 3, Fallhöhe 0.5 m\r\ntime (s)\tuncertainty (s)\r\n0.5\t0.001\r\n"
            "0.9\t0.001\r\n1.25\t0.001\r\n1.54\t0.001\r\n")
    path = tmp_path / "clicks.txt"
    path.write_bytes(text.encode(codec))
    assert path.read_bytes()[:2] not in (b"\xff\xfe", b"\xfe\xff")
    frame = read_timestamps(path)
    np.testing.assert_array_equal(frame["time"], [0.5, 0.9, 1.25, 1.54])
    np.testing.assert_array_equal(frame["time_uncertainty"], [0.001] * 4)
    assert f"{name} without byte-order mark" in frame.attrs["notes"][0]
    assert sniff_table(path) == "timestamps"


BINARY = {
    # A PNG's signature and IHDR chunk, then bytes as random as compressed image data.
    "png": b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00\x01\x00\x00\x00\x01\x00\x08\x02"
           + np.random.default_rng(1202).integers(0, 256, 4000, dtype=np.uint8).tobytes(),
    # Raw unsigned 16-bit readings below 256: every high byte is zero, as in UTF-16 text;
    # only the control characters they decode to tell them from text.
    "small-words": np.random.default_rng(1203).integers(0, 256, 3000).astype("<u2").tobytes(),
}


@pytest.mark.parametrize("content", list(BINARY.values()), ids=list(BINARY))
def test_binary_data_is_still_refused(tmp_path, content):
    path = tmp_path / "clicks.txt"
    path.write_bytes(content)
    with pytest.raises(InputError, match=r"clicks\.txt: not a table: the file holds binary "
                                         r"data$"):
        read_timestamps(path)


@pytest.mark.parametrize("reader", ["timestamps", "motion_sensor", "photogate"])
def test_csv_without_time_column(tmp_path, reader):
    path = tmp_path / "notime.csv"
    path.write_text("Position (m) Run #1,Velocity (m/s) Run #1\n0.10,0.0\n0.11,0.2\n")
    with pytest.raises(InputError, match=r"notime\.csv: no time column"):
        READERS[reader](path)


BAD_TIMES = {
    "nan": ("time (s)\n0.5\n1.0\nNaN\n1.9\n", 3, "missing"),
    "empty-cell": ("time (s),sigma (s)\n0.5,0.001\n,0.001\n1.9,0.001\n", 2, "missing"),
    "negative": ("time (s)\n-0.5\n1.0\n1.4\n", 1, "negative"),
    "not-increasing": ("time (s)\n0.5\n1.0\n1.4\n1.2\n", 4, "not after"),
    "text": ("time (s)\n0.5\nabc\n1.4\n", r"2, column 'time \(s\)'", "'abc' is not a number"),
}


@pytest.mark.parametrize("case", BAD_TIMES)
def test_bad_timestamps_name_the_row(tmp_path, case):
    text, row, problem = BAD_TIMES[case]
    path = tmp_path / "times.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=rf"times\.csv, row {row}: .*{problem}"):
        read_timestamps(path)


def test_bad_motion_times_name_the_row(tmp_path):
    path = tmp_path / "cart.csv"
    path.write_text("Time (s) Run #1,Position (m) Run #1\n0.00,0.5\n0.05,0.5\n0.04,0.5\n")
    with pytest.raises(InputError, match=r"cart\.csv, row 3: .*not after"):
        read_motion_sensor(path)
    path.write_text("Latest: Time (s),Latest: Position (m)\n0.00,0.5\n0.05,\n0.10,0.5\n")
    with pytest.raises(InputError, match=r"cart\.csv, row 2: .*missing inside the run"):
        read_motion_sensor(path)


@pytest.mark.parametrize("reader", ["phyphox", "timestamps", "motion_sensor", "photogate"])
def test_duplicated_rows(tmp_path, reader):
    files = {
        "phyphox": '"Event time (s)","Interval (s)"\n5.0E-1,1.0E-1\n6.0E-1,2.0E-1\n'
                   "6.0E-1,2.0E-1\n",
        "timestamps": "time (s)\n0.5\n0.9\n0.9\n1.2\n",
        "motion_sensor": "Time (s) Run #1,Position (m) Run #1\n0,0.5\n0.05,0.5\n0.05,0.5\n",
        "photogate": "Latest: Time (s),Latest: GateState\n0,0\n1.0,1\n1.0,1\n1.1,0\n",
    }
    path = tmp_path / "dup.csv"
    path.write_text(files[reader])
    with pytest.raises(InputError, match=r"dup\.csv, row 3: .*repeats row 2.*duplicated"):
        READERS[reader](path)


@pytest.mark.parametrize("reader,text", [
    ("timestamps", "time (fortnights)\n1\n2\n"),
    ("motion_sensor", "Time (s) Run #1,Position (furlong) Run #1\n0,1\n0.1,1\n"),
    ("motion_sensor", "Time (h) Run #1,Position (m) Run #1\n0,1\n0.1,1\n"),
    ("phyphox", '"Event time (min)"\n1\n2\n'),
], ids=["timestamps", "motion-length", "motion-time", "phyphox"])
def test_unknown_unit_in_header(tmp_path, reader, text):
    path = tmp_path / "units.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=r"units\.csv: unknown .* unit '(fortnights|furlong|h|"
                                         r"min)' in column header"):
        READERS[reader](path)


def test_excel_sheet_with_the_wrong_layout(tmp_path):
    book = openpyxl.Workbook()
    sheet = book.active
    sheet.title = "Raw Data"
    sheet.append(["Acceleration x (m/s^2)", "Acceleration y (m/s^2)"])
    sheet.append([0.1, 9.8])
    sheet.append([0.2, 9.7])
    book.save(tmp_path / "export.xlsx")
    with pytest.raises(InputError, match=r"export\.xlsx: no phyphox .*sheet 'Raw Data': "
                                         r"Acceleration x"):
        read_phyphox(tmp_path / "export.xlsx")
    with pytest.raises(InputError, match=r"export\.xlsx: sheet 'Raw Data': no time column"):
        read_motion_sensor(tmp_path / "export.xlsx")


def test_phyphox_interval_contradicting_event_times(tmp_path):
    path = tmp_path / "clicks.csv"
    path.write_text('"Event time (s)","Interval (s)"\n5.000000000E-1,NaN\n1.100000000E0,'
                    '6.000000000E-1\n1.500000000E0,9.000000000E-1\n')
    with pytest.raises(InputError, match=r"clicks\.csv, row 3: 'Interval' 0\.9 s disagrees"):
        read_phyphox(path)


def test_gate_state_that_is_not_a_state(tmp_path):
    path = tmp_path / "gate.csv"
    path.write_text("Latest: Time (s),Latest: GateState\n0,0\n1.0,1\n1.1,2\n")
    with pytest.raises(InputError, match=r"gate\.csv, row 3: gate state '2'"):
        read_photogate(path, flag_length=0.02)
    with pytest.raises(ValueError, match="flag_length"):
        read_photogate(path, flag_length=-1)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match=r"nothere\.csv: no such file"):
        read_timestamps(tmp_path / "nothere.csv")


def test_excel_unicode_text_comment_lines_and_extra_fields(tmp_path):
    """Excel's "Unicode text" (UTF-16 LE, BOM, tabs, CRLF); leading '#' comments; a row with a
    field too many is named unless the extra field is empty."""
    text = "time (s)\tuncertainty (s)\r\n0.5\t0.001\r\n0.9\t0.001\r\n1.25\t0.001\r\n"
    unicode_text = tmp_path / "clicks.txt"
    unicode_text.write_bytes("\ufeff".encode("utf-16-le") + text.encode("utf-16-le"))
    frame = read_timestamps(unicode_text)
    np.testing.assert_array_equal(frame["time"], [0.5, 0.9, 1.25])
    assert "UTF-16" in frame.attrs["notes"][0]
    commented = tmp_path / "commented.csv"
    commented.write_text("# bench 3, drop from 0.5 m\n# g = 9.81, sigma\ntime (s)\n0.5\n0.9\n"
                         "1.25\n")
    np.testing.assert_array_equal(read_timestamps(commented)["time"], [0.5, 0.9, 1.25])
    trailing = tmp_path / "trailing.csv"
    trailing.write_text("time (s),sigma (s)\n0.5,0.001\n0.9,0.001,\n1.25,0.001\n")
    np.testing.assert_array_equal(read_timestamps(trailing)["time"], [0.5, 0.9, 1.25])
    extra = tmp_path / "extra.csv"
    extra.write_text("time (s),sigma (s)\n0.5,0.001\n0.9,0.001,x\n1.25,0.001\n")
    with pytest.raises(InputError, match=r"extra\.csv, row 2: 3 fields where the header row "
                                         r"has 2 \(extra 'x'\)$"):
        read_timestamps(extra)
