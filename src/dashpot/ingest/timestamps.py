"""Readers of impact-time lists: a column of times in s or ms (with optional uncertainties),
and dashpot's own impact table as any spreadsheet re-saves it."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from . import (AUDIO_SUFFIXES, FLIGHT_CORRELATION_COLUMN, SPEED_OWN_COLUMNS,
               is_speed_error_column)
from ._tabular import (_TIME_NAMES, _UNCERTAINTY_NAMES, _check_duplicates, _check_times,
                       _impact_columns, _impact_frame, _is_impact_header, _is_label_track,
                       _kind_of,
                       _load_tables, _numbers, _unit_factor)

# ---------------------------------------------------------------------------------------------
# Plain impact-time lists
# ---------------------------------------------------------------------------------------------

_MS_INTERVAL_THRESHOLD = 20.0  # median interval above this (in file units) means milliseconds


def read_timestamps(path, *, unit=None):
    """One column of impact times, in s or ms, with optional per-row uncertainties.

    Parameters
    ----------
    path : str or os.PathLike
        Text table (any separator/decimal mark, sniffed) or workbook: a header like
        ``time (ms)``, ``t [s]``, ``impact time`` and optionally an uncertainty column
        (``uncertainty``, ``sigma``, ``error``, … with or without its own unit), or no header
        at all (first column times, optional second column uncertainties), or Audacity's
        label export (start, end and text of a label per line, no header: the starts are read,
        in s).
    unit : {"s", "ms"}, optional
        Unit of the times when the file does not say; must agree with the header if both do.

    Returns
    -------
    pandas.DataFrame
        Impact table of :mod:`dashpot.ingest` (times in s; speeds and amplitudes NaN; run 0).

    Raises
    ------
    InputError
        Empty file, not a table, no time column, a cell that is not a number, a missing,
        negative or non-increasing time, a duplicated row, a negative uncertainty, an unknown
        unit, or a unit argument contradicting the header.
    ValueError
        If `unit` is not "s" or "ms".

    Notes
    -----
    Unit inference (when neither header nor argument gives it), reported in ``notes``: the
    median interval between consecutive impacts is compared with 20 (in the file's units).
    A ball or cart bouncing to rest has intervals from about a millisecond (the last chatter)
    to a few seconds; 20 s between bounces would need a 500 m bounce of a ball, or a cart
    leaving at 10 m/s from a 1 m/s² incline, while 20 ms is the flight of a 0.5 mm bounce.
    So a median interval above 20 means milliseconds and below means seconds. A single time
    gives no interval and is taken in seconds (noted).

    Without an uncertainty column, ``time_uncertainty`` is the rounding of the written digits:
    one unit of the last decimal place over √12 (uniform rounding error).

    dashpot's own impact table (headers ``time`` and ``time_uncertainty``, as ``dashpot
    impacts`` writes them) is read by :func:`read_impact_table`, keeping all its columns.
    """
    if unit is not None and unit not in ("s", "ms"):
        raise ValueError(f"unit must be 's', 'ms' or None; got {unit!r}")
    tables = _load_tables(path)
    table = next((t for t in tables if _kind_of(t) == "timestamps"), None)
    if table is None:
        first = tables[0]
        described = ", ".join(c.header for c in first.columns) if first.columns else "no header"
        raise InputError(path, f"{first.where}no time column (expected a header like 'time (s)' "
                               f"or 'time (ms)'; found: {described})")
    if _is_impact_header(table):
        if unit == "ms":
            raise InputError(path, f"{table.where}dashpot's impact table holds times in s; "
                                   f"unit='ms' contradicts it")
        return _read_impact_table(path, table)
    where = table.where
    notes = [f"file variant: {table.variant}"]
    _check_duplicates(path, table)
    labels = _is_label_track(table)
    if labels:
        # Audacity's label export: the labels' starts are the marked impacts, in seconds.
        time_index, uncertainty_index = 0, None
        time_column = uncertainty_column = None
        regions = bool(np.any(_numbers(path, table, 1, what="label end")[0]
                              > _numbers(path, table, 0, what="label start")[0]))
        notes.append("no header, every second column at or after the first: an Audacity "
                     "label export (start, end, text), the label starts read as impact times "
                     "in s" + ("; region labels: their starts, not their ends, are the impacts"
                               if regions else ""))
        if unit == "ms":
            raise InputError(path, f"{where}an Audacity label export holds times in s; "
                                   f"unit='ms' contradicts it")
    elif table.columns is None:
        time_index, uncertainty_index = 0, (1 if table.cells.shape[1] > 1 else None)
        time_column = uncertainty_column = None
        notes.append("no header: first column read as times"
                     + (", second as their uncertainties" if uncertainty_index else ""))
    else:
        time_index = next(j for j, c in enumerate(table.columns) if c.name in _TIME_NAMES)
        uncertainty_index = next((j for j, c in enumerate(table.columns)
                                  if c.name in _UNCERTAINTY_NAMES), None)
        time_column = table.columns[time_index]
        uncertainty_column = (table.columns[uncertainty_index]
                              if uncertainty_index is not None else None)
    values, resolution = _numbers(path, table, time_index, what="time")
    rows = np.arange(values.size)
    header_factor = (_unit_factor(path, where, time_column, table, "time")
                     if time_column is not None else None)
    argument_factor = {"s": 1.0, "ms": 1e-3, None: None}[unit]
    if header_factor is not None and argument_factor is not None \
            and header_factor != argument_factor:
        raise InputError(path, f"{where}header '{time_column.header}' says the times are in "
                               f"'{time_column.unit}' but unit={unit!r} was given")
    _check_times(path, table, values, rows, unit="")
    factor = header_factor if header_factor is not None else argument_factor
    if labels:
        factor = 1.0
    elif factor is None:
        if values.size < 2:
            factor = 1.0
            notes.append("time unit not declared and only one time: read as seconds")
        else:
            median_interval = float(np.median(np.diff(values)))
            factor = 1e-3 if median_interval > _MS_INTERVAL_THRESHOLD else 1.0
            notes.append(f"time unit not declared: median interval {median_interval:g} "
                         f"{'is over' if factor < 1 else 'is under'} {_MS_INTERVAL_THRESHOLD:g} "
                         f"(no bounce train has intervals that long in seconds), so the times "
                         f"were read as {'ms' if factor < 1 else 's'}")
    elif header_factor is not None:
        notes.append(f"time unit from the header: {time_column.unit}")
    else:
        notes.append(f"time unit from the argument: {unit}")
    times = values * factor
    if uncertainty_index is not None:
        sigma, _ = _numbers(path, table, uncertainty_index, what="uncertainty")
        own = (_unit_factor(path, where, uncertainty_column, table, "time")
               if uncertainty_column is not None else None)
        sigma = sigma * (own if own is not None else factor)
        bad = ~np.isfinite(sigma) | (sigma < 0)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise InputError(path, f"{where}uncertainty '{table.cells[k, uncertainty_index]}' is "
                                   f"missing or negative", row=k + 1)
        if table.columns is None and times.size > 1:
            _check_unnamed_uncertainties(path, table, times, sigma, uncertainty_index)
        notes.append("time uncertainties from the file's uncertainty column")
    else:
        sigma = resolution * factor / np.sqrt(12.0)
        notes.append("time uncertainty: rounding of the written digits (last digit/√12)")
    return _impact_frame(path, "timestamps", notes, times, sigma)


def _check_unnamed_uncertainties(path, table, times, sigma, index):
    """InputError if a header-less second column cannot be the times' 1σ.

    An impact time uncertain by as much as the typical interval between impacts would not
    tell them apart; such a column is something else (a label, a counter, an end time),
    and reading it as uncertainties would weight the fit by nonsense.

    Parameters
    ----------
    path : str or os.PathLike
        The file, for the message.
    table : _Table
        The header-less table.
    times, sigma : numpy.ndarray
        Impact times and the second column read as their 1σ, both in s.
    index : int
        The second column's index.
    """
    median_interval = float(np.median(np.diff(times)))
    large = sigma >= median_interval
    if large.any():
        k = int(np.flatnonzero(large)[0])
        raise InputError(path, f"{table.where}the second column (no header) cannot be the "
                               f"times' uncertainties: '{table.cells[k, index]}' is not below "
                               f"the median interval between impacts ({median_interval:.4g} s); "
                               f"name the columns in a header row, e.g. 'time (s)' and "
                               f"'uncertainty (s)' (a label or counter column is not read)",
                         row=k + 1)


# ---------------------------------------------------------------------------------------------
# dashpot's own impact tables
# ---------------------------------------------------------------------------------------------

# Columns that hold a magnitude or a 1σ: never negative.
_NONNEGATIVE_COLUMNS = ("time_uncertainty", "impact_speed", "rebound_speed", "speed_uncertainty",
                        *SPEED_OWN_COLUMNS)
_LARGEST_RUN = 2**53 - 1  # floats hold every whole number up to 2^53 exactly, not beyond


def is_impact_table(path):
    """True if `path` is an impact table as ``dashpot impacts`` writes it (in any re-saving).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    bool
        False for audio files, unreadable files and tables without the headers ``time`` and
        ``time_uncertainty``.
    """
    if Path(path).suffix.lower() in AUDIO_SUFFIXES:
        return False
    try:
        return any(_is_impact_header(table) for table in _load_tables(path))
    except (InputError, OSError):
        return False


def read_impact_table(path):
    """Read an impact table written by ``dashpot impacts``, as saved by any spreadsheet.

    Parameters
    ----------
    path : str or os.PathLike
        Text table with the columns of :data:`dashpot.ingest.IMPACT_COLUMNS` (only ``time``
        is required), in any variant :func:`sniff_table` reads: comma, tab or semicolon
        separated, decimal point or comma, UTF-8 with or without a byte-order mark or UTF-16
        (Excel's "Unicode text"), leading ``#`` comment lines; or an Excel workbook.

    Returns
    -------
    pandas.DataFrame
        The impact table of :mod:`dashpot.ingest`, sorted by time; missing columns are NaN
        (``run`` 0). ``attrs['sensor']`` is "impact table".

    Raises
    ------
    InputError
        One line naming the file, and the row and column where they apply: no ``time``
        column; a cell that is not a number; an impact time that is empty, NaN or infinite;
        a negative or infinite uncertainty or speed; a ``run`` that is not a whole number
        from 0 to 2^53 - 1; times that do not increase within a run.

    Notes
    -----
    An empty or NaN ``time_uncertainty`` means the uncertainty is unknown: it stays NaN
    (never 0); the bounce table then gives NaN uncertainties for the intervals involving it,
    and the fit uses the file's other uncertainties (see :func:`dashpot.fit.prepare_data`).
    Times must increase within each run; runs may interleave in time (motion-sensor files
    hold several runs side by side).
    """
    tables = _load_tables(path)
    table = next((t for t in tables if "time" in _impact_columns(t)), None)
    if table is None:
        described = "; ".join(
            (t.where or "") + (", ".join(c.header for c in t.columns) if t.columns
                               else "no header") for t in tables)
        raise InputError(path, f"no 'time' column: not an impact table written by `dashpot "
                               f"impacts` (found: {described})")
    return _read_impact_table(path, table)


def _read_impact_table(path, table):
    """The impact table held in `table` (see read_impact_table)."""
    columns = _impact_columns(table)
    rows = table.cells.shape[0]

    def refuse(name, k, problem):
        raise InputError(path, f"{table.where}{problem}", row=int(k) + 1,
                         column=table.columns[columns[name]].header)

    flag = None
    if "flag" in columns:  # words, not numbers; an empty cell is an impact nobody flagged
        cells = table.cells[:, columns["flag"]]
        flag = np.where(cells == "", "ok", cells).astype(object)
    values = {name: _numbers(path, table, j, what=name)[0] for name, j in columns.items()
              if name != "flag"}
    time = values["time"]
    bad = ~np.isfinite(time)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        cell = table.cells[k, columns["time"]]
        refuse("time", k, "impact time is empty" if cell == "" else
               f"impact time '{cell}' is not a finite number")
    for name in values:
        if name == "time":
            continue
        value = values[name]
        bad = np.isinf(value) | ((value < 0) if name in _NONNEGATIVE_COLUMNS else False)
        if np.any(bad):
            k = int(np.flatnonzero(bad)[0])
            refuse(name, k, f"'{table.cells[k, columns[name]]}' is "
                            f"{'infinite' if np.isinf(value[k]) else 'negative'}")
    if FLIGHT_CORRELATION_COLUMN in values:
        bad = np.abs(values[FLIGHT_CORRELATION_COLUMN]) > 1.0
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            refuse(FLIGHT_CORRELATION_COLUMN, k, f"correlation "
                   f"'{table.cells[k, columns[FLIGHT_CORRELATION_COLUMN]]}' is outside [-1, 1]")
    if "run" in columns:
        run = values["run"]
        bad = ~np.isfinite(run) | (run < 0) | (run != np.round(run))
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            refuse("run", k, f"run '{table.cells[k, columns['run']]}' is not a whole number "
                             f"≥ 0")
        # Beyond 2^53 floats skip whole numbers (two runs could read as one), and the cast
        # to int64 wraps around past 2^63.
        large = run > _LARGEST_RUN
        if large.any():
            k = int(np.flatnonzero(large)[0])
            refuse("run", k, f"run '{table.cells[k, columns['run']]}' is too large (runs are "
                             f"numbered from 0 to {_LARGEST_RUN})")
        run = run.astype(int)
    else:
        run = np.zeros(rows, dtype=int)
    runs = np.unique(run)
    for number in runs:  # loop over runs
        members = np.flatnonzero(run == number)
        steps = np.diff(time[members])
        if np.any(steps <= 0):
            i = int(np.flatnonzero(steps <= 0)[0])
            k, before = members[i + 1], members[i]
            of_run = f" of run {number}" if runs.size > 1 else ""
            refuse("time", k, f"impact times must increase within a run: "
                              f"{float(time[k])!r} s is not after {float(time[before])!r} s "
                              f"in row {before + 1}{of_run}")
    notes = [f"dashpot impact table; file variant: {table.variant}"
             + (f", {table.where.rstrip(': ')}" if table.member else "")]
    sigma = values.get("time_uncertainty", np.full(rows, np.nan))
    unknown = int(np.sum(np.isnan(sigma)))
    if unknown:
        notes.append(f"{unknown} of {rows} impact time(s) have no uncertainty (empty or NaN "
                     f"time_uncertainty): treated as unknown")
    if runs.size > 1:
        notes.append(f"{runs.size} runs; times increase within each run")
    return _impact_frame(path, "impact table", notes, time, sigma,
                         amplitude=values.get("amplitude"),
                         impact_speed=values.get("impact_speed"),
                         rebound_speed=values.get("rebound_speed"),
                         speed_uncertainty=values.get("speed_uncertainty"), run=run,
                         flag=flag, speed_errors={name: value for name, value in values.items()
                                                  if is_speed_error_column(name)})
