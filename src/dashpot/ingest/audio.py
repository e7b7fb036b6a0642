"""Impacts of a bouncing ball from a sound recording (WAV, FLAC, OGG, MP3, AIFF, CAF, ...).

:func:`detect_impacts` streams the file in blocks and returns the impact table of
:mod:`dashpot.ingest`; :func:`read_audio` reads a whole (short) recording into memory. Both
raise :class:`dashpot.errors.InputError` on files that cannot be used.

Method, in four steps (each explained where it is implemented):

1. Detection. Every channel is high-passed (causal Butterworth, 100 Hz: removes DC offset, hum
   and handling rumble without moving an onset earlier), whitened by the lag-1 prediction of
   its own noise and divided by the noise level; the channels are combined as the mean of
   these noise-normalised powers, the statistic of an energy detector for a signal of unknown
   shape in independent noise, which cannot cancel between channels the way a sum of the
   waveforms can (the two microphones of a stereo recording hear the same impact with
   different delays and polarities). A transient is a jump of this power over 0.5 ms against
   the 2 ms before it (an STA/LTA trigger [1]_): strong above 9 dB, weak above 6 dB.
2. Rough onset: the Akaike-information-criterion picker [2]_ on the 3 ms before each trigger
   (but not into the transient triggered before it) finds where the power leaves the level
   before it, which catches a weak first arrival preceding the loud part of a transient;
   where that stretch lasts 0.5 ms or more and the power then jumps 3 dB over it, it is a
   sound of its own (the ring or echo of an earlier impact) and the onset is the later jump.
   Triggers within 1 ms of a kept onset belong to that transient unless 9 dB louder.
3. Selection by physics: the impacts of a ball bouncing to rest are the best chain of strong
   transients whose successive intervals shrink roughly geometrically, found by dynamic
   programming against a smooth trend of the interval ratio; ringing, echoes and rattles
   (weaker, and at a fixed delay after their impact) and noise break that trend. Members
   are then swapped for nearby transients that fit the trend better; its last impacts are
   chosen again among all transients, weak ones included; and the chain is followed past its
   end where the trend, refitted on fitted onsets, predicts further impacts, leaving out
   transients at the recurring delay of a ring or echo after an impact. Finally the trend,
   refitted robustly on the timed impacts, is walked once more: where it predicts an impact
   that no transient marks (the last bounces, a few ms apart, barely rise over the decaying
   sound of the earlier ones) or an impact was timed at the start of a ring or echo
   beginning just before it, the file is read again around the predicted time and probed
   with a trigger measured against the quietest 0.5 ms before it, or against the ring or
   echo since its start (:func:`_fill_impacts`); an impact whose onset does not rise out of
   that ring or echo takes the time the trend predicts.
   There is no fixed dead time.
4. Onset time: the posterior of the onset under a Bayesian change-point model of the rising
   edge, fitted to the high-passed waveform of the channel with the best onset SNR (see
   :func:`_onset_posterior`). It gives sub-sample times and a 1σ uncertainty from the local
   noise and the steepness of the edge, with floors for the misfit of the edge model and for
   the sub-sample error, calibrated so that about 68 % / 95 % of the true errors of synthetic
   impacts fall within 1σ / 2σ.

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
from math import exp, log
from statistics import median
from pathlib import Path

import numpy as np
import pandas as pd
import soundfile as sf
from scipy import signal

from ..errors import InputError
from ..plausibility import NOT_A_BOUNCE_TRAIN, bounce_train_problem, ratio_trend
from . import IMPACT_COLUMNS

__all__ = ["read_audio", "detect_impacts"]

# Detection (step 1).
_HIGHPASS_ORDER = 2
_STA_SECONDS = 0.5e-3  # short window after a sample: the first half millisecond of a transient
_BACKGROUND_SECONDS = 2e-3  # the level just before it
_NOISE_FRAME_SECONDS = 5e-3  # frames whose RMS gives the noise floor
_NOISE_PERCENTILE = 10.0  # quiet frames: below the impacts, above digital silence
_NOISE_FLOOR = 1e-9  # full scale; stands in for the noise of digitally silent channels
_MAX_NOISE_CORRELATION = 0.99
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
# Onset fit (step 4).
_PRE_SECONDS = 1e-3  # noise before the onset, for its level and colour
_SPAN_SECONDS = 1e-3  # start of the transient, for its amplitude and frequency scale
_ONSET_BACK_SECONDS = 1e-4  # how far from the rough onset the fit may put the onset
_POLY_ORDER = 6
# Calibration of the 1σ on synthetic modal transients (seeds other than the tests'): the
# polynomial edge follows a transient to about 0.3 % of its peak, and between samples the
# posterior mean carries a systematic error of a few hundredths of a sample.
_MODEL_ERROR = 3e-3  # residual misfit of the edge model, fraction of the transient's peak
_SUBSAMPLE_FLOOR = 0.03  # samples, added in quadrature to the posterior 1σ
_PRIOR_FREQUENCY_FACTOR = 1.3
_MAX_POST_SECONDS = 0.25e-3
_GRID_STEP = 0.25  # samples, coarse onset grid
_FINE_DIVISIONS = 8
_AMPLITUDE_SECONDS = 3e-3  # peak amplitude: largest deviation within this time of the onset
_CLIP_RUN = 3  # samples at the extreme value that mark a flat (clipped) top
_CLIP_TOLERANCE = 1e-4
# Selection (step 3).
_RATIO_BOUNDS = (0.45, 1.2)  # next interval / this interval for successive bounces, at most
_GROWTH_ALLOWANCE = 0.05  # a ratio may exceed 1 by this (restitution scatter of a few %) plus
# 3σ of the rough onsets' jitter on both intervals: up to 1.2 on the last, few-ms intervals,
# 1.06 on intervals of 0.3 s (random clicks otherwise chain at ratios of up to 1.2)
_RATIO_SCATTER_FLOOR = 0.02  # in log(ratio)
_ONSET_JITTER = 0.5e-3  # s: a faint transient's rough onset may move by this much (first
# arrival or loud part), which matters on the last, short intervals
_NOISE_WEIGHT = 1.0  # score of any transient included in the chain, plus its log SNR
_SECONDARY_SECONDS = 0.16  # ringing, rattle and echoes come up to this long after an impact
_SECONDARY_WEIGHT = 0.25  # factor on the score of a transient that may be one of them
_SECONDARY_LOUDNESS = 3.0  # ... because a transient at least 1/3 as loud came before it
_LEADING_LOUDNESS = 10.0  # the first impact is within 20 dB of the loudest
_EXTENSION_SLACK = 0.2e-3  # s, added to the tolerance of a predicted impact time
_TAIL_IMPACTS = 20  # the last impacts of the chain are chosen again among weak transients too
_EXTENSION_LOUDNESS = 2.0  # a predicted impact is at most 6 dB fainter than the last ones
_PROBE_WARMUP_SECONDS = 0.05  # high-pass settling before a probed stretch of the file
_PROBE_SECONDARY_SECONDS = 0.3e-3  # a probed onset this close to a ring or echo time is one
# Every container the bundled libsndfile decodes, except header-less RAW (it cannot be opened
# without being told its layout).
_FILE_FORMATS = set(sf.available_formats()) - {"RAW"}


# --------------------------------------------------------------------------------------------
# Reading


_UNSET_SIZES = (0, 0xFFFFFFFF)  # sizes a recorder writes before it knows (or never closed)


class _PatchedHeaderFile:
    """A read-only file object: `header` in place of the file's first bytes, then the file.

    Lets libsndfile read a WAV whose header sizes were never filled in, without copying the
    samples.
    """

    def __init__(self, path, header):
        self._file = open(path, "rb")
        self._header = bytes(header)
        self._size = Path(path).stat().st_size
        self._position = 0

    def seek(self, offset, whence=0):
        base = {0: 0, 1: self._position, 2: self._size}[whence]
        self._position = max(0, base + offset)
        return self._position

    def tell(self):
        return self._position

    def read(self, size=-1):
        if size is None or size < 0:
            size = max(0, self._size - self._position)
        data = self._header[self._position:self._position + size]
        if len(data) < size:
            self._file.seek(self._position + len(data))
            data += self._file.read(size - len(data))
        self._position += len(data)
        return data

    def close(self):
        self._file.close()


class _RepairedSoundFile(sf.SoundFile):
    """SoundFile over a _PatchedHeaderFile that closes it too; ``repair_note`` says why."""

    def __init__(self, source, repair_note):
        super().__init__(source)
        self.source = source
        self.repair_note = repair_note

    def close(self):
        super().close()
        self.source.close()


def _wav_with_unset_sizes(path):
    """Repaired header and a note for a WAV whose data size is 0 or 0xFFFFFFFF while samples
    follow the data chunk's header (a recorder that crashed or was never stopped); None for
    any other file. The samples are taken to run to the end of the file (whole frames)."""
    size = Path(path).stat().st_size
    with open(path, "rb") as handle:
        head = handle.read(1 << 16)
    if head[:4] != b"RIFF" or head[8:12] != b"WAVE":
        return None
    position, block_align = 12, 1
    while position + 8 <= len(head):  # loop over the chunks before the samples
        chunk, length = head[position:position + 4], int.from_bytes(head[position + 4:position + 8],
                                                                    "little")
        if chunk == b"fmt " and position + 22 <= len(head):
            block_align = max(1, int.from_bytes(head[position + 20:position + 22], "little"))
        if chunk == b"data":
            break
        position += 8 + length + (length & 1)
    else:
        return None
    start = position + 8
    present = (size - start) // block_align * block_align
    if present <= 0 or length not in _UNSET_SIZES:
        return None
    header = bytearray(head[:start])
    header[4:8] = (start + present - 8).to_bytes(4, "little")
    header[position + 4:position + 8] = present.to_bytes(4, "little")
    note = (f"the WAV header gives {'no' if length == 0 else 'an unset (0xFFFFFFFF)'} size for "
            f"the samples (a recording that was not closed properly): read the {present} bytes "
            f"of samples that follow it")
    return bytes(header), note


def _open(path):
    """Open `path` with libsndfile, turning every reason it cannot be used into InputError.

    A WAV whose header sizes were never filled in (0 or 0xFFFFFFFF, as a crashed recorder
    leaves them) is read from the samples present; the handle's ``repair_note`` says so.
    """
    from . import UNREADABLE_MEDIA, unreadable_media_problem

    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    if path.suffix.lower() in UNREADABLE_MEDIA:
        raise InputError(path, unreadable_media_problem(path))
    if path.stat().st_size == 0:
        raise InputError(path, "empty file (0 bytes)")
    try:
        repair = _wav_with_unset_sizes(path)
        if repair is None:
            handle = sf.SoundFile(str(path))
            handle.repair_note = ""
        else:
            handle = _RepairedSoundFile(_PatchedHeaderFile(path, repair[0]), repair[1])
    except (sf.LibsndfileError, RuntimeError, TypeError) as error:
        raise InputError(path, f"not a readable audio file (WAV, FLAC, OGG, MP3, AIFF, CAF or "
                               f"another format libsndfile decodes expected): "
                               f"{' '.join(str(error).split())}") from None
    if handle.format not in _FILE_FORMATS:
        handle.close()
        raise InputError(path, f"unsupported audio format {handle.format}: WAV, FLAC, OGG, "
                               f"MP3, AIFF or CAF expected")
    problem = _truncation(handle.extra_info)
    if problem:
        handle.close()
        raise InputError(path, problem)
    if handle.frames == 0:
        handle.close()
        raise InputError(path, "empty recording: the file holds no samples")
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
    """Samples and sample rate of a recording libsndfile decodes (WAV, FLAC, OGG, MP3, AIFF, …).

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
        interval (the posterior is not Gaussian at low SNR; this keeps the stated coverage),
        with 0.03 sample added in quadrature for the sub-sample error of the edge model.
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
    likelihood of t0 is evaluated on a grid of quarter samples within 0.1 ms of the rough
    onset (and before the end of the rising edge, a quarter period of Ω, at most 0.25 ms)
    under a flat prior, then on a grid 8 times finer around its maximum where the posterior
    is that narrow. The result does
    not depend on a template of the sound: only on the edge being smooth on the scale of the
    transient's own frequencies.

    Calibration: the residual variance gets a floor of (0.003·S)², since the polynomial
    follows a real edge only to a fraction of its peak (without it, onsets at 50-70 dB SNR
    came out up to a sample early with a 1σ of 0.02 sample), and 0.03 sample is added in
    quadrature to the 1σ (the posterior mean of synthetic modal onsets errs by a few
    hundredths of a sample, mostly late, which the posterior does not see). Both were set on
    synthetic trains other than those of the tests: 69-71 % of the true errors within 1σ,
    93 % within 2σ; the 2σ coverage is capped by the ~4 % of faint impacts whose rough
    onset a ring or an echo starting < 1.5 ms before them captured (errors of 0.04-1 ms).
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
    # The polynomial edge is a model: it follows a real transient to a fraction of its peak,
    # not to the last bit. Above that the misfit, not the noise, decides the onset, so the
    # variance of the residuals gets a floor of (ε·peak)²; loud onsets would otherwise come
    # out a sample off with a 1σ of a fiftieth of a sample.
    innovation_var = innovation_var + (_MODEL_ERROR * peak) ** 2
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

    def log_evidence(onsets):  # onsets: (K, G) in window samples -> (K, G)
        tau = np.maximum(sample_index[None, None, :] - onsets[..., None], 0.0)
        scaled = prior_omega[:, None, None] * tau
        # Columns (Ωτ)^p / p!, p = 1..P, by successive products (cheaper than powers).
        design = np.empty(scaled.shape + (_POLY_ORDER,))  # (K, G, rows, P)
        design[..., 0] = scaled
        for p in range(1, _POLY_ORDER):
            np.multiply(design[..., p - 1], scaled / (p + 1), out=design[..., p])
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
        allowed = (onsets >= n_pre - back) & (onsets <= np.minimum(n_pre + back,
                                                                     n_pre + post_len - 1)[:, None])
        return np.where(allowed, value, -np.inf)

    def summarise(onsets, log_post, step):
        weights = np.exp(log_post - log_post.max(axis=1, keepdims=True))
        weights /= weights.sum(axis=1, keepdims=True)
        cdf = np.cumsum(weights, axis=1) - 0.5 * weights  # at the grid points
        mean = (weights * onsets).sum(axis=1)
        half_width = 0.5 * (_quantile(cdf, onsets, 0.8413) - _quantile(cdf, onsets, 0.1587))
        # A grid point stands for an interval of one step: its uniform spread is added.
        return mean, np.sqrt(half_width**2 + step**2 / 12.0), weights

    n_grid = int(np.ceil((back + min(back, post_len.max() - 1)) / _GRID_STEP)) + 1
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
    # Sampling floor: between samples the onset is located through the model of the edge,
    # whose residual error (a few hundredths of a sample on synthetic modal sounds) the
    # posterior does not see; added in quadrature.
    sigma = np.hypot(sigma, _SUBSAMPLE_FLOOR)
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


@dataclass
class _Stream:
    """State carried from one block to the next while streaming a file."""

    settings: _Settings
    channels: int
    sos: np.ndarray
    filter_state: np.ndarray | None = None
    noise: np.ndarray | None = None  # noise RMS of each whitened channel (full scale)
    rho: np.ndarray | None = None  # lag-1 correlation of each channel's noise
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
        # (A matrix product: numpy's mean along the long axis of a (frames, channels) array
        # is strided and ten times slower.)
        stream.dc_offset = float(np.abs(np.ones(block.shape[0]) @ block).max() / block.shape[0])
    filtered_block, stream.filter_state = signal.sosfilt(stream.sos, block, axis=0,
                                                         zi=stream.filter_state)
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
        stream.noise = np.maximum(np.sqrt(innovation), _NOISE_FLOOR)
    elif stream.noise is None:
        stream.rho = np.zeros(stream.channels)
        stream.noise = np.maximum(np.sqrt((filtered**2).mean(axis=0)), _NOISE_FLOOR)
    # Detection runs on the noise whitened by its own lag-1 prediction, y[n] − ρ·y[n−1]:
    # for white noise (ρ ≈ 0) that is the signal itself; for noise dominated by low
    # frequencies it removes the slow swells of power that would otherwise look like onsets
    # in a half-millisecond window.
    # The mean noise-normalised power over the channels is summed channel by channel, on
    # contiguous copies of the columns (strided arithmetic on (frames, channels) is slower).
    weights = 1.0 / (stream.channels * stream.noise**2)
    power = np.zeros(frames)
    for c in range(stream.channels):
        column = np.ascontiguousarray(filtered[:, c])
        whitened = column[1:] - stream.rho[c] * column[:-1]
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
    limit = frames - settings.lookahead + 1  # triggers need this much recording after them
    lo, hi = settings.history, max(limit, settings.history)
    level = cumulative[lo:hi] - cumulative[lo - settings.background:hi
                                          - settings.background]
    np.maximum(level, settings.background, out=level)  # floor of 1 (noise-normalised)
    # Triggers down to a lower jump are kept as weak candidates: the selection looks among
    # them only where the bounce trend predicts an impact that no strong trigger marks
    # (an impact landing on the ringing or echo of an earlier one jumps less).
    weak = settings.min_jump / _WEAK_JUMP_FACTOR / settings.background
    passing = sta[lo:hi] >= settings.min_power
    passing &= sta[lo:hi] >= weak * level
    triggers = np.flatnonzero(passing) + lo
    jump = sta[triggers] * settings.background / level[triggers - lo]
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
        onsets = _onset_picks(_windows(power, search_start, length), first, gap,
                              settings.sta)
        # Each channel's own whitened signal, y[n] − ρ·y[n−1], over the same stretches.
        channel_onsets = np.stack([_onset_picks(
            (_windows(filtered[:, c], search_start, length) - stream.rho[c]
             * _windows(filtered[:, c], search_start - 1, length)) ** 2, first, gap,
            settings.sta) for c in range(stream.channels)], axis=1)
        _keep_transients(stream, raw, filtered, sta, search_start + onsets,
                         search_start[:, None] + channel_onsets, strong)
    stream.done_until = stream.start + max(limit, first_new)

    keep_from = max(0, frames - settings.carry)
    stream.raw, stream.filtered = raw[keep_from:], filtered[keep_from:]
    stream.start += keep_from


def _keep_transients(stream, raw, filtered, sta, onsets, channel_onsets, strong):
    """Group triggers into transients and store what the later steps need of each."""
    settings = stream.settings
    channel = np.arange(stream.channels)
    # Peak deviation of the raw samples (all channels) within `amplitude` samples after each
    # onset from their mean level over the `pre` samples before it: DC offset excluded.
    before = raw[(onsets[:, None] + np.arange(-settings.pre, 0))[:, :, None], channel]
    after = raw[(onsets[:, None] + np.arange(settings.amplitude))[:, :, None], channel]
    amplitudes = np.abs(after - before.mean(axis=1, keepdims=True)).max(axis=(1, 2))
    # A flat top, several samples at the largest magnitude, is what clipping leaves; a free
    # transient does not produce it.
    magnitude = np.abs(after).reshape(onsets.size, -1)
    extreme = magnitude.max(axis=1, keepdims=True)
    flat = ((magnitude >= extreme * (1 - _CLIP_TOLERANCE)).sum(axis=1) >= _CLIP_RUN) \
        & (extreme[:, 0] > 0)
    # Each channel's high-passed waveform around its own rough onset, for the onset fit.
    window_starts = channel_onsets - settings.pre
    windows = filtered[window_starts[:, :, None] + np.arange(settings.pre + settings.span),
                       channel[None, :, None]]
    for i, onset in enumerate(onsets.tolist()):
        absolute = stream.start + onset
        if stream.last_onset is not None and absolute <= stream.last_onset:
            continue  # the picker went back into a transient already kept
        if (stream.last_onset is not None and absolute - stream.last_onset < settings.merge
                and sta[onset] < _SPLIT_JUMP * stream.candidates[-1]["strength"]):
            # A second trigger within 1 ms of the onset of the transient just kept: its power
            # jumped again while rising. The same transient (impacts are further apart),
            # unless it is 9 dB louder: then the one kept was a faint sound (the ring or echo
            # of an earlier impact) just before this one, and both stay candidates.
            kept = stream.candidates[-1]
            kept["strength"] = max(kept["strength"], float(sta[onset]))
            kept["amplitude"] = max(kept["amplitude"], float(amplitudes[i]))
            kept["clipped"] = kept["clipped"] or bool(flat[i])
            kept["strong"] = kept["strong"] or bool(strong[i])
            continue
        stream.candidates.append({
            "onset": absolute,
            "window_starts": stream.start + window_starts[i],
            "windows": windows[i],
            "strength": float(sta[onset]),
            "amplitude": float(amplitudes[i]),
            "clipped": bool(flat[i]),
            "strong": bool(strong[i]),
        })
        stream.last_onset = absolute


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
    if trend is not None:
        coefficients, scatter = trend
        centre_t = (log_gap + np.polyval(coefficients, log_gap)).T.copy()
        spread_t = (scatter**2 + jitter).T.copy()
    log_gap_t = log_gap.T.copy()
    columns = np.arange(n)
    # Every pair (j, k), j < k, starts a chain, so every state ending at k is reachable from
    # all j < k (slices, not index lists, in the loop below). States ending at k are final
    # once every j < k has been seen: sweep k in time order.
    last = np.searchsorted(times, times[1:-1] + _RATIO_BOUNDS[1] * (times[1:-1] - times[0]),
                           side="right")
    for k in range(1, n - 1):
        stop = last[k - 1]
        if stop <= k + 1:
            continue
        following = log_gap[k, k + 1:stop]
        log_ratio = following - log_gap_t[k, :k, None]
        total = score[:k, k, None] + weights[k + 1:stop]
        if trend is not None:
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
    j, k = np.unravel_index(np.argmax(score), score.shape)
    chain = [int(k), int(j)]
    while pointer[chain[-1], chain[-2]] >= 0:
        chain.append(int(pointer[chain[-1], chain[-2]]))
    return np.array(chain[::-1])


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
    weights = _NOISE_WEIGHT + 0.5 * np.log(power_ratio)
    earlier = np.searchsorted(times, times - _SECONDARY_SECONDS)
    loudest_before = np.array([amplitude[a:i].max(initial=0.0) for i, a in enumerate(earlier)])
    secondary = loudest_before >= amplitude / _SECONDARY_LOUDNESS
    return np.where(secondary, _SECONDARY_WEIGHT * weights, weights)


def _select_bounces(times, power_ratio, amplitude, strong, precise=None):
    """Chain of impacts among the transients at `times` (s), and notes on missing ones.

    A first pass keeps the best chain of strong transients under the ratio bounds alone; the
    ratio of successive intervals of that chain is fitted as a straight line in log(interval)
    (restitution changes smoothly with impact speed, which is proportional to the interval
    [5]_); a second pass scores every step by how far its ratio is from that line, in units
    of the chain's robust scatter: an echo or a ring that replaced an impact would break the
    trend twice. Finally the chain is followed on (:func:`_extend_chain`) where the trend
    predicts further impacts, among all transients, weak ones included.

    Returns
    -------
    chain : ndarray of int
        Indices of the impacts, in time order.
    skipped : int
        Impacts the trend predicts but no transient marks (counted in the notes).
    """
    candidates = np.flatnonzero(strong)
    weights = np.zeros(times.size)
    weights[candidates] = _chain_weights(times[candidates], power_ratio[candidates],
                                         amplitude[candidates])
    chain = candidates[_trim_start(_best_chain(times[candidates], weights[candidates]),
                                   amplitude[candidates])]
    if chain.size < 4:
        return chain, 0
    trend = _trend(times[chain])
    candidates = candidates[times[candidates] >= times[chain[0]]]
    chain = candidates[_trim_start(_best_chain(times[candidates], weights[candidates], trend),
                                   amplitude[candidates])]
    if chain.size < 4:
        return chain, 0
    trend = _trend(times[chain])
    chain = _redo_tail(times, power_ratio, amplitude, strong, chain, trend)
    chain = _polish_chain(times, chain, trend)
    chain, skipped = _extend_chain(times, amplitude, chain, trend, precise,
                                   _secondary_delays(times, chain))
    return _polish_chain(times, chain, trend), skipped


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
    """
    coefficients, scatter = trend
    chain = chain.copy()
    for position in range(1, chain.size):
        lo, hi = np.searchsorted(times, [times[chain[position]] - _BACK_SEARCH_SECONDS,
                                         times[chain[position]] + _BACK_SEARCH_SECONDS])
        lo = max(lo, chain[position - 1] + 1)
        if position + 1 < chain.size:
            hi = min(hi, chain[position + 1])
        options = np.arange(lo, hi)
        if options.size < 2:
            continue
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
    return chain


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
    a parabola fitted to the longer intervals can bend away fast outside them.
    """
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
        return interval * exp(log_ratio)

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
        moment = float(anchors[-1 - back])
        for _ in range(back + 1 + missing):
            interval = step(interval)
            moment += interval
        moments.append(moment)
        intervals.append(interval)
    return median(moments), median(intervals)


def _extend_chain(times, amplitude, chain, trend, precise=None, delays=None):
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
    transient that comes that long after an impact of the chain: past the last impact the
    rings of the last ones continue its intervals exactly.
    """
    if precise is None:
        def precise(indices):
            return times[indices]
    else:
        trend = _trend(precise(chain))
    coefficients, scatter = trend
    step = _trend_step(coefficients, np.diff(times[chain]).min())
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
                             - members[None, None, :]).min(axis=(1, 2))
            inside &= echoing > _ONSET_JITTER
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
    others = np.setdiff1d(np.flatnonzero(times > impacts[0]), chain)
    if others.size < 3:
        return np.zeros(0)
    delays = (times[others][:, None] - impacts[None, :]).ravel()
    delays = delays[(delays > _MERGE_SECONDS) & (delays < 2 * _SECONDARY_SECONDS)]
    values, counts = np.unique(np.round(delays * 1e3).astype(np.int64), return_counts=True)
    # Neighbouring milliseconds belong together (a delay of 9.4 ms rounds to 9 or 10); a peak
    # of the pooled histogram is a candidate delay.
    pooled = counts + np.concatenate(([0], counts[:-1])) * (np.diff(values, prepend=-9) == 1)
    dense = np.zeros(values.size + 2)
    dense[1:-1] = pooled
    peaks = (pooled >= dense[:-2]) & (pooled > dense[2:]) & (pooled >= max(3, chain.size / 4))
    found = []
    for value in values[peaks] / 1e3:
        close = delays[np.abs(delays - value + 0.5e-3) <= 1e-3]
        found.append(float(np.median(close)))
    return np.array(found)


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


def _read_segment(path, start, stop):
    """Samples `start` to `stop` (frames, clipped to the file) as float64 (frames, channels)."""
    with _open(path) as handle:
        start, stop = max(0, int(start)), min(handle.frames, int(stop))
        handle.seek(start)
        return start, handle.read(max(stop - start, 0), dtype="float64", always_2d=True)


def _probe(path, stream, predicted, tolerance, timing, not_before=None):
    """The onset nearest an impact the bounce trend predicts, looked for in the file itself.

    Parameters
    ----------
    path : str or os.PathLike
        The recording.
    stream : _Stream
        State of the detection run (filter, noise level and colour of each channel).
    predicted : float
        Predicted onset (s).
    tolerance : float
        Half-width (s) of the interval around `predicted` in which a trigger may lie.
    timing : int
        Channel on which the onset is fitted.
    not_before : float, optional
        Onset (s) of a ring or an echo that captured the impact's onset before: the onset is
        looked for after it, as a sound of its own, whose power jumps 3 dB over the mean
        power since `not_before`.

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
    lead = settings.history + settings.background + int(_PROBE_WARMUP_SECONDS * sample_rate)
    offset, raw = _read_segment(path, centre - reach - lead,
                                centre + reach + settings.lookahead + 1)
    if offset + raw.shape[0] < centre + reach + settings.lookahead or offset > centre - reach \
            - settings.history - settings.background:
        return None  # too close to either end of the recording
    filtered, _ = signal.sosfilt(stream.sos, raw, axis=0, zi=signal.sosfilt_zi(stream.sos)[
        :, :, None] * raw[0][None, None, :])
    detector = np.zeros_like(filtered)
    detector[1:] = filtered[1:] - stream.rho * filtered[:-1]
    power = (detector * detector) @ (1.0 / (stream.channels * stream.noise**2))
    cumulative = np.concatenate(([0.0], np.cumsum(power)))
    earliest = centre - reach
    if not_before is not None:
        earliest = max(earliest, int(np.ceil(not_before * sample_rate)) + 2 * _AIC_MARGIN)
    if earliest > centre + reach:
        return None
    triggers = np.arange(earliest, centre + reach + 1) - offset
    sta = (cumulative[triggers + settings.sta] - cumulative[triggers]) / settings.sta
    parts = settings.background // settings.sta
    quietest = np.min([cumulative[triggers - k * settings.sta]
                       - cumulative[triggers - (k + 1) * settings.sta] for k in range(parts)],
                      axis=0) / settings.sta
    min_jump = settings.min_jump / _WEAK_JUMP_FACTOR
    if not_before is not None:
        # Past the start of a ring or an echo, the level to jump over is that sound's, the
        # mean power since it started, and by the 3 dB that tell a sound of its own.
        since = max(int(np.ceil(not_before * sample_rate)) - offset, 0)
        quietest = np.maximum(quietest, (cumulative[triggers] - cumulative[since])
                              / (triggers - since))
        min_jump = _RING_JUMP
    jump = sta / np.maximum(quietest, 1.0)
    usable = (sta >= settings.min_power) & (jump >= min_jump)
    if not usable.any():
        return None
    trigger = int(triggers[usable][np.argmax(jump[usable])])
    # The AIC picker looks back from the trigger, but not before the tolerance: a ring or an
    # echo of an earlier impact starting shortly before would capture the pick.
    search = max(trigger - settings.back_search, int(triggers[0]) - 2 * _AIC_MARGIN)
    gap = max(_AIC_MARGIN, int(round(_RING_GAP_SECONDS * sample_rate)))
    rough = search + int(_onset_picks(power[search:trigger + settings.sta][None, :],
                                      np.zeros(1, dtype=np.int64), gap, settings.sta)[0])
    if not_before is not None:
        # A sound of its own: its power jumps 3 dB over that of the sound since `not_before`.
        after = (cumulative[rough + settings.sta] - cumulative[rough]) / settings.sta
        if rough - since < _AIC_MARGIN or after < _RING_JUMP * (
                cumulative[rough] - cumulative[since]) / (rough - since):
            return None
    # As in the stream, the fit window sits on the timing channel's own rough onset (the
    # channels of a stereo pair hear an impact at different delays).
    own = detector[search:trigger + settings.sta, timing] ** 2
    start = search + int(_onset_picks(own[None, :], np.zeros(1, dtype=np.int64), gap,
                                      settings.sta)[0]) - settings.pre
    onset, sigma, _ = _onset_posterior(filtered[None, start:start + settings.pre
                                                + settings.span, timing], settings.pre,
                                       sample_rate)
    # Amplitude as for the stream's transients: largest deviation of the raw samples from
    # their level before the onset, over all channels; a flat top marks clipping.
    before = raw[rough - settings.pre:rough].mean(axis=0)
    after = raw[rough:rough + settings.amplitude]
    amplitude = float(np.abs(after - before).max())
    magnitude = np.abs(after).ravel()
    clipped = bool(magnitude.max() > 0 and (magnitude >= magnitude.max()
                                            * (1 - _CLIP_TOLERANCE)).sum() >= _CLIP_RUN)
    return ((offset + start + float(onset[0])) / sample_rate,
            float(sigma[0]) / sample_rate, amplitude, clipped)


def _robust_trend(impact_times, rounds=3):
    """:func:`_trend` of the impacts, leaving out ratios more than 3 scatters off the trend.

    A missed impact doubles an interval: the two ratios around it (about 1.9 and 0.5) would
    bend a parabola fitted through them exactly where the missed impacts are looked for
    (:func:`dashpot.plausibility.ratio_trend`, with the scatter floor of the selection).
    """
    return ratio_trend(impact_times, floor=_RATIO_SCATTER_FLOOR, rounds=rounds)


def _fill_impacts(times, amplitudes, coefficients, scatter, delays, probe, end):
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

    Returns
    -------
    added : list of tuple
        (time, sigma, amplitude, clipped) of each impact found between or after `times`.
    retimed : dict
        Index into `times` -> (time, sigma, amplitude, clipped): impacts whose onset was the
        start of a ring or an echo just before them, timed again; clipped is None where the
        time is the trend's prediction (amplitude unchanged).

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
    impact rises out of them); where no onset of its own rises out of them, the impact takes
    the predicted time, with the trend's scatter as its 1σ. A probed onset must lie within
    the tolerance of the prediction, be at most 6 dB fainter than the impacts before it, and
    not itself come at a secondary's delay after an earlier impact (an onset there is probed
    past in the same way; an impact that a ring lands on exactly is then lost: it cannot be
    told from the ring).
    An impact that is not found stays in the sequence as a predicted anchor, so that the
    predictions after it step over it; past the last impact two in a row end the search.
    """
    step = _trend_step(coefficients, np.diff(times).min())
    anchors, loudness = list(times), list(amplitudes)
    origin = list(range(len(anchors)))  # index into `times`, or -1 for a predicted anchor
    # From the fourth impact on, each one is predicted from the three intervals before it.
    added, retimed, i, missing = [], {}, 3, 0

    def secondary(moment, before):
        earlier = np.asarray(anchors[:before + 1])
        return delays.size > 0 and bool(np.abs(moment - earlier[:, None] - delays[None, :])
                                        .min() < _PROBE_SECONDARY_SECONDS)

    def accept(result, predicted, tolerance, before=None):
        # In time order between its neighbours: where the ratios scatter widely the tolerance
        # can exceed the interval itself.
        if before is None:
            before = anchors[i + 1] if i + 1 < len(anchors) else np.inf
        return (result is not None and abs(result[0] - predicted) <= tolerance
                and anchors[i] < result[0] < before
                and result[2] >= np.median(loudness[max(0, i - 2):i + 1]) / _EXTENSION_LOUDNESS
                and not secondary(result[0], i))

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

    for _ in range(20 * len(anchors) + 10):  # a bound on the probes, whatever the trend does
        predicted, interval = _predict_next(anchors[max(0, i - 3):i + 1], step)
        if interval < _MERGE_SECONDS or predicted > end:
            break
        tolerance = 3.0 * interval * scatter + _EXTENSION_SLACK
        if i + 1 < len(anchors) and anchors[i + 1] - anchors[i] < 1.5 * interval:
            # The next impact is there; if it sits off the trend at a secondary's delay after
            # an earlier impact, its onset is that of the ring or echo: time it again.
            following = anchors[i + 1]
            before = anchors[i + 2] if i + 2 < len(anchors) else np.inf
            if (origin[i + 1] >= 0 and abs(following - predicted) > tolerance
                    and following < predicted < before and secondary(following, i)):
                result = peel(predicted, tolerance, following, before)
                if result is None:
                    # No onset of its own rises out of the ring or echo: the impact is there
                    # (its sound follows), its time is the trend's, with the trend's scatter.
                    result = (predicted, interval * scatter, loudness[i + 1], None)
                retimed[origin[i + 1]] = result
                anchors[i + 1] = result[0]
            i += 1
            continue
        result = probe(predicted, tolerance)
        if result is not None and secondary(result[0], i):
            result = peel(predicted, tolerance, result[0])
        if accept(result, predicted, tolerance):
            added.append(result)
            anchors.insert(i + 1, result[0])
            loudness.insert(i + 1, result[2])
            missing = 0
        else:
            if i + 1 >= len(anchors):
                missing += 1
                if missing > 2:
                    break
            # Not found: the predicted time stands in for it as an anchor.
            anchors.insert(i + 1, predicted)
            loudness.insert(i + 1, loudness[i])
        origin.insert(i + 1, -1)
        i += 1
    return added, retimed

# --------------------------------------------------------------------------------------------
# Public entry point


def detect_impacts(path, *, block_seconds=30.0, highpass_hz=100.0, min_snr_db=12.0,
                   min_jump_db=9.0):
    """Impact table of a recording of a ball bouncing to rest.

    Parameters
    ----------
    path : str or os.PathLike
        A recording libsndfile decodes (WAV, FLAC, OGG, MP3, AIFF, CAF, ...); sample rate at
        least :data:`MIN_SAMPLE_RATE` (8 kHz); 8/16/24/32-bit integer or float samples; any
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
          the local noise (level and colour) and the steepness of the edge, plus floors for
          the edge model's misfit and sub-sample error (see :func:`_onset_posterior`);
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
        The file cannot be read (missing, empty, truncated, not audio, corrupt), is sampled
        below :data:`MIN_SAMPLE_RATE`, holds no impact (silence, noise only), or a single
        impact, which is not a bounce sequence.
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
    run on the selected impacts only, and the probes of predicted impacts read a few tens of
    ms of the file each.
    """
    _check_block_seconds(block_seconds)
    for name, value in (("highpass_hz", highpass_hz), ("min_snr_db", min_snr_db),
                        ("min_jump_db", min_jump_db)):
        if not np.isfinite(value) or value <= 0:
            raise ValueError(f"{name} must be a positive number; got {value!r}")
    with _open(path) as handle:
        sample_rate = int(handle.samplerate)
        if sample_rate < MIN_SAMPLE_RATE:
            raise InputError(path, f"sample rate {sample_rate} Hz is below the "
                                   f"{MIN_SAMPLE_RATE} Hz the impact detector needs (the first "
                                   f"{_STA_SECONDS * 1e3:g} ms of a transient must span "
                                   f"{_AIC_MARGIN} samples)")
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
        repair_note = handle.repair_note
    table = _impact_table(path, stream, sample_rate, duration)
    if repair_note:
        table.attrs["notes"].append(repair_note)
    return table


def _fitted_onsets(stream):
    """Function giving the fitted onset (s) of the stored transients of given indices.

    Each transient is fitted (:func:`_onset_posterior`) on its channel of best onset SNR;
    results are remembered, so that asking again costs nothing. The function's attribute
    ``fits`` maps each index fitted so far to (onset in samples from the start of the
    window, its 1σ in samples, channel): the final timing reuses them (the fit of a window
    does not depend on the others fitted with it).
    """
    candidates, settings = stream.candidates, stream.settings
    known, fits = {}, {}

    def fitted(indices):
        todo = [int(i) for i in np.unique(indices) if int(i) not in known]
        if todo:
            windows = np.stack([candidates[i]["windows"] for i in todo])  # (K, C, W)
            pre, post = windows[:, :, : settings.pre], windows[:, :, settings.pre:]
            snr = np.abs(post - pre.mean(axis=2, keepdims=True)).max(axis=2) / np.maximum(
                pre.std(axis=2), _NOISE_FLOOR)
            best = np.argmax(snr, axis=1)
            rows = np.arange(len(todo))
            onset, sigma, _ = _onset_posterior(windows[rows, best], settings.pre,
                                               settings.sample_rate)
            starts = np.array([candidates[i]["window_starts"][c] for i, c in zip(todo, best)])
            known.update(zip(todo, ((starts + onset) / settings.sample_rate).tolist()))
            fits.update(zip(todo, zip(onset.tolist(), sigma.tolist(), best.tolist())))
        return np.array([known[int(i)] for i in np.atleast_1d(indices)])

    fitted.fits = fits
    return fitted


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
    strong = np.array([c["strong"] for c in candidates])
    precise = _fitted_onsets(stream)
    chain, skipped = _select_bounces(rough, strength / stream.settings.min_power, amplitude,
                                     strong, precise)
    if chain.size < 3:
        # Two transients cannot be told from an impact and its ring or echo: without a third,
        # no interval ratio confirms a bounce.
        strongest = int(np.argmax(strength))
        raise InputError(path, f"{'only one impact' if chain.size < 2 else 'only two transients'}"
                               f" found (the loudest at {rough[strongest]:.3f} s): not a bounce "
                               f"sequence, which needs at least three impacts")

    chosen = [candidates[i] for i in chain]
    channels = stream.channels
    windows = np.stack([c["windows"] for c in chosen])  # (impacts, channels, width)
    # Timing channel: the best median SNR of the impacts' onsets (the precision of an onset
    # scales with its SNR), so that one fit per impact suffices.
    pre = windows[:, :, : stream.settings.pre]
    post = windows[:, :, stream.settings.pre:]
    snr = np.abs(post - pre.mean(axis=2, keepdims=True)).max(axis=2) / np.maximum(
        pre.std(axis=2), _NOISE_FLOOR)
    timing = int(np.argmax(np.median(snr, axis=0)))
    # Impacts already fitted on the timing channel during the selection keep that fit.
    onset, sigma = np.zeros(chain.size), np.zeros(chain.size)
    done = np.array([precise.fits.get(int(i), (0.0, 0.0, -1))[2] == timing for i in chain],
                    dtype=bool)
    for position in np.flatnonzero(done):
        onset[position], sigma[position], _ = precise.fits[int(chain[position])]
    if not done.all():
        onset[~done], sigma[~done], _ = _onset_posterior(windows[~done, timing],
                                                         stream.settings.pre, sample_rate)
    starts = np.array([c["window_starts"][timing] for c in chosen])

    times = (starts + onset) / sample_rate
    sigmas = sigma / sample_rate
    amplitudes = np.array([c["amplitude"] for c in chosen])
    clipped_flags = [c["clipped"] for c in chosen]
    order = np.argsort(times)
    # Only a chain whose intervals shrink as a bouncing ball's do is a bounce train: random
    # clicks also hold chains within the ratio bounds.
    problem = bounce_train_problem(times[order], sigmas[order]) or _louder_between(
        rough, strength / stream.settings.min_power, amplitude, strong, chain)
    if problem:
        raise InputError(path, f"{NOT_A_BOUNCE_TRAIN}: {problem}")
    filled, retimed = [], {}
    if chain.size >= 4:
        # The last impacts may have no trigger of their own: look for them in the file where
        # the trend, fitted on the timed impacts, puts them.
        coefficients, scatter = _robust_trend(times[order])
        filled, retimed = _fill_impacts(times[order], amplitudes[order], coefficients,
                                        scatter, _secondary_delays(rough, chain),
                                        lambda moment, tolerance, not_before=None: _probe(
                                            path, stream, moment, tolerance, timing,
                                            not_before),
                                        duration)
        for position, (moment, spread, loudness, flat) in retimed.items():
            times[order[position]], sigmas[order[position]] = moment, spread
            if flat is not None:  # timed on an onset of its own, not from the trend
                amplitudes[order[position]] = loudness
                clipped_flags[order[position]] = flat
    if filled:
        extra = np.array([row[:3] for row in filled])
        times = np.concatenate([times, extra[:, 0]])
        sigmas = np.concatenate([sigmas, extra[:, 1]])
        amplitudes = np.concatenate([amplitudes, extra[:, 2]])
        clipped_flags = clipped_flags + [row[3] for row in filled]

    table = pd.DataFrame({
        "time": times,
        "time_uncertainty": sigmas,
        "amplitude": amplitudes,
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
                     f"from channel {timing} (the best signal-to-noise ratio at the onsets)")
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
    if skipped:
        notes.append(f"{skipped} impacts predicted by the interval trend have no transient of "
                     f"their own (lost under ringing or echo, or too faint); the intervals "
                     f"around them span two or more bounces")
    if retimed:
        from_trend = sum(row[3] is None for row in retimed.values())
        notes.append(f"{len(retimed)} impacts timed again: their first onset was that of a ring "
                     f"or echo of an earlier impact starting just before them"
                     + (f"; {from_trend} of them have no onset of their own above it and take "
                        f"the time the interval trend predicts, with its scatter as uncertainty"
                        if from_trend else ""))
    if filled:
        notes.append(f"{len(filled)} faint impacts found where the interval trend predicts them "
                     f"(their sound jumps over the decaying sound before it less than a "
                     f"trigger's)")
    clipped = [i for i, flag in enumerate(clipped_flags) if flag]
    if clipped:
        notes.append(f"{len(clipped)} impacts clipped (flat tops): their amplitude is a lower "
                     f"bound")
    table.attrs.update(source=str(path), sensor="audio", notes=notes)
    return table
