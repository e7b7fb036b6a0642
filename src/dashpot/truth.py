"""Truth against fit for synthetic scenes: how far each fitted contact parameter lies from the
value that generated the recording, in units of its own error.

A synthetic scene (:func:`dashpot.synth.scene.write_scene`) carries a ``truth.json`` beside its
recording whose ``generator`` record holds the model and the parameters of the bounce train:
damping rate β (1/s), undamped contact frequency ω0 (rad/s) and first impact speed v0 (m/s);
the damping ratio ζ = β/ω0 [1]_ follows from them. :func:`truth_table` sets a fit's estimates
of these four beside the truth, with the pull

    pull = (fitted value − true value) / σ,

σ the fit's 1σ error: over many recordings the pulls of an unbiased fit with honest errors
scatter as N(0, 1) [2]_. A pull is left empty (NaN) where it means nothing, and the row's
``note`` says why: the fit has no such estimate, its error is infinite (the data do not
determine the parameter) or zero (the parameter was held fixed).

References
----------
.. [1] A. P. French, "Vibrations and Waves", ch. 3 (the damped oscillator: β, ω0 and the
   damping ratio ζ = β/ω0).
.. [2] L. Demortier and L. Lyons, "Everything you always wanted to know about pulls",
   CDF/ANAL/PUBLIC/5776 (2002): the pull of a fitted parameter and its N(0, 1) distribution.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from .atomic import atomic_path
from .errors import InputError

__all__ = ["TRUTH_PARAMETERS", "TRUTH_COLUMNS", "read_truth", "true_parameters", "pulls",
           "truth_table", "truth_comparison", "write_truth_csv"]

TRUTH_PARAMETERS = {"beta": "1/s", "omega0": "rad/s", "zeta": "1", "v0": "m/s"}
"""The parameters compared with the truth, and their units."""

TRUTH_COLUMNS = ("parameter", "unit", "truth", "value", "stderr", "pull", "low95", "high95",
                 "covered95", "note")
"""Columns of :func:`truth_table`, in order."""

_GENERATOR_KEYS = ("model", "beta", "omega0", "v0")


def read_truth(path):
    """The ``generator`` record of a synthetic scene's ``truth.json``.

    Parameters
    ----------
    path : str or os.PathLike
        The ``truth.json`` written by :func:`dashpot.synth.scene.write_scene`.

    Returns
    -------
    dict
        At least ``model`` (str), ``beta`` (1/s), ``omega0`` (rad/s) and ``v0`` (m/s).

    Raises
    ------
    InputError
        The file cannot be read, is not JSON, or lacks one of those keys or numbers.
    """
    try:
        record = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(path, f"cannot be read ({error.strerror or error})") from None
    except json.JSONDecodeError as error:
        raise InputError(path, f"not JSON ({error.msg}, line {error.lineno})") from None
    generator = record.get("generator") if isinstance(record, dict) else None
    if not isinstance(generator, dict):
        raise InputError(path, "no 'generator' record: not a synthetic scene's truth.json")
    missing = [key for key in _GENERATOR_KEYS if key not in generator]
    if missing:
        raise InputError(path, f"the generator record lacks {', '.join(missing)}")
    for key in _GENERATOR_KEYS[1:]:
        value = generator[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value) or value <= 0:
            raise InputError(path, f"generator {key} must be a positive number; got {value!r}")
    return generator


def true_parameters(generator):
    """The true β (1/s), ω0 (rad/s), ζ = β/ω0 and v0 (m/s) of a generator record."""
    beta, omega0 = float(generator["beta"]), float(generator["omega0"])
    return {"beta": beta, "omega0": omega0, "zeta": beta / omega0,
            "v0": float(generator["v0"])}


def pulls(value, stderr, truth):
    """Pulls (value − truth)/stderr, NaN where the error is not finite and positive.

    Parameters
    ----------
    value, stderr, truth : array_like
        Fitted values, their 1σ errors and the true values, in one unit per element.

    Returns
    -------
    numpy.ndarray
        The pulls (dimensionless).
    """
    value, stderr, truth = np.broadcast_arrays(*(np.asarray(x, dtype=float)
                                                 for x in (value, stderr, truth)))
    usable = np.isfinite(stderr) & (stderr > 0) & np.isfinite(value) & np.isfinite(truth)
    out = np.full(value.shape, np.nan)
    np.divide(value - truth, stderr, out=out, where=usable)
    return out


def _note(estimate):
    if estimate is None:
        return "not fitted: the fit has no such estimate"
    if not np.isfinite(estimate["stderr"]):
        return "no pull: the data do not determine it (infinite error)"
    if estimate["stderr"] == 0:
        return "no pull: held fixed (zero error)"
    return ""


def truth_table(generator, estimates):
    """One row per compared parameter: truth, the fit's value ± σ, pull and 95 % coverage.

    Parameters
    ----------
    generator : dict
        The ``generator`` record of ``truth.json`` (see :func:`read_truth`).
    estimates : mapping of str -> Estimate or mapping
        A fit's estimates by name (:class:`dashpot.fit.Estimate`, or a mapping or row with
        ``value``, ``stderr``, ``low95``, ``high95``), as in ``FitResult.estimates``;
        empty for a failed fit.

    Returns
    -------
    pandas.DataFrame
        Columns :data:`TRUTH_COLUMNS`: ``parameter``, ``unit``, ``truth``, the fit's
        ``value`` and ``stderr``, ``pull`` (NaN where the note says why), the fit's central
        95.45 % interval ``low95``/``high95``, ``covered95`` (the truth inside it) and
        ``note``; attribute ``model``: the generating model.
    """
    truth = true_parameters(generator)
    rows = []
    for name, unit in TRUTH_PARAMETERS.items():
        found = estimates.get(name)
        estimate = None if found is None else {
            key: float(found[key] if isinstance(found, (dict, pd.Series)) else
                       getattr(found, key)) for key in ("value", "stderr", "low95", "high95")}
        numbers = estimate or dict.fromkeys(("value", "stderr", "low95", "high95"), math.nan)
        rows.append({"parameter": name, "unit": unit, "truth": truth[name], **numbers,
                     "note": _note(estimate)})
    table = pd.DataFrame(rows)
    table["pull"] = pulls(table["value"], table["stderr"], table["truth"])
    table["covered95"] = (table["low95"] <= table["truth"]) & (table["truth"] <= table["high95"])
    table = table[list(TRUTH_COLUMNS)].astype({column: float for column in (
        "truth", "value", "stderr", "pull", "low95", "high95")})
    table.attrs["model"] = str(generator["model"])
    return table


def truth_comparison(path, scene_fit):
    """:func:`truth_table` of a fitted synthetic scene against its ``truth.json``.

    The fit compared is that of the generating model; where the scene did not fit that
    model, the table keeps the truth and says so in each row's note.

    Parameters
    ----------
    path : str or os.PathLike
        The scene's ``truth.json``.
    scene_fit : dashpot.fit.SceneFit
        The scene's fits.

    Returns
    -------
    pandas.DataFrame
        As :func:`truth_table`, with attributes ``model`` and ``source`` (the file's name).
    """
    generator = read_truth(path)
    fit = scene_fit.results.get(generator["model"])
    table = truth_table(generator, fit.estimates if fit is not None else {})
    if fit is None:
        table["note"] = f"the scene did not fit the generating model {generator['model']}"
    table.attrs["source"] = Path(path).name
    return table


def write_truth_csv(path, table, *, overwrite=False):
    """Write a truth table as CSV, atomically, with the generating model as first column.

    Parameters
    ----------
    path : str or os.PathLike
        Output file.
    table : pandas.DataFrame
        A :func:`truth_table` (or the ``truth`` of :func:`dashpot.store.read_fit`), whose
        attribute ``model`` names the generating model. Each row's numbers are in its
        ``unit`` column's unit; ``pull`` is dimensionless.
    overwrite : bool, default False
        Replace `path` if it exists.

    Raises
    ------
    InputError
        `path` exists and `overwrite` is false ("<path>: exists; pass overwrite=True to
        replace it"); the file is left as it was.
    """
    out = table.copy()
    out.insert(0, "model", str(table.attrs.get("model", "")))
    with atomic_path(path, overwrite=overwrite) as temporary:
        out.to_csv(temporary, index=False)  # shortest round-trip floats
