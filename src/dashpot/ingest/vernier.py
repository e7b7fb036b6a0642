"""Vernier's text export ("Vernier Format 2"): which columns and data sets a file holds.

Logger Pro and Graphical Analysis 3 exchange data sets as tab-delimited text, each under six
lines of header [8]_: ``Vernier Format 2``; the source and date; the data set's name (``Latest``,
``Run 1``, ...); the columns' long names (``Time``, ``Position``, ...); their short names
(``t``, ``x``, ...); their units (``s``, ``m``, ...); then a blank line and one row per
sample. Vernier's Arduino sketches write the same without the short names: five lines. Several
data sets follow one another, each under its own header lines; columns may be
shorter than others. Each data set is read here into the columns of :mod:`._tabular` side by
side, each column headed ``<data set>: <long name> (<unit>)``, the data set's name as its run
label, as Vernier's CSV export heads it.
Long names may be quoted (``"Greenwich Mean Time"``); a data set followed by another may
end in a row of zeros (the format's data set delimiter [8]_), which is not a sample.

References
----------
.. [8] Vernier Software & Technology, Logger Pro 3 help, "Importing Data From Custom
   Applications": the data set format, a tab-delimited block of text per data set.
"""

from __future__ import annotations

import re

__all__ = ["format2_layout"]

_MARK = re.compile(r"^\s*vernier format [23]\s*$", re.IGNORECASE)
_HEADER_LINES = 6  # the mark, source and date, data set name, long names, short names, units
_NAMES_LINES = 4  # the mark, source and date, data set name, long names: then units (and
# before them the short names, in Logger Pro's six lines), then the samples


def _label(text):
    """A data set's name as a run label: brackets and colons (header syntax) left out."""
    return " ".join(re.sub(r"[:()\[\]]", " ", text).split())


def _all_zero(row):
    """True for a row whose every cell is a zero (either decimal mark)."""
    cells = [cell.strip().replace(",", ".") for cell in row if cell.strip()]
    try:
        return bool(cells) and all(float(cell) == 0.0 for cell in cells)
    except ValueError:
        return False


def _is_sample(line):
    """True for a row of numbers (either decimal mark), as a data set's samples are."""
    cells = [cell.strip().replace(",", ".") for cell in line.split("\t") if cell.strip()]
    try:
        return bool([float(cell) for cell in cells])
    except ValueError:
        return False


def format2_layout(lines):
    """The columns of a "Vernier Format 2" text export as one tab-separated table, or None.

    Parameters
    ----------
    lines : list of str
        The file's lines (comment lines already skipped).

    Returns
    -------
    str or None
        Tab-separated text: a header row (``<data set>: <long name> (<unit>)`` per column)
        and the data sets' rows side by side, shorter ones padded with empty cells; None if
        the first non-blank line is not the format's mark.
    """
    starts = [k for k, line in enumerate(lines) if _MARK.match(line)]
    first = next((k for k, line in enumerate(lines) if line.strip()), None)
    if not starts or starts[0] != first:
        return None
    headers, blocks, widths = [], [], []
    seen = {}
    for start, end in zip(starts, starts[1:] + [len(lines)]):  # loop over data sets
        # The header ends where the samples start: six lines (Logger Pro) or five (no short
        # names); the units are the last of them.
        data = next((k for k in range(start + _NAMES_LINES, min(end, start + _HEADER_LINES + 1))
                     if _is_sample(lines[k])), start + _HEADER_LINES)
        head = lines[start:data]
        if len(head) <= _NAMES_LINES:
            return None
        name = _label(head[2]) or f"Data Set {len(blocks) + 1}"
        seen[name] = seen.get(name, 0) + 1
        if seen[name] > 1:  # two data sets of one name stay apart
            name = f"{name} {seen[name]}"
        long_names = [long.strip().strip('"') for long in head[3].rstrip("\r\n").split("\t")]
        units = head[-1].rstrip("\r\n").split("\t")
        width = len(long_names)
        units += [""] * (width - len(units))
        headers += [f"{name}: {long.strip() or f'column {j + 1}'}"
                    + (f" ({unit.strip()})" if unit.strip() else "")
                    for j, (long, unit) in enumerate(zip(long_names, units))]
        rows = [line.rstrip("\r\n").split("\t") for line in lines[data:end] if line.strip()]
        if end < len(lines) and len(rows) > 1 and _all_zero(rows[-1]):
            rows = rows[:-1]  # the row of zeros that may end a data set before the next [8]_
        blocks.append([(row + [""] * width)[:width] for row in rows])
        widths.append(width)
    length = max(len(block) for block in blocks)
    body = []
    for k in range(length):  # loop over output rows
        cells = []
        for block, width in zip(blocks, widths):
            cells += block[k] if k < len(block) else [""] * width
        body.append("\t".join(cells))
    return "\n".join(["\t".join(headers)] + body)
