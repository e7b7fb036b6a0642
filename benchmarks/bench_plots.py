"""Speed of the detection figure on a long recording's envelope, against drawing every point.

Prints one table: CPU time (time.process_time, best of three) to build and render the detection
figure (``dashpot.plots.detection_figure``, whose overview draws a min/max-decimated envelope of
at most 5000 points) for envelopes of 60 000 to 2 400 000 samples (1.4 s to 54 s of audio at
44.1 kHz), and the ratio against the named baseline ``plot-all``: the same two panels with
matplotlib drawing every sample of the envelope. Target: under 3 s of CPU for 600 000 samples.
Run with ``make bench``.
"""

from __future__ import annotations

import io
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from timing import best_cpu  # noqa: E402

from dashpot import plots  # noqa: E402

RATE = 44_100.0
SIZES = (60_000, 600_000, 2_400_000)
TARGET_SIZE, TARGET_SECONDS = 600_000, 3.0


def envelope(n):
    """An envelope of n samples with a bounce train of decaying impacts (as the tests use)."""
    time_s = np.arange(n) / RATE
    impacts = 0.2 + np.cumsum(0.5 * 0.85 ** np.arange(60))
    impacts = impacts[impacts < time_s[-1]]
    values = np.full(n, 0.01)
    for k, t in enumerate(impacts):
        i = int(t * RATE)
        values[i:i + 200] += 0.8 * 0.95 ** k * np.exp(-np.arange(min(200, n - i)) / 50.0)
    return time_s, values, impacts


def render(fig):
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return buffer.getvalue()


def detection(time_s, values, impacts):
    return render(plots.detection_figure(time_s, values, impacts, sample_time=time_s,
                                         samples=values - 0.01, tail_count=8))


def plot_all(time_s, values, impacts):
    """Baseline: the same overview and close-up, every sample drawn."""
    fig = Figure(figsize=(8, 6))
    overview, close = fig.subplots(2, 1)
    overview.plot(time_s, values, lw=0.5)
    overview.vlines(impacts, 0, 1, color="C3", lw=0.5)
    tail = time_s >= impacts[-min(8, impacts.size)] - 0.05
    close.plot(time_s[tail], values[tail] - 0.01, lw=0.3)
    close.plot(time_s[tail], values[tail], lw=0.8)
    return render(fig)


def main():
    print(f"{'samples':>10} {'audio s':>8} {'detection s':>12} {'plot-all s':>11} "
          f"{'speed-up':>9}")
    target = None
    for n in SIZES:
        inputs = envelope(n)
        ours, _ = best_cpu(lambda: detection(*inputs))
        baseline, _ = best_cpu(lambda: plot_all(*inputs))
        print(f"{n:>10} {n / RATE:>8.1f} {ours:>12.3f} {baseline:>11.3f} "
              f"{baseline / ours:>8.1f}x")
        if n == TARGET_SIZE:
            target = ours
    verdict = "meets" if target < TARGET_SECONDS else "MISSES"
    print(f"detection figure at {TARGET_SIZE} samples: {target:.2f} s CPU, {verdict} the "
          f"{TARGET_SECONDS:g} s target")


if __name__ == "__main__":
    main()
