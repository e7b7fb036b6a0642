"""Peak envelope of a sound recording, for drawing it with the detected impacts.

The envelope here is for display only (the impact detector of :mod:`dashpot.ingest.audio` has
its own, noise-whitened statistic): the largest absolute sample of any channel, after removing
each channel's mean (DC offset), in consecutive windows of fixed length. A window of 1 ms keeps
every impact transient visible while a 10-minute recording reduces to 600 000 points.

Files are read in blocks (:func:`recording_envelope`, :func:`channel_extremes`), keeping only
the smallest and largest sample of each window or run: an hour of 44.1 kHz mono needs some
100 MB instead of the 1.3 GB of its samples as float64.
"""

from __future__ import annotations

import numpy as np

from ._validation import check_positive

__all__ = ["peak_envelope", "recording_envelope", "channel_extremes"]


def _window_extremes(data, size):
    """Smallest and largest value of each column in consecutive windows of `size` rows.

    The last window may be shorter; it is padded with its own last row, which changes neither.
    Returns two arrays of shape (windows, columns).
    """
    count = -(-data.shape[0] // size)
    short = count * size - data.shape[0]
    if short:
        data = np.concatenate([data, np.repeat(data[-1:], short, axis=0)])
    windows = data.reshape(count, size, data.shape[1])
    return windows.min(axis=1), windows.max(axis=1)


def _envelope_from_extremes(low, high, mean):
    """max |x − mean| over a window and the channels, from its extremes per channel."""
    return np.maximum(high - mean, mean - low).max(axis=1)


def _window_centres(count, size, frames, sample_rate):
    starts = np.arange(count) * size
    stops = np.minimum(starts + size, frames)
    return 0.5 * (starts + stops - 1) / sample_rate


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
    size = max(1, int(round(window * sample_rate)))
    low, high = _window_extremes(data, size)
    envelope = _envelope_from_extremes(low, high, data.mean(axis=0))
    return _window_centres(envelope.size, size, data.shape[0], sample_rate), envelope


def recording_envelope(path, *, window=1e-3, block_seconds=10.0):
    """Peak envelope of an audio file (WAV, FLAC, OGG), read in blocks, and its loudest channel.

    Parameters
    ----------
    path : str or os.PathLike
    window : float, default 1e-3
        Envelope window in s.
    block_seconds : float, default 10
        Length of the blocks the file is read in (s); memory holds one block and two numbers
        per window and channel, whatever the length of the recording.

    Returns
    -------
    time, envelope : ndarray
        As :func:`peak_envelope` of the whole recording.
    loudest : int
        The channel with the largest absolute sample (for the close-up of
        :func:`dashpot.plots.detection_figure`, see :func:`channel_extremes`).
    sample_rate : int
        Hz.

    Raises
    ------
    InputError
        The file cannot be read as audio.
    """
    from .ingest.audio import _blocks, _open

    window = float(check_positive("window", window))
    block_seconds = float(check_positive("block_seconds", block_seconds))
    lows, highs = [], []
    with _open(path) as handle:
        sample_rate = int(handle.samplerate)
        size = max(1, int(round(window * sample_rate)))
        # Whole windows per block, so that no window straddles two blocks.
        block_frames = size * max(1, int(round(block_seconds * sample_rate)) // size)
        total, frames = np.zeros(handle.channels), 0
        for block in _blocks(handle, path, block_frames):
            low, high = _window_extremes(block, size)
            lows.append(low)
            highs.append(high)
            total += block.sum(axis=0)
            frames += block.shape[0]
    low, high = np.concatenate(lows), np.concatenate(highs)
    envelope = _envelope_from_extremes(low, high, total / frames)
    loudest = int(np.argmax(np.maximum(np.abs(low), np.abs(high)).max(axis=0)))
    return (_window_centres(envelope.size, size, frames, sample_rate), envelope, loudest,
            sample_rate)


def channel_extremes(path, channel, start, stop, *, columns=2000, block_seconds=10.0):
    """One channel's samples between two times, reduced to the extremes of `columns` runs.

    The samples from `start` to `stop` are split into at most `columns` runs of equal count
    (the last one shorter); each run gives its smallest and largest sample, in time order,
    so the curve through them draws the same picture as all the samples at that width.
    With at most 2·`columns` samples in the span, all of them are returned. The file is read
    in blocks: a long span costs no more memory than a short one.

    Parameters
    ----------
    path : str or os.PathLike
        Audio file.
    channel : int
        Channel index.
    start, stop : float
        Span in s (clipped to the recording).
    columns : int, default 2000
    block_seconds : float, default 10

    Returns
    -------
    time : ndarray
        Time of each returned sample in s (first sample of the file at t = 0).
    samples : ndarray
        Their values (full scale = 1).
    """
    from .ingest.audio import _open

    with _open(path) as handle:
        sample_rate = int(handle.samplerate)
        first = min(max(0, int(np.floor(start * sample_rate))), handle.frames)
        last = min(handle.frames, max(first, int(np.ceil(stop * sample_rate)) + 1))
        count = last - first
        per = 1 if count <= 2 * columns else -(-count // columns)
        block_frames = per * max(1, int(round(block_seconds * sample_rate)) // per)
        handle.seek(first)
        times, values, done = [], [], 0
        while done < count:
            block = handle.read(min(block_frames, count - done), dtype="float64",
                                always_2d=True)[:, channel]
            if block.size == 0:
                break
            if per == 1:
                index = np.arange(block.size)
            else:
                runs = -(-block.size // per)
                padded = np.concatenate([block, np.full(runs * per - block.size, block[-1])])
                shaped = padded.reshape(runs, per)
                low, high = np.argmin(shaped, axis=1), np.argmax(shaped, axis=1)
                base = np.arange(runs) * per
                index = np.stack([base + np.minimum(low, high), base + np.maximum(low, high)],
                                 axis=1).ravel()
                index = np.minimum(index, block.size - 1)
            times.append((first + done + index) / sample_rate)
            values.append(block[index])
            done += block.size
    if not times:
        return np.zeros(0), np.zeros(0)
    return np.concatenate(times), np.concatenate(values)
