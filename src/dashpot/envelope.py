"""Peak envelope of a sound recording, for drawing it with the detected impacts.

The envelope here is for display only (the impact detector of :mod:`dashpot.ingest.audio` has
its own, noise-whitened statistic): the largest absolute sample of any channel, after removing
each channel's mean (DC offset), in consecutive windows of fixed length. A window of 1 ms keeps
every impact transient visible while a 10-minute recording reduces to 600 000 points.
"""

from __future__ import annotations

import numpy as np

from ._validation import check_positive

__all__ = ["peak_envelope", "recording_envelope"]


def peak_envelope(samples, sample_rate, *, window=1e-3):
    """Largest absolute sample over channels in consecutive windows.

    Parameters
    ----------
    samples : array_like, shape (frames,) or (frames, channels)
        Recording in full-scale units (1 = the recorder's full scale).
    sample_rate : float
        Samples per second (Hz), > 0.
    window : float, default 1e-3
        Window length in s, > 0 (at least one sample).

    Returns
    -------
    time : ndarray
        Centre of each window in s (first sample at t = 0).
    envelope : ndarray
        max |x − mean(x)| over the window's samples and the channels (full-scale units).
    """
    sample_rate = float(check_positive("sample_rate", sample_rate))
    window = float(check_positive("window", window))
    data = np.asarray(samples, dtype=float)
    if data.ndim == 1:
        data = data[:, None]
    if data.ndim != 2 or data.shape[0] == 0:
        raise ValueError(f"samples must be a non-empty (frames,) or (frames, channels) array; "
                         f"got shape {np.shape(samples)}")
    peak = np.max(np.abs(data - data.mean(axis=0)), axis=1)
    size = max(1, int(round(window * sample_rate)))
    count = -(-peak.size // size)
    padded = np.zeros(count * size)
    padded[:peak.size] = peak
    envelope = padded.reshape(count, size).max(axis=1)
    starts = np.arange(count) * size
    stops = np.minimum(starts + size, peak.size)
    time = 0.5 * (starts + stops - 1) / sample_rate
    return time, envelope


def recording_envelope(path, *, window=1e-3):
    """Envelope and the loudest channel of an audio file (WAV, FLAC, OGG).

    Parameters
    ----------
    path : str or os.PathLike
    window : float, default 1e-3
        Envelope window in s.

    Returns
    -------
    time, envelope : ndarray
        As :func:`peak_envelope`.
    sample_time, channel : ndarray
        Time of every sample in s and the samples of the channel with the largest peak (for
        the close-up of :func:`dashpot.plots.detection_figure`).

    Raises
    ------
    InputError
        The file cannot be read as audio.
    """
    from .ingest.audio import read_audio

    samples, sample_rate = read_audio(path)
    time, envelope = peak_envelope(samples, sample_rate, window=window)
    loudest = int(np.argmax(np.max(np.abs(samples), axis=0)))
    channel = samples[:, loudest]
    return time, envelope, np.arange(channel.size) / sample_rate, channel
