"""Tracker (video analysis) data exports: which of Tracker's text layouts a file has.

Tracker [7]_ writes its data export as tab-delimited text in three layouts, each read here
into the columns of :mod:`._tabular`, whose cell conventions (numbers, units, run labels)
they share: a single track under a first line naming it (``mass_A``, then ``t``, ``x``,
``y``, ...); several tracks one below the other, each under its name; and Tracker 6's
export of several tracks side by side (a ``#multi:`` line, a row of track names starting
with the delimiter, the header with a delimiter after each column, blanks where a track has
no point). Each track's columns carry its name as their run label.

Tracker's delimiter is Tab, Space, Comma or Semicolon, and its numbers follow the system's
decimal style whatever the delimiter. Under Space, track names may hold the delimiter
("mass A"): the header's repeated columns tell how many spaces follow each name. Under Comma
with decimal commas, the header's column count and Tracker's number format ("3,000000E-1")
tell which comma is a decimal mark; where they do not, the error says to export again with
another delimiter.

References
----------
.. [7] D. Brown, Tracker video analysis and modeling tool, help pages "Exporting data" and
   "Datatable view"; Tracker 6 ``ExportDataDialog``.
"""

from __future__ import annotations

import csv
import re

import numpy as np

from ._tabular import _TIME_NAMES, _is_number, _sniff_separator

__all__ = ["TrackerLayoutError", "multi_track_layout", "stacked_tracks", "titled_track"]

# Tracker writes its unformatted numbers as "0.000000E0" (the time to full precision) in the
# system's decimal style: with a decimal comma, the digits after it always end in an exponent.
_INTEGER_PART = re.compile(r"[+-]?\d+")
_FRACTION_WITH_EXPONENT = re.compile(r"\d+E[+-]?\d+")
_FRACTION = re.compile(r"\d+(?:E[+-]?\d+)?")


class TrackerLayoutError(ValueError):
    """A Tracker export whose layout is recognised but cannot be read as it was written.

    Parameters
    ----------
    problem : str
        What is wrong and what to do, without the file's name.
    row : int, optional
        1-based data row (after the header) where the problem is.
    """

    def __init__(self, problem, row=None):
        super().__init__(problem)
        self.problem = problem
        self.row = row


def titled_track(head, lines):
    """Tracker's single-track data export: a first line naming the track ('mass_A'), then a
    separated header [7]_; None if `head` (the first non-blank lines) is not that.

    Returns (separator, the track's name, the text from the header on, the head from the
    header on, a note on how the file was read ('' if plainly)).

    Raises
    ------
    TrackerLayoutError
        Comma-delimited with decimal commas, where the header's column count does not
        settle which comma is which (as :func:`multi_track_layout`).
    """
    if len(head) <= 2 or _is_number([head[0].strip()], ".")[0]:
        return None
    below = _sniff_separator(head[1:])
    if below is None:
        # Under the Comma delimiter with decimal commas every number splits in two, so the
        # rows have more fields than the header: no separator splits them alike.
        return _titled_track_with_decimal_commas(head, lines)
    if below in head[0] or np.any(
            _is_number([f.strip() for f in next(csv.reader([head[1]], delimiter=below))], ".")):
        return None
    first = next(k for k, line in enumerate(lines) if line.strip())
    return below, head[0].strip(), "\n".join(lines[first + 1:]), head[1:], ""


def _titled_track_with_decimal_commas(head, lines):
    """The single-track export under the Comma delimiter with decimal commas, its rows
    rejoined by the header's column count (:func:`_rejoined_decimal_commas`), or None if
    `head` is not that.

    Returns
    -------
    tuple or None
        As :func:`titled_track`, the rows tab-separated.
    """
    if "," in head[0]:
        return None
    header = next(csv.reader([head[1]]))
    width = _header_width(header)
    words = [h.strip() for h in header[1:width]]
    if (width < 2 or header[0].strip().lower() not in _TIME_NAMES or not all(words)
            or np.any(_is_number(words, "."))):
        return None
    first = next(k for k, line in enumerate(lines) if line.strip())
    rows, note = _rejoined_decimal_commas(lines[first + 2:], width)
    if not note:
        return None  # no decimal comma: the rows are ragged for another reason
    text = "\n".join(["\t".join(h.strip() for h in header[:width])] + rows)
    below = [line for line in text.splitlines() if line.strip()][:len(head) - 1]
    return "\t", head[0].strip(), text, below, note


def _header_width(header):
    """The number of columns of a split header, less the empty field of a delimiter that
    Tracker writes after the last column name."""
    width = len(header)
    while width > 1 and not header[width - 1].strip():
        width -= 1
    return width


def stacked_tracks(text, separator):
    """Tracks below the first in a Tracker export that lists them one below the other.

    Each starts with a line naming it (no separator in it, a letter in it) right above a
    header whose first column is a time. Returns [(name, where its name line starts, the
    text of its header and rows)] in order; [] for a single track.
    """
    if separator is None:
        return []
    sep = re.escape(separator)
    times = "|".join(re.escape(name) for name in sorted(_TIME_NAMES, key=len, reverse=True))
    marker = re.compile(rf"^[ ]*(?P<name>[^\r\n{sep}]*[^\W\d][^\r\n{sep}]*?)[ ]*\r?\n"
                        rf"(?=[ ]*(?:{times})[ ]*(?:\([^)\r\n]*\))?[ ]*{sep})",
                        re.MULTILINE | re.IGNORECASE)
    found = list(marker.finditer(text))
    ends = [m.start() for m in found[1:]] + [len(text)]
    return [(m["name"].strip(), m.start(), text[m.end():end]) for m, end in zip(found, ends)]


def multi_track_layout(lines):
    """Tracker 6's data export layout of `lines`, or None if they are not one.

    Tracker writes ``#multi:`` when the export holds several tracks (skipped with the
    comments), then a row of track names that starts with the delimiter, each name above the
    first of its columns, then the header (``t`` and each track's columns, with a delimiter
    after each), then one row per frame with blanks where a track has no point [7]_.

    Returns (separator, the text from the header on, each column's track name ('' for the
    time column), the track names in order, a note on how the file was read ('' if plainly)).

    Raises
    ------
    TrackerLayoutError
        The layout is Tracker's but its cells or track names cannot be told apart: names with
        spaces under the Space delimiter, decimal commas under the Comma delimiter where the
        header's column count does not settle which comma is which.
    """
    first = [k for k, line in enumerate(lines[:60]) if line.strip()][:3]
    if len(first) < 3:
        return None
    spaced = _space_delimited_layout(lines, first)
    if spaced is not None:
        return spaced
    for separator in ("\t", ";", ","):
        names = next(csv.reader([lines[first[0]]], delimiter=separator))
        header = next(csv.reader([lines[first[1]]], delimiter=separator))
        if len(names) < 2 or names[0].strip() or len(header) < 2:
            continue
        named = [n.strip() for n in names if n.strip()]
        words = [h.strip() for h in header[1:] if h.strip()]
        if (not named or header[0].strip().lower() not in _TIME_NAMES or not words
                or np.any(_is_number(named + words, "."))):
            continue
        width = _header_width(header)
        # Each column's track: the name written above it or above a column to its left.
        written = np.array([n.strip() for n in names[:width]] + [""] * (width - len(names)),
                           dtype=object)
        named_at = np.where(written != "", np.arange(width), 0)
        owner = written[np.maximum.accumulate(named_at)].astype(str)
        tracks = tuple(dict.fromkeys(owner[1:][owner[1:] != ""]))
        rows, note = lines[first[1] + 1:], ""
        if separator == ",":
            rows, note = _rejoined_decimal_commas(rows, width)
            separator = "\t" if note else separator
        text = "\n".join([separator.join(header[:width])] + rows)
        return separator, text, list(owner), tracks, note
    return None


def _space_delimited_layout(lines, first):
    """Tracker 6's layout under its "Space" delimiter, or None if `lines` are not that.

    The row of track names is the delimiter, then each name followed by one delimiter per
    column; a name may hold spaces itself ("mass A"), so the names are found from the header:
    its columns repeat once per track, and each name is followed by exactly that many spaces.

    Parameters
    ----------
    lines : list of str
        The file's lines after its comment lines (``#multi:`` among them).
    first : list of int
        Indices of the first three non-blank lines.

    Returns
    -------
    tuple or None
        As :func:`multi_track_layout`.

    Raises
    ------
    TrackerLayoutError
        The names cannot be told apart (names with spaces, one column per track).
    """
    names_line, header_line = lines[first[0]].rstrip("\r\n"), lines[first[1]].rstrip("\r\n")
    if not names_line.startswith(" ") or not names_line.strip():
        return None
    header = header_line.split(" ")
    while len(header) > 1 and header[-1] == "":
        header.pop()  # the delimiter Tracker writes after the last column name
    words = header[1:]
    row = lines[first[2]].split(" ")[0]
    if (header[0].strip().lower() not in _TIME_NAMES or not words or not all(words)
            or np.any(_is_number(words, ".")) or not _is_number([row.replace(",", ".")], ".")[0]):
        return None
    names = _names_followed_by_spaces(names_line[1:], words)
    if names is None:
        raise TrackerLayoutError(
            f"Tracker export with the Space delimiter whose track names hold spaces "
            f"('{names_line.strip()}'), so the names cannot be told apart: export it again "
            f"with the Tab delimiter (Export Data, Delimiter: Tab)")
    columns = len(words) // len(names)
    owner = [""] + [name for name in names for _ in range(columns)]
    text = "\n".join([" ".join(header)] + lines[first[1] + 1:])
    return " ", text, owner, tuple(names), ""


def _names_followed_by_spaces(text, words):
    """The track names in `text` (each followed by one space per column), or None.

    The number of columns per track is the shortest period of the header's column names
    `words` whose split of `text` gives as many names as tracks, none empty or with a space
    at either end; a period of one column makes single spaces both separators and, possibly,
    part of a name, and is accepted only where that split is the one consistent with it.
    """
    for columns in range(1, len(words) + 1):
        count, remainder = divmod(len(words), columns)
        if remainder or words != words[:columns] * count:
            continue
        pieces = text.split(" " * columns)
        names = pieces[:-1]
        if (pieces[-1] == "" and len(names) == count
                and all(name and name == name.strip() for name in names)):
            return names
    return None


def _rejoined_decimal_commas(rows, width):
    """The data rows of a comma-delimited export, their decimal commas rejoined where needed.

    Tracker writes its numbers in the system's decimal style whatever the delimiter, so a
    "Comma" export in a decimal-comma locale splits every number in two. A row of `width`
    fields holds no decimal comma, one of twice as many holds nothing but numbers with one;
    in between, a comma followed by digits and an exponent ("3,000000E-1", as Tracker writes
    unformatted numbers) is a decimal comma.

    Parameters
    ----------
    rows : list of str
        The lines below the header.
    width : int
        The header's number of columns.

    Returns
    -------
    (list of str, str)
        The rows (tab-separated if any decimal comma was rejoined, else as given) and a note
        saying so ('' if there was none).

    Raises
    ------
    TrackerLayoutError
        A row whose commas cannot be told apart, naming it.
    """
    split = [next(csv.reader([row])) if row.strip() else [] for row in rows]
    # A delimiter after a row's last cell is one empty field too many, not a decimal comma.
    if all(len(fields) <= width or (len(fields) == width + 1 and fields[-1] == "")
           for fields in split):
        return rows, ""
    rejoined = []
    for number, fields in enumerate(split, start=1):
        cells = _cells_of(fields, width) if fields else []
        if cells is None:
            raise TrackerLayoutError(
                f"comma-delimited with decimal commas, and its {len(fields)} comma-separated "
                f"pieces do not tell which comma is a decimal mark in {width} columns: export "
                f"it again with the Tab or Semicolon delimiter", row=number)
        rejoined.append("\t".join(cells))
    return rejoined, (f"decimal commas told apart from the delimiter by the header's {width} "
                      f"columns")


def _cells_of(fields, width):
    """The `width` cells of one row's comma-separated `fields`, or None where ambiguous."""
    if len(fields) <= width:
        return fields  # no decimal comma (blank cells, whole numbers)
    if len(fields) == 2 * width and all(
            _INTEGER_PART.fullmatch(a) and _FRACTION.fullmatch(b)
            for a, b in zip(fields[0::2], fields[1::2])):
        return [f"{a},{b}" for a, b in zip(fields[0::2], fields[1::2])]
    cells, k = [], 0
    while k < len(fields):
        if (k + 1 < len(fields) and _INTEGER_PART.fullmatch(fields[k])
                and _FRACTION_WITH_EXPONENT.fullmatch(fields[k + 1])):
            cells.append(f"{fields[k]},{fields[k + 1]}")
            k += 2
        else:
            cells.append(fields[k])
            k += 1
    return cells if len(cells) == width else None
