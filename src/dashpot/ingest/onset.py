"""Onset time of an impact transient: the posterior of a Bayesian change-point model of its
rising edge (step 4 of :mod:`dashpot.ingest.audio`), and which edge is the impact's: that of
its first burst (:func:`_first_burst`), or that of its rise through a fifth of its peak
(:func:`_rise_crossing`) unless an earlier fitted onset leads into it as one sound
(:func:`_one_sound`).

References
----------
.. [3] C. M. Bishop, "Pattern Recognition and Machine Learning", Springer (2006), sections
   3.3-3.5 (Bayesian linear regression and its marginal likelihood).
.. [4] S. O. Rice, "Mathematical analysis of random noise", Bell Syst. Tech. J. 23, 282-332
   (1944) (mean-square frequency from the variance of the derivative).
"""

from __future__ import annotations

import numpy as np

from . import envelope as _envelope
from .envelope import _NOISE_FLOOR


# Onset fit (step 4).
_ONSET_BACK_SECONDS = 1e-4  # how far from the rough onset the fit may put the onset
_POLY_ORDER = 6
# Calibration of the 1σ on synthetic modal transients (seeds other than the tests'): the
# polynomial edge follows a transient to about 0.3 % of its peak, and between samples the
# posterior mean carries a systematic error of a few hundredths of a sample.
_MODEL_ERROR = 3e-3  # residual misfit of the edge model, fraction of the transient's peak
_SUBSAMPLE_FLOOR = 0.03  # samples, added in quadrature to the posterior 1σ
_PRIOR_FREQUENCY_FACTOR = 1.3
_MAX_POST_SECONDS = 0.25e-3
_MIN_EDGE_ROWS = 3  # samples from the onset on that the fit takes at least
_GRID_STEP = 0.25  # samples, coarse onset grid over the whole range
_FINE_STEP = 1.0 / 32.0  # samples, fine grid ...
_FINE_REACH = 1.0  # ... within this many samples of the coarse maximum
_CHUNK = 64  # windows whose grids are evaluated at once (memory)
_RISE_LEVELS = (0.1, 0.5)  # of the peak: the rise whose width counts in the 1σ


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
        with, in quadrature, the width of the sound's rise from 10 % to 50 % of its peak
        (less one sample) over √12 (see :func:`_rise_samples`) and 0.03 sample for the
        sub-sample error of the edge model.
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
    under a flat prior, and on a grid of 1/32 sample within a sample of its maximum. The
    result does not depend on a template of the sound: only on the edge being smooth on the
    scale of the transient's own frequencies.

    Calibration: the residual variance gets a floor of (0.003·S)², since the polynomial
    follows a real edge only to a fraction of its peak (without it, onsets at 50-70 dB SNR
    came out up to a sample early with a 1σ of 0.02 sample), and 0.03 sample is added in
    quadrature to the 1σ (the posterior mean of synthetic modal onsets errs by a few
    hundredths of a sample, mostly late, which the posterior does not see). Both were set on
    synthetic trains other than those of the tests: 69-71 % of the true errors within 1σ,
    93 % within 2σ. With the grid refined near the maximum (an onset just before a sample
    was timed up to a sample early, 3-4 % of the impacts of disturbed trains), 100 disturbed
    trains of a development block (seeds 20261125-20261224, :mod:`dashpot.synth.audio` with
    apex clicks, rest tails, rings with bursts and echoes) have 92 % within 1σ and 96 % within
    2σ: the posterior is wide on the sharp edges of synthetic modal sounds, and ~3 % of the
    impacts, whose onset a ring, burst or echo starting < 1.5 ms before them captured, err by
    0.06-1 ms.
    """
    n_windows, width = windows.shape
    back = _onset_reach(sample_rate)
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
    post_len = np.clip(np.ceil((np.pi / 2) / omega).astype(int), _MIN_EDGE_ROWS,
                       min(max_post, span - 1))
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
        if _envelope.COMPILED:
            squared, diagonal = _envelope._kernels().edge_fits(
                onsets, sample_index, prior_omega, rho, rows, innovation_var, peak, whitened,
                _POLY_ORDER)
        else:
            squared, diagonal = _edge_fits(onsets)
        log_det = 2.0 * np.log(diagonal).sum(axis=-1)
        value = -0.5 * (data_term[:, None] / innovation_var[:, None] - squared) - 0.5 * log_det
        allowed = (onsets >= n_pre - back) & (onsets <= np.minimum(n_pre + back,
                                                                     n_pre + post_len - 1)[:, None])
        return np.where(allowed, value, -np.inf)

    def _edge_fits(onsets):
        # The regression's ‖L⁻¹b‖² and the diagonal of L for each window and onset (the
        # reference of :func:`.audio_kernels.edge_fits`).
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
        return (solved**2).sum(axis=-1), np.diagonal(cholesky, axis1=-2, axis2=-1)

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
    offsets = _FINE_STEP * np.arange(-round(_FINE_REACH / _FINE_STEP),
                                     round(_FINE_REACH / _FINE_STEP) + 1)
    onset, sigma = np.zeros(n_windows), np.zeros(n_windows)
    full = (rho, innovation_var, peak, prior_omega, post_len, whitened, rows, data_term)
    for start in range(0, n_windows, _CHUNK):  # bounded memory
        part = slice(start, start + _CHUNK)
        (rho, innovation_var, peak, prior_omega, post_len, whitened, rows,
         data_term) = (item[part] for item in full)
        coarse_log = log_evidence(coarse[part])
        # Where the onset falls just before a sample (the first sample after it a few % of
        # the next), the posterior at high SNR is a spike a few hundredths of a sample wide,
        # which the coarse grid straddles: its maximum then falls on a spurious mode up to a
        # sample early (onsets 0.9-1 sample past a sample at 55-70 dB came out 0.8 sample
        # early with a 1σ of 0.1 sample). A fine grid within a sample of the coarse
        # maximum finds the spike; the two grids are merged, each point weighted by the
        # width of the cell it stands for.
        centre = coarse[part][np.arange(coarse_log.shape[0]), np.argmax(coarse_log, axis=1)]
        fine = centre[:, None] + offsets[None, :]
        fine_log = log_evidence(fine)
        inside = np.abs(coarse[part] - centre[:, None]) <= _FINE_REACH
        grid = np.concatenate([coarse[part], fine], axis=1)
        log_post = np.concatenate([np.where(inside, -np.inf, coarse_log + np.log(_GRID_STEP)),
                                   fine_log + np.log(_FINE_STEP)], axis=1)
        order = np.argsort(grid, axis=1, kind="stable")
        grid = np.take_along_axis(grid, order, axis=1)
        log_post = np.take_along_axis(log_post, order, axis=1)
        log_post[~np.isfinite(log_post).any(axis=1)] = 0.0  # all outside: flat
        onset[part], sigma[part], _ = summarise(grid, log_post, _FINE_STEP)
    rho, innovation_var, peak, prior_omega, post_len, whitened, rows, data_term = full
    snr = np.abs(post).max(axis=1) / np.sqrt(noise_var)
    # Rise floor: a real impact sound may rise from the noise over a millisecond or more
    # (ping-pong and rubber balls: 0.2-2 ms from 10 % to 50 % of the peak of its first
    # millisecond; synthetic modal transients within one sample). The edge model then
    # places the onset somewhere within that rise, which its posterior does not see: the
    # rise, less the one sample a sharp edge spans, counts as a uniform uncertainty (its
    # standard deviation, width/√12, in quadrature).
    sigma = np.hypot(sigma, _rise_samples(np.abs(post), np.sqrt(noise_var)) / np.sqrt(12.0))
    # Sampling floor: between samples the onset is located through the model of the edge,
    # whose residual error (a few hundredths of a sample on synthetic modal sounds) the
    # posterior does not see; added in quadrature.
    sigma = np.hypot(sigma, _SUBSAMPLE_FLOOR)
    return onset, sigma, snr


def _onset_reach(sample_rate):
    """Samples before (and after) its rough onset within which the fit may put the onset:
    0.1 ms, at least 4."""
    return max(4, int(np.ceil(_ONSET_BACK_SECONDS * sample_rate)))


def _rise_samples(magnitude, noise_rms):
    """Samples from the first crossing of the low to that of the high level, less one.

    Levels: 10 % and 50 % of the peak of `magnitude` (K, W), the low one at least 3 noise
    RMS (`noise_rms`, K) so that noise does not cross it; 0 where the low level is not
    below the high one.
    """
    peak = magnitude.max(axis=1)
    low = np.maximum(_RISE_LEVELS[0] * peak, 3.0 * noise_rms)
    high = _RISE_LEVELS[1] * peak
    first_low = np.argmax(magnitude >= low[:, None], axis=1)
    first_high = np.argmax(magnitude >= high[:, None], axis=1)
    return np.where(low < high, np.maximum(first_high - first_low - 1, 0), 0).astype(float)


def _quantile(cdf, grid, probability):
    """Linear interpolation of the `probability` quantile, row by row (cdf increasing)."""
    above = np.clip((cdf < probability).sum(axis=1), 1, cdf.shape[1] - 1)
    rows = np.arange(cdf.shape[0])
    c0, c1 = cdf[rows, above - 1], cdf[rows, above]
    fraction = np.clip(np.divide(probability - c0, c1 - c0, out=np.zeros_like(c0),
                                 where=c1 > c0), 0.0, 1.0)
    return grid[rows, above - 1] + fraction * (grid[rows, above] - grid[rows, above - 1])


# --------------------------------------------------------------------------------------------
# The impact's first burst

_BURST_REACH_SECONDS = (2e-3, 3e-3)  # before / after the fitted onset: where the impact's
# first burst (1-2 ms before a louder one on real recordings) and its peak are looked for
_BURST_MIN_LEAD_SECONDS = 0.25e-3  # a rise closer before the onset is the fitted edge's own
_BURST_LEVEL = 0.2  # of the impact's peak: the level a first burst rises through
_BURST_BACKGROUND = 4.0  # ... at least this many RMS of the sound before it
_BURST_BACKGROUND_SECONDS = 1e-3  # the stretch before the reach whose RMS is that sound's


def _burst_level(magnitude, onset, sample_rate):
    """A fifth of each row's peak magnitude from 2 ms before `onset` (an index) to 3 ms after
    it: the level an impact's first burst, and its rise, pass through (units of
    `magnitude`, shape (K, W))."""
    before, after = (int(round(s * sample_rate)) for s in _BURST_REACH_SECONDS)
    return _BURST_LEVEL * magnitude[:, max(onset - before, 0):onset + after].max(axis=1)


def _first_burst(magnitude, onset, noise_rms, sample_rate):
    """Sample where each impact's first burst rises through a fifth of the impact's peak.

    Parameters
    ----------
    magnitude : ndarray, shape (K, W)
        Magnitude of the high-passed waveform (level removed) around each impact.
    onset : int
        Index in each row of the onset fitted so far.
    noise_rms : float or ndarray, shape (K,)
        RMS of the recording's noise at each impact, in the units of `magnitude`.
    sample_rate : float
        Hz.

    Returns
    -------
    ndarray of int, shape (K,)
        For each row, the index of the first sample from 2 ms to 0.25 ms before `onset` at
        which the magnitude reaches L = 20 % of its peak from 2 ms before `onset` to 3 ms
        after it, where the sound from there to `onset` has an RMS of at least L/2 and a
        peak below that of the millisecond from `onset`; -1 where there is none, or where L
        is not 4 times the RMS of the noise and of the 1 ms before the reach.

    Notes
    -----
    A real impact sound may open with a burst 30-80 % as loud as a second one 1-2 ms later
    (ping-pong and rubber balls), each a rising edge of its own to the change-point fit,
    which times the one its window holds. The onset of an impact is where its first burst
    starts: a sound before the fitted edge that rises through a fifth of the impact's peak
    and lasts into it is that burst (a threshold crossing, as in the threshold pickers of
    seismology, e.g. M. Baer and U. Kradolfer, Bull. Seismol. Soc. Am. 77, 1437-1445,
    1987). The level clears the sound before the reach four times over (Gaussian noise
    exceeds 4 RMS once in 16,000 samples, so a crossing over the 2 ms is not the noise's,
    nor that of a ring of an earlier impact decaying there), a burst lasts (its RMS to
    the onset is half the level or more; a spike of noise or a click does not), and it is
    fainter than the edge it leads (on the real recordings 0.2-0.75 of its peak; a louder
    sound before that edge would have been chosen as the impact were it one).
    """
    before, after = (int(round(s * sample_rate)) for s in _BURST_REACH_SECONDS)
    quiet = int(round(_BURST_BACKGROUND_SECONDS * sample_rate))
    lo, hi = onset - before, min(onset + after, magnitude.shape[1])
    last = onset - int(round(_BURST_MIN_LEAD_SECONDS * sample_rate))
    if lo - quiet < 0 or last <= lo or hi <= onset:
        return np.full(magnitude.shape[0], -1)
    level = _burst_level(magnitude, onset, sample_rate)
    floor = np.maximum(noise_rms, np.sqrt(np.mean(magnitude[:, lo - quiet:lo] ** 2, axis=1)))
    above = magnitude[:, lo:last] >= level[:, None]
    first = lo + np.argmax(above, axis=1)
    # Mean square from each crossing to the onset, from cumulative sums.
    power = np.cumsum(magnitude[:, lo:onset] ** 2, axis=1)
    upto = power[:, -1] - np.where(first > lo, power[np.arange(first.size),
                                                     np.maximum(first - lo - 1, 0)], 0.0)
    lasting = upto / (onset - first) >= (0.5 * level) ** 2
    # ... and is fainter than the edge the fit timed, which it leads: a louder sound before
    # that edge is a sound of its own (the chain chose the edge), not its impact's opening.
    span = magnitude[:, lo:onset]
    burst_peak = np.where(np.arange(lo, onset)[None, :] >= first[:, None], span, 0.0).max(axis=1)
    fainter = burst_peak < magnitude[:, onset:onset + int(round(1e-3 * sample_rate))].max(axis=1)
    found = above.any(axis=1) & (level >= _BURST_BACKGROUND * floor) & lasting & fainter
    return np.where(found, first, -1)


# --------------------------------------------------------------------------------------------
# The edge of the impact's rise

_ONE_SOUND_SECONDS = 1e-4  # window of the short-time RMS that tells one sound from two
_ONE_SOUND_LEVEL = 2.0  # ... which stays above this many RMS of the sound before: one sound


def _rise_crossing(magnitude, onset, sample_rate):
    """Where each impact's sound rises through a fifth of its peak, from just before the onset.

    Parameters
    ----------
    magnitude, onset, sample_rate
        As for :func:`_first_burst`.

    Returns
    -------
    crossing : ndarray of int, shape (K,)
        First index from 0.25 ms before `onset` (closer before it a rise is the fitted edge's
        own; earlier ones are first bursts, :func:`_first_burst`) at which the magnitude
        reaches the level; -1 where it does not.
    level : ndarray, shape (K,)
        A fifth of the peak of the magnitude from 2 ms before `onset` to 3 ms after it (the
        impact's peak, as in :func:`_first_burst`), in the units of `magnitude`.
    """
    start = onset - int(round(_BURST_MIN_LEAD_SECONDS * sample_rate))
    level = _burst_level(magnitude, onset, sample_rate)
    above = magnitude[:, start:] >= level[:, None]
    return np.where(above.any(axis=1), start + np.argmax(above, axis=1), -1), level


def _one_sound(magnitude, early, late, background, sample_rate):
    """Whether the sound from sample `early` to sample `late` (fractional indices into the
    1-d `magnitude`) is one sound: its RMS over every 0.1 ms stays at least twice the RMS
    `background` of the sound before it. A stretch shorter than 0.1 ms is one sound.

    Notes
    -----
    A transient rises out of the background and keeps rising into its peak; a faint sound of
    its own before it (a click, or a fluctuation of the background the fit took for an edge)
    falls back to the background before the impact's edge. Over 0.1 ms a Gaussian
    background alone exceeds twice its RMS in 0.3 % of the windows at 44.1 kHz (4 samples:
    chi-square with 4 degrees of freedom over 4 reaching 4) and 2 % at 22.05 kHz (2 samples).
    """
    width = max(2, int(round(_ONE_SOUND_SECONDS * sample_rate)))
    first, last = int(np.ceil(early)), int(np.floor(late))
    if last - first < width:
        return True
    power = np.convolve(magnitude[first:last] ** 2, np.ones(width) / width, mode="valid")
    return bool(power.min() >= (_ONE_SOUND_LEVEL * background) ** 2)


# --------------------------------------------------------------------------------------------
# The 1σ stated for an impact's onset

_SHARP_EDGE_SHARE = 0.5  # of the fit's 1σ (less the sub-sample floor) on a short sharp edge
_AMBIGUITY_REACH_SECONDS = (1.5e-3, 1e-3)  # before / after an onset: where a ring, burst or
# echo of an earlier impact that starts makes the onset ambiguous
_AMBIGUITY_SECONDS = 0.06e-3  # s, added in quadrature to the 1σ of such an onset


def _edge_samples(sound, noise_rms):
    """Quarter period (samples) of each sound's noise-corrected RMS angular frequency.

    `sound` (K, W) is the high-passed waveform from each onset on (level removed; its first
    millisecond), `noise_rms` (K,) the RMS of the noise in its units; the frequency is that of
    :func:`_onset_posterior` (from the variance of the first difference [4]_, the noise taken
    as white), whose fit takes the rows of the edge up to this quarter period, and at least
    3.
    """
    steps = np.diff(sound, axis=1)
    noise_var = noise_rms**2
    step_power = np.einsum("kw,kw->k", steps, steps) - 2.0 * noise_var * steps.shape[1]
    power = np.einsum("kw,kw->k", sound, sound) - noise_var * sound.shape[1]
    omega = np.sqrt(np.divide(np.maximum(step_power, 0.0), power, out=np.zeros(len(sound)),
                              where=power > 0))
    return (np.pi / 2) / np.clip(omega, 0.05, np.pi)


def _stated_sigma(sigma, rise, edge, secondary_lead, sample_rate):
    """The 1σ stated for each impact's onset, from the 1σ of its fit.

    Parameters
    ----------
    sigma : ndarray, shape (K,)
        1σ of each fitted onset (:func:`_onset_posterior`, with any term added for a gap to
        the rise), s.
    rise : ndarray, shape (K,)
        Samples the sound from each onset takes from a tenth to half of the peak of its first
        millisecond, less one (:func:`_rise_samples`): 0 for a sharp edge.
    edge : ndarray, shape (K,)
        Quarter period of each sound, samples (:func:`_edge_samples`).
    secondary_lead : ndarray, shape (K,)
        Time from the start of the latest ring, burst or echo of an earlier impact (at a
        delay at which they recur) that starts up to 1 ms after each onset, to the onset, s
        (positive: it starts before the onset); NaN where there is none.
    sample_rate : float
        Hz.

    Returns
    -------
    ndarray, shape (K,)
        1σ, s.

    Notes
    -----
    Short sharp edges. Where a sound rises from a tenth to half of its peak within a sample
    and its quarter period is shorter than the 3 samples the fit takes at least (modes of
    2-5 kHz sampled at 22.05 kHz: 1.9-2.5 samples), the fit's rows run past the edge's first
    peak, and the posterior of the onset is one-sided: it ends sharply at the first sample of
    the rise and reaches back over earlier, slower starts. The true onset sits at its late
    end; the posterior mean errs by about half the posterior's half-width, early, with a
    scatter of a quarter of it (seeds 20261125-20261324 of the disturbed trains of issue 14,
    200 trains of :mod:`dashpot.synth.audio` at 22.05 kHz: of the impacts with a quarter
    period under 2.5 samples, 93 % of the errors within the fit's 1σ, 98 % within 2σ; at 44.1
    kHz, quarter periods of 3.5-5 samples, 72-73 % and 96-97 %). There the fit's 1σ, less the
    sub-sample floor, counts at half its width. Longer or slower edges (real impact sounds,
    whose 1σ the rise's width dominates) keep it.

    Secondaries. Where a ring, burst or echo of an earlier impact starts from 1.5 ms before
    an onset to 1 ms after it, the onset may be that sound's, or be pulled by it: on the
    development seeds 19 % of such impacts (16 % of all) erred by 0.05-0.7 ms (RMS of their
    errors 0.19 ms, against 0.03 ms elsewhere) before the chain timed again the impacts
    taken at a secondary's start. A mixture of this kind has no single Gaussian 1σ: 0.06 ms
    in quadrature (0.1 ms before that retiming), set on those seeds, has the impacts as a
    whole covered at the stated rates (68.4 % within 1σ, 95.5 % within 2σ).
    """
    floor = _SUBSAMPLE_FLOOR / sample_rate
    fitted = np.sqrt(np.maximum(sigma**2 - floor**2, 0.0))
    short = (rise == 0) & (edge < _MIN_EDGE_ROWS)
    stated = np.hypot(np.where(short, _SHARP_EDGE_SHARE * fitted, fitted), floor)
    near = ((secondary_lead <= _AMBIGUITY_REACH_SECONDS[0])
            & (secondary_lead >= -_AMBIGUITY_REACH_SECONDS[1]))
    return np.where(near, np.hypot(stated, _AMBIGUITY_SECONDS), stated)
