"""From a table of impacts to a table of bounces: intervals, rebound speeds, per-bounce ε.

Missed and spurious impacts are detected from the physics of a bouncing ball: successive
intervals shrink roughly geometrically, T_{n+1} ≈ r·T_n with r ≈ ε slowly varying. An interval
about (1 + r) times longer than predicted hides a missed impact (seen in real phyphox exports);
an interval split in two parts that add up to the prediction contains a spurious one. Flagged
rows stay in the table: nothing is dropped silently.

With air drag (a light ball, given its drag constant k_d) a flight of launch speed u lasts
T(u) = (v_t/g)(atan w + asinh w), w = u/v_t, and lands at L(u) = u/√(1 + w²) < u
(:func:`dashpot.physics.flight.drag_flight`): the interval ratio then underestimates ε, by
3 % for a ping-pong ball at 2 m/s. The table inverts T for the launch speeds and adds the
drag-corrected ε = u_{n+1}/L(u_n), launch over landing speed of the impact between two flights.

References
----------
.. [1] A. D. Bernstein, "Listening to the coefficient of restitution", Am. J. Phys. 45, 41-44
   (1977): ε from successive flight times, v = g·T/2.
.. [2] I. Stensgaard and E. Lægsgaard, "Listening to the coefficient of restitution —
   revisited", Am. J. Phys. 69, 301-305 (2001): the contact duration and the time origin.
.. [3] P. Timmerman and J. P. van der Weele, "On the rise and fall of a ball with linear or
   quadratic drag", Am. J. Phys. 67, 538-546 (1999): rise and fall times under quadratic drag.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ._validation import check_nonnegative, check_positive
from .physics.flight import drag_flight

__all__ = ["bounce_table", "interval_ratios", "drag_correction", "launch_speed",
           "BOUNCE_COLUMNS", "DRAG_COLUMNS", "DRAG_CORRECTION_COLUMNS"]

BOUNCE_COLUMNS = ("run", "bounce", "start_time", "interval", "interval_uncertainty",
                  "rebound_speed", "rebound_speed_uncertainty", "restitution",
                  "restitution_uncertainty", "flag", "restitution_flag")
# Added after BOUNCE_COLUMNS where the caller gives a drag constant.
DRAG_COLUMNS = ("landing_speed", "landing_speed_uncertainty", "restitution_corrected",
                "restitution_corrected_uncertainty")
# What :func:`drag_correction` returns, one value per interval: the launch speed of the drag
# flight (which ``bounce_table`` puts in ``rebound_speed``), DRAG_COLUMNS, and the part of the
# corrected ε's uncertainty that comes from the drag constant's (shared by every bounce).
DRAG_CORRECTION_COLUMNS = ("launch_speed", "launch_speed_uncertainty", *DRAG_COLUMNS,
                           "restitution_corrected_drag_uncertainty")

# A ratio of consecutive intervals this far from the local trend (relative, beyond the timing
# noise) is not a normal bounce. Real balls change ε by a few % between bounces.
TREND_TOLERANCE = 0.12
TREND_WINDOW = 7  # bounces in the running median of interval ratios


def _rolling_median(values):
    """Centred running median over TREND_WINDOW values, NaNs skipped, shorter at the ends
    (pandas' ``rolling(center=True, min_periods=1).median()``); NaN where a window holds
    nothing."""
    half = TREND_WINDOW // 2
    padded = np.concatenate([np.full(half, np.nan), values, np.full(half, np.nan)])
    # Sorting puts the NaNs of each window last: the median is the middle of the first
    # `valid` entries (np.nanmedian does the same, far slower on many short rows).
    ordered = np.sort(np.lib.stride_tricks.sliding_window_view(padded, TREND_WINDOW), axis=1)
    valid = np.sum(~np.isnan(ordered), axis=1)
    low = np.take_along_axis(ordered, np.maximum(valid - 1, 0)[:, None] // 2, axis=1)[:, 0]
    high = np.take_along_axis(ordered, (valid // 2)[:, None], axis=1)[:, 0]
    return np.where(valid > 0, 0.5 * (low + high), np.nan)


def _local_ratio(ratios):
    """Running median of the interval ratios, robust to the outliers it is meant to expose."""
    first = _rolling_median(ratios)
    typical = np.abs(ratios / first - 1.0) < 2 * TREND_TOLERANCE
    second = _rolling_median(np.where(typical, ratios, np.nan))
    return np.where(np.isnan(second), first, second)


def launch_speed(flight_time, g, drag):
    """Launch speed u of a flight lasting T under gravity and quadratic drag: T(u) inverted.

    Parameters
    ----------
    flight_time : float or ndarray
        Flight duration T in s (>= 0), from launch to landing at the launch height.
    g : float or ndarray
        Effective gravity g_eff in m/s² (> 0).
    drag : float or ndarray
        Drag constant k_d in 1/m (>= 0); 0 gives u = gT/2 exactly.

    Returns
    -------
    ndarray
        u in m/s, with T(u) of :func:`dashpot.physics.flight.drag_flight` equal to T to a few
        ulp.

    Notes
    -----
    With w = u√(k_d/g) the flight lasts T = (atan w + asinh w)/√(k_d g). Writing w = sinh x
    turns it into gd(x) + x = s with s = T√(k_d g) and the Gudermannian gd(x) = atan(sinh x),
    whose slope 1 + sech x lies in (1, 2]: the left side is increasing and concave, so Newton's
    method started at x = s/2 (below the root, as gd(x) ≤ x) climbs to it monotonically and
    converges quadratically, at every s, without a bracket.
    """
    flight_time = check_nonnegative("flight_time", flight_time)
    g = check_positive("g", g)
    drag = check_nonnegative("drag", drag)
    flight_time, g, drag = np.broadcast_arrays(flight_time, g, drag)
    target = flight_time * np.sqrt(drag * g)
    x = 0.5 * target
    with np.errstate(over="ignore"):  # cosh overflows only where sech x is 0 anyway
        for _ in range(100):
            step = (target - x - 2.0 * np.arctan(np.tanh(0.5 * x))) / (1.0 + 1.0 / np.cosh(x))
            x = x + step
            if np.all(np.abs(step) <= 4.0 * np.finfo(float).eps * x):
                break
        positive = drag > 0.0
        # u = sinh(x)·√(g/k_d); without drag x is 0 and u is the gravity flight's gT/2.
        scale = np.sqrt(g / np.where(positive, drag, 1.0))
        return np.where(positive, np.sinh(x) * scale, 0.5 * g * flight_time)


def bounce_table(impacts, *, g, contact_duration=0.0, drag_constant=None):
    """Intervals, rebound speeds and per-bounce restitution from an impact table, run by run.

    Parameters
    ----------
    impacts : pandas.DataFrame
        Impact table of :mod:`dashpot.ingest`: ``time`` in s, optional ``time_uncertainty``
        (1σ in s; NaN = unknown), ``run`` (runs side by side; 0 if absent) and ``flag`` (the
        motion reader's "ok", "few_samples" or "inferred"; "few_samples" impacts carry their
        larger σ into the uncertainties). Times must
        increase within each run; at least one run needs three impacts.
    g : float
        Acceleration pulling the ball back to the surface in m/s² (g·sin θ on an incline;
        with drag, the effective gravity with buoyancy and added mass,
        :attr:`dashpot.scene.AirDrag.effective_gravity`).
    contact_duration : float, default 0
        Contact duration in s where the scene knows it; subtracted from each interval before
        the flight-time speed estimate.
    drag_constant : float, optional
        Air drag constant k_d in 1/m (:attr:`dashpot.scene.AirDrag.drag_constant`), taken as
        exact. Given, the rebound speeds come from the drag flight and ``DRAG_COLUMNS`` are
        added; None (the default) leaves the table as without drag.

    Returns
    -------
    pandas.DataFrame
        One row per interval n (impact n to n + 1 of the same run; never across runs), columns
        ``BOUNCE_COLUMNS``: ``run``, ``bounce`` n (from 0 in each run), ``start_time`` (s),
        ``interval`` T_n (s) and its 1σ uncertainty, ``rebound_speed`` g·(T_n − τ_c)/2 (m/s)
        and its uncertainty, ``restitution`` T_{n+1}/T_n (NaN for the last interval of a run)
        and its uncertainty, ``flag`` judging the interval T_n: "ok", "missed" (an impact is
        missing inside it), "spurious" (it ends or starts at an impact that is not one),
        "irregular" (off the trend for another reason), "inferred" (it starts or ends at an
        impact the table's ``flag`` column marks "inferred": a contact the motion reader did
        not see reversing, its time not measured); and ``restitution_flag`` judging the
        ratio: "ok" only if both of its intervals T_n and T_{n+1} are "ok", else the flag of
        the first of them that is not (a ratio involving a flagged interval is never "ok"),
        and "last" where there is no next interval. ``attrs`` hold the notes.
        With a drag constant: ``rebound_speed`` is the launch speed u_n with T(u_n) = T_n − τ_c,
        ``landing_speed`` L(u_n) the speed of impact n + 1, and ``restitution_corrected``
        u_{n+1}/L(u_n) the ε of that impact (NaN for the last interval), each with its 1σ
        uncertainty from the impact times.

    Raises
    ------
    ValueError
        Times not finite or not increasing within a run, a negative or infinite
        ``time_uncertainty``, no run with three impacts, or a ``contact_duration`` not
        shorter than every interval.

    Notes
    -----
    Flight time T = τ_c + 2v/g gives v = g(T − τ_c)/2 [1]_ [2]_; the ratio of successive
    flight times estimates ε of the impact between them. Uncertainties are propagated from the
    impact times, with the shared middle impact of a ratio taken into account:
    σ_r² = (σ_{n+2}² + r²σ_n² + (1 + r)²σ_{n+1}²)/T_n². An unknown (NaN) σ makes the
    uncertainties that involve it NaN, never 0; the flags then judge those ratios against the
    trend tolerance alone.

    What the drag-corrected ε measures: given k_d, g_eff and τ_c, each flight time fixes its
    launch speed (T(u) is increasing) and hence its landing speed, so u_{n+1}/L(u_n) is the
    rebound over the impact speed of impact n + 1 [3]_. It is only as good as k_d: its
    uncertainty here is that of the timing alone, with the same three-impact propagation
    (∂ε/∂T_{n+1} = 1/(T'(u_{n+1})L_n), ∂ε/∂T_n = −ε L'(u_n)/(L_n T'(u_n))). The uncorrected
    ratio T_{n+1}/T_n stays in ``restitution``: it is what the impact times show directly.
    """
    g = float(check_positive("g", g))
    contact_duration = float(check_nonnegative("contact_duration", contact_duration))
    if drag_constant is not None:
        drag_constant = float(check_nonnegative("drag_constant", drag_constant))
    times = np.asarray(impacts["time"], dtype=float)
    if not np.all(np.isfinite(times)):
        raise ValueError(f"impact time {np.flatnonzero(~np.isfinite(times))[0]} is not finite")
    if "time_uncertainty" in impacts:
        sigma = np.asarray(impacts["time_uncertainty"], dtype=float)
    else:
        sigma = np.full(times.size, np.nan)
    bad = np.isinf(sigma) | (np.nan_to_num(sigma) < 0)
    if bad.any():
        raise ValueError(f"time_uncertainty {sigma[bad][0]!r} of impact "
                         f"{np.flatnonzero(bad)[0]} must be ≥ 0 and finite (NaN = unknown)")
    run = (np.asarray(impacts["run"], dtype=int) if "run" in impacts
           else np.zeros(times.size, dtype=int))
    # The motion reader's flag of each impact: an "inferred" one was not seen reversing.
    inferred = (np.asarray(impacts["flag"]).astype(str) == "inferred") if "flag" in impacts \
        else np.zeros(times.size, bool)
    runs = list(dict.fromkeys(run))  # order of first appearance
    sizes = [int(np.sum(run == number)) for number in runs]
    if max(sizes, default=0) < 3:
        raise ValueError(f"a bounce table needs at least three impacts in a run; got "
                         f"{', '.join(map(str, sizes)) or 0}")
    parts = []
    for number in runs:  # loop over runs
        members = np.flatnonzero(run == number)
        if np.any(np.diff(times[members]) <= 0):
            raise ValueError(f"impact times must increase strictly within a run (run {number})")
        if members.size >= 2:
            parts.append(_run_bounces(times[members], sigma[members], g, contact_duration,
                                      number, drag_constant, inferred[members]))
    table = pd.concat(parts, ignore_index=True)
    # Each interval contains a contact: a longer contact makes g(T - contact)/2 negative.
    too_short = np.flatnonzero(table["interval"].to_numpy() <= contact_duration)
    if too_short.size:
        row = table.iloc[too_short[0]]
        raise ValueError(f"contact_duration {contact_duration:g} s is not shorter than the "
                         f"interval {row['interval']:.6g} s of bounce {row['bounce']} (run "
                         f"{row['run']}): the rebound speed g(T - contact)/2 would be negative")
    flags, ratio_flags = table["flag"], table["restitution_flag"]
    unknown = int(np.sum(np.isnan(sigma)))
    table.attrs["notes"] = [
        f"{np.sum(flags == 'missed')} interval(s) hide a missed impact, "
        f"{np.sum(flags == 'spurious')} involve a spurious one, "
        f"{np.sum(flags == 'irregular')} are off the geometric trend otherwise"
        + (f", {np.sum(flags == 'inferred')} start or end at an inferred impact"
           if np.any(flags == "inferred") else "") + "; flagged rows kept",
        f"{int(np.sum(~ratio_flags.isin(['ok', 'last'])))} restitution value(s) involve a "
        f"flagged interval (restitution_flag)",
        "rebound speed from the flight time g(T - contact)/2 with contact duration "
        f"{contact_duration:g} s" if drag_constant is None else
        f"rebound speed from the flight time T - contact under gravity {g:g} m/s² and air drag "
        f"k_d = {drag_constant:g} 1/m (contact duration {contact_duration:g} s); "
        f"restitution_corrected is the rebound over the landing speed",
    ]
    if len(runs) > 1:
        table.attrs["notes"].append(f"{len(runs)} runs: intervals within each run only")
    if unknown:
        table.attrs["notes"].append(f"{unknown} impact time(s) without an uncertainty: the "
                                    f"uncertainties involving them are NaN")
    return table


def interval_ratios(times, sigma):
    """Intervals, their ratios and the flags judging them, for one run (arrays only).

    The core of :func:`bounce_table`, for callers that need no table (the plausibility check
    of every candidate chain).

    Parameters
    ----------
    times : ndarray
        Increasing impact times of one run (s).
    sigma : ndarray
        Their 1σ (s); NaN = unknown.

    Returns
    -------
    intervals : ndarray
        T_n (s), one fewer than `times`.
    ratio : ndarray
        T_{n+1}/T_n, one fewer than `intervals`.
    ratio_sigma : ndarray
        1σ of each ratio from the three impact times it depends on (see :func:`bounce_table`,
        Notes); NaN where a σ is unknown.
    flags : ndarray of object
        "ok", "missed", "spurious" or "irregular" for each interval.
    """
    intervals = np.diff(times)
    ratio = intervals[1:] / intervals[:-1]
    ratio_sigma = np.sqrt(sigma[2:] ** 2 + (ratio * sigma[:-2]) ** 2
                          + ((1 + ratio) * sigma[1:-1]) ** 2) / intervals[:-1]
    # An unknown σ leaves the timing term out of the flags' tolerance, not the flags out.
    flags = _flag_intervals(intervals, ratio, np.nan_to_num(ratio_sigma))
    return intervals, ratio, ratio_sigma, flags


def _run_bounces(times, sigma, g, contact_duration, run, drag_constant=None, inferred=None):
    """Bounce table rows of one run (see bounce_table); `inferred` marks the impacts whose
    time the reader inferred."""
    intervals, ratio, ratio_sigma, flags = interval_ratios(times, sigma)
    interval_sigma = np.hypot(sigma[:-1], sigma[1:])
    if inferred is not None and inferred.any():
        # An interval from or to an inferred impact is not measured: said, unless another
        # flag already judges it.
        touched = inferred[:-1] | inferred[1:]
        flags = np.where(touched & (flags == "ok"), "inferred", flags).astype(object)
    ratio_flags = np.where(flags[:-1] != "ok", flags[:-1], flags[1:])
    table = pd.DataFrame({
        "run": np.full(intervals.size, run, dtype=int),
        "bounce": np.arange(intervals.size),
        "start_time": times[:-1],
        "interval": intervals,
        "interval_uncertainty": interval_sigma,
        "rebound_speed": 0.5 * g * (intervals - contact_duration),
        "rebound_speed_uncertainty": 0.5 * g * interval_sigma,
        "restitution": np.append(ratio, np.nan),
        "restitution_uncertainty": np.append(ratio_sigma, np.nan),
        "flag": flags,
        "restitution_flag": np.append(ratio_flags, "last").astype(object),
    }, columns=list(BOUNCE_COLUMNS))
    if drag_constant is not None:
        _add_drag_columns(table, intervals - contact_duration, sigma, g, drag_constant)
    return table


def _add_drag_columns(table, flight_times, sigma, g, drag):
    """Launch speeds from the drag flight, landing speeds and the drag-corrected ε, in place
    (:func:`drag_correction` of the flight times, `sigma` the impact times' 1σ).

    A too-long contact gives a negative flight time: the caller refuses it, so those rows
    are filled with NaN here rather than raising first.
    """
    corrected = _corrected(flight_times, sigma, g, drag)
    table["rebound_speed"] = corrected["launch_speed"]
    table["rebound_speed_uncertainty"] = corrected["launch_speed_uncertainty"]
    for name in DRAG_COLUMNS:
        table[name] = corrected[name]


def drag_correction(times, g, drag_constant, *, time_uncertainty=None, contact_duration=0.0,
                    drag_uncertainty=0.0):
    """Drag-corrected launch and landing speeds and restitution of a train of impact times.

    Each flight time T_n − τ_c fixes the launch speed u_n of flight n under gravity and
    quadratic drag (:func:`launch_speed`), hence its landing speed L(u_n), the speed of impact
    n + 1; the ε of that impact is u_{n+1}/L(u_n) [3]_. Without drag it is the interval ratio.

    Parameters
    ----------
    times : array_like, shape (..., n)
        Impact times of one run in s, strictly increasing along the last axis (n >= 2);
        leading axes hold independent trains of the same length.
    g : float
        Effective gravity g_eff in m/s² (with buoyancy and added mass,
        :attr:`dashpot.scene.AirDrag.effective_gravity`, or a fit's ``g_eff``).
    drag_constant : float
        Drag constant k_d in 1/m (>= 0).
    time_uncertainty : array_like, optional
        1σ of each impact time in s, broadcast against `times`; NaN (or None, the default)
        for unknown, which makes the uncertainties that involve it NaN.
    contact_duration : float, default 0
        Contact duration τ_c in s, subtracted from each interval.
    drag_uncertainty : float, default 0
        1σ of k_d in 1/m: carried to ``restitution_corrected_drag_uncertainty``.

    Returns
    -------
    dict of str -> ndarray
        Keys :data:`DRAG_CORRECTION_COLUMNS`, each of shape (..., n − 1), one value per
        interval n: ``launch_speed`` u_n and ``landing_speed`` L(u_n) in m/s, with their 1σ
        from the impact times; ``restitution_corrected`` u_{n+1}/L(u_n), the ε of impact
        n + 1 (NaN for the last interval), with its 1σ from the impact times
        (``restitution_corrected_uncertainty``) and the 1σ that k_d's uncertainty adds
        (``restitution_corrected_drag_uncertainty``: the same error for every bounce, so
        kept apart from the timing error, which differs from bounce to bounce).

    Raises
    ------
    ValueError
        Times not finite or not increasing, fewer than two, a negative or infinite time
        uncertainty, or a contact duration not shorter than every interval.

    Notes
    -----
    The timing errors are propagated to first order through the three impacts each ε
    depends on, as in :func:`bounce_table`; the slopes dT/du and dL/du are those of
    :func:`dashpot.physics.flight.drag_flight`. k_d's error is carried by the secant: half
    the change of ε between k_d ± σ_k (the lower end clipped at 0), which is the first-order
    propagation where ε is linear in k_d over ±σ_k and stays finite at k_d = 0.
    """
    times = np.asarray(times, dtype=float)
    if times.ndim == 0 or times.shape[-1] < 2:
        raise ValueError(f"drag_correction needs at least two impact times; got "
                         f"{times.shape[-1] if times.ndim else 0}")
    if not np.all(np.isfinite(times)):
        raise ValueError("impact times must be finite")
    if np.any(np.diff(times, axis=-1) <= 0):
        raise ValueError("impact times must increase strictly")
    g = float(check_positive("g", g))
    drag = float(check_nonnegative("drag_constant", drag_constant))
    drag_sigma = float(check_nonnegative("drag_uncertainty", drag_uncertainty))
    contact_duration = float(check_nonnegative("contact_duration", contact_duration))
    sigma = np.full(times.shape, np.nan) if time_uncertainty is None else \
        np.broadcast_to(np.asarray(time_uncertainty, dtype=float), times.shape)
    if np.any(np.isinf(sigma) | (np.nan_to_num(sigma) < 0)):
        raise ValueError("time_uncertainty must be >= 0 and finite (NaN = unknown)")
    flight_times = np.diff(times, axis=-1) - contact_duration
    if np.any(flight_times <= 0):
        raise ValueError(f"contact_duration {contact_duration:g} s is not shorter than every "
                         f"interval")
    out = _corrected(flight_times, sigma, g, drag)
    if drag_sigma > 0:
        # The secant over k_d ± σ_k (see the Notes).
        low, high = max(drag - drag_sigma, 0.0), drag + drag_sigma
        change = (_corrected(flight_times, sigma, g, high)["restitution_corrected"]
                  - _corrected(flight_times, sigma, g, low)["restitution_corrected"])
        out["restitution_corrected_drag_uncertainty"] = np.abs(change) * drag_sigma / (high - low)
    else:
        out["restitution_corrected_drag_uncertainty"] = np.where(
            np.isnan(out["restitution_corrected"]), np.nan, 0.0)
    return {name: out[name] for name in DRAG_CORRECTION_COLUMNS}


def _corrected(flight_times, sigma, g, drag):
    """Unchecked core of :func:`drag_correction` along the last axis: `flight_times` (..., m)
    (NaN where not positive), `sigma` (..., m + 1) the impact times' 1σ."""
    valid = flight_times > 0.0
    launch = np.full(flight_times.shape, np.nan)
    launch[valid] = launch_speed(flight_times[valid], g, drag)
    flight = drag_flight(np.nan_to_num(launch), g, drag)
    duration_slope = np.where(valid, flight.duration_slope, np.nan)  # dT/du
    landing = np.where(valid, flight.landing_speed, np.nan)
    interval_sigma = np.hypot(sigma[..., :-1], sigma[..., 1:])
    launch_sigma = interval_sigma / duration_slope
    eps = launch[..., 1:] / landing[..., :-1]
    # ε of impact n + 1 depends on T_n and T_{n+1}, i.e. on impacts n, n + 1 and n + 2.
    by_next = 1.0 / (duration_slope[..., 1:] * landing[..., :-1])
    by_this = -eps * flight.landing_slope[..., :-1] / (landing[..., :-1]
                                                       * duration_slope[..., :-1])
    eps_sigma = np.sqrt((by_this * sigma[..., :-2]) ** 2
                        + ((by_this - by_next) * sigma[..., 1:-1]) ** 2
                        + (by_next * sigma[..., 2:]) ** 2)
    last = np.full(eps.shape[:-1] + (1,), np.nan)
    return {"launch_speed": launch, "launch_speed_uncertainty": launch_sigma,
            "landing_speed": landing,
            "landing_speed_uncertainty": flight.landing_slope * launch_sigma,
            "restitution_corrected": np.concatenate([eps, last], axis=-1),
            "restitution_corrected_uncertainty": np.concatenate([eps_sigma, last], axis=-1)}


def _flag_intervals(intervals, ratio, ratio_sigma):
    """Classify each interval against the local geometric trend of the intervals.

    ``ratio[k]`` = T_{k+1}/T_k judges interval k + 1 against the prediction T_k·r.
    """
    n = intervals.size
    flags = np.full(n, "ok", dtype=object)
    if n < 3:
        return flags
    trend = _local_ratio(ratio)
    tolerance = TREND_TOLERANCE + 3 * ratio_sigma / np.maximum(trend, 1e-12)
    deviation = ratio / trend - 1.0
    # About (1 + r) times longer than predicted: an impact was missed inside the interval.
    missed = (np.abs(ratio / (trend * (1.0 + trend)) - 1.0) < tolerance) & (deviation > tolerance)
    after_missed = np.zeros(ratio.size, bool)
    after_missed[1:] = missed[:-1]
    missed &= ~after_missed
    after_missed[1:] = missed[:-1]
    # A spurious impact splits interval k+1 into two parts adding up to T_k·r (judged only
    # after a normal interval: after a merged one every interval looks short).
    pair_sum = np.append((intervals[1:-1] + intervals[2:]) / intervals[:-2], np.nan)
    split = np.abs(pair_sum / trend - 1.0) < tolerance
    spurious_start = (deviation < -tolerance) & split & ~after_missed & ~missed
    following = np.zeros(n, bool)
    following[2:] = spurious_start[:-1]
    flags[1:][missed] = "missed"
    flags[1:][spurious_start] = "spurious"
    flags[following] = "spurious"
    # The ratio after an off-trend interval is off-trend too: blame the first one only.
    after_flag = np.zeros(ratio.size, bool)
    after_flag[1:] = (flags[1:-1] != "ok") | spurious_start[:-1]
    irregular = (np.abs(deviation) > tolerance) & (flags[1:] == "ok") & ~after_flag
    flags[1:][irregular] = "irregular"
    return flags
