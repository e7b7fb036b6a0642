"""The impacts among the transients: the chain whose intervals shrink as a ball bouncing to
rest makes them, its extension and the impacts its trend predicts where no transient was chosen
(step 3 of :mod:`dashpot.ingest.audio`).

References
----------
.. [5] T. Erickson, "Modeling a bouncing ball with exponential functions and infinite
   series", Mathematics Teacher 113(3), 233-236 (2020) (geometric shrinking of the intervals).
.. [6] J. Glover, V. Lazzarini and J. Timoney, "Real-time detection of musical onsets with
   linear prediction and sinusoidal modeling", EURASIP J. Adv. Signal Process. 2011, 68
   (2011).
.. [7] J. Makhoul, "Linear prediction: a tutorial review", Proc. IEEE 63(4), 561-580 (1975).
"""

from __future__ import annotations

from math import exp, log
from statistics import median

import numpy as np
from scipy import signal

from ..plausibility import ratio_trend
from . import envelope as _envelope
from .envelope import (_AIC_MARGIN, _BACK_SEARCH_SECONDS, _CLIP_RUN, _CLIP_TOLERANCE,
                       _MERGE_SECONDS, _NOISE_FLOOR, _RING_GAP_SECONDS, _STA_SECONDS,
                       _WEAK_JUMP_FACTOR, _channel_weights, _onset_picks)
from .onset import _onset_posterior


# Selection (step 3).
_RATIO_BOUNDS = (0.45, 1.2)  # next interval / this interval for successive bounces, at most
_GROWTH_ALLOWANCE = 0.05  # a ratio may exceed 1 by this (restitution scatter of a few %) plus
# 3σ of the rough onsets' jitter on both intervals: up to 1.2 on the last, few-ms intervals,
# 1.06 on intervals of 0.3 s (random clicks otherwise chain at ratios of up to 1.2)
_RATIO_SCATTER_FLOOR = 0.02  # in log(ratio)
_TREND_TIMING_SECONDS = 0.1e-3  # s: timing error of each onset the trend of the ratios allows
# for (fitted onsets err by 10-50 µs, more where taken on a ring's burst; of 0, 0.05, 0.1,
# 0.15 and 0.25 ms, 0.1 and 0.15 lost the fewest impacts on three development blocks)
_ONSET_JITTER = 0.5e-3  # s: a faint transient's rough onset may move by this much (first
# arrival or loud part), which matters on the last, short intervals
_NOISE_WEIGHT = 1.0  # score of any transient included in the chain, plus its log SNR
_SECONDARY_SECONDS = 0.16  # ringing, rattle and echoes come up to this long after an impact
_SECONDARY_WEIGHT = 0.25  # factor on the score of a transient that may be one of them
_SECONDARY_LOUDNESS = 3.0  # ... because a transient at least 1/3 as loud came before it
_MIN_POWER_RATIO = 1e-6  # onset power over the detection threshold, at least, in a weight
_LEADING_LOUDNESS = 10.0  # the first impact is within 20 dB of the loudest
_EXTENSION_SLACK = 0.2e-3  # s, added to the tolerance of a predicted impact time
_TAIL_IMPACTS = 20  # the last impacts of the chain are chosen again among weak transients too
_EXTENSION_LOUDNESS = 2.0  # a predicted impact is at most 6 dB fainter than the last ones
_IMPULSE_POWER_SHARE = 0.25  # a last bounce's impulse, in power, against the ones before it
_FAINT_IMPULSE_SHARE = 0.1  # ... or this (10 dB), where it jumps as much as a weak trigger's
_PROBE_WARMUP_SECONDS = 0.05  # high-pass settling before a probed stretch of the file
_PROBE_RING_JUMP = 1.5  # a probed impact's power rises this much (1.8 dB) over a ring or echo
# it starts inside: an impact about as loud as the sound it lands on adds as much again (3 dB),
# a fainter one less; the stream's separation of sounds (3 dB) stays stricter
_PROBE_SECONDARY_SECONDS = 0.3e-3  # a probed onset this close to a ring or echo time is one
_SECONDARY_RISE_SECONDS = 2e-3  # a probed onset this long after a ring or echo starts may be
# on that sound's rise
_CAUSE_DELAY_SECONDS = (_BACK_SEARCH_SECONDS, 0.2)  # of a ring's burst or an echo after its
# impact; closer ones are the impact's own first arrival, which the rough onset looks back for
_CAUSE_TOLERANCE = 0.3e-3  # s: the same delay after every impact, to the rough onsets' jitter
_CAUSE_SHARE = 0.25  # of the members that must have a transient at that delay before them
_CAUSE_FRACTION = 0.8  # a cause lies within this fraction of the interval before its member
_CAUSE_SPAN = 1.5  # the members sharing a cause's delay span intervals this different
_MOVE_TOLERANCE = 2 * _ONSET_JITTER  # s: a member and its cause, both rough onsets, each
# pulled early by up to the jitter (a ring or echo before them)
_MOST_BOUNCES = 3.0  # an interval spans at most this many of the one before (missed impacts)
_PERIODIC_RUN = 5  # successive intervals of periodic clicks, at least, as even as
_PERIODIC_SPREAD = 0.03  # this (of their median)
_DROP_GAP = 1.5  # an interval this much longer than the most bounces it can span is no flight
_MAX_DROP_RATIO = 0.99  # the ratio of successive flights (< 1: a train shrinks)
_DROP_RISE = 2.0  # ... or longer than the most, the impact after it this much louder
_ECHO_ROUGH_SECONDS = 1e-3  # s: a rough onset lies this close to the fitted one
_ECHO_SLACK_SECONDS = 2e-5  # s: an echo's fitted onset repeats its source's this closely
_ECHO_MATCH_SECONDS = 3e-5  # s: the loosest match of an echo to its source
_ECHO_FACTOR_SPREAD = 1.5  # an echo's amplitude is its source's times one factor, to this
_ECHO_GRID_SECONDS = 5e-4  # s: step of the delays tried
_ECHO_LOOSE_END = 2  # sounds after a train's echo that need not be echoes themselves
_SECONDARY_MARGIN = 2.0  # a secondary is at most this much louder than its usual level
_CAUSE_SEARCH_SECONDS = 0.5e-3  # s: a hidden impact lies this close to one delay before its burst
_MASK_SECONDS = 5e-3  # a sound hides an impact that starts at most this long after it
_FITTED_SECONDARY_SECONDS = 0.1e-3  # a fitted onset this close to the time of a secondary
# of a fitted impact is that secondary's start (fitted onsets err by some 10-50 µs)
_OWN_SECONDARY_LEVEL = 0.25  # secondaries this loud (relative) show after every impact
_LAST_SECONDARY_SECONDS = 1e-3  # the faint last impact's secondary, starting on the louder
# ones of the impacts before it, is timed up to 0.8 ms off its delay
_MIDWAY_LOUDNESS = 10.0  # an impact is not 20 dB fainter than both impacts around it
_HALVING_RUN = 5  # of six successive intervals of a chain that hold a stepped-over bounce:
# it took every other bounce
_HALVING_LOUDNESS = 0.5  # a stepped-over bounce is at least this loud against the fainter of
# the members around it (impact sounds fade by a few % per bounce)
_HALVING_SLACK = 0.01  # of the interval (plus the rough onsets' jitter): where the bounce
# stepped over lies, to a scatter of the ratios of a few %
_SPLITTING_LOUDNESS = 0.7  # a secondary splitting an interval is this much fainter than
# the impacts either side (3 dB), at least
_OUTLIER_SCATTERS = 3.0  # a ratio this many scatters off the trend is an outlier
_COST_TIE = log(1.5)  # chain costs closer than one ratio one scatter off the trend are a tie


# --------------------------------------------------------------------------------------------
# Selection by physics


def _best_chain(times, weights, trend=None):
    """Indices of the highest-scoring chain of events with geometrically shrinking intervals.

    Dynamic programming over states (j, k), "the chain ends with events j then k" (Bellman's
    principle: the best chain through (j, k) extends the best chain ending there). A chain
    scores the sum of its events' weights; a step from (j, k) to (k, l) is allowed only if the
    interval ratio ρ = (t_l − t_k)/(t_k − t_j) lies within the bounds of successive bounces.
    With ``trend = (coefficients, scatter)`` each step also costs ln(1 + z²/2), with
    z = (ln ρ − trend(ln(t_k − t_j))) / √(scatter² + jitter²), jitter being the effect on
    ln ρ of the rough onsets' jitter (:data:`_ONSET_JITTER`) on both intervals.
    """
    n = times.size
    if n < 2:
        return np.arange(n)
    log_lo, log_hi = np.log(_RATIO_BOUNDS)
    gaps = times[None, :] - times[:, None]  # gaps[k, l] = t_l − t_k
    upper = gaps > 0
    log_gap = np.log(np.where(upper, gaps, 1.0))
    jitter = 2 * _ONSET_JITTER**2 / np.where(upper, gaps, 1.0) ** 2
    score = np.where(upper, weights[:, None] + weights[None, :], -np.inf)
    pointer = np.full((n, n), -1, dtype=np.int64)
    # Per gap (j, k), the next gap's log that the trend expects (centre of the Cauchy cost)
    # and the bounds of the allowed ones; per column k, read as contiguous rows below.
    centre_t = spread_t = None
    if trend is not None:
        coefficients, scatter = trend
        centre_t = (log_gap + np.polyval(coefficients, log_gap)).T.copy()
        spread_t = (scatter**2 + jitter).T.copy()
    # Every pair (j, k), j < k, starts a chain, so every state ending at k is reachable from
    # all j < k (slices, not index lists, in the loop below). States ending at k are final
    # once every j < k has been seen: sweep k in time order.
    last = np.searchsorted(times, times[1:-1] + _RATIO_BOUNDS[1] * (times[1:-1] - times[0]),
                           side="right")
    if _envelope.COMPILED:
        _envelope._kernels().chain_scores(
            log_gap, jitter, np.ascontiguousarray(weights, dtype=float), last, score, pointer,
            centre_t, spread_t, log_lo=float(log_lo), log_hi=float(log_hi),
            log_growth=float(np.log1p(_GROWTH_ALLOWANCE)))
    else:
        _relax_states(log_gap, jitter, weights, last, score, pointer, centre_t, spread_t)
    j, k = np.unravel_index(np.argmax(score), score.shape)
    chain = [int(k), int(j)]
    while pointer[chain[-1], chain[-2]] >= 0:
        chain.append(int(pointer[chain[-1], chain[-2]]))
    return np.array(chain[::-1])


def _relax_states(log_gap, jitter, weights, last, score, pointer, centre_t, spread_t):
    """The loop of :func:`_best_chain` over the columns k (numpy reference of
    :func:`.audio_kernels.chain_scores`): `score` and `pointer` are updated in place."""
    n = log_gap.shape[0]
    log_lo, log_hi = np.log(_RATIO_BOUNDS)
    log_gap_t = log_gap.T.copy()
    columns = np.arange(n)
    for k in range(1, n - 1):
        stop = last[k - 1]
        if stop <= k + 1:
            continue
        following = log_gap[k, k + 1:stop]
        log_ratio = following - log_gap_t[k, :k, None]
        total = score[:k, k, None] + weights[k + 1:stop]
        if centre_t is not None:
            deviation = following - centre_t[k, :k, None]
            deviation *= deviation
            deviation /= spread_t[k, :k, None] + jitter[k, k + 1:stop]
            # Cauchy (Lorentzian) cost: quadratic for small deviations, logarithmic for large
            # ones, so that one odd bounce (a spin, a tilted floor) does not cut the chain.
            total -= np.log1p(0.5 * deviation)
        # Bouncing balls' intervals shrink: one may grow only as much as the restitution's
        # scatter and the rough onsets' jitter on both intervals explain.
        growth = np.minimum(log_hi, np.log1p(_GROWTH_ALLOWANCE) + 3.0 * np.sqrt(
            jitter[:k, k, None] + jitter[k, k + 1:stop]))
        total[(log_ratio < log_lo) | (log_ratio > growth)] = -np.inf
        best = np.argmax(total, axis=0)
        value = total[best, columns[:stop - k - 1]]
        better = value > score[k, k + 1:stop]
        score[k, k + 1:stop] = np.where(better, value, score[k, k + 1:stop])
        pointer[k, k + 1:stop] = np.where(better, best, pointer[k, k + 1:stop])


def _chain_weights(times, power_ratio, amplitude):
    """Score of each transient as a member of the chain of impacts.

    A transient counts 1 + ½·ln(its power over the detection threshold), the log of its
    amplitude SNR, so that a clear impact outweighs a faint one. A transient that follows,
    within 160 ms, one at least a third as loud (−10 dB) may be its ringing, rattle or echo
    and counts a quarter: where an impact and its secondary fit the geometric trend equally
    well (secondaries at a fixed delay form a geometric chain of their own), the first of
    them, the cause, is the impact. Only a transient much louder than anything in the
    160 ms before it keeps its full score. Late bounces, less than 160 ms apart, are all
    quartered; among them the trend decides.
    """
    # A faint sound in digital silence (a lossy codec's, or a recorder's zero padding) has
    # an onset power the running sums may round to zero or below: it counts as the floor.
    weights = _NOISE_WEIGHT + 0.5 * np.log(np.maximum(power_ratio, _MIN_POWER_RATIO))
    secondary = (_loudest_before(times, amplitude, _SECONDARY_SECONDS)
                 >= amplitude / _SECONDARY_LOUDNESS)
    return np.where(secondary, _SECONDARY_WEIGHT * weights, weights)


def _loudest_before(times, amplitude, reach):
    """Largest `amplitude` among the transients in the `reach` (s) before each of those at
    `times` (s, increasing), itself excluded; 0 where there is none."""
    earlier = np.searchsorted(times, times - reach)
    if _envelope.COMPILED:
        return _envelope._kernels().window_maxima(amplitude, earlier)
    return np.array([amplitude[a:i].max(initial=0.0) for i, a in enumerate(earlier)])


def _first_pass(times, power_ratio, amplitude, strong):
    """The first pass of :func:`_select_bounces`: the best chain of the strong transients
    under the ratio bounds alone (indices into the transients at `times`, s), without the
    faint members before its first impact, and the strong transients' scores
    (:func:`_chain_weights`)."""
    candidates = np.flatnonzero(strong)
    weights = _chain_weights(times[candidates], power_ratio[candidates], amplitude[candidates])
    return candidates[_trim_start(_best_chain(times[candidates], weights),
                                  amplitude[candidates])], weights


def _select_bounces(times, power_ratio, amplitude, strong, precise=None):
    """Chain of impacts among the transients at `times` (s), and notes on missing ones.

    A first pass keeps the best chain of strong transients under the ratio bounds alone; the
    ratio of successive intervals of that chain is fitted as a straight line in log(interval)
    (restitution changes smoothly with impact speed, which is proportional to the interval
    [5]_); a second pass scores every step by how far its ratio is from that line, in units
    of the chain's robust scatter: an echo or a ring that replaced an impact would break the
    trend twice. Members that follow a transient left out at a recurring secondary delay are
    moved onto it where the trend says so (:func:`_move_to_causes`). Finally the chain is
    followed on (:func:`_extend_chain`) where the trend predicts further impacts, among all
    transients, weak ones included. Last, members at a recurring secondary delay after a
    louder transient left out, no louder than that secondary usually is, are moved onto it
    (:func:`_back_to_louder_causes`).

    Returns
    -------
    chain : ndarray of int
        Indices of the impacts, in time order.
    skipped : int
        Impacts the trend predicts but no transient marks (counted in the notes).
    """
    candidates = np.flatnonzero(strong)
    weights = np.zeros(times.size)
    chain, weights[candidates] = _first_pass(times, power_ratio, amplitude, strong)
    if chain.size < 4:
        return chain, 0
    chain = _shift_to_causes(times, chain)
    trend = _trend(times[chain])
    candidates = candidates[times[candidates] >= times[chain[0]]]
    chain = candidates[_trim_start(_best_chain(times[candidates], weights[candidates], trend),
                                   amplitude[candidates])]
    if chain.size < 4:
        return chain, 0
    chain = _move_to_causes(times, amplitude, _shift_to_causes(times, chain))
    chain = _every_bounce(times, amplitude, chain)
    trend = _trend(times[chain])
    chain = _redo_tail(times, power_ratio, amplitude, strong, chain, trend)
    chain = _polish_chain(times, chain, trend)
    delays = _secondary_delays(times, chain)
    chain, skipped = _extend_chain(times, amplitude, chain, trend, precise, delays,
                                   _secondary_levels(times, amplitude, chain, delays))
    chain = _shift_to_causes(times, _polish_chain(times, chain, trend))
    chain = _move_to_causes(times, amplitude, chain)
    chain = _back_to_louder_causes(times, amplitude, chain)
    chain = _without_members_secondaries(times, amplitude, chain)
    return _drop_faint_between(amplitude, chain), skipped


def _without_members_secondaries(times, amplitude, chain):
    """Chain without members that are the rings or echoes of members before them.

    An echo (or a ring) of an impact can land anywhere inside a long interval after it, and
    a chain through it splits that interval in two: with few such members the trend of the
    ratios stays put and the chain passes, and each missing impact later found by the trend
    sits beside its secondary, a false impact. Such a member comes at a delay at which
    secondaries recur after the impacts (:func:`_secondary_delays`, 10 ms or more: not a
    ring's burst, which alternates with the impacts on the last intervals, where which one
    is the outlier is the selection's to judge) after an earlier member (to 0.3 ms), no
    louder than twice that secondary's usual level times that member
    (:func:`_secondary_levels`), and fainter than both members around it (by 3 dB: an
    impact's sound fades by a few % a bounce); its own interval ratio is more than three
    scatters off the chain's robust trend (:func:`_robust_trend`), as a true impact there
    is not; and the chain's Cauchy cost about its trend (:func:`_chain_cost`) falls without
    it by more than a tie. Removed one at a time, the largest fall first. The chain's first
    and last members stay (a ratio fewer costs less whatever the member is). Parameters and
    return as in :func:`_back_to_louder_causes`.
    """
    chain = np.asarray(chain)
    if chain.size < 8:
        return chain
    delays, levels = _recurring_secondaries(times, amplitude, chain)
    usable = np.isfinite(levels) & (delays >= 2 * _MASK_SECONDS)
    if not usable.any():
        return chain
    delays, levels = delays[usable], levels[usable]
    moments, loudness = times[chain], amplitude[chain]
    lag = moments[:, None, None] - moments[None, :, None] - delays[None, None, :]
    bound = _SECONDARY_MARGIN * levels[None, None, :] * loudness[None, :, None]
    suspect = np.any((np.abs(lag) <= _CAUSE_TOLERANCE) & (loudness[:, None, None] <= bound),
                     axis=(1, 2))
    suspect[[0, -1]] = False
    suspect[1:-1] &= loudness[1:-1] < _SPLITTING_LOUDNESS * np.minimum(loudness[:-2],
                                                                        loudness[2:])
    coefficients, scatter = _robust_trend(moments)
    outlier = np.zeros(chain.size, dtype=bool)
    outlier[1:-1] = _ratio_cost(moments[:-2], moments[1:-1], moments[2:], coefficients,
                                scatter) > np.log1p(0.5 * _OUTLIER_SCATTERS**2)
    candidates = set(np.flatnonzero(suspect & outlier).tolist())
    kept = np.ones(chain.size, dtype=bool)
    cost = _chain_cost(moments)
    while candidates:
        trials = {}
        for position in candidates:
            kept[position] = False
            trials[position] = _chain_cost(moments[kept])
            kept[position] = True
        position = min(trials, key=trials.get)
        if not trials[position] < cost - _COST_TIE:
            break
        kept[position] = False
        candidates.discard(position)
        cost = trials[position]
    return chain[kept]


def _back_to_louder_causes(times, amplitude, chain):
    """Chain with members that are secondaries of louder sounds it left out moved onto those.

    A ring's burst or an echo comes at a delay that recurs after every impact
    (:func:`_secondary_delays`), at a level relative to its impact that recurs too
    (:func:`_secondary_levels`). A member at such a delay (to 0.3 ms) after a transient left
    out of the chain that is at least as loud as the member, the member being no louder than
    twice that secondary's usual level times that transient, is that transient's secondary:
    the chain took it where the impact itself was passed over (on the long first intervals,
    where the trend barely tells 8 ms apart, or on a run of bursts late in the train), and the
    transient replaces it. Left as they are: a transient within 3 ms after the member before
    (that member's own first arrival or a sound on it, which :func:`_polish_chain` weighs),
    and one that itself comes at a recurring delay after an earlier member, to the jitter of
    two rough onsets (1 ms): it is that member's secondary, not an impact passed over, and the
    member after it at twice the delay may be the next impact.

    Parameters
    ----------
    times, amplitude : ndarray
        Rough onsets (s, increasing) and amplitudes (full scale) of all the transients.
    chain : ndarray of int
        Indices of the chain's members, in time order.

    Returns
    -------
    ndarray of int
        The chain, in time order.
    """
    chain = np.asarray(chain)
    if chain.size < 6:
        return chain
    delays, levels = _recurring_secondaries(times, amplitude, chain)
    # From 3 ms on: closer sounds are the impact's own first arrival, not a later secondary.
    usable = np.isfinite(levels) & (delays >= _CAUSE_DELAY_SECONDS[0])
    if not usable.any():
        return chain
    in_chain = np.zeros(times.size, dtype=bool)
    in_chain[chain] = True
    moved = chain.copy()
    for position in range(1, chain.size):
        member = chain[position]
        previous = times[moved[position - 1]]
        for delay, level in zip(delays[usable], levels[usable]):
            lo, hi = np.searchsorted(times, [times[member] - delay - _CAUSE_TOLERANCE,
                                             times[member] - delay + _CAUSE_TOLERANCE])
            causes = np.arange(lo, hi)
            causes = causes[~in_chain[causes]
                            & (times[causes] - previous > _BACK_SEARCH_SECONDS)
                            & (amplitude[causes] >= amplitude[member])
                            & (amplitude[member] <= _SECONDARY_MARGIN * level
                               * amplitude[causes])]
            if causes.size:
                # Not itself a secondary of an earlier member.
                after = times[causes, None, None] - times[moved[:position]][None, :, None] \
                    - delays[None, None, :]
                causes = causes[np.abs(after).min(axis=(1, 2)) > _MOVE_TOLERANCE]
            if causes.size:
                moved[position] = causes[np.argmax(amplitude[causes])]
                in_chain[moved[position]] = True
                break
    return np.sort(moved)


def _chain_cost(times):
    """Sum of the Cauchy costs of the interval ratios of impacts at `times` (s) about their
    own robust trend (:func:`_robust_trend`, :func:`_ratio_cost`)."""
    if times.size < 5 or np.any(np.diff(times) <= 0):
        return np.inf
    coefficients, scatter = _robust_trend(times)
    return float(_ratio_cost(times[:-2], times[1:-1], times[2:], coefficients, scatter).sum())


def _move_to_causes(times, amplitude, chain):
    """Chain with members that follow a sound at a recurring secondary delay moved onto it.

    The secondaries of the impacts the chain holds (a ring's burst 5-8 ms after its impact,
    an echo) are left out and recur at fixed delays (:func:`_secondary_delays`). A member
    with a transient left out at one of these delays before it (to 0.3 ms, from 3 ms on,
    within 0.8 of the interval before it, and at least half as loud as the member: a burst
    may swell to 1.5 times its impact) is that transient's secondary where the impact itself
    was passed over, often for a run of bounces once the impacts grow quiet. The members so
    placed are moved together (a run of them fits the trend as well as the impacts inside
    the run; only its ends tell), and kept moved unless the chain's interval ratios then
    follow their trend worse (:func:`_chain_cost`) by more than the cost of one ratio one
    scatter off it, ln(3/2): a tie goes to the causes, the onset of an impact being where
    its first burst starts. Where they are not kept, each run of consecutive members so
    placed is moved on its own where the chain then follows its trend better by more than
    that. Each moved member is then put back on its own where that fits better still (a true
    impact that happens to follow a secondary of an earlier one).
    """
    chain = np.asarray(chain)
    if chain.size < 6:
        return chain
    delays = _secondary_delays(times, chain)
    delays = delays[delays >= _CAUSE_DELAY_SECONDS[0]]
    if delays.size == 0:
        return chain
    members = times[chain]
    before = np.diff(members, prepend=-np.inf)
    previous = np.concatenate(([-np.inf], members[:-1]))
    in_chain = np.zeros(times.size, dtype=bool)
    in_chain[chain] = True
    moved = chain.copy()
    for position in range(1, chain.size):
        best, best_error = -1, _MOVE_TOLERANCE
        for delay in delays:
            if delay >= _CAUSE_FRACTION * before[position]:
                continue
            lo, hi = np.searchsorted(times, [members[position] - delay - _MOVE_TOLERANCE,
                                             members[position] - delay + _MOVE_TOLERANCE])
            for cause in range(lo, hi):
                error = abs(members[position] - delay - times[cause])
                if (not in_chain[cause] and error <= best_error
                        and times[cause] - previous[position] > _MERGE_SECONDS
                        and 2.0 * amplitude[cause] >= amplitude[chain[position]]):
                    best, best_error = cause, error
        if best >= 0:
            moved[position] = best
    if np.array_equal(moved, chain):
        return chain
    # A tie goes to the causes: where the secondaries of the impacts hidden under the ones
    # before them continue the run to the train's end, the run of members and the run of
    # their causes each break the trend once, where they join the chain's impacts.
    cost = _chain_cost(members)
    if _chain_cost(times[np.sort(moved)]) >= cost + _COST_TIE:
        # Moved together they fit worse: each run of consecutive members so placed is moved
        # on its own where that fits clearly better (a run of bursts taken on the long
        # first intervals is independent of a member late in the train that happens to
        # follow a secondary).
        changed = np.flatnonzero(moved != chain)
        kept = chain.copy()
        for run in np.split(changed, np.flatnonzero(np.diff(changed) > 1) + 1):
            trial = kept.copy()
            trial[run] = moved[run]
            trial_cost = _chain_cost(times[np.sort(trial)])
            if trial_cost < cost - _COST_TIE:
                kept, cost = trial, trial_cost
        moved = kept
        if np.array_equal(moved, chain):
            return chain
    for position in np.flatnonzero(moved != chain):
        trial = moved.copy()
        trial[position] = chain[position]
        if _chain_cost(times[np.sort(trial)]) < _chain_cost(times[np.sort(moved)]):
            moved = trial
    return np.sort(moved)


def _shift_to_causes(times, chain):
    """Chain moved back onto the sounds its members follow at one fixed delay, if any.

    A ring that swells again a few ms after its impact (a second burst, louder than the
    first once the impacts grow quiet) or an echo is a copy of the impact train at a fixed
    delay: both chains have the same intervals, and where the copy is louder it can win the
    chain. A bounce train has no such shadow before it: the delay from a member back to the
    rings, echoes and apex clicks of earlier impacts changes from bounce to bounce. So where
    at least a quarter of the members (and four), over intervals differing by 1.5 times or
    more, have a transient at one and the same delay d before them (to 0.3 ms; d from 3 ms,
    closer sounds being the impact's own first arrival, which the rough onset and
    :func:`_polish_chain` look back for, to 200 ms, and within 0.8 of the interval before
    the member), the members are secondaries and each is replaced by the transient at d
    before it: the onset of an impact is where its first burst starts. This is done once
    more on the result (an echo of a ring's burst). Members without a transient
    at d before them stay.
    """
    lo_delay, hi_delay = _CAUSE_DELAY_SECONDS
    for _ in range(2):
        members = times[chain]
        first, last = np.searchsorted(times, [members - hi_delay, members - lo_delay])
        counts = last - first
        if counts.sum() == 0:
            return chain
        owner = np.repeat(np.arange(chain.size), counts)
        index = np.concatenate([np.arange(a, b) for a, b in zip(first, last)])
        delays = members[owner] - times[index]
        # A cause lies well inside the interval before its member (not at the previous
        # member's own ring or echo, which a slowly shrinking train repeats at slowly
        # changing delays).
        before = np.diff(members, prepend=-np.inf)[owner]
        inside = delays < _CAUSE_FRACTION * before
        owner, index, delays = owner[inside], index[inside], delays[inside]
        if owner.size == 0:
            return chain
        # Candidate delay: the one most members share (each member counted once per delay).
        order = np.argsort(delays)
        sorted_delays, sorted_owner = delays[order], owner[order]
        reach = np.searchsorted(sorted_delays, sorted_delays + 2 * _CAUSE_TOLERANCE,
                                side="right")
        if _envelope.COMPILED:
            support = _envelope._kernels().distinct_counts(sorted_owner, reach)
        else:
            support = np.array([np.unique(sorted_owner[i:j]).size
                                for i, j in enumerate(reach)])
        best = int(np.argmax(support))
        if support[best] < max(4, _CAUSE_SHARE * chain.size):
            return chain
        # ... and the same delay over intervals that differ widely: a coincidence of a few
        # similar intervals is not a fixed delay.
        spanned = before[inside][order][best:reach[best]]
        if spanned.max() < _CAUSE_SPAN * spanned.min():
            return chain
        delay = float(np.median(sorted_delays[best:reach[best]]))
        close = np.abs(delays - delay) <= _CAUSE_TOLERANCE
        replaced = chain.copy()
        for member in np.unique(owner[close]):
            picks = np.flatnonzero(close & (owner == member))
            cause = index[picks[np.argmin(np.abs(delays[picks] - delay))]]
            # Where the intervals come down to the delay, the cause may be the member before
            # or too close to it to be another impact.
            previous = times[replaced[member - 1]] if member > 0 else -np.inf
            if times[cause] - previous > _MERGE_SECONDS:
                replaced[member] = cause
        if np.array_equal(replaced, chain):
            return chain
        chain = np.sort(replaced)
    return chain


def _every_bounce(times, amplitude, chain):
    """Chain with the bounces it stepped over, where it took every other bounce.

    Every other bounce of a train is a geometric train too, with the ratio ρ² of two
    bounces in place of ρ, and so passes the bounce-train check; its fit would give ε² for
    ε. Such a chain leaves out, inside each of its intervals I, a transient about as loud as
    its members where the bounce stepped over lies: after the member before it by
    I/(1 + √ρ), ρ being the ratio of this interval to the one before in the chain (the two
    flights of ratio √ρ each; [5]_). A ring, burst or echo comes at a fixed delay, which
    matches that place on two or three successive intervals of a shrinking train at most, and
    those at a delay that recurs after the members are not counted.
    Where five of six successive intervals of the chain (or five of five) hold such a
    transient, the chain stepped over bounces, and every such transient in its intervals is
    added (an interval that holds none spans one bounce, or more than two, or its bounce was
    set aside with the echoes it lands on: the search for the impacts the trend predicts
    goes on from there); else the chain is returned as it was. `times` (s, increasing) and
    `amplitude` (full scale) are those of all the transients.
    """
    chain = np.asarray(chain)
    if chain.size < 5:
        return chain
    impacts = times[chain]
    intervals = np.diff(impacts)
    ratio = np.concatenate(([intervals[1] / intervals[0]], intervals[1:] / intervals[:-1]))
    expected = impacts[:-1] + intervals / (1.0 + np.sqrt(ratio))
    tolerance = _HALVING_SLACK * intervals + _ONSET_JITTER
    fainter = np.minimum(amplitude[chain[:-1]], amplitude[chain[1:]])
    left_out = np.setdiff1d(np.arange(times.size), chain)
    # Not at a delay at which secondaries recur after the members (a ring's burst 5-8 ms
    # after each impact sits midway in intervals of 10-16 ms, which shrink slowly there).
    delays = _secondary_delays(times, chain)
    if delays.size:
        lead = times[left_out][:, None, None] - impacts[None, :, None] - delays[None, None, :]
        left_out = left_out[np.abs(lead).min(axis=(1, 2)) > _ONSET_JITTER]
    if left_out.size == 0:
        return chain
    distance = np.abs(times[left_out][None, :] - expected[:, None])
    loud = amplitude[left_out][None, :] >= _HALVING_LOUDNESS * fainter[:, None]
    distance = np.where(loud & (distance <= tolerance[:, None]), distance, np.inf)
    nearest = distance.argmin(axis=1)
    found = np.isfinite(distance[np.arange(intervals.size), nearest])
    # Most intervals holding one among any six successive ones (an impact the chain's
    # choice set aside, one an echo of an earlier impact lands on, leaves one empty).
    span = min(found.size, _HALVING_RUN + 1)
    if np.convolve(found, np.ones(span, dtype=int), mode="valid").max() < _HALVING_RUN:
        return chain
    return np.sort(np.concatenate([chain, left_out[nearest[found]]]))


def _drop_faint_between(amplitude, chain):
    """Chain without members far fainter than both members around them.

    Impact sounds fade smoothly along a train (amplitude ∝ impact speed, a few % per
    bounce), so an impact is never 20 dB fainter than both the impact before and the one
    after it. A sound that is (a faint click near the apex of the flight, as on a real
    tennis-ball recording, 40 dB under the impacts) splits a real interval in two while the
    interval ratios may still look geometric: the amplitude pattern, not the timing, tells
    it out. Removed repeatedly until none is left; the first and last members are judged
    against their one neighbour.
    """
    chain = np.asarray(chain)
    while chain.size >= 3:
        loudness = amplitude[chain]
        previous = np.concatenate(([np.inf], loudness[:-1]))
        following = np.concatenate((loudness[1:], [np.inf]))
        neighbours = np.minimum(previous, following)
        neighbours[0], neighbours[-1] = loudness[1], loudness[-2]
        faint = loudness * _MIDWAY_LOUDNESS < neighbours
        if not faint.any():
            break
        chain = chain[~faint]
    return chain


def _redo_tail(times, power_ratio, amplitude, strong, chain, trend):
    """Chain with its last impacts chosen again among all transients, weak ones included.

    The last, faintest impacts land on the ringing and echoes of earlier ones, so their
    power jumps less and they may be weak triggers only, while rings of comparable loudness
    come at fixed delays. With the trend known, the best chain (:func:`_best_chain`) through
    every transient from the last :data:`_TAIL_IMPACTS` impacts on tells them apart by the
    whole run of intervals rather than one predicted time at a time; a weak transient counts
    half. The new tail is kept only if it continues the chain (starts on one of its members).
    """
    start = chain[max(0, chain.size - _TAIL_IMPACTS)]
    pool = np.arange(start, times.size)
    if pool.size < 3:
        return chain
    weights = _chain_weights(times[pool], power_ratio[pool], amplitude[pool])
    weights = np.where(strong[pool], weights, 0.5 * weights)
    tail = pool[_best_chain(times[pool], weights, trend)]
    if tail.size < 3 or tail[0] not in set(chain.tolist()) or tail[-1] <= chain[-1]:
        return chain
    return np.concatenate([chain[chain < tail[0]], tail])


def _ratio_cost(times_a, times_b, times_c, coefficients, scatter):
    """Cauchy cost of the interval ratio (c − b)/(b − a) against the trend, elementwise."""
    previous, following = times_b - times_a, times_c - times_b
    valid = (previous > 0) & (following > 0)
    previous, following = np.where(valid, previous, 1.0), np.where(valid, following, 1.0)
    deviation = np.log(following / previous) - np.polyval(coefficients, np.log(previous))
    jitter = 2 * _ONSET_JITTER**2 * (1 / previous**2 + 1 / following**2)
    return np.where(valid, np.log1p(0.5 * deviation**2 / (scatter**2 + jitter)), np.inf)


def _polish_chain(times, chain, trend):
    """Replace chain members by a transient within 3 ms that fits the trend better.

    A ring or an echo that starts shortly before an impact can take its place in the chain
    (and hide it from the strong triggers); the impact itself continues the geometric trend
    better. Each member in turn is replaced by the transient, among those within the
    back-search time of it, that minimises the cost of the three interval ratios it enters.

    The costs of every member's options are computed in one batch on the chain as given
    (elementwise, so each is what a member's own call gives); a member is costed again, on
    its own, only where a replacement before it changed the members its ratios use.
    """
    if not _envelope.COMPILED:  # the reference: one member at a time
        return _polish_chain_reference(times, chain, trend)
    coefficients, scatter = trend
    original, chain = chain, chain.copy()
    size = chain.size
    if size < 2:
        return chain
    centres = times[original]
    lower = np.searchsorted(times, centres - _BACK_SEARCH_SECONDS)
    upper = np.searchsorted(times, centres + _BACK_SEARCH_SECONDS)
    positions = np.arange(1, size)
    lo = np.maximum(lower[1:], original[:-1] + 1)
    hi = np.where(positions + 1 < size, np.minimum(upper[1:], np.append(original[2:], 0)),
                  upper[1:])
    counts = np.where(hi - lo >= 2, hi - lo, 0)
    owner = np.repeat(positions, counts)  # position of each option
    choice = {}  # position -> its best option, on the chain as given
    if owner.size:
        starts = np.repeat(lo - np.cumsum(counts) + counts, counts)
        option = starts + np.arange(owner.size)  # index into `times` of each option
        t = times[option]
        member = np.append(centres, [np.nan, np.nan])  # times of the members, past the end NaN

        def costed(present, a, b, c):
            # Cost of one kind of ratio where the position has it, 0 (adds exactly) elsewhere.
            return np.where(present, _ratio_cost(np.where(present, a, t), np.where(present, b, t),
                                                 np.where(present, c, t), coefficients,
                                                 scatter), 0.0)

        total = costed(owner >= 2, member[owner - 2], member[owner - 1], t)
        total = total + costed(owner + 1 < size, member[owner - 1], t, member[owner + 1])
        total = total + costed(owner + 2 < size, t, member[owner + 1], member[owner + 2])
        ends = np.cumsum(counts)
        for position, count, end in zip(positions.tolist(), counts.tolist(), ends.tolist()):
            if count:
                best = int(np.argmin(total[end - count:end]))
                choice[position] = int(option[end - count + best])
    for position in range(1, size):
        if chain[position - 1] == original[position - 1] and (
                position < 2 or chain[position - 2] == original[position - 2]):
            if position in choice:
                chain[position] = choice[position]
        else:
            _polish_member(times, chain, position, coefficients, scatter)
    return chain


def _polish_chain_reference(times, chain, trend):
    """:func:`_polish_chain`, one member at a time (the reference of its batched form)."""
    coefficients, scatter = trend
    chain = chain.copy()
    for position in range(1, chain.size):
        _polish_member(times, chain, position, coefficients, scatter)
    return chain


def _polish_member(times, chain, position, coefficients, scatter):
    """Replace chain[position], in place, by the transient of least trend cost near it."""
    lo, hi = np.searchsorted(times, [times[chain[position]] - _BACK_SEARCH_SECONDS,
                                     times[chain[position]] + _BACK_SEARCH_SECONDS])
    lo = max(lo, chain[position - 1] + 1)
    if position + 1 < chain.size:
        hi = min(hi, chain[position + 1])
    options = np.arange(lo, hi)
    if options.size < 2:
        return
    # The (up to three) ratios the member enters, one row each, costed in one call.
    t = times[options]
    around = times[chain[max(position - 2, 0):position + 3]]
    before = position - max(position - 2, 0)  # members of `around` before this one
    rows = []
    if before == 2:
        rows.append((np.full_like(t, around[0]), np.full_like(t, around[1]), t))
    if position + 1 < chain.size:
        rows.append((np.full_like(t, around[before - 1]), t,
                     np.full_like(t, around[before + 1])))
    if position + 2 < chain.size:
        rows.append((t, np.full_like(t, around[before + 1]),
                     np.full_like(t, around[before + 2])))
    if rows:
        a, b, c = (np.array(column) for column in zip(*rows))
        cost = _ratio_cost(a, b, c, coefficients, scatter).sum(axis=0)
    else:
        cost = np.zeros(options.size)
    chain[position] = options[int(np.argmin(cost))]


def _trend(impact_times):
    """(polynomial coefficients, scatter) of ln(next interval / interval) against ln(interval).

    A straight line, or a parabola for chains of ten bounces or more, whose restitution may
    change faster at high speed.
    """
    intervals = np.diff(impact_times)
    log_ratio = np.log(intervals[1:] / intervals[:-1])
    log_interval = np.log(intervals[:-1])
    coefficients = np.polyfit(log_interval, log_ratio, 2 if log_ratio.size >= 9 else 1)
    residual = log_ratio - np.polyval(coefficients, log_interval)
    # Scatter of log(ratio): the bounce-to-bounce variation of restitution, robust, from the
    # chain itself (_best_chain adds the effect of the onsets' jitter on short intervals).
    scatter = max(1.4826 * np.median(np.abs(residual - np.median(residual))),
                  _RATIO_SCATTER_FLOOR)
    return coefficients, scatter


def _trend_step(coefficients, shortest):
    """Function giving the next interval (s) from an interval (s) under the ratio trend.

    Below the `shortest` interval (s) of the chain the trend is continued along its tangent:
    a parabola fitted to the longer intervals can bend away fast outside them. The ratio it
    gives is held within the bounds of successive bounces (:data:`_RATIO_BOUNDS`), which
    every step of the chain obeys: fitted on a chain that scatters widely, the curve can run
    off to any ratio away from its intervals (and overflow).
    """
    log_lo, log_hi = (log(bound) for bound in _RATIO_BOUNDS)
    edge = float(np.log(shortest))
    edge_value = float(np.polyval(coefficients, edge))
    edge_slope = float(np.polyval(np.polyder(coefficients), edge))
    terms = [float(c) for c in coefficients]

    def step(interval):  # scalar arithmetic: called a few times per impact
        log_interval = log(interval)
        if log_interval < edge:
            log_ratio = edge_value + edge_slope * (log_interval - edge)
        else:
            log_ratio = 0.0
            for term in terms:  # Horner's scheme, as np.polyval
                log_ratio = log_ratio * log_interval + term
        return interval * exp(min(max(log_ratio, log_lo), log_hi))

    return step


def _predict_next(anchors, step, missing=0):
    """Time (s) of the next impact and the interval before it, from consecutive `anchors`.

    Each of the last three intervals is stepped on through the trend to the next impact (past
    `missing` impacts in between); the median of these predictions is used, so that one
    anchor pulled off by a ring or an echo does not throw it off.
    """
    moments, intervals = [], []
    for back in range(min(3, len(anchors) - 1)):
        interval = float(anchors[-1 - back] - anchors[-2 - back])
        if interval <= 0:  # anchors out of order (a predicted one past the next impact)
            continue
        moment = float(anchors[-1 - back])
        for _ in range(back + 1 + missing):
            interval = step(interval)
            moment += interval
        moments.append(moment)
        intervals.append(interval)
    if not moments:
        return np.inf, 0.0
    return median(moments), median(intervals)


def _extend_chain(times, amplitude, chain, trend, precise=None, delays=None, levels=None):
    """Follow the bounce trend past the end of `chain`, through up to two missing impacts.

    The trend predicts the next impact time from each of the last three impacts and the
    interval before it (stepped on through the bounces in between); the median of these
    predictions is used, so that one rough onset pulled early by a ring or an echo does not
    throw the prediction off. The transient nearest to it within three standard deviations
    (from the ratio scatter and the rough onsets' jitter) plus 0.2 ms, and not more than
    6 dB fainter than the last impacts, is taken. If none is there, the prediction steps on
    by one more interval (an impact lost under the ringing or echo of an earlier one, or too
    faint), at most twice in a row. The search stops when the predicted interval falls below
    the merge window, where successive impacts can no longer be told apart.

    With `precise` (a function giving the fitted onset times, s, of the transients of given
    indices) the trend is refitted on the fitted onsets of the chain, the predictions start
    from them, and the transients near a prediction are compared by their fitted onsets:
    the rough onsets jitter by up to half a millisecond, a tenth of the last intervals.

    `delays` (s), the fixed delays of the rings and echoes left out of the chain, reject a
    transient that comes that long after an impact of the chain (to the rough onsets'
    jitter): past the last impact the rings of the last ones continue its intervals exactly.
    With `levels`, the usual loudness of each of these secondaries relative to its impact
    (:func:`_secondary_levels`; NaN: unknown), a transient more than twice as loud as that
    secondary usually is after that impact is not rejected.
    """
    if precise is None:
        def precise(indices):
            return times[indices]
    else:
        trend = _trend(precise(chain))
    coefficients, scatter = trend
    step = _trend_step(coefficients, np.diff(times[chain]).min())
    if delays is not None:
        usual = (np.full(delays.size, np.inf) if levels is None else
                 np.where(np.isfinite(levels), levels, np.inf))  # unknown level: any loudness
    chain = list(chain)
    anchors = list(precise(np.array(chain[-4:])))  # one bounce apart (skips filled in)
    skipped, missing = 0, 0
    while True:
        predicted_time, interval = _predict_next(anchors, step, missing)
        if interval < _MERGE_SECONDS or predicted_time > times[-1] + interval:
            break
        # The fitted onsets of faint transients still err by a fraction of the jitter, and
        # so do the anchors; after a skipped impact, though, rings of the last impacts are
        # as likely there as the next one, and only a transient on the trend itself counts.
        tolerance = 3.0 * np.hypot(interval * scatter, 0.0 if missing else
                                   0.5 * _ONSET_JITTER) + _EXTENSION_SLACK
        # Transients whose rough onset, jittered, may lie within the tolerance ...
        reach = tolerance + 3.0 * _ONSET_JITTER
        lo, hi = np.searchsorted(times, [predicted_time - reach, predicted_time + reach])
        near = np.arange(max(lo, chain[-1] + 1), hi)
        # Late bounces fade slowly (amplitude ∝ speed, a few % per bounce): a transient much
        # fainter than the last impacts is a ring or an echo of theirs, not the next one.
        near = near[amplitude[near] >= np.median(amplitude[chain[-3:]]) / _EXTENSION_LOUDNESS]
        # ... and whose fitted onset does.
        fitted = precise(near) if near.size else np.zeros(0)
        inside = np.abs(fitted - predicted_time) <= tolerance
        if delays is not None and delays.size and near.size:
            members = precise(np.array(chain))
            echoing = np.abs(fitted[:, None, None] - delays[None, :, None]
                             - members[None, None, :]) <= _ONSET_JITTER
            # A transient far louder than that secondary usually is after its impact is not
            # it (the delays are many, and with the intervals' sums they soon meet the
            # predictions by chance).
            loudest = _SECONDARY_MARGIN * usual[:, None] * amplitude[chain][None, :]
            echoing &= amplitude[near][:, None, None] <= loudest[None, :, :]
            inside &= ~echoing.any(axis=(1, 2))
        near, fitted = near[inside], fitted[inside]
        if near.size:
            nearest = int(np.argmin(np.abs(fitted - predicted_time)))
            best = int(near[nearest])
            # Impacts skipped before it are placed on the trend between, as anchors.
            if missing:
                fill = np.linspace(anchors[-1], fitted[nearest], missing + 2)[1:-1]
                anchors.extend(fill.tolist())
            anchors.append(float(fitted[nearest]))
            chain.append(best)
            skipped += missing
            missing = 0
        else:
            missing += 1
            if missing > 2:
                break
    return np.array(chain), skipped


def _trim_start(chain, amplitude):
    """Drop leading chain members more than 20 dB below the loudest impact of the chain.

    Each bounce is slower than the one before it and the sound grows with impact speed, so
    the first impact is among the loudest; faint transients that happen to fit the geometric
    trend before it (handling noise, footsteps) are not bounces.
    """
    if chain.size == 0:  # no strong transient to chain
        return chain
    loud = amplitude[chain] >= amplitude[chain].max() / _LEADING_LOUDNESS
    return chain[int(np.argmax(loud)):]


def _louder_between(times, power_ratio, amplitude, strong, chain):
    """Plain-words problem if the chain was picked out of clicks, else ''.

    Between two impacts of a ball the loudest sounds are theirs and their own rings, rattles
    and echoes; a transient louder than both impacts around it that is not such a secondary
    (:func:`_chain_weights`: no transient at least a third as loud in the 160 ms before it)
    is a sound of its own. In more than a quarter of the intervals, the chain is a
    selection among clicks or knocks, not a bounce train (synthetic trains with rings and
    echoes: none; the real bouncy-ball drop, rattle-heavy: 9 of 51 intervals; random clicks:
    a quarter to all of them).
    """
    chain = np.sort(chain)
    candidates = np.flatnonzero(strong)
    weights = np.zeros(times.size)
    weights[candidates] = _chain_weights(times[candidates], power_ratio[candidates],
                                         amplitude[candidates])
    primary = strong & (weights >= _NOISE_WEIGHT)
    after = np.searchsorted(chain, np.arange(times.size))  # chain[after - 1] < i <= chain[after]
    between = (after > 0) & (after < chain.size) & ~np.isin(np.arange(times.size), chain)
    around = np.clip(after, 1, chain.size - 1)
    louder = between & primary & (amplitude >= np.maximum(amplitude[chain[around - 1]],
                                                          amplitude[chain[around]]))
    # A transient at a delay that recurs after the impacts is their ring's burst or echo,
    # however loud (a ring can swell louder than its impact's first burst).
    delays = _secondary_delays(times, chain)
    if delays.size and louder.any():
        suspects = np.flatnonzero(louder)
        offsets = times[suspects][:, None, None] - times[chain][None, :, None] - delays
        louder[suspects[np.abs(offsets).min(axis=(1, 2)) <= _ONSET_JITTER]] = False
    intervals = np.unique(after[louder]).size
    if intervals <= 0.25 * (chain.size - 1):
        return ""
    return (f"{intervals} of {chain.size - 1} intervals between the impacts found hold a sound "
            f"louder than both of them that is not their ring or echo: the impacts were picked "
            f"out of clicks or knocks, not heard from one bouncing ball")


def _secondary_delays(times, chain):
    """Delays (s) at which rings or echoes recur after the impacts of `chain`.

    Every transient left out of the chain is measured from each of the impacts before it
    (within the time secondaries last, or the echo delay); a delay shared by a quarter of the
    impacts, to within 1 ms, is a secondary of theirs (a ring of the ball or the table, an
    echo from a wall). Each is refined to the median of the delays within 1 ms of it.
    """
    impacts = times[chain]
    # Within the train only: after the last impact the clicks of a ball at rest (every
    # 80-100 ms) measured from the last impacts make chance peaks of their own.
    others = np.setdiff1d(np.flatnonzero((times > impacts[0]) & (times < impacts[-1])), chain)
    if others.size < 3:
        return np.zeros(0)
    delays = (times[others][:, None] - impacts[None, :]).ravel()
    delays = delays[(delays > _MERGE_SECONDS) & (delays < 2 * _SECONDARY_SECONDS)]
    counts = np.bincount(np.round(delays * 1e3).astype(np.int64))
    return _recurring_delays(delays, counts, max(3, chain.size / 4))


def _recurring_delays(delays, counts, threshold):
    """The delays (s) among `delays` that recur: peaks of `counts` (how many there are per
    millisecond, rounded) reaching `threshold`, each refined to the median of the delays
    within 1 ms of it. Neighbouring milliseconds belong together (a delay of 9.4 ms rounds
    to 9 or 10): each is pooled with the one before."""
    pooled = counts + np.concatenate(([0], counts[:-1]))
    dense = np.zeros(pooled.size + 2)
    dense[1:-1] = pooled
    peaks = (pooled >= dense[:-2]) & (pooled > dense[2:]) & (pooled >= threshold)
    return np.array([float(np.median(delays[np.abs(delays - value + 0.5e-3) <= 1e-3]))
                     for value in np.flatnonzero(peaks) / 1e3])


def _periodic_members(times, chain):
    """Which transients of `chain` (indices into the transients at `times`, s) are periodic
    clicks: those in a run of :data:`_PERIODIC_RUN` successive intervals within
    :data:`_PERIODIC_SPREAD` of their median.

    A ball at rest may click on for seconds at a steady period (a rolling ball, a clock): the
    best chain can follow such clicks (their ratios are 1, as smooth a trend as any) rather
    than the train. A ball's intervals shrink at every bounce, by several % (a restitution
    of 0.97 spans 14 % over five intervals): no run of them is this even. A run's first
    member is not counted (the clicks may begin one period after the last impact) unless an
    earlier run holds it.
    """
    periodic = np.zeros(times.size, dtype=bool)
    members = chain[np.argsort(times[chain])]
    intervals = np.diff(times[members])
    if intervals.size < _PERIODIC_RUN:
        return periodic
    runs = np.lib.stride_tricks.sliding_window_view(intervals, _PERIODIC_RUN)
    even = np.all(np.abs(runs / np.median(runs, axis=1, keepdims=True) - 1.0)
                  <= _PERIODIC_SPREAD, axis=1)
    # Interval k joins members k and k + 1; a run starting at k spans members k to k + run,
    # and its first member may be the impact the clicks began one period after.
    for start in np.flatnonzero(even):
        periodic[members[start + 1:start + _PERIODIC_RUN + 1]] = True
    return periodic


def _explained_secondaries(times, amplitude, chain, louder=False):
    """Which transients are secondaries of louder ones: within 0.3 ms of a delay at which
    rings, bursts or echoes recur after the impacts of `chain` (:func:`_secondary_delays`)
    after a transient at least as loud, and no louder than twice that secondary's usual
    level (:func:`_secondary_levels`) times its amplitude; with `louder`, a transient louder
    than its cause is one too (a ring's burst can outsound its impact) within that bound.
    `times` (s, increasing) and `amplitude` (full scale) are those of all the transients."""
    delays, levels = _recurring_secondaries(times, amplitude, chain)
    explained = np.zeros(times.size, dtype=bool)
    for delay, level in zip(delays, levels):
        if not np.isfinite(level):
            continue
        lo, hi = np.searchsorted(times, [times - delay - _CAUSE_TOLERANCE,
                                         times - delay + _CAUSE_TOLERANCE])
        for k in np.flatnonzero(hi > lo):
            cause = amplitude[lo[k]:hi[k]].max()
            explained[k] |= amplitude[k] <= (_SECONDARY_MARGIN * level * cause if louder
                                             else min(cause, _SECONDARY_MARGIN * level * cause))
    return explained


def _echoing_members(times, amplitude, chain, causes_in_chain=True, everywhere=False):
    """Which transients of `chain` are the secondaries of louder ones it left out.

    A chain can follow an echo of the train instead of the train (an echo copies its
    intervals, and outlasts it by its delay): each member then comes at one delay after a
    louder transient left out, the impact. A delay (from 3 ms to twice the longest secondary
    delay) at which a quarter of the members (three at least) follow a louder transient left
    out recurs (:func:`_recurring_delays`); the members within 0.3 ms of it after a louder
    transient are its secondaries: any louder transient where `causes_in_chain` (the first
    impact's echo follows it in the chain), else only one left out (a later impact may
    come one echo delay after an earlier one by chance). With `everywhere`, every transient
    left out of the chain within 0.3 ms of such a delay after a louder one is marked too
    (the echoes of impacts the chain skipped). `times` (s, increasing) and `amplitude` (full
    scale) are those of all the transients; returns a boolean mask of them.
    """
    echoing = np.zeros(times.size, dtype=bool)
    others = np.setdiff1d(np.arange(times.size), chain)
    if chain.size < 4 or others.size == 0:
        return echoing
    delays = times[chain][:, None] - times[others][None, :]
    valid = ((amplitude[others][None, :] >= amplitude[chain][:, None])
             & (delays >= _CAUSE_DELAY_SECONDS[0]) & (delays < 2 * _SECONDARY_SECONDS))
    if not valid.any():
        return echoing
    # Each member counts once per millisecond.
    member, column = np.nonzero(valid)
    bins = np.round(delays[member, column] * 1e3).astype(np.int64)
    counts = np.bincount(np.unique(np.stack([member, bins]), axis=1)[1])
    after_any = times[chain][:, None] - times[None, :]
    louder = amplitude[None, :] >= amplitude[chain][:, None]
    if not causes_in_chain:
        louder[:, chain] = False
    recurring = _recurring_delays(delays[valid], counts, max(3, chain.size / 4))
    for delay in recurring:
        echoing[chain[np.any(louder & (np.abs(after_any - delay) <= _CAUSE_TOLERANCE),
                             axis=1)]] = True
    if everywhere and echoing.any():
        left_out = np.ones(times.size, dtype=bool)
        left_out[chain] = False
        for delay in recurring:
            lo, hi = np.searchsorted(times, [times - delay - _CAUSE_TOLERANCE,
                                             times - delay + _CAUSE_TOLERANCE], side="right")
            for k in np.flatnonzero(left_out & (hi > lo)):
                echoing[k] |= amplitude[lo[k]:hi[k]].max() >= amplitude[k]
    return echoing


def _fixed_delays(times, chain):
    """Most common delay (s) of the transients left out after the preceding impact, and count."""
    impacts = times[chain]
    others = np.setdiff1d(np.arange(times.size), chain)
    others = others[times[others] > impacts[0]]
    if others.size < 3:
        return None, 0
    preceding = impacts[np.searchsorted(impacts, times[others]) - 1]
    delays_ms = np.round((times[others] - preceding) * 1e3).astype(np.int64)
    values, counts = np.unique(delays_ms, return_counts=True)
    # Neighbouring milliseconds belong together (a delay of 9.4 ms rounds to 9 or 10).
    pooled = counts + np.concatenate(([0], counts[:-1])) * (np.diff(values, prepend=-9) == 1)
    best = int(np.argmax(pooled))
    return values[best] / 1e3, int(pooled[best])


# --------------------------------------------------------------------------------------------
# Impacts the trend predicts where no transient was chosen


_PREDICTOR_ORDER = 12  # poles: two per mode, for a few modes of the impact, its ring, an echo
# The rate at which the predictor's order and the jumps in its error were set: 12 samples
# there span 0.54 ms, a few periods of the modes, and the 0.5 ms short-term window holds 11.
_PREDICTOR_REFERENCE_RATE = 22050.0
_IMPULSE_SAMPLES = 11  # samples over which an impulse in the error is measured, at most


def _predictor_order(sample_rate):
    """Order of the predictor of a sound sampled at `sample_rate` (Hz): 12 up to 22.05 kHz,
    and the same span of time (0.54 ms) at higher rates, where 12 samples would cover about
    one period of a 4 kHz mode."""
    return max(_PREDICTOR_ORDER,
               int(round(_PREDICTOR_ORDER * sample_rate / _PREDICTOR_REFERENCE_RATE)))


def _sound_predictor(filtered, stop, order=_PREDICTOR_ORDER):
    """Linear predictor of the sound before `stop`, per channel.

    A struck ball rings in a few modes, a sum of damped sinusoids, which a linear predictor
    with two poles per mode continues exactly; a new impact is an impulse into the same
    resonances and stands out in the prediction error however loud the ring it starts on
    [6]_. The predictor is fitted per channel by least squares on ``filtered[:stop]`` (the
    covariance method [7]_), the sound a probed stretch follows.

    Parameters
    ----------
    filtered : ndarray, shape (frames, channels)
        High-passed samples (full scale).
    stop : int
        The predictor is fitted on the samples before this one (at least 4 × `order`).
    order : int, default 12
        Past samples a prediction uses.

    Returns
    -------
    ndarray, shape (channels, order + 1)
        Error filter a = (1, −c) of each channel: the prediction of y[n] is
        Σ_k c[k] y[n − 1 − k], its error Σ_k a[k] y[n − k].
    """
    channels = filtered.shape[1]
    taps = np.zeros((channels, order + 1))
    taps[:, 0] = 1.0
    for channel in range(channels):
        column = filtered[:stop, channel]
        # A contiguous copy: the product of a strided view is several times slower.
        past = np.ascontiguousarray(
            np.lib.stride_tricks.sliding_window_view(column, order)[:-1, ::-1])
        # Normal equations, with a ridge of 1e-9 of their scale so that silence (all-zero
        # samples) still gives a solution.
        gram = past.T @ past
        gram[np.diag_indices(order)] += 1e-9 * max(np.trace(gram), _NOISE_FLOOR**2) / order
        taps[channel, 1:] = -np.linalg.solve(gram, past.T @ column[order:])
    return taps


def _prediction_error(filtered, taps, noise, rho):
    """Error of the predictor `taps` (:func:`_sound_predictor`) on `filtered` (frames,
    channels; 0 on the first samples), and its variance on the noise alone per channel
    (full scale²): for AR(1) noise of innovation RMS σ and lag-1 correlation ρ,
    Σ_jk a_j a_k σ² ρ^|j−k| / (1 − ρ²)."""
    order = taps.shape[1] - 1
    error = np.zeros_like(filtered)
    for channel in range(filtered.shape[1]):
        error[order:, channel] = signal.lfilter(taps[channel], 1.0,
                                                filtered[:, channel])[order:]
    lags = np.abs(np.arange(order + 1)[:, None] - np.arange(order + 1)[None, :])
    floor = np.einsum("ci,cij,cj->c", taps, rho[:, None, None] ** lags[None], taps) \
        * noise**2 / np.maximum(1.0 - rho**2, 1e-6)
    return error, np.maximum(floor, _NOISE_FLOOR**2)


def _new_sound(filtered, taps, start, length):
    """The sound from `start` on less the predictor's free continuation of the sound before
    it: what started there (length, channels).

    The least-squares predictor may have poles outside the unit circle, and its free
    continuation then grows without bound (by 10⁹ within 3 ms on a development train): each
    such pole is reflected to 1/z̄ inside it, which keeps the frequency of its mode and the
    shape of the spectrum [7]_, and a ring decays as it should.
    """
    order = taps.shape[1] - 1
    out = np.empty((length, filtered.shape[1]))
    for channel in range(filtered.shape[1]):
        poles = np.roots(taps[channel])
        outside = np.abs(poles) > 1.0
        denominator = taps[channel]
        if outside.any():
            poles[outside] = 1.0 / np.conj(poles[outside])
            denominator = np.poly(poles).real
        state = signal.lfiltic([1.0], denominator, filtered[start - order:start, channel][::-1])
        free = signal.lfilter([1.0], denominator, np.zeros(length), zi=state)[0]
        out[:, channel] = filtered[start:start + length, channel] - free
    return out


def _hidden_causes(times, amplitudes, delays, levels, sounds, loudness, probe):
    """Impacts hidden under a ring's burst, found one burst delay before their own burst.

    Once the intervals shrink to a few times a ring's burst delay, an impact may start on
    the loud burst of the one before and barely raise the power: only its own burst,
    `delay` later, rises clearly, and the chain follows the bursts, whose intervals are the
    impacts'. A member is such a burst where the error of a predictor of the sound
    (``probe(moment, tolerance, predicted_sound=True)``) shows an onset one recurring
    secondary delay before it (within 0.5 ms), later than 1 ms after the member before it,
    at least half as loud as the impacts before, and loud enough for the member to be its
    secondary (the member at most twice the usual level of that secondary times the
    onset's amplitude), and not within 0.1 ms of one recurring delay after the member before
    (the fitted start of that member's own burst, ring or echo). Only where a transient at
    least half as loud as those impacts started within 5 ms before is the file probed: a
    sound of that loudness on a quiet stretch would have been found by the trigger.

    Parameters
    ----------
    times, amplitudes : ndarray
        Fitted onsets (s, increasing) and amplitudes (full scale) of the chain's members.
    delays, levels : ndarray
        Delays (s) of the secondaries recurring after the impacts (:func:`_secondary_delays`)
        and their usual loudness relative to their impact (:func:`_secondary_levels`, NaN:
        unknown, then not used here); delays under 3 ms are the impact's own first
        arrivals, not a later burst, and are not used either.
    sounds, loudness : ndarray
        Rough onsets (s) and amplitudes (full scale) of all the transients found.
    probe : callable
        As for :func:`_fill_impacts`, with the keyword ``predicted_sound``.

    Returns
    -------
    times, sigmas, amplitudes, clipped : ndarray
        The members with those bursts replaced by their causes: times (s), 1σ (s; NaN where
        a member was not replaced), amplitudes (full scale) and clip flags.
    """
    times, amplitudes = times.copy(), amplitudes.copy()
    sigmas, clipped = np.full(times.size, np.nan), np.zeros(times.size, dtype=bool)
    order = np.argsort(sounds)
    sounds, loudness = sounds[order], loudness[order]
    # From 3 ms on: closer sounds are the impact's own first arrivals, not a later burst.
    usable = np.isfinite(levels) & (delays >= _CAUSE_DELAY_SECONDS[0])
    for position in range(1, times.size):
        recent = median(amplitudes[max(0, position - 3):position].tolist())
        for delay, level in zip(delays[usable], levels[usable]):
            moment = times[position] - delay
            if moment <= times[position - 1] + _MERGE_SECONDS:
                continue
            # Hidden only under a loud sound that started shortly before.
            lo, hi = np.searchsorted(sounds, [moment - _MASK_SECONDS,
                                              moment - _CAUSE_SEARCH_SECONDS])
            if not np.any(loudness[lo:hi] >= recent / _EXTENSION_LOUDNESS):
                continue
            result = probe(moment, _CAUSE_SEARCH_SECONDS, predicted_sound=True, impulse=True)
            if (result is None or abs(result[0] - moment) > _CAUSE_SEARCH_SECONDS
                    or result[0] <= times[position - 1] + _MERGE_SECONDS
                    or result[2] < recent / _EXTENSION_LOUDNESS
                    or amplitudes[position] > _SECONDARY_MARGIN * level * result[2]):
                continue
            # An onset at a secondary's time after the member before is that secondary's own
            # start (the burst, ring or echo of that member), not an impact hidden under it.
            if np.abs(result[0] - times[position - 1]
                      - delays[usable]).min() < _FITTED_SECONDARY_SECONDS:
                continue
            times[position], sigmas[position], amplitudes[position], clipped[position] = result
            break
    return times, sigmas, amplitudes, clipped


def _probe(stream, predicted, tolerance, timing, not_before=None, predicted_sound=False,
           expected=False, any_jump=False, impulse=False):
    """The onset nearest an impact the bounce trend predicts, looked for in the recording.

    Parameters
    ----------
    stream : _Stream
        State of the detection run (the recording, filter, noise level and colour of each
        channel).
    predicted : float
        Predicted onset (s).
    tolerance : float
        Half-width (s) of the interval around `predicted` in which a trigger may lie.
    timing : int
        Channel on which the onset is fitted.
    not_before : float, optional
        Onset (s) of a ring or an echo that captured the impact's onset before: the onset is
        looked for after it, as a sound of its own, whose power jumps 1.8 dB over the mean
        power since `not_before`.
    predicted_sound : bool, default False
        Look for the jump in the error of a linear predictor of the sound before the window
        (:func:`_prediction_error`) instead of the whitened signal: an impact that starts
        inside a loud ring, whose power barely rises over it, is an impulse there. A sound
        seen only there must jump as much as a strong trigger (9 dB), or, where `expected`
        (a secondary looked for at its known delay), as a weak one (6 dB).
    expected : bool, default False
        See `predicted_sound`.
    any_jump : bool, default False
        Take the strongest jump within the tolerance however small it is, and return the
        power over its first 0.5 ms (relative to the floor of the detector: the noise's, or
        the predictor error's) in place of the amplitude: how strongly something starts there.
    impulse : bool, default False
        With `predicted_sound`: a sound is there where the error's first 11 samples jump
        enough, where those are fewer than 0.5 ms (above 22.05 kHz); the strongest jump over
        0.5 ms still places it. An impact starting on a ring's burst of the impact before,
        which the predictor continues, is an impulse into the same modes: in the error its
        power sits in its first samples, whatever the rate, and averaged over 0.5 ms it is
        diluted by the samples that holds (3.4 dB more at 48 kHz than at 22.05 kHz, where
        the thresholds were set). Only for the searches on a burst (:func:`_hidden_causes`,
        and an impact between two others whose onset was found on a burst's swell,
        :func:`_fill_impacts`): in the probes of quieter stretches the shorter window lets
        more of the noise's spikes through.

    Returns
    -------
    tuple of float or None
        Onset (s), its 1σ (s), amplitude (full scale) and whether it clipped; None if no
        transient starts there.

    Notes
    -----
    The last bounces come a few ms apart, on the decaying sound, rings and echoes of the ones
    before: their power jumps less over the mean of the 2 ms before them than an isolated
    impact's, often below the weak trigger. Where the trend says an impact must be, the
    trigger compares the power of its first 0.5 ms with the quietest 0.5 ms of the 2 ms
    before it instead (the level the earlier sound has decayed to), with the thresholds of a
    weak trigger; the strongest such jump within the tolerance is timed as in the stream.
    The segment read starts 50 ms earlier, for the high-pass to settle.
    """
    settings, sample_rate = stream.settings, stream.settings.sample_rate
    centre, reach = int(round(predicted * sample_rate)), int(np.ceil(tolerance * sample_rate))
    # A probe asked again at the same moment (with another threshold) reuses the stretch,
    # its filtering and its predictor.
    key = (predicted, tolerance, predicted_sound)
    if stream.probe_memo is None or stream.probe_memo[0] != key:
        stream.probe_memo = (key, _probed_stretch(stream, predicted, centre, reach,
                                                  predicted_sound))
    if stream.probe_memo[1] is None:
        return None  # too close to either end of the recording
    offset, raw, filtered, detector, power, loudness, taps = stream.probe_memo[1]
    cumulative = np.concatenate(([0.0], np.cumsum(power)))
    earliest = centre - reach
    if not_before is not None:
        earliest = max(earliest, int(np.ceil(not_before * sample_rate)) + 2 * _AIC_MARGIN)
    if earliest > centre + reach:
        return None
    triggers = np.arange(earliest, centre + reach + 1) - offset
    sta = (cumulative[triggers + settings.sta] - cumulative[triggers]) / settings.sta
    short = min(settings.sta, _IMPULSE_SAMPLES) if impulse and taps is not None else settings.sta
    first = (cumulative[triggers + short] - cumulative[triggers]) / short
    parts = settings.background // settings.sta
    quietest = np.min([cumulative[triggers - k * settings.sta]
                       - cumulative[triggers - (k + 1) * settings.sta] for k in range(parts)],
                      axis=0) / settings.sta
    # A sound seen only in the prediction error must jump as much as a strong trigger.
    min_jump = settings.min_jump / (1.0 if taps is not None and not expected
                                    else _WEAK_JUMP_FACTOR)
    if any_jump:
        min_jump = 0.0
    if not_before is not None:
        # Past the start of a ring or an echo, the level to jump over is that sound's, the
        # mean power since it started, and by the 1.8 dB that tell a sound of its own.
        since = max(int(np.ceil(not_before * sample_rate)) - offset, 0)
        quietest = np.maximum(quietest, (cumulative[triggers] - cumulative[since])
                              / (triggers - since))
        min_jump = _PROBE_RING_JUMP
    jump = sta / np.maximum(quietest, 1.0)
    loud = (loudness[triggers + settings.sta] - loudness[triggers]) / settings.sta
    # A sound is there where its first samples jump enough (`impulse`: its first 11); the
    # strongest jump over the first 0.5 ms places it.
    usable = (loud >= settings.min_power) & (first / np.maximum(quietest, 1.0) >= min_jump)
    if not usable.any():
        return None
    trigger = int(triggers[usable][np.argmax(jump[usable])])
    if any_jump:
        return (trigger + offset) / sample_rate, np.nan, float(sta[trigger - triggers[0]]), False
    # The AIC picker looks back from the trigger, but not before the tolerance: a ring or an
    # echo of an earlier impact starting shortly before would capture the pick.
    search = max(trigger - settings.back_search, int(triggers[0]) - 2 * _AIC_MARGIN)
    gap = max(_AIC_MARGIN, int(round(_RING_GAP_SECONDS * sample_rate)))
    rough = search + int(_onset_picks(power[search:trigger + settings.sta][None, :],
                                      np.zeros(1, dtype=np.int64), gap, settings.sta)[0])
    if not_before is not None:
        # A sound of its own: its power jumps 1.8 dB over that of the sound since `not_before`.
        after = (cumulative[rough + settings.sta] - cumulative[rough]) / settings.sta
        if rough - since < _AIC_MARGIN or after < _PROBE_RING_JUMP * (
                cumulative[rough] - cumulative[since]) / (rough - since):
            return None
    # As in the stream, the fit window sits on the timing channel's own rough onset (the
    # channels of a stereo pair hear an impact at different delays).
    own = detector[search:trigger + settings.sta, timing] ** 2
    start = search + int(_onset_picks(own[None, :], np.zeros(1, dtype=np.int64), gap,
                                      settings.sta)[0]) - settings.pre
    if taps is None:
        window = filtered[start:start + settings.pre + settings.span, timing]
        # Amplitude as for the stream's transients: largest deviation of the raw samples
        # from their level before the onset, over all channels; a flat top marks clipping.
        before = raw[rough - settings.pre:rough].mean(axis=0)
        amplitude = float(np.abs(raw[rough:rough + settings.amplitude] - before).max())
    else:
        # On a ring, the new sound is the signal less the ring's predicted continuation:
        # its onset is fitted, and its amplitude measured, on that (the ring's own samples
        # would count towards the amplitude of a faint sound starting on it).
        window = _new_sound(filtered, taps, start, settings.pre + settings.span)[:, timing]
        amplitude = float(np.abs(_new_sound(filtered, taps, rough, settings.amplitude)).max())
    onset, sigma, _ = _onset_posterior(window[None, :], settings.pre, sample_rate)
    after = raw[rough:rough + settings.amplitude]
    magnitude = np.abs(after).ravel()
    clipped = bool(magnitude.max() > 0 and (magnitude >= magnitude.max()
                                            * (1 - _CLIP_TOLERANCE)).sum() >= _CLIP_RUN)
    return ((offset + start + float(onset[0])) / sample_rate,
            float(sigma[0]) / sample_rate, amplitude, clipped)


def _probed_stretch(stream, predicted, centre, reach, predicted_sound):
    """The stretch of the recording :func:`_probe` searches around `predicted` (s; sample
    `centre`, `reach` samples either side): its first sample, raw and high-passed samples,
    the detector's whitened signal (or, with `predicted_sound`, the error of a predictor of
    the sound before the window) and its weighted power, the whitened power's running sum
    from 0, and the predictor's taps (None without); None where the stretch runs past
    either end of the recording."""
    settings, sample_rate = stream.settings, stream.settings.sample_rate
    lead = settings.history + settings.background + int(_PROBE_WARMUP_SECONDS * sample_rate)
    offset, raw = stream.recording.stretch(centre - reach - lead,
                                           centre + reach + settings.lookahead + 1)
    if offset + raw.shape[0] < centre + reach + settings.lookahead or offset > centre - reach \
            - settings.history - settings.background:
        return None
    filtered = stream.highpass_from_rest(raw)
    noise, rho = stream.noise_at(predicted)  # as the detection had it there
    share = stream.share_at(predicted)  # each channel's share of the statistic, too
    detector = np.zeros_like(filtered)
    detector[1:] = filtered[1:] - rho * filtered[:-1]
    power = (detector * detector) @ _channel_weights(noise, stream.noise_floor, noise**2, share)
    loudness = np.concatenate(([0.0], np.cumsum(power)))
    taps = None
    order = _predictor_order(sample_rate)
    if predicted_sound and centre - reach - offset > 4 * order:
        # Jumps are looked for in the error of a predictor of the sound before the window:
        # an impact starting inside a loud ring is an impulse there; its loudness is still
        # the whitened signal's.
        taps = _sound_predictor(filtered, centre - reach - offset, order)
        detector, floor = _prediction_error(filtered, taps, noise, rho)
        power = (detector * detector) @ _channel_weights(noise, stream.noise_floor, floor, share)
    return offset, raw, filtered, detector, power, loudness, taps


def _one_per_impact(times, sigmas):
    """Indices of `times` (s) in time order, one per impact: times less than 1 ms apart (the
    merge window) are one impact timed twice, on its own onset and on a ring or an echo
    that a later pass timed it from, and only the most precise (smallest 1σ, `sigmas`) is
    kept."""
    order = np.argsort(times, kind="stable")
    group = np.cumsum(np.r_[True, np.diff(times[order]) >= _MERGE_SECONDS])
    best = order[np.lexsort((sigmas[order], group))]  # by group, the most precise first
    kept = best[np.r_[True, np.diff(np.sort(group)) > 0]]
    return kept[np.argsort(times[kept])]


def _robust_trend(impact_times, rounds=3, timed_off=False):
    """:func:`_trend` of the impacts, leaving out ratios more than 3 scatters off the trend.

    A missed impact doubles an interval: the two ratios around it (about 1.9 and 0.5) would
    bend a parabola fitted through them exactly where the missed impacts are looked for
    (:func:`dashpot.plausibility.ratio_trend`, with the scatter floor of the selection).
    Where `timed_off`, for the search for the impacts the trend predicts
    (:func:`_fill_impacts`), the fit also allows for onsets timed off on the last, short
    intervals (a ring's burst or the sound of the impact before taken for the onset, by a few
    tenths of a ms): each ratio is weighted by its timing noise, and a ratio left out takes
    its neighbours on the other side of the trend with it. Left in, those neighbours bent the
    trend of such trains by several % where their last impacts are predicted, and the
    predictions missed them.
    """
    if not timed_off:
        return ratio_trend(impact_times, floor=_RATIO_SCATTER_FLOOR, rounds=rounds)
    return ratio_trend(impact_times, floor=_RATIO_SCATTER_FLOOR, rounds=rounds,
                       jitter=_TREND_TIMING_SECONDS, paired=True)


def _trim_growing_end(times, sigmas, scatter):
    """Number of impacts to keep: the train ends before its intervals grow.

    A ball coming to rest bounces ever more often; past the last bounce, sounds that happen
    to follow (a ring of the last impacts, the rest tail of a rolling ball, a click) make an
    interval longer than the one before, and those after it may shrink again (rings and
    echoes of the last impacts repeat their intervals). Each interval ratio of the last
    quarter of the impacts is tested against 1, from the first on: where its log exceeds 3σ
    of the onsets' timing noise (`sigmas`, s, on both intervals) plus the scatter of the log
    ratios about their trend (`scatter`: the restitution's own variation), the train ends
    before that interval, unless the interval is two or three bounces of the trend
    (:func:`_spans_missed_bounces`: an impact missed in between), or, where sounds follow,
    it and the interval before or after it are two (the impact between them timed off, or a
    ring taken for one), or the intervals after it come back under the three before it
    (their medians) and it is less than three times as long as them. An interval three
    times as long as those before it, and not two or three bounces, ends the train from the
    last half of the impacts on: an echo of the train's tail can hold more than a quarter of
    the sounds.
    """
    for end in range(max(4, int(0.5 * times.size)), times.size):
        a, b, c = times[end - 2:end + 1]
        first, second = b - a, c - b
        before = median(np.diff(times[end - 4:end]).tolist())
        impossible = second >= _MOST_BOUNCES * before
        if end < int(0.75 * times.size) and not impossible:
            continue
        timing = (sigmas[end - 2] ** 2 + sigmas[end - 1] ** 2) / first**2 + (
            sigmas[end - 1] ** 2 + sigmas[end] ** 2) / second**2
        allowed = 3.0 * np.sqrt(timing) + scatter
        if np.log(second / first) <= allowed or _spans_missed_bounces(
                times[:end], second, allowed):
            continue
        if end + 1 == times.size or impossible:
            return end
        # One impact timed off, early (b) or late (c), or a ring taken for one.
        if _spans_missed_bounces(times[:end - 1], c - a, allowed, most=2) or (
                _spans_missed_bounces(times[:end], times[end + 1] - b, allowed, most=2)):
            continue
        # The train goes on past a grown interval where the intervals after it come back
        # under those before it (impacts timed off in a row); the sounds after a train
        # (rings and echoes of its impacts repeat its earlier intervals) do not.
        if median(np.diff(times[end:]).tolist()) < before:
            continue
        return end
    return times.size


def _drop_start(times, amplitudes):
    """Index of the impact at which the ball's last drop among `times` (s, increasing; their
    `amplitudes`, full scale) starts: 0 where they are all one drop's.

    A chain of impacts over a recording of several drops can take the loud first impacts of
    the earlier drops, a few seconds apart, before the last drop's train: their intervals
    shrink and grow within the bounds of missed impacts. The train is walked back from its
    end, each interval a flight of the ball or up to :data:`_MOST_BOUNCES` of them (missed
    impacts), each earlier flight longer by 1/r, r the median ratio of the intervals after
    it (a geometric train [5]_). An interval longer than :data:`_DROP_GAP` times the most it
    can span (the restitution may be lower at the higher speeds of the earlier flights) is
    no flight of this ball: it holds the ball's rest, pick-up and fall. So is one longer
    than the most it can span where the impact after it is more than :data:`_DROP_RISE`
    times as loud as the one before: within a train the impact speed, and with it the
    sound, only falls (an impact on a secondary of the one before sums the two).
    """
    intervals = np.diff(times)
    if intervals.size < 2:
        return 0
    ratios = np.clip(intervals[1:] / intervals[:-1], *_RATIO_BOUNDS)
    # The median of the ratios from each on to the end, at once.
    upper = np.triu(np.ones((ratios.size, ratios.size), dtype=bool))
    medians = np.minimum(np.nanmedian(np.where(upper, ratios[None, :], np.nan), axis=1),
                         _MAX_DROP_RATIO).tolist()
    limits = np.where(amplitudes[1:] > _DROP_RISE * amplitudes[:-1], 1.0, _DROP_GAP).tolist()
    # The first flight of the interval after the impact reached. Transients taken for impacts
    # at the end make intervals short, so it starts from the upper quartile of the last eight,
    # and going back it never shrinks.
    flight = float(np.percentile(intervals[-8:], 75))
    spans = [0.0] * int(_MOST_BOUNCES)
    # Sequential, in scalars: each interval's flights are measured from the one after it.
    for index, interval in zip(range(intervals.size - 2, -1, -1), intervals[-2::-1].tolist()):
        earliest, total = flight, 0.0
        for bounce in range(len(spans)):
            earliest /= medians[index]
            total += earliest
            spans[bounce] = total
        if interval > limits[index] * total:
            return index + 1
        bounces = min(range(len(spans)), key=lambda k: abs(spans[k] - interval))
        first = flight / medians[index] ** (bounces + 1)  # the earliest of its flights
        flight = max(interval * first / spans[bounces], flight)
    return 0


def _rest_time(times, coefficients, scatter, bounces=10):
    """Number of impacts to keep: none after the ball has come to rest.

    The flights after an impact shrink and sum to a finite rest time: for a ratio r held
    constant, T·r/(1 − r) after a flight of T s (a geometric series [5]_). Each of the last
    `bounces` impacts whose two interval ratios before it follow the trend (to 3 `scatter`,
    in log) gives an estimate of that time, from the median T of the three intervals before
    it and the trend's ratio there (held within the ratio bounds; no rest time where it is
    1 or more): the impacts of one train give about the same (a mis-timed onset or a
    transient taken for an impact give outliers). The ratio is not stepped on along the
    trend below the intervals it was fitted to, where a parabola can bend back to 1. Sounds
    later than the estimates' median by more than 3 of their robust standard deviations,
    plus the merge window, are not bounces of this train (a run of echoes of its impacts that
    continues its intervals, a rest click); at most a quarter of the impacts go. The last
    impacts are used because they are the closest to the rest time.
    """
    keep = times.size
    if keep < 8:
        return keep
    intervals = np.diff(times)
    log_interval = np.log(intervals)
    residual = log_interval[1:] - log_interval[:-1] - np.polyval(coefficients, log_interval[:-1])
    # Impact k (k >= 3) follows the trend where the ratios residual[k - 3], residual[k - 2]
    # do; its flight is the median of intervals[k - 3:k].
    follows = np.all(np.abs(np.stack([residual[:-2], residual[1:-1]])) <= 3.0 * scatter,
                     axis=0)
    chosen = (np.flatnonzero(follows) + 3)[-bounces:]
    if chosen.size < 5:
        return keep
    flights = np.median(np.stack([intervals[chosen - 3], intervals[chosen - 2],
                                  intervals[chosen - 1]]), axis=0)
    log_lo, log_hi = (log(bound) for bound in _RATIO_BOUNDS)
    ratio = np.exp(np.clip(np.polyval(coefficients, np.log(flights)), log_lo, log_hi))
    moment = np.full(chosen.size, np.inf)  # where the flights do not shrink: no rest time
    shrinking = ratio < 1.0
    moment[shrinking] = (times[chosen] + flights * ratio / (1.0 - ratio))[shrinking]
    centre = float(np.median(moment))
    if not np.isfinite(centre):
        return keep
    spread = 1.4826 * float(np.median(np.abs(moment - centre)))
    late = np.flatnonzero(times > centre + 3.0 * spread + _MERGE_SECONDS)
    if late.size:
        keep = max(int(late[0]), int(0.75 * times.size))
    return keep


def _drop_faint_end(times, amplitudes, bounces=10, at_most=2):
    """Number of impacts to keep: the train does not end on a sound fainter than its impact.

    The sound of an impact grows with the impact speed (its peak force, for a linear contact,
    is proportional to it), and the impact speed with the flight before it (v = g·T/2 for a
    flight of T s): along a train, amplitude / interval is about constant. The last impact is
    expected at that constant (the median over the `bounces` impacts before it) times the
    shorter of its interval and the one before it (an interval spanning missed bounces holds
    a shorter flight than itself). A last sound more than 6 dB (:data:`_EXTENSION_LOUDNESS`)
    under that is a ring, echo or click after the ball's last bounce, not a bounce; at most
    `at_most` are dropped. The interval holds the contact too (about 1 ms for a hard ball),
    so the law holds while the flights are long against it (intervals of several ms); on
    shorter last intervals it expects too loud a sound and may drop a true last impact.
    """
    keep = times.size
    while keep > max(5, times.size - at_most):
        intervals = np.diff(times[:keep])
        speed_law = np.median(amplitudes[max(1, keep - 1 - bounces):keep - 1]
                              / intervals[max(0, keep - 2 - bounces):keep - 2])
        flight = min(intervals[-1], intervals[-2])
        if amplitudes[keep - 1] * _EXTENSION_LOUDNESS >= speed_law * flight:
            break
        keep -= 1
    return keep


def _recurring_secondaries(times, amplitude, chain):
    """Delays (s) at which rings, bursts or echoes recur after the impacts of `chain`
    (:func:`_secondary_delays`), and their usual levels relative to the impact
    (:func:`_secondary_levels`; NaN where none is found)."""
    delays = _secondary_delays(times, chain)
    return delays, _secondary_levels(times, amplitude, chain, delays)


def _secondary_levels(times, amplitude, chain, delays):
    """Loudness of the secondaries recurring at `delays` (s) after the impacts of `chain`,
    relative to their impact: per delay, the median ratio of the amplitude of the loudest
    transient within 1 ms of that delay after each impact (left out of the chain) to the
    impact's amplitude; NaN where none is found."""
    levels = np.full(delays.size, np.nan)
    others = np.setdiff1d(np.arange(times.size), chain)
    if others.size == 0:
        return levels
    impacts = times[chain]
    for k, delay in enumerate(delays):
        ratios = []
        for member, moment in zip(chain, impacts):
            lo, hi = np.searchsorted(times[others], [moment + delay - 1e-3,
                                                     moment + delay + 1e-3])
            if hi > lo:
                ratios.append(amplitude[others[lo:hi]].max() / amplitude[member])
        if ratios:
            levels[k] = float(np.median(ratios))
    return levels


def _drop_trailing_secondaries(times, amplitudes, delays, levels, impact=None):
    """Number of impacts to keep: the train does not end on rings, bursts or echoes.

    Past its last impact a ball's train falls silent, but the secondaries of the last impacts
    (a ring's burst 5-8 ms after its impact, a ring, an echo) come on at the delays at which
    they recur after every impact (`delays`, s, :func:`_secondary_delays`), where the last
    intervals, a few ms long, make them look like the next bounces. The last member is
    dropped while it lies within 0.3 ms of such a delay after an earlier member and is no
    louder than twice what that secondary is after its impact (`levels`, the median
    ratio, :func:`_secondary_levels`): the sums of the last intervals span the delays
    closely, so the delay alone would take true last impacts too, but those are about as
    loud as the impacts before them. Where twice that secondary is still fainter than the
    last impacts (the median of the three before), the sound must be closer to it than to
    them in log amplitude (no louder than their geometric mean): an impact that lands on a
    faint ring is measured fainter than the impacts before it, but far louder than the ring.
    At most a quarter of the impacts go, and none for which
    `impact` (a function of its index, optional) is true: a sound that sets off the
    secondaries of an impact (:func:`_sets_off_secondaries`) is one, whatever falls on it.
    """
    keep = times.size
    usable = np.isfinite(levels)
    delays, levels = delays[usable], levels[usable]
    if delays.size == 0:
        return keep
    while keep > max(4, int(0.75 * times.size)):
        offsets = times[keep - 1] - times[:keep - 1, None] - delays[None, :]
        secondary = amplitudes[:keep - 1, None] * levels[None, :]
        recent = np.median(amplitudes[max(0, keep - 4):keep - 1])
        expected = _SECONDARY_MARGIN * secondary
        expected = np.where(expected < recent, np.sqrt(secondary * recent), expected)
        if not np.any((np.abs(offsets) < _PROBE_SECONDARY_SECONDS)
                      & (amplitudes[keep - 1] <= expected)) or (
                impact is not None and impact(keep - 1)):
            break
        keep -= 1
    return keep


def _shows_secondary(probe, moment, amplitude, delay, level, expected=False,
                     timing=_CAUSE_SEARCH_SECONDS):
    """Whether a sound at `moment` (s) of `amplitude` (full scale) is followed, `delay` (s)
    later, by a sound at least a quarter as loud as the secondary of usual loudness `level`
    (relative) there, looked for in the error of a predictor of the sound (``probe(moment,
    tolerance, predicted_sound=True, expected=expected)``: `expected` confirms it with a
    weak trigger's jump, else a strong one's) within 0.5 ms of that time, and its onset
    timed within `timing` (s) of it."""
    result = probe(moment + delay, _CAUSE_SEARCH_SECONDS, predicted_sound=True,
                   expected=expected)
    return (result is not None and abs(result[0] - moment - delay) <= timing
            and result[2] >= _OWN_SECONDARY_LEVEL * level * amplitude)


def _lands_on_impact(impacts, moment):
    """Whether one of `impacts` (s) starts at `moment` (s), from 0.5 ms before it to 1 ms
    after: a probe for a secondary there finds that impact's onset, which shows nothing
    either way."""
    gap = np.asarray(impacts, dtype=float) - moment
    return bool(np.any((gap > -_CAUSE_SEARCH_SECONDS)
                       & (gap <= _CAUSE_SEARCH_SECONDS + _STA_SECONDS)))


def _sets_off_secondaries(probe, moment, amplitude, delays, levels, end, shown_by=(),
                          impacts=()):
    """Whether a sound at `moment` (s) sets off every secondary at least a quarter as loud
    as its impact, 3 ms or more after it, that the recording (to `end`, s) holds: a sound
    that does is an impact, whatever ring or echo of an earlier one falls on it; False where
    none can be tested. Given `shown_by`, (moment, amplitude) of impacts, only secondaries
    that each of them is seen to set off are tested (a ring of low modes landing on the
    sounds of the last bounces may not stand out in the predictor's error after any). A
    secondary of one of them that one of `impacts` (s) starts on, or up to 1 ms after, is
    not looked for: the probe would find that impact's onset (the last intervals come down
    to a ring burst's delay), which shows nothing either way."""
    testable = [(delay, level) for delay, level in zip(delays, levels)
                if np.isfinite(level) and level >= _OWN_SECONDARY_LEVEL
                and delay >= _CAUSE_DELAY_SECONDS[0] and moment + delay + _MASK_SECONDS < end
                and all(_lands_on_impact(impacts, at + delay)
                        or _shows_secondary(probe, at, loud, delay, level, expected=True)
                        for at, loud in shown_by)]
    return bool(testable) and all(_shows_secondary(probe, moment, amplitude, delay, level,
                                                   expected=True)
                                  for delay, level in testable)


def _drop_unechoed_end(times, amplitudes, delays, levels, probe, end):
    """Number of impacts to keep: the last one must be followed by its own secondaries.

    An impact sets off the secondaries every impact of the train sets off (a ring's burst,
    a ring, an echo, at the delays `delays`, s, with the usual levels `levels` relative to
    the impact, at least a quarter); a burst, ring or echo of the last impact, heard after
    it like one more bounce, sets off none. Where the four impacts before the last each
    show a secondary within 0.5 ms of one delay (looked for in the error of a predictor of
    the sound, ``probe(moment, tolerance, predicted_sound=True)``, at least a quarter of
    the usual level; those whose secondary another impact starts on are not asked,
    :func:`_lands_on_impact`), the last impact is kept only if it shows one too, or if the
    recording (`end`, s) stops before that secondary's time is over. Its own need only jump
    as much as a weak trigger's, and its onset may be timed up to 1 ms off: the last impact
    is the faintest, and its secondary starts on the decaying sound of the louder ones of
    the impacts before it. At most two are dropped.
    """
    keep = times.size
    # From 3 ms on: closer sounds are the impact's own first arrivals, not a secondary.
    usable = (np.isfinite(levels) & (levels >= _OWN_SECONDARY_LEVEL)
              & (delays >= _CAUSE_DELAY_SECONDS[0]))

    def shows(position, delay, level, expected=False):
        return _shows_secondary(probe, times[position], amplitudes[position], delay, level,
                                expected, _LAST_SECONDARY_SECONDS if expected
                                else _CAUSE_SEARCH_SECONDS)

    for delay, level in zip(delays[usable], levels[usable]):
        while keep > max(5, times.size - 2) and times[keep - 1] + delay + _MASK_SECONDS < end:
            tested = [position for position in range(keep - 5, keep - 1)
                      if not _lands_on_impact(times[:keep], times[position] + delay)]
            if not tested or not all(shows(position, delay, level) for position in tested):
                break
            if shows(keep - 1, delay, level, expected=True):
                break
            keep -= 1
    return keep


def _drop_unexcited_end(times, probe, probed=None, at_most=2):
    """Number of impacts to keep: the train does not end on a sound that excites nothing.

    An impact excites the ball's modes anew: in the error of a linear predictor of the sound
    before it [6]_ [7]_ it is an impulse. Past the last bounce the decaying sound of the last
    impacts, their rings and echoes still beat (modes drifting in and out of phase): a swell
    of that beating jumps over the quietest stretch before it like an onset, and is probed as
    one where the trend puts a next bounce, but the predictor continues it. The last sound's
    impulse (the error's power over its first 0.5 ms, ``probe(moment, tolerance,
    predicted_sound=True, any_jump=True)``) is compared with those of the three impacts
    before it, which the last bounces, of about one impact speed, match to within 6 dB (a
    quarter in power, :data:`_IMPULSE_POWER_SHARE`: their speeds, and so their impulses, fall
    by a few % per bounce, the timbre of each impact varying more).
    A weaker one is still an impact where it jumps as much as a weak trigger's (``probe(...,
    expected=True)``, within 0.5 ms of its onset) and is at least a tenth of theirs (10 dB,
    :data:`_FAINT_IMPULSE_SHARE`): in a faint train every impulse barely clears the error's
    floor, but after loud impacts a swell clears it too. The last sound is dropped while it
    passes neither test; at most `at_most` go, and none that cannot be tested. Only sounds
    found by probing the file are tested (`probed`, bool per sound; default all): a
    transient the stream triggered on rose over the mean power before it, which a swell of a
    beat, rising over a trough of it, does not.
    """
    keep = times.size
    while keep > max(5, times.size - at_most):
        if probed is not None and not probed[keep - 1]:
            break
        # The last bounces, of about one speed, match the impulses of the impacts before
        # them to within 6 dB (in power, a quarter); a weaker one needs a weak trigger's jump.
        power = [probe(moment, _CAUSE_SEARCH_SECONDS, predicted_sound=True, any_jump=True)
                 for moment in times[keep - 4:keep]]
        if any(result is None for result in power):  # untestable (the file's ends)
            break
        share = power[-1][2] / median(r[2] for r in power[:-1])
        if share >= _IMPULSE_POWER_SHARE or (
                share >= _FAINT_IMPULSE_SHARE
                and probe(times[keep - 1], _CAUSE_SEARCH_SECONDS, predicted_sound=True,
                          expected=True) is not None):
            break
        keep -= 1
    return keep


def _echoed_tail(times, sigmas, amplitudes, sounds, loudness, fitted, shortest=4):
    """Which impacts to keep: the train does not end on an echo of its own sounds.

    An echo repeats the train's sounds one fixed delay later, each weakened by the same
    factor; where the delay is long, the echoes of the last impacts come after the ball has
    come to rest and continue the train with intervals the ball flew earlier. A sound is the
    echo of a louder one (an impact so far or any transient the stream found, located by its
    rough onset to within 1 ms) where it follows that sound's fitted onset by the echo's
    delay to within 3·√2 of its 1σ plus 20 µs, never more loosely than 30 µs (an echo
    repeats the onset of the sound it copies), and where its amplitude is that sound's times
    the echo's factor to within a factor 1.5. The delay and the factor are those the most
    sounds in the last half share. The run of such echoes that reaches the last sounds (the
    last two may be other sounds), going back past up to two sounds in a row that are not
    echoes (echoes timed off their sources, other sounds among them), is a copy if it holds at
    least `shortest` echoes; then every echo at that delay and factor in the last half is
    left out (where the delay is shorter than the train, the echoes come among its last
    bounces), and the sounds between them are judged with the train's end
    (:func:`_train_end`). Delays of 3-200 ms (those of rings' bursts and echoes) are tried on
    a 0.5 ms grid, from the last three sounds back to the louder transients before them:
    one delay and one factor shared by several sounds at once to tens of µs is no chance
    coincidence.

    Parameters
    ----------
    times, sigmas, amplitudes : ndarray
        Onsets (s, increasing), 1σ (s) and amplitudes (full scale) of the impacts so far.
    sounds, loudness : ndarray
        Rough onsets (s) and amplitudes of all transients the stream found.
    fitted : callable
        Fitted onsets (s) of the transients of given indices.
    shortest : int, default 4
        Fewest echoes that make a copy.

    Returns
    -------
    ndarray of bool
        False for the echoes of the copy.
    """
    count = times.size
    if count < 2 * shortest:
        return np.ones(count, dtype=bool)
    rough = np.concatenate([times, sounds])
    louder = np.concatenate([amplitudes, loudness])
    positions = np.arange(count // 2, count)
    # Sources may be any louder sound (the rows: the last half of the impacts).
    quieter = louder[None, :] <= amplitudes[positions][:, None]
    allowed = np.minimum(3.0 * np.sqrt(2.0) * sigmas[positions] + _ECHO_SLACK_SECONDS,
                         _ECHO_MATCH_SECONDS)
    ends = np.arange(count - _ECHO_LOOSE_END - 1, count)
    tried = np.concatenate([times[k] - rough[louder > amplitudes[k]] for k in ends])
    tried = tried[(tried >= _CAUSE_DELAY_SECONDS[0]) & (tried <= _CAUSE_DELAY_SECONDS[1])]
    keep = np.ones(count, dtype=bool)
    # Each delay tried locates sources to 1 ms: delays on a 0.5 ms grid miss none.
    for delay in np.unique(np.round(tried / _ECHO_GRID_SECONDS)) * _ECHO_GRID_SECONDS:
        distance = np.abs(times[positions][:, None] - delay - rough[None, :])
        distance[quieter] = np.inf
        nearest = np.argmin(distance, axis=1)
        located = distance[np.arange(positions.size), nearest] <= _ECHO_ROUGH_SECONDS
        if located.sum() < shortest:
            continue
        onsets = np.full(positions.size, np.nan)
        member = located & (nearest < count)
        onsets[member] = times[nearest[member]]
        transient = located & (nearest >= count)
        if transient.any():
            onsets[transient] = fitted(nearest[transient] - count)
        offset = times[positions] - onsets
        factor = np.log(amplitudes[positions] / louder[nearest])
        # The delay and factor the most sounds share.
        close = ((np.abs(offset[:, None] - offset[None, :]) <= allowed[:, None])
                 & (np.abs(factor[:, None] - factor[None, :]) <= log(_ECHO_FACTOR_SPREAD)))
        if not close.any():
            continue
        echo = close[int(np.argmax(close.sum(axis=1)))]
        found = np.flatnonzero(echo)
        if found[-1] < positions.size - 1 - _ECHO_LOOSE_END:
            continue
        # Back from there while the sounds are echoes, past up to two in a row that are not
        # (echoes timed off their sources, other sounds of the train's tail among them).
        start = found[-1]
        while (behind := np.flatnonzero(echo[max(0, start - 3):start])).size:
            start = max(0, start - 3) + int(behind[-1])
        if echo[start:].sum() >= shortest:
            keep[positions[echo]] = False
    return keep


def _train_end(times, sigmas, amplitudes, scatter, delays, levels, probe, probed, end):
    """Number of sounds that are the train's impacts, and how many each check left out.

    The last sounds are judged in turn: the train ends before its intervals grow
    (:func:`_trim_growing_end`); it does not end on a sound at a secondary's delay no louder
    than such a secondary (:func:`_drop_trailing_secondaries`; unless it sets off the
    secondaries of an impact itself, :func:`_sets_off_secondaries`: then it is one, whatever
    falls on it), nor on one that lacks the secondary every impact before it sets off
    (:func:`_drop_unechoed_end`), nor on a swell of the beating of the sound before it (no
    impulse in the error of a predictor of that sound, :func:`_drop_unexcited_end`), nor on
    one far fainter than the impact speed its flight gives (:func:`_drop_faint_end`). A
    sound that became the last once the later checks left out sounds after it is judged
    for a secondary's delay once more.

    Parameters
    ----------
    times, sigmas, amplitudes : ndarray
        Onsets (s, increasing), their 1σ (s) and amplitudes (full scale) of the sounds.
    scatter : float
        Scatter of the log interval ratios about their trend (:func:`_robust_trend`).
    delays, levels : ndarray
        Delays (s) and usual levels (relative) of the recurring secondaries
        (:func:`_secondary_delays`, :func:`_secondary_levels`).
    probe : callable
        As in :func:`_fill_impacts`.
    probed : ndarray of bool
        Which sounds were found by probing the file (no trigger of their own).
    end : float
        End of the recording (s).

    Returns
    -------
    kept, grown_out, secondaries_out, faint_out : int
        Sounds kept (the first `kept`), and those left out for a grown interval, as
        secondaries (or unexcited), and as too faint.
    """
    grown = _trim_growing_end(times, sigmas, scatter)

    def impact(k):
        return _sets_off_secondaries(probe, times[k], amplitudes[k], delays, levels, end,
                                     list(zip(times[k - 3:k - 1], amplitudes[k - 3:k - 1])),
                                     times)

    kept = _drop_trailing_secondaries(times[:grown], amplitudes[:grown], delays, levels,
                                      impact)
    kept = _drop_unechoed_end(times[:kept], amplitudes[:kept], delays, levels, probe, end)
    kept = _drop_unexcited_end(times[:kept], probe, probed[:kept])
    faint = _drop_faint_end(times[:kept], amplitudes[:kept])
    if faint < grown:
        final = _drop_trailing_secondaries(times[:faint], amplitudes[:faint], delays, levels,
                                           impact)
    else:
        final = faint
    return final, times.size - grown, grown - kept + faint - final, kept - faint


def _spans_missed_bounces(times, interval, allowed, most=3):
    """Whether `interval` (s) after `times` is two (to `most`) bounces of their trend.

    An impact lost under the ring of the one before (the last bounces barely rise over it)
    leaves an interval of two bounces, about twice the last one: not a growing interval.
    The trend of the impacts before (:func:`_robust_trend`) steps the last bounce (the
    shortest of the last three intervals, stepped on to the end) on by two and by three
    bounces; `interval` must match one of the sums to within `allowed`
    (in log).
    """
    if times.size < 5:
        return False
    coefficients, _ = _robust_trend(times)
    step = _trend_step(coefficients, np.diff(times).min())
    # Stepped on from the shortest of the last three intervals, a single bounce: the last one
    # may itself span missed bounces (or end on a ring), and stepping on from it would accept
    # ever longer intervals after it.
    recent = np.diff(times[-4:])
    back = recent.size - 1 - int(np.argmin(recent))
    bounce, total = float(recent.min()), 0.0
    for _ in range(back):
        bounce = step(bounce)
    for count in range(1, most + 1):
        bounce = step(bounce)
        total += bounce
        if count >= 2 and abs(np.log(interval / total)) <= allowed:
            return True
    return False


def _fill_impacts(times, amplitudes, coefficients, scatter, delays, probe, end, levels=None,
                  stop=None):
    """Impacts the bounce trend predicts where none was timed, found by `probe`.

    Parameters
    ----------
    times, amplitudes : ndarray
        Fitted onsets (s, increasing) and amplitudes (full scale) of the impacts chosen so far.
    coefficients, scatter : ndarray, float
        Trend of ln(interval ratio) against ln(interval) (:func:`_robust_trend`).
    delays : ndarray
        Delays (s) of the rings and echoes that recur after the impacts.
    probe : callable
        ``probe(predicted, tolerance, not_before=None)`` -> (time, sigma, amplitude,
        clipped) or None (:func:`_probe`).
    end : float
        End of the recording (s).
    levels : ndarray, optional
        Usual loudness of the secondaries at `delays` relative to their impact
        (:func:`_secondary_levels`; NaN or not given: unknown).
    stop : float, optional
        No impact is looked for past this time (s; default `end`). The secondaries of a sound
        are still looked for up to `end`.

    Returns
    -------
    added : list of tuple
        (time, sigma, amplitude, clipped) of each impact found between or after `times`.
    retimed : dict
        Index into `times` -> (time, sigma, amplitude, clipped): impacts whose onset was the
        start of a ring or an echo just before them, timed again on an onset of their own;
        None where no onset of their own rises out of that sound (the impact is then left
        out of the table: a gap, never a time taken from the trend).

    Notes
    -----
    The impacts are walked in time order, each predicted from the three before it
    (:func:`_predict_next`); the tolerance is three standard deviations of the ratio scatter
    plus 0.2 ms. An interval more than 1.5 times the predicted one holds a missed impact, and
    past the last impact the train goes on while the predicted interval exceeds the merge
    window: the file is probed at the predicted time. An impact off its prediction by more
    than the tolerance whose onset lies within 0.3 ms of a ring or an echo of an earlier
    impact (a fixed delay after it) was timed at the start of that secondary sound, which
    began just before it: it is probed again at the predicted time, past that start, and past
    each further secondary the probe finds (an echo may be followed by a ring before the
    impact rises out of them), or else looked for as an impulse in the error of a predictor
    of that sound, as below; where neither shows, the impact is
    reported missing (a gap), not placed at the predicted time. An impact within the tolerance
    whose onset is that of such a secondary (the sound began less than the tolerance before
    it) is timed again on an onset of its own rising out of it, where there is one, or else
    on an impulse in the error of a predictor of that sound (``predicted_sound=True``) past
    0.3 ms after its start (a ring's burst is the impact's own modes excited again, which
    the predictor continues), and kept as timed where there is neither. A probed onset must
    lie within the tolerance of the prediction, be at most 6 dB fainter than the impacts
    before it, and
    not itself come at a secondary's delay after an earlier impact, unless it fills an
    interval of two bounces between impacts (the ball bounced there) and is louder than that
    secondary usually is after its impact (an onset there is probed
    past in the same way; an impact that a ring lands on exactly is then lost: it cannot be
    told from the ring). Where a ring died down before the impact (a ring's short burst), the
    impact may also rise over the quietest stretch before it, as any probed onset, at least
    1 ms after the burst's start.
    A sound off its prediction by more than the tolerance, followed by an impact within the
    tolerance of that prediction, is a sound besides the impacts where it comes at a
    secondary's delay after an earlier impact (that ring's burst or echo) or too close before
    that impact for both to be bounces (an interval ratio under 0.45): it is left out. So is,
    on its prediction or not, a sound too close before the next one for both to be bounces
    that comes at a secondary's delay after an earlier impact, no louder than twice that
    secondary usually is, where the next one comes at no such delay after any sound before
    it (an echo landing just before an impact, where a trend bent by such sounds puts it).
    An impact coming later than its tolerance allows, at a secondary's delay after an earlier
    impact or after the predicted time (a delay more than twice the tolerance, so that the
    prediction tells the two apart), is a ring's burst or an echo standing in for an
    impact that was passed over (it barely rose over the sound before it): the impact is
    probed at the predicted time and, found, replaces it; not found, it is left out (None),
    unless it sets off the secondaries of an impact itself, as is also required before an
    impact off its prediction at a secondary's time is left out.
    A sound at a secondary's delay that sets off the secondaries of an impact itself
    (:func:`_sets_off_secondaries`) is an impact. Past the last impact, where no onset of its
    own rises out of such a sound, the sound itself is an impact if it is louder than twice
    what the secondary usually is after an impact two or more bounces before it (the sums of
    the last intervals span the recurring delays closely, and the last impacts are about as
    loud as the ones before them; the check the end of the train gets,
    :func:`_drop_trailing_secondaries`); one delay after the last impact timed it stays that
    impact's ring burst or echo, however loud, unless it sets off the secondaries of an impact
    itself. An impact's onset before its predicted time, less than 2 ms after a ring, burst or
    echo of an earlier impact started (from 3 ms on), may be on that sound's own rise: it is
    probed again past that start, and an onset of its own rising out of it, at least 0.3 ms
    later and closer to the predicted time, is taken instead; so is, between impacts, a probed
    onset more than 0.3 ms early there (a swell of that sound), or else, where no onset of its
    own is closer, an impulse in the error of a predictor of that sound closer to the predicted
    time (in its first samples a weak trigger's jump, as in :func:`_hidden_causes`). Past the
    last impact, a probed onset 0.3-2 ms after such a sound began, which may be as loud as
    it (up to twice its usual level), is that sound's swell (the probe's window opened on
    its rise) unless it sets off the secondaries of an impact itself: the impact, if there,
    is an onset of its own rising out of that sound or an impulse in the error of a
    predictor of it, whichever is closer to the predicted time. An impact timed more than
    0.3 ms after its predicted time but within the tolerance, less than 2 ms after such a
    sound began, may have had its onset's fit pulled late by that sound: such an
    impulse at least 0.3 ms earlier and closer to the predicted time is taken instead. Where the
    whitened power shows no onset on time, the error of a predictor of the sound is probed too
    (``predicted_sound=True``: an impact starting on the loud burst or ring of the one before),
    past the start of that burst or ring where the first impulse found there is at a
    secondary's delay and no more than twice as loud as that secondary usually is (a louder
    impulse there is no ring or echo of the earlier impact: an impact whose onset happens to
    fall on the delay of a faint ring). Between two impacts timed (the ball bounced there) the
    impulse need only jump as much as a weak trigger's (``expected=True``), past the last
    impact as much as a strong one's, or a weak one's where the sound comes at no
    secondary's delay and sets off the secondaries of an impact itself; where nothing is
    found past that start between two impacts, the error is searched once more from 0.6 ms
    past it, for a sound of its own over the power since (the probe's picker may look back
    onto the start itself). An impact that is not found stays in the sequence as a predicted
    anchor, so that the predictions after it step over it; past the last impact two in a
    row end the search.

    Inside the train, a prediction shorter than the merge window (from anchors jammed
    together: a rattle among the impacts, an impact timed twice) is stepped past, not taken
    for the train's end; and a predicted time standing in for an impact left out, within the
    merge window of the next impact timed, is dropped: that impact is the one predicted.
    """
    step = _trend_step(coefficients, np.diff(times).min())
    usual = np.full(delays.size, np.inf) if levels is None else np.where(
        np.isfinite(levels), levels, np.inf)  # unknown level: any loudness
    anchors, loudness = list(times), list(amplitudes)
    origin = list(range(len(anchors)))  # index into `times`, or -1 for a predicted anchor
    heard = [True] * len(anchors)  # a sound timed there (False: a predicted time stands in)
    # From the fourth impact on, each one is predicted from the three intervals before it.
    added, retimed, i, missing = [], {}, 3, 0

    def secondary(moment, before, amplitude=None, margin=1.0, first=0):
        # At a recurring delay after an earlier impact (from index `first` on; and, given
        # the sound's `amplitude`, no louder than `margin` times what that secondary usually
        # is after its impact).
        if delays.size == 0:
            return False
        earlier = np.asarray(anchors[first:before + 1])
        close = np.abs(moment - earlier[:, None] - delays[None, :]) < _PROBE_SECONDARY_SECONDS
        if amplitude is not None:
            close &= amplitude <= (margin * np.asarray(loudness[first:before + 1])[:, None]
                                   * usual[None, :])
        return bool(close.any())

    def rising_secondary(moment, before, amplitude=None):
        # Start (s) of the latest ring, burst or echo of an earlier impact (from 3 ms on)
        # that began less than 2 ms before `moment` (and, given the sound's `amplitude`, may
        # be as loud: up to twice what it usually is), or None.
        if delays.size == 0:
            return None
        usable = delays >= _CAUSE_DELAY_SECONDS[0]
        starts = np.asarray(anchors[:before + 1])[:, None] + delays[usable][None, :]
        possible = (starts < moment - _PROBE_SECONDARY_SECONDS) & (
            starts > moment - _SECONDARY_RISE_SECONDS)
        if amplitude is not None:
            possible &= amplitude <= (_SECONDARY_MARGIN * np.asarray(loudness[:before + 1])[
                :, None] * usual[usable][None, :])
        return float(starts[possible].max()) if possible.any() else None

    def beyond():
        # Past the last impact: the sums of the last intervals, a few ms each, span the
        # recurring delays closely, so a true last impact often falls within 0.3 ms of a
        # secondary's delay after an earlier one. There the delay alone does not make a sound
        # a secondary of an impact two or more bounces before it: one louder than twice that
        # secondary's usual level is no ring or echo of that impact (the test the end of the
        # train gets, :func:`_drop_trailing_secondaries`). One delay after the impact just
        # before it, the sound is that impact's ring burst or echo, however loud (a ring's
        # burst may swell louder than its impact): no impact follows to tell them apart.
        return i + 1 >= len(anchors)

    def last_heard():
        # The last impact timed up to the current one (predicted times stand in for others).
        return max(k for k in range(i + 1) if heard[k])

    def own(result):
        # A sound that sets off the secondaries of an impact (those the impacts before it are
        # seen to set off) is one.
        return result is not None and _sets_off_secondaries(
            probe, result[0], result[2], delays, usual, end,
            [(anchors[k], loudness[k]) for k in range(max(0, i - 1), i + 1) if heard[k]],
            [anchors[k] for k in range(len(anchors)) if heard[k]] + [result[0]])

    def accept(result, predicted, tolerance, before=None, bounded=False, impact=False):
        # In time order between its neighbours: where the ratios scatter widely the tolerance
        # can exceed the interval itself. Within an interval of two bounces between impacts
        # (`bounded`) the ball did bounce there: a sound on time, louder than a ring or an
        # echo of an earlier impact falling there would be, is its impact.
        if before is None:
            before = anchors[i + 1] if i + 1 < len(anchors) else np.inf
        return (result is not None and abs(result[0] - predicted) <= tolerance
                and anchors[i] < result[0] < before
                and result[2] >= np.median(loudness[max(0, i - 2):i + 1]) / _EXTENSION_LOUDNESS
                and (impact or not (
                    (secondary(result[0], last_heard() - 1, result[2], _SECONDARY_MARGIN)
                     or secondary(result[0], i, first=last_heard())) if beyond()
                    else secondary(result[0], i, result[2] if bounded else None))))

    def peel(predicted, tolerance, onset, before=None):
        # `onset` is that of a ring or an echo of an earlier impact: the impact, if there, is a
        # sound of its own starting after it, possibly after further secondaries.
        for _ in range(delays.size + 1):
            result = probe(predicted, tolerance, onset)
            if result is None or result[0] <= onset:
                return None
            if not secondary(result[0], i):
                return result if accept(result, predicted, tolerance, before) else None
            onset = result[0]
        return None

    def on_secondary(predicted, tolerance, onset, before, expected=False, impulse=False,
                     again=False):
        # An impact starting on a ring's burst (the impact's own modes, excited again) or an
        # echo barely raises the power, but the predictor of the sound continues that
        # sound's modes and the impact is an impulse in its error: looked for there, past
        # the secondary's own onset (a probed onset within 0.3 ms of it is that onset).
        lo = max(predicted - tolerance, onset + _PROBE_SECONDARY_SECONDS)
        hi = predicted + tolerance
        if hi <= lo:
            return None
        result = probe(0.5 * (lo + hi), 0.5 * (hi - lo), predicted_sound=True,
                       expected=expected, impulse=impulse)
        later = max(lo, onset + 2 * _PROBE_SECONDARY_SECONDS)
        if (again and (result is None or result[0] < lo) and later < hi
                and not beyond()):
            # The probe's picker looks back up to two AIC margins (0.36 ms at 22.05 kHz)
            # before its window, onto the secondary's own start where the window opens
            # 0.3 ms into it. Between impacts (the ball bounced there) the error is searched
            # once more from 0.6 ms past that start, for a sound of its own over the power
            # since 0.3 ms past it.
            result = probe(0.5 * (later + hi), 0.5 * (hi - later),
                           onset + _PROBE_SECONDARY_SECONDS, predicted_sound=True,
                           expected=expected, impulse=impulse)
        if result is None or result[0] < lo:
            return None
        return result if accept(result, predicted, tolerance, before) else None

    for _ in range(20 * len(anchors) + 10):  # a bound on the probes, whatever the trend does
        predicted, interval = _predict_next(anchors[max(0, i - 3):i + 1], step)
        if interval < _MERGE_SECONDS and i + 1 < len(anchors):
            # Anchors jammed closer together inside the train (a rattle among the impacts, an
            # impact timed twice, the predicted times stepped down from them) predict an
            # interval shorter than the merge window, which is no bounce: the walk goes on
            # from the next anchor. Only past the last impact does the train end there.
            i += 1
            continue
        if interval < _MERGE_SECONDS or predicted > (end if stop is None else stop):
            break
        tolerance = 3.0 * interval * scatter + _EXTENSION_SLACK
        if i + 1 < len(anchors) and anchors[i + 1] - anchors[i] < 1.5 * interval:
            # The next impact is there; if it sits off the trend at a secondary's delay after
            # an earlier impact, its onset is that of the ring or echo: time it again.
            following = anchors[i + 1]
            before = anchors[i + 2] if i + 2 < len(anchors) else np.inf
            too_close = before - following < _RATIO_BOUNDS[0] * (following - anchors[i])
            if origin[i + 1] >= 0 and i + 2 < len(anchors) and origin[i + 2] >= 0 and (
                    (abs(following - predicted) > tolerance
                     and abs(before - predicted) <= tolerance
                     and (secondary(following, i) or too_close))
                    or (too_close and abs(before - predicted) <= 1.5 * interval
                        and secondary(following, i, loudness[i + 1], _SECONDARY_MARGIN)
                        and not secondary(before, i + 1))):
                # A sound off the trend with the next impact on time right after it, at a
                # secondary's delay after an earlier impact (that ring's burst or echo) or too
                # close before that impact for both to be bounces (their interval ratio under
                # the bounds of successive bounces): a sound besides the impacts. So is, on
                # the trend or not, a sound too close before the next one for both to be
                # bounces that is such a secondary, no louder than twice it usually is, where
                # the next one is no secondary of any sound before it (an echo landing just
                # before an impact: the trend, bent by such sounds, may put the impact at the
                # echo). It is left out, and the walk goes on.
                retimed[origin[i + 1]] = None
                del anchors[i + 1], loudness[i + 1], origin[i + 1]
                continue
            if (origin[i + 1] >= 0 and abs(following - predicted) > tolerance
                    and following < predicted < before and secondary(following, i)):
                result = peel(predicted, tolerance, following, before)
                if result is None:
                    # A short secondary (a ring's burst) may have died down before the
                    # impact: its onset then jumps over the quietest stretch before it, as
                    # any probed onset, if well after the secondary's start.
                    result = probe(predicted, tolerance)
                    if (result is None or result[0] <= following + _MERGE_SECONDS
                            or not accept(result, predicted, tolerance, before)):
                        result = None
                if result is None:
                    # Or it is an impulse in the error of a predictor of that sound.
                    result = on_secondary(predicted, tolerance, following, before)
                # No onset of its own rises out of the ring or echo: the data do not time
                # this impact. It is left out (None), a gap in the train for the fit to
                # flag, rather than given the time the trend predicts, which would be
                # circular evidence for the fit that follows; the prediction stays as an
                # anchor for the next ones. A sound that sets off the secondaries of an
                # impact is one, though (an impact one delay after the one before), and
                # stays as timed.
                if result is not None or not own((following, None, loudness[i + 1])):
                    retimed[origin[i + 1]] = result
                    anchors[i + 1] = predicted if result is None else result[0]
                    heard[i + 1] = result is not None
            elif (origin[i + 1] >= 0 and following < predicted < before
                    and secondary(following, i)):
                # On the trend, but its onset is that of a ring or an echo of an earlier
                # impact beginning within the tolerance before it: timed again where an onset
                # of its own rises out of that sound, or shows in the error of a predictor of
                # it; kept as timed where none does.
                result = peel(predicted, tolerance, following, before)
                if result is None:
                    result = on_secondary(predicted, tolerance, following, before)
                if result is not None:
                    retimed[origin[i + 1]] = result
                    anchors[i + 1] = result[0]
            elif (origin[i + 1] >= 0 and following < predicted < before
                    and rising_secondary(following, i) is not None):
                # Its onset is on the rise of a ring's burst or an echo of an earlier impact
                # that began shortly before it: timed again where an onset of its own, closer
                # to the trend's time, rises out of that sound; kept as timed where none does.
                result = peel(predicted, tolerance, rising_secondary(following, i), before)
                if (result is not None and result[0] > following + _PROBE_SECONDARY_SECONDS
                        and abs(result[0] - predicted) < abs(following - predicted)):
                    retimed[origin[i + 1]] = result
                    anchors[i + 1] = result[0]
            elif (origin[i + 1] >= 0
                    and _PROBE_SECONDARY_SECONDS < following - predicted <= tolerance
                    and (start := rising_secondary(following, i)) is not None):
                # Late on the trend, less than 2 ms after a ring, burst or echo of an earlier
                # impact began: the fit of its onset may have been pulled late by that sound.
                # Its impulse in the error of a predictor of that sound, closer to the trend's
                # time, is taken instead (a weak trigger's jump: a sound is there).
                result = on_secondary(predicted, tolerance, start, before, expected=True,
                                      impulse=True)
                if (result is not None and result[0] < following - _PROBE_SECONDARY_SECONDS
                        and abs(result[0] - predicted) < abs(following - predicted)):
                    retimed[origin[i + 1]] = result
                    anchors[i + 1] = result[0]
            elif (origin[i + 1] >= 0 and following - predicted > tolerance
                    and (secondary(following, i) or np.any(
                        (delays >= _CAUSE_DELAY_SECONDS[0]) & (delays > 2.0 * tolerance)
                        & (np.abs(following - predicted - delays) <= tolerance)))):
                # It comes late, at a secondary's delay after an earlier impact or after the
                # predicted one (from 3 ms on: closer sounds are the impact's own first
                # arrival; and more than twice the tolerance, or the impact itself, anywhere
                # in the tolerance, fits the prediction as well as a secondary of it: on the
                # long first intervals the trend places an impact only to several ms):
                # a ring's burst or an echo standing in for an impact that was
                # passed over (it barely rose over the sound before it). The impact is looked
                # for where the trend puts it; not found, the secondary is left out (a gap).
                result = probe(predicted, tolerance)
                if not accept(result, predicted, tolerance, following):
                    result = None
                if result is not None or not own((following, None, loudness[i + 1])):
                    retimed[origin[i + 1]] = result
                    anchors[i + 1] = predicted if result is None else result[0]
                    heard[i + 1] = result is not None
            if (not heard[i + 1] and i + 2 < len(anchors) and heard[i + 2]
                    and anchors[i + 2] - anchors[i + 1] < _MERGE_SECONDS):
                # The predicted time standing in for the impact left out lies within the
                # merge window of the next impact timed: that impact is the one predicted
                # (two impacts this close cannot be told apart), and is judged as such.
                del anchors[i + 1], loudness[i + 1], origin[i + 1], heard[i + 1]
                continue
            i += 1
            continue
        result = probe(predicted, tolerance)
        if (result is not None and result[0] < predicted - _PROBE_SECONDARY_SECONDS
                and not beyond() and (start := rising_secondary(result[0], i)) is not None):
            # Between impacts, an onset early, less than 2 ms after a ring, burst or echo of
            # an earlier impact began, may be a swell of that sound: the impact's own onset
            # rising out of it, or else its impulse in the error of a predictor of it (in
            # its first samples, a weak trigger's jump: the ball bounced there), closer to
            # the predicted time, is taken instead. Not past the last impact: there the
            # later onset may be that of a ring of the last impact, taken for one more.
            def closer(found):
                return (found is not None
                        and abs(found[0] - predicted) < abs(result[0] - predicted))

            own_onset = peel(predicted, tolerance, start)
            if not closer(own_onset):
                own_onset = on_secondary(predicted, tolerance, start, None, expected=True,
                                         impulse=True)
            if closer(own_onset):
                result = own_onset
        elif (result is not None and beyond()
                and (start := rising_secondary(result[0], i, result[2])) is not None
                and not own(result)):
            # Past the last impact, an onset less than 2 ms after a ring, burst or echo of an
            # earlier impact began, which may be as loud as it, is a swell of that sound (the
            # probe's window opened on its rise), unless it sets off the secondaries of an
            # impact itself. The impact, if there, is an onset of its own rising out of that
            # sound, or an impulse in the error of a predictor of it: of the two, the one
            # closer to the predicted time.
            found = [onset for onset in (peel(predicted, tolerance, start),
                                         on_secondary(predicted, tolerance, start, None))
                     if onset is not None]
            result = min(found, key=lambda onset: abs(onset[0] - predicted), default=None)
        bounded = i + 1 < len(anchors) and origin[i + 1] >= 0
        impact = False
        if result is not None and secondary(result[0], i) and not (
                bounded and accept(result, predicted, tolerance, bounded=True)):
            impact = accept(result, predicted, tolerance, impact=True) and own(result)
            if not impact:
                # Past the last impact, a sound with no onset of its own rising out of the
                # secondary it starts on is judged itself, by its loudness (`accept`).
                first, result = result, peel(predicted, tolerance, result[0])
                if result is None and beyond():
                    result = first
        if not accept(result, predicted, tolerance, bounded=bounded, impact=impact):
            # An impact starting on the loud burst or ring of the one before barely raises the
            # power; in the error of a predictor of that sound it is an impulse (but so is
            # the start of that burst or ring: at a secondary's delay, it is one, and the
            # impact is looked for past it, unless it is louder than that secondary can be:
            # an impact that falls on the delay of a faint ring of an earlier one). Between
            # two impacts the ball bounced: a weak trigger's jump suffices there.
            result = probe(predicted, tolerance, predicted_sound=True, expected=bounded)
            bounded = impact = False
            if result is not None and secondary(result[0], i, result[2], _SECONDARY_MARGIN):
                result = on_secondary(predicted, tolerance, result[0], None, again=True)
            if result is None and beyond():
                # Past the last impact a weak trigger's jump will do where the sound, at no
                # secondary's delay, sets off the secondaries of an impact itself (the last
                # bounces barely rise over the decaying sound of the ones before).
                weak = probe(predicted, tolerance, predicted_sound=True, expected=True)
                if (weak is not None and not secondary(weak[0], i)
                        and accept(weak, predicted, tolerance) and own(weak)):
                    result = weak
        if accept(result, predicted, tolerance, bounded=bounded, impact=impact):
            added.append(result)
            anchors.insert(i + 1, result[0])
            heard.insert(i + 1, True)
            loudness.insert(i + 1, result[2])
            missing = 0
        else:
            if i + 1 >= len(anchors):
                missing += 1
                if missing > 2:
                    break
            # Not found: the predicted time stands in for it as an anchor.
            anchors.insert(i + 1, predicted)
            heard.insert(i + 1, False)
            loudness.insert(i + 1, loudness[i])
        origin.insert(i + 1, -1)
        i += 1
    # The train's last sound, one recurring secondary delay after the impact before it, is
    # that impact's ring burst or echo: no impact followed it to tell it from one. Unless it
    # sets off the secondaries of an impact itself: a burst or echo sets off none, a last
    # bounce that happens to come one delay after the one before does.
    last = len(anchors) - 1
    while last > 0 and origin[last] < 0:
        last -= 1
    if (last >= 4 and origin[last] == len(times) - 1 and origin[last - 1] >= 0
            and origin[last] not in retimed and delays.size > 0
            and np.abs(anchors[last] - anchors[last - 1] - delays).min()
            < _PROBE_SECONDARY_SECONDS
            and not any(moment > anchors[last] for moment, *_ in added)
            and not _sets_off_secondaries(
                probe, anchors[last], loudness[last], delays, usual, end,
                [(anchors[k], loudness[k]) for k in range(last - 3, last - 1) if heard[k]],
                [anchors[k] for k in range(len(anchors)) if heard[k]])):
        retimed[origin[last]] = None
    return added, retimed

