"""Compiled loops of the audio impact detector: the high-pass, the power envelope and its
trigger, the measures of each transient, the AIC onset picker, the onset fit's regression and
the dynamic programme of the bounce chain.

Each kernel does, sample by sample or step by step, what a vectorized numpy form in
:mod:`.envelope` or :mod:`.chain` does over whole arrays (those forms stay, as the reference
the tests compare these kernels with), with the same operations in the same order, so that the
results are the same to the last bit:

* :func:`highpass` is the direct-form II transposed recursion of ``scipy.signal.sosfilt``
  (its Cython loop, section by section), written channel by channel into a (channels, frames)
  array as scipy does, whose transpose is returned: later reductions over it (the noise
  estimate's einsum) see the same memory layout and sum in the same order.
  Being a recursion, it is bound by the latency of its arithmetic: the filter state stays in
  registers and two channels are stepped together, so that their chains overlap.
* :func:`envelope_triggers` does the whitening, the noise-normalised power, its running sum
  and the STA/LTA trigger of :func:`dashpot.ingest.envelope._process` chunk by chunk, and
  keeps the running sum only every 64 samples (:class:`Envelope` forms the power and STA
  where they are asked for, from the nearest of these, by the same additions).
* :func:`transient_measures` gathers each transient's amplitude, clipping flag and fit windows
  (maxima and counts: exact in any order); the mean level before the onset stays numpy's.
* :func:`edge_fits` is the one exception to the last bit: the onset fit's Bayesian linear
  regression of the rising edge, for each window and candidate onset (the normal equations of
  six polynomial terms, their Cholesky factor and the whitened projection), where the numpy
  form calls LAPACK on stacks of 6 × 6 matrices and BLAS for their products, whose order of
  summation no loop reproduces. The onsets and their 1σ agree with the reference to about
  1e-9 sample; the impacts chosen are the same.
* The AIC picker and the chain's Cauchy cost need logarithms. numpy's ``log`` and ``log1p``
  (SIMD, on machines with AVX-512) and the C library's, which compiled code calls, differ in
  the last bit for a fraction of arguments, and a last-bit difference could move a pick or a
  chain on a tie. So the kernels only prepare the arguments of the logarithms, numpy takes
  them over whole arrays as the reference does, and the kernels go on from there.

Why compiled: these are loops over the samples (tens of thousands per channel and second of
a recording) and over the states of the chain (about n³/6 steps for n transients), where
numpy spent most of its time on temporaries (the STA/LTA trigger, a sosfilt that first copies
the block to channel-major order) and on per-column Python overhead (the chain). Large
outputs are allocated by numpy, which asks the kernel for huge pages: the page faults of a
fresh array of a few MB cost about as much as filtering it. This module
imports numba; it is imported on the first detection, so that importing dashpot does not load
it. The compiled code is cached on disk (``cache=True``): compiling takes a few seconds once;
loading from the cache takes a fraction of a second in each new process.

References
----------
.. [1] R. V. Allen, "Automatic earthquake recognition and timing from single traces", Bull.
   Seismol. Soc. Am. 68(5), 1521-1532 (1978) (STA/LTA trigger).
.. [2] R. Sleeman and T. van Eck, "Robust automatic P-phase picking: an on-line implementation
   in the analysis of broadband seismogram recordings", Phys. Earth Planet. Inter. 113,
   265-275 (1999) (the AIC picker of N. Maeda, Zisin 38, 365-379, 1985).
.. [3] A. V. Oppenheim and R. W. Schafer, "Discrete-Time Signal Processing", 3rd ed.,
   Prentice Hall (2010), section 6.5 (transposed direct form II of a second-order section).
.. [4] R. Bellman, "Dynamic Programming", Princeton University Press (1957) (the chain's
   recursion over states).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["highpass", "Envelope", "envelope_triggers", "transient_measures", "whitened_rows",
           "onset_picks", "edge_fits", "chain_scores", "window_maxima", "distinct_counts"]

# Float division by zero gives inf/nan as in numpy instead of raising; no fastmath, so that
# every operation is rounded as numpy rounds it (no fused multiply-add, no reassociation).
_jit = numba.njit(cache=True, error_model="numpy")


# --------------------------------------------------------------------------------------------
# Envelope and trigger


@_jit
def _section(coefficients, block, scale, state, out):
    """One second-order section over the columns of `block` (frames, channels) times `scale`
    into `out` (channels, frames); `state` (channels, 2) is updated in place."""
    frames, channels = block.shape
    b0, b1, b2 = coefficients[0], coefficients[1], coefficients[2]
    a1, a2 = coefficients[4], coefficients[5]
    # The state lives in local variables (registers), not in `state`: a store and reload per
    # sample would lengthen the recursion's latency-bound chain. Two channels are stepped
    # together, so that the processor overlaps their chains.
    for first in range(0, channels - 1, 2):
        second = first + 1
        s0_first, s1_first = state[first, 0], state[first, 1]
        s0_second, s1_second = state[second, 0], state[second, 1]
        for n in range(frames):
            x_first, x_second = block[n, first] * scale, block[n, second] * scale
            y_first = b0 * x_first + s0_first
            y_second = b0 * x_second + s0_second
            s0_first = b1 * x_first - a1 * y_first + s1_first
            s0_second = b1 * x_second - a1 * y_second + s1_second
            s1_first = b2 * x_first - a2 * y_first
            s1_second = b2 * x_second - a2 * y_second
            out[first, n] = y_first
            out[second, n] = y_second
        state[first, 0], state[first, 1] = s0_first, s1_first
        state[second, 0], state[second, 1] = s0_second, s1_second
    if channels % 2:
        last = channels - 1
        s0, s1 = state[last, 0], state[last, 1]
        for n in range(frames):
            x = block[n, last] * scale
            y = b0 * x + s0
            s0 = b1 * x - a1 * y + s1
            s1 = b2 * x - a2 * y
            out[last, n] = y
        state[last, 0], state[last, 1] = s0, s1


def highpass(sos, block, zi, scale=1.0):
    """``scipy.signal.sosfilt(sos, block * scale, axis=0, zi=zi)``, to the last bit.

    Parameters
    ----------
    sos : ndarray, shape (sections, 6)
        Second-order sections.
    block : ndarray, shape (frames, channels)
        Samples: float (full scale), or integers, converted sample by sample (a 16-bit
        file's samples read as int16 take a quarter of the memory of float64).
    zi : ndarray, shape (sections, 2, channels)
        Filter state before the block (as ``sosfilt`` takes it with ``axis=0``).
    scale : float, default 1
        Full scale per unit of `block` (2⁻¹⁵ for int16: exact, as libsndfile's conversion).

    Returns
    -------
    filtered : ndarray, shape (frames, channels)
        The filtered block, a transposed view of a (channels, frames) array as sosfilt
        returns it.
    zf : ndarray, shape (sections, 2, channels)
        Filter state after the block.
    """
    state = np.ascontiguousarray(np.moveaxis(np.asarray(zi, dtype=float), (0, 1), (1, 2)))
    block = np.ascontiguousarray(block)
    # Outputs are allocated by numpy, which asks the kernel for huge pages for large arrays:
    # a fresh array of a few MB otherwise costs more in page faults than filtering it.
    sos = np.ascontiguousarray(sos, dtype=float)
    out = np.empty((block.shape[1], block.shape[0]))
    # Section after section over the whole block: each section's output depends only on its
    # input, so this is sosfilt's sample-by-sample cascade to the last bit.
    for section in range(sos.shape[0]):
        _section(sos[section], block, float(scale), state[:, section], out)
        block, scale = out.T, 1.0
    return out.T, np.moveaxis(state, (1, 2), (0, 1))


# The running sum S of the power (S[0] = 0, S[m] = power[0] + … + power[m − 1]) is kept at
# every _CHECKPOINT-th sample only; S anywhere else is summed on from the checkpoint before it,
# the same additions in the same order as the whole pass.
_CHECKPOINT = 64
_CHUNK = 4096  # samples whose power is formed together (vectorized over a short buffer)


@_jit
def _power_at(filtered, rho, weights, n):
    """Noise-normalised power of the whitened channels at sample n, summed over channels
    in order from 0 as numpy adds the channels' columns."""
    value = 0.0
    if n == 0:
        return value
    for c in range(filtered.shape[1]):
        whitened = filtered[n, c] - rho[c] * filtered[n - 1, c]
        whitened = whitened * whitened
        whitened = whitened * weights[c]
        value += whitened
    return value


@_jit
def _envelope_triggers(filtered, rho, weights, sta_length, background, lo, hi, min_power,
                       weak, checkpoints, triggers, jump):
    frames, channels = filtered.shape
    # S is kept in a ring of its last values (a power of two, at least
    # `sta_length + background + 1`): once S[m] is known, the STA of sample i = m − sta_length
    # and its trigger test (which needs S[i − background]) follow.
    ring_size = 1
    while ring_size < sta_length + background + 1:
        ring_size *= 2
    mask = ring_size - 1
    ring = np.zeros(ring_size)
    power = np.zeros(_CHUNK)
    count = 0
    total = 0.0
    checkpoints[0] = 0.0
    for start in range(0, frames, _CHUNK):
        stop = min(start + _CHUNK, frames)
        # The power of the chunk, channel by channel (contiguous, vectorized), added in
        # channel order onto zero as numpy adds the columns.
        for q in range(stop - start):
            power[q] = 0.0
        first = max(start, 1)
        for c in range(channels):
            # The channel's constants in locals and its samples as slices: with the stores into
            # `power` possibly aliasing rho[c] and weights[c], the loop was not vectorized.
            factor, weight = rho[c], weights[c]
            current, previous = filtered.T[c, first:stop], filtered.T[c, first - 1:stop - 1]
            for q in range(current.size):
                whitened = current[q] - factor * previous[q]
                whitened = whitened * whitened
                whitened = whitened * weight
                power[first - start + q] += whitened
        for n in range(start, stop):
            m = n + 1
            total += power[n - start]
            ring[m & mask] = total
            if m % _CHECKPOINT == 0:
                checkpoints[m // _CHECKPOINT] = total
            i = m - sta_length
            if i < lo or i >= hi:
                continue
            value = (total - ring[i & mask]) / sta_length
            if value < min_power:
                continue
            level = ring[i & mask] - ring[(i - background) & mask]
            if level < background:  # np.maximum with a number: NaN stays NaN
                level = float(background)
            if value >= weak * level:
                triggers[count] = i
                jump[count] = value * background / level
                count += 1
    return count


@_jit
def _running_sum(filtered, rho, weights, checkpoints, m):
    total = checkpoints[m // _CHECKPOINT]
    for q in range(m // _CHECKPOINT * _CHECKPOINT, m):
        total += _power_at(filtered, rho, weights, q)
    return total


@_jit
def _sta_at(filtered, rho, weights, checkpoints, sta_length, indices):
    frames = filtered.shape[0]
    out = np.zeros(indices.size)
    for k in range(indices.size):
        i = indices[k]
        if i + sta_length <= frames:  # 0 past the end, as the whole array holds it
            out[k] = (_running_sum(filtered, rho, weights, checkpoints, i + sta_length)
                      - _running_sum(filtered, rho, weights, checkpoints, i)) / sta_length
    return out


@_jit
def _envelope_rows(filtered, rho, weights, starts, length):
    rows = np.empty((starts.size, length))
    for k in range(starts.size):
        for i in range(length):
            rows[k, i] = _power_at(filtered, rho, weights, starts[k] + i)
    return rows


class Envelope:
    """The power envelope of a block, kept as its running sum's checkpoints: its rows and
    STA are formed where asked, to the last bit as the whole arrays would hold them."""

    def __init__(self, filtered, rho, weights, sta_length, checkpoints):
        self.filtered, self.rho, self.weights = filtered, rho, weights
        self.sta_length, self.checkpoints = sta_length, checkpoints

    def power_rows(self, starts, length):
        """Rows power[s : s + length] for each s in `starts`, as a (K, length) array."""
        return _envelope_rows(self.filtered, self.rho, self.weights,
                              np.ascontiguousarray(starts, dtype=np.int64), int(length))

    def sta_at(self, indices):
        """STA (mean power of the `sta_length` samples from each index on; 0 past the end)."""
        return _sta_at(self.filtered, self.rho, self.weights, self.checkpoints,
                       self.sta_length, np.ascontiguousarray(indices, dtype=np.int64))


def envelope_triggers(filtered, rho, weights, sta_length, background, lo, hi, min_power, weak):
    """Power envelope, STA and triggers of a block, as :func:`.envelope._process` forms them.

    Parameters
    ----------
    filtered : ndarray, shape (frames, channels)
        High-passed samples (full scale).
    rho, weights : ndarray, shape (channels,)
        Lag-1 correlation of each channel's noise, and 1/(channels·noise²) (1/full scale²).
    sta_length, background : int
        Samples of the short window after a sample and of the level before it.
    lo, hi : int
        Samples at which triggers may lie: lo <= n < hi.
    min_power, weak : float
        Trigger thresholds: STA at least `min_power`, and at least `weak` × the summed
        power of the `background` samples before.

    Returns
    -------
    envelope : Envelope
        The mean noise-normalised power of the whitened channels (power[0] = 0) and its STA
        (mean power of the `sta_length` samples from each sample on), formed where asked.
    triggers : ndarray of int64
        Samples passing both thresholds, increasing.
    jump : ndarray
        STA over the mean power of the background before each trigger (floored at 1).

    Notes
    -----
    No array of the block's length is written: whole arrays of the power, its running sum and
    the STA (tens of MB for a long block) cost more in fresh memory than forming them.
    """
    frames = filtered.shape[0]
    rho = np.ascontiguousarray(rho, dtype=float)
    weights = np.ascontiguousarray(weights, dtype=float)
    checkpoints = np.zeros(frames // _CHECKPOINT + 1)
    # Room for a trigger at every sample, of which only the pages used are touched.
    triggers, jump = np.empty(max(hi - lo, 0), dtype=np.int64), np.empty(max(hi - lo, 0))
    count = _envelope_triggers(filtered, rho, weights, int(sta_length), int(background),
                               int(lo), int(hi), float(min_power), float(weak), checkpoints,
                               triggers, jump)
    return (Envelope(filtered, rho, weights, int(sta_length), checkpoints),
            triggers[:count].copy(), jump[:count].copy())


@_jit
def _transient_measures(raw, scale, filtered, onsets, window_starts, level,
                        amplitude_length, window_length, clip_factor, clip_run, amplitudes, flat,
                        windows):
    count, channels = window_starts.shape
    for k in range(count):
        largest, extreme = 0.0, 0.0
        for i in range(amplitude_length):
            for c in range(channels):
                sample = raw[onsets[k] + i, c] * scale
                deviation = abs(sample - level[k, c])
                if deviation > largest:
                    largest = deviation
                if abs(sample) > extreme:
                    extreme = abs(sample)
        at_extreme = 0
        for i in range(amplitude_length):
            for c in range(channels):
                if abs(raw[onsets[k] + i, c] * scale) >= extreme * clip_factor:
                    at_extreme += 1
        amplitudes[k] = largest
        flat[k] = at_extreme >= clip_run and extreme > 0
        for c in range(channels):
            for i in range(window_length):
                windows[k, c, i] = filtered[window_starts[k, c] + i, c]


def transient_measures(raw, filtered, onsets, window_starts, level, amplitude_length,
                       window_length, clip_factor, clip_run, scale=1.0):
    """Amplitude, clipping flag and fit windows of each transient, as
    :func:`.envelope._keep_transients` forms them.

    Parameters
    ----------
    raw, filtered : ndarray, shape (frames, channels)
        Samples (float or integers, times `scale` in full scale) and high-passed samples.
    onsets : ndarray of int, shape (K,)
        Rough onsets (samples).
    window_starts : ndarray of int, shape (K, channels)
        First sample of each channel's fit window.
    level : ndarray, shape (K, channels)
        Mean raw level before each onset (full scale).
    amplitude_length, window_length : int
        Samples of the amplitude window (from the onset) and of the fit windows.
    clip_factor : float
        A sample at or above this fraction of the largest magnitude counts towards a flat top.
    clip_run : int
        Samples at the extreme that make a flat (clipped) top.
    scale : float, default 1
        Full scale per unit of `raw`.

    Returns
    -------
    amplitudes : ndarray, shape (K,)
        Largest |raw − level| within the amplitude window, over the channels.
    flat : ndarray of bool, shape (K,)
        Clipped (flat top) transients.
    windows : ndarray, shape (K, channels, window_length)
        Each channel's high-passed samples from its window start.
    """
    count, channels = window_starts.shape
    amplitudes = np.empty(count)
    flat = np.empty(count, dtype=np.bool_)
    windows = np.empty((count, channels, int(window_length)))
    # Maxima and counts are exact: no order of operations to follow.
    _transient_measures(raw, float(scale), filtered,
                        np.ascontiguousarray(onsets, dtype=np.int64),
                        np.ascontiguousarray(window_starts, dtype=np.int64),
                        np.ascontiguousarray(level, dtype=float), int(amplitude_length),
                        int(window_length), float(clip_factor), int(clip_run), amplitudes,
                        flat, windows)
    return amplitudes, flat, windows


# --------------------------------------------------------------------------------------------
# AIC onset picker


@_jit
def _whitened_rows(filtered, channel, rho, starts, length):
    """(y[n] − ρ·y[n−1])² over the rows, as numpy forms it from two gathered windows."""
    rows = np.empty((starts.size, length))
    for k in range(starts.size):
        for i in range(length):
            value = filtered[starts[k] + i, channel] - rho * filtered[starts[k] - 1 + i, channel]
            rows[k, i] = value * value
    return rows


@_jit
def _aic_arguments(power, first, margin):
    """Arguments of the two logarithms of the AIC criterion, per row and split."""
    count, length = power.shape
    splits = length - 2 * margin
    head_ratio = np.empty((count, splits))
    tail_ratio = np.empty((count, splits))
    cumulative = np.empty(length)
    for k in range(count):
        total = 0.0
        for i in range(length):
            total += power[k, i] + 1e-300  # digital silence has zero power
            cumulative[i] = total
        before_first = cumulative[max(first[k] - 1, 0)] if first[k] > 0 else 0.0
        for s in range(splits):
            split = margin + s
            head_count = max(split - first[k], 1)
            head = cumulative[split - 1] - before_first
            if head < 1e-300:  # np.maximum: NaN stays NaN
                head = 1e-300
            head_ratio[k, s] = head / head_count
            tail_ratio[k, s] = (cumulative[length - 1] - cumulative[split - 1]) / (length - split)
    return head_ratio, tail_ratio


@_jit
def _aic_argmin(log_head, log_tail, first, margin, length):
    """Split of least AIC per row (numpy's argmin: the first minimum, or the first NaN)."""
    count, splits = log_head.shape
    picks = np.empty(count, dtype=np.int64)
    for k in range(count):
        best, best_value = 0, np.inf
        for s in range(splits):
            split = margin + s
            head_count = split - first[k]
            if head_count >= margin:
                value = max(head_count, 1) * log_head[k, s] + (length - split) * log_tail[k, s]
            else:
                value = np.inf + (length - split) * log_tail[k, s]
            if np.isnan(value):
                best = s
                break
            if value < best_value or (s == 0):
                best, best_value = s, value
        picks[k] = margin + best
    return picks


def _aic_picks(power, first, margin, log_tail=None):
    """:func:`.envelope._aic_picks` (the AIC change point of each row), compiled: the picks,
    and the logarithms of the criterion's tail terms, which do not depend on `first`
    (`log_tail`, where given, holds them already: the rows' from an earlier pick)."""
    head_ratio, tail_ratio = _aic_arguments(power, first, margin)
    if log_tail is None:
        log_tail = np.log(tail_ratio)
    return (_aic_argmin(np.log(head_ratio), log_tail, first, margin, power.shape[1]),
            log_tail)


@_jit
def _separate_sounds(power, picks, second, later, min_gap, min_tail, ring_jump):
    """The second pick where it starts a sound of its own, else the first."""
    count, length = power.shape
    out = picks.copy()
    cumulative = np.empty(length)
    for k in range(count):
        if not later[k]:
            continue
        total = 0.0
        for i in range(length):
            total += power[k, i]
            cumulative[i] = total
        between = (cumulative[second[k] - 1] - cumulative[picks[k] - 1]) \
            / max(second[k] - picks[k], 1)
        after = (cumulative[length - 1] - cumulative[second[k] - 1]) / max(length - second[k], 1)
        if second[k] - picks[k] >= min_gap and length - second[k] >= min_tail \
                and after >= ring_jump * between:
            out[k] = second[k]
    return out


def onset_picks(power, first, min_gap, min_tail, margin, ring_jump):
    """:func:`.envelope._onset_picks` (AIC pick, moved past an earlier sound), compiled.

    Parameters
    ----------
    power : ndarray, shape (K, L)
        Rows of power.
    first : ndarray of int, shape (K,)
        First sample of each row the picker may use.
    min_gap, min_tail, margin : int
        Samples (see :func:`.envelope._onset_picks`); `margin` is the picker's shortest
        segment.
    ring_jump : float
        Power ratio that makes a sound of its own.

    Returns
    -------
    ndarray of int64, shape (K,)
        The rough onset of each row (index into the row).
    """
    power = np.ascontiguousarray(power, dtype=float)
    first = np.ascontiguousarray(first, dtype=np.int64)
    length = power.shape[1]
    picks, log_tail = _aic_picks(power, first, margin)
    later = picks + 2 * margin < length - margin
    if not later.any():
        return picks
    second = picks.copy()
    second[later] = _aic_picks(np.ascontiguousarray(power[later]), picks[later], margin,
                               log_tail[later])[0]
    return _separate_sounds(power, picks, second, later, int(min_gap), int(min_tail),
                            float(ring_jump))


def whitened_rows(filtered, channel, rho, starts, length):
    """Rows (y[n] − ρ·y[n−1])² of column `channel` of `filtered`, n from s to s + length − 1,
    for each s in `starts`."""
    return _whitened_rows(filtered, int(channel), float(rho),
                          np.ascontiguousarray(starts, dtype=np.int64), int(length))


# --------------------------------------------------------------------------------------------
# Onset fit


# Terms of the edge polynomial (:data:`.onset._POLY_ORDER`): a constant of the compiled code,
# so that its loops over them are unrolled (a third faster than with the order an argument).
_EDGE_ORDER = 6


@_jit
def _edge_fits(onsets, sample_index, prior_omega, rho, rows, innovation_var, peak, whitened,
               squared, diagonal):
    n_windows, n_grid = onsets.shape
    order = _EDGE_ORDER
    gram = np.empty((order, order))
    projection = np.empty(order)
    current = np.empty(order)
    previous = np.empty(order)
    white = np.empty(order)
    solved = np.empty(order)
    for k in range(n_windows):
        ridge = 1.0 / (peak[k] * peak[k])
        factor, omega, variance = rho[k], prior_omega[k], innovation_var[k]
        # Rows past the window's last fitted row add nothing.
        stop = sample_index.size
        while stop > 0 and not rows[k, stop - 1]:
            stop -= 1
        for g in range(n_grid):
            gram[:, :] = 0.0
            projection[:] = 0.0
            onset = onsets[k, g]
            # Rows up to the onset have a zero design (τ = 0) and after whitening add exact
            # zeros: the sums start at the first row after it.
            start = 0
            while start < stop and sample_index[start] <= onset:
                start += 1
            previous[:] = 0.0
            for w in range(start, stop):
                scaled = omega * max(sample_index[w] - onset, 0.0)
                current[0] = scaled
                for p in range(1, order):
                    current[p] = current[p - 1] * (scaled / (p + 1))
                if w >= 1 and rows[k, w]:
                    target = whitened[k, w]
                    for p in range(order):
                        white[p] = current[p] - factor * previous[p]
                    for p in range(order):
                        value = white[p]
                        projection[p] += value * target
                        for q in range(p + 1):
                            gram[p, q] += value * white[q]
                previous, current = current, previous
            for p in range(order):
                projection[p] /= variance
                for q in range(p + 1):
                    gram[p, q] /= variance
                gram[p, p] += ridge
            # Cholesky factor (lower triangle, in place) and forward substitution.
            total = 0.0
            for j in range(order):
                value = gram[j, j]
                for m in range(j):
                    value -= gram[j, m] * gram[j, m]
                root = np.sqrt(value)
                gram[j, j] = root
                diagonal[k, g, j] = root
                for i in range(j + 1, order):
                    value = gram[i, j]
                    for m in range(j):
                        value -= gram[i, m] * gram[j, m]
                    gram[i, j] = value / root
                value = projection[j]
                for m in range(j):
                    value -= gram[j, m] * solved[m]
                solved[j] = value / root
                total += solved[j] * solved[j]
            squared[k, g] = total


def edge_fits(onsets, sample_index, prior_omega, rho, rows, innovation_var, peak, whitened,
              order):
    """The regression of :func:`.onset._onset_posterior`'s ``log_evidence``, compiled.

    For window k and candidate onset t0 = ``onsets[k, g]`` (samples), the design holds
    (Ω_k·τ)^p / p!, p = 1 … `order`, τ = max(t − t0, 0) at the samples ``sample_index``,
    whitened by the AR(1) coefficient ρ_k on the rows `rows` (k, t); with the whitened data
    `whitened` (k, t), G = DᵀD/σ² + I/S² (σ² the innovation variance, S the peak) and
    b = Dᵀy/σ² [1]_. `order` must be :data:`_EDGE_ORDER` (6), the compiled code's constant
    (ValueError otherwise).

    Returns
    -------
    squared : ndarray, shape (K, G)
        ‖L⁻¹b‖², L the Cholesky factor of G.
    diagonal : ndarray, shape (K, G, order)
        The diagonal of L (its log, taken by numpy, gives ln det G).

    References
    ----------
    .. [1] C. M. Bishop, "Pattern Recognition and Machine Learning", Springer (2006),
       section 3.5 (the evidence of Bayesian linear regression).
    """
    if order != _EDGE_ORDER:
        raise ValueError(f"the compiled edge fit has {_EDGE_ORDER} terms; got {order}")
    squared = np.empty(onsets.shape)
    diagonal = np.empty(onsets.shape + (order,))
    _edge_fits(np.ascontiguousarray(onsets, dtype=float), sample_index, prior_omega, rho,
               np.ascontiguousarray(rows), innovation_var, peak,
               np.ascontiguousarray(whitened), squared, diagonal)
    return squared, diagonal


# --------------------------------------------------------------------------------------------
# Chain of impacts


@_jit
def _chain_deviations(log_gap, log_gap_t, centre_t, spread_t, jitter, last, log_lo, k_from,
                      k_to, out):
    """Half the squared, scaled deviation from the trend of the steps of columns
    k_from <= k < k_to, in the order :func:`_chain_steps` uses them; returns their count.
    Steps whose interval ratio is under the lower bound are left out: they score −∞ whatever
    they cost (most steps from early events are)."""
    count = 0
    for k in range(k_from, k_to):
        stop = last[k - 1]
        if stop <= k + 1:
            continue
        for l in range(k + 1, stop):
            following = log_gap[k, l]
            for j in range(k):
                if following - log_gap_t[k, j] < log_lo:
                    continue
                deviation = following - centre_t[k, j]
                deviation = deviation * deviation
                deviation = deviation / (spread_t[k, j] + jitter[k, l])
                out[count] = 0.5 * deviation
                count += 1
    return count


@_jit
def _chain_steps(log_gap, log_gap_t, jitter, weights, last, score, pointer, costs, has_trend,
                 log_lo, log_hi, log_growth, k_from, k_to):
    """Relax the states ending at k, k_from <= k < k_to (see :func:`.chain._best_chain`)."""
    n = log_gap.shape[0]
    # Column k of the scores and of the jitter, read once per l: contiguous copies (the
    # column is final, since the states relaxed at k are those of row k).
    column, jitter_column = np.empty(n), np.empty(n)
    count = 0
    for k in range(k_from, k_to):
        stop = last[k - 1]
        if stop <= k + 1:
            continue
        for j in range(k):
            column[j], jitter_column[j] = score[j, k], jitter[j, k]
        for l in range(k + 1, stop):
            best, best_value = 0, -np.inf
            found_nan = False
            following = log_gap[k, l]
            for j in range(k):
                log_ratio = following - log_gap_t[k, j]
                if log_ratio < log_lo:
                    total = -np.inf  # out of bounds whatever the cost and the growth allowed
                else:
                    total = column[j] + weights[l]
                    if has_trend:
                        total -= costs[count]  # in the order _chain_deviations wrote them
                        count += 1
                    growth = log_growth + 3.0 * math.sqrt(jitter_column[j] + jitter[k, l])
                    if growth > log_hi:  # np.minimum: NaN stays NaN
                        growth = log_hi
                    if log_ratio > growth:
                        total = -np.inf
                if not found_nan:
                    if np.isnan(total):
                        best, found_nan = j, True
                    elif total > best_value or j == 0:
                        best, best_value = j, total
            value = np.nan if found_nan else best_value
            if value > score[k, l]:
                score[k, l] = value
                pointer[k, l] = best
    return count


def chain_scores(log_gap, jitter, weights, last, score, pointer, trend_centre=None,
                 trend_spread=None, *, log_lo, log_hi, log_growth, budget=1 << 20):
    """The loop over k of :func:`.chain._best_chain`, compiled; `score` and `pointer` are
    updated in place.

    Parameters
    ----------
    log_gap : ndarray, shape (n, n)
        ln(t_l − t_k) above the diagonal (0 elsewhere).
    jitter : ndarray, shape (n, n)
        Variance of ln(interval) from the rough onsets' jitter.
    weights : ndarray, shape (n,)
        Score of each event.
    last : ndarray of int, shape (n − 2,)
        End (exclusive) of the events a step from (j, k) may reach, for k = 1 … n − 2.
    score, pointer : ndarray, shape (n, n)
        Initial scores of the states (j, k) and back-pointers, updated in place.
    trend_centre, trend_spread : ndarray, shape (n, n), optional
        Transposed centre and variance of the trend's expected next log gap (with a trend).
    log_lo, log_hi, log_growth : float
        ln of the ratio bounds and ln(1 + growth allowance), as numpy computes them.
    budget : int
        Steps whose costs are prepared at once (memory: 8 bytes each).
    """
    n = log_gap.shape[0]
    log_gap_t = np.ascontiguousarray(log_gap.T)
    has_trend = trend_centre is not None
    last = np.ascontiguousarray(last, dtype=np.int64)
    if not has_trend:
        _chain_steps(log_gap, log_gap_t, jitter, weights, last, score, pointer,
                     np.zeros(0), False, log_lo, log_hi, log_growth, 1, n - 1)
        return
    # The Cauchy cost of a step does not depend on the scores: the costs of a run of columns
    # are prepared together, their log1p taken by numpy (see the module's notes), then the
    # columns are relaxed.
    ks = np.arange(1, n - 1)
    sizes = ks * np.maximum(last - ks - 1, 0)
    buffer = np.empty(max(budget, int(sizes.max(initial=0))))
    k_from = 1
    while k_from < n - 1:
        total, k_to = 0, k_from
        while k_to < n - 1 and (k_to == k_from or total + sizes[k_to - 1] <= buffer.size):
            total += sizes[k_to - 1]
            k_to += 1
        count = _chain_deviations(log_gap, log_gap_t, trend_centre, trend_spread, jitter, last,
                                  log_lo, k_from, k_to, buffer)
        costs = np.log1p(buffer[:count])
        _chain_steps(log_gap, log_gap_t, jitter, weights, last, score, pointer, costs, True,
                     log_lo, log_hi, log_growth, k_from, k_to)
        k_from = k_to


@_jit
def _window_maxima(values, first):
    out = np.empty(values.size)
    for i in range(values.size):
        largest = 0.0
        for q in range(first[i], i):
            if np.isnan(values[q]):  # numpy's max: NaN wins
                largest = values[q]
                break
            if values[q] > largest:
                largest = values[q]
        out[i] = largest
    return out


def window_maxima(values, first):
    """max(values[first[i]:i], initial=0) for each i (the loudest transient before each, in
    :func:`.chain._chain_weights`)."""
    return _window_maxima(np.ascontiguousarray(values, dtype=float),
                          np.ascontiguousarray(first, dtype=np.int64))


@_jit
def _distinct_counts(labels, stops, size):
    seen = np.full(size, -1, dtype=np.int64)
    out = np.zeros(labels.size, dtype=np.int64)
    for i in range(labels.size):
        count = 0
        for q in range(i, stops[i]):
            if seen[labels[q]] != i:
                seen[labels[q]] = i
                count += 1
        out[i] = count
    return out


def distinct_counts(labels, stops):
    """Number of distinct values of labels[i:stops[i]] for each i (non-negative integer
    labels; the members sharing a delay in :func:`.chain._shift_to_causes`)."""
    labels = np.ascontiguousarray(labels, dtype=np.int64)
    size = int(labels.max()) + 1 if labels.size else 0
    return _distinct_counts(labels, np.ascontiguousarray(stops, dtype=np.int64), size)
