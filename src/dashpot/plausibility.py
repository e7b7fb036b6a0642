"""Whether a sequence of impact times is a ball bouncing to rest, before anything is fitted to it.

A bouncing ball's flight times shrink at every bounce: T_{n+1} = ε·T_n with the restitution
ε < 1 changing smoothly with impact speed and scattering by a few % from bounce to bounce (real
recordings: 0.2-0.7 % [1]_, a log-ratio scatter of about 1 % about the trend). Clicks at random
times are not: about half of their intervals are longer than the one before, and a chain of them
picked to shrink (an impact detector choosing among many transients) keeps long stretches of
equal intervals and steps between them, with ratios scattering by 5-20 %.

Two tests, on the ratios r_n = T_{n+1}/T_n:

* growing intervals: r_n > 1 by more than 3σ of the timing noise, where neither interval is
  flagged by :func:`dashpot.bounces.bounce_table` as hiding a missed impact or holding a
  spurious one (those the fit accounts for). More than a quarter of the ratios growing is not a
  bounce train.
* scatter: the robust scatter of ln r_n about a smooth trend in ln T_n (:func:`ratio_trend`),
  less the timing noise (in quadrature), above 5 % is not a bounce train (from six ratios on:
  fewer cannot tell a trend from scatter).

References
----------
.. [1] The recordings in ``../shared/data`` (README there): restitution scatter of about
   0.2-0.3 % for a ping-pong ball and 0.7 % for a bouncy ball.
.. [2] J. R. Taylor, *An Introduction to Error Analysis*, 2nd ed., University Science Books
   (1997), ch. 3 (propagation of independent errors to first order).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .errors import InputError

__all__ = ["ratio_trend", "bounce_train_problem", "check_bounce_train", "NOT_A_BOUNCE_TRAIN",
           "MAX_GROWING_FRACTION", "MAX_RATIO_SCATTER", "implied_acceleration",
           "acceleration_problem"]

MAX_GROWING_FRACTION = 0.25  # of the interval ratios that may exceed 1 beyond the timing noise
MAX_RATIO_SCATTER = 0.05  # of ln(interval ratio) about its trend, beyond the timing noise
_MIN_RATIOS_FOR_SCATTER = 6
NOT_A_BOUNCE_TRAIN = "intervals do not shrink as a bouncing ball's do"  # start of the message
ACCELERATION_TOLERANCE = 0.25  # relative: friction makes a cart's legs differ by ~5-10 %
_MIN_FLIGHTS = 3


def ratio_trend(impact_times, *, floor=0.0, rounds=3, jitter=0.0, paired=False):
    """Trend of ln(next interval / interval) against ln(interval), fitted robustly.

    A straight line, or a parabola from nine ratios on (restitution may change faster at high
    speed), refitted up to `rounds` times without the ratios more than 3 scatters off it: a
    missed impact doubles an interval, and the two ratios around it (about 1.9 and 0.5) would
    bend the fit. The first fit leaves out the ratios more than 5 robust scatters (1.4826 ×
    the median absolute deviation) off their median, unless that leaves fewer than half:
    a few ratios of 0.2 or 4 (a ring's burst taken for an impact) bend a least-squares fit
    through all ratios so far that every later round keeps them.

    Timing errors weigh most on the short intervals at the train's end: a time off by δ
    moves the ln ratios it enters by about δ/T, twice that on the ratio of its own two
    intervals. Given the `jitter` σ of the times, the variance of ln(T₂/T₁) is
    σ²[(1/T₁ + 1/T₂)² + 1/T₁² + 1/T₂²] to first order [2]_; each ratio is weighted in the fit
    by the inverse of `floor`² plus that variance, and is left out only when more than 3
    times their root sum off the trend. Where `paired`, a ratio left out also takes out its
    neighbours on the other side of the trend: a time off moves the ratio of its own two
    intervals to one side and the ratios before and after it to the other, and a neighbour
    left in bends the fit as far as the ratio left out would have.

    Parameters
    ----------
    impact_times : array_like
        At least four increasing impact times (s).
    floor : float, default 0
        Smallest scatter returned (in ln ratio).
    rounds : int, default 3
    jitter : float, default 0
        Timing error (s, 1σ) of each of `impact_times`.
    paired : bool, default False
        Leave out, with each ratio left out, its neighbours on the other side of the trend.

    Returns
    -------
    coefficients : ndarray
        Polynomial coefficients (highest power first) of ln ratio against ln interval (s).
    scatter : float
        Robust standard deviation of ln ratio about the trend (1.4826 × the median absolute
        deviation of the residuals kept), at least `floor`.
    """
    intervals = np.diff(np.asarray(impact_times, dtype=float))
    log_ratio = np.log(intervals[1:] / intervals[:-1])
    log_interval = np.log(intervals[:-1])
    # Variance of each ln ratio that timing errors of `jitter` on its three times give.
    timing = jitter**2 * ((1 / intervals[1:] + 1 / intervals[:-1]) ** 2
                          + 1 / intervals[1:] ** 2 + 1 / intervals[:-1] ** 2)
    # The first fit starts without the ratios far off their median (5 robust scatters): two
    # ratios of a missed impact or a ring taken for one (ln ratio of ±0.7 or more) would bend
    # a least-squares parabola through all of them, widening the scatter the next rounds
    # start from until nothing is left out.
    off_median = np.abs(log_ratio - _median(log_ratio))
    spread = 1.4826 * _median(off_median)
    keep = off_median <= 5.0 * max(spread, floor, 1e-12)
    if keep.sum() < max(3, log_ratio.size // 2):
        keep = np.ones(log_ratio.size, dtype=bool)
    for _ in range(rounds):
        degree = 2 if keep.sum() >= 9 else 1
        weights = 1 / np.sqrt(max(floor, 1e-3) ** 2 + timing[keep]) if jitter else None
        coefficients = np.polyfit(log_interval[keep], log_ratio[keep], degree, w=weights)
        residual = log_ratio - np.polyval(coefficients, log_interval)
        scatter = max(1.4826 * _median(np.abs(residual[keep] - _median(residual[keep]))),
                      floor)
        inside = np.abs(residual) <= 3.0 * np.sqrt(scatter**2 + timing)
        if paired:
            off = ~inside
            opposite = np.sign(residual[1:]) != np.sign(residual[:-1])
            inside[1:] &= ~(off[:-1] & opposite)
            inside[:-1] &= ~(off[1:] & opposite)
        if inside.sum() < 3 or (inside == keep).all():
            break
        keep = inside
    return coefficients, scatter


def _median(values):
    """``np.median`` of a 1-D float array, to the last bit (the middle value, or the mean of
    the middle two; NaN if any value is), without its overhead: the robust fits here take
    the medians of tens of values, many times per recording."""
    ordered = np.sort(values)  # NaN last
    half = ordered.size // 2
    if ordered.size == 0 or np.isnan(ordered[-1]):
        return np.float64(np.nan)
    # Summed onto 0.0 as np.mean sums (a lone −0.0 gives 0.0).
    if ordered.size % 2:
        return 0.0 + ordered[half]
    return (0.0 + ordered[half - 1] + ordered[half]) / 2


def bounce_train_problem(times, sigma=None):
    """Why the intervals between `times` are not those of a ball bouncing to rest, or ''.

    Parameters
    ----------
    times : array_like
        Increasing impact times (s) of one run.
    sigma : array_like, optional
        Their 1σ uncertainties (s); missing or NaN count as 0.

    Returns
    -------
    str
        '' for a plausible bounce train (or fewer than three impacts, which say nothing), else
        the reason in plain words, with the numbers (see the module notes for the tests).
    """
    from .bounces import interval_ratios

    times = np.asarray(times, dtype=float)
    if times.size < 3 or not np.all(np.diff(times) > 0):
        return ""  # too few to judge, or refused by the readers and the fit for what they are
    # Unknown (missing or NaN) uncertainties count as 0, as documented: a NaN tolerance would
    # silently pass every ratio.
    sigma = np.zeros(times.size) if sigma is None else np.nan_to_num(
        np.asarray(sigma, dtype=float), nan=0.0)
    if not np.all(np.isfinite(times) & np.isfinite(sigma) & (sigma >= 0)):
        raise ValueError("impact times and their uncertainties must be finite, the "
                         "uncertainties ≥ 0")
    _, ratio, ratio_sigma, flags = interval_ratios(times, sigma)
    glitch = (flags == "missed") | (flags == "spurious")
    explained = glitch[:-1] | glitch[1:]  # the fit bridges a missed or drops a spurious impact
    growing = (ratio > 1.0 + 3.0 * ratio_sigma) & ~explained
    if growing.sum() > MAX_GROWING_FRACTION * ratio.size:
        worst = int(np.argmax(np.where(growing, ratio, -np.inf)))
        return (f"{int(growing.sum())} of {ratio.size} intervals are longer than the one before "
                f"(up to {ratio[worst]:.3g} times, the interval from {times[worst + 1]:.6g} s "
                f"to {times[worst + 2]:.6g} s), where a ball's shrink at every bounce")
    if ratio.size >= _MIN_RATIOS_FOR_SCATTER:
        _, scatter = ratio_trend(times)
        noise = float(np.median(ratio_sigma / ratio))
        excess = np.sqrt(max(scatter**2 - noise**2, 0.0))
        if excess > MAX_RATIO_SCATTER:
            return (f"the ratios of successive intervals scatter by {100 * excess:.0f} % about "
                    f"their trend, a bouncing ball's by a few % at most (the impacts are "
                    f"clicks or noise, not one ball's bounces)")
    return ""


def check_bounce_train(impacts, source):
    """Raise InputError naming `source` unless the impacts are a ball bouncing to rest.

    Parameters
    ----------
    impacts : pandas.DataFrame
        Impact table of :mod:`dashpot.ingest` (``time``, optional ``time_uncertainty`` and
        ``run``). Only the first run is checked: it is the one fitted
        (:func:`dashpot.fit.prepare_data`).
    source : str or os.PathLike
        The file the impacts come from.

    Raises
    ------
    InputError
        "intervals do not shrink as a bouncing ball's do: <reason>" (:func:`bounce_train_problem`).
    """
    table = impacts
    if "run" in table and table["run"].nunique() > 1:
        table = table[table["run"] == table["run"].min()]
    sigma = table["time_uncertainty"] if "time_uncertainty" in table else None
    problem = bounce_train_problem(table["time"].to_numpy(float), sigma)
    if problem:
        raise InputError(source, f"{NOT_A_BOUNCE_TRAIN}: {problem}")


def implied_acceleration(impacts):
    """Driving acceleration (m/s²) the measured speeds and flight times imply, and the number
    of flights it comes from.

    Under a constant acceleration a along the track, a flight that leaves an impact at the
    rebound speed u and meets the next at the impact speed w lasts T = (u + w)/a (up and
    back down, [2]_): a = (u + w)/T. The median over the flights of each run (consecutive
    rows of one run with both speeds measured) is returned; on an incline with rolling
    friction the up and down legs' accelerations differ by a few %, and this is about their
    harmonic mean.

    Parameters
    ----------
    impacts : pandas.DataFrame
        Impact table of :mod:`dashpot.ingest` (``time``, ``impact_speed``, ``rebound_speed``,
        optional ``run``).

    Returns
    -------
    acceleration : float
        m/s²; NaN where no flight has both speeds.
    flights : int

    References
    ----------
    .. [2] Kinematics of constant acceleration: v = u − a·t up, w = a·t' down, T = t + t'.
    """
    if not {"impact_speed", "rebound_speed"} <= set(impacts.columns):
        return float("nan"), 0
    runs = impacts["run"] if "run" in impacts else pd.Series(0, index=impacts.index)
    values = []
    for _, table in impacts.groupby(runs, sort=True):
        table = table.sort_values("time")
        flight = np.diff(table["time"].to_numpy(float))
        launch = table["rebound_speed"].to_numpy(float)[:-1]
        landing = table["impact_speed"].to_numpy(float)[1:]
        usable = np.isfinite(launch) & np.isfinite(landing) & (flight > 0)
        values.append((launch[usable] + landing[usable]) / flight[usable])
    values = np.concatenate(values) if values else np.zeros(0)
    if values.size == 0:
        return float("nan"), 0
    return float(np.median(values)), int(values.size)


def acceleration_problem(impacts, driving_acceleration):
    """Plain words where the measured speeds and flight times disagree with the driving
    acceleration the fits assume (m/s²), by more than a quarter over three flights or more
    (:func:`implied_acceleration`); "" where they agree or cannot tell.

    A cart on an incline fitted under free fall, or a dropped ball under a cart's g_eff,
    misfits by orders of magnitude (χ²/ν of 10⁵ and more) and its contact parameters mean
    nothing: the scene must give the acceleration.
    """
    implied, flights = implied_acceleration(impacts)
    if flights < _MIN_FLIGHTS or not np.isfinite(implied) or (
            abs(implied / driving_acceleration - 1.0) <= ACCELERATION_TOLERANCE):
        return ""
    return (f"the measured speeds and flight times imply a driving acceleration of "
            f"{implied:.3g} m/s² (median of {flights} flights: (rebound + next impact "
            f"speed) / flight time), the fits assume {driving_acceleration:.6g} m/s²: give the "
            f"scene's g_eff or incline angle (apparatus: g_eff, incline_angle)")
