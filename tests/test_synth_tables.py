"""Synthetic lab tables: layout, numbers and truth checked against independent references.

The references are written out by hand here: phyphox's export wording and number format (from
its experiment definitions and DataExport), the stopwatch's audio-sample grid, the collision
experiment's h = (g/8)·Δt², and closed-form free motion on an incline. Files are read back
with the csv module and openpyxl, not with dashpot's readers.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import re
import zipfile
from pathlib import Path

import numpy as np
import openpyxl
import pytest
from scipy import stats

import dashpot
from dashpot.synth.tables import (write_motion_sensor, write_phyphox_collision,
                                  write_phyphox_stopwatch, write_photogate, write_timestamps)

# A hard cart on a gentle incline: short contacts, long flights, many impacts.
G_EFF = 0.5
STIFF = dict(model="Ib", beta=8.0, omega0=300.0, g=G_EFF, v0=0.5, v_min=0.05)
PHYPHOX_NUMBER = re.compile(r"^-?\d[.,]\d{9}E-?\d+$")  # Java DecimalFormat "0.000000000E0"


def rows_of(path, delimiter=","):
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.reader(handle, delimiter=delimiter))


def number(text):
    return float(text.replace(",", "."))


# --------------------------------------------------------------------------------- phyphox

def test_stopwatch_clicks_csv_layout_and_values(tmp_path):
    times = [0.0, 0.61, 1.1305, 1.5]
    truth = write_phyphox_stopwatch(tmp_path / "a.csv", times, start_delay=0.25)
    rows = rows_of(tmp_path / "a.csv")
    assert rows[0] == ["Event time (s)", "Interval (s)"]
    # On phyphox's 48 kHz sample grid, shifted by the start delay.
    expected = [round((t + 0.25) * 48000) / 48000 for t in times]
    written = [number(r[0]) for r in rows[1:]]
    assert written == pytest.approx(expected, rel=1e-9)
    assert truth["impact_times"] == pytest.approx(expected, rel=1e-12)
    assert all(PHYPHOX_NUMBER.match(r[0]) for r in rows[1:])
    # Interval = time to the next click, the shorter column padded with NaN at its end.
    assert [number(r[1]) for r in rows[1:-1]] == pytest.approx(np.diff(expected), rel=1e-8)
    assert rows[-1][1] == "NaN"
    # The header is quoted in the file, as phyphox writes it.
    assert (tmp_path / "a.csv").read_text().startswith('"Event time (s)","Interval (s)"')


def test_phyphox_number_format_matches_java_decimalformat(tmp_path):
    write_phyphox_stopwatch(tmp_path / "a.csv", [0.0, 9.9999999999], start_delay=0.5,
                            sample_rate=1e12)
    rows = rows_of(tmp_path / "a.csv")
    # 0.5 -> 5.000000000E-1 ; 10.4999999999 -> 1.050000000E1 (no '+', no zero padding)
    assert rows[1][0] == "5.000000000E-1"
    assert rows[2][0] == "1.050000000E1"


@pytest.mark.parametrize("delimiter,decimal", [("\t", "."), (";", "."), ("\t", ","), (";", ",")])
def test_stopwatch_variants_use_the_separator_and_decimal_mark(tmp_path, delimiter, decimal):
    write_phyphox_stopwatch(tmp_path / "a.csv", [0.0, 0.75], delimiter=delimiter, decimal=decimal)
    rows = rows_of(tmp_path / "a.csv", delimiter)
    assert rows[0] == ["Event time (s)", "Interval (s)"]
    assert rows[1][0] == ("5.000000000E-1" if decimal == "." else "5,000000000E-1")
    assert number(rows[2][0]) == pytest.approx(1.25)


def test_stock_stopwatch_sets_in_excel(tmp_path):
    times = [0.0, 0.4, 0.7, 0.9]  # four clicks: stops 4 and 5 never trigger
    write_phyphox_stopwatch(tmp_path / "a.xlsx", times, layout="multiple", excel=True,
                            start_delay=1.0)
    book = openpyxl.load_workbook(tmp_path / "a.xlsx", read_only=True)
    assert book.sheetnames == ["Simple", "Multiple", "Metadata Device", "Metadata Time"]
    simple = list(book["Simple"].iter_rows(values_only=True))
    assert simple[0] == ("Start (s)", "Stop (s)", "Difference (s)")
    assert simple[1] == pytest.approx((1.0, 1.4, 0.4))
    multiple = list(book["Multiple"].iter_rows(values_only=True))
    assert multiple[0] == ("Start (s)", "Stop 1 (s)", "Stop 2 (s)", "Stop 3 (s)", "Stop 4 (s)",
                           "Stop 5 (s)")
    assert multiple[1] == pytest.approx((1.0, 1.4, 1.7, 1.9, 0.0, 0.0))


def test_zipped_export_holds_one_csv_per_set_and_metadata(tmp_path):
    write_phyphox_stopwatch(tmp_path / "a.zip", [0.0, 0.5], layout="multiple", zipped=True)
    names = zipfile.ZipFile(tmp_path / "a.zip").namelist()
    assert names == ["Simple.csv", "Multiple.csv", "meta/device.csv", "meta/time.csv"]


def test_collision_heights_and_energies_follow_the_experiment(tmp_path):
    # Flights of 0.8, 0.64 and 0.512 s (ratio 0.8): h = g/8·Δt², E_i = Δt_i²/Δt_1².
    times = [0.0, 0.8, 1.44, 1.952]
    truth = write_phyphox_collision(tmp_path / "c.csv", times, start_delay=0.5,
                                    export_delay=2.0)
    header, values = rows_of(tmp_path / "c.csv")
    cell = dict(zip(header, map(number, values)))
    assert header[:5] == ["Bounce 0 (s)", "Height 0 (m)", "Bounce 1 (s)", "Height 1 (m)",
                          "Energy 1"]
    assert [cell[f"Bounce {i} (s)"] for i in range(4)] == pytest.approx([0.5, 1.3, 1.94, 2.452])
    assert cell["Bounce 4 (s)"] == 0.0 and cell["Bounce 5 (s)"] == 0.0
    assert cell["Height 1 (m)"] == pytest.approx(9.81 / 8 * 0.8 ** 2, rel=1e-8)
    assert cell["Height 3 (m)"] == pytest.approx(9.81 / 8 * 0.512 ** 2, rel=1e-8)
    assert cell["Energy 1"] == 1.0
    assert cell["Energy 2"] == pytest.approx(0.64, rel=1e-8)
    assert cell["Height 0 (m)"] == pytest.approx(9.81 / 8 * 0.8 ** 2 / 0.64, rel=1e-8)
    # The first bounce not heard gets its height from the export time (2 s after the last).
    assert cell["Height 4 (m)"] == pytest.approx(9.81 / 8 * 2.0 ** 2, rel=1e-8)
    assert cell["Height 5 (m)"] == 0.0
    assert truth["impact_times"] == pytest.approx([0.5, 1.3, 1.94, 2.452])


def test_collision_keeps_only_six_bounces(tmp_path):
    truth = write_phyphox_collision(tmp_path / "c.csv", np.arange(9) * 0.3)
    assert len(truth["impact_times"]) == 6
    header = rows_of(tmp_path / "c.csv")[0]
    assert "Bounce 5 (s)" in header and "Bounce 6 (s)" not in header


# ------------------------------------------------------------------------------ timestamps

def test_timestamps_in_ms_with_uncertainty(tmp_path):
    truth = write_timestamps(tmp_path / "t.csv", [0.1, 0.25], unit="ms", uncertainty=2e-4,
                             delimiter=";", decimal=",")
    rows = rows_of(tmp_path / "t.csv", ";")
    assert rows == [["time (ms)", "uncertainty (ms)"], ["100,000", "0,2000"], ["250,000", "0,2000"]]
    assert truth["resolution"] == pytest.approx(1e-6)


def test_timestamps_round_to_the_written_digits(tmp_path):
    truth = write_timestamps(tmp_path / "t.csv", [0.1234567891], decimals=4, declare_unit=False)
    assert rows_of(tmp_path / "t.csv") == [["time"], ["0.1235"]]
    assert truth["impact_times"] == [0.1235]



# Seed of the scatter test below, drawn once at random when the test was written.
SCATTER_SEED = 918_273_645
CONFIG = Path(__file__).resolve().parents[1] / "config" / "config.yaml"


def _chi_square_range(dof):
    """Central 99.9 % range of a chi-square with `dof` degrees of freedom."""
    return stats.chi2.ppf(0.0005, dof), stats.chi2.ppf(0.9995, dof)


def _written_times(path):
    """Times and stated 1σ (s) of a timestamp table, read with the csv module."""
    rows = rows_of(path)
    assert rows[0] == ["time (s)", "uncertainty (s)"]
    values = np.array([[number(x) for x in row] for row in rows[1:]])
    return values[:, 0], values[:, 1]


def test_scattered_times_scatter_with_the_stated_sigma(tmp_path):
    """Many times: the deviations from the truth are N(0, σ²) by the chi-square of their
    standardized values, and without scatter the file holds the truth rounded."""
    truth = np.cumsum(np.full(4000, 0.01))
    sigma = 1e-5
    written = write_timestamps(tmp_path / "t.csv", truth, uncertainty=sigma, scatter=True,
                               seed=SCATTER_SEED, start_delay=0.5)
    times, stated = _written_times(tmp_path / "t.csv")
    assert np.all(stated == sigma) and written["scatter"] and written["start_delay"] == 0.5
    deviations = (times - (truth + 0.5)) / stated
    low, high = _chi_square_range(truth.size)
    assert low < np.sum(deviations ** 2) < high
    # The draws are independent of the seed's neighbours: another seed, other times.
    write_timestamps(tmp_path / "u.csv", truth, uncertainty=sigma, scatter=True,
                     seed=SCATTER_SEED + 1, start_delay=0.5)
    assert not np.array_equal(_written_times(tmp_path / "u.csv")[0], times)
    # Without scatter the times are the truth to the written digit (1 µs).
    write_timestamps(tmp_path / "v.csv", truth, uncertainty=sigma, start_delay=0.5)
    exact, _ = _written_times(tmp_path / "v.csv")
    assert np.max(np.abs(exact - (truth + 0.5))) <= 0.5e-6 + 1e-12


def test_timestamp_table_scene_scatters_with_its_stated_uncertainty(tmp_path):
    """The workflow's timestamp-table scene, as config/config.yaml defines it: its written
    times scatter about truth.json's impact times with the 1σ the file states."""
    import yaml

    from dashpot.pipeline import write_synthetic_scene

    spec = yaml.safe_load(CONFIG.read_text(encoding="utf-8"))["synthetic"]["timestamp-table"]
    write_synthetic_scene(tmp_path, spec, name="timestamp-table")
    truth = json.loads((tmp_path / "truth.json").read_text())
    times, stated = _written_times(tmp_path / "timestamps.csv")
    true_times = np.asarray(truth["sequence"]["impact_times"])
    start = truth["recording"]["start_delay"]
    assert times.size == true_times.size >= 10
    assert np.all(stated == spec["options"]["uncertainty"])
    chi_square = np.sum(((times - (true_times + start)) / stated) ** 2)
    low, high = _chi_square_range(times.size)
    assert low < chi_square < high, (chi_square, low, high)


def test_scatter_needs_an_uncertainty_and_a_start_delay(tmp_path):
    with pytest.raises(ValueError, match="scatter needs"):
        write_timestamps(tmp_path / "t.csv", [0.0, 1.0], scatter=True, start_delay=1.0)
    with pytest.raises(ValueError, match="6 sigma"):
        write_timestamps(tmp_path / "t.csv", [0.0, 1.0], uncertainty=1e-3, scatter=True,
                         start_delay=5e-3)
    with pytest.raises(ValueError, match="start_delay"):
        write_timestamps(tmp_path / "t.csv", [0.0, 1.0], start_delay=-1.0)
    assert not any(tmp_path.iterdir())


# ------------------------------------------------------------------------ motion and gates

def test_motion_sensor_positions_follow_free_motion_on_the_incline(tmp_path):
    seq = dashpot.bounce_sequence(**STIFF)
    truth = write_motion_sensor(tmp_path / "m.csv", seq, noise=0.0, bumper_position=1.2,
                                sample_rate=25.0)
    rows = rows_of(tmp_path / "m.csv")
    assert rows[0] == ["Time (s) Run #1", "Position (m) Run #1", "Velocity (m/s) Run #1"]
    data = np.array([[float(c) for c in r] for r in rows[1:]])
    t, x, v = data.T
    run = truth["runs"][0]
    assert truth["g_eff"] == pytest.approx(G_EFF)
    impacts = np.array(run["impact_times"])
    assert np.diff(impacts) == pytest.approx(np.asarray(seq.intervals))
    # In flight n the cart leaves the bumper at u_n = v_{n+1} after the contact and is at
    # distance s = u·τ − g·τ²/2; the sensor at the top reads 1.2 m − s.
    n = 3
    leave = impacts[n] + seq.contact_durations[n]
    u = seq.impact_speeds[n + 1]
    inside = (t > leave + 0.05) & (t < impacts[n + 1] - 0.05)
    tau = t[inside] - leave
    assert inside.sum() > 10
    assert x[inside] == pytest.approx(1.2 - (u * tau - G_EFF / 2 * tau ** 2), abs=6e-5)
    # Central differences of a parabola are exact: velocity = −(u − g·τ) (moving up, away).
    middle = inside & np.roll(inside, 1) & np.roll(inside, -1)
    assert v[middle] == pytest.approx(-(u - G_EFF * (t[middle] - leave)), abs=3e-3)
    # Held still before release, resting at the bumper after the last impact.
    assert np.all(x[t < run["release_time"]] == x[0])
    assert x[0] == pytest.approx(1.2 - 0.5 ** 2 / (2 * G_EFF), abs=1e-4)
    assert np.all(x[t > impacts[-1] + 0.2] == pytest.approx(1.2, abs=1e-4))
    assert run["rebound_speeds"][-1] == 0.0


def test_vernier_runs_are_labelled_and_padded(tmp_path):
    seq = dashpot.bounce_sequence(**STIFF)
    truth = write_motion_sensor(tmp_path / "m.csv", seq, vendor="vernier", runs=3,
                                quantities=("position",), lead=0.5, seed=3)
    rows = rows_of(tmp_path / "m.csv")
    assert rows[0] == ["Run 1: Time (s)", "Run 1: Position (m)", "Run 2: Time (s)",
                       "Run 2: Position (m)", "Latest: Time (s)", "Latest: Position (m)"]
    lengths = [sum(1 for r in rows[1:] if r[2 * k] != "") for k in range(3)]
    assert len(set(lengths)) > 1 or lengths[0] == len(rows) - 1
    assert [r["label"] for r in truth["runs"]] == ["Run 1", "Run 2", "Latest"]
    # Each run's clock starts at its own recording; releases differ by < 1 sample period.
    releases = [r["release_time"] for r in truth["runs"]]
    assert max(releases) - min(releases) < 1 / 20.0


def test_photogate_events_are_exact_crossings(tmp_path):
    seq = dashpot.bounce_sequence(**STIFF)
    flag, gap = 0.025, 0.015
    truth = write_photogate(tmp_path / "g.csv", seq, flag_length=flag, gate_distance=gap)
    rows = rows_of(tmp_path / "g.csv")
    assert rows[0] == ["Latest: Time (s)", "Latest: GateState"]
    times = np.array([float(r[0]) for r in rows[1:]])
    states = [r[1] for r in rows[1:]]
    assert states[:5] == ["0", "1", "0", "1", "0"]
    # First passage: sliding down, s(τ) = v0·τ − g·τ²/2 with τ before the first impact; the
    # flag blocks the beam from s = gap + flag down to s = gap.
    first_impact = truth["impact_times"][0]
    before = [min(np.roots([-G_EFF / 2, 0.5, -level]).real) for level in (gap + flag, gap)]
    assert times[1:3] == pytest.approx([first_impact - before[0], first_impact - before[1]],
                                       abs=1e-6)
    # Away passage after impact 0: leaves at the rebound speed after the contact.
    leave = first_impact + seq.contact_durations[0]
    u = seq.impact_speeds[1]
    after = [min(np.roots([-G_EFF / 2, u, -level]).real) for level in (gap, gap + flag)]
    assert times[3:5] == pytest.approx([leave + after[0], leave + after[1]], abs=1e-6)
    kinds = truth["passages"]["kind"]
    assert kinds[:4] == ["toward", "away", "toward", "away"]
    assert set(kinds[kinds.index("partial"):]) == {"partial"}  # once partial, always partial
    assert truth["passages"]["mean_speed"][0] == pytest.approx(flag / (times[2] - times[1]),
                                                               rel=1e-4)


def test_sampled_photogate_matches_the_events(tmp_path):
    seq = dashpot.bounce_sequence(**STIFF)
    truth = write_photogate(tmp_path / "g.csv", seq, flag_length=0.02, mode="sampled",
                            sample_rate=500.0, vendor="pasco")
    rows = rows_of(tmp_path / "g.csv")
    assert rows[0] == ["Time (s) Run #1", "Gate State Run #1"]
    t = np.array([float(r[0]) for r in rows[1:]])
    blocked = np.array([r[1] == "1" for r in rows[1:]])
    starts = np.array(truth["passages"]["start"])
    ends = np.array(truth["passages"]["end"])
    inside = ((t[:, None] >= starts) & (t[:, None] < ends)).any(axis=1)
    assert np.array_equal(blocked, inside)
    assert np.allclose(np.diff(t), 1 / 500.0)


# -------------------------------------------------------------- reproducibility and safety

def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("writer", ["motion", "photogate", "xlsx", "zip"])
def test_same_seed_same_bytes_and_no_leftovers(tmp_path, writer):
    seq = dashpot.bounce_sequence(**STIFF)
    write = {
        "motion": lambda p, s, **kw: write_motion_sensor(p, seq, seed=s, runs=2, **kw),
        "photogate": lambda p, s, **kw: write_photogate(p, seq, flag_length=0.02, seed=s, **kw),
        "xlsx": lambda p, s, **kw: write_phyphox_stopwatch(p, seq.impact_times, excel=True,
                                                           **kw),
        "zip": lambda p, s, **kw: write_phyphox_collision(p, seq.impact_times, zipped=True,
                                                          **kw),
    }[writer]
    first, second, other = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    write(first, 7)
    write(second, 7)
    write(other, 8)
    assert digest(first) == digest(second)
    if writer in ("motion", "photogate"):
        assert digest(first) != digest(other)
    write(first, 7, overwrite=True)  # replacing goes through a temporary name and os.replace
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b", "c"]
    assert digest(first) == digest(second)


def test_bad_arguments_raise_value_errors(tmp_path):
    seq = dashpot.bounce_sequence(**STIFF)
    with pytest.raises(ValueError, match="delimiter"):
        write_timestamps(tmp_path / "t.csv", [0.0, 1.0], delimiter="|")
    with pytest.raises(ValueError, match="comma"):
        write_phyphox_stopwatch(tmp_path / "t.csv", [0.0, 1.0], delimiter=",", decimal=",")
    with pytest.raises(ValueError, match="increasing"):
        write_timestamps(tmp_path / "t.csv", [1.0, 0.5])
    with pytest.raises(ValueError, match="vendor"):
        write_motion_sensor(tmp_path / "m.csv", seq, vendor="acme")
    with pytest.raises(ValueError, match="noise"):
        write_motion_sensor(tmp_path / "m.csv", seq, noise=-1e-4)
    with pytest.raises(ValueError, match="released above the gate"):
        write_photogate(tmp_path / "g.csv", seq, flag_length=0.2, gate_distance=0.1)
    one = dashpot.bounce_sequence("Ia", beta=1.0, omega0=100.0, g=1.0, v0=1.0, n_max=1)
    with pytest.raises(ValueError, match="g_eff"):
        write_motion_sensor(tmp_path / "m.csv", one)
    assert not any(tmp_path.iterdir())  # nothing half-written


def test_single_impact_sequence_with_explicit_g(tmp_path):
    one = dashpot.bounce_sequence("Ia", beta=1.0, omega0=100.0, g=1.0, v0=1.0, n_max=1)
    truth = write_motion_sensor(tmp_path / "m.csv", one, g_eff=1.0, noise=0.0)
    assert truth["runs"][0]["impact_times"] == pytest.approx(
        [truth["runs"][0]["release_time"] + 1.0])  # slides 1 s from rest at v0/g
    assert math.isclose(truth["g_eff"], 1.0)


def test_csv_text_is_plain_utf8_lines(tmp_path):
    write_timestamps(tmp_path / "t.csv", [0.0, 1.0])
    raw = (tmp_path / "t.csv").read_bytes()
    assert raw.endswith(b"\n") and b"\r" not in raw
    assert list(csv.reader(io.StringIO(raw.decode()))) == [["time (s)"], ["0.000000"],
                                                          ["1.000000"]]
