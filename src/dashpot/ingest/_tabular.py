"""Conventions shared by the lab-table readers: loading, headers, units, numbers, runs.

A file is loaded as one or more tables of string cells: a text table (the separator sniffed
among tab, semicolon and comma, else a space where every line splits alike [7]_; the decimal
mark a comma when the separator is not and numbers like ``1,25`` occur; leading ``#`` comment
lines skipped; Tracker's data export layouts, a
track named above its header or several side by side, are told apart in :mod:`.tracker`, each
track's columns carrying its name as their run label), every CSV member of a zip
archive (phyphox's export [2]_), or every sheet of a workbook — Excel ``.xlsx``, legacy Excel
97-2003 ``.xls`` (BIFF8) or OpenDocument ``.ods`` — read through pandas' calamine engine.
Headers are read in the exporting program's words (name, unit in brackets, run label in front
or behind); cells become numbers in SI units with their written resolution; bad cells raise
:class:`dashpot.errors.InputError` naming the file, row and column. Every reader builds its
impact table with :func:`_impact_frame`, and :func:`sniff_table` tells the kinds apart by their
headers.

References
----------
.. [2] phyphox-android ``DataExport.java``: CSV with quoted headers, numbers formatted
   ``0.000000000E0``, separators comma/tab/semicolon with decimal point or comma, one CSV per
   set in a zip (metadata under ``meta/``), or one Excel sheet per set; shorter columns padded
   with ``NaN``.
.. [7] D. Brown, Tracker, ``TrackerIO.getData`` and ``ExportDataDialog``: the data export's
   delimiter is a tab, space, comma or semicolon (or one the user adds); blank cells where a
   track has no point.
.. [9] Audacity manual, "Label Tracks", exporting labels: a text file of one label per line,
   start and end time in seconds and the label's text, tab-separated, no header; Audacity's
   ``LabelStruct::Export`` writes a label's frequency range (spectral selection, in Hz) on a
   line of its own below it, starting with a backslash and a tab (``\\<tab>f0<tab>f1``);
   saved under a ``.srt`` or ``.vtt`` name, its labels are SubRip or WebVTT cues instead (a
   number, ``HH:MM:SS,mmm --> HH:MM:SS,mmm`` or with a period before the milliseconds, the
   label's text, a blank line; WebVTT under a first line ``WEBVTT``).
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

from ..errors import InputError, require_file
from . import FLAG_COLUMN, IMPACT_COLUMNS, is_speed_error_column

TABLE_KINDS = ("phyphox", "timestamps", "motion_sensor", "photogate")
"""What :func:`sniff_table` can answer, and the ``sensor`` attribute of each reader's table."""

# ---------------------------------------------------------------------------------------------
# Units and header words
# ---------------------------------------------------------------------------------------------

_TIME_UNITS = {"s": 1.0, "sec": 1.0, "second": 1.0, "seconds": 1.0, "ms": 1e-3, "msec": 1e-3,
               "millisecond": 1e-3, "milliseconds": 1e-3, "us": 1e-6, "µs": 1e-6, "μs": 1e-6}
_LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "meter": 1.0, "meters": 1.0, "metre": 1.0,
                 "metres": 1.0, "centimeter": 1e-2, "centimeters": 1e-2, "centimetre": 1e-2,
                 "centimetres": 1e-2, "millimeter": 1e-3, "millimeters": 1e-3,
                 "millimetre": 1e-3, "millimetres": 1e-3}
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
_CHANNEL = re.compile(r",\s*ch(?:annel)?\s*[\w&/ -]*$")  # ', Ch 1&2', ', Ch P3', ', Ch A'
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
    # PASCO Capstone names a wired sensor's measurement after its interface channel too
    # ('Position, Ch 1&2 (m) Run #1', 'Voltage, Ch A (V)'): the quantity is before the comma.
    name = _CHANNEL.sub("", name)
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
    tracks: tuple = ()  # Tracker's track names, in the order of their columns

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
    reported by its row rather than hiding the separator. A space (Tracker's "Space"
    delimiter [7]_) is tried last and only where every line splits alike: a header's words
    ('Time (s)') hold spaces too.
    """
    for candidate in ("\t", ";", ","):
        counts = [len(fields) for fields in csv.reader(lines, delimiter=candidate)]
        if counts and counts[0] > 1:
            differing = sum(count != counts[0] for count in counts)
            if differing <= max(1, len(counts) // 10):
                return candidate
    counts = np.array([len(line.split(" ")) for line in lines])
    if len(lines) > 1 and counts[0] > 1 and np.all(counts == counts[0]):
        return " "
    return None


_DECIMAL_COMMA_NUMBER = re.compile(r"^\s*[+-]?(\d+),(\d+)\s*$")


def _comma_is_decimal(text):
    """True if every line of `text` is one number with a decimal comma, not two fields.

    A spreadsheet on a system with a decimal comma saves a single column of numbers without
    any separator (``1,234568``), which reads as two comma-separated integer fields. It is a
    decimal comma where every non-blank line is digits, a comma and digits, and the two
    fields could not be times with their uncertainties: the first not increasing, or a
    second field as large as the median step of the first (see timestamps' check of an
    unnamed uncertainty column).
    """
    matches = [_DECIMAL_COMMA_NUMBER.match(line) for line in text.splitlines() if line.strip()]
    if len(matches) < 2 or not all(matches):
        return False
    first = np.array([float(m[1]) for m in matches])
    second = np.array([float(m[2]) for m in matches])
    steps = np.diff(first)
    if np.any(steps <= 0):
        return True
    return bool(np.any(second >= np.median(steps)))


_QUOTED_DECIMAL_COMMA = re.compile(r"[+-]?\d*,\d+(?:[eE][+-]?\d+)?")
_DECIMAL_POINT = re.compile(r"[+-]?\d*\.\d+(?:[eE][+-]?\d+)?")


def _quoted_decimal_commas(cells):
    """True if a comma-separated table's numbers carry decimal commas (each quoted).

    A spreadsheet on a system with a decimal comma that saves comma-separated values quotes
    every number holding a comma (``"0,7499"``). Such cells, and none with a decimal point,
    make the comma the decimal mark inside the fields.
    """
    flat = pd.Series(cells.ravel(), dtype=object).astype(str)
    commas = flat.str.fullmatch(_QUOTED_DECIMAL_COMMA.pattern).sum()
    points = flat.str.fullmatch(_DECIMAL_POINT.pattern).sum()
    return bool(commas > 0 and points == 0)


def _below_title_lines(head, lines, most=3):
    """A table under up to `most` title lines (words, a date: no number among their fields),
    as a spreadsheet's author writes above the header; None if `head` is not that.

    Returns (separator, the number of title lines, the text from the header on, the head
    from the header on).
    """
    for skip in range(1, min(most, len(head) - 2) + 1):
        separator = _sniff_separator(head[skip:])
        if separator is None:
            continue
        if separator == "," and all(_DECIMAL_COMMA_NUMBER.match(line) for line in head[skip:]):
            return None  # a header above one column of numbers with decimal commas
        above = [field.strip() for line in head[:skip]
                 for field in next(csv.reader([line], delimiter=separator)) if field.strip()]
        if np.any(_is_number(above, ".")) or np.any(_is_number(above, ",")):
            return None  # a line of numbers above is data: no title
        written = [k for k, line in enumerate(lines) if line.strip()]
        return separator, skip, "\n".join(lines[written[skip]:]), head[skip:]
    return None


def _ordinal(number):
    """'1st', '2nd', '3rd', '4th', ... '11th', '21st'."""
    suffix = "th" if 10 <= number % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(
        number % 10, "th")
    return f"{number}{suffix}"


def _ragged_problem(lines):
    """Why separated lines make no table: their numbers of fields differ (or None).

    A file whose lines split at a separator into different numbers of fields has no single
    separator (see _sniff_separator); told plainly, the reader sees it is not one table
    (several tables one below the other, a title line above the header).
    """
    spelled = {"\t": "tab", ";": "semicolon", ",": "comma"}
    for candidate in ("\t", ";", ","):
        counts = [len(fields) for fields in csv.reader(lines, delimiter=candidate)]
        if counts and max(counts) > 1:
            k = next(k for k, count in enumerate(counts) if count != counts[0])
            return (f"its lines have different numbers of {spelled[candidate]}-separated "
                    f"fields ({counts[0]} on the first non-blank line, {counts[k]} on the "
                    f"{_ordinal(k + 1)}), as several tables one below the other or a title "
                    f"line above the header would")
    return None


# How much of a file decides whether it is UTF-16 without a byte-order mark.
_UTF16_SNIFF_BYTES = 4096
# In UTF-16 text of digits, separators and Latin letters nearly every code unit has a zero
# high byte and no code unit has a zero low byte; binary data shows no such alternation. A
# few non-Latin characters (a "µs" or "Δt" header) are allowed for.
_UTF16_ZERO_HIGH_BYTES = 0.7
_UTF16_ZERO_LOW_BYTES = 0.02
_UTF16_NAMES = {"utf-16-le": "UTF-16LE", "utf-16-be": "UTF-16BE"}
# No text table holds a control character (C0 or C1) other than tab, line feed and carriage
# return; binary data read as UTF-16 is full of them.
_CONTROL_CHARACTER = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x9f]")


def _bomless_utf16(raw):
    """The codec of `raw` where it is UTF-16 text without a byte-order mark, else None.

    Some Windows programs (a few loggers, some of Excel's "Unicode text" saves) write UTF-16
    LE or BE without the byte-order mark; their zero high bytes made the file look binary.
    The byte pattern of the file's start picks the byte order, and the text must then decode
    and hold no control character besides tabs and line breaks, so that binary data with
    many zero bytes (16-bit samples, say) is not taken for text.

    Parameters
    ----------
    raw : bytes
        The file's content (it starts with no UTF-16 byte-order mark).

    Returns
    -------
    str or None
        ``"utf-16-le"``, ``"utf-16-be"`` or None.
    """
    sample = raw[:_UTF16_SNIFF_BYTES]
    sample = sample[:len(sample) - len(sample) % 2]
    units = len(sample) // 2
    if units < 2 or len(raw) % 2:
        return None
    zeros_even = sample[0::2].count(0) / units
    zeros_odd = sample[1::2].count(0) / units
    for codec, zero_high, zero_low in (("utf-16-le", zeros_odd, zeros_even),
                                       ("utf-16-be", zeros_even, zeros_odd)):
        if zero_high >= _UTF16_ZERO_HIGH_BYTES and zero_low <= _UTF16_ZERO_LOW_BYTES:
            try:
                text = raw.decode(codec)
            except UnicodeDecodeError:
                return None
            return None if _CONTROL_CHARACTER.search(text) else codec
    return None


def _decode(path, raw, member):
    """Text of a table file and the name of its encoding.

    UTF-16 with a byte-order mark (Excel's "Unicode text") or without one (see
    :func:`_bomless_utf16`) and UTF-8 with or without one are recognised; anything else is
    read as Windows-1252 (Excel's "CSV" on Western systems).
    """
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        try:
            return raw.decode("utf-16"), "UTF-16"
        except UnicodeDecodeError as error:
            raise InputError(path, f"not a table: {member or 'the file'} starts like UTF-16 "
                                   f"text but does not decode ({error.reason})") from None
    if b"\x00" in raw:
        codec = _bomless_utf16(raw)
        if codec is None:
            raise InputError(path, f"not a table: {member or 'the file'} holds binary data")
        return raw.decode(codec), f"{_UTF16_NAMES[codec]} without byte-order mark"
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


def _parse_cells(path, text, separator, decimal, member):
    """String cells of a text table (pandas' C parser; the csv module where rows differ)."""
    try:
        frame = pd.read_csv(io.StringIO(text), sep=separator or "\x1f", header=None, dtype=str,
                            keep_default_na=False, skip_blank_lines=True, quotechar='"',
                            engine="c")
        cells = frame.fillna("").to_numpy(dtype=str)
    except pd.errors.ParserError:
        cells = _rows_by_csv_module(path, text, separator, decimal, member)
    except (pd.errors.EmptyDataError, ValueError) as error:
        raise InputError(path, f"not a table: {str(error).strip()}") from error
    return np.char.strip(cells)


def _label_frequency_lines(lines):
    """Boolean array: which lines are Audacity's frequency ranges of the label above [9]_.

    Such a line starts with a backslash and a tab (Audacity's mark for a line that continues
    the label before it), so no table row of numbers or words is one.
    """
    return np.array([line.startswith("\\\t") for line in lines], dtype=bool)


_CUE_TIMES = re.compile(r"^\s*(\d+):(\d{2}):(\d{2})[,.](\d{3})\s*-->\s*"
                        r"(\d+):(\d{2}):(\d{2})[,.](\d{3})\s*$")


def _subtitle_labels(lines):
    """Audacity's labels exported as SubRip or WebVTT cues [9]_, restated in its text format
    (start and end in s, the label's text; tab-separated), or None for any other text.

    The times are written to the millisecond, and are restated with three decimals so that
    their resolution stays what was written.
    """
    written = [line.strip() for line in lines if line.strip()]
    if len(written) < 2 or not (written[0].startswith("WEBVTT") or (
            written[0].isdigit() and _CUE_TIMES.match(written[1]))):
        return None
    matches = [_CUE_TIMES.match(line) for line in lines]
    cues = [k for k, match in enumerate(matches) if match]
    if not cues:
        return None
    fields = np.array([match.groups() for match in matches if match], dtype=float)
    seconds = np.array([3600.0, 60.0, 1.0, 1e-3])
    start, end = fields[:, :4] @ seconds, fields[:, 4:] @ seconds
    # The label's text is the line below its times (empty for a label without text).
    texts = [lines[k + 1].replace("\t", " ").strip() if k + 1 < len(lines) else ""
             for k in cues]
    return "\n".join(f"{a:.3f}\t{b:.3f}\t{text}" for a, b, text in zip(start, end, texts))


def _text_table(path, raw, member):
    """Parse one text table (CSV, TSV, semicolon-separated; either decimal mark).

    Lines starting with '#' before the first table line are comments and are skipped, and so
    are the frequency lines of an Audacity label export (see _label_frequency_lines); its
    SubRip or WebVTT cues are read as its labels (see _subtitle_labels).
    """
    text, encoding = _decode(path, raw, member)
    lines = text.splitlines()
    cues = _subtitle_labels(lines)
    if cues is not None:
        text = cues
        lines = text.splitlines()
    frequency_lines = _label_frequency_lines(lines)
    if frequency_lines.any():
        lines = [line for line, skip in zip(lines, frequency_lines) if not skip]
        text = "\n".join(lines)
    comments = 0
    while comments < len(lines) and lines[comments].lstrip().startswith("#"):
        comments += 1
    if comments:
        text = "\n".join(lines[comments:])
    # Sniff from the first non-blank lines only; the whole table is parsed by pandas below.
    head = [line for line in lines[comments:comments + 60] if line.strip()][:20]
    if not head:
        raise InputError(path, f"{member + ': ' if member else ''}file is empty")
    # Tracker's layouts build on this module's cell conventions (imported here, not above).
    from .tracker import TrackerLayoutError, multi_track_layout, stacked_tracks, titled_track
    from .vernier import format2_layout

    vernier = format2_layout(lines[comments:])
    if vernier is not None:
        # Vernier's text export: six header lines per data set, restated as one header row.
        text = vernier
        lines = text.splitlines()
        comments = 0
        head = lines[:20]
    try:
        tracker = None if vernier is not None else multi_track_layout(lines[comments:])
    except TrackerLayoutError as error:
        raise InputError(path, f"{member + ': ' if member else ''}{error.problem}",
                         row=error.row) from None
    tracker_note = ""
    if tracker is not None:
        separator, text, owner, tracks, tracker_note = tracker
        head = text.splitlines()[:20]
    else:
        separator = _sniff_separator(head)
        if separator == "," and _comma_is_decimal(text):
            separator = None  # one header-less column of numbers with a decimal comma
    title = None
    if tracker is None and separator is None:
        try:
            titled = titled_track(head, lines[comments:])
        except TrackerLayoutError as error:
            raise InputError(path, f"{member + ': ' if member else ''}{error.problem}",
                             row=error.row) from None
        if titled is not None:
            separator, title, text, head, tracker_note = titled
    titles = 0
    if tracker is None and separator is None and title is None:
        titled = _below_title_lines(head, lines[comments:])
        if titled is not None:
            separator, titles, text, head = titled
    body = "\n".join(head[1:])
    decimal = "," if separator != "," and re.search(r"\d,\d", body) else "."
    blocks = stacked_tracks(text, separator) if title else []
    if blocks:
        # Several tracks one below the other, each under its name: side by side here, each
        # track with its own time column.
        parts = [_parse_cells(path, block, separator, decimal, member)
                 for block in [text[:blocks[0][1]]] + [block for _, _, block in blocks]]
        length = max(part.shape[0] for part in parts)
        cells = np.hstack([np.vstack([part, np.full((length - part.shape[0], part.shape[1]), "")])
                           for part in parts])
        tracks = (title,) + tuple(name for name, _, _ in blocks)
        owner = list(np.repeat(tracks, [part.shape[1] for part in parts]))
    else:
        cells = _parse_cells(path, text, separator, decimal, member)
        if separator == "," and _quoted_decimal_commas(cells[1:]):
            decimal = ","  # comma separated, each number quoted with its decimal comma
    spelled = {"\t": "tab", ";": "semicolon", ",": "comma", " ": "space",
               None: "single-column"}
    # Decimal commas rejoined from a comma-delimited Tracker export: the cells are tab-joined
    # here, but the file is comma separated.
    written = "," if tracker_note else separator
    variant = (f"CSV, {spelled[written]}{' separated' if written else ''}, decimal "
               f"{'comma' if decimal == ',' else 'point'}"
               + (f", {encoding}" if encoding != "UTF-8" else "")
               + (", Audacity labels as SubRip/WebVTT cues" if cues is not None else "")
               + (f", {comments} comment line(s) skipped" if comments else "")
               + (f", {int(frequency_lines.sum())} label frequency line(s) skipped"
                  if frequency_lines.any() else "")
               + (", Vernier Format 2 text export" if vernier is not None else "")
               + (f", {titles} title line(s) above the header skipped" if titles else ""))
    if tracker is None and not blocks:
        if title:
            variant += f", first line names the track '{title}' (Tracker data export)"
        if tracker_note:
            variant += f", {tracker_note}"
        try:
            table = _finish_table(path, cells, decimal, variant, member)
        except InputError:
            ragged = _ragged_problem(head) if separator is None else None
            if ragged is None:
                raise
            raise InputError(path, f"{member + ': ' if member else ''}not a table: {ragged}"
                             ) from None
        table.tracks = (title,) if title else ()
        return table
    if blocks:
        variant += ", tracks one below the other, each under its name"
    names_list = ", ".join(f"'{t}'" for t in tracks)
    variant += f", Tracker data export of {len(tracks)} track(s) ({names_list})"
    if tracker_note:
        variant += f", {tracker_note}"
    table = _finish_table(path, cells, decimal, variant, member)
    several = len(tracks) > 1
    # Each track's columns carry its name as their run label (the time column is shared); with
    # several tracks the name goes in front of the header too, so an error says which.
    table.columns = [_Column(f"{label}: {column.header}" if several and label else column.header,
                             column.name, column.unit, label)
                     for column, label in zip(table.columns, owner)]
    table.tracks = tracks
    return table


def _used_width(cells):
    """Number of columns up to the last one with any cell written (header included).

    A separator after the last column on every line (a spreadsheet that saved a formatted
    but empty column, a logger that ends each field with one) adds columns of nothing.
    """
    used = np.flatnonzero((cells != "").any(axis=0))
    return int(used[-1]) + 1 if used.size else cells.shape[1]


def _title_rows(cells, decimal, most=10):
    """How many rows above the header are a title (0 if none): rows of at most one written
    cell (a title, a date, a blank row) above a header row that sits right above the first
    row of numbers, within the first `most` rows."""
    written = cells[:most + 2] != ""
    numeric = written & _is_number(cells[:most + 2].ravel(), decimal).reshape(written.shape)
    data = np.flatnonzero(written.any(axis=1) & (numeric == written).all(axis=1))
    if data.size == 0 or data[0] < 2:
        return 0
    header = int(data[0]) - 1
    if not np.all(written[:header].sum(axis=1) <= 1) or numeric[header].all():
        return 0
    return header


def _finish_table(path, cells, decimal, variant, member):
    """Split off the header row (if the first row is not all numbers) and check for data."""
    where = f"'{member}': " if member else ""
    if cells.size == 0 or not np.any(cells != ""):
        raise InputError(path, f"{where}file is empty")
    cells = cells[:, :_used_width(cells)]
    first = cells[0]
    # A row of numbers is data; so is a label of Audacity's export (two times and its text).
    if np.all(_is_number(first[first != ""], decimal)) or (
            first.size == 3 and np.all(_is_number(first[:2], decimal))):
        columns = None
    else:
        columns = [_parse_header(h) for h in first]
        cells = cells[1:]
    table = _Table(member, columns, cells, decimal, variant)
    if columns is not None and _kind_of(table) is None:
        # A title (and blank rows) above the header, as a spreadsheet's author writes one:
        # the header is the row right above the first row of numbers.
        skip = _title_rows(np.vstack([first, cells]), decimal)
        if skip:
            below = _Table(member, [_parse_header(h) for h in cells[skip - 1]], cells[skip:],
                           decimal, variant + f", {skip} title row(s) above the header skipped")
            if _kind_of(below) is not None:
                table = below
                cells = below.cells
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
    require_file(path)
    try:
        raw = path.read_bytes()
    except OSError as error:  # no permission, a failing disk
        raise InputError(path, f"cannot read the file ({error.strerror or error})") from None
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
    """Float values of column `index` and the resolution of its written digits (the column's,
    on each cell with a number; NaN elsewhere).

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
    # Resolution of the written digits, taken for the whole column as the median over its
    # cells. One cell's text does not set it: a spreadsheet writes the shortest text of a
    # number (1.25 for 1.2500, 0.5 for a click at exactly half a second), and a workbook's
    # cells hold floats whose digits show no resolution at all.
    written = _written_resolutions(strings)
    finite = np.isfinite(values.to_numpy(dtype=float))
    resolution = np.full(finite.size, np.nan)
    if finite.any():
        resolution[finite] = float(np.median(written[finite]))
    return values.to_numpy(dtype=float), resolution


def _written_resolutions(strings):
    """One unit of the last written digit of each number in `strings` (a pandas Series of str,
    decimal point), allowing for an exponent (phyphox writes 1.234567890E-1 to 1e-10); NaN
    where a cell is no number."""
    parts = strings.str.strip().str.extract(_NUMBER)
    decimals = parts["frac"].fillna("").str.len() - pd.to_numeric(parts["exp"]).fillna(0)
    digits = (parts["int"].fillna("") + parts["frac"].fillna("")).str.len() > 0
    return np.where(digits, 10.0 ** (-decimals.to_numpy(dtype=float)), np.nan)


def _cell_resolutions(table, index):
    """:func:`_written_resolutions` of each cell of column `index` of `table`: where the
    written digits grow with the number (exponent notation: 1.093691667E1 is written to 1e-8,
    9.005000000E-1 to 1e-10), checking one column against another needs each cell's own, not
    the column's median (:func:`_numbers`)."""
    strings = pd.Series(table.cells[:, index], dtype=object).astype(str)
    if table.decimal == ",":
        strings = strings.str.replace(",", ".", regex=False)
    return _written_resolutions(strings)


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
                  flag=None, speed_errors=None):
    """The impact table of dashpot.ingest, sorted by time, with its attrs; `speed_errors`
    ({column: values}, the columns of the speeds' correlated errors a reader states) before
    the flag (which stays last)."""
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
    for name, values in (speed_errors or {}).items():
        frame[name] = np.asarray(values, dtype=float)
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


def _is_label_track(table):
    """True for Audacity's label export [9]_: no header; per label its start and end in s
    and its text (which may be empty), tab-separated; every label ends at or after its start.

    Two header-less columns whose second is never below the first are such labels, never
    times with their uncertainties (an uncertainty as large as the time itself is none).
    """
    if table.columns is not None or table.cells.shape[1] not in (2, 3):
        return False
    bounds = table.cells[:, :2]
    if np.any(bounds == "") or not np.all(_is_number(bounds.ravel(), table.decimal)):
        return False
    if table.decimal == ",":
        bounds = np.char.replace(bounds, ",", ".")
    start, end = bounds.astype(float).T
    return bool(np.all(np.isfinite(start)) and np.all(end >= start))


def _kind_of(table):
    """Which reader a single table belongs to, or None."""
    if _phyphox_layout(table) is not None:
        return "phyphox"
    if _is_impact_header(table):
        return "timestamps"  # dashpot's own impact table, read by read_impact_table
    if table.columns is None:
        return ("timestamps" if table.cells.shape[1] <= 2 or _is_label_track(table)
                else None)
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


def _impact_columns(table):
    """{column of IMPACT_COLUMNS (or FLAG_COLUMN, or a column of the speeds' correlated
    errors): index} for the headers that are exactly those names."""
    found = {}
    for j, column in enumerate(table.columns or ()):
        key = column.header.strip().lower()
        if ((key in (*IMPACT_COLUMNS, FLAG_COLUMN) or is_speed_error_column(key))
                and key not in found):
            found[key] = j
    return found


def _is_impact_header(table):
    """True for dashpot's impact table: headers ``time`` and ``time_uncertainty``, no units."""
    return {"time", "time_uncertainty"} <= set(_impact_columns(table))


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


def _velocity_spread(time, values):
    """Spread of the velocity along one coordinate: the range of its central 90 %.

    A bouncing object's velocity along the bounce reverses at every impact, so it spans
    about twice the impact speed; along a coordinate it merely drifts or travels (a ball
    thrown forward, bouncing along the floor) the velocity stays near one value, however far
    the object goes. The coordinate with the larger spread is the one bounced along.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times in s (NaN where missing).
    values : numpy.ndarray
        Positions along the coordinate (NaN where not marked).

    Returns
    -------
    float
        The 5-95 percentile range of the velocities between consecutive marked samples
        (units of `values` per s); -1 where fewer than two samples are marked.
    """
    marked = np.isfinite(time) & np.isfinite(values)
    t, x = time[marked], values[marked]
    steps = np.diff(t)
    velocity = np.diff(x)[steps > 0] / steps[steps > 0]
    if velocity.size == 0:
        return -1.0
    low, high = np.percentile(velocity, [5.0, 95.0])
    return float(high - low)


def _span(present):
    """First and last index (inclusive) where `present` is True, or None if it never is."""
    where = np.flatnonzero(present)
    return (int(where[0]), int(where[-1])) if where.size else None


def _runs(path, table, quantities, *, skip_blanks=False):
    """Group columns into runs and read each run's time and `quantities` in SI units.

    `quantities` maps a quantity ('position', 'velocity', 'state') to (names, unit kind), in
    order of preference: the first one a run has is the one its samples are read from, and a
    later one (velocity beside a position) is not used, so its blanks cannot reject the file.
    Blanks at the start or end of a column are normal (a derivative starts a sample or two
    after the position; shorter runs are padded at the end); a blank between values of the
    column read, or of the time beside them, is an error naming the row, unless
    `skip_blanks` (a Tracker track has no point on a frame nobody marked): those rows are
    then left out of the run.
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
            # Several coordinates (Tracker's x and y): the one the object bounces along.
            seconds = time * (_unit_factor(path, where, columns[time_index], table, "time")
                              or 1.0)
            spread = [_velocity_spread(seconds, v) for _, _, v, _ in read]
            read = [read[int(np.argmax(spread))]]
        j, filled, values, res = read[0]
        span = _span(filled)
        if span is None:
            continue
        rows = np.arange(span[0], span[1] + 1)
        if skip_blanks:
            rows = rows[filled[rows]]
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
