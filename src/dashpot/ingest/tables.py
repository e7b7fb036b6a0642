"""Readers of tabular lab files: phyphox exports, impact-time lists, motion sensors, video
trackers, photogates.

This module gathers them; each lives in a module of its own — :mod:`.phyphox`,
:mod:`.timestamps` (time lists and dashpot's own impact table), :mod:`.motion` (PASCO Capstone,
Vernier, Tracker), :mod:`.photogate` — over the conventions of :mod:`._tabular` (loading,
headers, units, numbers, runs, the impact frame, sniffing).

Every reader returns the impact table of :mod:`dashpot.ingest` (one row per impact, SI units,
sorted by time) with ``attrs`` ``source``, ``sensor`` (the kind, as :func:`sniff_table` names
it) and ``notes``. Files that cannot be used raise :class:`dashpot.errors.InputError` naming the
file, the 1-based data row (counted after the header) where that applies, and the problem.

Text tables are sniffed, not configured: the separator is the one of tab, semicolon or comma
(else a space, as Tracker may delimit its export) that splits the first lines into the same
number (> 1) of fields, and the decimal mark is a
comma when the separator is not and numbers like ``1,25`` occur (also inside quoted fields of a
comma-separated file, and in a header-less single column, where ``1,234568`` is one number).
A first line that is a single word above a separated header names a Tracker track
(``mass_A``) and is skipped; other title lines (no number among their fields) above a header
are skipped, noted. Vernier's text format (``Vernier Format 2``: six header lines per data
set) is read data set by data set (:mod:`.vernier`); separators ending every line add no
column; Audacity's label export (start, end, text; no header; a label's frequency range on
a line of its own below it is skipped; or SubRip/WebVTT cues) is a list of impact times.
Workbooks —
Excel ``.xlsx``, legacy Excel 97-2003 ``.xls`` (BIFF8, phyphox's "Excel" export) and
OpenDocument ``.ods`` — are read sheet by sheet through pandas' calamine engine, and zip
archives (phyphox's CSV export) member by member.

Column headers are read in the exporting program's own words: a name, a unit in parentheses or
brackets, and a run label either in front (Vernier: ``Latest: Time (s)``, ``Run 2: Position
(m)``, ``Data Set 1:Time(s)``) or behind (PASCO Capstone: ``Time (s) Run #1``; a wired
sensor's interface channel, ``Position, Ch 1&2 (m) Run #1``, is not part of the name).
Tracker writes bare names (``t``, ``x``, ``y``) in its calibrated units (s and, usually, m).


The formats' sources are cited in the module of each reader.
"""

from ._tabular import TABLE_KINDS, sniff_table
from .motion import read_motion_sensor
from .photogate import read_photogate
from .phyphox import PHYPHOX_AUDIO_RATE, read_phyphox
from .timestamps import is_impact_table, read_impact_table, read_timestamps

__all__ = ["read_phyphox", "read_timestamps", "read_motion_sensor", "read_photogate",
           "read_impact_table", "is_impact_table", "sniff_table", "TABLE_KINDS",
           "PHYPHOX_AUDIO_RATE"]
