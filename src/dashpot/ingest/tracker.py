"""Tracker (video analysis) data exports: which of Tracker's text layouts a file has.

Tracker [7]_ writes its data export as tab-delimited text in three layouts, each read here
into the columns of :mod:`._tabular`, whose cell conventions (numbers, units, run labels)
they share: a single track under a first line naming it (``mass_A``, then ``t``, ``x``,
``y``, ...); several tracks one below the other, each under its name; and Tracker 6's
export of several tracks side by side (a ``#multi:`` line, a row of track names starting
with the delimiter, the header with a delimiter after each column, blanks where a track has
no point). Each track's columns carry its name as their run label.

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

__all__ = ["multi_track_layout", "stacked_tracks", "titled_track"]


def titled_track(head, lines):
    """Tracker's single-track data export: a first line naming the track ('mass_A'), then a
    separated header [7]_; None if `head` (the first non-blank lines) is not that.

    Returns (separator, the track's name, the text from the header on, the head from the
    header on).
    """
    if len(head) <= 2 or _is_number([head[0].strip()], ".")[0]:
        return None
    below = _sniff_separator(head[1:])
    if below is None or below in head[0] or np.any(
            _is_number([f.strip() for f in next(csv.reader([head[1]], delimiter=below))], ".")):
        return None
    first = next(k for k, line in enumerate(lines) if line.strip())
    return below, head[0].strip(), "\n".join(lines[first + 1:]), head[1:]


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
    time column), the track names in order).
    """
    first = [k for k, line in enumerate(lines[:60]) if line.strip()][:3]
    if len(first) < 3:
        return None
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
        width = len(header)
        while width > 1 and not header[width - 1].strip():
            width -= 1  # the delimiter Tracker writes after the last column name
        # Each column's track: the name written above it or above a column to its left.
        written = np.array([n.strip() for n in names[:width]] + [""] * (width - len(names)),
                           dtype=object)
        named_at = np.where(written != "", np.arange(width), 0)
        owner = written[np.maximum.accumulate(named_at)].astype(str)
        tracks = tuple(dict.fromkeys(owner[1:][owner[1:] != ""]))
        text = "\n".join([separator.join(header[:width])] + lines[first[1] + 1:])
        return separator, text, list(owner), tracks
    return None
