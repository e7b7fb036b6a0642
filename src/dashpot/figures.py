"""One scene's figures from its stored fit: the data each figure of :mod:`dashpot.plots` needs.

The command line (``dashpot analyze``) and the workflow draw the same figures from the same
scene file (``results/<scene>.h5``, read with :func:`load_record`):

- ``intervals``: observed bounce intervals T_n with every fitted model's predicted intervals
  (differences of its predicted impact times at the fitted impacts) and the residuals;
- ``restitution``: measured ε against impact speed with every fitted model's ε(v) curve, and
  where the scene was also fitted under the noise model, each of those fits' ε(v) (its law at
  the fitted parameters, over the observed speed range, as stored in ``noise_fits/<law>``);
  where the points are interval ratios, beside each model's ε(v) its predicted ratios;
- ``selection``: the Akaike weights and ΔAIC of the models, with a second panel of the fits
  under the noise model where the scene has them, below it the effects the data required
  (:func:`noise_effect_steps`: each effect's best ΔBIC against its simpler rung) and the bars of
  the fits the nested steps did not keep hatched;
- ``detection`` (audio recordings only): the recording's envelope with the detected impacts.

Measured ε and impact speed (:func:`restitution_points`): where the sensor measured speeds
(motion sensor, photogate), ε = rebound/impact speed of each impact; otherwise from the flight
times, ε of the impact ending interval n is T_{n+1}/T_n and its impact speed the landing speed
of flight n, g_eff·T_n/2 (the ``rebound_speed`` of row n of the bounce table, the flight being
symmetric).

Predicted interval ratios (:func:`predicted_interval_ratios`): an interval T_n holds the
contact of impact n as well as the flight, so the ratio T_{n+1}/T_n is not ε: on a train of
1.5 ms contacts and 0.3 s flights a model's own ratios lie about 2e-4 above its ε(v). Where the
points are interval ratios the ``restitution`` figure draws, beside each model's ε(v), the
ratios of its predicted intervals (those of the ``intervals`` figure) at the measured speeds:
what the fit compared with the data. The fits under the noise model have no such counterpart
(their predictions are the filter's, one impact ahead of the data), only their ε(v).

Drag-corrected ε (:func:`drag_corrected_points`): where the scene file's bounce table was
corrected for air drag (a fit under the noise model fitted k_d, or the scene gives the ball's
mass and diameter: :func:`dashpot.analysis.stored_bounces`), the ``restitution`` figure draws
the corrected ε of each bounce (launch over landing speed of the drag flights) against its
impact speed, the landing speed of flight n, beside the uncorrected interval ratios; the legend
names the k_d and the fit it comes from. Those points are the ones to compare with the laws'
ε(v) curves, which hold ε itself, without the flight.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import plots
from .atomic import refuse_existing
from .store import read_fit

__all__ = ["SCENE_FIGURES", "load_record", "interval_series", "restitution_points",
           "drag_corrected_points", "predicted_interval_ratios", "noise_effect_steps",
           "scene_name",
           "scene_figures", "detection_figure_data", "detection_figure", "save_scene_figures"]

SCENE_FIGURES = ("intervals", "restitution", "selection")
"""Figures of every scene (``detection`` is added for audio recordings)."""


def load_record(path):
    """:func:`dashpot.store.read_fit` of a scene file, plus ``used_in_fit`` in ``impacts``."""
    import h5py

    record = read_fit(path)
    with h5py.File(path, "r") as source:
        record["impacts"]["used_in_fit"] = source["impacts"]["used_in_fit"][()].astype(bool)
    return record


def _fitted_impacts(record):
    impacts = record["impacts"]
    return impacts[impacts["used_in_fit"]] if "used_in_fit" in impacts else impacts


def interval_series(record):
    """Observed and predicted bounce intervals of a scene.

    Returns
    -------
    index : ndarray
        Bounce number of each interval.
    observed, uncertainty : ndarray
        Observed intervals between the fitted impacts in s and their 1σ (uncertainty None if
        unknown).
    predictions : dict of str -> ndarray
        Each successful model's predicted intervals in s (np.diff of ``predicted/at_data``).
    failed : list of str
        Models whose fit failed.
    """
    bounces = record["bounces"]
    used = _fitted_impacts(record)
    times = used["time"].to_numpy(float)
    if len(bounces) == times.size - 1:  # nothing left out: the bounce table is the data
        index = bounces["bounce"].to_numpy(float)
        observed = bounces["interval"].to_numpy(float)
        uncertainty = bounces["interval_uncertainty"].to_numpy(float)
    else:
        index = np.arange(times.size - 1, dtype=float)
        observed = np.diff(times)
        sigma = used["time_uncertainty"].to_numpy(float)
        uncertainty = np.hypot(sigma[:-1], sigma[1:])
    if not np.all(np.isfinite(uncertainty) & (uncertainty > 0)):
        uncertainty = None
    predictions, failed = {}, []
    for model, fit in record["fits"].items():
        at_data = np.asarray(fit["predicted"].get("at_data", []), dtype=float)
        if not fit["attrs"].get("success", False) or at_data.size < 2:
            failed.append(model)
            continue
        predictions[model] = np.diff(at_data)
    return index, observed, uncertainty, predictions, failed


def restitution_points(record):
    """Measured ε against impact speed, with 1σ uncertainties (see the module notes).

    Returns
    -------
    speed, eps, speed_uncertainty, eps_uncertainty : ndarray
        Impact speeds in m/s, restitution, and their 1σ (NaN where unknown).
    """
    impacts = _fitted_impacts(record)
    good = _measured_speeds(impacts)
    if good.sum() >= 2:
        speed = impacts["impact_speed"].to_numpy(float)[good]
        rebound = impacts["rebound_speed"].to_numpy(float)[good]
        sigma = impacts["speed_uncertainty"].to_numpy(float)[good]
        eps = rebound / speed
        eps_sigma = eps * np.hypot(sigma / speed, sigma / np.where(rebound > 0, rebound, np.nan))
        return speed, eps, sigma, eps_sigma
    bounces = record["bounces"]
    keep = _sound_ratios(bounces)
    return (bounces["rebound_speed"].to_numpy(float)[keep],
            bounces["restitution"].to_numpy(float)[keep],
            bounces["rebound_speed_uncertainty"].to_numpy(float)[keep],
            bounces["restitution_uncertainty"].to_numpy(float)[keep])


def _measured_speeds(impacts):
    """Rows of an impact table with a measured impact and rebound speed."""
    speed, rebound = (impacts[name].to_numpy(float) if name in impacts
                      else np.full(len(impacts), np.nan)
                      for name in ("impact_speed", "rebound_speed"))
    return np.isfinite(speed) & np.isfinite(rebound) & (speed > 0)


def _has_measured_speeds(record):
    """Whether :func:`restitution_points` takes the sensor's speeds (else the flight times)."""
    return int(_measured_speeds(_fitted_impacts(record)).sum()) >= 2


def _sound_ratios(bounces):
    """Rows of a bounce table whose ratio T_{n+1}/T_n is finite and whose two intervals are
    both "ok"."""
    keep = np.isfinite(bounces["restitution"].to_numpy(float))
    if "flag" in bounces:
        ok = bounces["flag"].to_numpy(str) == "ok"
        keep &= ok & np.append(ok[1:], True)  # both intervals of the ratio are sound
    return keep


def predicted_interval_ratios(record):
    """Each fitted model's own ratios T_{n+1}/T_n at the bounces whose measured ratio the
    ``restitution`` figure draws.

    Parameters
    ----------
    record : dict
        Of :func:`load_record`.

    Returns
    -------
    dict of str -> (ndarray, ndarray)
        Model -> (impact speed of each bounce in m/s: the measured g_eff·T_n/2 the point of
        :func:`restitution_points` stands at; the ratio of the model's predicted intervals
        T_{n+1}/T_n there, dimensionless), for each successful fit whose predicted times
        ``predicted/at_data`` cover the fitted impacts, at the bounces whose three impacts
        were all fitted. Empty where the points are the sensor's speeds (their ε is ε, to be
        read against the curves themselves) or the file's impact and bounce tables do not
        line up.
    """
    if _has_measured_speeds(record):
        return {}
    bounces = record["bounces"]
    impacts = record["impacts"]
    if "run" in impacts and len(bounces):
        # The bounce table and the fits at the root are those of the first run.
        impacts = impacts[impacts["run"].to_numpy() == bounces["run"].iloc[0]]
    used = (impacts["used_in_fit"].to_numpy(bool) if "used_in_fit" in impacts
            else np.ones(len(impacts), bool))
    if len(bounces) != used.size - 1:
        return {}
    # Row n's ratio spans impacts n, n + 1 and n + 2; each fitted impact has its place in the
    # predicted times at the data.
    rows = np.flatnonzero(_sound_ratios(bounces))
    rows = rows[rows + 2 < used.size]
    rows = rows[used[rows] & used[rows + 1] & used[rows + 2]]
    place = np.cumsum(used) - 1
    first, middle, last = place[rows], place[rows + 1], place[rows + 2]
    speed = bounces["rebound_speed"].to_numpy(float)[rows]
    ratios = {}
    for model, fit in record["fits"].items():
        at_data = np.asarray(fit["predicted"].get("at_data", []), dtype=float)
        if not fit["attrs"].get("success", False) or at_data.size != int(used.sum()):
            continue
        ratios[model] = (speed, (at_data[last] - at_data[middle])
                         / (at_data[middle] - at_data[first]))
    return ratios


def drag_corrected_points(record):
    """The drag-corrected ε of a scene file's bounce table against impact speed, or None.

    Parameters
    ----------
    record : dict
        Of :func:`load_record`.

    Returns
    -------
    dict or None
        None where the bounce table has no ``restitution_corrected`` column; else ``speed``
        (the landing speed of flight n, which is the impact speed of the impact whose ε it is,
        m/s), ``eps``, ``speed_uncertainty`` (1σ from the impact times) and
        ``eps_uncertainty`` (1σ: that from the impact times and that from k_d's uncertainty in
        quadrature, the whole error of one bounce's ε; None where unknown) of the bounces
        whose ratio is sound (as in :func:`restitution_points`), and ``label``, naming the
        drag constant used and its source.
    """
    bounces = record["bounces"]
    if "restitution_corrected" not in bounces:
        return None
    keep = _sound_ratios(bounces) & np.isfinite(bounces["restitution_corrected"].to_numpy(float))
    attrs = bounces.attrs
    source = str(attrs.get("drag_source", ""))
    where = ("scene prior" if source == "scene" else f"noise fit {source}") if source else ""
    constant = attrs.get("drag_constant")
    label = "drag-corrected" + (f" ($k_d$ = {float(constant):.3g} 1/m, {where})"
                                if constant is not None else "")
    column = {name: bounces[name].to_numpy(float)[keep] for name in (
        "landing_speed", "landing_speed_uncertainty", "restitution_corrected",
        "restitution_corrected_uncertainty")}
    # k_d's share is common to every bounce, but it is part of each one's error.
    shared = (bounces["restitution_corrected_drag_uncertainty"].to_numpy(float)[keep]
              if "restitution_corrected_drag_uncertainty" in bounces else 0.0)
    return {"speed": column["landing_speed"], "eps": column["restitution_corrected"],
            "speed_uncertainty": _finite_or_none(column["landing_speed_uncertainty"]),
            "eps_uncertainty": _finite_or_none(np.hypot(
                column["restitution_corrected_uncertainty"], shared)),
            "label": label}


def _eps_curves(record, group="fits"):
    curves = {}
    for model, fit in record.get(group, {}).items():
        curve = fit["eps_curve"]
        if fit["attrs"].get("success", False) and len(curve.get("speed", [])):
            curves[model] = (np.asarray(curve["speed"], float), np.asarray(curve["eps"], float))
    return curves


def _failed(record, group="fits"):
    """Names of the fits of `group` that failed (no ε(v) curve to draw), in the file's order
    (the noise selection table's for the noise fits)."""
    fits = record.get(group, {})
    order = (list(record["noise_selection"]["model"]) if group == "noise_fits"
             and "noise_selection" in record else list(fits))
    return [name for name in order
            if name in fits and not fits[name]["attrs"].get("success", False)]


def _noise_eps_curves(record):
    """ε(v) of the fits under the noise model, in their selection table's order (the file's
    groups list them alphabetically)."""
    curves = _eps_curves(record, "noise_fits")
    if "noise_selection" not in record:
        return curves
    return {name: curves[name] for name in record["noise_selection"]["model"] if name in curves}


def _finite_or_none(values):
    values = np.asarray(values, dtype=float)
    return values if values.size and np.all(np.isfinite(values)) else None


def scene_name(record):
    """The scene's name as its file stores it (``name`` of the root attribute ``scene``), or
    None where the file does not say."""
    import json

    try:
        name = json.loads(record.get("attrs", {}).get("scene", "") or "{}").get("name")
    except (TypeError, ValueError, AttributeError):
        return None
    return str(name) if name else None


def scene_figures(record):
    """The figures :data:`SCENE_FIGURES` of one scene, as a dict of name -> Figure, each
    titled with the scene's name (:func:`dashpot.plots.name_scene`)."""
    figures = _scene_figures(record)
    name = scene_name(record)
    return {key: plots.name_scene(figure, name) for key, figure in figures.items()}


def _scene_figures(record):
    index, observed, uncertainty, predictions, failed = interval_series(record)
    speed, eps, speed_sigma, eps_sigma = restitution_points(record)
    corrected = drag_corrected_points(record)
    # The points say what they are: the sensor's speeds, or ratios of successive intervals
    # (whose flights include the contacts: not ε itself where the contact time matters).
    speeds = _has_measured_speeds(record)
    if corrected is not None:
        measured_label = ("measured speeds (no drag correction)" if speeds
                          else "interval ratios (no drag correction)")
    else:
        measured_label = ("measured: rebound / impact speed" if speeds
                          else r"interval ratios $T_{n+1}/T_n$")
    selection = record["selection"]
    return {
        "intervals": plots.intervals_figure(index, observed, uncertainty, predictions,
                                            failed=failed),
        "restitution": plots.restitution_speed_figure(speed, eps, _finite_or_none(speed_sigma),
                                                      _finite_or_none(eps_sigma),
                                                      _eps_curves(record),
                                                      _noise_eps_curves(record),
                                                      corrected=corrected,
                                                      measured_label=measured_label,
                                                      failed=_failed(record),
                                                      failed_noise=_failed(record,
                                                                           "noise_fits"),
                                                      predicted_ratios=(
                                                          predicted_interval_ratios(record))),
        "selection": _selection_figure(selection, record.get("noise_selection")),
    }


def _weights_and_criterion(selection):
    """Names, Akaike weights (NaN for a failed fit), Δ and its criterion of a selection table:
    ΔQAIC where the models share a misfit (files written before ΔQAIC was stored show ΔAIC)."""
    weights = np.where(selection["success"].to_numpy(bool),
                       selection["akaike_weight"].to_numpy(float), np.nan)
    delta_aic = selection["delta_aic"].to_numpy(float)
    delta = (selection["delta_qaic"].to_numpy(float) if "delta_qaic" in selection
             else delta_aic)
    scaled = bool(np.any(np.isfinite(delta) & (delta != delta_aic)))
    return selection["model"].tolist(), weights, delta, "QAIC" if scaled else "AIC"


def _selection_figure(selection, noise_selection=None):
    """The selection figure, with the panel of the fits under the noise model where given
    (the effects the data required below it, the fits not kept hatched)."""
    models, weights, delta, criterion = _weights_and_criterion(selection)
    if noise_selection is None:
        return plots.selection_figure(models, weights, delta, criterion=criterion)
    steps = noise_effect_steps(noise_selection)
    kept = None if steps is None else noise_selection["kept"].to_numpy(bool)
    return plots.selection_figure(models, weights, delta, criterion=criterion,
                                  noise=_weights_and_criterion(noise_selection),
                                  noise_steps=steps, noise_kept=kept)


def noise_effect_steps(noise_selection):
    """Each effect the nested steps of the noise selection tried, as the verdict reads them.

    Parameters
    ----------
    noise_selection : pandas.DataFrame
        The noise selection table (:func:`dashpot.noise_selection.noise_selection_table`, or
        as stored in a scene file): columns ``model``, ``effect``, ``simpler``, ``bic_gain``
        (dimensionless), ``kept``, ``selected``.

    Returns
    -------
    list of tuple or None
        One ``(effect, fit, simpler, bic_gain, required, carrier)`` per effect with a finite
        BIC step, in the table's order: the fit adding it with the largest ΔBIC against its
        simpler rung, that rung, the ΔBIC, whether the data required the effect (that fit was
        kept, or a kept fit carries the effect from a simpler rung of its own) and that
        carrying fit ("" where the effect's own fit was kept or none carries it). None for a
        table without the nested-steps columns (files written before them).
    """
    from .noise_selection import carried_effects

    columns = ("model", "effect", "simpler", "bic_gain", "kept", "selected")
    if not all(name in noise_selection for name in columns):
        return None
    table = noise_selection.reset_index(drop=True)
    effects = table["effect"].fillna("").astype(str)
    gains = table["bic_gain"].to_numpy(float)
    kept_mask = table["kept"].to_numpy(bool)
    # Kept fits, the selected one first (the verdict names that one as the carrier).
    kept = sorted(table.loc[kept_mask, "model"].astype(str),
                  key=lambda name: not bool(table.loc[table["model"] == name, "selected"].iloc[0]))

    steps = []
    for effect in dict.fromkeys(e for e in effects if e):
        rows = np.flatnonzero((effects == effect).to_numpy() & np.isfinite(gains))
        if rows.size == 0:
            continue
        best = rows[np.argmax(gains[rows])]
        carrier = "" if kept_mask[best] else next(
            (name for name in kept if effect in carried_effects(name)), "")
        steps.append((effect, str(table.loc[best, "model"]), str(table.loc[best, "simpler"]),
                      float(gains[best]), bool(kept_mask[best]) or bool(carrier), carrier))
    return steps


def detection_figure_data(recording, impact_times, *, tail_count=8, columns=2000, runs=None):
    """What the detection figure draws of a recording, read in blocks (bounded memory).

    Parameters
    ----------
    recording : str or os.PathLike
        Audio file.
    impact_times : array_like
        Impact times in s.
    tail_count : int, default 8
        Impacts in the close-up (:func:`dashpot.plots.detection_closeup`).
    columns : int, default 2000
        Pixel columns of the close-up: its raw samples are reduced to the smallest and largest
        of each (:func:`dashpot.envelope.channel_extremes`).
    runs : array_like, optional
        The run of each impact: the close-up shows the last run's.

    Returns
    -------
    dict
        ``time`` and ``envelope`` (1 ms peak envelope of the whole recording, s and full
        scale), ``sample_time`` and ``samples`` (the loudest channel over the close-up's span,
        s and full scale).
    """
    from .envelope import channel_extremes, recording_envelope

    time, envelope, loudest, _ = recording_envelope(recording)
    start, stop = plots.detection_closeup(impact_times, time[0], time[-1],
                                          tail_count=tail_count, runs=runs)
    # A sample or two beyond the span, so that the curve reaches both edges of the close-up.
    margin = 2e-3
    sample_time, samples = channel_extremes(recording, loudest, start - margin, stop + margin,
                                            columns=columns)
    return {"time": time, "envelope": envelope, "sample_time": sample_time, "samples": samples}


def detection_figure(record, recording):
    """Envelope of an audio recording with the impacts stored in its scene file (each drop of
    the ball a run)."""
    impacts = record["impacts"]["time"].to_numpy(float)
    runs = record["impacts"]["run"].to_numpy() if "run" in record["impacts"] else None
    data = detection_figure_data(recording, impacts, runs=runs)
    figure = plots.detection_figure(data["time"], data["envelope"], impacts,
                                    sample_time=data["sample_time"], samples=data["samples"],
                                    runs=runs)
    return plots.name_scene(figure, scene_name(record))


def save_scene_figures(record, folder, *, recording=None, overwrite=False):
    """Write each scene figure as ``folder/<name>.png`` and ``.pdf``.

    Parameters
    ----------
    record : dict
        A scene file read with :func:`load_record`.
    folder : str or os.PathLike
        Where the figures go (created if missing).
    recording : str or os.PathLike, optional
        The scene's audio file: adds the ``detection`` figure.
    overwrite : bool, default False
        Replace figures of these names that exist. Without it, if any of them exists, none
        is drawn or written.

    Returns
    -------
    list of pathlib.Path
        The PNG of each figure.

    Raises
    ------
    InputError
        A figure's PNG or PDF exists and `overwrite` is false ("<path>: exists; pass
        overwrite=True to replace it"); every file is left as it was.
    """
    folder = Path(folder)
    names = [*SCENE_FIGURES, *(["detection"] if recording is not None else [])]
    refuse_existing(*(folder / f"{name}.{fmt}" for name in names for fmt in ("png", "pdf")),
                    overwrite=overwrite)  # before any figure is drawn
    figures = scene_figures(record)
    if recording is not None:
        figures["detection"] = detection_figure(record, recording)
    return [plots.save_figure(figure, folder / name, overwrite=overwrite)[0]
            for name, figure in figures.items()]
