"""Transients in a recording: the noise-normalised power envelope of every channel, its
STA/LTA trigger and the AIC picker of the rough onset, streamed block by block (steps 1-2 of
:mod:`dashpot.ingest.audio`).

References
----------
.. [1] R. V. Allen, "Automatic earthquake recognition and timing from single traces", Bull.
   Seismol. Soc. Am. 68(5), 1521-1532 (1978).
.. [2] R. Sleeman and T. van Eck, "Robust automatic P-phase picking: an on-line implementation
   in the analysis of broadband seismogram recordings", Phys. Earth Planet. Inter. 113,
   265-275 (1999) (the AIC picker of N. Maeda, Zisin 38, 365-379, 1985).
.. [5] S. M. Kay, "Fundamentals of Statistical Signal Processing: Estimation Theory",
   Prentice Hall (1993), ch. 4 (the linear model: sinusoids of known frequencies fitted by
   least squares, and the variance noise leaves in their amplitudes).
.. [6] S. J. Orfanidis, "Introduction to Signal Processing", Prentice Hall (1996), section 6.4
   (the second-order notch filter, :func:`scipy.signal.iirnotch`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from scipy import signal


# Detection (step 1).
_HIGHPASS_ORDER = 2
# Mains hum (_mains_hum): a hum is steady, so it fills the quiet stretches between the
# impacts, where the detection measures its noise. Frames of 80 ms (four periods of 50 Hz) of
# the first 8 s, the quietest quarter of them, are each fitted with the harmonics of 50 Hz,
# and of 60 Hz, up to 1 kHz (a buzz's), the frequencies halfway between them, a line and a
# constant (rumble); a harmonic is hum where its median power over the frames is 20 times
# that halfway either side, and is notched out. The 100 Hz high-pass alone leaves a hum of
# -26 dBFS louder than the last impacts. Notches of Q 15: 3-7 Hz wide at 50-100 Hz (mains
# wanders by tenths of a hertz), far from the impacts' kHz. On 500 synthetic trains without
# hum (white or pink noise, rings, bursts, echoes) none was found.
_HUM_FUNDAMENTALS_HZ = (50.0, 60.0)
_HUM_TOP_HZ = 1000.0
_HUM_FRAME_SECONDS = 0.08
_HUM_ANALYSIS_SECONDS = 8.0
_HUM_QUIET_SHARE = 0.25
_HUM_LEAST_FRAMES = 8
_HUM_LINE_RATIO = 20.0
_HUM_NOTCH_Q = 15.0
_STA_SECONDS = 0.5e-3  # short window after a sample: the first half millisecond of a transient
_BACKGROUND_SECONDS = 2e-3  # the level just before it
_NOISE_FRAME_SECONDS = 5e-3  # frames whose RMS gives the noise floor
_NOISE_PERCENTILE = 10.0  # quiet frames: below the impacts, above digital silence
# Full scale: keeps a division by a noise finite. A channel's noise is floored higher, at the
# quantization noise of the file's format (_Stream.noise_floor), save float64's.
_NOISE_FLOOR = 1e-9
_MAX_NOISE_CORRELATION = 0.99
# Channel weights (_relative_snr, _shares): each channel's SNR from the loudest frames of a
# block (the top 1 %, its loudest impacts), where they rise 3 dB over the noise at least.
_LOUD_SHARE = 0.01
_MIN_LOUD_SNR = 1.0
_EQUAL_SNR_RATIO = 0.1  # channels within 10 dB of the best SNR weigh the same
_TIMING_SNR_RATIO = 0.5  # channels within 3 dB of the best SNR may time the onsets
# Windows around a transient: the noise before it and the start of it (the data of the onset
# fit), its peak amplitude and what marks it clipped.
_PRE_SECONDS = 1e-3  # noise before the onset, for its level and colour
_SPAN_SECONDS = 1e-3  # start of the transient, for its amplitude and frequency scale
_AMPLITUDE_SECONDS = 3e-3  # peak amplitude: largest deviation within this time of the onset
_CLIP_RUN = 3  # samples at the extreme value that mark a flat (clipped) top
_CLIP_TOLERANCE = 1e-4
# Rough onset and grouping (step 2).
_BACK_SEARCH_SECONDS = 3e-3
_AIC_MARGIN = 4  # samples: shortest segment the AIC picker may leave on either side
# Lowest sample rate the detector works at: the first 0.5 ms of a transient must span the
# picker's shortest segment (8 kHz; below about 5 kHz the windows collapse and picking fails).
MIN_SAMPLE_RATE = int(round(_AIC_MARGIN / _STA_SECONDS))
_MERGE_SECONDS = 1e-3  # triggers this close to a transient's onset belong to it
_WEAK_JUMP_FACTOR = 2.0  # weak candidates: power jump down to min_jump / 2 (3 dB lower)
_RING_GAP_SECONDS = 0.5e-3  # a sound this long before a transient's jump is a sound of its own
_RING_JUMP = 2.0  # ... if the power then jumps 3 dB over it
_SPLIT_JUMP = 8.0  # a trigger 9 dB louder than a transient < 1 ms before it is a new one

# The loops over the samples (high-pass, power envelope, trigger, transient measures) and
# the AIC picker run compiled (:mod:`.audio_kernels`: same operations in the same order, same
# results to the last bit), and so do the chain's search and counts and its polish in one
# batch (:mod:`.chain`); the numpy forms kept beside them are their reference, which the
# tests compare them with. False runs the reference throughout.
COMPILED = True


def _kernels():
    """The compiled kernels, imported on first use (numba loads only when audio is read)."""
    from . import audio_kernels

    return audio_kernels


# --------------------------------------------------------------------------------------------
# Detection on a block


def _windows(array, starts, length):
    """Rows array[s : s + length] for each s in `starts` (1-D array), as a (K, length) array."""
    return array[starts[:, None] + np.arange(length)[None, :]]


def _whitened_windows(filtered, channel, rho, starts, length):
    """Rows (y[n] − ρ·y[n−1])² of one channel y of `filtered`, n = s … s + length − 1 for
    each s in `starts`: the channel's whitened power over the stretches of the picker."""
    if COMPILED:
        return _kernels().whitened_rows(filtered, channel, rho, starts, length)
    return (_windows(filtered[:, channel], starts, length)
            - rho * _windows(filtered[:, channel], starts - 1, length)) ** 2


def _aic_picks(power, first):
    """AIC change point of each row of `power`: index of the first sample of the loud part.

    AIC(k) = n_k·ln(mean of the n_k samples before k) + (N − k)·ln(mean of the rest) [2]_, on
    the power (the square of a zero-mean signal, so its mean is the variance); samples before
    index ``first`` of a row (the previous transient) are left out.
    """
    length = power.shape[1]
    cumulative = np.cumsum(power + 1e-300, axis=1)  # digital silence has zero power
    split = np.arange(_AIC_MARGIN, length - _AIC_MARGIN)
    rows = np.arange(power.shape[0])
    before_first = np.where(first > 0, cumulative[rows, np.maximum(first - 1, 0)], 0.0)
    head_count = split[None, :] - first[:, None]
    head = cumulative[:, split - 1] - before_first[:, None]
    tail = cumulative[:, -1:] - cumulative[:, split - 1]
    usable = head_count >= _AIC_MARGIN
    criterion = np.where(usable, np.maximum(head_count, 1) * np.log(
        np.maximum(head, 1e-300) / np.maximum(head_count, 1)), np.inf) \
        + (length - split) * np.log(tail / (length - split))
    return split[np.argmin(criterion, axis=1)]


def _onset_picks(power, first, min_gap, min_tail):
    """Rough onset of each row of `power`: the AIC change point, moved past an earlier sound.

    The AIC picker finds where the power first leaves the level before it. When a ring or an
    echo of an earlier impact starts shortly before the transient, that is the start of the
    ring, not of the transient. A second pick on the rest of the row (from the first pick
    on) finds the next change point; if it lies at least `min_gap` samples later and the power
    jumps there by the trigger's weak factor or more over the stretch since the first pick,
    the stretch is a sound of its own (an impact's rising edge reaches its level well within
    `min_gap`) and the transient starts at the second pick. The second pick must leave at
    least `min_tail` samples after it: the mean of a few samples of a loud transient
    fluctuates by a factor of 2 by itself.
    """
    if COMPILED:
        return _kernels().onset_picks(power, first, min_gap, min_tail, _AIC_MARGIN, _RING_JUMP)
    picks = _aic_picks(power, first)
    length = power.shape[1]
    later = picks + 2 * _AIC_MARGIN < length - _AIC_MARGIN
    if not later.any():
        return picks
    second = np.where(later, _aic_picks(power, np.where(later, picks, first)), picks)
    cumulative = np.cumsum(power, axis=1)
    rows = np.arange(power.shape[0])
    between = (cumulative[rows, second - 1] - cumulative[rows, picks - 1]) \
        / np.maximum(second - picks, 1)
    after = (cumulative[:, -1] - cumulative[rows, second - 1]) / np.maximum(length - second, 1)
    separate = later & (second - picks >= min_gap) & (length - second >= min_tail) \
        & (after >= _RING_JUMP * between)
    return np.where(separate, second, picks)


@dataclass(frozen=True)
class _Settings:
    """Window lengths (samples) and thresholds of one detection run."""

    sample_rate: int
    sta: int
    background: int
    back_search: int
    pre: int
    span: int
    amplitude: int
    merge: int
    min_power: float
    min_jump: float

    @classmethod
    def make(cls, sample_rate, min_snr_db, min_jump_db):
        def samples(seconds):
            return max(4, int(round(seconds * sample_rate)))
        return cls(sample_rate=sample_rate, sta=samples(_STA_SECONDS),
                   background=samples(_BACKGROUND_SECONDS),
                   back_search=samples(_BACK_SEARCH_SECONDS), pre=samples(_PRE_SECONDS),
                   span=samples(_SPAN_SECONDS), amplitude=samples(_AMPLITUDE_SECONDS),
                   merge=samples(_MERGE_SECONDS),
                   min_power=10.0 ** (min_snr_db / 10.0), min_jump=10.0 ** (min_jump_db / 10.0))

    @property
    def history(self):
        """Samples a trigger needs before it (background, back-search, fit pre-window)."""
        return self.background + self.back_search + self.pre + _AIC_MARGIN

    @property
    def lookahead(self):
        """Samples a transient needs after its trigger (fit span, amplitude window)."""
        return self.sta + self.span + self.amplitude + 1

    @property
    def carry(self):
        return self.history + self.lookahead + self.background


@functools.lru_cache(maxsize=8)
def _harmonic_fit(length, sample_rate, fundamental):
    """(harmonic numbers, least-squares projector) of `length` samples onto the sines and
    cosines of the harmonics k·`fundamental` (Hz) up to :data:`_HUM_TOP_HZ` and of the
    frequencies halfway between them, (k - 1/2)·`fundamental` and one more above, beside a
    constant and a line; the projector (pseudo-inverse of the design, columns by samples)
    gives the coefficients: harmonics' sines, their cosines, then the halfway ones'."""
    order = np.arange(1, int(min(_HUM_TOP_HZ, 0.45 * sample_rate) // fundamental) + 1)
    halfway = np.arange(order.size + 1) + 0.5
    frequencies = fundamental * np.concatenate([order, halfway])
    phase = 2.0 * np.pi * np.arange(length)[:, None] * frequencies[None, :] / sample_rate
    design = np.column_stack([np.sin(phase[:, :order.size]), np.cos(phase[:, :order.size]),
                              np.sin(phase[:, order.size:]), np.cos(phase[:, order.size:]),
                              np.ones(length), np.linspace(-1.0, 1.0, length)])
    return order, np.linalg.pinv(design)


def _mains_hum(samples, sample_rate):
    """Frequencies (Hz) of the mains hum lines in `samples`.

    The first :data:`_HUM_ANALYSIS_SECONDS` of each channel are cut into frames of
    :data:`_HUM_FRAME_SECONDS`; the quietest :data:`_HUM_QUIET_SHARE` of them (between the
    impacts) are each fitted by least squares with sines and cosines at the harmonics of
    50 Hz (and, again, of 60 Hz) up to :data:`_HUM_TOP_HZ` and halfway between them, a line
    and a constant [5]_. A harmonic is hum where the median over those frames of its fitted
    power exceeds :data:`_HUM_LINE_RATIO` times that of the halfway frequencies either side
    (the background there, whatever its colour). The mains frequency with the more hum lines wins
    (none: no hum). They are named by the nominal frequency: mains wanders by tenths of a
    hertz, within the notches.

    Parameters
    ----------
    samples : ndarray, shape (frames, channels)
        The recording's first block, in any scale (the test compares powers).
    sample_rate : float
        Hz.

    Returns
    -------
    ndarray
        Frequencies (Hz) of the harmonics found, increasing; empty if none, or if `samples`
        holds fewer than 4 × :data:`_HUM_LEAST_FRAMES` frames.
    """
    length = int(round(_HUM_FRAME_SECONDS * sample_rate))
    count = min(samples.shape[0], int(_HUM_ANALYSIS_SECONDS * sample_rate)) // length
    quiet = int(count * _HUM_QUIET_SHARE)
    if quiet < _HUM_LEAST_FRAMES:
        return np.empty(0)
    channels = samples.shape[1]
    # Single precision to rank the frames by their energy; the chosen ones in double.
    frames = np.asarray(samples[:count * length], dtype=np.float32).reshape(
        count, length, channels).transpose(2, 0, 1).reshape(-1, length)
    frames -= frames.mean(axis=1, keepdims=True)
    order_by_energy = np.argsort(np.einsum("ij,ij->i", frames, frames))
    chosen = frames[order_by_energy[:quiet * channels]].astype(float)
    found = np.empty(0)
    for fundamental in _HUM_FUNDAMENTALS_HZ:
        order, projector = _harmonic_fit(length, sample_rate, fundamental)
        coefficients = chosen @ projector.T  # frames by columns
        size = order.size
        # A sinusoid of amplitude a carries a²/2 of power per sample.
        harmonic = 0.5 * np.median(coefficients[:, :size] ** 2
                                   + coefficients[:, size:2 * size] ** 2, axis=0)
        halfway = 0.5 * np.median(coefficients[:, 2 * size:3 * size + 1] ** 2
                                  + coefficients[:, 3 * size + 1:4 * size + 2] ** 2, axis=0)
        background = 0.5 * (halfway[:-1] + halfway[1:])
        is_hum = harmonic > _HUM_LINE_RATIO * np.maximum(background, np.finfo(float).tiny)
        if is_hum.sum() > found.size:
            found = fundamental * order[is_hum]
    return found


def _hum_notches(frequencies, sample_rate):
    """Second-order sections of a notch (quality :data:`_HUM_NOTCH_Q`) at each of
    `frequencies` (Hz) [6]_: shape (len(frequencies), 6)."""
    sections = [signal.tf2sos(*signal.iirnotch(frequency, _HUM_NOTCH_Q, fs=sample_rate))
                for frequency in frequencies]
    return np.concatenate(sections) if sections else np.empty((0, 6))


@dataclass
class _Stream:
    """State carried from one block to the next while streaming a file."""

    settings: _Settings
    channels: int
    sos: np.ndarray
    filter_state: np.ndarray | None = None
    noise: np.ndarray | None = None  # noise RMS of each whitened channel (full scale)
    rho: np.ndarray | None = None  # lag-1 correlation of each channel's noise
    # (first sample, noise, rho) of each block's estimate: the later steps look up the one
    # of the block a moment lies in (the noise may change over a long recording).
    noise_blocks: list = field(default_factory=list)
    relative_snr: np.ndarray | None = None  # each channel's SNR over the best's (_relative_snr)
    snr_blocks: list = field(default_factory=list)  # relative_snr of each of noise_blocks
    raw: np.ndarray | None = None  # carried samples (frames, channels)
    filtered: np.ndarray | None = None
    start: int = 0  # absolute index of the first carried sample
    done_until: int = 0  # absolute index below which triggers have been handled
    last_onset: int | None = None  # absolute rough onset of the latest transient kept
    candidates: list = field(default_factory=list)
    dc_offset: float = 0.0
    scale: float = 1.0  # full scale per unit of the raw samples (2⁻¹⁵ for int16)
    lossy_codec: str = ""  # the lossy codec the file was coded with (libsndfile's name), or ""
    # Least noise RMS a channel is judged against (full scale): the quantization noise of the
    # file's sample format (:func:`.audio_file._quantization_noise`). A dead input (digital
    # silence with rare one-step blips) measures less; against that, its blips would be
    # enormous transients.
    noise_floor: float = _NOISE_FLOOR
    # The recording's samples for the later steps that read stretches of it again
    # (:class:`.audio_file._Recording`).
    recording: object = None
    # (moment, tolerance, predicted_sound) of the last stretch probed and what it holds
    # (:func:`.chain._probed_stretch`), for a probe asked again there.
    probe_memo: tuple | None = None
    hum: np.ndarray = field(default_factory=lambda: np.empty(0))  # hum lines notched (Hz)
    steady_state: np.ndarray = field(init=False)  # high-pass state for a unit input at rest

    def __post_init__(self):
        self.steady_state = signal.sosfilt_zi(self.sos)

    def notch_mains_hum(self, start):
        """Add a notch at each mains hum line in `start` (the file's first block, frames by
        channels, as read) to the high-pass (:func:`_mains_hum`); before any filtering."""
        self.hum = _mains_hum(start, self.settings.sample_rate)  # ratios: scale-free
        if self.hum.size:
            self.sos = np.concatenate([self.sos, _hum_notches(self.hum,
                                                              self.settings.sample_rate)])
            self.steady_state = signal.sosfilt_zi(self.sos)

    def noise_at(self, seconds):
        """Noise RMS and lag-1 correlation of each channel (arrays of shape (..., channels))
        that the detection used at the moments `seconds` (s): the estimate of the block each
        lies in."""
        firsts = np.array([first for first, _, _ in self.noise_blocks])
        block = np.clip(np.searchsorted(firsts, np.asarray(seconds) * self.settings.sample_rate,
                                        side="right") - 1, 0, None)
        return (np.stack([noise for _, noise, _ in self.noise_blocks])[block],
                np.stack([rho for _, _, rho in self.noise_blocks])[block])

    def relative_snr_at(self, seconds):
        """Each channel's SNR over the best channel's (:func:`_relative_snr`) at the moments
        `seconds` (s): array of shape (..., channels), that of the block each lies in."""
        firsts = np.array([first for first, _, _ in self.noise_blocks])
        block = np.clip(np.searchsorted(firsts, np.asarray(seconds) * self.settings.sample_rate,
                                        side="right") - 1, 0, None)
        return np.stack(self.snr_blocks)[block]

    def share_at(self, seconds):
        """Each channel's share of the detection statistic (:func:`_shares`) at the moments
        `seconds` (s): array of shape (..., channels)."""
        return _shares(self.relative_snr_at(seconds))

    def timed_at(self, seconds):
        """Which channels may time the onsets at the moments `seconds` (s): boolean array of
        shape (..., channels), the channels heard (:meth:`heard_at`) whose SNR is within a
        factor 2 (3 dB) of the best channel's. A channel that carries the impacts' sound far
        weaker than another has the less precise onsets, whatever its waveform's peaks over
        the 1 ms before them say (a channel of white noise beside one of low-frequency noise
        has the steeper-looking edges)."""
        return self.heard_at(seconds) & (self.relative_snr_at(seconds) >= _TIMING_SNR_RATIO)

    def heard_at(self, seconds):
        """Which channels the detection used at the moments `seconds` (s): boolean array of
        shape (..., channels), :func:`_heard` of the noise of the block each lies in."""
        return _heard(self.noise_at(seconds)[0], self.noise_floor)

    def highpass_from_rest(self, raw):
        """`raw` (frames, channels; float, full scale) high-passed, each channel's filter
        started at rest on its first sample, so that a DC offset does not ring through the
        first milliseconds like an impact."""
        return _sosfilt(self.sos, raw, self.steady_state[:, :, None] * raw[0][None, None, :])[0]

    def highpass(self, block):
        """The next `block` (frames, channels) of the file high-passed, the filter going on
        from the block before (started at rest on the file's first sample)."""
        if self.filter_state is None:
            self.filter_state = self.steady_state[:, :, None] * (block[0] * self.scale)[
                None, None, :]
        filtered, self.filter_state = _sosfilt(self.sos, block, self.filter_state, self.scale)
        return filtered


def _heard(noise, noise_floor):
    """Channels that recorded noise: whose noise RMS is above the quantization noise.

    A channel whose quiet stretches hold less noise than its sample format can resolve
    records no analogue signal there: a dead or unconnected input, digitally silent save
    for rare one-step blips. Against the quantization noise its blips are √12 ≈ 3.5σ (a step
    over step/√12): no triggers, but as large as the rare peaks of a live channel's noise,
    and in the mean over the channels they still move the picks of the live channel's
    transients (a 16-bit stereo copy of the ping-pong recording with 300 blips on a dead
    channel kept 48 of its 52 impacts with the floor alone). Such a channel's power is left
    out of the detection, and its samples out of the timing, while another channel recorded
    noise; so is a channel gated to digital silence between impacts beside a live one, which
    hears them too. A recording in which no channel recorded noise (a noise gate on all of
    them) keeps them all, each judged against the quantization noise.

    Parameters
    ----------
    noise : ndarray, shape (..., channels)
        Noise RMS of each channel (full scale), floored at `noise_floor`.
    noise_floor : float
        Quantization noise RMS of the file's format (full scale).

    Returns
    -------
    ndarray of bool, shape (..., channels)
    """
    heard = noise > noise_floor
    return heard | ~heard.any(axis=-1, keepdims=True)


def _relative_snr(frame_snr, heard):
    """Each channel's signal-to-noise power ratio in the loudest sounds of a block, over the
    best channel's.

    Each channel's SNR is its mean excess power over its noise in the block's loudest frames:
    the top 1 % of the mean of the channels' powers, its loudest impacts. Where those do not
    rise 3 dB over the noise (a block of noise), or fewer than two channels are heard,
    nothing tells the channels apart and every ratio is 1.

    Parameters
    ----------
    frame_snr : ndarray, shape (frames, channels)
        Whitened power of each channel in each frame over its noise variance (1 for noise
        alone).
    heard : ndarray of bool, shape (channels,)
        The channels that recorded noise (:func:`_heard`); the others' ratios are 1 (their
        weights are 0 all the same).

    Returns
    -------
    ndarray, shape (channels,)
        Ratios in [0, 1], 1 for the best channel.
    """
    ratio = np.ones(frame_snr.shape[1])
    if heard.sum() < 2:
        return ratio
    loudness = frame_snr[:, heard].mean(axis=1)
    # The top 1 % (a partition: a percentile's sort costs more than the rest together).
    first = loudness.size - max(1, int(np.ceil(loudness.size * _LOUD_SHARE)))
    loud = loudness >= np.partition(loudness, first)[first]
    snr = (frame_snr[loud] - 1.0).mean(axis=0)
    best = snr[heard].max()
    if best >= _MIN_LOUD_SNR:
        ratio[heard] = np.clip(snr[heard] / best, 0.0, 1.0)
    return ratio


def _shares(relative_snr):
    """Share of each channel in the detection statistic, from its SNR relative to the best
    channel's (:func:`_relative_snr`): 1 within a factor 10 (10 dB) of the best, 0 below.

    For a signal of known shape in independent noises, the combination of the channels'
    noise-normalised powers that best tells it from the noise weighs each channel by its
    signal-to-noise power ratio (maximal-ratio combining [3]_). A channel that carries little
    of the impacts' sound (a second microphone far from them, or one not connected, picking
    up hum and hiss) should then add little of its noise to the statistic; with equal weights
    it halves the impacts' power over the noise of a stereo recording (a copy of the
    ping-pong recording with a second channel of noise alone lost up to 5 of its 52 impacts
    and gained up to 5 false ones). A channel 10 dB under the best would weigh a tenth at
    most, and below about 5 dB the statistic of the best channel alone beats the equal mean:
    such a channel is left out. Partial weights are not used: the SNR read from a block's
    loudest frames is too rough for them (a second channel of the ping-pong recording 2-3
    times weaker plus noise, 11-17 dB under the first, lost 16-20 of 520 impacts with
    weights in proportion to the SNR from 10 dB down, none left out). Channels within 10 dB
    weigh the same, as before, and the recordings analysed so far keep their impact tables.

    Parameters
    ----------
    relative_snr : ndarray, shape (..., channels)
        Each channel's SNR over the best channel's.

    Returns
    -------
    ndarray, shape (..., channels)
        Shares, 0 or 1.

    References
    ----------
    .. [3] D. G. Brennan, "Linear diversity combining techniques", Proc. IRE 47(6),
       1075-1102 (1959).
    """
    return np.where(relative_snr >= _EQUAL_SNR_RATIO, 1.0, 0.0)


def _channel_weights(noise, noise_floor, variance, share=None):
    """Weight of each channel's power in the detection statistic: its `share` over (the sum
    of the shares of the channels heard × `variance`) for the channels heard
    (:func:`_heard`), 0 for the others, so that the statistic is the share-weighted mean
    power of the channels heard over the `variance` of their noise (the plain mean where
    every share is 1).

    Parameters
    ----------
    noise : ndarray, shape (..., channels)
        Noise RMS of each channel (full scale), floored at `noise_floor` (full scale).
    noise_floor : float
        Quantization noise RMS of the file's format (full scale).
    variance : ndarray, shape (..., channels)
        Variance of the noise of the power that is weighted (full scale²).
    share : ndarray, shape (..., channels), optional
        Each channel's share (:func:`_shares`); 1 for all by default.

    Returns
    -------
    ndarray, shape (..., channels)
        Weights (1/full scale²).
    """
    heard = _heard(noise, noise_floor)
    share = np.where(heard, 1.0 if share is None else share, 0.0)
    return np.where(heard, share / (share.sum(axis=-1, keepdims=True) * variance), 0.0)


def _sosfilt(sos, block, initial, scale=1.0):
    """``scipy.signal.sosfilt(sos, block * scale, axis=0, zi=initial)``, compiled where
    COMPILED (to the last bit)."""
    if COMPILED:
        return _kernels().highpass(sos, block, initial, scale)
    return signal.sosfilt(sos, block * scale, axis=0, zi=initial)


def _envelope_triggers(filtered, rho, weights, settings, lo, hi, weak):
    """Power envelope, STA, triggers and their jumps of a block (numpy reference of
    :func:`.audio_kernels.envelope_triggers`)."""
    frames, channels = filtered.shape
    # The power is summed channel by channel, on contiguous copies of the columns (strided
    # arithmetic on (frames, channels) is slower).
    power = np.zeros(frames)
    for c in range(channels):
        column = np.ascontiguousarray(filtered[:, c])
        whitened = column[1:] - rho[c] * column[:-1]
        whitened *= whitened
        whitened *= weights[c]
        power[1:] += whitened

    # STA/LTA [1]_: mean power over the next `sta` samples against the `background` before.
    # Both are differences of one running sum, taken as slices (contiguous passes; loud
    # recordings pass the STA threshold on half their samples, where gathering by index
    # would cost more).
    cumulative = np.empty(frames + 1)
    cumulative[0] = 0.0
    np.cumsum(power, out=cumulative[1:])
    sta = np.zeros(frames)
    sta[: frames - settings.sta + 1] = (cumulative[settings.sta:]
                                        - cumulative[:-settings.sta]) / settings.sta
    level = cumulative[lo:hi] - cumulative[lo - settings.background:hi
                                          - settings.background]
    np.maximum(level, settings.background, out=level)  # floor of 1 (noise-normalised)
    passing = sta[lo:hi] >= settings.min_power
    passing &= sta[lo:hi] >= weak * level
    triggers = np.flatnonzero(passing) + lo
    jump = sta[triggers] * settings.background / level[triggers - lo]
    return power, sta, triggers, jump


class _EnvelopeArrays:
    """The power envelope and STA of a block as whole arrays (the reference path), with the
    interface of :class:`.audio_kernels.Envelope`."""

    def __init__(self, power, sta):
        self.power, self.sta = power, sta

    def power_rows(self, starts, length):
        return _windows(self.power, starts, length)

    def sta_at(self, indices):
        return self.sta[indices]


def _process(stream, block, final):
    """Find the transients in the carried samples + `block` and append them to the stream."""
    settings = stream.settings
    if stream.filter_state is None:
        # The DC offset, for the notes, from the first second (it is constant). A matrix
        # product: numpy's mean along the long axis of a (frames, channels) array is strided
        # and ten times slower.
        opening = block[:settings.sample_rate]
        stream.dc_offset = float(np.abs(np.ones(opening.shape[0]) @ opening).max()
                                 * stream.scale / opening.shape[0])
    filtered_block = stream.highpass(block)
    if stream.raw is None:
        raw, filtered = block, filtered_block
    else:
        raw = np.concatenate([stream.raw, block])
        filtered = np.concatenate([stream.filtered, filtered_block])
    frames = raw.shape[0]

    # Noise per channel, from short frames: the quiet ones (RMS at or below the 10th
    # percentile: the stretches between impacts) give its level and its lag-1 correlation.
    # A block too short to say keeps the previous estimate.
    frame = max(2, int(round(_NOISE_FRAME_SECONDS * settings.sample_rate)))
    n_frames = frames // frame
    if n_frames >= 20 or (stream.noise is None and n_frames >= 1):
        framed = filtered[: n_frames * frame].reshape(n_frames, frame, -1)
        energy = np.einsum("fsc,fsc->fc", framed, framed)
        lagged = np.einsum("fsc,fsc->fc", framed[:, 1:], framed[:, :-1])
        quiet = energy <= np.percentile(energy, _NOISE_PERCENTILE, axis=0)
        quiet_energy = np.where(quiet, energy, 0.0).sum(axis=0)
        rho = np.divide(np.where(quiet, lagged, 0.0).sum(axis=0), quiet_energy,
                        out=np.zeros(stream.channels), where=quiet_energy > 0)
        stream.rho = np.clip(rho, 0.0, _MAX_NOISE_CORRELATION)
        # Innovation RMS of the quiet frames: the noise of the whitened signal below.
        innovation = np.maximum(quiet_energy * (1 - stream.rho**2) / (quiet.sum(axis=0) * frame),
                                0.0)
        stream.noise = np.maximum(np.sqrt(innovation), stream.noise_floor)
        stream.relative_snr = np.ones(stream.channels)
        if stream.channels > 1:
            # Each frame's whitened power, Σ(y[n] − ρ·y[n−1])² ≈ (1 + ρ²)Σy² − 2ρΣy[n]y[n−1],
            # over the noise's: how far the loudest sounds rise over each channel's noise.
            whitened = energy * (1.0 + stream.rho**2) - 2.0 * stream.rho * lagged
            stream.relative_snr = _relative_snr(whitened / (frame * stream.noise**2),
                                                _heard(stream.noise, stream.noise_floor))
    elif stream.noise is None:
        stream.rho = np.zeros(stream.channels)
        stream.noise = np.maximum(np.sqrt((filtered**2).mean(axis=0)),
                                  stream.noise_floor)
        stream.relative_snr = np.ones(stream.channels)
    if not stream.noise_blocks or stream.noise_blocks[-1][1] is not stream.noise:
        # A new estimate (a block too short keeps the previous one, the same array) holds
        # from the first sample whose triggers this block judges.
        stream.noise_blocks.append((stream.done_until, stream.noise, stream.rho))
        stream.snr_blocks.append(stream.relative_snr)
    # Detection runs on the noise whitened by its own lag-1 prediction, y[n] − ρ·y[n−1]:
    # for white noise (ρ ≈ 0) that is the signal itself; for noise dominated by low
    # frequencies it removes the slow swells of power that would otherwise look like onsets
    # in a half-millisecond window.
    # The statistic is the mean noise-normalised power over the channels that recorded noise,
    # each weighed by its share of the impacts' sound.
    weights = _channel_weights(stream.noise, stream.noise_floor, stream.noise**2,
                               _shares(stream.relative_snr))
    limit = frames - settings.lookahead + 1  # triggers need this much recording after them
    lo, hi = settings.history, max(limit, settings.history)
    # Triggers down to a lower jump are kept as weak candidates: the selection looks among
    # them only where the bounce trend predicts an impact that no strong trigger marks
    # (an impact landing on the ringing or echo of an earlier one jumps less).
    weak = settings.min_jump / _WEAK_JUMP_FACTOR / settings.background
    if COMPILED:
        envelope, triggers, jump = _kernels().envelope_triggers(
            filtered, stream.rho, weights, settings.sta, settings.background, lo, hi,
            settings.min_power, weak)
    else:
        power, sta, triggers, jump = _envelope_triggers(filtered, stream.rho, weights,
                                                        settings, lo, hi, weak)
        envelope = _EnvelopeArrays(power, sta)
    # Runs of consecutive trigger samples; each run is one trigger, at its largest jump.
    breaks = np.flatnonzero(np.diff(triggers) > 1) + 1
    run_first = np.concatenate(([0], breaks)) if triggers.size else np.zeros(0, dtype=np.int64)
    run_last = np.concatenate((breaks, [triggers.size])) - 1 if triggers.size else run_first

    # Runs starting before `limit` are handled now if they have ended; later ones wait for the
    # next block, whose carried samples overlap this one.
    first_new = stream.done_until - stream.start
    starts, stops = triggers[run_first], triggers[run_last] + 1
    own = starts >= first_new
    if not final:
        unfinished = own & (stops >= limit)
        if unfinished.any():
            limit = int(starts[unfinished][0])
            own &= starts < limit
    if own.any():
        # First sample of the largest jump of each run (np.argmax's choice on a tie).
        run_of = np.repeat(np.arange(run_first.size), run_last - run_first + 1)
        largest = np.maximum.reduceat(jump, run_first)
        at_peak = np.flatnonzero(jump == largest[run_of])
        peaks = at_peak[np.r_[True, run_of[at_peak][1:] != run_of[at_peak][:-1]]][own]
        detections = triggers[peaks]
        strong = jump[peaks] >= settings.min_jump
        search_start = detections - settings.back_search
        length = settings.back_search + settings.sta
        # The back-search may not reach into the transient triggered just before (a ring or
        # an echo a few ms before an impact must not capture its onset).
        previous = np.concatenate((
            [-length if stream.last_onset is None else stream.last_onset - stream.start],
            detections[:-1]))
        first = np.clip(previous + settings.sta - search_start, 0,
                        length - 2 * _AIC_MARGIN - settings.sta)
        gap = max(_AIC_MARGIN, int(round(_RING_GAP_SECONDS * settings.sample_rate)))
        onsets = _onset_picks(envelope.power_rows(search_start, length), first, gap,
                              settings.sta)
        # Each channel's own whitened signal, y[n] − ρ·y[n−1], over the same stretches.
        channel_onsets = np.stack([_onset_picks(
            _whitened_windows(filtered, c, stream.rho[c], search_start, length), first, gap,
            settings.sta) for c in range(stream.channels)], axis=1)
        _keep_transients(stream, raw, filtered, envelope.sta_at(search_start + onsets),
                         search_start + onsets, search_start[:, None] + channel_onsets, strong)
    stream.done_until = stream.start + max(limit, first_new)

    keep_from = max(0, frames - settings.carry)
    stream.raw, stream.filtered = raw[keep_from:], filtered[keep_from:]
    stream.start += keep_from


def _keep_transients(stream, raw, filtered, strengths, onsets, channel_onsets, strong):
    """Group triggers into transients and store what the later steps need of each
    (`strengths`: the STA at each onset)."""
    settings = stream.settings
    channel = np.arange(stream.channels)
    # Peak deviation of the raw samples (all channels) within `amplitude` samples after each
    # onset from their mean level over the `pre` samples before it: DC offset excluded.
    before = raw[(onsets[:, None] + np.arange(-settings.pre, 0))[:, :, None],
                 channel] * stream.scale
    # Each channel's high-passed waveform around its own rough onset, for the onset fit.
    window_starts = channel_onsets - settings.pre
    if COMPILED:
        # The mean level stays numpy's (its summation order), the rest is gathered compiled.
        amplitudes, flat, windows = _kernels().transient_measures(
            raw, filtered, onsets, window_starts, before.mean(axis=1), settings.amplitude,
            settings.pre + settings.span, 1 - _CLIP_TOLERANCE, _CLIP_RUN, stream.scale)
    else:
        after = raw[(onsets[:, None] + np.arange(settings.amplitude))[:, :, None],
                    channel] * stream.scale
        amplitudes = np.abs(after - before.mean(axis=1, keepdims=True)).max(axis=(1, 2))
        # A flat top, several samples at the largest magnitude, is what clipping leaves; a
        # free transient does not produce it.
        magnitude = np.abs(after).reshape(onsets.size, -1)
        extreme = magnitude.max(axis=1, keepdims=True)
        flat = ((magnitude >= extreme * (1 - _CLIP_TOLERANCE)).sum(axis=1) >= _CLIP_RUN) \
            & (extreme[:, 0] > 0)
        windows = filtered[window_starts[:, :, None] + np.arange(settings.pre + settings.span),
                           channel[None, :, None]]
    # Python scalars for the loop (indexing numpy arrays one element at a time costs more).
    strengths, amplitude_list = strengths.tolist(), amplitudes.tolist()
    flat_list, strong_list = flat.tolist(), strong.tolist()
    absolute_starts = stream.start + window_starts
    for i, onset in enumerate(onsets.tolist()):
        absolute = stream.start + onset
        if stream.last_onset is not None and absolute <= stream.last_onset:
            continue  # the picker went back into a transient already kept
        if (stream.last_onset is not None and absolute - stream.last_onset < settings.merge
                and strengths[i] < _SPLIT_JUMP * stream.candidates[-1]["strength"]):
            # A second trigger within 1 ms of the onset of the transient just kept: its power
            # jumped again while rising. The same transient (impacts are further apart),
            # unless it is 9 dB louder: then the one kept was a faint sound (the ring or echo
            # of an earlier impact) just before this one, and both stay candidates.
            kept = stream.candidates[-1]
            kept["strength"] = max(kept["strength"], strengths[i])
            kept["amplitude"] = max(kept["amplitude"], amplitude_list[i])
            kept["clipped"] = kept["clipped"] or flat_list[i]
            kept["strong"] = kept["strong"] or strong_list[i]
            continue
        stream.candidates.append({
            "onset": absolute,
            "window_starts": absolute_starts[i],
            "windows": windows[i],
            "strength": strengths[i],
            "amplitude": amplitude_list[i],
            "clipped": flat_list[i],
            "strong": strong_list[i],
        })
        stream.last_onset = absolute


