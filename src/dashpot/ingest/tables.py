"""Readers of tabular lab files: phyphox exports, impact-time lists, motion sensors, video
trackers, photogates.

Every reader returns the impact table of :mod:`dashpot.ingest` (one row per impact, SI units,
sorted by time) with ``attrs`` ``source``, ``sensor`` (the kind, as :func:`sniff_table` names
it) and ``notes``. Files that cannot be used raise :class:`dashpot.errors.InputError` naming the
file, the 1-based data row (counted after the header) where that applies, and the problem.

Text tables are sniffed, not configured: the separator is the one of tab, semicolon or comma
that splits the first lines into the same number (> 1) of fields, and the decimal mark is a
comma when the separator is not and numbers like ``1,25`` occur. A first line that is a single
word above a separated header names a Tracker track (``mass_A``) and is skipped. Workbooks —
Excel ``.xlsx``, legacy Excel 97-2003 ``.xls`` (BIFF8, phyphox's "Excel" export) and
OpenDocument ``.ods`` — are read sheet by sheet through pandas' calamine engine, and zip
archives (phyphox's CSV export) member by member.

Column headers are read in the exporting program's own words: a name, a unit in parentheses or
brackets, and a run label either in front (Vernier: ``Latest: Time (s)``, ``Run 2: Position
(m)``) or behind (PASCO Capstone: ``Time (s) Run #1``). Tracker writes bare names (``t``,
``x``, ``y``) in its calibrated units (s and, usually, m).

References
----------
.. [1] phyphox experiment definitions ``acoustic_stopwatch.phyphox`` and
   ``inelastic_collision.phyphox`` (repository phyphox/phyphox-experiments): export sets
   "Simple" (``Start (s)``, ``Stop (s)``, ``Difference (s)``), "Multiple" (``Start (s)``,
   ``Stop 1 (s)`` … ``Stop 5 (s)``) and "Energy" (``Bounce i (s)``, ``Height i (m)``,
   ``Energy i``); heights h_i = (g/8)·(t_i − t_{i−1})² with g = 9.81 m/s².
.. [2] phyphox-android ``DataExport.java``: CSV with quoted headers, numbers formatted
   ``0.000000000E0``, separators comma/tab/semicolon with decimal point or comma, one CSV per
   set in a zip (metadata under ``meta/``), or one Excel sheet per set; shorter columns padded
   with ``NaN``.
.. [3] Vernier Logger Pro 3 help, "Photogate timing": the time column holds the clock times of
   all gate-status changes (blocked/unblocked).
.. [4] P. J. Rousseeuw and C. Croux, "Alternatives to the median absolute deviation", J. Am.
   Stat. Assoc. 88, 1273-1283 (1993): σ ≈ 1.4826·MAD for Gaussian noise.
.. [5] D. Halliday, R. Resnick and J. Walker, "Fundamentals of Physics", ch. 2: motion with
   constant acceleration, x = x0 + v0·t + a·t²/2, v² = v0² + 2a·Δx.
.. [6] W. K. Newey and K. D. West, "A simple, positive semi-definite, heteroskedasticity and
   autocorrelation consistent covariance matrix", Econometrica 55, 703-708 (1987): least-squares
   uncertainties under serially correlated noise via the long-run variance.
.. [7] D. Brown, Tracker video analysis and modeling tool, help pages "Exporting data" and
   "Datatable view": the data export is tab-delimited text, a first line with the track name,
   a header row (``t``, ``x``, ``y``, ...), numbers as ``0.000000000E0``; derivatives are
   blank at a track's first and last steps.
"""

from __future__ import annotations

import csv
import io
import re
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.integrate import cumulative_trapezoid

from .._validation import (BUMPER_POSITION_RANGE, FLAG_LENGTH_RANGE, GATE_DISTANCE_RANGE,
                           check_range)
from ..errors import InputError
from . import AUDIO_SUFFIXES, FLAG_COLUMN, IMPACT_COLUMNS

__all__ = ["read_phyphox", "read_timestamps", "read_motion_sensor", "read_photogate",
           "read_impact_table", "is_impact_table", "sniff_table", "TABLE_KINDS"]

TABLE_KINDS = ("phyphox", "timestamps", "motion_sensor", "photogate")
"""What :func:`sniff_table` can answer, and the ``sensor`` attribute of each reader's table."""

PHYPHOX_AUDIO_RATE = 48000.0
"""Hz. phyphox's stopwatch experiments time a click by the index of an audio sample, so their
times sit on this grid (the usual rate of phone microphones)."""

_MAD_TO_SIGMA = 1.4826  # σ of Gaussian noise from its median absolute deviation [4]_
_MEDIAN_EFFICIENCY = 1.2533  # σ(median) = 1.2533·σ/√n for Gaussian samples, √(π/2)

# ---------------------------------------------------------------------------------------------
# Units and header words
# ---------------------------------------------------------------------------------------------

_TIME_UNITS = {"s": 1.0, "sec": 1.0, "second": 1.0, "seconds": 1.0, "ms": 1e-3, "msec": 1e-3,
               "millisecond": 1e-3, "milliseconds": 1e-3, "us": 1e-6, "µs": 1e-6, "μs": 1e-6}
_LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
_SPEED_UNITS = {"m/s": 1.0, "cm/s": 1e-2, "mm/s": 1e-3, "m s-1": 1.0, "m·s⁻¹": 1.0}

_TIME_NAMES = {"time", "t", "zeit", "timestamp", "timestamps", "impact time", "impact times",
               "time of impact", "clock time"}
_POSITION_NAMES = {"position", "distance", "x", "y", "pos"}
_VELOCITY_NAMES = {"velocity", "v", "speed"}
_UNCERTAINTY_NAMES = {"uncertainty", "time uncertainty", "sigma", "σ", "error", "time error",
                      "std", "u", "dt"}

_HEADER = re.compile(
    r"^\s*(?:(?P<prefix>[^:()\[\]]+?)\s*:\s*)?"      # Vernier run label: 'Latest:', 'Run 2:'
    r"(?P<name>[^()\[\]]*?)\s*"
    r"(?:[(\[]\s*(?P<unit>[^()\[\]]*?)\s*[)\]])?\s*"  # unit: '(m/s)' or '[ms]'
    r"(?P<suffix>run\s*#?\s*\d+)?\s*$",              # PASCO run label: 'Run #1'
    re.IGNORECASE)
_NUMBER = re.compile(r"^[+-]?(?P<int>\d*)(?:\.(?P<frac>\d*))?(?:[eE](?P<exp>[+-]?\d+))?$")
# Zip archives (phyphox exports, .xlsx): what a member may expand to. A lab table of impacts
# or of a motion sensor's samples is at most a few MB; the ratio limit is Apache POI's
# default for the same protection (an expanded member at most 100 times its compressed size).
_ZIP_MEMBER_BYTES = 64_000_000
_ZIP_MAX_RATIO = 100
_ZIP_RATIO_FROM_BYTES = 1_000_000  # smaller members may compress as well as they like
_OLE2_MAGIC = b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1"  # compound file: Excel 97-2003 .xls
_ODS_MIMETYPE = b"application/vnd.oasis.opendocument.spreadsheet"
_WORKBOOK_VARIANTS = ("Excel", "OpenDocument")  # variants whose members are sheets


@dataclass(frozen=True)
class _Column:
    """One parsed column header."""

    header: str  # as written
    name: str  # lower case, single spaces, e.g. 'time', 'stop 1', 'bounce 0'
    unit: str | None  # as written inside the brackets, None if there are none
    run: str  # run label ('' when the header has none), e.g. 'Run #1', 'Latest', 'Run 2'


def _parse_header(header):
    """Split a column header into name, unit and run label (see module docstring)."""
    text = str(header).strip().strip('"').strip()
    match = _HEADER.match(text)
    if match is None:  # e.g. nested brackets: keep the whole header as the name
        return _Column(text, " ".join(text.lower().replace("_", " ").split()), None, "")
    name = " ".join(match["name"].lower().replace("_", " ").split())
    run = match["prefix"] or match["suffix"] or ""
    run = " ".join(run.split())
    unit = match["unit"]
    return _Column(text, name, unit.strip() if unit is not None else None, run)


def _unit_factor(path, where, column, table, kind):
    """SI factor of a column's unit for a quantity `kind` ('time', 'length', 'speed')."""
    units = {"time": _TIME_UNITS, "length": _LENGTH_UNITS, "speed": _SPEED_UNITS}[kind]
    if column.unit is None or column.unit == "":
        return None
    key = column.unit.replace(" ", "") if kind == "speed" else column.unit
    factor = units.get(key, units.get(key.lower()))
    if factor is None:
        raise InputError(path, f"{where}unknown {kind} unit '{column.unit}' in column header "
                               f"'{column.header}' (known: {', '.join(units)})")
    return factor


# ---------------------------------------------------------------------------------------------
# Loading: text, zip and Excel tables as header + string cells
# ---------------------------------------------------------------------------------------------

@dataclass
class _Table:
    """A table as written: parsed headers (None if the file has none) and string cells."""

    member: str | None  # sheet name or zip member, None for a plain text file
    columns: list[_Column] | None
    cells: np.ndarray  # 2-D array of str, '' for an empty cell
    decimal: str
    variant: str  # the sniffed layout in plain words

    @property
    def where(self):
        """Prefix for error messages that locates the table inside its file."""
        if self.member is None:
            return ""
        return (f"sheet '{self.member}': " if self.variant.startswith(_WORKBOOK_VARIANTS)
                else f"'{self.member}': ")


def _is_number(strings, decimal):
    """Boolean array: which cells are numbers (including 'NaN') in this decimal convention."""
    series = pd.Series(strings, dtype=object).astype(str)
    if decimal == ",":
        series = series.str.replace(",", ".", regex=False)
    return (pd.to_numeric(series, errors="coerce").notna() | series.str.fullmatch(r"(?i)nan")
            ).to_numpy()


def _sniff_separator(lines):
    """The separator that splits the sniffed lines into the header's number (> 1) of fields.

    One line in ten (at least one) may differ, so that a row with a stray extra field is
    reported by its row rather than hiding the separator.
    """
    for candidate in ("\t", ";", ","):
        counts = [len(fields) for fields in csv.reader(lines, delimiter=candidate)]
        if counts and counts[0] > 1:
            differing = sum(count != counts[0] for count in counts)
            if differing <= max(1, len(counts) // 10):
                return candidate
    return None


def _decode(path, raw, member):
    """Text of a table file and the name of its encoding.

    UTF-16 with a byte-order mark (Excel's "Unicode text") and UTF-8 with or without one are
    recognised; anything else is read as Windows-1252 (Excel's "CSV" on Western systems).
    """
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        try:
            return raw.decode("utf-16"), "UTF-16"
        except UnicodeDecodeError as error:
            raise InputError(path, f"not a table: {member or 'the file'} starts like UTF-16 "
                                   f"text but does not decode ({error.reason})") from None
    if b"\x00" in raw:
        raise InputError(path, f"not a table: {member or 'the file'} holds binary data")
    for encoding, name in (("utf-8-sig", "UTF-8"), ("cp1252", "Windows-1252")):
        try:
            return raw.decode(encoding), name
        except UnicodeDecodeError:
            continue
    raise InputError(path, f"not a table: {member or 'the file'} is not text")


def _rows_by_csv_module(path, text, separator, decimal, member):
    """Cells of a table whose rows have different numbers of fields (pandas refuses those).

    Rows shorter than the first are padded with empty cells; fields past the first row's
    width are dropped when empty (a trailing separator) and refused, naming the row, when not.
    """
    try:
        rows = [row for row in csv.reader(io.StringIO(text), delimiter=separator or "\x1f")
                if row and not (len(row) == 1 and not row[0].strip())]
    except csv.Error as error:
        raise InputError(path, f"not a table: {error}") from None
    width = len(rows[0])
    # Data rows are counted after the header; a first row of numbers is data itself.
    first_is_data = bool(np.all(_is_number([c.strip() for c in rows[0] if c.strip()], decimal)))
    for k, row in enumerate(rows):  # loop over rows only where pandas could not
        extra = [cell for cell in row[width:] if cell.strip()]
        if extra:
            where = f"'{member}': " if member else ""
            raise InputError(path, f"{where}{len(row)} fields where the header row has {width} "
                                   f"(extra '{extra[0].strip()}')",
                             row=k + (1 if first_is_data else 0))
    return np.array([row[:width] + [""] * (width - len(row)) for row in rows], dtype=str)


def _text_table(path, raw, member):
    """Parse one text table (CSV, TSV, semicolon-separated; either decimal mark).

    Lines starting with '#' before the first table line are comments and are skipped.
    """
    text, encoding = _decode(path, raw, member)
    lines = text.splitlines()
    comments = 0
    while comments < len(lines) and lines[comments].lstrip().startswith("#"):
        comments += 1
    if comments:
        text = "\n".join(lines[comments:])
    # Sniff from the first non-blank lines only; the whole table is parsed by pandas below.
    head = [line for line in lines[comments:comments + 60] if line.strip()][:20]
    if not head:
        raise InputError(path, f"{member + ': ' if member else ''}file is empty")
    separator = _sniff_separator(head)
    title = None
    if separator is None and len(head) > 2 and not _is_number([head[0].strip()], ".")[0]:
        # Tracker's data export: a first line naming the track ('mass_A'), then the header.
        below = _sniff_separator(head[1:])
        header_below = below is not None and not np.any(
            _is_number([f.strip() for f in next(csv.reader([head[1]], delimiter=below))], "."))
        if header_below and below not in head[0]:
            separator, title = below, head[0].strip()
            rest = lines[comments:]
            first = next(k for k, line in enumerate(rest) if line.strip())
            text = "\n".join(rest[first + 1:])
            head = head[1:]
    body = "\n".join(head[1:])
    decimal = "," if separator != "," and re.search(r"\d,\d", body) else "."
    try:
        frame = pd.read_csv(io.StringIO(text), sep=separator or "\x1f", header=None, dtype=str,
                            keep_default_na=False, skip_blank_lines=True, quotechar='"',
                            engine="c")
        cells = frame.fillna("").to_numpy(dtype=str)
    except pd.errors.ParserError:
        cells = _rows_by_csv_module(path, text, separator, decimal, member)
    except (pd.errors.EmptyDataError, ValueError) as error:
        raise InputError(path, f"not a table: {str(error).strip()}") from error
    cells = np.char.strip(cells)
    names = {"\t": "tab", ";": "semicolon", ",": "comma", None: "single-column"}
    variant = (f"CSV, {names[separator]}{' separated' if separator else ''}, decimal "
               f"{'comma' if decimal == ',' else 'point'}"
               + (f", {encoding}" if encoding != "UTF-8" else "")
               + (f", {comments} comment line(s) skipped" if comments else "")
               + (f", first line names the track '{title}' (Tracker data export)" if title
                  else ""))
    return _finish_table(path, cells, decimal, variant, member)


def _finish_table(path, cells, decimal, variant, member):
    """Split off the header row (if the first row is not all numbers) and check for data."""
    where = f"'{member}': " if member else ""
    if cells.size == 0 or not np.any(cells != ""):
        raise InputError(path, f"{where}file is empty")
    first = cells[0]
    if np.all(_is_number(first[first != ""], decimal)):
        columns = None
    else:
        columns = [_parse_header(h) for h in first]
        cells = cells[1:]
    table = _Table(member, columns, cells, decimal, variant)
    if cells.shape[0] == 0:
        raise InputError(path, f"{table.where}no data rows below the header")
    numeric = _is_number(cells.ravel(), decimal) & (cells.ravel() != "")
    if not numeric.any():
        raise InputError(path, f"not a table: {table.where or ''}no numeric data")
    return table


def _excel_tables(path, raw, variant):
    """Every sheet of a workbook (.xlsx, legacy BIFF .xls or OpenDocument .ods) as a table.

    All three are read by pandas with the calamine engine (python-calamine); numbers come back
    as floats, so their written digits are not known and the column's resolution is inferred
    from the spacing of its values (see _column_resolution).
    """
    try:
        sheets = pd.read_excel(io.BytesIO(raw), sheet_name=None, header=None, dtype=object,
                               engine="calamine")
    except Exception as error:  # calamine raises several kinds for damaged workbooks
        problem = " ".join(str(error).split()) or type(error).__name__
        raise InputError(path, f"not a readable {variant} workbook: {problem}") from error
    tables = []
    for name, frame in sheets.items():  # loop over sheets, not rows
        if frame.size == 0:
            continue
        cells = frame.astype(object).where(frame.notna(), "").astype(str).to_numpy(dtype=str)
        cells = np.char.strip(cells)
        try:
            tables.append(_finish_table(path, cells, ".", variant, str(name)))
        except InputError:
            continue  # e.g. a metadata sheet of words only; the caller reports what is missing
    if not tables:
        raise InputError(path, f"no sheet with a table of numbers (sheets: "
                               f"{', '.join(map(repr, sheets))})")
    return tables


def _check_zip_sizes(path, archive, names):
    """InputError if a member of `archive` would expand past what a lab table can be.

    A zip bomb (a few hundred KB expanding to hundreds of MB) would otherwise take minutes and
    many GB to parse. The sizes are those the archive declares: Python's zipfile stops a
    member at its declared size (and fails its CRC check if there was more).
    """
    infos = {info.filename: info for info in archive.infolist()}
    total = 0
    for name in names:
        info = infos[name]
        total += info.file_size
        ratio = info.file_size / max(info.compress_size, 1)
        if info.file_size > _ZIP_MEMBER_BYTES or (info.file_size > _ZIP_RATIO_FROM_BYTES
                                                  and ratio > _ZIP_MAX_RATIO):
            raise InputError(path, f"archive member '{name}' expands to "
                                   f"{info.file_size / 1e6:.0f} MB ({ratio:.0f} times its "
                                   f"compressed size): refused as a possible zip bomb (limits: "
                                   f"{_ZIP_MEMBER_BYTES / 1e6:.0f} MB, or {_ZIP_MAX_RATIO} times "
                                   f"above {_ZIP_RATIO_FROM_BYTES / 1e6:.0f} MB)")
    if total > _ZIP_MEMBER_BYTES:
        raise InputError(path, f"archive members expand to {total / 1e6:.0f} MB together: "
                               f"refused as a possible zip bomb (limit "
                               f"{_ZIP_MEMBER_BYTES / 1e6:.0f} MB)")


def _load_tables(path):
    """All tables in a file: a text table, every CSV of a zip, or every sheet of a workbook."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "no such file")
    raw = path.read_bytes()
    if not raw.strip():
        raise InputError(path, "file is empty")
    if raw[:4] == b"PK\x03\x04":
        try:
            archive = zipfile.ZipFile(io.BytesIO(raw))
            names = archive.namelist()
        except zipfile.BadZipFile as error:
            raise InputError(path, "not a table: a damaged zip/xlsx archive") from error
        if "xl/workbook.xml" in names:
            _check_zip_sizes(path, archive, names)
            return _excel_tables(path, raw, "Excel")
        if "mimetype" in names and archive.read("mimetype").startswith(_ODS_MIMETYPE):
            _check_zip_sizes(path, archive, names)
            return _excel_tables(path, raw, "OpenDocument spreadsheet (.ods)")
        members = [n for n in names if n.lower().endswith(".csv") and not n.startswith("meta/")]
        if not members:
            raise InputError(path, "not a table: a zip archive without CSV files")
        _check_zip_sizes(path, archive, members)
        tables = []
        for member in members:  # loop over archive members
            try:
                content = archive.read(member)
            except (zipfile.BadZipFile, zlib.error, EOFError) as error:
                raise InputError(path, f"not a table: archive member '{member}' is damaged "
                                       f"({error})") from None
            try:
                tables.append(_text_table(path, content, member))
            except InputError:
                continue
        if not tables:
            raise InputError(path, "not a table: no CSV member of the archive holds numbers")
        return tables
    if raw[:8] == _OLE2_MAGIC:
        # Excel 97-2003 (BIFF8 inside an OLE2 compound file), as phyphox's "Excel" export
        # writes it. The OLE2 container caps nothing itself, so refuse what no lab table needs.
        if len(raw) > _ZIP_MEMBER_BYTES:
            raise InputError(path, f"Excel 97-2003 workbook of {len(raw) / 1e6:.0f} MB: larger "
                                   f"than a lab table can be (limit "
                                   f"{_ZIP_MEMBER_BYTES / 1e6:.0f} MB)")
        return _excel_tables(path, raw, "Excel 97-2003 (.xls)")
    return [_text_table(path, raw, None)]


def _numbers(path, table, index, *, what):
    """Float values of column `index` and the resolution of the written digits.

    Empty cells and 'NaN' become NaN (callers decide what they mean); any other text raises
    InputError naming its row and column.
    """
    strings = pd.Series(table.cells[:, index], dtype=object).astype(str)
    if table.decimal == ",":
        strings = strings.str.replace(",", ".", regex=False)
    values = pd.to_numeric(strings.where(strings != ""), errors="coerce")
    bad = values.isna() & (strings != "") & ~strings.str.fullmatch(r"(?i)nan")
    if bad.any():
        row = int(np.flatnonzero(bad.to_numpy())[0])
        cell = table.cells[row, index]
        if table.columns:
            raise InputError(path, f"{table.where}'{cell}' is not a number", row=row + 1,
                             column=table.columns[index].header)
        raise InputError(path, f"{table.where}{what} '{cell}' is not a number", row=row + 1)
    # Resolution of the written digits: one unit of the last decimal place, allowing for an
    # exponent (phyphox writes 1.234567890E-1).
    parts = strings.str.extract(_NUMBER)
    decimals = parts["frac"].fillna("").str.len() - pd.to_numeric(parts["exp"]).fillna(0)
    resolution = 10.0 ** (-decimals.to_numpy(dtype=float))
    resolution[~np.isfinite(values.to_numpy(dtype=float))] = np.nan
    return values.to_numpy(dtype=float), resolution


def _check_duplicates(path, table, rows=None):
    """InputError naming the first data row that repeats an earlier one."""
    cells = table.cells if rows is None else table.cells[rows]
    frame = pd.DataFrame(cells)
    nonblank = (cells != "").any(axis=1)
    duplicated = frame.duplicated(keep="first").to_numpy() & nonblank
    if duplicated.any():
        row = int(np.flatnonzero(duplicated)[0])
        same = frame.iloc[:row][(frame.iloc[:row] == frame.iloc[row]).all(axis=1)].index[0]
        raise InputError(path, f"{table.where}row repeats row {same + 1} exactly (duplicated "
                               f"row)", row=row + 1)


def _check_times(path, table, times, rows, what="time", unit=" s"):
    """Times must be finite, non-negative and strictly increasing; name the first bad row."""
    where = table.where
    missing = ~np.isfinite(times)
    if missing.any():
        k = int(np.flatnonzero(missing)[0])
        raise InputError(path, f"{where}{what} is missing (empty or NaN)", row=int(rows[k]) + 1)
    negative = times < 0
    if negative.any():
        k = int(np.flatnonzero(negative)[0])
        raise InputError(path, f"{where}{what} {times[k]:g}{unit} is negative",
                         row=int(rows[k]) + 1)
    steps = np.diff(times)
    if np.any(steps <= 0):
        k = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise InputError(path, f"{where}{what} {times[k]:g}{unit} is not after the previous row's "
                               f"{times[k - 1]:g}{unit} (times must increase)",
                         row=int(rows[k]) + 1)


def _impact_frame(path, sensor, notes, time, time_uncertainty, *, amplitude=None,
                  impact_speed=None, rebound_speed=None, speed_uncertainty=None, run=None,
                  flag=None):
    """The impact table of dashpot.ingest, sorted by time, with its attrs."""
    n = np.asarray(time).size
    nan = np.full(n, np.nan)
    frame = pd.DataFrame({
        "time": np.asarray(time, dtype=float),
        "time_uncertainty": np.broadcast_to(np.asarray(time_uncertainty, dtype=float), (n,)),
        "amplitude": nan if amplitude is None else amplitude,
        "impact_speed": nan if impact_speed is None else impact_speed,
        "rebound_speed": nan if rebound_speed is None else rebound_speed,
        "speed_uncertainty": nan if speed_uncertainty is None else speed_uncertainty,
        "run": np.zeros(n, dtype=int) if run is None else np.asarray(run, dtype=int),
    }, columns=list(IMPACT_COLUMNS))
    if flag is not None:
        frame[FLAG_COLUMN] = np.asarray(flag, dtype=object)
    frame = frame.sort_values(["time", "run"], kind="stable").reset_index(drop=True)
    frame.attrs.update(source=str(path), sensor=sensor, notes=list(notes))
    return frame


# ---------------------------------------------------------------------------------------------
# Layout recognition
# ---------------------------------------------------------------------------------------------

def _names(table):
    return [] if table.columns is None else [c.name for c in table.columns]


def _phyphox_layout(table):
    """'clicks', 'multiple', 'simple', 'collision' or None for a table's header."""
    names = set(_names(table))
    if not names:
        return None
    if any(re.fullmatch(r"bounce \d+", n) for n in names):
        return "collision"
    if names & {"event time", "interval"}:
        return "clicks"
    if "start" in names and any(re.fullmatch(r"stop \d+", n) for n in names):
        return "multiple"
    if {"start", "stop"} <= names:
        return "simple"
    return None


def _is_state(column):
    return "state" in column.name or column.name in {"gate", "photogate", "blocked"}


def _kind_of(table):
    """Which reader a single table belongs to, or None."""
    if _phyphox_layout(table) is not None:
        return "phyphox"
    if _is_impact_header(table):
        return "timestamps"  # dashpot's own impact table, read by read_impact_table
    if table.columns is None:
        return "timestamps" if table.cells.shape[1] <= 2 else None
    names = _names(table)
    has_time = any(n in _TIME_NAMES for n in names)
    if not has_time:
        return None
    if any(_is_state(c) for c in table.columns):
        return "photogate"
    if any(n in _POSITION_NAMES | _VELOCITY_NAMES for n in names):
        return "motion_sensor"
    others = [n for n in names if n not in _TIME_NAMES and n != ""]
    if len(names) - len(others) == 1 and all(n in _UNCERTAINTY_NAMES for n in others) \
            and len(others) <= 1:
        return "timestamps"
    return None


def sniff_table(path):
    """Which kind of lab table a file is.

    Parameters
    ----------
    path : str or os.PathLike
        A CSV/TSV/semicolon text table (a Tracker data export included), a workbook (.xlsx,
        .xls, .ods) or a phyphox zip export.

    Returns
    -------
    str
        One of ``TABLE_KINDS``: "phyphox" (Acoustic Stopwatch or (In)elastic collision export),
        "motion_sensor" (time with position and/or velocity, PASCO, Vernier or Tracker),
        "photogate" (time with a gate state) or "timestamps" (one column of impact times,
        optionally their uncertainties, or a header-less column of numbers).

    Raises
    ------
    InputError
        If the file is empty, not a table, or none of these kinds.

    Notes
    -----
    The decision is made from the column headers alone (see the module docstring for how they
    are parsed); the first table of a workbook or archive that fits a kind decides.
    """
    tables = _load_tables(path)
    kinds = [_kind_of(t) for t in tables]
    for kind in kinds:
        if kind is not None:
            return kind
    described = "; ".join(
        (t.where or "") + (", ".join(c.header for c in t.columns) if t.columns else "no header")
        for t in tables)
    raise InputError(path, f"not a table of impacts, motion, gate states or phyphox clicks "
                           f"(columns: {described})")


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
            tolerance = 2.0 * (time_resolution[1:] + time_resolution[:-1]) + 1e-9
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
        at all (first column times, optional second column uncertainties).
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
    if table.columns is None:
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
    if factor is None:
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
        notes.append("time uncertainties from the file's uncertainty column")
    else:
        sigma = resolution * factor / np.sqrt(12.0)
        notes.append("time uncertainty: rounding of the written digits (last digit/√12)")
    return _impact_frame(path, "timestamps", notes, times, sigma)


# ---------------------------------------------------------------------------------------------
# dashpot's own impact tables
# ---------------------------------------------------------------------------------------------

# Columns that hold a magnitude or a 1σ: never negative.
_NONNEGATIVE_COLUMNS = ("time_uncertainty", "impact_speed", "rebound_speed", "speed_uncertainty")


def _impact_columns(table):
    """{column of IMPACT_COLUMNS: index} for the headers that are exactly those names."""
    found = {}
    for j, column in enumerate(table.columns or ()):
        key = column.header.strip().lower()
        if key in (*IMPACT_COLUMNS, FLAG_COLUMN) and key not in found:
            found[key] = j
    return found


def _is_impact_header(table):
    """True for dashpot's impact table: headers ``time`` and ``time_uncertainty``, no units."""
    return {"time", "time_uncertainty"} <= set(_impact_columns(table))


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
        ≥ 0; times that do not increase within a run.

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
    if "run" in columns:
        run = values["run"]
        bad = ~np.isfinite(run) | (run < 0) | (run != np.round(run))
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            refuse("run", k, f"run '{table.cells[k, columns['run']]}' is not a whole number "
                             f"≥ 0")
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
                         flag=flag)


# ---------------------------------------------------------------------------------------------
# Runs side by side (PASCO, Vernier)
# ---------------------------------------------------------------------------------------------

@dataclass
class _Run:
    label: str
    rows: np.ndarray  # data rows (0-based) of the run's samples
    time: np.ndarray  # s
    columns: dict  # quantity -> (values in SI, resolution in SI)


def _column_resolution(values, resolution):
    """Resolution of a column of readings from the data's spacing, in the values' unit.

    The smallest non-zero change between consecutive readings, never finer than the finest
    digit written in the column. One cell's text (a zeroed start written ``0.0``, a number an
    exporter shortened) cannot set it: a column's digits show its resolution only where they
    are most numerous, and a workbook's cells hold floats without written digits.
    """
    finite = np.isfinite(values)
    steps = np.abs(np.diff(values[finite]))
    steps = steps[steps > 0]
    written = resolution[finite & np.isfinite(resolution)]
    finest = float(np.min(written)) if written.size else 0.0
    if steps.size == 0:
        return finest
    return max(float(np.min(steps)), finest)


def _span(present):
    """First and last index (inclusive) where `present` is True, or None if it never is."""
    where = np.flatnonzero(present)
    return (int(where[0]), int(where[-1])) if where.size else None


def _runs(path, table, quantities):
    """Group columns into runs and read each run's time and `quantities` in SI units.

    `quantities` maps a quantity ('position', 'velocity', 'state') to (names, unit kind), in
    order of preference: the first one a run has is the one its samples are read from, and a
    later one (velocity beside a position) is not used, so its blanks cannot reject the file.
    Blanks at the start or end of a column are normal (a derivative starts a sample or two
    after the position; shorter runs are padded at the end); a blank between values of the
    column read, or of the time beside them, is an error naming the row.
    """
    where = table.where
    columns = table.columns
    labels = list(dict.fromkeys(c.run for c in columns))  # order of first appearance
    shared_time = [j for j, c in enumerate(columns) if c.run == "" and c.name in _TIME_NAMES]
    runs = []
    for label in labels:  # loop over runs
        members = [j for j, c in enumerate(columns) if c.run == label]
        time_index = next((j for j in members if columns[j].name in _TIME_NAMES), None)
        if time_index is None:
            if len(shared_time) != 1:
                continue
            time_index = shared_time[0]
        found = {}
        for quantity, (names, kind) in quantities.items():
            candidates = [j for j in members if (columns[j].name in names if names else
                                                 _is_state(columns[j]))]
            if candidates:
                found[quantity] = candidates
        if not found:
            continue
        quantity = next(iter(found))
        names, kind = quantities[quantity]
        time, time_res = _numbers(path, table, time_index, what="time")
        time_factor = _unit_factor(path, where, columns[time_index], table, "time") or 1.0
        read = []
        for j in found[quantity]:  # loop over candidate columns (Tracker: x and y)
            filled = table.cells[:, j] != ""
            if kind is not None:
                values, res = _numbers(path, table, j, what=quantity)
                factor = _unit_factor(path, where, columns[j], table, kind) or 1.0
                filled = np.isfinite(values)
                read.append((j, filled, values * factor, res * factor))
            else:
                read.append((j, filled, None, None))
        if len(read) > 1:
            # Several coordinates (Tracker's x and y): the one the object moves along most.
            spread = [np.nanstd(v) if np.any(np.isfinite(v)) else -1.0 for _, _, v, _ in read]
            read = [read[int(np.argmax(spread))]]
        j, filled, values, res = read[0]
        span = _span(filled)
        if span is None:
            continue
        rows = np.arange(span[0], span[1] + 1)
        gap = ~filled[rows]
        if gap.any():
            k = int(rows[np.flatnonzero(gap)[0]])
            raise InputError(path, f"{where}{columns[j].header} is missing inside the run "
                                   f"(a blank between its values)", row=k + 1)
        _check_times(path, table, time[rows] * time_factor, rows)
        data = {"time_resolution": time_res[rows] * time_factor, "column": columns[j].header}
        if kind is not None:
            quantum = _column_resolution(values[rows], res[rows])
            data[quantity] = (values[rows], np.full(rows.size, quantum))
        runs.append(_Run(label, rows, time[rows] * time_factor, data))
    return runs


# ---------------------------------------------------------------------------------------------
# Motion sensor
# ---------------------------------------------------------------------------------------------

def _mad_sigma(values):
    """Robust σ of Gaussian noise in `values` (median absolute deviation) [4]_."""
    values = values[np.isfinite(values)]
    if values.size == 0:
        return 0.0
    return float(_MAD_TO_SIGMA * np.median(np.abs(values - np.median(values))))


def _runs_of(state):
    """Start, end (inclusive) and value of each run of equal values in an integer array."""
    change = np.flatnonzero(np.diff(state)) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change - 1, [state.size - 1]])
    return starts, ends, state[starts]


def _first_extreme(values, starts, ends, which):
    """Index of the first maximum ('max') or minimum ('min') of `values` in each index run."""
    run_id = np.repeat(np.arange(starts.size), ends - starts + 1)
    reduce = np.maximum if which == "max" else np.minimum
    extreme = reduce.reduceat(values, starts)
    index = np.arange(values.size)
    return np.minimum.reduceat(np.where(values == extreme[run_id], index, values.size), starts)


def _crossing(a, c, b, cov, bumper, var_bumper, incoming):
    """Where a fitted parabola meets the bumper position, with 1σ uncertainties.

    The parabola is s(τ) = c + b·τ + (a/2)·τ² about an edge sample (τ = 0), oriented so s
    grows toward the bumper and a > 0 is the free-motion acceleration toward it [5]_. With
    D = B − c the distance left, the speed there is V = √(b² + 2aD); the crossing is
    τ = 2D/(b + V) for the incoming branch (after the edge) and τ = −2D/(V − b) for the
    outgoing one (before it). Written this way neither form divides by a, which may be small.

    Returns (τ, V, σ_τ, σ_V); `cov` is the (…, 3, 3) covariance of (a, c, b).
    """
    distance = bumper - c
    speed2 = b ** 2 + 2.0 * a * distance
    with np.errstate(invalid="ignore", divide="ignore"):
        speed = np.sqrt(np.where(speed2 >= 0, speed2, np.nan))
        sign = 1.0 if incoming else -1.0
        denominator = sign * b + speed  # b + V incoming, V − b outgoing
        tau = sign * 2.0 * distance / denominator
        # Partial derivatives with respect to (a, c, b) and to the bumper position B.
        dv_dd, dv_db, dv_da = a / speed, b / speed, distance / speed
        dt_dd = sign * (2.0 / denominator - 2.0 * distance * dv_dd / denominator ** 2)
        dt_db = -sign * 2.0 * distance * (sign + dv_db) / denominator ** 2
        dt_da = -sign * 2.0 * distance * dv_da / denominator ** 2
    grad_t = np.stack([dt_da, -dt_dd, dt_db], axis=-1)
    grad_v = np.stack([dv_da, -dv_dd, dv_db], axis=-1)
    var_t = np.einsum("...i,...ij,...j->...", grad_t, cov, grad_t) + dt_dd ** 2 * var_bumper
    var_v = np.einsum("...i,...ij,...j->...", grad_v, cov, grad_v) + dv_dd ** 2 * var_bumper
    return tau, speed, np.sqrt(var_t), np.sqrt(var_v)


def _motion_run(run, bumper_position, notes, legs):
    """Impacts of one run: arrays (time, σ_time, impact speed, rebound speed, σ_speed, flag)."""
    empty = tuple(np.empty(0) for _ in range(5)) + (np.empty(0, dtype=str),)
    time = run.time
    n = time.size
    if n < 12:
        notes.append(f"run '{run.label or 0}': only {n} samples, no impacts looked for")
        return empty
    dt = float(np.median(np.diff(time)))
    if "position" in run.columns:
        x, x_res = run.columns["position"]
        # Velocity by central differences of the position: its noise statistics are then
        # known (σ_v = σ_x/(√2·Δt)), unlike a vendor's smoothed derivative. The third
        # differences of a parabola vanish, so their spread is noise: var(Δ³x) = 20σ_x².
        w_raw = np.gradient(x, time)
        sigma_x = max(_mad_sigma(np.diff(x, 3)) / np.sqrt(20.0),
                      float(np.nanmax(x_res)) / np.sqrt(12.0))
        sigma_w = sigma_x / (np.sqrt(2.0) * dt)
        threshold, guard = 4.0 * sigma_w, 1
    else:
        v, v_res = run.columns["velocity"]
        # Velocity only: position up to a constant by integrating it (trapezoid rule). The
        # vendor's smoothing is unknown, so the threshold and guard are more generous.
        x = cumulative_trapezoid(v, time, initial=0.0)
        w_raw = v
        sigma_w = max(_mad_sigma(np.diff(v, 2)) / np.sqrt(6.0),
                      float(np.nanmax(v_res)) / np.sqrt(12.0))
        sigma_x = sigma_w * dt
        threshold, guard = 5.0 * sigma_w, 2
        notes.append(f"run '{run.label or 0}': no position column; position integrated from the "
                     f"velocity (its unknown smoothing leaves the uncertainties about 2x "
                     f"optimistic)")
    # Orientation: in free motion the cart accelerates toward the bumper, and free motion is
    # most of the moving samples, so the median change of velocity there points to the bumper.
    moving = np.abs(w_raw) > threshold
    steps = np.diff(w_raw)[moving[:-1] & moving[1:]]
    if steps.size < 3:
        notes.append(f"run '{run.label or 0}': the cart hardly moves; no impacts")
        return empty
    orientation = 1.0 if np.median(steps) >= 0 else -1.0
    w, s = orientation * w_raw, orientation * x  # both grow toward the bumper
    # Toward (+1), away (−1) or neither (0, within noise: apex, rest) at each sample.
    state = np.where(w > threshold, 1, np.where(w < -threshold, -1, 0)).astype(np.int8)
    starts, ends, values = _runs_of(state)
    lengths = ends - starts + 1
    count = starts.size
    padded_values = np.concatenate([values, [0, 0]])
    padded_lengths = np.concatenate([lengths, [0, 0]])
    i = np.arange(count)
    # A reversal at the bumper: moving toward it, then away, with at most a couple of samples
    # in between (the contact smears the velocity). Every reversal ends a flight; an impact is
    # reported only where >= 2 samples move toward and >= 2 away: rest noise cannot fake that,
    # as it would need four samples beyond 4σ with the right signs in a row. Reversals at the
    # top of the incline go the other way (away, then toward) and are flights' apexes.
    max_gap = 2 + guard
    direct = padded_values[i + 1] == -1
    bridged = ((padded_values[i + 1] == 0) & (padded_lengths[i + 1] <= max_gap)
               & (padded_values[i + 2] == -1))
    reversal = (padded_values[i] == 1) & (direct | bridged)
    away_of = np.where(direct, i + 1, i + 2)
    resolved = reversal & (padded_lengths[i] >= 2) & (padded_lengths[np.minimum(away_of, count + 1)]
                                                      >= 2)
    if not resolved.any():
        notes.append(f"run '{run.label or 0}': no velocity reversal at the bumper")
        return empty
    # Reversals up to the last resolved one cut the record into flights, and so do later ones
    # while the cart still leaves the bumper by more than the noise (short flights of the
    # last bounces: their velocity exceeds the threshold on a sample or two only). Once the
    # position stays within 4σ of where the record ends, the cart rests and a reversal there
    # would be noise.
    if "position" in run.columns:
        moved_at_all = np.flatnonzero(np.abs(s - np.median(s[-min(20, n):])) > 4.0 * sigma_x)
        resting_from = moved_at_all[-1] + 1 if moved_at_all.size else 0
    else:
        resting_from = 0
    keep = reversal & ((i <= i[resolved][-1]) | (ends[np.minimum(i + 1, count - 1)]
                                                 < resting_from))
    toward_runs, away_runs = i[keep], away_of[keep]
    is_impact = resolved[keep]
    real_reversal = np.ones(is_impact.size, dtype=bool)  # False: a contact put in below
    impacts = toward_runs.size
    # The contact starts where the velocity toward the bumper peaks (free motion speeds it up,
    # the bumper slows it) and ends where the velocity away from it peaks: samples between,
    # plus a guard for the derivative's reach, are not free motion.
    peaks = _first_extreme(w, starts, ends, "max")[toward_runs]
    troughs = _first_extreme(w, starts, ends, "min")[away_runs]
    later_toward = np.flatnonzero((values == 1) & (i > away_runs[-1]))
    if later_toward.size:  # the flight after the last resolved impact ends at the next contact
        last_end = _first_extreme(w, starts, ends, "max")[later_toward[0]] - guard - 1
    else:
        last_end = ends[away_runs[-1]]
    # Free flight is symmetric about its apex: it ends no later than the apex mirrored about
    # the contact end. Where that falls well before the next reversal, a contact showed no
    # clear reversal in between (a slow one, its speed within the noise): an unreported
    # contact is put there, so that the next impact gets its own incoming flight.
    rising = np.flatnonzero(w >= 0)

    def mirror(troughs):
        apex = (rising[np.minimum(np.searchsorted(rising, troughs), rising.size - 1)]
                if rising.size else np.full(troughs.size, n - 1))
        apex = np.where(apex >= troughs, apex, n - 1)
        return 2 * apex - troughs - guard - 1

    mirrored = mirror(troughs)
    # The apex is where the noisy velocity first turns toward the bumper: uncertain by about
    # σ_v/(g·Δt) samples (g·Δt, the velocity change per sample, is the median step in motion).
    apex_noise = sigma_w / max(abs(float(np.median(steps))), 1e-12)
    missed = np.flatnonzero((peaks[1:] - guard - 1) - mirrored[:-1] > 3.0 + 4.0 * apex_noise)
    if missed.size:
        unseen_peaks = mirrored[missed] + guard + 1
        peaks = np.insert(peaks, missed + 1, unseen_peaks)
        troughs = np.insert(troughs, missed + 1, unseen_peaks + 2)
        is_impact = np.insert(is_impact, missed + 1, False)
        real_reversal = np.insert(real_reversal, missed + 1, False)
        impacts = peaks.size
        mirrored = mirror(troughs)
    # The release: the first sample moving toward the bumper beyond the noise may still be
    # the held cart's (its central difference reaches a sample after the release).
    segment_lo = np.concatenate([[starts[toward_runs[0]] + guard], troughs + guard + 1])
    segment_hi = np.concatenate([peaks - guard - 1, [last_end]])
    segment_hi[1:] = np.minimum(segment_hi[1:], mirrored)
    index = np.arange(n)
    segment = np.searchsorted(segment_lo, index, side="right") - 1
    inside = (segment >= 0) & (index <= segment_hi[np.clip(segment, 0, None)])
    segment = np.where(inside, segment, -1)

    label = run.label or 0

    def fit(labels, apex=None):
        """Least squares over the samples with a flight label (>= 2 per flight).

        Each flight is s(τ) = c + b·τ + a·τ²/2 about a reference time; `apex` (s, per flight)
        makes the reference the flight's apex and gives the leg before it (away from the
        bumper) and the leg after it (toward it) accelerations of their own, common to all
        flights (rolling friction adds to the incline's pull going up and subtracts from it
        going down [5]_); position and velocity stay continuous at the apex. Without `apex`,
        one acceleration for both legs. One pass of 5σ outlier rejection. Returns a dict of
        the fit; ``theta`` is always (a_away, a_toward, c_0, b_0, c_1, b_1, ...).
        """
        def solve(selected):
            counts = np.bincount(labels[selected], minlength=impacts + 1)
            usable = counts >= 2
            rows = np.flatnonzero(selected & usable[np.clip(labels, 0, None)])
            used = np.flatnonzero(usable)
            column = np.full(impacts + 1, -1)
            column[used] = np.arange(used.size)
            seg = labels[rows]
            reference = (np.bincount(seg, weights=time[rows], minlength=impacts + 1)
                         / np.maximum(counts, 1))
            if apex is not None:
                reference = np.where(np.isfinite(apex), apex, reference)
            tau = time[rows] - reference[seg]
            toward = tau >= 0
            # Two accelerations only where both legs are sampled well enough to tell them apart.
            split = apex is not None and min(int(toward.sum()), int((~toward).sum())) >= 3
            n_acc = 2 if split else 1
            design = np.zeros((rows.size, n_acc + 2 * used.size))
            if split:
                design[:, 0] = np.where(toward, 0.0, 0.5 * tau ** 2)
                design[:, 1] = np.where(toward, 0.5 * tau ** 2, 0.0)
            else:
                design[:, 0] = 0.5 * tau ** 2
            design[np.arange(rows.size), n_acc + 2 * column[seg]] = 1.0
            design[np.arange(rows.size), n_acc + 1 + 2 * column[seg]] = tau
            # Full parameters (a_away, a_toward, c, b, ...) from the fitted ones.
            expand = np.zeros((2 + 2 * used.size, design.shape[1]))
            expand[0, 0] = 1.0
            expand[1, 1 if split else 0] = 1.0
            expand[2:, n_acc:] = np.eye(2 * used.size)
            fitted = (np.linalg.lstsq(design, s[rows], rcond=None)[0] if rows.size
                      else np.zeros(design.shape[1]))
            return dict(rows=rows, usable=usable, column=column, reference=reference,
                        design=design, expand=expand, split=split, theta=expand @ fitted,
                        residual=s[rows] - design @ fitted)

        result = solve(labels >= 0)
        if result["rows"].size == 0:
            return None
        # A sample 5σ off its flight's parabola is not free motion. Near a flight's end such a
        # sample means the flight ran into a contact that showed no clear reversal: the samples
        # after it belong to the next flight, so the flight is cut there (likewise at its
        # start).
        outliers = np.zeros(n, dtype=bool)
        outliers[result["rows"]] = np.abs(result["residual"]) > 5.0 * sigma_x
        if outliers.any():
            flight = np.clip(labels, 0, None)
            middle = (np.bincount(labels[labels >= 0], weights=index[labels >= 0],
                                  minlength=impacts + 1)
                      / np.maximum(np.bincount(labels[labels >= 0], minlength=impacts + 1), 1))
            late = outliers & (index > middle[flight])
            early = outliers & (index < middle[flight])
            cut_hi = np.full(impacts + 1, n)
            cut_lo = np.full(impacts + 1, -1)
            np.minimum.at(cut_hi, flight[late], index[late])
            np.maximum.at(cut_lo, flight[early], index[early])
            selected = ((labels >= 0) & ~outliers & (index < cut_hi[flight])
                        & (index > cut_lo[flight]))
            outliers = (labels >= 0) & ~selected
            result = solve(selected)
        rows, design, residual = result["rows"], result["design"], result["residual"]
        dof = rows.size - design.shape[1]
        result["variance"] = float(residual @ residual / dof) if dof >= 3 else sigma_x ** 2
        # Correlated noise (a vendor's smoothing, an integrated velocity) makes s²(AᵀA)⁻¹ too
        # small: scale it by the long-run variance ratio 1 + 2Σρ_k of the residuals, lags 1-3
        # within a flight [6]_ (≈ 1 for white noise).
        seg = labels[rows]
        ratio = 1.0
        for lag in (1, 2, 3):  # loop over three lags
            same = (seg[lag:] == seg[:-lag]) & (rows[lag:] - rows[:-lag] == lag)
            if same.sum() > 10 and residual @ residual > 0:
                ratio += 2.0 * float(np.mean(residual[lag:][same] * residual[:-lag][same])
                                     / np.mean(residual ** 2))
        expand = result["expand"]
        result["covariance"] = (max(ratio, 1.0) * result["variance"]
                                * expand @ np.linalg.pinv(design.T @ design) @ expand.T)
        result["outliers"] = int(outliers.sum())
        result["samples"] = np.bincount(seg, minlength=impacts + 1)
        result["first"] = np.full(impacts + 1, np.nan)
        result["last"] = np.full(impacts + 1, np.nan)
        np.fmin.at(result["first"], seg, time[rows])
        np.fmax.at(result["last"], seg, time[rows])
        return result

    def apexes(result):
        """Time (s) of each flight's apex, where its fitted velocity is zero (NaN if unfitted).

        The velocity b + a·τ about the reference is zero before it on the leg away from the
        bumper (b > 0) and after it on the leg toward it (b < 0).
        """
        theta, usable = result["theta"], result["usable"]
        col = np.clip(result["column"], 0, None)
        b = theta[3 + 2 * col]
        with np.errstate(divide="ignore", invalid="ignore"):
            shift = np.where(b > 0, -b / theta[0], -b / theta[1])
        return np.where(usable, result["reference"] + shift, np.nan)

    def edge_parabola(result, segments, edge_times):
        """(ok, a, c, b, cov) of each segment's leg at an edge time, cov of (a, c, b).

        The leg is the one the edge time falls on: toward the bumper after the apex (the
        reference of a two-leg fit), away from it before.
        """
        usable, column, theta = result["usable"], result["column"], result["theta"]
        ok = usable[segments]
        col = np.clip(column[segments], 0, None)
        delta = edge_times - result["reference"][segments]
        leg = np.where(delta >= 0, 1, 0)
        a = theta[leg]
        c0, b0 = theta[2 + 2 * col], theta[3 + 2 * col]
        c = c0 + b0 * delta + 0.5 * a * delta ** 2
        b = b0 + a * delta
        blocks = np.stack([leg, 2 + 2 * col, 3 + 2 * col], axis=-1)
        cov = result["covariance"][blocks[:, :, None], blocks[:, None, :]]
        jac = np.zeros((segments.size, 3, 3))
        jac[:, 0, 0] = 1.0
        jac[:, 1, 0], jac[:, 1, 1], jac[:, 1, 2] = 0.5 * delta ** 2, 1.0, delta
        jac[:, 2, 0], jac[:, 2, 2] = delta, 1.0
        return ok, a, c, b, jac @ cov @ np.swapaxes(jac, 1, 2)

    def crossings(result, bumper, var_bumper):
        """Contact start (incoming parabola reaches the bumper) and end (outgoing leaves it)."""
        k = np.arange(impacts)
        te_in, te_out = result["last"][k], result["first"][k + 1]
        in_ok, a_in, c_in, b_in, cov_in = edge_parabola(result, k, te_in)
        out_ok, a_out, c_out, b_out, cov_out = edge_parabola(result, k + 1, te_out)
        tau_in, v_in, sd_t_in, sd_v_in = _crossing(a_in, c_in, b_in, cov_in, bumper, var_bumper,
                                                   incoming=True)
        tau_out, v_out, sd_t_out, sd_v_out = _crossing(a_out, c_out, b_out, cov_out, bumper,
                                                       var_bumper, incoming=False)
        return dict(t_in=np.where(in_ok, te_in + tau_in, np.nan),
                    t_out=np.where(out_ok, te_out + tau_out, np.nan),
                    v_in=np.where(in_ok, v_in, np.nan), v_out=np.where(out_ok, v_out, np.nan),
                    sd_t_in=sd_t_in, sd_t_out=sd_t_out, sd_v_in=np.where(in_ok, sd_v_in, np.nan),
                    sd_v_out=np.where(out_ok, sd_v_out, np.nan))

    def meeting_bumper(result):
        """Median position where each impact's incoming and outgoing parabolas meet."""
        k = np.arange(impacts)
        te_in, te_out = result["last"][k], result["first"][k + 1]
        in_ok, a_in, c_in, b_in, _ = edge_parabola(result, k, te_in)
        out_ok, a_out, c_out, b_out, _ = edge_parabola(result, k + 1, te_out)
        # s_in(u) − s_out(u) = A·u² + B·u + C with u the time after te_in: the root between the
        # two edges (the one nearer their middle); linear when the legs share the acceleration.
        gap = te_out - te_in
        quadratic = 0.5 * (a_in - a_out)
        linear = b_in - b_out + a_out * gap
        const = c_in - c_out + b_out * gap - 0.5 * a_out * gap ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            root = np.sqrt(linear ** 2 - 4.0 * quadratic * const)
            candidates = np.stack([(-linear + root) / (2.0 * quadratic),
                                   (-linear - root) / (2.0 * quadratic)])
            nearest = candidates[np.argmin(np.abs(np.nan_to_num(candidates - 0.5 * gap,
                                                                nan=np.inf)), axis=0),
                                 np.arange(impacts)]
            meet = np.where(np.abs(quadratic * gap) < 1e-9 * np.abs(linear) + 1e-300,
                            -const / linear, nearest)
        meets = (c_in + b_in * meet + 0.5 * a_in * meet ** 2)[
            in_ok & out_ok & np.isfinite(meet) & is_impact]
        if meets.size == 0:
            return None, None
        spread = float(np.std(meets)) ** 2 / meets.size if meets.size > 1 else result["variance"]
        return float(np.median(meets)), spread

    def fit_legs(labels):
        """The flights' fit with one acceleration, then with each leg's own about the apex
        (twice, the second about the apexes the first found)."""
        common = fit(labels)
        if common is None:
            return None
        result = common
        for _ in range(2):  # the apex moves by a fraction of a sample at most
            legs = fit(labels, apex=apexes(result))
            if legs is None or not legs["split"]:
                return result
            result = legs
        return result

    first = fit_legs(segment)
    if first is None:
        notes.append(f"run '{label}': no free motion between the impacts to fit")
        return empty
    # Bumper position: given, or where the cart rests after the last impact, or (no rest)
    # where the incoming and outgoing parabolas of each impact meet.
    source = "meet"
    if bumper_position is not None:
        bumper, var_bumper, source = orientation * float(bumper_position), 0.0, "given"
        notes.append(f"run '{label}': bumper position given: {bumper_position:g} m")
    else:
        # The rest is the final stretch in which the position stays within 4σ of where the
        # record ends: small bounces before it leave the bumper by more than the noise even
        # when their speeds are too small to register. Only its second half is used, as the
        # smallest bounces (within the noise) come first. A position integrated from the
        # velocity drifts; there the stretch is the final one with no velocity beyond the
        # threshold, single-sample excursions (the one-sided derivative at the end doubles
        # the noise) not counting as motion.
        if "position" in run.columns:
            settled = np.median(s[-min(20, n):])
            moved = np.flatnonzero(np.abs(s - settled) > 4.0 * sigma_x)
            rest_start = moved[-1] + 1 if moved.size else 0
        else:
            calm = np.where(np.repeat(lengths == 1, lengths), 0, state)
            calm_starts, _, calm_values = _runs_of(calm)
            rest_start = calm_starts[-1] if calm_values[-1] == 0 else n
        rest_start = max(rest_start, last_end + guard + 1)
        tail = index >= rest_start + (n - rest_start) // 2
        if tail.sum() >= 5 and np.median(s[tail]) > np.max(s[first["rows"]]) - 3.0 * sigma_x:
            bumper = float(np.median(s[tail]))
            var_bumper = (_MEDIAN_EFFICIENCY * sigma_x) ** 2 / tail.sum()
            source = "rest"
            notes.append(f"run '{label}': bumper position {orientation * bumper:.5g} m from the "
                         f"resting tail ({tail.sum()} samples; a soft bumper's static "
                         f"compression under the cart's weight is included)")
        else:
            bumper, var_bumper = meeting_bumper(first)
            if bumper is None:
                notes.append(f"run '{label}': no resting tail and no impact with free motion on "
                             f"both sides: bumper position unknown")
                return empty
    # Second pass. The first cut the flights where the noisy velocity peaked, which favours
    # samples whose noise made it peak: a small selection bias at the flight ends. Now each
    # flight runs from the fitted end of the previous contact (or the fitted release, the
    # descent's vertex) to the fitted start of the next contact, or at the latest to the
    # fitted apex mirrored about the contact end (scaled by √(a_away/a_toward): the leg
    # toward the bumper lasts longer when friction slows it).
    cross = crossings(first, bumper, var_bumper)
    vertex = apexes(first)
    with np.errstate(divide="ignore", invalid="ignore"):
        legs_ratio = np.sqrt(first["theta"][0] / first["theta"][1])
    legs_ratio = legs_ratio if np.isfinite(legs_ratio) and legs_ratio > 0 else 1.0
    lo_time = np.concatenate([[vertex[0]], cross["t_out"]])
    hi_time = np.concatenate([cross["t_in"], [np.inf]])
    mirrored_time = np.concatenate([[np.inf], vertex[1:] + legs_ratio * (vertex[1:]
                                                                          - cross["t_out"])])
    hi_time = np.fmin(hi_time, mirrored_time)
    # No cut moves past the samples where the velocity turned (the contact lies between
    # them); where a fit is missing, the cut is there, or the first pass's mirrored apex. A
    # flight of a few samples then keeps the samples next to its contacts, which the first
    # pass's guard left out: with a position column, a sample more than 3σ short of the
    # bumper is off it, so those count as free flight.
    # Without a position column (integrated from a vendor's smoothed velocity) the samples
    # next to a contact are smeared: no cut moves more than a sample past the first pass's.
    reach = (guard + 1) * dt if "position" in run.columns else dt
    turn_lo = np.fmax(time[np.clip(np.concatenate([[segment_lo[0]], troughs]), 0, n - 1)],
                      time[np.clip(segment_lo, 0, n - 1)] - reach) - 1e-9
    turn_hi = np.fmin(time[np.clip(np.concatenate([peaks, [segment_hi[-1]]]), 0, n - 1)],
                      time[np.clip(segment_hi, 0, n - 1)] + reach) + 1e-9
    if "position" in run.columns:
        # The last flight runs until the cart is back at rest (its apex mirrored, when fitted):
        # its return may be too slow to pass the velocity threshold.
        turn_hi[-1] = max(turn_hi[-1], time[np.clip(resting_from - 1, 0, n - 1)] + 1e-9)
    lo_time = np.where(np.isfinite(lo_time), np.fmax(lo_time, turn_lo), turn_lo)
    hi_time = np.where(np.isfinite(hi_time), np.fmin(hi_time, turn_hi), turn_hi)
    lo_time = np.maximum.accumulate(lo_time)
    refined = np.searchsorted(lo_time, time, side="right") - 1
    keep = (refined >= 0) & (time > lo_time[np.clip(refined, 0, None)]) \
        & (time < hi_time[np.clip(refined, 0, None)])
    if "position" in run.columns:
        keep &= s < bumper - 3.0 * np.sqrt(sigma_x ** 2 + var_bumper)
        # One flight is one excursion from the bumper: where a cut spans several (bounces too
        # small to show a reversal), only its longest run of off-bumper samples is kept.
        same = np.concatenate([[False], keep[:-1] & keep[1:] & (refined[:-1] == refined[1:])])
        excursion = np.where(keep, np.cumsum(keep & ~same), 0)
        if excursion.max() > 0:
            length = np.bincount(excursion)[1:]
            owner = refined[np.flatnonzero(keep & ~same)]
            order = np.lexsort((-length, owner))
            longest = order[np.concatenate([[True], owner[order][1:] != owner[order][:-1]])]
            keep &= np.isin(excursion, longest + 1)
    second = fit_legs(np.where(keep, refined, -1))
    result = second if second is not None else first
    if source == "meet":
        bumper, var_bumper = meeting_bumper(result)
        notes.append(f"run '{label}': no resting tail; bumper position "
                     f"{orientation * bumper:.5g} m where the fitted trajectories meet (biased "
                     f"past the bumper by a long contact)")
    cross = crossings(result, bumper, var_bumper)
    resolved_count = int(is_impact.sum())
    a_away, a_toward = result["theta"][:2]
    sd_away, sd_toward = np.sqrt(np.diag(result["covariance"])[:2])
    legs.append(dict(label=str(run.label), toward=float(a_toward), toward_sd=float(sd_toward),
                     away=float(a_away), away_sd=float(sd_away), separate=bool(result["split"])))
    accelerations = (f"{a_toward:.4g} ± {sd_toward:.2g} m/s² on the legs toward the bumper and "
                     f"{a_away:.4g} ± {sd_away:.2g} m/s² on the legs away from it (the incline's "
                     f"g·sin θ less and plus rolling friction)" if result["split"] else
                     f"{a_toward:.4g} ± {sd_toward:.2g} m/s² on both legs (too few samples on "
                     f"one leg to tell them apart)")
    notes.append(f"run '{label}': free-motion acceleration toward the bumper {accelerations}, "
                 f"position noise {np.sqrt(result['variance']) * 1e3:.3g} mm, "
                 f"{resolved_count} resolved reversal(s) at the bumper "
                 f"({impacts - resolved_count} other contact(s) with fewer than two samples "
                 f"beyond the noise on a side), {result['outliers']} outlying sample(s) left out")
    # Every reversal is reported; one whose incoming or outgoing flight has fewer than two
    # free samples in the fit is flagged, timed by what it has: the incoming parabola, else the
    # outgoing one (the contact end: late by the contact), else the midpoint of the samples
    # where the velocity turned (1σ: their spacing/√12).
    k = np.arange(impacts)
    samples_in, samples_out = result["samples"][k], result["samples"][k + 1]
    short = (samples_in < 2) | (samples_out < 2)
    has_in, has_out = np.isfinite(cross["t_in"]), np.isfinite(cross["t_out"])
    turn_lo, turn_hi = time[np.clip(peaks, 0, n - 1)], time[np.clip(troughs, 0, n - 1)]
    impact_time = np.where(has_in, cross["t_in"], np.where(has_out, cross["t_out"],
                                                            0.5 * (turn_lo + turn_hi)))
    time_sd = np.where(has_in, cross["sd_t_in"], np.where(
        has_out, np.hypot(cross["sd_t_out"], dt / np.sqrt(12.0)),
        np.maximum(turn_hi - turn_lo, dt) / np.sqrt(12.0)))
    # A fitted flight whose parabola never reaches the bumper position cannot time its
    # contact (a bumper position given where the cart never is): such contacts are dropped.
    timed = has_in | ((samples_in < 2) & (has_out | (samples_out < 2)))
    # The train ends at its last well-sampled reversal (none: no train). Flagged contacts
    # after it are the cart's last, smallest bounces, timed mostly by the noise (a 2 mm error
    # is 20 ms at 0.1 m/s), and would end the train on intervals that are no bounce train.
    good = np.flatnonzero(real_reversal & ~short & timed)
    reported = (k <= (good[-1] if good.size else -1)) & timed
    if np.any(~timed):
        notes.append(f"run '{label}': {int(np.sum(~timed))} contact(s) whose fitted flight "
                     f"never reaches the bumper position dropped")
    if np.any(~reported & timed):
        notes.append(f"run '{label}': {int(np.sum(~reported & timed))} last contact(s) after the "
                     f"last reversal with two free-flight samples on each side left out (the "
                     f"cart's smallest bounces, timed by the noise)")
    flags = np.where(~real_reversal, "inferred", np.where(short, "few_samples", "ok"))[reported]
    few = int(np.sum(short & real_reversal & reported))
    if np.any(~real_reversal & reported):
        notes.append(f"run '{label}': {int(np.sum(~real_reversal & reported))} contact(s) "
                     f"without a visible reversal (a flight ending well before the next "
                     f"reversal, its apex mirrored) flagged 'inferred'")
    if few:
        notes.append(f"run '{label}': {few} reversal(s) with fewer than two free-flight samples "
                     f"on a side flagged 'few_samples' ({int(np.sum(~has_in & reported))} timed "
                     f"by the outgoing flight or the turning samples, the incoming flight being "
                     f"too short)")
    speed_sd = np.fmax(cross["sd_v_in"], cross["sd_v_out"])
    speed_sd = np.where(np.isfinite(speed_sd), speed_sd, np.fmin(cross["sd_v_in"],
                                                                 cross["sd_v_out"]))
    found = (impact_time[reported], time_sd[reported], cross["v_in"][reported],
             cross["v_out"][reported], speed_sd[reported], flags)
    if "position" in run.columns and reported.any() and result["split"]:
        # The last bounces: too slow for a velocity reversal beyond the noise, but each still
        # an excursion from the bumper of two samples or more.
        tail = _tail_excursions(time, s, bumper, var_bumper, sigma_x, result,
                                float(impact_time[reported][-1]))
        if tail[0].size:
            notes.append(f"run '{label}': {tail[0].size} later contact(s) between excursions "
                         f"from the bumper of two or more samples, too slow for a velocity "
                         f"reversal beyond the noise, timed by parabolas with the fitted leg "
                         f"accelerations")
            found = tuple(np.concatenate([a, b]) for a, b in zip(found, tail))
    # Past the last resolved reversal the bounces shrink into the noise: the train ends where
    # an impact's timing noise exceeds a quarter of the change between successive intervals,
    # (1 − r)·interval/4 with r the median interval ratio so far, beyond which intervals
    # would no longer shrink bounce by bounce (a ratio above 1 would be a 3σ event before).
    times, sigmas = found[0], found[1]
    resolved_times = impact_time[reported & real_reversal & is_impact]
    trailing = times > (resolved_times[-1] if resolved_times.size else np.inf)
    if times.size >= 4 and trailing.any():
        intervals = np.diff(times)
        ratio = float(np.median(intervals[1:][~trailing[2:]] / intervals[:-1][~trailing[2:]])) \
            if np.any(~trailing[2:]) else np.nan
        if np.isfinite(ratio) and ratio < 1.0:
            noisy = trailing[1:] & (sigmas[1:] > (1.0 - ratio) * intervals / 4.0)
            if noisy.any():
                cut = int(np.flatnonzero(noisy)[0]) + 1
                notes.append(f"run '{label}': {times.size - cut} last contact(s) left out: their "
                             f"timing noise exceeds a quarter of the change between successive "
                             f"intervals (median interval ratio {ratio:.3f})")
                found = tuple(a[:cut] for a in found)
    return found


def _tail_excursions(time, s, bumper, var_bumper, sigma_x, fitted, after):
    """Contacts after time `after` found as excursions of the position from the bumper.

    An excursion is a run of two or more consecutive samples more than 4σ short of the bumper
    (a resting cart's noise makes one sample in 30 000 do that, two in a row almost never).
    The first excursion after `after` is the flight that follows the last contact found; each
    later one follows a contact of its own. Each excursion is fitted with its own position and
    velocity and the run's leg accelerations (fixed), about its apex (found by iterating);
    a contact is timed where the parabola before it reaches the bumper, with speeds from
    both parabolas, as in read_motion_sensor. Excursions stop at the first of fewer than two
    samples. A contact whose neighbouring samples both stay off the bumper joins two flights
    into one excursion; one that no parabola fits (a residual beyond 5σ) is split at its
    sample nearest the bumper.

    Returns arrays (time, σ_time, impact speed, rebound speed, σ_speed, flag).
    """
    empty = tuple(np.empty(0) for _ in range(5)) + (np.empty(0, dtype=object),)
    margin = 4.0 * np.sqrt(sigma_x ** 2 + var_bumper)
    off = (s < bumper - margin) & (time > after)
    starts, ends, values = _runs_of(off.astype(np.int8))
    starts, ends = starts[values == 1], ends[values == 1]
    a_away, a_toward = fitted["theta"][:2]

    def fit(starts, ends):
        """Each excursion's c, b (about its apex), their covariance and its worst residual."""
        marker = np.zeros(time.size + 1, dtype=int)
        np.add.at(marker, starts, 1)
        np.add.at(marker, ends + 1, -1)
        rows = np.flatnonzero(np.cumsum(marker)[:-1] > 0)
        member = np.searchsorted(starts, rows, side="right") - 1
        n_k = np.bincount(member).astype(float)

        def solve(apex):
            """Per excursion s − a_leg·τ²/2 = c + b·τ by least squares (closed form)."""
            tau = time[rows] - apex[member]
            y = s[rows] - 0.5 * np.where(tau >= 0, a_toward, a_away) * tau ** 2
            st, stt = np.bincount(member, tau), np.bincount(member, tau ** 2)
            sy, sty = np.bincount(member, y), np.bincount(member, tau * y)
            det = n_k * stt - st ** 2
            c, b = (stt * sy - st * sty) / det, (n_k * sty - st * sy) / det
            # Covariance of (c, b) for white noise of σ_x.
            return (c, b, sigma_x ** 2 * stt / det, sigma_x ** 2 * n_k / det,
                    -sigma_x ** 2 * st / det, y - c[member] - b[member] * tau)

        apex = np.bincount(member, weights=time[rows]) / n_k
        for _ in range(3):  # the apex moves by a fraction of a sample after the first pass
            c, b, *_ = solve(apex)
            apex = apex + np.where(b > 0, -b / a_away, -b / a_toward)
        *solution, residual = solve(apex)
        worst = np.zeros(starts.size)
        np.maximum.at(worst, member, np.abs(residual))
        return apex, solution, worst

    for _ in range(4):  # split excursions that hold two flights (below)
        long_enough = ends - starts + 1 >= 2
        if not long_enough.any():
            return empty
        # Up to the first excursion too short to fit: later ones cannot be told from noise.
        stop = np.flatnonzero(~long_enough)
        starts, ends = starts[: stop[0] if stop.size else None], ends[: stop[0] if stop.size
                                                                       else None]
        if starts.size < 2:
            return empty
        apex, (c, b, var_c, var_b, cov_cb), worst = fit(starts, ends)
        # A contact whose neighbouring samples both stay 4σ off the bumper joins two flights
        # into one excursion, which no parabola fits: split it at the sample nearest the
        # bumper (the contact is next to it), leaving that sample out.
        joined = np.flatnonzero((worst > 5.0 * sigma_x) & (ends - starts >= 4))
        if joined.size == 0:
            break
        index = np.arange(time.size)
        inside = [(index > starts[k]) & (index < ends[k]) for k in joined]  # a few at most
        nearest = np.array([int(np.argmax(np.where(m, s, -np.inf))) for m in inside])
        starts = np.sort(np.concatenate([starts, nearest + 1]))
        ends = np.sort(np.concatenate([ends, nearest - 1]))
    count = starts.size
    cov_a = np.diag(fitted["covariance"])[:2]

    def edge(k, times, toward):
        """(a, c, b, cov of (a, c, b)) of excursion k's leg at the edge times."""
        delta = times - apex[k]
        a = a_toward if toward else a_away
        ce = c[k] + b[k] * delta + 0.5 * a * delta ** 2
        be = b[k] + a * delta
        jac = np.zeros((k.size, 3, 3))
        jac[:, 0, 0] = 1.0
        jac[:, 1, 0], jac[:, 1, 1], jac[:, 1, 2] = 0.5 * delta ** 2, 1.0, delta
        jac[:, 2, 0], jac[:, 2, 2] = delta, 1.0
        cov = np.zeros((k.size, 3, 3))
        cov[:, 0, 0] = cov_a[1] if toward else cov_a[0]
        cov[:, 1, 1], cov[:, 2, 2] = var_c[k], var_b[k]
        cov[:, 1, 2] = cov[:, 2, 1] = cov_cb[k]
        return a, ce, be, jac @ cov @ np.swapaxes(jac, 1, 2)

    k_in = np.arange(count - 1)
    a_in, c_in, b_in, cov_in = edge(k_in, time[ends[:-1]], toward=True)
    a_out, c_out, b_out, cov_out = edge(k_in + 1, time[starts[1:]], toward=False)
    tau_in, v_in, sd_t, sd_v_in = _crossing(a_in, c_in, b_in, cov_in, bumper, var_bumper,
                                            incoming=True)
    _, v_out, _, sd_v_out = _crossing(a_out, c_out, b_out, cov_out, bumper, var_bumper,
                                      incoming=False)
    impact = time[ends[:-1]] + tau_in
    ok = np.isfinite(impact) & (impact < time[starts[1:]])
    if not ok.all():  # a parabola that misses the bumper ends the tail there
        last = np.flatnonzero(~ok)[0]
        ok = np.arange(ok.size) < last
    return (impact[ok], sd_t[ok], v_in[ok], v_out[ok], np.fmax(sd_v_in, sd_v_out)[ok],
            np.full(int(ok.sum()), "ok", dtype=object))


def _table_of_kind(path, kind, missing, expected):
    """The first table (sheet) of `path` that reads as `kind`, else a one-line InputError.

    The error says whether the time column or the `missing` data column is absent, for
    `expected` (what such an export looks like), and lists the headers found.
    """
    tables = _load_tables(path)
    table = next((t for t in tables if _kind_of(t) == kind), None)
    if table is None:
        first = tables[0]
        described = ", ".join(c.header for c in first.columns) if first.columns else "no header"
        has_time = first.columns is not None and any(c.name in _TIME_NAMES for c in first.columns)
        problem = missing if has_time else "no time column"
        raise InputError(path, f"{first.where}{problem} for {expected}; found: {described})")
    return table


def read_motion_sensor(path, *, bumper_position=None):
    """Impacts of a cart (or ball) from a motion-sensor or video-tracker position export.

    Parameters
    ----------
    path : str or os.PathLike
        Text table or workbook (.xlsx, .xls, .ods) with, per run, a time column and a position
        and/or velocity column in the export's words: PASCO Capstone ``Time (s) Run #1``,
        ``Position (m) Run #1``, ``Velocity (m/s) Run #1`` (and ``Acceleration`` columns, not
        used); Vernier ``Latest: Time (s)``, ``Run 1: Position (m)``, ``Latest: Velocity
        (m/s)``; Tracker's data export (a first line naming the track, ``t``, ``x``, ``y``
        without units [7]_) or any ``t,y`` table. Several runs side by side. Blanks at a
        column's start or end are normal (a derivative starts a sample or two after the
        position; shorter runs end early); a blank between a column's values is an error. The
        position is read when there is one, and the velocity beside it is then not used. Units
        m/cm/mm, m/s/cm/s/mm/s, s/ms; a position without a unit is read in m.
    bumper_position : float, optional
        Position reading (m, the file's axis) at which the cart touches the bumper, if known
        from the scene, in [-20, 20] m. Otherwise estimated (see Notes).

    Returns
    -------
    pandas.DataFrame
        Impact table of :mod:`dashpot.ingest`: ``time`` (s, the file's clock) of each contact
        start, ``impact_speed`` and ``rebound_speed`` (m/s) and their common 1σ
        ``speed_uncertainty`` (the larger of the two), ``run`` the 0-based order of the run in
        the file (``notes`` map it to the run's label; every run is returned), and ``flag``:
        "ok", "few_samples" (fewer than two free-flight samples on a side of the reversal) or
        "inferred" (a contact whose reversal the samples do not show). ``attrs
        ['accelerations']`` lists per run the free-motion accelerations toward the bumper on
        the legs toward it and away from it (m/s², with 1σ).

    Raises
    ------
    InputError
        Empty file, not a table, no time column or no position/velocity column, bad cells,
        missing/negative/non-increasing times (row named), a value missing between the values
        of the column read, duplicated rows, unknown units; motion without a bounce (no run
        with more than one reversal at the bumper).
    ValueError
        If `bumper_position` is not a finite number in [-20, 20] m.

    Notes
    -----
    A sensor sampling at 20-50 Hz has one or two points near each hit, and those are smeared
    by the contact and by the derivative. They are not used. Instead:

    1. Velocity: central differences of the position (noise σ_v = σ_x/(√2·Δt), with σ_x
       from the third differences, which vanish for free motion [4]_, and no smaller than the
       column's resolution over √12, the resolution being the smallest change between
       consecutive readings); the vendor's own velocity column is used only when there is no
       position (then integrated for one).
    2. Orientation: the median change of velocity while moving points toward the bumper
       (free motion accelerates toward it and is most of the record).
    3. Reversals toward → away at most two (plus guard) samples apart end the flights. One
       with at least two samples beyond ±4σ_v toward the bumper and two away is *resolved*: a
       resting cart's noise cannot produce that (four samples beyond 4σ with the right signs).
       Reversals after the last resolved one count while the position still leaves the bumper
       by more than 4σ_x (the last, short flights); reversals at the top of the incline go
       the other way and are apexes.
    4. Flights, first pass: from the peak velocity away from the bumper after a contact
       (where it ended) to the peak velocity toward it before the next (where it starts),
       less a guard sample (the release's first moving sample too); and no later than the
       apex mirrored about the contact end. Where that mirror falls well short of the next
       reversal, a slow contact showed no clear reversal in between: a contact is put there
       (flagged "inferred"), so the next impact gets its own incoming flight.
    5. Fit: all flight samples by least squares, each flight s(τ) = c + b·τ + a·τ²/2 about its
       apex with one acceleration for the legs away from the bumper and another for the legs
       toward it, common to all flights of the run (on an incline rolling friction adds to the
       pull going up and subtracts from it going down [5]_), position and velocity continuous
       at the apex; first with a single acceleration, then twice about the apexes found. Both
       are reported; with fewer than three samples on either kind of leg, one acceleration.
       Samples 5σ off their parabola, and the rest of the flight beyond them, are left out
       (a contact the reversals missed). Covariance s²(AᵀA)⁻¹, scaled by the residuals'
       long-run variance ratio 1 + 2Σρ_k when the noise is correlated [6]_.
    6. Second pass: each flight is cut again at the *fitted* contact times (and the fitted
       release), never past the samples where the velocity turned, keeping the samples next
       to a contact whose position is more than 3σ short of the bumper (off it), and refitted.
    7. Impact time: where the incoming parabola reaches the bumper position, i.e. the start
       of contact (the convention of :func:`dashpot.bounce_sequence`); the outgoing parabola
       leaves it at the end of contact. The bumper position is the ``bumper_position``
       argument; else the median of the second half of the final stretch in which the
       position stays within 4σ of where the record ends (the cart at rest; it includes a
       soft bumper's static compression g·sin θ/ω0², which makes the times late by that
       distance over the impact speed); else the median point where incoming and outgoing
       parabolas meet (past the bumper by a long contact; noted).
    8. Speeds: each leg's slope at those crossings, √(b² + 2a·D) with D the distance left and
       a that leg's acceleration, so the impact speed of a bounce and the rebound speed of
       the one before are measured separately; 1σ by linear propagation of the fit covariance
       and of the bumper position's uncertainty.

    Every reversal is reported. One whose incoming or outgoing flight has fewer than two free
    samples in the fit is flagged "few_samples" and timed by what it has: the incoming
    parabola, else the outgoing one (the contact end), else the midpoint of the samples where
    the velocity turned (1σ: their spacing/√12); the speed it cannot measure is NaN. The
    train ends at its last reversal with two free samples on each side: flagged contacts
    after it (the smallest bounces, timed by the noise) are left out, noted; so is a contact
    whose fitted flight never reaches the bumper position.

    After the last reversal, bounces too slow to pass the velocity threshold are still found
    as excursions of the position from the bumper: runs of two or more samples more than 4σ
    short of it, each fitted with its own position and velocity and the run's two leg
    accelerations; a contact lies between consecutive excursions. The train ends where an
    impact's timing noise exceeds a quarter of the change between successive intervals,
    (1 − r)·interval/4 with r the median interval ratio: beyond it the intervals no longer
    shrink bounce by bounce within the noise.
    """
    if bumper_position is not None:
        bumper_position = check_range("bumper_position", bumper_position,
                                      *BUMPER_POSITION_RANGE, unit="m", low_inclusive=True)
    table = _table_of_kind(path, "motion_sensor", "no position or velocity column",
                           "a motion sensor (expected e.g. 'Time (s) Run #1' and "
                           "'Position (m) Run #1'")
    _check_duplicates(path, table)
    runs = _runs(path, table, {"position": (_POSITION_NAMES, "length"),
                               "velocity": (_VELOCITY_NAMES, "speed")})
    if not runs:
        raise InputError(path, f"{table.where}no run has both a time column and a position or "
                               f"velocity column")
    vendor = ("Vernier" if any(":" in c.header for c in table.columns) else
              "PASCO" if any(re.search(r"run\s*#", c.header, re.I) for c in table.columns)
              else "Tracker" if "Tracker" in table.variant else "unlabelled")
    notes = [f"file variant: {table.variant}; {vendor} column layout, {len(runs)} run(s): "
             + ", ".join(f"run {k} = '{r.label or '(unlabelled)'}'" for k, r in enumerate(runs))]
    if any(c.unit is None and c.name in _POSITION_NAMES for c in table.columns):
        notes.append("position column without a unit: read in m (Tracker writes its calibrated "
                     "world units, usually m, without naming them)")
    parts, legs = [], []
    for number, run in enumerate(runs):  # loop over runs
        before = len(legs)
        result = _motion_run(run, bumper_position, notes, legs)
        parts.append(result + (np.full(result[0].size, number),))
        if len(legs) > before:
            legs[-1] = dict(run=number, **legs[-1])
        if "column" in run.columns and len([c for c in table.columns if c.run == run.label
                                            and c.name in _POSITION_NAMES]) > 1:
            notes.append(f"run {number}: position read from column '{run.columns['column']}' "
                         f"(the coordinate that moves most)")
    merged = [np.concatenate([p[q] for p in parts]) for q in range(7)]
    counts = [p[0].size for p in parts]
    if max(counts) == 1:
        where = " in every run" if len(runs) > 1 else ""
        raise InputError(path, f"{table.where}motion but no bounce: a single reversal at the "
                               f"bumper{where} (a cart pushed by hand, or caught after one hit); "
                               f"a bounce train needs at least two impacts")
    frame = _impact_frame(path, "motion_sensor", notes, merged[0], merged[1],
                          impact_speed=merged[2], rebound_speed=merged[3],
                          speed_uncertainty=merged[4], flag=merged[5], run=merged[6])
    frame.attrs["accelerations"] = legs
    return frame


# ---------------------------------------------------------------------------------------------
# Photogate
# ---------------------------------------------------------------------------------------------

_FLIGHT_MISMATCH = 0.05  # relative difference of the two passages around a flight, at most
_FLIGHT_G_TOLERANCE = 0.10  # relative scatter of g·sin θ between flights, at most


def _gate_states(path, table, column_index, rows):
    """1 (blocked) / 0 (unblocked) from numbers or the words Blocked/Unblocked."""
    words = pd.Series(table.cells[rows, column_index], dtype=object).astype(str).str.lower()
    state = words.map({"blocked": 1.0, "unblocked": 0.0, "1": 1.0, "0": 0.0})
    numeric = pd.to_numeric(words.str.replace(",", ".", regex=False), errors="coerce")
    state = state.fillna(numeric).to_numpy(dtype=float)
    bad = ~np.isin(state, (0.0, 1.0))
    if bad.any():
        k = int(rows[np.flatnonzero(bad)[0]])
        raise InputError(path, f"{table.where}gate state '{table.cells[k, column_index]}' is "
                               f"neither 1/0 nor Blocked/Unblocked", row=k + 1)
    return state


def _photogate_run(path, table, run, state_index, flag_length, gate_distance, notes):
    """Impacts of one photogate run (see read_photogate)."""
    label = run.label or 0
    time = run.time
    state = _gate_states(path, table, state_index, run.rows)
    change = np.flatnonzero(np.diff(state) != 0) + 1
    empty = tuple(np.empty(0) for _ in range(5))
    # An event log (Vernier photogate timing [3]_) has a row per change of state; a sampled log
    # repeats the state at a fixed rate, and a change happened between two samples.
    event_log = change.size == state.size - 1 and state.size > 1
    resolution = np.nan_to_num(run.columns["time_resolution"], nan=0.0)
    if event_log:
        change_time = time[change]
        change_sd = resolution[change] / np.sqrt(12.0)
    else:
        change_time = 0.5 * (time[change - 1] + time[change])
        change_sd = (time[change] - time[change - 1]) / np.sqrt(12.0)
    blocked_now = state[change] == 1.0
    on = np.flatnonzero(blocked_now[:-1])  # a blocking change followed by an unblocking one
    t_on, t_off = change_time[on], change_time[on + 1]
    sd_on, sd_off = change_sd[on], change_sd[on + 1]
    blocks = t_on.size
    notes.append(f"run '{label}': {'event' if event_log else 'sampled'} log, {blocks} complete "
                 f"passage(s) of the flag")
    if blocks == 0:
        return empty
    duration = t_off - t_on
    sd_duration = np.hypot(sd_on, sd_off)
    speed = flag_length / duration

    def mismatch(first, second):
        return np.abs(duration[first] - duration[second]) / (duration[first] + duration[second])

    # Phase: toward and away passages alternate; the two passages around a flight (away, then
    # toward again at the same place) take equal times, those around an impact do not (ε < 1).
    # Judge on the first flights, before any partial passage (apex inside the gate) can occur.
    def scores(spare):
        # Flight pairs of each phase among the first blocks, leaving out the last `spare`.
        top = blocks - 1 - spare
        flights0 = np.arange(1, top, 2)[:2]  # pairs (1, 2), (3, 4)
        flights1 = np.arange(0, top, 2)[:2]  # pairs (0, 1), (2, 3)
        return ((np.mean(mismatch(flights0, flights0 + 1)) if flights0.size else None),
                (np.mean(mismatch(flights1, flights1 + 1)) if flights1.size else None))

    score0, score1 = scores(1)  # the last block may be a partial passage
    if score0 is None or score1 is None:
        score0, score1 = scores(0)
    phase = 1 if (score0 is not None and score1 is not None and score1 < score0) else 0
    if phase:
        notes.append(f"run '{label}': the log starts with an away passage (its impact came "
                     f"before the log); it is skipped")
    toward = np.arange(phase, blocks, 2)
    away = toward + 1
    has_away = away < blocks
    has_next = toward + 2 < blocks
    nxt = np.clip(toward + 2, 0, blocks - 1)
    aw = np.clip(away, 0, blocks - 1)
    # Free motion between an away passage and the next toward one: the cart leaves the gate
    # top at w = L/τ − g·τ/2 and is back after F = 2w/g, so g·sin θ = 2L/(τ(F + τ)) [5]_.
    flight = t_on[nxt] - t_off[aw]
    tau_mean = 0.5 * (duration[aw] + duration[nxt])
    with np.errstate(divide="ignore", invalid="ignore"):
        g_flight = 2.0 * flag_length / (tau_mean * (flight + tau_mean))
    symmetric = has_away & has_next & (mismatch(aw, nxt) < _FLIGHT_MISMATCH)
    g_eff = float(np.median(g_flight[symmetric])) if symmetric.any() else 0.0
    genuine_flight = symmetric & (np.abs(g_flight / g_eff - 1.0) < _FLIGHT_G_TOLERANCE
                                  if g_eff > 0 else symmetric)
    if g_eff > 0:
        notes.append(f"run '{label}': g·sin θ = {g_eff:.4g} m/s² from "
                     f"{int(genuine_flight.sum())} flight(s) between passages")
    else:
        notes.append(f"run '{label}': no complete flight between passages; speeds taken as "
                     f"constant near the gate")
    # An away passage is genuine only if the cart came back through the whole gate after it;
    # otherwise it turned inside the gate (a partial passage) and so did every later bounce.
    broken = np.flatnonzero(~genuine_flight)
    last_full = int(broken[0]) if broken.size else toward.size
    later = blocks - phase - 2 * last_full - 1
    if broken.size and later > 0:
        notes.append(f"run '{label}': {later} later passage(s) (partial, the cart turning inside "
                     f"the beam, or unpaired) were not used")
    full = np.arange(toward.size) < last_full
    tw = toward
    v_exit = flag_length / duration[tw] + 0.5 * g_eff * duration[tw]  # at the gate's bumper edge
    w_entry = flag_length / duration[aw] + 0.5 * g_eff * duration[aw]
    if gate_distance is not None:
        # Uniform acceleration over the gate-to-bumper distance d: V² = v² + 2gd and the time
        # 2d/(v + V), exact for the incline, independent of the contact duration.
        impact_speed = np.sqrt(v_exit ** 2 + 2.0 * g_eff * gate_distance)
        rebound_speed = np.sqrt(w_entry ** 2 + 2.0 * g_eff * gate_distance)
        impact_time = t_off[tw] + 2.0 * gate_distance / (v_exit + impact_speed)
        keep = np.arange(toward.size) <= last_full
        rebound_speed = np.where(full, rebound_speed, np.nan)
        notes.append(f"run '{label}': speeds and times extrapolated from the gate to the bumper "
                     f"(gate_distance {gate_distance:g} m)")
    else:
        # Without the distance: split the gap between the passages assuming an instantaneous
        # contact and the same distance in and out, under uniform acceleration (closed form of
        # t1 + t2 = G with t_i the travel times over d); a contact of duration τc makes the time
        # late by about τc·v_out/(v_in + v_out).
        gap = t_on[aw] - t_off[tw]
        impact_time = t_off[tw] + gap * (g_eff * gap + 2.0 * w_entry) / (
            2.0 * (g_eff * gap + v_exit + w_entry))
        impact_speed = speed[tw]
        rebound_speed = np.where(full, speed[aw], np.nan)
        keep = full
        notes.append(f"run '{label}': speeds are the flag's mean passage speeds L/τ at the gate; "
                     f"impact times split the gap between passages assuming a brief contact "
                     f"(pass gate_distance for exact times)")
    sd_speed_in = speed[tw] * sd_duration[tw] / duration[tw]
    sd_speed_out = np.where(full, speed[aw] * sd_duration[aw] / duration[aw], np.nan)
    sd_time = np.hypot(sd_off[tw], np.where(gate_distance is None, sd_on[aw], 0.0))
    dropped = int(np.sum(~keep & (np.arange(toward.size) <= last_full)))
    if dropped:
        notes.append(f"run '{label}': {dropped} impact(s) without an away passage need "
                     f"gate_distance to be timed; dropped")
    return (impact_time[keep], sd_time[keep], impact_speed[keep], rebound_speed[keep],
            np.fmax(sd_speed_in, sd_speed_out)[keep])


def read_photogate(path, *, flag_length, gate_distance=None):
    """Impacts of a cart from a photogate's state log near the bumper.

    Parameters
    ----------
    path : str or os.PathLike
        Text table or workbook with a time column and a gate-state column: Vernier
        ``Latest: Time (s)``, ``Latest: GateState`` (one row per change of state) or a
        sampled log (``Time (s) Run #1``, ``Gate State Run #1``, one row per sample). States
        1 = blocked, 0 = unblocked, or the words Blocked/Unblocked.
    flag_length : float
        Length in m of the flag on the cart that blocks the beam, in (0, 1] m.
    gate_distance : float, optional
        Distance in m the cart travels from leaving the beam to touching the bumper, if
        measured in the scene, in (0, 10] m. With it, times and speeds are extrapolated to
        the bumper.

    Returns
    -------
    pandas.DataFrame
        Impact table of :mod:`dashpot.ingest` (``run`` numbers runs side by side).

    Raises
    ------
    InputError
        Bad file (as for the other readers), no time or state column, states other than 1/0.
    ValueError
        If `flag_length` or `gate_distance` is not a finite number in its range.

    Notes
    -----
    Passages: a change to blocked followed by a change to unblocked; the flag's mean speed
    through the beam is L/τ (τ the blocking time). For a sampled log a change is put midway
    between the two samples that straddle it (1σ = sample spacing/√12); for an event log at
    the logged time (1σ = last digit/√12). A passage cut by the start or end of the log is
    ignored.

    Pairing: each impact is a passage toward the bumper followed by one away from it; between
    an away passage and the next toward one the cart flies up the incline and back through the
    same beam, so those two passages take *equal* times (uniform acceleration is time-reversal
    symmetric), while the two around an impact differ by the restitution. The phase of the
    alternation is the one whose 'flight' pairs are the more symmetric over the first flights.
    Each flight also gives g·sin θ = 2L/(τ(F + τ)) (F the time out of the beam); a flight
    that is not symmetric or disagrees with the median g·sin θ means the away passage before it
    was partial (the cart turned inside the beam): that impact keeps only its toward passage
    and every later block is dropped. An away passage with no later passage is partial too
    (the log is assumed to run until the cart rests).

    Impact time, with gate_distance d: the cart leaves the beam at v = L/τ + g·τ/2 and reaches
    the bumper at V = √(v² + 2g·d) after 2d/(v + V) — the start of contact; rebound speed
    likewise from the away passage. Without d: the gap G between the passages is split as if
    the contact were instantaneous and the distance in and out the same, which under uniform
    acceleration gives t = t_off + G(gG + 2w)/(2(gG + v + w)) (w the speed entering the beam
    on the way out); the speeds reported are then the passage speeds L/τ at the gate.
    """
    flag_length = check_range("flag_length", flag_length, *FLAG_LENGTH_RANGE, unit="m")
    if gate_distance is not None:
        gate_distance = check_range("gate_distance", gate_distance, *GATE_DISTANCE_RANGE,
                                    unit="m")
    table = _table_of_kind(path, "photogate", "no gate-state column",
                           "a photogate log (expected e.g. 'Latest: Time (s)' and "
                           "'Latest: GateState'")
    _check_duplicates(path, table)
    runs = _runs(path, table, {"state": (None, None)})
    notes = [f"file variant: {table.variant}; {len(runs)} run(s): "
             + ", ".join(f"run {k} = '{r.label or '(unlabelled)'}'" for k, r in enumerate(runs)),
             f"flag length {flag_length:g} m"]
    parts = []
    for number, run in enumerate(runs):  # loop over runs
        state_index = next(j for j, c in enumerate(table.columns)
                           if c.run == run.label and _is_state(c))
        result = _photogate_run(path, table, run, state_index, flag_length, gate_distance, notes)
        parts.append(result + (np.full(result[0].size, number),))
    merged = [np.concatenate([p[q] for p in parts]) for q in range(6)]
    return _impact_frame(path, "photogate", notes, merged[0], merged[1],
                         impact_speed=merged[2], rebound_speed=merged[3],
                         speed_uncertainty=merged[4], run=merged[5])
