"""Impact data ready for fitting: times since the first impact, their uncertainties, the
position of each impact in the predicted train and the measured speeds.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd

from ..bounces import bounce_table
from ..ingest import SHARED_SPEED_COLUMN
from .results import FitData, SpeedErrors


def prepare_data(impacts, scene):
    """Impact times, uncertainties and train positions for fitting, from an impact table.

    Parameters
    ----------
    impacts : pandas.DataFrame
        Impact table of :mod:`dashpot.ingest` (``time`` in s, optional ``time_uncertainty``,
        ``impact_speed``, ``rebound_speed``, ``speed_uncertainty``, ``run``).
    scene : Scene

    Returns
    -------
    FitData

    Raises
    ------
    ValueError
        Fewer than three impacts, or none left once the flagged ones are left out.

    Notes
    -----
    Where the recording gives no timing uncertainty the scene's timing resolution r gives
    σ = r/√12 (uniform rounding); where neither is known σ is estimated from the scatter of
    the fit (and the information criteria use the unknown-variance form). Where only some
    uncertainties are zero or unknown, those are set to r/√12, or without r to the smallest
    positive σ of the table, and the others kept (noted). Impacts the bounce
    table flags as spurious are left out; an interval flagged as hiding a missed impact
    shifts the later impacts by one place in the train. Impacts the motion reader flags
    ``inferred`` (column ``flag``) keep their place in the train but are not fitted; those
    flagged ``few_samples`` are fitted with their (larger) stated σ. Only the first run of a
    multi-run file is fitted here (:func:`dashpot.fit.fit_runs` fits every run). Where the
    table states the speeds' correlated errors (the columns ``impact_speed_shared_<j>`` ...
    of :mod:`dashpot.ingest`, a motion reader's) ``speed_errors`` holds them and the fits
    weigh the speeds by that covariance; without those columns nothing changes.
    """
    table = impacts
    notes = []
    if "run" in table and table["run"].nunique() > 1:
        first = table["run"].min()
        notes.append(f"{table['run'].nunique()} runs in the file; fitted run {first} only")
        table = table[table["run"] == first]
    table = table.reset_index(drop=True)
    times = table["time"].to_numpy(float)
    if times.size < 3:
        raise ValueError(f"fitting needs at least three impacts; got {times.size}")
    sigma = table["time_uncertainty"].to_numpy(float) if "time_uncertainty" in table \
        else np.full(times.size, np.nan)
    usable = np.isfinite(sigma) & (sigma > 0)
    sigma_known = bool(np.all(usable))
    if usable.any() and not sigma_known:
        # A few zero or unknown σ must not discard the others: fill in those few.
        if scene.timing_resolution:
            fill, source = scene.timing_resolution / math.sqrt(12.0), \
                "the scene's timing resolution / sqrt(12)"
        else:
            fill, source = float(np.min(sigma[usable])), "the smallest timing uncertainty given"
        notes.append(f"{int(np.sum(~usable))} of {times.size} timing uncertainties zero or "
                     f"missing: set to {source} ({fill:.3g} s); the others kept")
        sigma = np.where(usable, sigma, fill)
        sigma_known = True
    if not sigma_known:
        if scene.timing_resolution:
            sigma = np.full(times.size, scene.timing_resolution / math.sqrt(12.0))
            sigma_known = True
            notes.append("timing uncertainty from the scene's timing resolution / sqrt(12)")
        else:
            sigma = np.ones(times.size)
            notes.append("no timing uncertainty given: estimated from the scatter of the fit")
    g = scene.driving_acceleration
    run = table["run"].to_numpy() if "run" in table else np.zeros(times.size, dtype=int)
    columns = {"time": times, "time_uncertainty": sigma, "run": run}
    if "flag" in table:
        columns["flag"] = table["flag"].to_numpy()  # intervals at inferred impacts flagged
    bounces = bounce_table(pd.DataFrame(columns), g=g)
    flags = bounces["flag"].to_numpy()
    # Interval n ends at impact n + 1: a "spurious" interval pair brackets one false impact.
    spurious_impacts = np.flatnonzero((flags[:-1] == "spurious") & (flags[1:] == "spurious")) + 1
    keep = np.ones(times.size, bool)
    keep[spurious_impacts] = False
    gaps = np.concatenate([[0], np.cumsum(flags == "missed")])
    index = np.arange(times.size) + gaps
    if spurious_impacts.size:
        notes.append(f"left out {spurious_impacts.size} impact(s) flagged as spurious")
    # The motion reader's flags: an "inferred" impact's time is not measured (its reversal
    # is not in the samples), so it keeps its place in the train but is not fitted; a
    # "few_samples" one is fitted with the larger σ the reader gave it.
    flag = table["flag"].astype(str).to_numpy() if "flag" in table else np.zeros(0, str)
    inferred = flag == "inferred"
    if inferred.any():
        keep &= ~inferred
        notes.append(f"left out {int(inferred.sum())} impact(s) flagged 'inferred' (no "
                     f"reversal in the samples); their places in the train kept")
    if np.any(flag == "few_samples"):
        notes.append(f"{int(np.sum(flag == 'few_samples'))} impact(s) flagged 'few_samples' "
                     f"fitted with their larger timing uncertainty")
    if np.any(flags == "missed"):
        notes.append(f"{int(np.sum(flags == 'missed'))} missed impact(s) bridged in the train")
    if not keep.any():
        raise ValueError(f"no impact left to fit: all {times.size} are flagged 'inferred' or "
                         f"spurious")
    index = index[keep]
    index = index - index[0]

    def column(name):
        if name in table:
            return table[name].to_numpy(float)[keep]
        return np.full(int(keep.sum()), np.nan)

    speed_sigma = column("speed_uncertainty")
    has_speed = np.isfinite(column("impact_speed")) & np.isfinite(speed_sigma) & (speed_sigma > 0)
    if np.any(np.isfinite(column("impact_speed"))) and not np.any(has_speed):
        notes.append("measured speeds have no uncertainty: not used in the fit")
    rebound_speed = column("rebound_speed")
    speed_errors = _speed_errors(table, keep, has_speed, speed_sigma, notes)
    origin = float(times[0])  # t - origin is exact for t up to twice the origin (Sterbenz)
    return FitData(times=times[keep] - origin, time_origin=origin, sigma=sigma[keep],
                   index=index,
                   impact_speed=np.where(has_speed, column("impact_speed"), np.nan),
                   rebound_speed=np.where(has_speed & np.isfinite(rebound_speed),
                                          rebound_speed, np.nan),
                   speed_sigma=np.where(has_speed, speed_sigma, np.nan), g=g,
                   sigma_known=sigma_known, excluded=np.flatnonzero(~keep), bounces=bounces,
                   notes=notes, speed_errors=speed_errors)


_SHARED_COLUMN = re.compile(SHARED_SPEED_COLUMN)


def _speed_errors(table, keep, has_speed, speed_sigma, notes):
    """The measured speeds' correlated errors (SpeedErrors) of the impacts kept, from the
    table's columns of them (:mod:`dashpot.ingest`); None where it has no shared column.

    A shared component missing where its speed is measured counts as 0. Without an
    ``*_own`` column (or where it is missing) a speed's own σ is what its
    ``speed_uncertainty`` leaves after the shared components, √(σ² − Σ_j s_j²); an own σ
    is at least 1 % of ``speed_uncertainty`` (the covariance stays positive definite); a
    ``flight_correlation`` is kept only where the next row is the next impact kept (a
    left-out impact between them breaks the flight).
    """
    numbers = sorted({int(m.group(2)) for name in table.columns
                      if (m := _SHARED_COLUMN.fullmatch(str(name)))})
    if not numbers:
        return None
    count = int(keep.sum())

    def values(name):
        if name not in table:
            return np.full(count, np.nan)
        return table[name].to_numpy(float)[keep]

    sigma = np.where(has_speed, speed_sigma, np.nan)
    shared, own = {}, {}
    for prefix in ("impact", "rebound"):
        shared[prefix] = np.nan_to_num(np.column_stack(
            [values(f"{prefix}_speed_shared_{j}") for j in numbers]))
        left = np.sqrt(np.maximum(sigma ** 2 - np.sum(shared[prefix] ** 2, axis=1),
                                  (0.01 * sigma) ** 2))
        stated = values(f"{prefix}_speed_own")
        own[prefix] = np.where(np.isfinite(stated), np.maximum(stated, 0.01 * sigma), left)
    correlation = values("flight_correlation")
    adjacent = np.append(np.diff(np.flatnonzero(keep)) == 1, False)
    correlation = np.where(adjacent & np.isfinite(correlation), correlation, 0.0)
    notes.append(f"measured speeds fitted with the errors the table states them to share "
                 f"within the run ({len(numbers)} shared component(s), and one flight's "
                 f"rebound and next impact speed)")
    return SpeedErrors(shared_in=shared["impact"], shared_out=shared["rebound"],
                       own_in=np.nan_to_num(own["impact"]),
                       own_out=np.nan_to_num(own["rebound"]), correlation=correlation)


def flight_notes(scene):
    """The notes of a deterministic fit (:func:`dashpot.fit.fit_model`) on the flight physics
    the scene asks for: air drag where it gives the ball's mass and diameter; none else.

    Parameters
    ----------
    scene : Scene

    Returns
    -------
    list of str
    """
    drag = scene.drag
    if drag is None:
        return []
    k_d = drag.drag_constant
    how = (f"k_d fitted with the scene's prior {k_d.value:.3g} +- {k_d.uncertainty:.2g} 1/m"
           if k_d.uncertainty is not None else f"k_d = {k_d.value:.3g} 1/m, exact")
    return [f"air drag in flight: {how} (from the ball's mass, diameter, drag coefficient and "
            f"the air density); g_eff = {scene.driving_acceleration:.6g} m/s² with buoyancy "
            f"and added mass"]
