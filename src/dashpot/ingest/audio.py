"""Impacts of a bouncing ball from a sound recording (WAV, FLAC, OGG).

:func:`detect_impacts` streams the file in blocks and returns the impact table of
:mod:`dashpot.ingest`; :func:`read_audio` reads a whole (short) recording into memory. Both
raise :class:`dashpot.errors.InputError` on files that cannot be used.

Method, in four steps (each explained where it is implemented):

1. Detection. Every channel is high-passed (causal Butterworth, 100 Hz: removes DC offset, hum
   and handling rumble without moving an onset earlier) and divided by its noise floor; the
   channels are combined as the mean of these noise-normalised powers, the statistic of an
   energy detector for a signal of unknown shape in independent noise, which cannot cancel
   between channels the way a sum of the waveforms can (the two microphones of a stereo
   recording hear the same impact with different delays and polarities). A transient is a
   jump of this power over 0.5 ms against the 2 ms before it (an STA/LTA trigger [1]_).
2. Rough onset: the Akaike-information-criterion picker [2]_ on the 3 ms before each trigger
   finds where the power leaves the level before it, which catches a weak first arrival that
   precedes the loud part of a transient. Triggers inside the build-up of an earlier
   transient (its power never fell to half its maximum before them) are part of it.
3. Selection by physics: the impacts of a ball bouncing to rest are the longest chain of
   transients whose successive intervals shrink roughly geometrically, found by dynamic
   programming; ringing, echoes and rattles (at a fixed delay after each impact, and weaker
   than it) and noise break that trend and are left out. There is no fixed dead time.
4. Onset time: the posterior of the onset under a Bayesian change-point model of the rising
   edge, fitted to the high-passed waveform of the channel whose onsets are the most precise
   (see :func:`_onset_posterior`). It gives sub-sample times and a 1σ uncertainty from the
   local noise and the steepness of the edge.

References
----------
.. [1] R. V. Allen, "Automatic earthquake recognition and timing from single traces", Bull.
   Seismol. Soc. Am. 68(5), 1521-1532 (1978).
.. [2] R. Sleeman and T. van Eck, "Robust automatic P-phase picking: an on-line implementation
   in the analysis of broadband seismogram recordings", Phys. Earth Planet. Inter. 113,
   265-275 (1999) (the AIC picker of N. Maeda, Zisin 38, 365-379, 1985).
.. [3] C. M. Bishop, "Pattern Recognition and Machine Learning", Springer (2006), sections
   3.3-3.5 (Bayesian linear regression and its marginal likelihood).
.. [4] S. O. Rice, "Mathematical analysis of random noise", Bell Syst. Tech. J. 23, 282-332
   (1944) (mean-square frequency from the variance of the derivative).
.. [5] T. Erickson, "Modeling a bouncing ball with exponential functions and infinite
   series", Mathematics Teacher 113(3), 233-236 (2020) (geometric shrinking of the intervals).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from math import factorial
from pathlib import Path

import numpy as np
import pandas as pd
import soundfile as sf
from scipy import signal

from ..errors import InputError
from . import IMPACT_COLUMNS

__all__ = ["read_audio", "detect_impacts"]

# Detection (step 1).
_HIGHPASS_ORDER = 2
_STA_SECONDS = 0.5e-3  # short window after a sample: the first half millisecond of a transient
_BACKGROUND_SECONDS = 2e-3  # the level just before it
_NOISE_FRAME_SECONDS = 5e-3  # frames whose RMS gives the noise floor
_NOISE_PERCENTILE = 10.0  # quiet frames: below the impacts, above digital silence
_NOISE_FLOOR = 1e-9  # full scale; stands in for the noise of digitally silent channels
# Rough onset and grouping (step 2).
_BACK_SEARCH_SECONDS = 3e-3
_AIC_MARGIN = 4  # samples: shortest segment the AIC picker may leave on either side
_BUILD_UP_FRACTION = 0.5
# Onset fit (step 4).
_PRE_SECONDS = 1e-3  # noise before the onset, for its level and colour
_SPAN_SECONDS = 1e-3  # start of the transient, for its amplitude and frequency scale
_ONSET_BACK_SECONDS = 1e-4  # how far before the rough onset the fit may put the onset
_POLY_ORDER = 6
_PRIOR_FREQUENCY_FACTOR = 1.3
_MAX_POST_SECONDS = 0.4e-3
_GRID_STEP = 0.25  # samples, coarse onset grid
_FINE_DIVISIONS = 8
_AMPLITUDE_SECONDS = 3e-3  # peak amplitude: largest deviation within this time of the onset
_CLIP_RUN = 3  # samples at the extreme value that mark a flat (clipped) top
_CLIP_TOLERANCE = 1e-4
# Selection (step 3).
_RATIO_BOUNDS = (0.45, 1.2)  # next interval / this interval for successive bounces
_RATIO_SCATTER_FLOOR = 0.02  # in log(ratio)
_NOISE_WEIGHT = 1.0  # score of any transient included in the chain, plus its log SNR
_SECONDARY_SECONDS = 0.16  # ringing, rattle and echoes come up to this long after an impact
_SECONDARY_WEIGHT = 0.25  # factor on the score of a transient that may be one of them
_FILE_FORMATS = {"WAV", "FLAC", "OGG"}


# --------------------------------------------------------------------------------------------
# Reading


def _open(path):
    """Open `path` with libsndfile, turning every reason it cannot be used into InputError."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    if path.stat().st_size == 0:
        raise InputError(path, "empty file (0 bytes)")
    try:
        handle = sf.SoundFile(str(path))
    except (sf.LibsndfileError, RuntimeError, TypeError) as error:
        raise InputError(path, f"not a readable audio file (WAV, FLAC or OGG expected): "
                               f"{error}") from None
    if handle.format not in _FILE_FORMATS:
        handle.close()
        raise InputError(path, f"unsupported audio format {handle.format}: WAV, FLAC or OGG "
                               f"expected")
    if handle.frames == 0:
        handle.close()
        raise InputError(path, "empty recording: the file holds no samples")
    problem = _truncation(handle.extra_info)
    if problem:
        handle.close()
        raise InputError(path, problem)
    return handle


def _truncation(extra_info):
    """Plain-words problem if libsndfile's header log shows a cut-off file, else ''."""
    # WAV: the data chunk claims more bytes than the file holds ("data : 352800 (should be
    # 176360)"); libsndfile then silently shortens the recording.
    for claimed, present in re.findall(r"^data\s*:\s*(\d+)\s*\(should be (\d+)\)", extra_info,
                                       flags=re.MULTILINE):
        if int(claimed) > int(present):
            return (f"truncated file: the header announces {claimed} bytes of samples but only "
                    f"{present} are present")
    # OGG: a complete stream ends with a page carrying the end-of-stream flag.
    if "Last page lacks an end-of-stream bit" in extra_info:
        return "truncated file: the Ogg stream ends without its end-of-stream page"
    return ""


def _blocks(handle, path, block_frames):
    """Yield consecutive float64 blocks of shape (frames, channels) until the end of file."""
    expected = handle.frames
    seen = 0
    while True:
        try:
            block = handle.read(block_frames, dtype="float64", always_2d=True)
        except (sf.LibsndfileError, RuntimeError) as error:
            raise InputError(path, f"truncated or corrupt file: decoding failed after "
                                   f"{seen / handle.samplerate:.3f} s ({error})") from None
        if block.shape[0] == 0:
            break
        if not np.all(np.isfinite(block)):
            bad = seen + int(np.argmax(~np.all(np.isfinite(block), axis=1)))
            raise InputError(path, f"non-finite sample (NaN or infinity) at "
                                   f"{bad / handle.samplerate:.6f} s")
        seen += block.shape[0]
        yield block
        if block.shape[0] < block_frames:
            break
    if seen < expected:
        raise InputError(path, f"truncated file: the header announces {expected} frames, only "
                               f"{seen} could be read")


def _check_block_seconds(block_seconds):
    if not np.isfinite(block_seconds) or block_seconds <= 0:
        raise ValueError(f"block_seconds must be a positive number of seconds; got "
                         f"{block_seconds!r}")


def read_audio(path, *, block_seconds=10.0):
    """Samples and sample rate of a WAV, FLAC or OGG recording.

    Parameters
    ----------
    path : str or os.PathLike
        The recording: any sample rate; 8/16/24/32-bit integer or 32/64-bit float samples;
        any number of channels.
    block_seconds : float, default 10
        Length of the blocks the file is decoded in (s). The whole recording ends up in memory;
        :func:`detect_impacts` streams instead.

    Returns
    -------
    samples : ndarray of float64, shape (frames, channels)
        Full scale = 1 (integer formats map to [-1, 1)).
    sample_rate : int
        Samples per second (Hz).

    Raises
    ------
    InputError
        Missing, empty (0 bytes or no samples), truncated, non-audio or corrupt file, or
        non-finite samples.
    """
    _check_block_seconds(block_seconds)
    with _open(path) as handle:
        block_frames = max(1, int(round(block_seconds * handle.samplerate)))
        samples = np.concatenate(list(_blocks(handle, path, block_frames)), axis=0)
        return samples, int(handle.samplerate)


# --------------------------------------------------------------------------------------------
# Onset fit


def _onset_posterior(windows, n_pre, sample_rate):
    """Posterior mean and 1σ of the onset of a transient in each window (Bayesian fit).

    Parameters
    ----------
    windows : ndarray, shape (K, W)
        High-passed waveform around each rough onset, which sits at index `n_pre`; the
        window holds `n_pre` samples before it and at least 1 ms after.
    n_pre : int
        Index of the rough onset in each window.
    sample_rate : float
        Hz.

    Returns
    -------
    onset : ndarray, shape (K,)
        Posterior mean of the onset, in samples from the start of the window (fractional).
    sigma : ndarray, shape (K,)
        Its 1σ uncertainty in samples: half the width of the central 68.3 % posterior
        interval (the posterior is not Gaussian at low SNR; this keeps the stated coverage).
    snr : ndarray, shape (K,)
        Peak of the first millisecond of the transient over the noise RMS (amplitude ratio).

    Notes
    -----
    Model: before the onset t0 the window is noise, a first-order autoregressive process
    (level, colour and innovation variance from the `n_pre` samples before the rough onset,
    less the last few which may already hold the transient); from t0 on a smooth function is
    added, f(τ) = Σ_{p=1..6} a_p (Ωτ)^p / p!, τ = t − t0, which starts from zero (an impact
    sets the surface and the ball in motion from rest). The priors a_p ~ N(0, S²), with S the
    peak of the first millisecond, say that the edge rises to the size of the transient over
    about a radian of its own oscillation, Ω = 1.3 × the noise-corrected RMS angular frequency
    of that millisecond (from the variance of the first difference [4]_). With the
    coefficients integrated out analytically (linear-Gaussian evidence [3]_) the marginal
    likelihood of t0 is evaluated on a grid of quarter samples from 0.1 ms before the rough
    onset to the end of the rising edge (a quarter period of Ω) under a flat prior, then on a
    grid 8 times finer around its maximum where the posterior is that narrow. The result does
    not depend on a template of the sound: only on the edge being smooth on the scale of the
    transient's own frequencies.
    """
    n_windows, width = windows.shape
    back = max(4, int(np.ceil(_ONSET_BACK_SECONDS * sample_rate)))
    span = width - n_pre
    # Noise before the onset: level, lag-1 correlation, innovation variance.
    quiet = windows[:, : n_pre - back]
    level = quiet.mean(axis=1)
    centred = windows - level[:, None]
    noise = centred[:, : n_pre - back]
    lag0 = np.einsum("kw,kw->k", noise[:, :-1], noise[:, :-1])
    lag1 = np.einsum("kw,kw->k", noise[:, 1:], noise[:, :-1])
    rho = np.clip(np.divide(lag1, lag0, out=np.zeros(n_windows), where=lag0 > 0), -0.5, 0.95)
    innovations = noise[:, 1:] - rho[:, None] * noise[:, :-1]
    innovation_var = np.maximum(np.einsum("kw,kw->k", innovations, innovations)
                                / max(innovations.shape[1] - 2, 1), _NOISE_FLOOR**2)
    noise_var = innovation_var / (1.0 - rho**2)
    # Scale of the transient: peak and noise-corrected RMS frequency of its first millisecond.
    post = centred[:, n_pre:]
    steps = np.diff(post, axis=1)
    step_power = np.einsum("kw,kw->k", steps, steps) - 2 * (1 - rho) * noise_var * steps.shape[1]
    power = np.einsum("kw,kw->k", post, post) - noise_var * post.shape[1]
    omega = np.sqrt(np.divide(np.maximum(step_power, 0.0), power, out=np.zeros(n_windows),
                              where=power > 0))
    omega = np.clip(omega, 0.05, np.pi)  # rad/sample
    peak = np.maximum(np.abs(post).max(axis=1), np.sqrt(noise_var))
    max_post = max(3, int(np.ceil(_MAX_POST_SECONDS * sample_rate)))
    post_len = np.clip(np.ceil((np.pi / 2) / omega).astype(int), 3, min(max_post, span - 1))
    prior_omega = _PRIOR_FREQUENCY_FACTOR * omega

    # Rows of the fit: from just before the earliest allowed onset to the end of the edge.
    # Rows before them are noise under every hypothesis and do not change the posterior.
    first = n_pre - back - 1
    last = n_pre + int(post_len.max())
    sample_index = np.arange(first, last + 1, dtype=float)
    data = centred[:, first:last + 1]
    rows = sample_index[None, :] <= (n_pre + post_len)[:, None]
    rows[:, 0] = False  # needs its predecessor for the whitening
    whitened = np.zeros_like(data)
    whitened[:, 1:] = data[:, 1:] - rho[:, None] * data[:, :-1]
    whitened *= rows
    data_term = np.einsum("kw,kw->k", whitened, whitened)
    powers = np.arange(1, _POLY_ORDER + 1)
    inverse_factorials = np.array([1.0 / factorial(p) for p in powers])

    def log_evidence(onsets):  # onsets: (K, G) in window samples -> (K, G)
        tau = np.maximum(sample_index[None, None, :] - onsets[..., None], 0.0)
        scaled = (prior_omega[:, None, None] * tau)[..., None]
        design = scaled ** powers * inverse_factorials  # (K, G, rows, P)
        white = np.zeros_like(design)
        white[:, :, 1:] = design[:, :, 1:] - rho[:, None, None, None] * design[:, :, :-1]
        white *= rows[:, None, :, None]
        gram = np.swapaxes(white, -1, -2) @ white / innovation_var[:, None, None, None]
        gram += np.eye(_POLY_ORDER) / peak[:, None, None, None] ** 2
        projection = np.einsum("kgwp,kw->kgp", white, whitened) / innovation_var[:, None, None]
        cholesky = np.linalg.cholesky(gram)
        solved = np.linalg.solve(cholesky, projection[..., None])[..., 0]
        log_det = 2.0 * np.log(np.diagonal(cholesky, axis1=-2, axis2=-1)).sum(axis=-1)
        value = -0.5 * (data_term[:, None] / innovation_var[:, None]
                        - (solved**2).sum(axis=-1)) - 0.5 * log_det
        allowed = (onsets >= n_pre - back) & (onsets <= (n_pre + post_len - 1)[:, None])
        return np.where(allowed, value, -np.inf)

    def summarise(onsets, log_post, step):
        weights = np.exp(log_post - log_post.max(axis=1, keepdims=True))
        weights /= weights.sum(axis=1, keepdims=True)
        mean = (weights * onsets).sum(axis=1)
        cdf = np.cumsum(weights, axis=1) - 0.5 * weights  # at the grid points
        half_width = 0.5 * (_quantile(cdf, onsets, 0.8413) - _quantile(cdf, onsets, 0.1587))
        # A grid point stands for an interval of one step: its uniform spread is added.
        return mean, np.sqrt(half_width**2 + step**2 / 12.0), weights

    n_grid = int(np.ceil((back + post_len.max()) / _GRID_STEP))
    coarse = (n_pre - back) + _GRID_STEP * np.arange(n_grid)[None, :] + np.zeros((n_windows, 1))
    log_post = log_evidence(coarse)
    onset, sigma, weights = summarise(coarse, log_post, _GRID_STEP)
    narrow = np.flatnonzero(sigma < _GRID_STEP)
    if narrow.size:
        fine_step = _GRID_STEP / _FINE_DIVISIONS
        centre = coarse[narrow, np.argmax(weights[narrow], axis=1)]
        offsets = fine_step * np.arange(-2 * _FINE_DIVISIONS, 2 * _FINE_DIVISIONS + 1)
        fine = centre[:, None] + offsets[None, :]
        keep = (rho, innovation_var, peak, prior_omega, post_len, whitened, rows, data_term)
        (rho, innovation_var, peak, prior_omega, post_len, whitened, rows,
         data_term) = (item[narrow] for item in keep)
        fine_log_post = log_evidence(fine)
        fine_log_post[~np.isfinite(fine_log_post).any(axis=1)] = 0.0  # all outside: flat
        onset[narrow], sigma[narrow], _ = summarise(fine, fine_log_post, fine_step)
    snr = np.abs(post).max(axis=1) / np.sqrt(noise_var)
    return onset, sigma, snr


def _quantile(cdf, grid, probability):
    """Linear interpolation of the `probability` quantile, row by row (cdf increasing)."""
    above = np.clip((cdf < probability).sum(axis=1), 1, cdf.shape[1] - 1)
    rows = np.arange(cdf.shape[0])
    c0, c1 = cdf[rows, above - 1], cdf[rows, above]
    fraction = np.clip(np.divide(probability - c0, c1 - c0, out=np.zeros_like(c0),
                                 where=c1 > c0), 0.0, 1.0)
    return grid[rows, above - 1] + fraction * (grid[rows, above] - grid[rows, above - 1])


# --------------------------------------------------------------------------------------------
# Detection on a block


def _windows(array, starts, length):
    """Rows array[s : s + length] for each s in `starts` (1-D array), as a (K, length) array."""
    return array[starts[:, None] + np.arange(length)[None, :]]


def _aic_picks(power, starts, length):
    """AIC change point of `power` in each window [s, s + length): first sample of the loud part.

    AIC(k) = k·ln(mean of the first k) + (N − k)·ln(mean of the rest) [2]_, on the power (the
    square of a zero-mean signal, so its mean is the variance).
    """
    segment = _windows(power, starts, length) + 1e-12  # digital silence has zero power
    cumulative = np.cumsum(segment, axis=1)
    total = cumulative[:, -1:]
    split = np.arange(_AIC_MARGIN, length - _AIC_MARGIN)
    head = cumulative[:, split - 1] / split
    tail = (total - cumulative[:, split - 1]) / (length - split)
    criterion = split * np.log(head) + (length - split) * np.log(tail)
    return starts + split[np.argmin(criterion, axis=1)]


def _trigger_runs(triggered):
    """(start, stop) index arrays of the runs of True in a boolean array."""
    edges = np.diff(np.concatenate(([0], triggered.astype(np.int8), [0])))
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)


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


@dataclass
class _Stream:
    """State carried from one block to the next while streaming a file."""

    settings: _Settings
    channels: int
    sos: np.ndarray
    filter_state: np.ndarray | None = None
    noise: np.ndarray | None = None  # noise RMS of each high-passed channel (full scale)
    raw: np.ndarray | None = None  # carried samples (frames, channels)
    filtered: np.ndarray | None = None
    start: int = 0  # absolute index of the first carried sample
    done_until: int = 0  # absolute index below which triggers have been handled
    last_onset: int | None = None  # absolute rough onset of the latest transient kept
    candidates: list = field(default_factory=list)
    dc_offset: float = 0.0


def _process(stream, block, final):
    """Find the transients in the carried samples + `block` and append them to the stream."""
    settings = stream.settings
    if stream.filter_state is None:
        # Start the high-pass in its steady state for the first sample, so that a DC offset
        # does not ring through the first milliseconds like an impact.
        stream.filter_state = signal.sosfilt_zi(stream.sos)[:, :, None] * block[0][None, None, :]
        stream.dc_offset = float(np.abs(block.mean(axis=0)).max())
    filtered_block, stream.filter_state = signal.sosfilt(stream.sos, block, axis=0,
                                                         zi=stream.filter_state)
    if stream.raw is None:
        raw, filtered = block, filtered_block
    else:
        raw = np.concatenate([stream.raw, block])
        filtered = np.concatenate([stream.filtered, filtered_block])
    frames = raw.shape[0]

    # Noise floor per channel: a low percentile of the RMS in short frames (the quiet
    # stretches between impacts). A block too short to say keeps the previous estimate.
    frame = max(1, int(round(_NOISE_FRAME_SECONDS * settings.sample_rate)))
    n_frames = frames // frame
    if n_frames >= 20 or (stream.noise is None and n_frames >= 1):
        rms = np.sqrt((filtered[: n_frames * frame].reshape(n_frames, frame, -1) ** 2)
                      .mean(axis=1))
        stream.noise = np.maximum(np.percentile(rms, _NOISE_PERCENTILE, axis=0), _NOISE_FLOOR)
    elif stream.noise is None:
        stream.noise = np.maximum(np.sqrt((filtered**2).mean(axis=0)), _NOISE_FLOOR)
    power = ((filtered / stream.noise) ** 2).mean(axis=1)

    # STA/LTA [1]_: mean power over the next `sta` samples against the `background` before.
    cumulative = np.concatenate(([0.0], np.cumsum(power)))
    sta = np.zeros(frames)
    if frames >= settings.sta:
        sta[: frames - settings.sta + 1] = (cumulative[settings.sta:]
                                            - cumulative[:-settings.sta]) / settings.sta
    background = np.ones(frames)
    if frames > settings.background:
        background[settings.background:] = (cumulative[settings.background:-1]
                                            - cumulative[:-settings.background - 1]) \
            / settings.background
    jump = sta / np.maximum(background, 1.0)
    index = np.arange(frames)
    valid = (index >= settings.history) & (index + settings.lookahead <= frames)
    triggered = valid & (sta >= settings.min_power) & (jump >= settings.min_jump)
    starts, stops = _trigger_runs(triggered)

    # Runs starting before `limit` are handled now if they have ended; later ones wait for the
    # next block, whose carried samples overlap this one.
    limit = frames - settings.lookahead + 1
    first_new = stream.done_until - stream.start
    own = (starts >= first_new) & (starts < limit)
    if not final:
        unfinished = own & (stops >= limit)
        if unfinished.any():
            limit = int(starts[unfinished][0])
            own &= starts < limit
    starts, stops = starts[own], stops[own]
    if starts.size:
        detections = np.array([a + int(np.argmax(jump[a:b])) for a, b in zip(starts, stops)])
        search_start = detections - settings.back_search
        length = settings.back_search + settings.sta
        onsets = _aic_picks(power, search_start, length)
        channel_onsets = np.stack([_aic_picks(filtered[:, c] ** 2, search_start, length)
                                   for c in range(stream.channels)], axis=1)
        _keep_transients(stream, raw, filtered, sta, onsets, channel_onsets)
    stream.done_until = stream.start + max(limit, first_new)

    keep_from = max(0, frames - settings.carry)
    stream.raw, stream.filtered = raw[keep_from:], filtered[keep_from:]
    stream.start += keep_from


def _keep_transients(stream, raw, filtered, sta, onsets, channel_onsets):
    """Group triggers into transients and store what the later steps need of each."""
    settings = stream.settings
    width = settings.pre + settings.span
    for onset, per_channel in zip(onsets.tolist(), channel_onsets):
        absolute = stream.start + onset
        if stream.last_onset is not None and absolute <= stream.last_onset:
            continue  # the picker went back into a transient already kept
        previous = None if stream.last_onset is None else stream.last_onset - stream.start
        if previous is not None and previous >= 0:
            # Part of the previous transient if its power never fell below half of its
            # running maximum before this trigger's window began: it was still building up.
            level = sta[previous:onset - settings.sta + 1]
            if np.all(level >= _BUILD_UP_FRACTION * np.maximum.accumulate(level)):
                kept = stream.candidates[-1]
                kept["strength"] = max(kept["strength"], float(sta[onset]))
                continue
        # Each channel's high-passed waveform around its own rough onset, for the fit.
        window_starts = per_channel - settings.pre
        windows = filtered[window_starts[:, None] + np.arange(width)[None, :],
                           np.arange(stream.channels)[:, None]]
        # Peak deviation of the raw samples from their level just before the onset.
        baseline = np.median(raw[onset - settings.pre:onset], axis=0)
        after = raw[onset:onset + settings.amplitude]
        amplitude = float(np.abs(after - baseline).max())
        magnitude = np.abs(after)
        extreme = magnitude.max()
        # A flat top: several samples at the largest magnitude, which a free transient does
        # not produce; a recorder or preamplifier that clipped does.
        clipped = bool(extreme > 0 and np.count_nonzero(
            magnitude >= extreme * (1 - _CLIP_TOLERANCE)) >= _CLIP_RUN)
        stream.candidates.append({
            "onset": absolute,
            "window_starts": stream.start + window_starts,
            "windows": windows,
            "strength": float(sta[onset]),
            "amplitude": amplitude,
            "clipped": clipped,
        })
        stream.last_onset = absolute


# --------------------------------------------------------------------------------------------
# Selection by physics


def _best_chain(times, weights, penalty=None):
    """Indices of the highest-scoring chain of events with geometrically shrinking intervals.

    Dynamic programming over states (j, k), "the chain ends with events j then k": a chain
    scores the sum of its events' weights, less ``penalty(previous_interval, ratio)`` for every
    step; a step from (j, k) to (k, l) is allowed only if the interval ratio
    (t_l − t_k)/(t_k − t_j) lies within the bounds of successive bounces.
    """
    n = times.size
    if n < 2:
        return np.arange(n)
    lo, hi = _RATIO_BOUNDS
    score = np.full((n, n), -np.inf)
    pointer = np.full((n, n), -1, dtype=np.int64)
    first, second = np.triu_indices(n, 1)
    score[first, second] = weights[first] + weights[second]
    # States ending at k are final once every j < k has been seen: sweep k in time order.
    for k in range(1, n - 1):
        reach = np.flatnonzero(np.isfinite(score[:k, k]))
        previous = times[k] - times[reach]
        nexts = np.arange(np.searchsorted(times, times[k] + lo * previous.min()),
                          np.searchsorted(times, times[k] + hi * previous.max(), side="right"))
        nexts = nexts[nexts > k]
        if nexts.size == 0:
            continue
        ratio = (times[nexts] - times[k])[None, :] / previous[:, None]
        total = score[reach, k][:, None] + weights[nexts][None, :]
        if penalty is not None:
            total = total - penalty(np.broadcast_to(previous[:, None], ratio.shape), ratio)
        total = np.where((ratio >= lo) & (ratio <= hi), total, -np.inf)
        best = np.argmax(total, axis=0)
        value = total[best, np.arange(nexts.size)]
        better = value > score[k, nexts]
        score[k, nexts[better]] = value[better]
        pointer[k, nexts[better]] = reach[best[better]]
    j, k = np.unravel_index(np.argmax(score), score.shape)
    chain = [int(k), int(j)]
    while pointer[chain[-1], chain[-2]] >= 0:
        chain.append(int(pointer[chain[-1], chain[-2]]))
    return np.array(chain[::-1])


def _chain_weights(times, power_ratio, amplitude):
    """Score of each transient as a member of the chain of impacts.

    A transient counts 1 + ½·ln(its power over the detection threshold), the log of its
    amplitude SNR, so that a clear impact outweighs a faint one. A transient that follows a
    louder one (larger peak amplitude) within 160 ms may be its ringing, rattle or echo and
    counts a quarter: where a bounce and a secondary fit the geometric trend equally well
    (an echo at a fixed delay forms a geometric chain of its own), the earlier, louder one
    is the impact. Late bounces, weaker than the one before and less than 160 ms after it,
    are quartered too; among them the trend alone decides.
    """
    weights = _NOISE_WEIGHT + 0.5 * np.log(power_ratio)
    earlier = np.searchsorted(times, times - _SECONDARY_SECONDS)
    # Largest amplitude among the transients of the preceding 160 ms (excluding itself).
    louder = np.array([amplitude[a:i].max(initial=0.0) >= amplitude[i]
                       for i, a in enumerate(earlier)])
    return np.where(louder, _SECONDARY_WEIGHT * weights, weights)


def _select_bounces(times, weights):
    """Chain of impacts among the transients at `times` (s), and the trend it follows.

    A first pass keeps the best chain under the ratio bounds alone; the ratio of successive
    intervals of that chain is fitted as a straight line in log(interval) (restitution
    changes smoothly with impact speed, which is proportional to the interval [5]_); a second
    pass scores every step by how far its ratio is from that line, in units of the chain's
    robust scatter. An echo or a ring that replaced an impact would break the trend twice.
    """
    chain = _best_chain(times, weights)
    if chain.size < 4:
        return chain
    intervals = np.diff(times[chain])
    log_ratio = np.log(intervals[1:] / intervals[:-1])
    log_interval = np.log(intervals[:-1])
    slope, intercept = np.polyfit(log_interval, log_ratio, 1)
    residual = log_ratio - (intercept + slope * log_interval)
    scatter = max(1.4826 * np.median(np.abs(residual - np.median(residual))),
                  _RATIO_SCATTER_FLOOR)

    def penalty(previous, ratio):
        return 0.5 * ((np.log(ratio) - intercept - slope * np.log(previous)) / scatter) ** 2

    return _best_chain(times, weights, penalty)


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
# Public entry point


def detect_impacts(path, *, block_seconds=30.0, highpass_hz=100.0, min_snr_db=12.0,
                   min_jump_db=9.0):
    """Impact table of a recording of a ball bouncing to rest.

    Parameters
    ----------
    path : str or os.PathLike
        WAV, FLAC or OGG file; any sample rate; 8/16/24/32-bit integer or float samples; any
        number of channels.
    block_seconds : float, default 30
        The file is decoded and analysed in blocks of this length (s), so that memory stays
        bounded however long the recording.
    highpass_hz : float, default 100
        Cut-off (Hz) of the 2nd-order causal Butterworth high-pass applied before detection
        and timing: removes DC offset, hum and rumble. Being causal it cannot move an onset
        earlier.
    min_snr_db : float, default 12
        A transient must carry at least this power over the noise floor in its first 0.5 ms
        (dB, noise-normalised power averaged over channels).
    min_jump_db : float, default 9
        ... and its power must jump by at least this much over the 2 ms before it (dB).

    Returns
    -------
    pandas.DataFrame
        One row per impact with the columns of :data:`dashpot.ingest.IMPACT_COLUMNS`:

        * ``time`` (s from the start of the file): the onset of the impact transient, i.e.
          the posterior mean of the instant t0 at which the high-passed waveform of the
          timing channel leaves the noise under the change-point model of
          :func:`_onset_posterior` (sub-sample; the first arrival of the impact's sound at
          the microphone, earlier than the loud part of the transient);
        * ``time_uncertainty`` (s): its 1σ, half the central 68 % posterior interval, from
          the local noise (level and colour) and the steepness of the edge;
        * ``amplitude`` (full scale = 1): the largest deviation of the raw samples from their
          level just before the onset within 3 ms after it, over all channels (DC offset
          excluded; a lower bound where the recording clipped);
        * ``impact_speed``, ``rebound_speed``, ``speed_uncertainty``: NaN (sound does not
          measure speed);
        * ``run``: 0.

        ``attrs``: ``source`` (the file), ``sensor`` = "audio", ``notes`` (list of str: the
        timing channel, transients left out and why, clipped impacts).

    Raises
    ------
    InputError
        The file cannot be read (missing, empty, truncated, not audio, corrupt), holds no
        impact (silence, noise only), or a single impact, which is not a bounce sequence.
    ValueError
        An option is out of range.

    Notes
    -----
    Channels: detection uses all of them (mean noise-normalised power); times come from the
    single channel whose onsets are the most precise (smallest median uncertainty). Averaging
    channels would overstate the precision when their noise is shared (room noise heard by
    both microphones, or one microphone mixed to several channels), and the channels of a
    stereo pair hear each impact at different delays.

    Selection: among all transients, the impacts are those of the best chain whose successive
    interval ratios stay within [0.45, 1.2] and follow a smooth trend (see
    :func:`_select_bounces`). Ringing, echoes and rattles, which come at a fixed delay after
    their impact, and noise are left out and counted in the notes.

    Speed: the work per sample is a few vectorized passes (high-pass, running sums); the fits
    run on the selected impacts only.
    """
    _check_block_seconds(block_seconds)
    for name, value in (("highpass_hz", highpass_hz), ("min_snr_db", min_snr_db),
                        ("min_jump_db", min_jump_db)):
        if not np.isfinite(value) or value <= 0:
            raise ValueError(f"{name} must be a positive number; got {value!r}")
    with _open(path) as handle:
        sample_rate = int(handle.samplerate)
        if highpass_hz >= 0.45 * sample_rate:
            raise ValueError(f"highpass_hz must be below 0.45 × the sample rate "
                             f"({0.45 * sample_rate:g} Hz); got {highpass_hz!r}")
        settings = _Settings.make(sample_rate, min_snr_db, min_jump_db)
        sos = signal.butter(_HIGHPASS_ORDER, highpass_hz, "highpass", fs=sample_rate,
                            output="sos")
        stream = _Stream(settings=settings, channels=handle.channels, sos=sos)
        block_frames = max(int(round(block_seconds * sample_rate)), settings.carry)
        pending = None
        # One block of look-ahead, so that the last one is processed as final.
        for block in _blocks(handle, path, block_frames):
            if pending is not None:
                _process(stream, pending, final=False)
            pending = block
        _process(stream, pending, final=True)
        duration = handle.frames / sample_rate
    return _impact_table(path, stream, sample_rate, duration)


def _impact_table(path, stream, sample_rate, duration):
    """Select the impacts among the stored transients, time them, and build the table."""
    candidates = stream.candidates
    if not candidates:
        raise InputError(path, f"no impacts found in {duration:.3f} s: silence or noise only "
                               f"(no transient rose {10 * np.log10(stream.settings.min_jump):.0f}"
                               f" dB over the level before it and "
                               f"{10 * np.log10(stream.settings.min_power):.0f} dB over the "
                               f"noise floor)")
    rough = np.array([c["onset"] for c in candidates]) / sample_rate
    strength = np.array([c["strength"] for c in candidates])
    amplitude = np.array([c["amplitude"] for c in candidates])
    weights = _chain_weights(rough, strength / stream.settings.min_power, amplitude)
    chain = _select_bounces(rough, weights)
    if chain.size < 2:
        strongest = int(np.argmax(strength))
        raise InputError(path, f"only one impact found (at {rough[strongest]:.3f} s): a single "
                               f"impact is not a bounce sequence")

    chosen = [candidates[i] for i in chain]
    channels = stream.channels
    windows = np.concatenate([c["windows"] for c in chosen])  # (impacts × channels, width)
    onset, sigma, snr = _onset_posterior(windows, stream.settings.pre, sample_rate)
    starts = np.concatenate([c["window_starts"] for c in chosen])
    times = ((starts + onset) / sample_rate).reshape(-1, channels)
    sigmas = (sigma / sample_rate).reshape(-1, channels)
    timing = int(np.argmin(np.median(sigmas, axis=0)))

    table = pd.DataFrame({
        "time": times[:, timing],
        "time_uncertainty": sigmas[:, timing],
        "amplitude": [c["amplitude"] for c in chosen],
        "impact_speed": np.nan,
        "rebound_speed": np.nan,
        "speed_uncertainty": np.nan,
        "run": 0,
    }, columns=list(IMPACT_COLUMNS))
    table = table.sort_values("time", ignore_index=True)

    notes = [f"time: onset of each impact transient (Bayesian change-point fit of its rising "
             f"edge), {sample_rate} Hz recording"]
    if channels > 1:
        notes.append(f"{channels} channels: transients detected on all of them, times taken "
                     f"from channel {timing} (the most precise onsets)")
    if stream.dc_offset > 1e-3:
        notes.append(f"DC offset of about {stream.dc_offset:.3g} (full scale) removed by the "
                     f"high-pass; amplitudes are measured from the local level")
    left_out = len(candidates) - chain.size
    if left_out:
        delay, count = _fixed_delays(rough, chain)
        remark = (f"{left_out} transients not counted as impacts: they break the geometric "
                  f"shrinking of the intervals (ringing, echo, rattle or noise)")
        if count >= 3:
            remark += (f"; {count} of them come {delay * 1e3:.0f} ms after an impact "
                       f"(ringing or echo)")
        notes.append(remark)
    clipped = [i for i, c in enumerate(chosen) if c["clipped"]]
    if clipped:
        notes.append(f"{len(clipped)} impacts clipped (flat tops): their amplitude is a lower "
                     f"bound")
    table.attrs.update(source=str(path), sensor="audio", notes=notes)
    return table
