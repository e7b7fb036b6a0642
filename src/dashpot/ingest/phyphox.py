"""Readers of phyphox's Acoustic Stopwatch and (In)elastic collision exports.

References
----------
.. [1] phyphox experiment definitions ``acoustic_stopwatch.phyphox`` and
   ``inelastic_collision.phyphox`` (repository phyphox/phyphox-experiments): export sets
   "Simple" (``Start (s)``, ``Stop (s)``, ``Difference (s)``), "Multiple" (``Start (s)``,
   ``Stop 1 (s)`` … ``Stop 5 (s)``) and "Energy" (``Bounce i (s)``, ``Height i (m)``,
   ``Energy i``); heights h_i = (g/8)·(t_i − t_{i−1})² with g = 9.81 m/s².
.. [2] phyphox-android ``DataExport.java``: CSV with quoted headers, numbers formatted
   ``0.000000000E0``, separators comma/tab/semicolon with decimal point or comma, one CSV per
   set in a zip (metadata under ``meta/``), or one Excel sheet per set (a legacy ``.xls``);
   shorter columns padded with ``NaN``.
"""

from __future__ import annotations

import re

import numpy as np

from ..errors import InputError
from ._tabular import (_cell_resolutions, _check_duplicates, _check_times, _impact_frame,
                       _load_tables, _numbers, _phyphox_layout, _unit_factor)

PHYPHOX_AUDIO_RATE = 48000.0
"""Hz. phyphox's stopwatch experiments time a click by the index of an audio sample, so their
times sit on this grid (the usual rate of phone microphones)."""

# ---------------------------------------------------------------------------------------------
# phyphox
# ---------------------------------------------------------------------------------------------

def _phyphox_time_uncertainty(resolution):
    """1σ of a phyphox click time: one audio sample (uniform) and the printed digits."""
    sample = 1.0 / (PHYPHOX_AUDIO_RATE * np.sqrt(12.0))
    digits = np.nan_to_num(resolution, nan=0.0) / np.sqrt(12.0)
    return np.hypot(sample, digits)


def _column_index(table, pattern):
    """{name: index} of the columns whose name matches `pattern` fully."""
    return {c.name: j for j, c in enumerate(table.columns) if re.fullmatch(pattern, c.name)}


def _phyphox_clicks(path, table, notes):
    """Per-click table: 'Event time' (s from the start of the recording) and/or 'Interval'."""
    where = table.where
    index = _column_index(table, r"event time|interval")
    times = intervals = None
    for name, j in index.items():  # at most two columns
        factor = _unit_factor(path, where, table.columns[j], table, "time") or 1.0
        values, resolution = _numbers(path, table, j, what=name)
        if name == "event time":
            times, time_resolution = values * factor, resolution * factor
        else:
            intervals, interval_resolution = values * factor, resolution * factor
    rows = np.arange(table.cells.shape[0])
    if times is not None:
        # phyphox pads shorter columns with NaN at the end: trailing blanks are padding.
        filled = np.flatnonzero(np.isfinite(times) | (table.cells[:, index["event time"]] != ""))
        used = rows[: filled[-1] + 1] if filled.size else rows[:0]
        _check_times(path, table, times[used], used, "event time")
        times, time_resolution = times[used], time_resolution[used]
        if intervals is not None:
            # Either alignment occurs: row k holds t_k − t_{k−1} (first row blank) or, when the
            # export pads the shorter buffer at its end, t_{k+1} − t_k (last row blank).
            steps = np.diff(times)
            digits = np.fmax(time_resolution,
                             _cell_resolutions(table, index["event time"])[used])
            digits += np.nan_to_num(
                _cell_resolutions(table, index["interval"])[: times.size], nan=0.0)
            tolerance = 2.0 * (digits[1:] + digits[:-1]) + 1e-9
            both = np.isfinite(intervals[: times.size])
            backward = np.abs(intervals[1:times.size] - steps)
            forward = np.abs(intervals[: times.size - 1] - steps)
            if np.all((backward <= tolerance) | ~both[1:times.size]):
                notes.append("'Interval' holds the time since the previous click; it agrees "
                             "with 'Event time'")
            elif np.all((forward <= tolerance) | ~both[: times.size - 1]):
                notes.append("'Interval' holds the time to the next click (phyphox pads the "
                             "shorter column at its end); it agrees with 'Event time'")
            else:
                bad = np.flatnonzero((backward > tolerance) & both[1:times.size])
                k = int(bad[0]) + 1 if bad.size else 1
                raise InputError(path, f"{where}'Interval' {intervals[k]:g} s disagrees with the "
                                       f"difference of 'Event time' ({steps[k - 1]:g} s)",
                                 row=k + 1)
        return times, _phyphox_time_uncertainty(time_resolution)
    finite = np.isfinite(intervals)
    if not finite.any():
        raise InputError(path, f"{where}'Interval' column holds no numbers")
    values = intervals[finite]
    if np.any(values <= 0):
        k = int(rows[finite][np.flatnonzero(values <= 0)[0]])
        raise InputError(path, f"{where}interval {intervals[k]:g} s is not positive", row=k + 1)
    times = np.concatenate([[0.0], np.cumsum(values)])
    res = interval_resolution[finite]
    notes.append("no 'Event time' column: clicks rebuilt from the intervals with the first "
                 "click at t = 0 s; each time accumulates the rounding of the intervals before it")
    resolution = np.concatenate([[0.0], np.sqrt(np.cumsum(res ** 2))])
    return times, _phyphox_time_uncertainty(resolution)


def _phyphox_single_row(path, table, pattern, notes, what):
    """The one data row of the stock Stopwatch or Collision sets as {name: (value, res)}."""
    if table.cells.shape[0] != 1:
        raise InputError(path, f"{table.where}a phyphox '{what}' set has one data row; this one "
                               f"has {table.cells.shape[0]}")
    out = {}
    for name, j in _column_index(table, pattern).items():  # loop over columns
        factor = _unit_factor(path, table.where, table.columns[j], table, "time") or 1.0
        value, resolution = _numbers(path, table, j, what=f"'{table.columns[j].header}'")
        out[name] = (value[0] * factor, resolution[0] * factor)
    return out


def _triggered_in_order(path, table, found, order, what, gap_problem):
    """Times and resolutions of a one-row phyphox set, in `order`, up to the first unset one.

    Buffers start at 0 and stay 0 until their event arrives (init="0" in the experiments [1]_),
    so a 0 (or empty) cell is an event that never happened; one followed by a set cell means a
    corrupt or edited file.
    """
    values = np.array([found[n][0] for n in order])
    resolution = np.array([found[n][1] for n in order])
    happened = np.isfinite(values) & (values > 0)
    skipped = np.flatnonzero(~happened)
    if skipped.size and np.any(happened[skipped[0]:]):
        raise InputError(path, f"{table.where}'{order[skipped[0]]}' {gap_problem}", row=1)
    times = values[happened]
    _check_times(path, table, times, np.zeros(times.size, dtype=int), what)
    return times, resolution[happened]


def _phyphox_stopwatch(path, table, layout, notes):
    """Stock Acoustic Stopwatch sets: Start and Stop(s) in one row; 0 means 'not triggered'."""
    found = _phyphox_single_row(path, table, r"start|stop|stop \d+", notes, layout)
    order = sorted(found, key=lambda n: (n != "start", int(n.split()[1]) if " " in n else 0))
    times, resolution = _triggered_in_order(path, table, found, order, "click time",
                                            "never triggered but a later stop did")
    notes.append(f"phyphox Acoustic Stopwatch, '{layout.capitalize()}' set: {times.size} "
                 f"click(s) ({len(order) - times.size} stop(s) never triggered)")
    return times, _phyphox_time_uncertainty(resolution)


def _phyphox_collision(path, table, notes):
    """(In)elastic collision 'Energy' set: Bounce i (s) are the impact times themselves."""
    found = _phyphox_single_row(path, table, r"bounce \d+", notes, "Energy")
    order = sorted(found, key=lambda n: int(n.split()[1]))
    times, resolution = _triggered_in_order(path, table, found, order, "bounce time",
                                            "was never detected but a later bounce was")
    notes.append(f"phyphox (In)elastic collision: {times.size} bounce time(s) read from "
                 f"'Bounce i (s)' ({len(order) - times.size} never detected)")
    # The heights are the experiment's own function of the times, h_i = (g/8)·Δt_i² [1]_: read
    # back the g they imply as a consistency check of the file.
    heights = {int(c.name.split()[1]): j for j, c in enumerate(table.columns)
               if re.fullmatch(r"height [1-9]\d*", c.name)}
    usable = [i for i in sorted(heights) if i < times.size]
    if usable:
        h = np.array([_numbers(path, table, heights[i], what="height")[0][0] for i in usable])
        h = h * np.array([_unit_factor(path, table.where, table.columns[heights[i]], table,
                                       "length") or 1.0 for i in usable])
        steps = np.diff(times)[np.array(usable) - 1]
        implied = 8.0 * h / steps ** 2
        notes.append(f"heights imply g = {np.median(implied):.4g} m/s² (phyphox uses 9.81); "
                     f"spread {np.ptp(implied):.2g} m/s²")
    return times, _phyphox_time_uncertainty(resolution)


def read_phyphox(path):
    """Impact times from a phyphox Acoustic Stopwatch or (In)elastic collision export.

    Parameters
    ----------
    path : str or os.PathLike
        A phyphox export in any of its variants: CSV separated by comma, tab or semicolon, with
        decimal point or comma (the variant is sniffed); the zip archive of the normal CSV
        export (one CSV per set); or an Excel workbook (one sheet per set).

    Returns
    -------
    pandas.DataFrame
        Impact table of :mod:`dashpot.ingest`: ``time`` in s from the start of the phyphox
        recording, ``time_uncertainty`` in s; amplitudes and speeds are NaN (not measured);
        ``run`` 0. ``attrs['notes']`` names the experiment, the set and the file variant.

    Raises
    ------
    InputError
        Empty file, not a table, no table in a phyphox layout (an Excel workbook whose sheets
        have other columns), a cell that is not a number, missing, negative or non-increasing
        click times, duplicated rows, unknown units, an 'Interval' that contradicts the times.

    Notes
    -----
    Layouts recognised (headers in the export's own words, units in parentheses) [1]_ [2]_:

    * per-click table: ``Event time (s)`` (time of each click from the start of the
      recording) and/or ``Interval (s)`` (time between consecutive clicks), one row per click.
      With both, the intervals are checked against the differences of the times (either row
      alignment). With intervals only, the first click is put at t = 0 and the others follow
      by accumulation.
    * stock Acoustic Stopwatch: set "Multiple" (``Start (s)``, ``Stop 1 (s)`` … ``Stop 5
      (s)``) or "Simple" (``Start (s)``, ``Stop (s)``, ``Difference (s)``), one row. Each value
      is an absolute time; 0 means the stop never triggered (the buffers start at 0).
      "Multiple" is preferred when an archive or workbook holds both.
    * (In)elastic collision, set "Energy": ``Bounce 0 (s)`` … ``Bounce 5 (s)``, ``Height i
      (m)``, ``Energy i``, one row. The impact times are the bounce times themselves (absolute,
      from the recording start; 0 = not detected). phyphox derives everything else from them:
      the flight time Δt_i = t_i − t_{i−1}, the height h_i = (g/8)·Δt_i², g = 9.81 m/s²,
      the energy ratio E_i = Δt_i²/Δt_1², and "Height 0" = h_1/E_2 extrapolated to the drop.
      Heights of bounces not yet detected are computed by phyphox from the export time and are
      meaningless; they are ignored. The g implied by the heights is reported as a check.

    phyphox times a click by the loudest audio sample after the threshold is crossed, on the
    48 kHz sample grid: ``time_uncertainty`` is one sample over √12 combined with the printed
    digits (a floor; the peak-vs-onset offset is the same for every click and cancels in
    intervals).
    """
    tables = _load_tables(path)
    layouts = [_phyphox_layout(t) for t in tables]
    preference = ("clicks", "multiple", "simple", "collision")
    ranked = sorted((preference.index(lay), k) for k, lay in enumerate(layouts) if lay)
    if not ranked:
        seen = "; ".join((t.where or "") + (", ".join(c.header for c in t.columns)
                                            if t.columns else "no header") for t in tables)
        raise InputError(path, f"no phyphox Acoustic Stopwatch or (In)elastic collision table "
                               f"(expected e.g. 'Event time (s)', 'Start (s)'/'Stop 1 (s)' or "
                               f"'Bounce 0 (s)'; found {seen})")
    table = tables[ranked[0][1]]
    layout = layouts[ranked[0][1]]
    notes = [f"file variant: {table.variant}"
             + (f", {table.where.rstrip(': ')}" if table.member else "")]
    _check_duplicates(path, table)
    if layout == "clicks":
        notes.insert(0, "phyphox Acoustic Stopwatch, per-click table")
        times, uncertainty = _phyphox_clicks(path, table, notes)
    elif layout == "collision":
        times, uncertainty = _phyphox_collision(path, table, notes)
    else:
        times, uncertainty = _phyphox_stopwatch(path, table, layout, notes)
    notes.append("times mark phyphox's loudest audio sample of each click (48 kHz grid); speeds "
                 "are not measured by this experiment")
    return _impact_frame(path, "phyphox", notes, times, uncertainty)
