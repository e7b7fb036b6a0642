"""One HDF5 file per scene: impacts, bounces, every model's fit and the selection table, and
where they were asked for the fits under the noise model and their own selection table.
Where the scene has an air-drag constant the bounce table also holds the drag-corrected ε
(:func:`dashpot.analysis.stored_bounces`).

The layout (``docs/hdf5-layout.md`` lists every item, its unit and its type) uses only
groups, numeric and UTF-8 string datasets and attributes, so plain h5py reads it; every table
is a group with one dataset per column (attribute ``columns`` keeps their order, each dataset a
CF-style attribute ``units``), so ``pandas.DataFrame({c: group[c][()] for c in
group.attrs["columns"]})`` rebuilds it; :func:`read_table` does exactly that. Numbers are
float64 (NaN where unknown), counts int64, flags bool, text UTF-8 strings, whatever types the
tables held in memory. One column of each table is an HDF5 dimension scale that the others are
attached to (the netCDF-4 convention [1]_), so ``xarray.open_dataset(path, engine="h5netcdf",
group="impacts")`` gives a dataset with a named dimension. Files are built in memory, written to a unique
temporary name in the same folder and renamed, so an interrupted run, a full disk or a
concurrent writer never leaves a half-written file; they carry no timestamps other than the
root attribute ``created``: the same inputs give the same numbers bit for bit.

A synthetic scene's file also holds the ``truth`` table (:mod:`dashpot.truth`): each contact
parameter's true value beside the generating model's fit, with its pull.

References
----------
.. [1] Unidata, "NetCDF-4 format: dimensions as HDF5 dimension scales", The NetCDF User's
   Guide, and the CF Conventions 1.11, §3.1 (the ``units`` attribute; ``"1"`` for
   dimensionless numbers).
"""

from __future__ import annotations

import hashlib
import json
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path

import h5py
import numpy as np
import pandas as pd

from . import __version__
from .ingest import FLIGHT_CORRELATION_COLUMN, is_speed_error_column
from .atomic import atomic_path, refuse_existing
from .provenance import source_fingerprint

__all__ = ["write_scene_fit", "read_table", "read_fit", "file_sha256", "atomic_path",
           "write_summary", "csv_header", "FORMAT"]

FORMAT = "dashpot-scene-1"
IMPACT_UNITS = {"time": "s", "time_uncertainty": "s", "amplitude": "1", "impact_speed": "m/s",
                "rebound_speed": "m/s", "speed_uncertainty": "m/s", "run": "1", "flag": "1"}
BOUNCE_UNITS = {"run": "1", "bounce": "1", "start_time": "s", "interval": "s",
                "interval_uncertainty": "s", "rebound_speed": "m/s",
                "rebound_speed_uncertainty": "m/s", "restitution": "1",
                "restitution_uncertainty": "1", "flag": "1", "restitution_flag": "1",
                # Where the scene has a drag constant (dashpot.analysis.stored_bounces).
                "launch_speed": "m/s", "launch_speed_uncertainty": "m/s",
                "landing_speed": "m/s", "landing_speed_uncertainty": "m/s",
                "restitution_corrected": "1", "restitution_corrected_uncertainty": "1",
                "restitution_corrected_drag_uncertainty": "1"}
# Attributes of a bounce table corrected for air drag: what corrected it.
BOUNCE_DRAG_ATTRIBUTES = ("drag_constant", "drag_constant_uncertainty", "effective_gravity",
                          "drag_source", "drag_note")
# Why a column of the impact or bounce table holds NaN, for its dataset's attribute `note`
# (given only where it holds NaN): (the text where every value is, the text where some are).
_SPEED_NOT_MEASURED = (
    "all NaN: the recording gives impact times only, no speeds (an audio recording, a "
    "stopwatch or a table of times)",
    "NaN where the speed was not measured (a motion sensor: no free flight fitted on that "
    "side of the impact)")
IMPACT_NAN_NOTES = {
    "time_uncertainty": ("all NaN: the recording states no timing error",
                         "NaN where the recording states no timing error"),
    "amplitude": ("all NaN: the recording gives no loudness of its impacts (measured in audio "
                  "recordings only)", "NaN where the table gives no amplitude"),
    "impact_speed": _SPEED_NOT_MEASURED, "rebound_speed": _SPEED_NOT_MEASURED,
    "speed_uncertainty": _SPEED_NOT_MEASURED,
    FLIGHT_CORRELATION_COLUMN: (
        "all NaN: no two speeds measured on one flight",
        "NaN on each run's last impact (no next flight) and where a speed was not measured"),
}
_SPEED_ERROR_NOT_MEASURED = ("all NaN: no speed measured",
                             "NaN where the speed was not measured")
_NO_NEXT_INTERVAL = "NaN on the last interval of each run: there is no next interval T_{n+1}"
_SIGMA_UNKNOWN = ("all NaN: the impact times' 1σ is unknown",
                  "NaN where an impact time's 1σ is unknown")
BOUNCE_NAN_NOTES = {
    "interval_uncertainty": _SIGMA_UNKNOWN, "rebound_speed_uncertainty": _SIGMA_UNKNOWN,
    "restitution": (_NO_NEXT_INTERVAL,) * 2,
    "restitution_uncertainty": (f"{_NO_NEXT_INTERVAL}; and where an impact time's 1σ is "
                                f"unknown",) * 2,
    "launch_speed": ("NaN where no launch speed gives the flight's duration",) * 2,
    "launch_speed_uncertainty": ("NaN where there is no launch speed, or an impact time's 1σ "
                                 "is unknown",) * 2,
    "landing_speed": ("NaN where there is no launch speed",) * 2,
    "landing_speed_uncertainty": ("NaN where there is no launch speed, or an impact time's 1σ "
                                  "is unknown",) * 2,
    "restitution_corrected": (f"{_NO_NEXT_INTERVAL}; and where there is no launch speed",) * 2,
    "restitution_corrected_uncertainty": (
        f"{_NO_NEXT_INTERVAL}; and where there is no launch speed, an impact time's 1σ is "
        f"unknown or the impact was left out of the fit",) * 2,
    "restitution_corrected_drag_uncertainty": (
        f"{_NO_NEXT_INTERVAL}; and where there is no launch speed",) * 2,
}
SELECTION_UNITS = {"model": "1", "success": "1", "nvarys": "1", "ndata": "1", "chisqr": "1",
                   "redchi": "1", "aic": "1", "bic": "1", "delta_aic": "1", "delta_bic": "1", "delta_qaic": "1",
                   "akaike_weight": "1", "rank": "1"}
SUMMARY_UNITS = {"beta": "1/s", "beta_stderr": "1/s", "k": "N/m", "k_stderr": "N/m",
                 "omega0": "rad/s", "omega0_stderr": "rad/s", "v0": "m/s", "v0_stderr": "m/s",
                 "sigma_j": "s", "beta_truth": "1/s", "omega0_truth": "rad/s",
                 "v0_truth": "m/s"}
IMPACT_DTYPES = {**dict.fromkeys(IMPACT_UNITS, "float64"), "run": "int64", "flag": None}
JOINT_RUN_UNITS = {"run": "1", "v0": "m/s", "v0_stderr": "m/s", "t0": "s", "t0_stderr": "s"}
TRUTH_UNITS = {"truth": "see column 'unit'", "value": "see column 'unit'",
               "stderr": "see column 'unit'", "low95": "see column 'unit'",
               "high95": "see column 'unit'"}
# netCDF's marker of a dimension scale that is no variable (the name of the HDF5 scale).
_NETCDF_DIMENSION = "This is a netCDF dimension but not a netCDF variable"
# The column of each table that is its dimension scale (its coordinate for xarray).
TABLE_SCALES = {"impacts": "time", "bounces": "bounce", "selection": "model",
                "noise_selection": "model", "parameters": "name", "intervals": "method",
                "truth": "parameter", "summary": "scene", "runs": "run"}
INTERVAL_COLUMNS = ("low68", "high68", "low95", "high95", "cpu_seconds", "samples",
                    "autocorrelation_steps", "converged")
NOISE_SELECTION_UNITS = {**SELECTION_UNITS, "sigma_j": "s"}
PREDICTED_UNITS = {"times": "s", "speeds": "m/s", "restitution": "1",
                   "contact_durations": "s", "at_data": "s"}


def file_sha256(path):
    """SHA-256 hex digest of a file's bytes, read in blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


@contextmanager
def _new_hdf5(path, *, overwrite, **options):
    """Yield a new HDF5 file built in memory; write it to `path` atomically when done
    (replacing an existing `path` only with `overwrite`, see :func:`atomic_path`).

    HDF5 that fails to write (a full disk) cannot close its objects, and its own exit handler
    then crashes the process (SIGSEGV in H5_term_library): so the file is built in memory
    (core driver, no backing store; the same bytes as a file on disk) and written with one
    plain write, whose failure is an ordinary OSError. `options` go to :class:`h5py.File`.
    """
    with atomic_path(path, overwrite=overwrite) as temporary:
        # Named after the unique temporary (no file of that name is opened) so that two
        # files built at once in one process never share a name.
        with h5py.File(f"{temporary}.image", "w", driver="core", backing_store=False,
                       **options) as out:
            yield out
            out.flush()
            image = out.id.get_file_image()
        temporary.write_bytes(image)


def _is_number(value):
    return (value is None or isinstance(value, (int, float, np.integer, np.floating))) \
        and not isinstance(value, (bool, np.bool_))


def _typed(values, dtype=None):
    """`values` as the array to store: `dtype` if given, else float64 for an object column
    that holds only numbers and missing values (a column of None and NaN is numeric, never
    the text "nan"), bool for one of booleans only, strings for other object columns, anything
    else as it is."""
    values = np.asarray(values)
    if dtype is not None:
        return values.astype(dtype) if dtype != "float64" else pd.to_numeric(
            pd.Series(values.ravel()), errors="raise").to_numpy(np.float64).reshape(values.shape)
    if values.dtype.kind == "O" and values.size and all(map(_is_number, values.ravel())):
        return np.array([np.nan if v is None else v for v in values.ravel()],
                        dtype=np.float64).reshape(values.shape)
    if values.dtype.kind == "O" and values.size and all(
            isinstance(v, (bool, np.bool_)) for v in values.ravel()):
        return values.astype(bool)
    return values


def _dataset(group, name, values, unit, dtype=None):
    values = _typed(values, dtype)
    if values.dtype.kind in "OUS":
        # Missing text (None, NaN) is the empty string, not "None" or "nan".
        values = np.asarray(["" if v is None or (isinstance(v, float) and np.isnan(v))
                             else str(v) for v in values.ravel()],
                            dtype=object).reshape(values.shape)
        dataset = group.create_dataset(name, data=values, dtype=h5py.string_dtype(),
                                       track_times=False)
    else:
        dataset = group.create_dataset(name, data=values, track_times=False)
    dataset.attrs["units"] = unit
    return dataset


def _table(parent, name, table, units, dtypes=None, nan_notes=None):
    """A table group: one dataset per column, in order (`dtypes`: column -> type where the
    column's own would not do); the column ``TABLE_SCALES[name]`` a dimension scale that
    every other column is attached to. A column of `nan_notes` that holds NaN gets the
    attribute ``note`` saying why (:func:`_nan_note`)."""
    group = parent.create_group(name, track_order=True)
    group.attrs["columns"] = list(map(str, table.columns))
    dtypes = dtypes or {}
    # Kept by name: looking a dataset up in its group again costs more than writing it.
    datasets = {str(column): _dataset(group, str(column), table[column].to_numpy(),
                                      units.get(column, "1"), dtypes.get(column))
                for column in table.columns}
    for column, reasons in (nan_notes or {}).items():
        note = _nan_note(table[column].to_numpy(), reasons) if column in table else ""
        if note:
            datasets[column].attrs["note"] = note
    scale = datasets.get(TABLE_SCALES.get(name))
    if scale is not None:
        scale.make_scale(TABLE_SCALES[name])
        for column, dataset in datasets.items():
            if column != TABLE_SCALES[name]:
                dataset.dims[0].attach_scale(scale)
    return group


def _nan_note(values, reasons):
    """Why `values` hold NaN: ``reasons[0]`` where all of them do, ``reasons[1]`` where some
    do, '' where none (or they are no numbers)."""
    values = np.asarray(values)
    if values.dtype.kind != "f":
        return ""
    missing = np.isnan(values)
    if not missing.any():
        return ""
    return reasons[0] if missing.all() else reasons[1]


def _attach(group, dataset):
    """Attach a dataset that is not a listed column to its table's dimension scale."""
    for name in group:
        if group[name].is_scale:
            dataset.dims[0].attach_scale(group[name])


def read_table(group):
    """DataFrame of a table group (columns in their stored order, strings decoded)."""
    columns = {}
    for name in group.attrs["columns"]:
        values = group[name][()]
        if values.dtype.kind == "O":
            values = np.array([v.decode() if isinstance(v, bytes) else v for v in values],
                              dtype=object)
        columns[name] = values
    return pd.DataFrame(columns)


def _write_fit(group, fit):
    group.attrs.update({"success": fit.success, "message": fit.message, "chisqr": fit.chisqr,
                        "redchi": fit.redchi, "aic": fit.aic, "bic": fit.bic,
                        "ndata": fit.ndata, "nvarys": fit.nvarys, "nfev": fit.nfev,
                        "numerical_tolerance": fit.numerical_tolerance,
                        "error_bound": fit.error_bound, "accuracy": fit.accuracy,
                        "varied": json.dumps(list(fit.varied)),
                        "notes": json.dumps(fit.notes)})
    _parameters_and_residuals(group, fit, "every residual of the fit divided by its 1-sigma: "
                              "times, then measured impact and rebound speeds (whitened by "
                              "their covariance where the table states the errors they "
                              "share), then priors")
    _intervals_table(group, fit)
    _eps_curve(group, fit)


def _intervals_table(group, fit):
    """The table of β's intervals by method of a fit (or a joint fit)."""
    # Numbers only (NaN where a method has no such figure; converged as 1 or 0).
    rows = [{"method": method, **{key: float(row.get(key, np.nan)) for key in INTERVAL_COLUMNS}}
            for method, row in fit.intervals.items()]
    _table(group, "intervals", pd.DataFrame(rows, columns=["method", *INTERVAL_COLUMNS]),
           {**{key: "1/s" for key in INTERVAL_COLUMNS[:4]}, "cpu_seconds": "s", "samples": "1",
            "autocorrelation_steps": "1", "converged": "1"})


def _write_noise_fit(group, fit):
    """A fit under the noise model: as a deterministic fit's group, with −2 ln L, σ_ε and σ_j
    (with their intervals) as attributes, the standardized innovations as the normalized
    residuals, the flagged impacts and each impact's timing noise; no intervals table (the
    parameters table holds every interval); the accuracy figures are the filter's step map's."""
    attrs = {"success": fit.success, "message": fit.message, "chisqr": fit.chisqr,
             "redchi": fit.redchi, "aic": fit.aic, "bic": fit.bic,
             "neg2_log_likelihood": fit.neg2_log_likelihood, "ndata": fit.ndata,
             "nvarys": fit.nvarys, "nfev": fit.nfev, "accuracy": fit.accuracy or "",
             "error_bound": fit.error_bound, "numerical_tolerance": fit.numerical_tolerance,
             "varied": json.dumps(list(fit.varied)), "notes": json.dumps(fit.notes)}
    for name in ("sigma_eps", "sigma_j"):
        estimate = fit.estimates.get(name)
        values = ((estimate.value, estimate.low68, estimate.high68, estimate.low95,
                   estimate.high95) if estimate is not None else (np.nan,) * 5)
        attrs[name] = values[0]
        attrs[f"{name}_interval68"] = np.array(values[1:3], dtype=float)
        attrs[f"{name}_interval95"] = np.array(values[3:5], dtype=float)
    group.attrs.update(attrs)
    _parameters_and_residuals(group, fit, "standardized innovation r/sqrt(S) of each impact "
                              "(NaN for the first, which anchors the train): independent "
                              "N(0, 1) under the model")
    _eps_curve(group, fit)
    outliers = _dataset(group, "outliers", np.asarray(fit.outliers, dtype=np.int64), "1")
    outliers.attrs["meaning"] = ("positions in residuals/* of the innovations with |z| > 4 "
                                 "(kept in the fit)")
    timing = _dataset(group, "timing_sigma", np.asarray(fit.timing_sigma, dtype=float), "s")
    timing.attrs["meaning"] = ("total 1-sigma timing noise of each fitted impact, "
                               "sqrt(detector sigma^2 + sigma_j^2)")
    # Each its own dimension (a netCDF coordinate variable), so that xarray opens the tables
    # below this group without inventing dimensions.
    outliers.make_scale("outliers")
    timing.make_scale("timing_sigma")


def _parameters_and_residuals(group, fit, normalized_meaning):
    """The parameters table, correlation, residuals and predicted train of a fit."""
    rows = [{"name": name, "value": e.value, "stderr": e.stderr, "low68": e.low68,
             "high68": e.high68, "low95": e.low95, "high95": e.high95, "unit": e.unit,
             "status": e.status, "note": e.note} for name, e in fit.estimates.items()]
    parameters = pd.DataFrame(rows, columns=["name", "value", "stderr", "low68", "high68",
                                             "low95", "high95", "unit", "status", "note"])
    # A failed fit has no rows: keep the numeric columns numeric (not empty string datasets).
    parameters = parameters.astype({column: float for column in
                                    ("value", "stderr", "low68", "high68", "low95", "high95")})
    table = _table(group, "parameters", parameters, {})
    # Each row has its own unit: the numeric columns carry the row's "unit" column.
    for column in ("value", "stderr", "low68", "high68", "low95", "high95"):
        table[column].attrs["units"] = "see column 'unit'"
    correlation = _dataset(group, "correlation", np.asarray(fit.correlation, dtype=float), "1")
    correlation.attrs["parameters"] = list(fit.varied)
    # Its rows and columns named by the varied parameters, as two dimension scales.
    for axis, name in enumerate(("varied", "varied_with")):
        names = _dataset(group, name, np.asarray(list(fit.varied), dtype=object), "1")
        names.make_scale(name)
        correlation.dims[axis].attach_scale(names)
    residuals = group.create_group("residuals", track_order=True)
    time = _dataset(residuals, "time", fit.time_residuals, "s")
    time.attrs["meaning"] = "observed minus predicted impact time"
    normalized = _dataset(residuals, "normalized", fit.normalized_residuals, "1")
    normalized.attrs["meaning"] = normalized_meaning
    _dimension(residuals, "fitted_impact", [time])
    _dimension(residuals, "residual", [normalized])
    predicted = group.create_group("predicted", track_order=True)
    for name, values in fit.predicted.items():
        _dataset(predicted, name, values, PREDICTED_UNITS[name])
    train = [predicted[name] for name in predicted if name != "at_data"]
    if train and len({dataset.shape for dataset in train}) == 1:
        _dimension(predicted, "impact", train)
    if "at_data" in predicted:
        _dimension(predicted, "fitted_impact", [predicted["at_data"]])


def _dimension(group, name, datasets):
    """A netCDF dimension without a variable [1]_ (an HDF5 dimension scale holding no data,
    named by netCDF's marker) that the 1-D `datasets`, all of one length, are attached to."""
    size = datasets[0].shape[0]
    dimension = group.create_dataset(name, shape=(size,), dtype=np.float64, track_times=False)
    dimension.make_scale(f"{_NETCDF_DIMENSION}.{size:10d}")
    dimension.attrs["units"] = "1"
    for dataset in datasets:
        dataset.dims[0].attach_scale(dimension)
    return dimension


def _eps_curve(group, fit):
    curve = group.create_group("eps_curve", track_order=True)
    for name, unit in (("speed", "m/s"), ("eps", "1"), ("captured", "1")):
        if name in fit.eps_curve:
            _dataset(curve, name, fit.eps_curve[name], unit)
    if "speed" in curve:
        # ε and capture as functions of the impact speed: speed is their coordinate.
        curve["speed"].make_scale("speed")
        for name in ("eps", "captured"):
            if name in curve:
                curve[name].dims[0].attach_scale(curve["speed"])


def write_scene_fit(path, scene_fit, impacts, *, input_path=None, config=None, truth=None,
                    runs=None, overwrite=False):
    """Write one scene's impacts, bounces, fits and selection to an HDF5 file, atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Output file (``.h5``); with `overwrite`, an existing one is replaced only once the
        new file is complete.
    scene_fit : dashpot.fit.SceneFit
    impacts : pandas.DataFrame
        The impact table the fits used (all rows, including any left out).
    input_path : str or os.PathLike, optional
        The recording, whose SHA-256 is stored as provenance.
    config : dict, optional
        Analysis configuration to record.
    truth : pandas.DataFrame, optional
        A synthetic scene's truth against fit (:func:`dashpot.truth.truth_comparison`),
        stored as the table ``truth`` with its attributes ``model`` and ``source``.
    runs : dashpot.fit.RunsFit, optional
        Every run of a multi-run recording fitted (:func:`dashpot.analysis.analyze_runs`):
        with more than one run, each run's bounces, fits and selection go to ``runs/<run>``
        and the joint fits to ``joint/<model>`` (``scene_fit`` is then the first run's, kept
        at the root as in a single-run file); with one run (or None) the file is a
        single-run file, without these groups.
    overwrite : bool, default False
        Replace `path` if it exists. Without it an existing `path` is refused before
        anything is built, and left as it was.

    Raises
    ------
    InputError
        `path` exists and `overwrite` is false ("<path>: exists; pass overwrite=True to
        replace it").
    """
    several = runs is not None and len(runs.runs) > 1
    with _new_hdf5(path, overwrite=overwrite, track_order=True) as out:
        out.attrs["format"] = FORMAT
        out.attrs["dashpot_version"] = __version__
        out.attrs["dashpot_source_sha256"] = source_fingerprint()
        out.attrs["created"] = datetime.now(timezone.utc).isoformat(timespec="seconds")
        out.attrs["scene"] = json.dumps(scene_fit.scene.as_dict(), sort_keys=True)
        out.attrs["config"] = json.dumps(config or {}, sort_keys=True, default=str)
        if input_path is not None:
            out.attrs["input_file"] = Path(input_path).name
            out.attrs["input_sha256"] = file_sha256(input_path)
            recording = scene_fit.scene.recording
            if recording is not None:
                # The scene may name another file (the recording an impact table came from):
                # say which of the two was fitted.
                out.attrs["input_is_scene_recording"] = bool(
                    Path(input_path).resolve() == Path(recording).resolve())
        out.attrs["verdict"] = scene_fit.verdict
        # The speeds' correlated errors where the reader states them (dashpot.ingest).
        errors = [c for c in impacts.columns if is_speed_error_column(c)]
        table = impacts[[c for c in IMPACT_UNITS if c in impacts] + errors].reset_index(
            drop=True)
        group = _table(out, "impacts", table, {
            **IMPACT_UNITS, **{c: "1" if c == FLIGHT_CORRELATION_COLUMN else "m/s"
                               for c in errors}}, IMPACT_DTYPES,
            {**dict.fromkeys(errors, _SPEED_ERROR_NOT_MEASURED), **IMPACT_NAN_NOTES})
        group.attrs["notes"] = json.dumps(list(impacts.attrs.get("notes", [])))
        # data.excluded counts rows of its own run only.
        run = impacts["run"].to_numpy() if "run" in impacts else np.zeros(len(table))
        used = np.zeros(len(table), bool)
        fitted = (runs.runs.items() if several
                  else [(np.min(run) if len(table) else 0, scene_fit)])
        for number, fit in fitted:
            rows = np.flatnonzero(run == number)
            used[rows] = True
            used[rows[fit.data.excluded]] = False
        _attach(group, _dataset(group, "used_in_fit", used, "1"))
        _write_fits(out, scene_fit)
        if truth is not None:
            # Only for a synthetic scene: other files have the layout they always had.
            compared = _table(out, "truth", truth, TRUTH_UNITS)
            compared.attrs["model"] = str(truth.attrs.get("model", ""))
            compared.attrs["source"] = str(truth.attrs.get("source", ""))
        _write_noise_fits(out, scene_fit)
        if several:
            # Only for a multi-run recording: a single-run file has the layout it always had.
            _write_runs(out, runs)



def _write_fits(group, scene_fit):
    """A scene's (or one run's) bounce table, its fits under fits/<model> and its selection."""
    _bounces(group, scene_fit)
    fits = group.create_group("fits")
    for model, fit in scene_fit.results.items():
        _write_fit(fits.create_group(model), fit)
    selection = _table(group, "selection", scene_fit.selection, SELECTION_UNITS)
    selection.attrs["verdict"] = scene_fit.verdict


def _bounces(group, scene_fit):
    """The bounce table, with the drag-corrected ε and what corrected it where the scene has a
    drag constant (:func:`dashpot.analysis.stored_bounces`; a table without it has the layout
    it always had)."""
    from .analysis import stored_bounces

    table = stored_bounces(scene_fit)
    written = _table(group, "bounces", table, BOUNCE_UNITS, nan_notes=BOUNCE_NAN_NOTES)
    drag = table.attrs.get("drag")
    if drag is not None:
        written.attrs.update(dict(zip(BOUNCE_DRAG_ATTRIBUTES, (
            drag.drag_constant, drag.uncertainty, drag.effective_gravity, drag.source,
            drag.note))))


def _read_bounces(group):
    """A bounce table group as a DataFrame, with the attributes of its drag correction (where
    it has one) in ``attrs``."""
    table = read_table(group)
    table.attrs.update({key: group.attrs[key] for key in BOUNCE_DRAG_ATTRIBUTES
                        if key in group.attrs})
    return table


def _write_noise_fits(group, scene_fit):
    """Its fits under the noise model and their selection, only where it has them: a file
    without them has the layout it always had."""
    if not scene_fit.noise_results:
        return
    noise_fits = group.create_group("noise_fits")
    for law, fit in scene_fit.noise_results.items():
        _write_noise_fit(noise_fits.create_group(law), fit)
    noise = _table(group, "noise_selection", scene_fit.noise_selection, NOISE_SELECTION_UNITS)
    noise.attrs["verdict"] = scene_fit.noise_verdict

def _write_runs(out, runs):
    """Each run's bounces, fits and selection under runs/<run>, the joint fits under
    joint/<model>."""
    group = out.create_group("runs", track_order=True)
    group.attrs["notes"] = json.dumps(list(runs.notes))
    for number, fit in runs.runs.items():
        run = group.create_group(str(number), track_order=True)
        run.attrs.update({"run": int(number), "verdict": fit.verdict,
                          "notes": json.dumps(list(fit.data.notes))})
        _write_fits(run, fit)
        _write_noise_fits(run, fit)
    joint = out.create_group("joint", track_order=True)
    for model, fit in runs.joint.items():
        target = joint.create_group(model, track_order=True)
        target.attrs.update({"success": fit.success, "message": fit.message,
                             "chisqr": fit.chisqr, "redchi": fit.redchi, "aic": fit.aic,
                             "bic": fit.bic, "ndata": fit.ndata, "nvarys": fit.nvarys,
                             "nfev": fit.nfev, "varied": json.dumps(list(fit.varied)),
                             "notes": json.dumps(fit.notes)})
        rows = [{"name": name, "value": e.value, "stderr": e.stderr, "low68": e.low68,
                 "high68": e.high68, "low95": e.low95, "high95": e.high95, "unit": e.unit,
                 "status": e.status, "note": e.note} for name, e in fit.estimates.items()]
        numeric = ("value", "stderr", "low68", "high68", "low95", "high95")
        parameters = pd.DataFrame(rows, columns=["name", *numeric, "unit", "status", "note"])
        table = _table(target, "parameters", parameters.astype(dict.fromkeys(numeric, float)),
                       {})
        for column in numeric:
            table[column].attrs["units"] = "see column 'unit'"
        per_run = pd.DataFrame(
            [{"run": int(number), **{key: float(getattr(values.get(name), field, np.nan))
                                     for name in ("v0", "t0")
                                     for key, field in ((name, "value"),
                                                        (f"{name}_stderr", "stderr"))}}
             for number, values in fit.run_estimates.items()],
            columns=list(JOINT_RUN_UNITS)).astype({"run": "int64"})
        _table(target, "runs", per_run, JOINT_RUN_UNITS)
        _intervals_table(target, fit)


def _is_dimension(dataset):
    """Whether a dataset is a netCDF dimension without a variable (no data of its own)."""
    name = dataset.attrs.get("NAME", b"")
    name = name.decode() if isinstance(name, bytes) else str(name)
    return name.startswith(_NETCDF_DIMENSION)


def _arrays(group):
    """The datasets of a group as arrays, without its netCDF dimensions."""
    return {key: dataset[()] for key, dataset in group.items() if not _is_dimension(dataset)}


def read_fit(path):
    """Everything in a scene file as plain Python: attrs, tables as DataFrames, fits as dicts.

    Returns
    -------
    dict
        ``attrs`` (root attributes), ``impacts``, ``bounces`` (with the attributes of its drag
        correction in its ``attrs`` where it has one: ``drag_constant``,
        ``drag_constant_uncertainty``, ``effective_gravity``, ``drag_source``,
        ``drag_note``), ``selection`` (DataFrames) and
        ``fits``: model -> dict with ``attrs``, ``parameters`` (DataFrame indexed by name),
        ``correlation``, ``residuals``, ``predicted`` and ``eps_curve`` (dicts of arrays);
        where the file holds fits under the noise model also ``noise_selection`` (DataFrame),
        its ``noise_verdict`` (str) and ``noise_fits``: law -> dict as in ``fits`` without
        ``intervals``, with ``outliers`` and ``timing_sigma`` (arrays); where it holds the
        truth of a synthetic scene also ``truth`` (DataFrame, attributes ``model`` and
        ``source``); where it holds several runs also ``runs``: run -> dict with ``attrs``,
        ``bounces``, ``selection`` and ``fits`` (as at the root; with the noise fits also
        ``noise_selection``, ``noise_verdict`` and ``noise_fits``), and ``joint``: model ->
        dict with ``attrs``, ``parameters`` (DataFrame indexed by name), ``runs``
        (DataFrame: each run's v0 and t0 with their errors) and ``intervals`` (as a fit's).
    """
    with h5py.File(path, "r") as source:
        out = {"attrs": dict(source.attrs), "impacts": read_table(source["impacts"]),
               "bounces": _read_bounces(source["bounces"]),
               "selection": read_table(source["selection"]), "fits": {}}
        for model, group in source["fits"].items():
            out["fits"][model] = {
                "attrs": dict(group.attrs),
                "parameters": read_table(group["parameters"]).set_index("name"),
                "intervals": read_table(group["intervals"]).set_index("method"),
                "correlation": group["correlation"][()],
                **{name: _arrays(group[name])
                   for name in ("residuals", "predicted", "eps_curve")},
            }
        if "truth" in source:
            out["truth"] = read_table(source["truth"])
            out["truth"].attrs.update({key: str(source["truth"].attrs.get(key, ""))
                                       for key in ("model", "source")})
        if "runs" in source:
            out["runs"] = {}
            for number, group in source["runs"].items():
                out["runs"][int(number)] = {
                    "attrs": dict(group.attrs), "bounces": _read_bounces(group["bounces"]),
                    "selection": read_table(group["selection"]),
                    "fits": {model: {
                        "attrs": dict(fit.attrs),
                        "parameters": read_table(fit["parameters"]).set_index("name"),
                        "intervals": read_table(fit["intervals"]).set_index("method"),
                        "correlation": fit["correlation"][()],
                        **{name: _arrays(fit[name])
                           for name in ("residuals", "predicted", "eps_curve")},
                    } for model, fit in group["fits"].items()}}
                if "noise_fits" in group:
                    out["runs"][int(number)].update(_noise_record(group))
            out["joint"] = {model: {"attrs": dict(group.attrs),
                                    "parameters": read_table(group["parameters"]).set_index(
                                        "name"),
                                    "runs": read_table(group["runs"]),
                                    "intervals": read_table(group["intervals"]).set_index(
                                        "method")}
                            for model, group in source["joint"].items()}
        if "noise_fits" in source:
            out.update(_noise_record(source))
    return out


def _noise_record(source):
    """``noise_selection``, ``noise_verdict`` and ``noise_fits`` of a group holding them (the
    root, or a run's group), as :func:`read_fit` returns them."""
    out = {"noise_selection": read_table(source["noise_selection"]),
           "noise_verdict": str(source["noise_selection"].attrs.get("verdict", "")),
           "noise_fits": {}}
    for law, group in source["noise_fits"].items():
        out["noise_fits"][law] = {
            "attrs": dict(group.attrs),
            "parameters": read_table(group["parameters"]).set_index("name"),
            "correlation": group["correlation"][()],
            "outliers": group["outliers"][()],
            "timing_sigma": group["timing_sigma"][()],
            **{name: _arrays(group[name]) for name in ("residuals", "predicted", "eps_curve")},
        }
    return out


def csv_header(column, units=None):
    """A column's CSV header: its name with its unit in brackets (``beta [1/s]``), or the bare
    name where it has none or is dimensionless (``zeta``, ``model``).

    Parameters
    ----------
    column : str
        Column name, as in the HDF5 table (where a ``/`` could not be part of a name).
    units : dict, optional
        Column -> unit; default :data:`SUMMARY_UNITS`.
    """
    unit = (SUMMARY_UNITS if units is None else units).get(column, "1")
    return column if unit == "1" else f"{column} [{unit}]"


def write_summary(path_h5, path_csv, summary, *, overwrite=False):
    """Cross-scene summary (one row per scene and model) as HDF5 and CSV, each atomically.

    The HDF5 table's columns carry their units as attributes; the CSV's headers carry them in
    brackets (:func:`csv_header`: ``beta [1/s]``, ``k [N/m]``, ``sigma_j [s]``).

    Parameters
    ----------
    path_h5, path_csv : str or os.PathLike
        The HDF5 and the CSV file to write.
    summary : pandas.DataFrame
        The table (:func:`dashpot.summary.summary_from_files`).
    overwrite : bool, default False
        Replace either file if it exists. Without it, if either exists, neither is written.

    Raises
    ------
    InputError
        One of the files exists and `overwrite` is false ("<path>: exists; pass
        overwrite=True to replace it").
    """
    refuse_existing(path_h5, path_csv, overwrite=overwrite)  # before writing either
    with _new_hdf5(path_h5, overwrite=overwrite) as out:
        out.attrs["format"] = "dashpot-summary-1"
        out.attrs["dashpot_version"] = __version__
        out.attrs["dashpot_source_sha256"] = source_fingerprint()
        _table(out, "summary", summary, SUMMARY_UNITS)
    with atomic_path(path_csv, overwrite=overwrite) as temporary:
        # Shortest round-trip floats.
        summary.rename(columns=csv_header).to_csv(temporary, index=False)
