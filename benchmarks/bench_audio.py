"""Speed and accuracy of ``dashpot.ingest.audio.detect_impacts`` on 48 kHz recordings.

Prints one table. Rows: dashpot's detector, and two simple baselines run on the same files:

* "phyphox-like": the loudest sample of every 0.1 s buffer above a threshold, then a fixed
  dead time of 0.1 s, stopping after six impacts (how phyphox's acoustic stopwatch times
  bounces);
* "frame onsets": a spectral-flux onset detector on 1024-sample frames, hop 512 (10.7 ms at
  48 kHz), peak-picked: the frame-quantised approach of general-purpose onset detectors.

Columns: the real-time factor (seconds of recording analysed per CPU second, best of three
runs, five on the real recording, time.process_time, one BLAS thread) against the target of
200, and on the synthetic recording
the recall within 2 ms and the median timing error against the known onsets. Workloads: a
60 s mono 48 kHz recording (16-bit WAV) holding one bounce train with ringing and an echo, and
the real 12.8 s stereo 48 kHz 16-bit bouncy-ball drop (rattle-heavy: about 290 transients for
some 50 impacts) when ../shared/data is present; without it that row is skipped with a message.
Pin the process to one core (``taskset -c 1``) on a shared machine.

Run with ``make bench`` or ``python benchmarks/bench_audio.py``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core, before numpy loads BLAS
os.environ.setdefault("OMP_NUM_THREADS", "1")

import math  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import soundfile as sf  # noqa: E402
from scipy import signal  # noqa: E402

import dashpot  # noqa: E402
from dashpot.ingest.audio import detect_impacts  # noqa: E402
from dashpot.synth.audio import impact_sound, write_audio  # noqa: E402
from timing import best_cpu  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BOUNCY = ROOT / ".." / "shared" / "data" / "bouncy-ball-pfe" / "drop_0.9m.wav"
RATE = 48000
TARGET = 200.0


def phyphox_like(path, dead_time=0.1, max_impacts=6):
    """Loudest sample per 0.1 s buffer over 10x the median level, fixed dead time, six impacts."""
    samples, rate = sf.read(str(path), always_2d=True)
    level = np.abs(samples).max(axis=1)
    buffer = int(0.1 * rate)
    n = level.size // buffer
    blocks = level[: n * buffer].reshape(n, buffer)
    peaks = blocks.argmax(axis=1) + np.arange(n) * buffer
    loud = blocks.max(axis=1) > 10 * np.median(level)
    times, last = [], -math.inf
    for t in peaks[loud] / rate:
        if t - last >= dead_time and len(times) < max_impacts:
            times.append(t)
            last = t
    return np.array(times)


def frame_onsets(path, frame=1024, hop=512):
    """Spectral-flux onsets at frame resolution (times of the frame centres)."""
    samples, rate = sf.read(str(path), always_2d=True)
    mono = samples.mean(axis=1)
    _, times, spectrum = signal.stft(mono, fs=rate, nperseg=frame, noverlap=frame - hop,
                                     boundary=None, padded=False)
    magnitude = np.log1p(100 * np.abs(spectrum))
    flux = np.maximum(np.diff(magnitude, axis=1), 0).sum(axis=0)
    threshold = np.median(flux) + 3 * np.median(np.abs(flux - np.median(flux))) * 1.4826 * 3
    peaks, _ = signal.find_peaks(flux, height=threshold, distance=2)
    return times[1:][peaks]


def scores(found, truth, tolerance=2e-3):
    if found.size == 0:
        return 0.0, math.nan
    error = found[np.abs(truth[:, None] - found[None, :]).argmin(axis=1)] - truth
    within = np.abs(error) < tolerance
    return within.mean(), (np.median(np.abs(error[within])) if within.any() else math.nan)


def synthetic_recording(folder):
    sequence = dashpot.bounce_sequence("hybrid", beta=80.0, omega0=3000.0, g=9.81, v0=1.5,
                                       n_max=400, v_min=0.03)
    samples, onsets = impact_sound(sequence.impact_times, sequence.impact_speeds,
                                   sample_rate=RATE, duration=60.0, lead_in=2.0, snr_db=55.0,
                                   echo_delay=0.09, echo_level=0.4, seed=1)
    return write_audio(Path(folder) / "train_48k.wav", samples, RATE), onsets


def main():
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        path, onsets = synthetic_recording(folder)
        duration = sf.info(str(path)).duration
        for name, method in (("dashpot detect_impacts", lambda: detect_impacts(path)["time"]
                              .to_numpy()),
                             ("phyphox-like (0.1 s dead time)", lambda: phyphox_like(path)),
                             ("frame onsets (1024/512)", lambda: frame_onsets(path))):
            seconds, found = best_cpu(method)
            recall, median = scores(found, onsets)
            rows.append(("synthetic 60 s mono", name, duration / seconds, recall, median))
    skipped = None
    if BOUNCY.exists():
        # No onset truth for the real drop: speed only, against the same baselines.
        duration = sf.info(str(BOUNCY)).duration
        for name, method in (("dashpot detect_impacts", lambda: detect_impacts(BOUNCY)),
                             ("phyphox-like (0.1 s dead time)", lambda: phyphox_like(BOUNCY)),
                             ("frame onsets (1024/512)", lambda: frame_onsets(BOUNCY))):
            seconds, _ = best_cpu(method, repeats=5)
            rows.append(("bouncy ball 12.8 s stereo", name, duration / seconds, math.nan,
                         math.nan))
    else:
        skipped = f"bouncy-ball recording not found ({BOUNCY}): its row is skipped"
    print(f"Real-time factor on one core (target >= {TARGET:.0f}x at 48 kHz); accuracy against "
          f"the synthetic onsets (recall within 2 ms, median |error| of those)")
    print(f"{'recording':<26} {'method':<32} {'x real time':>11} {'recall':>7} "
          f"{'median |err|':>13}")
    for recording, name, factor, recall, median in rows:
        recall_text = "-" if math.isnan(recall) else f"{recall:.3f}"
        median_text = "-" if math.isnan(median) else f"{median * 1e6:.1f} us"
        print(f"{recording:<26} {name:<32} {factor:>10.0f}x {recall_text:>7} {median_text:>13}")
    if skipped:
        print(skipped)


if __name__ == "__main__":
    main()
