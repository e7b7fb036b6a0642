"""Synthetic lab tables with known truth: phyphox exports, time lists, motion sensors, photogates.

Each writer takes impact times (or a whole :class:`dashpot.BounceSequence`) with known
parameters, writes the kind of file a lab would get from phyphox, a PASCO or Vernier motion
sensor or a photogate, and returns the truth it used as a dict of plain numbers and lists (so
another tool can store it beside the file). Files are written atomically (a temporary name in
the same directory, then renamed: :func:`dashpot.atomic.atomic_path`), replace an existing
file only with ``overwrite=True``, and are byte-for-byte the same for the same arguments and
seed.

The cart of the motion-sensor and photogate writers moves along an incline that ends at the
bumper: free motion with constant acceleration g_eff = g·sin θ toward the bumper between
contacts [2]_, exactly the flights of the sequence (rebound speed u leaves the bumper, lands
again after 2u/g_eff). During a contact of duration τc the cart's position is a smooth stand-in
for the bumper's compression: the cubic Hermite curve that leaves the bumper at the impact
speed and returns to it at the rebound speed (its depth, τc·(v + u)/8, is of the right order;
readers are expected not to use contact samples). The last impact of the sequence ends with
the cart resting against the bumper (its rebound is not simulated: real trains end in ever
smaller bounces that no sensor resolves).

References
----------
.. [1] phyphox experiment definitions ``acoustic_stopwatch.phyphox``,
   ``inelastic_collision.phyphox`` and phyphox-android ``DataExport.java`` (see
   :mod:`dashpot.ingest.tables`): export sets, column names, number format ``0.000000000E0``,
   separators, NaN padding, one Excel sheet per set plus metadata sheets.
.. [2] D. Halliday, R. Resnick and J. Walker, "Fundamentals of Physics", ch. 2: motion with
   constant acceleration.
.. [3] A. Savitzky and M. J. E. Golay, "Smoothing and differentiation of data by simplified
   least squares procedures", Anal. Chem. 36, 1627-1639 (1964): the smoothed derivative used
   for the Vernier-style velocity column.
.. [4] ECMA-376 Office Open XML, Part 1, §18 (SpreadsheetML): the minimal workbook parts
   written by the Excel variant.
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np
from scipy.signal import savgol_filter

from ..atomic import atomic_path

__all__ = ["write_phyphox_stopwatch", "write_phyphox_collision", "write_timestamps",
           "write_motion_sensor", "write_photogate"]

_FIXED_ZIP_TIME = (2000, 1, 1, 0, 0, 0)  # zip entry dates, fixed so that output is reproducible
_PHYPHOX_STOPS = 5  # the stock Acoustic Stopwatch keeps a start and five stops
_PHYPHOX_BOUNCES = 6  # the (In)elastic collision experiment keeps bounces 0 … 5


# ---------------------------------------------------------------------------------------------
# Output helpers
# ---------------------------------------------------------------------------------------------

def _atomic_write(path, data, overwrite):
    """Write bytes to `path` through a unique temporary name beside it, then rename it (over
    an existing `path` only with `overwrite`)."""
    with atomic_path(path, overwrite=overwrite) as temporary:
        temporary.write_bytes(data)


def _check_times(name, values, *, min_size=1):
    array = np.atleast_1d(np.asarray(values, dtype=float))
    if array.ndim != 1 or array.size < min_size:
        raise ValueError(f"{name} must be a 1-D sequence of at least {min_size} time(s)")
    if not np.all(np.isfinite(array)) or np.any(array < 0) or np.any(np.diff(array) <= 0):
        raise ValueError(f"{name} must be finite, >= 0 and strictly increasing; got {values!r}")
    return array


def _check_format(delimiter, decimal):
    if delimiter not in (",", ";", "\t"):
        raise ValueError(f"delimiter must be ',', ';' or '\\t'; got {delimiter!r}")
    if decimal not in (".", ","):
        raise ValueError(f"decimal must be '.' or ','; got {decimal!r}")
    if delimiter == "," and decimal == ",":
        raise ValueError("a comma cannot be both the delimiter and the decimal mark")


def _fixed(values, decimals, decimal):
    """Numbers as fixed-point strings ('' for NaN), with the chosen decimal mark."""
    values = np.asarray(values, dtype=float)
    text = np.char.mod(f"%.{decimals}f", np.where(np.isfinite(values), values, 0.0))
    text = np.where(np.isfinite(values), text, "")
    return np.char.replace(text, ".", decimal) if decimal != "." else text


def _phyphox_number(values, decimal):
    """phyphox's number format: Java DecimalFormat '0.000000000E0', 'NaN' for missing [1]_."""
    values = np.asarray(values, dtype=float)
    finite = np.isfinite(values) & (values != 0)
    magnitude = np.abs(np.where(finite, values, 1.0))
    exponent = np.floor(np.log10(magnitude)).astype(int)
    mantissa = np.round(np.where(finite, values, 0.0) / 10.0 ** exponent, 9)
    carry = np.abs(mantissa) >= 10.0  # 9.9999999996 rounds up to the next decade
    mantissa = np.where(carry, mantissa / 10.0, mantissa)
    exponent = np.where(carry, exponent + 1, np.where(finite, exponent, 0))
    text = np.char.add(np.char.add(np.char.mod("%.9f", mantissa), "E"), exponent.astype(str))
    text = np.where(np.isnan(values), "NaN", text)
    return np.char.replace(text, ".", decimal) if decimal != "." else text


def _csv_bytes(headers, columns, delimiter, *, quote_headers=False):
    """A text table from column headers and string columns of possibly different lengths."""
    rows = max(len(c) for c in columns)
    grid = np.full((rows, len(columns)), "", dtype=object)
    for j, column in enumerate(columns):  # loop over columns
        grid[: len(column), j] = column
    head = [f'"{h}"' if quote_headers else h for h in headers]
    lines = np.array([delimiter.join(head)] + [""] * rows, dtype=object)
    if rows:
        # Join each row's cells: a column-wise accumulation, no loop over rows.
        joined = grid[:, 0].astype(str)
        for j in range(1, grid.shape[1]):  # loop over columns
            joined = np.char.add(np.char.add(joined, delimiter), grid[:, j].astype(str))
        lines[1:] = joined
    return ("\n".join(lines.tolist()) + "\n").encode("utf-8")


def _column_letters(count):
    letters = []
    for j in range(count):  # loop over columns
        name, k = "", j
        while True:
            name = chr(ord("A") + k % 26) + name
            k = k // 26 - 1
            if k < 0:
                break
        letters.append(name)
    return np.array(letters)


def _escape(text):
    text = np.char.replace(np.asarray(text, dtype=str), "&", "&amp;")
    return np.char.replace(np.char.replace(text, "<", "&lt;"), ">", "&gt;")


def _sheet_xml(headers, body):
    """SpreadsheetML of one sheet: a header row of strings over a body of numbers or strings.

    A float body is written as numbers (NaN as the string 'NaN', as phyphox does [1]_); any
    other body as strings.
    """
    body = np.asarray(body)
    rows, cols = body.shape
    letters = _column_letters(max(cols, len(headers)))

    def cells(refs, text, numeric):
        opening = np.char.add(np.char.add('<c r="', refs),
                              '"><v>' if numeric else '" t="inlineStr"><is><t>')
        return np.char.add(np.char.add(opening, text), "</v></c>" if numeric else "</t></is></c>")

    head = cells(np.char.add(letters[: len(headers)], "1"), _escape(headers), numeric=False)
    head_xml = '<row r="1">' + "".join(head.tolist()) + "</row>"
    body_xml = ""
    if rows:
        refs = np.char.add(letters[None, :cols], np.arange(2, rows + 2).astype(str)[:, None])
        if body.dtype.kind == "f":
            finite = np.isfinite(body)
            grid = np.where(finite, cells(refs, np.char.mod("%.17g", np.where(finite, body, 0.0)),
                                          numeric=True),
                            cells(refs, np.full(body.shape, "NaN"), numeric=False))
        else:
            grid = cells(refs, _escape(body.astype(str)), numeric=False)
        grid = grid.astype(object)
        opening = np.char.add(np.char.add('<row r="', np.arange(2, rows + 2).astype(str)), '">')
        grid[:, 0] = np.char.add(opening, grid[:, 0].astype(str))
        grid[:, -1] = np.char.add(grid[:, -1].astype(str), "</row>")
        body_xml = "".join(grid.ravel().tolist())
    return ('<?xml version="1.0" encoding="UTF-8" standalone="yes"?>\n'
            '<worksheet xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main">'
            f"<sheetData>{head_xml}{body_xml}</sheetData></worksheet>")


def _zip_bytes(members):
    """A zip archive of {name: bytes} with fixed dates (reproducible output)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():  # loop over archive members
            info = zipfile.ZipInfo(name, date_time=_FIXED_ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, data)
    return buffer.getvalue()


def _xlsx_bytes(sheets):
    """A minimal .xlsx workbook [4]_ from [(sheet name, headers, 2-D body), …]."""
    ns = "http://schemas.openxmlformats.org/"
    count = len(sheets)
    overrides = "".join(
        f'<Override PartName="/xl/worksheets/sheet{k + 1}.xml" ContentType="application/'
        f'vnd.openxmlformats-officedocument.spreadsheetml.worksheet+xml"/>' for k in range(count))
    members = {
        "[Content_Types].xml": (
            '<?xml version="1.0" encoding="UTF-8" standalone="yes"?>\n'
            f'<Types xmlns="{ns}package/2006/content-types">'
            '<Default Extension="rels" ContentType="application/vnd.openxmlformats-package.'
            'relationships+xml"/><Default Extension="xml" ContentType="application/xml"/>'
            '<Override PartName="/xl/workbook.xml" ContentType="application/vnd.openxmlformats-'
            'officedocument.spreadsheetml.sheet.main+xml"/>'
            '<Override PartName="/xl/styles.xml" ContentType="application/vnd.openxmlformats-'
            f'officedocument.spreadsheetml.styles+xml"/>{overrides}</Types>'),
        "_rels/.rels": (
            '<?xml version="1.0" encoding="UTF-8" standalone="yes"?>\n'
            f'<Relationships xmlns="{ns}package/2006/relationships"><Relationship Id="rId1" '
            f'Type="{ns}officeDocument/2006/relationships/officeDocument" '
            'Target="xl/workbook.xml"/></Relationships>'),
        "xl/workbook.xml": (
            '<?xml version="1.0" encoding="UTF-8" standalone="yes"?>\n'
            f'<workbook xmlns="{ns}spreadsheetml/2006/main" '
            f'xmlns:r="{ns}officeDocument/2006/relationships"><sheets>'
            + "".join(f'<sheet name="{name}" sheetId="{k + 1}" r:id="rId{k + 1}"/>'
                      for k, (name, _, _) in enumerate(sheets))
            + "</sheets></workbook>"),
        "xl/_rels/workbook.xml.rels": (
            '<?xml version="1.0" encoding="UTF-8" standalone="yes"?>\n'
            f'<Relationships xmlns="{ns}package/2006/relationships">'
            + "".join(f'<Relationship Id="rId{k + 1}" Type="{ns}officeDocument/2006/'
                      f'relationships/worksheet" Target="worksheets/sheet{k + 1}.xml"/>'
                      for k in range(count))
            + f'<Relationship Id="rId{count + 1}" Type="{ns}officeDocument/2006/relationships/'
              'styles" Target="styles.xml"/></Relationships>'),
        "xl/styles.xml": (
            '<?xml version="1.0" encoding="UTF-8" standalone="yes"?>\n'
            f'<styleSheet xmlns="{ns}spreadsheetml/2006/main">'
            '<fonts count="1"><font><sz val="11"/><name val="Calibri"/></font></fonts>'
            '<fills count="1"><fill><patternFill patternType="none"/></fill></fills>'
            '<borders count="1"><border/></borders>'
            '<cellStyleXfs count="1"><xf numFmtId="0" fontId="0" fillId="0" borderId="0"/>'
            '</cellStyleXfs><cellXfs count="1"><xf numFmtId="0" fontId="0" fillId="0" '
            'borderId="0" xfId="0"/></cellXfs><cellStyles count="1"><cellStyle name="Normal" '
            'xfId="0" builtinId="0"/></cellStyles></styleSheet>'),
    }
    for k, (_, headers, body) in enumerate(sheets):  # loop over sheets
        members[f"xl/worksheets/sheet{k + 1}.xml"] = _sheet_xml(headers, body)
    return _zip_bytes({name: text.encode("utf-8") for name, text in members.items()})


# The two metadata tables phyphox adds to full exports [1]_ (content illustrative, fixed).
_PHYPHOX_DEVICE = [("version", "1.2.0"), ("build", "1020003"), ("fileFormat", "1.19"),
                   ("deviceModel", "synthetic"), ("deviceBrand", "dashpot")]
_PHYPHOX_TIME = [("START", 0.0, 946684800.0, "2000-01-01 00:00:00.000 UTC+00:00")]


def _write_phyphox(path, sets, *, delimiter, decimal, excel, zipped, overwrite):
    """Write phyphox export sets [(name, headers, 2-D float body)] in the chosen variant [1]_."""
    device, time = _PHYPHOX_DEVICE, _PHYPHOX_TIME
    if excel:
        sheets = [(name, headers, np.asarray(body, dtype=float)) for name, headers, body in sets]
        sheets.append(("Metadata Device", ["property", "value"], np.array(device, dtype=str)))
        sheets.append(("Metadata Time", ["event", "experiment time", "system time",
                                         "system time text"], np.array(time, dtype=str)))
        _atomic_write(path, _xlsx_bytes(sheets), overwrite)
        return

    def csv_of(headers, body):
        columns = [_phyphox_number(body[:, j], decimal) for j in range(body.shape[1])]
        return _csv_bytes(headers, columns, delimiter, quote_headers=True)

    if not zipped:  # phyphox's "minimalistic" export: one set, one CSV
        name, headers, body = sets[-1]
        _atomic_write(path, csv_of(headers, body), overwrite)
        return
    members = {f"{name}.csv": csv_of(headers, body) for name, headers, body in sets}
    members["meta/device.csv"] = _csv_bytes(
        ["property", "value"], [np.array([d[0] for d in device]), np.array([d[1] for d in device])],
        delimiter, quote_headers=True)
    members["meta/time.csv"] = _csv_bytes(
        ["event", "experiment time", "system time", "system time text"],
        [np.array([time[0][0]]), _phyphox_number([time[0][1]], decimal),
         _fixed([time[0][2]], 3, decimal), np.array([time[0][3]])], delimiter, quote_headers=True)
    _atomic_write(path, _zip_bytes(members), overwrite)


def _audio_grid(impact_times, start_delay, sample_rate):
    """Times from the recording start, on phyphox's audio-sample grid (it times by index)."""
    return np.round((impact_times + start_delay) * sample_rate) / sample_rate


# ---------------------------------------------------------------------------------------------
# phyphox
# ---------------------------------------------------------------------------------------------

def write_phyphox_stopwatch(path, impact_times, *, layout="clicks", delimiter=",", decimal=".",
                            excel=False, zipped=False, start_delay=0.5, sample_rate=48000.0,
                            overwrite=False):
    """Write a phyphox Acoustic Stopwatch export of clicks at the impact times.

    Parameters
    ----------
    path : str or os.PathLike
        Destination (.csv, .zip or .xlsx as chosen below).
    impact_times : array_like
        Impact times in s (strictly increasing, >= 0), e.g. ``BounceSequence.impact_times``.
    layout : {"clicks", "multiple"}, default "clicks"
        "clicks": one row per click, ``Event time (s)`` and ``Interval (s)`` (time to the
        next click; the shorter interval column is padded with NaN at its end, as phyphox pads
        shorter buffers). "multiple": the stock experiment's sets "Simple" (``Start (s)``,
        ``Stop (s)``, ``Difference (s)``) and "Multiple" (``Start (s)``, ``Stop 1 (s)`` …
        ``Stop 5 (s)``): only the first six clicks fit; stops never triggered hold 0.
    delimiter : {",", ";", "\\t"}, default ","
        CSV separator (phyphox offers comma, tab and semicolon).
    decimal : {".", ","}, default "."
        Decimal mark (phyphox offers a comma with tab or semicolon).
    excel : bool, default False
        Write an Excel workbook instead: one sheet per set plus "Metadata Device" and
        "Metadata Time" sheets.
    zipped : bool, default False
        Write phyphox's full CSV export instead: a zip with one CSV per set and ``meta/``.
    start_delay : float, default 0.5
        Time in s from the start of the recording to t = 0 of `impact_times`.
    sample_rate : float, default 48000
        Audio rate in Hz; phyphox times a click by a sample index, so the written times lie
        on this grid.
    overwrite : bool, default False
        Replace `path` if it exists; without it an existing `path` is refused
        (:class:`~dashpot.errors.InputError`, "<path>: exists; pass overwrite=True to replace
        it") and left as it was.

    Returns
    -------
    dict
        ``impact_times`` (s, as written: shifted by `start_delay` and on the sample grid, only
        those that fit the layout), ``layout``, ``sample_rate``, ``start_delay``, ``format``.
    """
    times = _check_times("impact_times", impact_times)
    _check_format(delimiter, decimal)
    if layout not in ("clicks", "multiple"):
        raise ValueError(f"layout must be 'clicks' or 'multiple'; got {layout!r}")
    written = _audio_grid(times, float(start_delay), float(sample_rate))
    if layout == "clicks":
        intervals = np.concatenate([np.diff(written), [np.nan]])
        sets = [("Clicks", ["Event time (s)", "Interval (s)"],
                 np.column_stack([written, intervals]))]
    else:
        written = written[: _PHYPHOX_STOPS + 1]
        slots = np.zeros(_PHYPHOX_STOPS + 1)
        slots[: written.size] = written
        stop = slots[1]
        simple = np.array([[slots[0], stop, stop - slots[0] if stop > 0 else 0.0]])
        sets = [("Simple", ["Start (s)", "Stop (s)", "Difference (s)"], simple),
                ("Multiple", ["Start (s)"] + [f"Stop {k} (s)" for k in range(1, 6)],
                 slots[None, :])]
    _write_phyphox(path, sets, delimiter=delimiter, decimal=decimal, excel=excel, zipped=zipped,
                   overwrite=overwrite)
    return {"kind": "phyphox", "experiment": "Acoustic Stopwatch", "layout": layout,
            "impact_times": written.tolist(), "sample_rate": float(sample_rate),
            "start_delay": float(start_delay),
            "format": "xlsx" if excel else ("zip" if zipped else "csv"),
            "delimiter": delimiter, "decimal": decimal}


def write_phyphox_collision(path, impact_times, *, g=9.81, delimiter=",", decimal=".",
                            excel=False, zipped=False, start_delay=0.5, sample_rate=48000.0,
                            export_delay=1.0, overwrite=False):
    """Write a phyphox (In)elastic collision export ("Energy" set) for the first six impacts.

    Parameters
    ----------
    path : str or os.PathLike
        Destination.
    impact_times : array_like
        Impact times in s, at least two; only the first six fit the experiment.
    g : float, default 9.81
        Gravitational acceleration in m/s² used for the heights (phyphox hard-codes 9.81).
    delimiter, decimal, excel, zipped, start_delay, sample_rate, overwrite
        As for :func:`write_phyphox_stopwatch`.
    export_delay : float, default 1.0
        Time in s from the last impact to the export. phyphox computes the height of the first
        bounce it has not heard from the time of export, so that height is meaningless.

    Returns
    -------
    dict
        ``impact_times`` (s, as written), ``heights`` (m, h_1 … h_5 as written), ``g``,
        ``sample_rate``, ``start_delay``, ``format``.

    Notes
    -----
    The experiment's analysis [1]_, replayed: t_i the bounce times (0 while not heard),
    t_i,eff = t_i or the export time, Δt_i = t_i,eff − t_{i−1},eff, h_i = (g/8)·Δt_i²,
    E_i = Δt_i²/Δt_1² (E_1 = 1) and "Height 0" = h_1/E_2.
    """
    times = _check_times("impact_times", impact_times, min_size=2)
    _check_format(delimiter, decimal)
    written = _audio_grid(times, float(start_delay), float(sample_rate))[:_PHYPHOX_BOUNCES]
    slots = np.zeros(_PHYPHOX_BOUNCES)
    slots[: written.size] = written
    export_time = written[-1] + float(export_delay)
    effective = np.where(slots > 0, slots, export_time)
    steps = np.diff(effective)
    heights = g / 8.0 * steps ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        energy = steps ** 2 / steps[0] ** 2
    height0 = heights[0] / energy[1]
    headers, values = ["Bounce 0 (s)", "Height 0 (m)"], [slots[0], height0]
    for i in range(1, _PHYPHOX_BOUNCES):  # the six bounces of the experiment
        headers += [f"Bounce {i} (s)", f"Height {i} (m)", f"Energy {i}"]
        values += [slots[i], heights[i - 1], energy[i - 1]]
    _write_phyphox(path, [("Energy", headers, np.array([values]))], delimiter=delimiter,
                   decimal=decimal, excel=excel, zipped=zipped, overwrite=overwrite)
    return {"kind": "phyphox", "experiment": "(In)elastic collision",
            "impact_times": written.tolist(), "heights": heights.tolist(), "g": float(g),
            "sample_rate": float(sample_rate), "start_delay": float(start_delay),
            "format": "xlsx" if excel else ("zip" if zipped else "csv"),
            "delimiter": delimiter, "decimal": decimal}


# ---------------------------------------------------------------------------------------------
# Plain list of impact times
# ---------------------------------------------------------------------------------------------

def write_timestamps(path, impact_times, *, unit="s", uncertainty=None, scatter=False, seed=0,
                     start_delay=0.0, declare_unit=True, decimals=None, delimiter=",",
                     decimal=".", overwrite=False):
    """Write a one-column list of impact times (optionally with uncertainties).

    With ``scatter=True`` the written times are the true ones plus independent Gaussian
    errors of the stated `uncertainty` (the column then tells the truth about the times'
    scatter, as a fit assumes); without it they are the true times rounded to the written
    digits and the column only declares an uncertainty.

    Parameters
    ----------
    path : str or os.PathLike
        Destination text file.
    impact_times : array_like
        Impact times in s (strictly increasing, >= 0).
    unit : {"s", "ms"}, default "s"
        Unit of the written numbers.
    uncertainty : float or array_like, optional
        1σ uncertainty of each time in s; adds an ``uncertainty`` column in `unit`.
    scatter : bool, default False
        Draw each written time from N(true time, `uncertainty`²) (needs `uncertainty`); the
        draws are sorted back into order only if they cross, which at σ far below the flight
        times they never do.
    seed : int, default 0
        Seed of the draws (numpy's default generator), for reproducible files.
    start_delay : float, default 0
        Time in s from the clock's zero to the first impact: added to every time. With
        `scatter` it must exceed 6σ, so that no drawn time is negative (a list of times
        starting exactly at the first impact would lose half its first draws).
    declare_unit : bool, default True
        Put the unit in the header (``time (ms)``); False writes a bare ``time`` header.
    decimals : int, optional
        Digits after the decimal mark; default 6 for s and 3 for ms (1 µs).
    delimiter, decimal
        Separator and decimal mark, as for :func:`write_phyphox_stopwatch`.
    overwrite : bool, default False
        Replace `path` if it exists; without it an existing `path` is refused
        (:class:`~dashpot.errors.InputError`, "<path>: exists; pass overwrite=True to replace
        it") and left as it was.

    Returns
    -------
    dict
        ``impact_times`` in s as written (rounded; on the file's clock, `start_delay` after
        the true times), ``resolution`` (s, one unit of the last digit), ``unit``,
        ``uncertainty`` (s or None), ``scatter`` (bool), ``seed`` and ``start_delay`` (s).
    """
    times = _check_times("impact_times", impact_times)
    _check_format(delimiter, decimal)
    if unit not in ("s", "ms"):
        raise ValueError(f"unit must be 's' or 'ms'; got {unit!r}")
    scale = 1.0 if unit == "s" else 1e3
    decimals = (6 if unit == "s" else 3) if decimals is None else int(decimals)
    sigma = None
    if uncertainty is not None:
        sigma = np.broadcast_to(np.asarray(uncertainty, dtype=float), times.shape)
        if not np.all(np.isfinite(sigma)) or np.any(sigma < 0):
            raise ValueError("uncertainty must be finite and >= 0")
    start_delay = float(start_delay)
    if not np.isfinite(start_delay) or start_delay < 0:
        raise ValueError(f"start_delay must be finite and >= 0; got {start_delay!r}")
    times = times + start_delay
    if scatter:
        if sigma is None:
            raise ValueError("scatter needs the uncertainty the times scatter with")
        if start_delay <= 6.0 * np.max(sigma):
            raise ValueError(f"with scatter, start_delay must exceed 6 sigma "
                             f"({6.0 * np.max(sigma):g} s) so that no time is negative")
        times = np.sort(times + sigma * np.random.default_rng(seed).standard_normal(times.size))
    values = np.round(times * scale, decimals)
    headers = [f"time ({unit})" if declare_unit else "time"]
    columns = [_fixed(values, decimals, decimal)]
    if sigma is not None:
        headers.append(f"uncertainty ({unit})" if declare_unit else "uncertainty")
        columns.append(_fixed(sigma * scale, decimals + 1, decimal))
    _atomic_write(path, _csv_bytes(headers, columns, delimiter), overwrite)
    return {"kind": "timestamps", "impact_times": (values / scale).tolist(),
            "resolution": 10.0 ** -decimals / scale, "unit": unit,
            "uncertainty": None if sigma is None else np.asarray(sigma).tolist(),
            "scatter": bool(scatter), "seed": int(seed), "start_delay": start_delay}


# ---------------------------------------------------------------------------------------------
# Cart on an incline: the true motion
# ---------------------------------------------------------------------------------------------

class _Cart:
    """Distance s(t) ≥ 0 of a cart from the bumper (negative: bumper compressed), in m.

    Built from a bounce sequence; t = 0 is the sequence's first impact. Before it the cart is
    held at rest at the release height, released at −v0/g_eff, and slides down.
    """

    def __init__(self, sequence, g_eff):
        times = np.asarray(sequence.impact_times, dtype=float)
        speeds = np.asarray(sequence.impact_speeds, dtype=float)
        contacts = np.asarray(sequence.contact_durations, dtype=float)
        if times.size == 0 or np.any(~np.isfinite(times)) or np.any(speeds <= 0):
            raise ValueError("sequence must hold at least one impact with positive speed")
        flights = np.asarray(sequence.flight_times, dtype=float)
        if g_eff is None:
            if flights.size == 0:
                raise ValueError("a single-impact sequence does not tell g_eff; pass g_eff")
            estimates = 2.0 * speeds[1:] / flights  # each flight lasts 2u/g_eff
            g_eff = float(np.median(estimates))
            if np.ptp(estimates) > 1e-6 * g_eff:
                raise ValueError("the sequence's flights disagree on g_eff; pass g_eff")
        self.g = float(g_eff)
        if not np.isfinite(self.g) or self.g <= 0:
            raise ValueError(f"g_eff must be > 0; got {g_eff!r}")
        self.times = times
        self.speeds = speeds
        # Rebound speed of impact n is the next impact speed; the last impact ends at rest.
        self.rebounds = np.concatenate([speeds[1:], [0.0]])
        finite = contacts[np.isfinite(contacts)]
        settle = float(np.median(finite)) if finite.size else 0.1
        # A captured last impact has an infinite contact; the cart settles in a typical one.
        self.contacts = np.where(np.isfinite(contacts), contacts, settle)
        self.release_time = -speeds[0] / self.g
        self.release_height = speeds[0] ** 2 / (2.0 * self.g)
        self.rest_time = times[-1] + self.contacts[-1]

    def distance(self, t):
        """s(t) in m for an array of times in s (sequence clock)."""
        t = np.asarray(t, dtype=float)
        g, times, contacts = self.g, self.times, self.contacts
        # Which impact's contact-and-flight piece each time falls in (-1: before the first).
        piece = np.searchsorted(times, t, side="right") - 1
        k = np.clip(piece, 0, times.size - 1)
        since = t - times[k]
        theta = np.clip(since / contacts[k], 0.0, 1.0)
        # Cubic Hermite stand-in for the compression: s = τc[−v·h10(θ) + u·h11(θ)].
        h10 = theta * (1.0 - theta) ** 2
        h11 = theta ** 2 * (theta - 1.0)
        contact = contacts[k] * (-self.speeds[k] * h10 + self.rebounds[k] * h11)
        flying = since - contacts[k]
        flight = self.rebounds[k] * flying - 0.5 * g * flying ** 2
        before = -t  # time left until the first impact, while sliding down
        descent = self.speeds[0] * before - 0.5 * g * before ** 2
        return np.select(
            [t < self.release_time, piece < 0, since < contacts[k], piece == times.size - 1],
            [self.release_height, descent, contact, 0.0], flight)

    def truth(self, offset):
        """Impact times (file clock, s), speeds (m/s) and contact durations (s) as lists."""
        return {"impact_times": (self.times + offset).tolist(),
                "impact_speeds": self.speeds.tolist(),
                "rebound_speeds": self.rebounds.tolist(),
                "contact_durations": self.contacts.tolist()}


# ---------------------------------------------------------------------------------------------
# Motion sensor
# ---------------------------------------------------------------------------------------------

def write_motion_sensor(path, sequence, *, vendor="pasco", sample_rate=20.0, runs=1,
                        noise=1e-3, bumper_position=1.0, rest_tail=2.0, lead=0.5,
                        sensor_at="top", quantities=("position", "velocity"), g_eff=None,
                        delimiter=",", decimal=".", seed=0, overwrite=False):
    """Write a PASCO Capstone or Vernier motion-sensor export of a cart bouncing on a bumper.

    Parameters
    ----------
    path : str or os.PathLike
        Destination text file.
    sequence : dashpot.BounceSequence
        The true impacts (times from the first impact, speeds in m/s, contact durations in s).
    vendor : {"pasco", "vernier"}, default "pasco"
        Column headers and derivative of that software: PASCO ``Time (s) Run #1``,
        ``Position (m) Run #1``, ``Velocity (m/s) Run #1`` with central-difference velocity;
        Vernier ``Run 1: Time (s)`` … and ``Latest: …`` for the last run, with a 5-point
        Savitzky-Golay derivative [3]_.
    sample_rate : float, default 20
        Sensor rate in Hz.
    runs : int, default 1
        Runs side by side, each with its own noise, lead time and length.
    noise : float, default 1e-3
        1σ position noise in m (white, Gaussian); positions are then rounded to 0.1 mm
        (PASCO) or 1 µm (Vernier).
    bumper_position : float, default 1.0
        Sensor reading in m when the cart touches the bumper.
    rest_tail : float, default 2.0
        Seconds recorded after the last impact, the cart resting against the bumper.
    lead : float, default 0.5
        Seconds from the start of the recording to the release of the cart (held still until
        then); each run adds a random fraction of a sample period to it.
    sensor_at : {"top", "bumper"}, default "top"
        Where the sensor sits: at the top of the incline (readings grow toward the bumper) or
        at the bumper end looking up (readings grow away from it).
    quantities : tuple of {"position", "velocity"}
        Which columns to write besides time.
    g_eff : float, optional
        Acceleration along the incline in m/s²; by default read from the sequence's flights
        (each lasts 2u/g_eff).
    delimiter, decimal
        Separator and decimal mark.
    seed : int, default 0
        Seed of the noise.
    overwrite : bool, default False
        Replace `path` if it exists; without it an existing `path` is refused
        (:class:`~dashpot.errors.InputError`, "<path>: exists; pass overwrite=True to replace
        it") and left as it was.

    Returns
    -------
    dict
        ``g_eff``, ``bumper_position``, ``sensor_at``, ``noise``, ``sample_rate``, ``vendor``
        and ``runs``: per run its ``label``, ``impact_times`` (s, file clock), ``impact_speeds``,
        ``rebound_speeds`` (the last is 0: the cart stays), ``contact_durations``,
        ``release_time``.
    """
    if vendor not in ("pasco", "vernier"):
        raise ValueError(f"vendor must be 'pasco' or 'vernier'; got {vendor!r}")
    if sensor_at not in ("top", "bumper"):
        raise ValueError(f"sensor_at must be 'top' or 'bumper'; got {sensor_at!r}")
    quantities = tuple(quantities)
    if not quantities or not set(quantities) <= {"position", "velocity"}:
        raise ValueError(f"quantities must name 'position' and/or 'velocity'; got {quantities!r}")
    if int(runs) != runs or runs < 1:
        raise ValueError(f"runs must be a positive integer; got {runs!r}")
    if not (np.isfinite(sample_rate) and sample_rate > 0):
        raise ValueError(f"sample_rate must be > 0 Hz; got {sample_rate!r}")
    for name, value in (("noise", noise), ("rest_tail", rest_tail), ("lead", lead)):
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be finite and >= 0; got {value!r}")
    _check_format(delimiter, decimal)
    cart = _Cart(sequence, g_eff)
    rng = np.random.default_rng(seed)
    dt = 1.0 / float(sample_rate)
    side = -1.0 if sensor_at == "top" else 1.0  # reading = bumper_position + side·s
    decimals = 4 if vendor == "pasco" else 6
    headers, columns, truths = [], [], []
    for r in range(int(runs)):  # loop over runs
        label = (f"Run #{r + 1}" if vendor == "pasco" else
                 ("Latest" if r == runs - 1 else f"Run {r + 1}"))
        start = float(lead) + rng.uniform(0.0, dt)  # release time on the file clock
        offset = start - cart.release_time  # file clock minus sequence clock
        end = cart.rest_time + offset + float(rest_tail)
        time = np.arange(0.0, end + 0.5 * dt, dt)
        reading = bumper_position + side * cart.distance(time - offset)
        reading = reading + float(noise) * rng.standard_normal(time.size)
        reading = np.round(reading, decimals)
        if vendor == "pasco":
            velocity = np.gradient(reading, time)
        else:
            velocity = savgol_filter(reading, 5, 2, deriv=1, delta=dt, mode="interp")
        names = {"time": "Time (s)", "position": "Position (m)", "velocity": "Velocity (m/s)"}
        values = {"time": _fixed(time, 4, decimal), "position": _fixed(reading, decimals, decimal),
                  "velocity": _fixed(velocity, decimals, decimal)}
        for quantity in ("time",) + quantities:  # loop over columns
            headers.append(f"{names[quantity]} {label}" if vendor == "pasco"
                           else f"{label}: {names[quantity]}")
            columns.append(values[quantity])
        truth = cart.truth(offset)
        truth.update(label=label, release_time=start)
        truths.append(truth)
    _atomic_write(path, _csv_bytes(headers, columns, delimiter), overwrite)
    return {"kind": "motion_sensor", "vendor": vendor, "g_eff": cart.g,
            "bumper_position": float(bumper_position), "sensor_at": sensor_at,
            "noise": float(noise), "sample_rate": float(sample_rate), "runs": truths}


# ---------------------------------------------------------------------------------------------
# Photogate
# ---------------------------------------------------------------------------------------------

def _gate_blocks(cart, near, far):
    """Blocked intervals (sequence clock) while near <= s <= far, and their kinds.

    Exact crossings of the uniform-acceleration pieces [2]_: sliding down before the first
    impact, and each flight (up, apex, down). A flight whose apex lies between `near` and
    `far` blocks the beam once without the flag passing (kind 'partial').
    """
    g, v0 = cart.g, cart.speeds[0]

    def down_descent(level):  # s = v0·τ − g·τ²/2 with τ the time left to the first impact
        return cart.times[0] - 2.0 * level / (v0 + np.sqrt(v0 ** 2 - 2.0 * g * level))

    if cart.release_height <= far:
        raise ValueError("the cart must be released above the gate (v0²/(2·g_eff) > "
                         "gate_distance + flag_length)")
    starts, ends, kinds = [down_descent(far)], [down_descent(near)], ["toward"]
    u = cart.rebounds[:-1]
    leave = cart.times[:-1] + cart.contacts[:-1]
    apex = u ** 2 / (2.0 * g)
    with np.errstate(invalid="ignore"):
        root_near = np.sqrt(u ** 2 - 2.0 * g * near)
        root_far = np.sqrt(u ** 2 - 2.0 * g * far)
    up_near, down_near = leave + (u - root_near) / g, leave + (u + root_near) / g
    up_far, down_far = leave + (u - root_far) / g, leave + (u + root_far) / g
    full, partial = apex > far, (apex > near) & (apex <= far)
    starts = np.concatenate([starts, up_near[full], down_far[full], up_near[partial]])
    ends = np.concatenate([ends, up_far[full], down_near[full], down_near[partial]])
    kinds = np.concatenate([kinds, np.repeat("away", full.sum()), np.repeat("toward", full.sum()),
                            np.repeat("partial", partial.sum())])
    order = np.argsort(starts, kind="stable")
    return starts[order], ends[order], kinds[order]


def write_photogate(path, sequence, *, flag_length, gate_distance=0.02, vendor="vernier",
                    mode="events", initial_row=True, sample_rate=1000.0, resolution=1e-6,
                    rest_tail=1.0,
                    lead=0.5, g_eff=None, delimiter=",", decimal=".", seed=0, overwrite=False):
    """Write a photogate state log of a cart's flag passing a gate just before the bumper.

    Parameters
    ----------
    path : str or os.PathLike
        Destination text file.
    sequence : dashpot.BounceSequence
        The true impacts.
    flag_length : float
        Length in m of the flag that blocks the beam, > 0.
    gate_distance : float, default 0.02
        Distance in m from the point where the flag leaves the beam to the bumper, > 0.
    vendor : {"vernier", "pasco"}, default "vernier"
        Headers ``Latest: Time (s)``, ``Latest: GateState`` (Vernier's photogate timing) or
        ``Time (s) Run #1``, ``Gate State Run #1`` (a PASCO-style layout).
    mode : {"events", "sampled"}, default "events"
        "events": one row per change of state (plus the initial state at t = 0), as Vernier
        logs a photogate; "sampled": the state every 1/`sample_rate` s.
    initial_row : bool, default True
        Mode "events": begin with a row of the initial (unblocked) state at t = 0; without
        it the log's first row is the first blocking (a log of the changes only).
    sample_rate : float, default 1000
        Hz, for mode "sampled".
    resolution : float, default 1e-6
        Clock resolution in s of the event times (they are rounded to it).
    rest_tail, lead, g_eff, delimiter, decimal
        As for :func:`write_motion_sensor` (the cart rests out of the beam at the end).
    seed : int, default 0
        Seed of the random lead-time fraction.
    overwrite : bool, default False
        Replace `path` if it exists; without it an existing `path` is refused
        (:class:`~dashpot.errors.InputError`, "<path>: exists; pass overwrite=True to replace
        it") and left as it was.

    Returns
    -------
    dict
        ``impact_times`` (s, file clock, contact starts), ``impact_speeds`` and
        ``rebound_speeds`` at the bumper (m/s), ``passages``: start/end times (s), kind
        ("toward", "away", "partial") and mean speed L/τ (m/s) of each blocking, and the
        scene (``flag_length``, ``gate_distance``, ``g_eff``).
    """
    flag_length, gate_distance = float(flag_length), float(gate_distance)
    if not (np.isfinite(flag_length) and flag_length > 0):
        raise ValueError(f"flag_length must be > 0 m; got {flag_length!r}")
    if not (np.isfinite(gate_distance) and gate_distance > 0):
        raise ValueError(f"gate_distance must be > 0 m; got {gate_distance!r}")
    if vendor not in ("vernier", "pasco"):
        raise ValueError(f"vendor must be 'vernier' or 'pasco'; got {vendor!r}")
    if mode not in ("events", "sampled"):
        raise ValueError(f"mode must be 'events' or 'sampled'; got {mode!r}")
    _check_format(delimiter, decimal)
    cart = _Cart(sequence, g_eff)
    rng = np.random.default_rng(seed)
    on, off, kinds = _gate_blocks(cart, gate_distance, gate_distance + flag_length)
    offset = float(lead) + rng.uniform(0.0, 1e-3) - cart.release_time
    on, off = on + offset, off + offset
    end = cart.rest_time + offset + float(rest_tail)
    decimals = max(int(np.ceil(-np.log10(resolution))), 0)
    if mode == "events":
        edges = np.round(np.ravel(np.column_stack([on, off])), decimals)
        time = np.concatenate([[0.0], edges])
        state = np.concatenate([[0], np.tile([1, 0], on.size)])
        if not initial_row:
            time, state = time[1:], state[1:]
    else:
        time = np.arange(0.0, end, 1.0 / float(sample_rate))
        state = (np.searchsorted(np.ravel(np.column_stack([on, off])), time, side="right")
                 % 2).astype(int)
        decimals = max(decimals, 4)
    if vendor == "vernier":
        headers = ["Latest: Time (s)", "Latest: GateState"]
    else:
        headers = ["Time (s) Run #1", "Gate State Run #1"]
    _atomic_write(path, _csv_bytes(headers, [_fixed(time, decimals, decimal),
                                             state.astype(str)], delimiter), overwrite)
    truth = cart.truth(offset)
    truth.update(kind="photogate", flag_length=flag_length, gate_distance=gate_distance,
                 g_eff=cart.g, mode=mode, vendor=vendor,
                 passages={"start": on.tolist(), "end": off.tolist(), "kind": kinds.tolist(),
                           "mean_speed": (flag_length / (off - on)).tolist()})
    return truth
