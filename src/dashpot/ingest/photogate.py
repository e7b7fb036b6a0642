"""Impacts of a cart from a photogate's state log near the bumper (Vernier, PASCO).

References
----------
.. [3] Vernier Logger Pro 3 help, "Photogate timing": the time column holds the clock times of
   all gate-status changes (blocked/unblocked).
.. [5] D. Halliday, R. Resnick and J. Walker, "Fundamentals of Physics", ch. 2: motion with
   constant acceleration, x = x0 + v0·t + a·t²/2, v² = v0² + 2a·Δx.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .._validation import FLAG_LENGTH_RANGE, GATE_DISTANCE_RANGE, check_range
from ..errors import InputError
from ._tabular import _check_duplicates, _impact_frame, _is_state, _runs, _table_of_kind

# ---------------------------------------------------------------------------------------------
# Photogate
# ---------------------------------------------------------------------------------------------

_FLIGHT_MISMATCH = 0.05  # relative difference of the two passages around a flight, at most
_FLIGHT_G_TOLERANCE = 0.10  # relative scatter of g·sin θ between flights, at most


def _gate_states(path, table, column_index, rows):
    """1 (blocked) / 0 (unblocked) from numbers or the words Blocked/Unblocked."""
    words = pd.Series(table.cells[rows, column_index], dtype=object).astype(str).str.lower()
    state = words.map({"blocked": 1.0, "unblocked": 0.0, "1": 1.0, "0": 0.0})
    numeric = pd.to_numeric(words.str.replace(",", ".", regex=False), errors="coerce")
    state = state.fillna(numeric).to_numpy(dtype=float)
    bad = ~np.isin(state, (0.0, 1.0))
    if bad.any():
        k = int(rows[np.flatnonzero(bad)[0]])
        raise InputError(path, f"{table.where}gate state '{table.cells[k, column_index]}' is "
                               f"neither 1/0 nor Blocked/Unblocked", row=k + 1)
    return state


def _photogate_run(path, table, run, state_index, flag_length, gate_distance, notes):
    """Impacts of one photogate run (see read_photogate)."""
    label = run.label or 0
    time = run.time
    state = _gate_states(path, table, state_index, run.rows)
    change = np.flatnonzero(np.diff(state) != 0) + 1
    empty = tuple(np.empty(0) for _ in range(5))
    # An event log (Vernier photogate timing [3]_) has a row per change of state; a sampled log
    # repeats the state at a fixed rate, and a change happened between two samples.
    event_log = change.size == state.size - 1 and state.size > 1
    resolution = np.nan_to_num(run.columns["time_resolution"], nan=0.0)
    if event_log:
        # Its first row is a change too: a log that starts at the first blocking (no row of
        # the state before it) starts with the first passage.
        change = np.arange(state.size)
        change_time = time[change]
        change_sd = resolution[change] / np.sqrt(12.0)
    else:
        change_time = 0.5 * (time[change - 1] + time[change])
        change_sd = (time[change] - time[change - 1]) / np.sqrt(12.0)
    blocked_now = state[change] == 1.0
    on = np.flatnonzero(blocked_now[:-1])  # a blocking change followed by an unblocking one
    t_on, t_off = change_time[on], change_time[on + 1]
    sd_on, sd_off = change_sd[on], change_sd[on + 1]
    blocks = t_on.size
    notes.append(f"run '{label}': {'event' if event_log else 'sampled'} log, {blocks} complete "
                 f"passage(s) of the flag")
    if blocks == 0:
        return empty
    duration = t_off - t_on
    sd_duration = np.hypot(sd_on, sd_off)
    speed = flag_length / duration

    def mismatch(first, second):
        return np.abs(duration[first] - duration[second]) / (duration[first] + duration[second])

    # Phase: toward and away passages alternate; the two passages around a flight (away, then
    # toward again at the same place) take equal times, those around an impact do not (ε < 1).
    # Judge on the first flights, before any partial passage (apex inside the gate) can occur.
    def scores(spare):
        # Flight pairs of each phase among the first blocks, leaving out the last `spare`.
        top = blocks - 1 - spare
        flights0 = np.arange(1, top, 2)[:2]  # pairs (1, 2), (3, 4)
        flights1 = np.arange(0, top, 2)[:2]  # pairs (0, 1), (2, 3)
        return ((np.mean(mismatch(flights0, flights0 + 1)) if flights0.size else None),
                (np.mean(mismatch(flights1, flights1 + 1)) if flights1.size else None))

    score0, score1 = scores(1)  # the last block may be a partial passage
    if score0 is None or score1 is None:
        score0, score1 = scores(0)
    phase = 1 if (score0 is not None and score1 is not None and score1 < score0) else 0
    if phase:
        notes.append(f"run '{label}': the log starts with an away passage (its impact came "
                     f"before the log); it is skipped")
    toward = np.arange(phase, blocks, 2)
    away = toward + 1
    has_away = away < blocks
    has_next = toward + 2 < blocks
    nxt = np.clip(toward + 2, 0, blocks - 1)
    aw = np.clip(away, 0, blocks - 1)
    # Free motion between an away passage and the next toward one: the cart leaves the gate
    # top at w = L/τ − g·τ/2 and is back after F = 2w/g, so g·sin θ = 2L/(τ(F + τ)) [5]_.
    flight = t_on[nxt] - t_off[aw]
    tau_mean = 0.5 * (duration[aw] + duration[nxt])
    with np.errstate(divide="ignore", invalid="ignore"):
        g_flight = 2.0 * flag_length / (tau_mean * (flight + tau_mean))
    symmetric = has_away & has_next & (mismatch(aw, nxt) < _FLIGHT_MISMATCH)
    g_eff = float(np.median(g_flight[symmetric])) if symmetric.any() else 0.0
    genuine_flight = symmetric & (np.abs(g_flight / g_eff - 1.0) < _FLIGHT_G_TOLERANCE
                                  if g_eff > 0 else symmetric)
    if g_eff > 0:
        notes.append(f"run '{label}': g·sin θ = {g_eff:.4g} m/s² from "
                     f"{int(genuine_flight.sum())} flight(s) between passages")
    else:
        notes.append(f"run '{label}': no complete flight between passages; speeds taken as "
                     f"constant near the gate")
    # An away passage is genuine only if the cart came back through the whole gate after it;
    # otherwise it turned inside the gate (a partial passage) and so did every later bounce.
    broken = np.flatnonzero(~genuine_flight)
    last_full = int(broken[0]) if broken.size else toward.size
    later = blocks - phase - 2 * last_full - 1
    if broken.size and later > 0:
        notes.append(f"run '{label}': {later} later passage(s) (partial, the cart turning inside "
                     f"the beam, or unpaired) were not used")
    full = np.arange(toward.size) < last_full
    tw = toward
    v_exit = flag_length / duration[tw] + 0.5 * g_eff * duration[tw]  # at the gate's bumper edge
    w_entry = flag_length / duration[aw] + 0.5 * g_eff * duration[aw]
    if gate_distance is not None:
        # Uniform acceleration over the gate-to-bumper distance d: V² = v² + 2gd and the time
        # 2d/(v + V), exact for the incline, independent of the contact duration.
        impact_speed = np.sqrt(v_exit ** 2 + 2.0 * g_eff * gate_distance)
        rebound_speed = np.sqrt(w_entry ** 2 + 2.0 * g_eff * gate_distance)
        impact_time = t_off[tw] + 2.0 * gate_distance / (v_exit + impact_speed)
        keep = np.arange(toward.size) <= last_full
        rebound_speed = np.where(full, rebound_speed, np.nan)
        notes.append(f"run '{label}': speeds and times extrapolated from the gate to the bumper "
                     f"(gate_distance {gate_distance:g} m)")
    else:
        # Without the distance: split the gap between the passages assuming an instantaneous
        # contact and the same distance in and out, under uniform acceleration (closed form of
        # t1 + t2 = G with t_i the travel times over d); a contact of duration τc makes the time
        # late by about τc·v_out/(v_in + v_out).
        gap = t_on[aw] - t_off[tw]
        impact_time = t_off[tw] + gap * (g_eff * gap + 2.0 * w_entry) / (
            2.0 * (g_eff * gap + v_exit + w_entry))
        impact_speed = speed[tw]
        rebound_speed = np.where(full, speed[aw], np.nan)
        keep = full
        notes.append(f"run '{label}': speeds are the flag's mean passage speeds L/τ at the gate; "
                     f"impact times split the gap between passages assuming a brief contact "
                     f"(pass gate_distance for exact times)")
    sd_speed_in = speed[tw] * sd_duration[tw] / duration[tw]
    sd_speed_out = np.where(full, speed[aw] * sd_duration[aw] / duration[aw], np.nan)
    sd_time = np.hypot(sd_off[tw], np.where(gate_distance is None, sd_on[aw], 0.0))
    dropped = int(np.sum(~keep & (np.arange(toward.size) <= last_full)))
    if dropped:
        notes.append(f"run '{label}': {dropped} impact(s) without an away passage need "
                     f"gate_distance to be timed; dropped")
    return (impact_time[keep], sd_time[keep], impact_speed[keep], rebound_speed[keep],
            np.fmax(sd_speed_in, sd_speed_out)[keep])


def read_photogate(path, *, flag_length, gate_distance=None):
    """Impacts of a cart from a photogate's state log near the bumper.

    Parameters
    ----------
    path : str or os.PathLike
        Text table or workbook with a time column and a gate-state column: Vernier
        ``Latest: Time (s)``, ``Latest: GateState`` (one row per change of state) or a
        sampled log (``Time (s) Run #1``, ``Gate State Run #1``, one row per sample). States
        1 = blocked, 0 = unblocked, or the words Blocked/Unblocked.
    flag_length : float
        Length in m of the flag on the cart that blocks the beam, in (0, 1] m.
    gate_distance : float, optional
        Distance in m the cart travels from leaving the beam to touching the bumper, if
        measured in the scene, in (0, 10] m. With it, times and speeds are extrapolated to
        the bumper.

    Returns
    -------
    pandas.DataFrame
        Impact table of :mod:`dashpot.ingest` (``run`` numbers runs side by side).

    Raises
    ------
    InputError
        Bad file (as for the other readers), no time or state column, states other than 1/0.
    ValueError
        If `flag_length` or `gate_distance` is not a finite number in its range.

    Notes
    -----
    Passages: a change to blocked followed by a change to unblocked; the flag's mean speed
    through the beam is L/τ (τ the blocking time). For a sampled log a change is put midway
    between the two samples that straddle it (1σ = sample spacing/√12); for an event log at
    the logged time (1σ = last digit/√12). A passage cut by the start or end of the log is
    ignored.

    Pairing: each impact is a passage toward the bumper followed by one away from it; between
    an away passage and the next toward one the cart flies up the incline and back through the
    same beam, so those two passages take *equal* times (uniform acceleration is time-reversal
    symmetric), while the two around an impact differ by the restitution. The phase of the
    alternation is the one whose 'flight' pairs are the more symmetric over the first flights.
    Each flight also gives g·sin θ = 2L/(τ(F + τ)) (F the time out of the beam); a flight
    that is not symmetric or disagrees with the median g·sin θ means the away passage before it
    was partial (the cart turned inside the beam): that impact keeps only its toward passage
    and every later block is dropped. An away passage with no later passage is partial too
    (the log is assumed to run until the cart rests).

    Impact time, with gate_distance d: the cart leaves the beam at v = L/τ + g·τ/2 and reaches
    the bumper at V = √(v² + 2g·d) after 2d/(v + V) — the start of contact; rebound speed
    likewise from the away passage. Without d: the gap G between the passages is split as if
    the contact were instantaneous and the distance in and out the same, which under uniform
    acceleration gives t = t_off + G(gG + 2w)/(2(gG + v + w)) (w the speed entering the beam
    on the way out); the speeds reported are then the passage speeds L/τ at the gate.
    """
    flag_length = check_range("flag_length", flag_length, *FLAG_LENGTH_RANGE, unit="m")
    if gate_distance is not None:
        gate_distance = check_range("gate_distance", gate_distance, *GATE_DISTANCE_RANGE,
                                    unit="m")
    table = _table_of_kind(path, "photogate", "no gate-state column",
                           "a photogate log (expected e.g. 'Latest: Time (s)' and "
                           "'Latest: GateState'")
    _check_duplicates(path, table)
    runs = _runs(path, table, {"state": (None, None)})
    notes = [f"file variant: {table.variant}; {len(runs)} run(s): "
             + ", ".join(f"run {k} = '{r.label or '(unlabelled)'}'" for k, r in enumerate(runs)),
             f"flag length {flag_length:g} m"]
    parts = []
    for number, run in enumerate(runs):  # loop over runs
        state_index = next(j for j, c in enumerate(table.columns)
                           if c.run == run.label and _is_state(c))
        result = _photogate_run(path, table, run, state_index, flag_length, gate_distance, notes)
        parts.append(result + (np.full(result[0].size, number),))
    merged = [np.concatenate([p[q] for p in parts]) for q in range(6)]
    return _impact_frame(path, "photogate", notes, merged[0], merged[1],
                         impact_speed=merged[2], rebound_speed=merged[3],
                         speed_uncertainty=merged[4], run=merged[5])
