"""Synthetic microphone recordings of a ball bouncing to rest, with known impact onsets.

Each impact is rendered as the sound of a struck resonant body: a sum of exponentially
decaying sinusoids (modal synthesis [1]_) that starts at the impact with zero value and a
finite slope, i.e. the response of the modes to an impulsive contact force. The onset of each
transient is therefore a sharp, exactly known instant, which is what the audio reader is asked
to find. On top come the traps of real recordings: a ringing secondary transient, an echo from
a wall, background noise, a DC offset and clipping, and the quiet sounds real recordings hold
besides the impacts (dashpot issue 14): a faint click near each apex of the flight (a tennis
ball's recording had one about 40 dB under the impacts, midway between each pair of them), a
steady periodic click after the ball has come to rest (about every 0.09 s), and rings with
bursts of their own inside them (a ping-pong ball's ring swells again a few ms after the
impact, louder than the impact's first burst once the impacts grow quiet).

References
----------
.. [1] K. van den Doel, P. G. Kry and D. K. Pai, "FoleyAutomatic: physically-based sound
   effects for interactive simulation and animation", Proc. SIGGRAPH 2001, pp. 537-544
   (impact sounds as sums of damped modes excited by the contact force).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import soundfile as sf
from scipy import signal

from ..atomic import atomic_path

__all__ = ["impact_sound", "write_audio", "AUDIO_FORMATS"]

# Modes of the direct impact sound: frequency (Hz), decay time (s), relative weight. A small
# hard ball on a table rings at a few kHz for a few ms.
_DIRECT_MODES = np.array([[2000.0, 3.0e-3, 1.0],
                          [3300.0, 1.8e-3, 0.7],
                          [4900.0, 1.1e-3, 0.5]])
# The ringing secondary transient (e.g. the ball's shell or the table top answering later) is
# lower and longer.
_RING_MODES = np.array([[1100.0, 4.0e-3, 1.0],
                        [1800.0, 2.5e-3, 0.6]])
_ECHO_CUTOFF_HZ = 2500.0  # a wall reflection loses the highs: one-pole low-pass
_FREQUENCY_JITTER = 0.03  # relative scatter of the mode frequencies from impact to impact
_PEAK_GRID_STEP = 2e-6  # s, grid on which the continuous-time peak of a transient is found
_PEAK_SEARCH_DECAYS = 1.5  # ... over this many decay times of the slowest mode (the sum of
# decaying modes peaks within its first cycles: its envelope is below a quarter of the first
# lobe after 1.5 decay times)
_NOISE_COLORS = ("white", "pink")
_APEX_JITTER = 0.05  # the apex click falls within ±5 % of the flight time of the midpoint
_DISTURBANCE_STREAM = 14  # second key of the generator of the disturbances (see impact_sound)

AUDIO_FORMATS = {".wav": "WAV", ".flac": "FLAC", ".ogg": "OGG"}
"""File suffixes understood by :func:`write_audio` and the libsndfile format each means."""


def _check_array(name, value, *, positive=False, nonnegative=False):
    array = np.atleast_1d(np.asarray(value, dtype=float))
    if array.ndim != 1 or array.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D sequence; got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite; got {value!r}")
    if positive and np.any(array <= 0):
        raise ValueError(f"{name} must be > 0; got {value!r}")
    if nonnegative and np.any(array < 0):
        raise ValueError(f"{name} must be >= 0; got {value!r}")
    return array


def _render(onsets, amplitudes, modes, rng, sample_rate, n_samples):
    """Sum of modal transients starting at `onsets` (s) with peak values `amplitudes`.

    Each transient is evaluated in continuous time at the sample instants, so its onset lies
    exactly at the given time, between samples in general. Its peak over continuous time (not
    just over the samples) equals the amplitude.
    """
    if onsets.size == 0:
        return np.zeros(n_samples)
    # Modes too close to the Nyquist frequency cannot be sampled; a real ADC filters them out.
    modes = modes[modes[:, 0] < 0.45 * sample_rate]
    if modes.shape[0] == 0:
        raise ValueError(f"sample_rate {sample_rate} Hz is too low for modes of a few kHz")
    n_modes = modes.shape[0]
    # Each impact excites the modes a little differently: jittered frequencies and weights.
    freqs = modes[:, 0] * np.exp(_FREQUENCY_JITTER * rng.standard_normal((onsets.size, n_modes)))
    weights = modes[:, 2] * rng.uniform(0.6, 1.0, (onsets.size, n_modes))
    decays = np.broadcast_to(modes[:, 1], freqs.shape)

    def shape(tau):  # tau: (impacts, points) time since onset (s), zero before the onset
        t = np.maximum(tau, 0.0)[..., None]
        waves = weights[:, None, :] * np.exp(-t / decays[:, None, :]) * np.sin(
            2 * np.pi * freqs[:, None, :] * t)
        return np.where(tau >= 0.0, waves.sum(axis=-1), 0.0)

    # Peak of each transient over continuous time: it falls within the first few ms.
    grid = np.arange(0.0, _PEAK_SEARCH_DECAYS * modes[:, 1].max(), _PEAK_GRID_STEP)
    peaks = np.abs(shape(np.broadcast_to(grid, (onsets.size, grid.size)))).max(axis=1)
    gains = amplitudes / peaks

    support = int(np.ceil(8.0 * modes[:, 1].max() * sample_rate)) + 2  # e^-8 of the slowest mode
    first = np.floor(onsets * sample_rate).astype(np.int64)
    index = first[:, None] + np.arange(support)
    tau = index / sample_rate - onsets[:, None]
    values = gains[:, None] * shape(tau)
    inside = (index >= 0) & (index < n_samples)
    return np.bincount(index[inside], weights=values[inside], minlength=n_samples)


def _noise(rng, n_samples, color, sample_rate):
    """Gaussian noise of unit RMS: white, or pink (power ∝ 1/f above 20 Hz)."""
    white = rng.standard_normal(n_samples)
    if color == "pink":
        spectrum = np.fft.rfft(white)
        freqs = np.fft.rfftfreq(n_samples, 1.0 / sample_rate)
        spectrum /= np.sqrt(np.maximum(freqs, 20.0) / 20.0)
        spectrum[0] = 0.0
        white = np.fft.irfft(spectrum, n_samples)
    white -= white.mean()
    return white / np.sqrt(np.mean(white**2))


def impact_sound(impact_times, impact_speeds, *, sample_rate=44100, duration=None, lead_in=0.2,
                 snr_db=40.0, ring_delay=0.02, ring_level=0.3, echo_delay=None, echo_level=0.0,
                 clip_level=None, dc_offset=0.0, seed=0, peak_level=0.5, speed_exponent=1.0,
                 noise_color="white", apex_click_db=None, rest_click_period=None,
                 rest_click_level=0.5, rest_click_duration=1.0, burst_delays=(),
                 burst_levels=(), hum_level=0.0, hum_hz=50.0, hum_harmonics=1):
    """Microphone signal of a bounce train, and the true onset of every impact transient.

    Parameters
    ----------
    impact_times : array_like
        Impact times in s, relative to the start of the train (e.g.
        ``dashpot.bounce_sequence(...).impact_times``, first impact at 0).
    impact_speeds : array_like
        Impact speeds in m/s, > 0, one per impact. Only their ratios matter: the peak amplitude
        of impact i is ``peak_level * (v_i / max v) ** speed_exponent``.
    sample_rate : int, default 44100
        Samples per second (Hz), >= 8000.
    duration : float, optional
        Length of the recording in s. Default: the last onset plus enough time for its
        transient, ringing and echo to die away.
    lead_in : float, default 0.2
        Time in s before the first impact (noise only); onsets are ``lead_in + impact_times``.
    snr_db : float, default 40
        Signal-to-noise ratio of the loudest impact in dB: 20·log10(peak / noise RMS), with the
        peak of the loudest direct transient and the RMS of the added noise (full scale = 1).
        Quieter impacts have proportionally lower SNR.
    ring_delay : float, default 0.02
        Delay in s of the ringing secondary transient after each impact.
    ring_level : float, default 0.3
        Peak of the ringing transient relative to its impact (0 disables it).
    echo_delay : float, optional
        Delay in s of an echo of each impact (e.g. from a wall 10-25 m away: 60-150 ms).
        None (default) means no echo.
    echo_level : float, default 0
        Peak of the echo relative to its impact (before its low-pass, which lowers it a little).
    clip_level : float, optional
        Symmetric clipping of the total signal at ±clip_level (full scale = 1), as an
        overdriven preamplifier or ADC does. None: no clipping.
    dc_offset : float, default 0
        Constant added to the signal (full scale = 1).
    seed : int, default 0
        Seed of the ``numpy.random.Generator`` drawing the noise and the per-impact timbre; the
        output is a deterministic function of all arguments.
    peak_level : float, default 0.5
        Peak amplitude of the loudest direct transient (full scale = 1).
    speed_exponent : float, default 1
        Exponent p of the amplitude law ∝ v^p. For a linear spring-dashpot contact the peak
        force, and so the radiated pressure, is proportional to the impact speed (p = 1).
    noise_color : {"white", "pink"}, default "white"
        Spectrum of the Gaussian background noise (pink: power ∝ 1/f above 20 Hz).
    apex_click_db : float, optional
        Level (dB, e.g. −40) of a faint click near the apex of every flight, relative to the
        geometric mean of the peaks of the two impacts around it; it falls at the midpoint of
        the flight ±5 % of its duration (uniform). None (default): no apex clicks.
    rest_click_period : float, optional
        Period (s, e.g. 0.09) of a steady click heard after the ball has come to rest (a
        clock, a fan, a relay), starting one period after the last impact, ±2 % jitter per
        click. None (default): no such tail.
    rest_click_level : float, default 0.5
        Peak of each rest click relative to the last impact's peak.
    rest_click_duration : float, default 1
        Length (s) of the tail of rest clicks; `duration` is lengthened to hold it.
    burst_delays, burst_levels : sequence of float, default ()
        Bursts inside each impact's ring: the direct modes excited again `burst_delays` (s)
        after the impact's onset with peaks `burst_levels` × the impact's peak (may exceed 1:
        the swell of a ring can be louder than its first burst). The impact's onset is the
        start of its first burst.
    hum_level : float, default 0
        Amplitude (full scale) of mains hum: a sine of `hum_hz` and, for a buzz, its
        harmonics k = 2 ... `hum_harmonics` at amplitude `hum_level` / k (phase k rad each).
        0 (default): no hum.
    hum_hz : float, default 50
        Mains frequency (Hz): 50 or 60, or a little off.
    hum_harmonics : int, default 1
        Number of hum lines (1: a pure hum).

    Returns
    -------
    samples : ndarray of float64, shape (n,)
        The signal, full scale = 1 (values may exceed 1 unless clipped).
    onset_times : ndarray of float64
        True onset of each impact transient in s on the timeline of `samples` (sample k is at
        k / sample_rate): the instant the transient starts, between samples in general. Apex
        clicks, rest clicks and ring bursts are not impacts and are not listed.

    Notes
    -----
    A direct transient is Σ_k w_k exp(−τ/T_k) sin(2π f_k τ) for τ >= 0 and 0 before, with three
    modes near 2.0, 3.3 and 4.9 kHz (T = 3.0, 1.8, 1.1 ms) whose frequencies (±3 %) and weights
    vary from impact to impact; modes above 0.45·sample_rate are left out. It is scaled so that
    its peak over continuous time is the impact's amplitude. The ringing transient has two
    lower modes (1.1, 1.8 kHz); the echo is a copy of the direct transient low-passed at
    2.5 kHz (one-pole). Apex clicks, rest clicks and ring bursts are direct transients too
    (the same modes): only their loudness and timing tell them from impacts. Their random
    draws come from a generator of their own (keyed by `seed` and a constant), so that adding
    them leaves the rest of the signal, noise included, unchanged. References: modal synthesis
    of contact sounds [1]_.
    """
    times = _check_array("impact_times", impact_times)
    speeds = _check_array("impact_speeds", impact_speeds, positive=True)
    if speeds.shape != times.shape:
        raise ValueError(f"impact_times and impact_speeds must have the same length; got "
                         f"{times.size} and {speeds.size}")
    if int(sample_rate) != sample_rate or sample_rate < 8000:
        raise ValueError(f"sample_rate must be an integer >= 8000 Hz; got {sample_rate!r}")
    sample_rate = int(sample_rate)
    for name, value in (("lead_in", lead_in), ("ring_delay", ring_delay),
                        ("ring_level", ring_level), ("echo_level", echo_level)):
        _check_array(name, value, nonnegative=True)
    for name, value in (("peak_level", peak_level), ("speed_exponent", speed_exponent)):
        _check_array(name, value, positive=True)
    _check_array("snr_db", snr_db)
    _check_array("dc_offset", dc_offset)
    if echo_delay is not None:
        _check_array("echo_delay", echo_delay, positive=True)
    if clip_level is not None:
        _check_array("clip_level", clip_level, positive=True)
    if noise_color not in _NOISE_COLORS:
        raise ValueError(f"noise_color must be one of {_NOISE_COLORS}; got {noise_color!r}")
    _check_array("hum_level", hum_level, nonnegative=True)
    _check_array("hum_hz", hum_hz, positive=True)
    if int(hum_harmonics) != hum_harmonics or hum_harmonics < 1:
        raise ValueError(f"hum_harmonics must be a whole number >= 1; got {hum_harmonics!r}")
    if apex_click_db is not None:
        _check_array("apex_click_db", apex_click_db)
    if rest_click_period is not None:
        _check_array("rest_click_period", rest_click_period, positive=True)
        _check_array("rest_click_level", rest_click_level, positive=True)
        _check_array("rest_click_duration", rest_click_duration, positive=True)
    burst_delays = np.asarray(burst_delays, dtype=float).ravel()
    burst_levels = np.asarray(burst_levels, dtype=float).ravel()
    if burst_delays.shape != burst_levels.shape:
        raise ValueError(f"burst_delays and burst_levels must have the same length; got "
                         f"{burst_delays.size} and {burst_levels.size}")
    if burst_delays.size:
        _check_array("burst_delays", burst_delays, positive=True)
        _check_array("burst_levels", burst_levels, positive=True)

    onsets = lead_in + times
    if np.any(onsets < 0):
        raise ValueError("lead_in + impact_times must be >= 0 (an onset before the recording)")
    tail = 8.0 * max(_DIRECT_MODES[:, 1].max(), _RING_MODES[:, 1].max()) + ring_delay
    if echo_delay is not None:
        tail += echo_delay
    if burst_delays.size:
        tail += burst_delays.max()
    if rest_click_period is not None:
        tail += rest_click_duration
    if duration is None:
        duration = float(onsets.max()) + tail + 0.05
    _check_array("duration", duration, positive=True)
    if onsets.max() >= duration:
        raise ValueError(f"duration {duration} s ends before the last onset at {onsets.max()} s")
    n_samples = int(round(duration * sample_rate))

    rng = np.random.default_rng(seed)
    amplitudes = peak_level * (speeds / speeds.max()) ** speed_exponent
    samples = _render(onsets, amplitudes, _DIRECT_MODES, rng, sample_rate, n_samples)
    if ring_level > 0:
        samples += _render(onsets + ring_delay, ring_level * amplitudes, _RING_MODES, rng,
                           sample_rate, n_samples)
    if echo_delay is not None and echo_level > 0:
        echo = _render(onsets + echo_delay, echo_level * amplitudes, _DIRECT_MODES, rng,
                       sample_rate, n_samples)
        # One-pole low-pass y[n] = (1 − a) x[n] + a y[n−1]: causal, so the echo starts on time.
        pole = np.exp(-2 * np.pi * _ECHO_CUTOFF_HZ / sample_rate)
        samples += signal.lfilter([1.0 - pole], [1.0, -pole], echo)
    samples += _disturbances(onsets, amplitudes, np.random.default_rng(
        [int(seed), _DISTURBANCE_STREAM]), sample_rate, n_samples, apex_click_db,
        rest_click_period, rest_click_level, rest_click_duration, burst_delays, burst_levels)
    noise_rms = peak_level * 10.0 ** (-float(snr_db) / 20.0)
    samples += noise_rms * _noise(rng, n_samples, noise_color, sample_rate)
    if hum_level > 0:
        harmonic = np.arange(1, int(hum_harmonics) + 1)
        time = np.arange(n_samples) / sample_rate
        samples += hum_level * np.sum(np.sin(2.0 * np.pi * hum_hz * harmonic[:, None]
                                             * time[None, :] + harmonic[:, None])
                                      / harmonic[:, None], axis=0)
    samples += dc_offset
    if clip_level is not None:
        samples = np.clip(samples, -clip_level, clip_level)
    return samples, onsets


def _disturbances(onsets, amplitudes, rng, sample_rate, n_samples, apex_click_db,
                  rest_click_period, rest_click_level, rest_click_duration, burst_delays,
                  burst_levels):
    """Apex clicks, rest clicks and ring bursts (see :func:`impact_sound`), summed."""
    times, levels = [np.zeros(0)], [np.zeros(0)]
    if apex_click_db is not None and onsets.size > 1:
        flights = np.diff(onsets)
        times.append(onsets[:-1] + flights * (0.5 + rng.uniform(-_APEX_JITTER, _APEX_JITTER,
                                                                  flights.size)))
        levels.append(10.0 ** (apex_click_db / 20.0) * np.sqrt(amplitudes[:-1] * amplitudes[1:]))
    if rest_click_period is not None:
        count = int(rest_click_duration / rest_click_period)
        steps = rest_click_period * (1.0 + 0.02 * rng.uniform(-1.0, 1.0, count))
        times.append(onsets[-1] + np.cumsum(steps))
        levels.append(np.full(count, rest_click_level * amplitudes[-1]))
    for delay, level in zip(burst_delays, burst_levels):
        times.append(onsets + delay)
        levels.append(level * amplitudes)
    times, levels = np.concatenate(times), np.concatenate(levels)
    inside = times < n_samples / sample_rate
    return _render(times[inside], levels[inside], _DIRECT_MODES, rng, sample_rate, n_samples)


def _subtype_bits(subtype):
    """Bits per sample of an integer PCM subtype, None for float or compressed subtypes."""
    digits = "".join(ch for ch in subtype if ch.isdigit())
    return int(digits) if subtype.startswith("PCM") and digits else None


def write_audio(path, samples, sample_rate, *, subtype="PCM_16", channels=1, format=None,
                overwrite=False):
    """Write a recording as WAV, FLAC or OGG, atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Destination. Its suffix (.wav, .flac, .ogg) gives the format unless `format` is given.
    samples : array_like
        Signal, full scale = 1: shape (n,) for a mono signal (mixed into `channels` channels),
        or (n, channels) to write the channels as they are.
    sample_rate : int
        Samples per second (Hz).
    subtype : str, default "PCM_16"
        libsndfile subtype: "PCM_U8" (WAV), "PCM_S8" (FLAC), "PCM_16", "PCM_24", "PCM_32",
        "FLOAT", "DOUBLE" (WAV). OGG holds only lossy codecs: for it a PCM subtype means
        "VORBIS"; "OPUS" (sample rates 8, 12, 16, 24, 48 kHz) may be asked for explicitly.
    channels : int, default 1
        Number of channels written. A mono signal is mixed into them as a pair of microphones
        at different distances would record it: channel k has gain 0.8^k and is delayed by
        3k samples (a path about 2.3k cm longer at 44.1 kHz).
    format : {"WAV", "FLAC", "OGG"}, optional
        Container; default from the suffix of `path`.
    overwrite : bool, default False
        Replace `path` if it exists.

    Returns
    -------
    pathlib.Path
        The written file.

    Raises
    ------
    InputError
        `path` exists and `overwrite` is false ("<path>: exists; pass overwrite=True to
        replace it"); the file is left as it was.

    Notes
    -----
    The file is written under a temporary name in the destination folder and moved into
    place (:func:`dashpot.atomic.atomic_path`), so a reader never sees a half-written file. Integer
    subtypes cannot hold values beyond full scale: they are clipped to [−1, 1] first, as a
    recorder would.
    """
    path = Path(path)
    if format is None:
        format = AUDIO_FORMATS.get(path.suffix.lower())
        if format is None:
            raise ValueError(f"cannot tell the format of {path}: use a suffix among "
                             f"{sorted(AUDIO_FORMATS)} or pass format=")
    format = format.upper()
    if format not in AUDIO_FORMATS.values():
        raise ValueError(f"format must be one of {sorted(AUDIO_FORMATS.values())}; got {format!r}")
    subtype = subtype.upper()
    if format == "OGG" and subtype not in ("VORBIS", "OPUS"):
        subtype = "VORBIS"
    if not sf.check_format(format, subtype):
        raise ValueError(f"{format} cannot hold subtype {subtype!r}; it can hold "
                         f"{sorted(sf.available_subtypes(format))}")
    if int(sample_rate) != sample_rate or sample_rate <= 0:
        raise ValueError(f"sample_rate must be a positive integer; got {sample_rate!r}")
    if int(channels) != channels or channels < 1:
        raise ValueError(f"channels must be a positive integer; got {channels!r}")

    data = np.asarray(samples, dtype=float)
    if data.ndim == 1:
        # A common source heard at different distances: weaker and later on each channel.
        delays = 3 * np.arange(int(channels))
        gains = 0.8 ** np.arange(int(channels))
        padded = np.concatenate([np.zeros(delays[-1]), data])
        data = np.stack([gain * padded[delays[-1] - delay:padded.size - delay]
                         for gain, delay in zip(gains, delays)], axis=1)
    elif data.ndim != 2 or data.shape[1] != channels:
        raise ValueError(f"samples must have shape (n,) or (n, channels={channels}); got "
                         f"{data.shape}")
    if not np.all(np.isfinite(data)):
        raise ValueError("samples must be finite")
    if _subtype_bits(subtype) is not None or subtype in ("VORBIS", "OPUS"):
        data = np.clip(data, -1.0, 1.0)

    # The format is given: the temporary's name has no suffix.
    with atomic_path(path, overwrite=overwrite) as temporary:
        sf.write(temporary, data, int(sample_rate), subtype=subtype, format=format)
    return path
