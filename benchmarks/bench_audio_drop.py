"""Speed of ``dashpot.ingest.audio.detect_impacts`` on the real bouncy-ball drop (issue 14).

Prints one table: CPU seconds and the real-time factor (seconds of recording analysed per CPU
second, best of five runs, time.process_time, one BLAS thread) of the detector on the stereo
48 kHz 16-bit 12.8 s drop in ``../shared/data/bouncy-ball-pfe``, against the target of 300×
and against two named baselines run on the same file, which bound what any detector pays:

* "decode": reading the file with soundfile (float64);
* "decode + high-pass + 20 % threshold": decoding, the 100 Hz causal high-pass the detector
  also applies, and the plain onset "first sample above 20 % of the impact's peak" at the
  impacts the detector found (the baseline of the interval-scatter tests).

The ratio column is the detector's time over each baseline's. Without ``../shared/data`` the
script says so and exits 0. Pin the process to one core (``taskset -c 1``) on a shared machine.

Run with ``python benchmarks/bench_audio_drop.py``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core, before numpy loads BLAS
os.environ.setdefault("OMP_NUM_THREADS", "1")

from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import soundfile as sf  # noqa: E402
from scipy import signal  # noqa: E402

from dashpot.ingest.audio import detect_impacts  # noqa: E402
from timing import best_cpu  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BOUNCY = ROOT / ".." / "shared" / "data" / "bouncy-ball-pfe" / "drop_0.9m.wav"
TARGET = 300.0
REPEATS = 5


def decode(path):
    return sf.read(str(path), always_2d=True)


def threshold_baseline(path, times, fraction=0.2):
    """Decode, high-pass at 100 Hz, first sample over `fraction` of each impact's peak (s)."""
    samples, rate = decode(path)
    sos = signal.butter(2, 100.0, "highpass", fs=rate, output="sos")
    magnitude = np.abs(signal.sosfilt(sos, samples, axis=0)).max(axis=1)
    starts = np.round(times * rate).astype(int) - int(2e-3 * rate)
    windows = magnitude[starts[:, None] + np.arange(int(6e-3 * rate))]
    above = windows >= fraction * windows.max(axis=1, keepdims=True)
    return (starts + above.argmax(axis=1)) / rate


def main():
    if not BOUNCY.exists():
        print(f"{BOUNCY} not found: the real recordings are not available; nothing measured")
        return
    duration = sf.info(str(BOUNCY)).duration
    detector, table = best_cpu(lambda: detect_impacts(BOUNCY), repeats=REPEATS)
    times = table["time"].to_numpy()
    rows = [("dashpot detect_impacts", detector),
            ("decode", best_cpu(lambda: decode(BOUNCY), repeats=REPEATS)[0]),
            ("decode + high-pass + 20 % threshold",
             best_cpu(lambda: threshold_baseline(BOUNCY, times), repeats=REPEATS)[0])]
    print(f"bouncy-ball drop: {duration:.1f} s, stereo 48 kHz 16-bit, {len(table)} impacts; "
          f"target >= {TARGET:.0f}x real time on one core")
    print(f"{'method':<38} {'CPU s':>8} {'x real time':>12} {'detector / this':>16}")
    for name, seconds in rows:
        print(f"{name:<38} {seconds:>8.4f} {duration / seconds:>11.0f}x "
              f"{detector / seconds:>15.2f}x")
    verdict = "meets" if duration / detector >= TARGET else "misses"
    print(f"detector: {duration / detector:.0f}x real time, {verdict} the {TARGET:.0f}x target")


if __name__ == "__main__":
    main()
