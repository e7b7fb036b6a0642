"""Peak memory of every command on a one-hour recording, against a limit of 1 GB.

Prints one table. Rows: ``dashpot impacts``, ``bounces``, ``fit`` and ``analyze`` run on a
synthetic one-hour mono recording (44.1 kHz, 16-bit WAV, 318 MB: background noise with one
bounce train of 40 impacts half-way through), each in a child process of its own. Columns: the
command, the recording's length, the child's peak resident memory (``ru_maxrss`` of that child,
from ``os.wait4``), the limit of 1 GB, the peak measured before streaming the detection figure
(the baseline: ``analyze`` read the whole file as float64 for its figure and peaked at 4.07 GB;
``impacts`` needed 297 MB) and the ratio of the two, and the wall time. Exits with status 1 if a command exceeds the
limit or fails.

The recording is written block by block in a temporary folder (it needs 318 MB of free disk;
the folder is removed at the end). ``fit`` and ``analyze`` fit one model (IIb) only: memory
depends on the recording's length through the detection and the figure, not on the number of
models. About two minutes on one core.

Run with ``make bench`` or ``python benchmarks/bench_memory.py [--minutes 60]``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import soundfile as sf

import dashpot
from dashpot.synth.audio import impact_sound

RATE = 44100
LIMIT = 1e9  # bytes
# Peak RSS before the detection figure was streamed: impacts and analyze as reported in
# issue 12 (297 MB, 4.07 GB); bounces and fit measured by this script at commit fcfe739 (its
# analyze peaked at 4.21 GB there).
BASELINE = {"impacts": 297e6, "bounces": 159e6, "fit": 375e6, "analyze": 4.07e9}
NOISE_RMS = 1.6e-3  # full scale: the noise impact_sound adds at 50 dB below a 0.5 peak


def write_recording(path, minutes, seed=2718):
    """A mono 16-bit WAV of `minutes` of noise with one bounce train in the middle."""
    rng = np.random.default_rng(seed)
    sequence = dashpot.bounce_sequence("hybrid", beta=80.0, omega0=3000.0, g=9.81, v0=1.5,
                                       n_max=40)
    train, _ = impact_sound(sequence.impact_times, sequence.impact_speeds, sample_rate=RATE,
                            snr_db=50.0, seed=seed)
    frames = int(minutes * 60 * RATE)
    train_start = frames // 2
    block = 60 * RATE
    with sf.SoundFile(str(path), "w", samplerate=RATE, channels=1, subtype="PCM_16",
                      format="WAV") as handle:
        for start in range(0, frames, block):  # one minute at a time
            stop = min(start + block, frames)
            samples = NOISE_RMS * rng.standard_normal(stop - start)
            lo, hi = max(start, train_start), min(stop, train_start + train.size)
            if lo < hi:
                samples[lo - start:hi - start] = train[lo - train_start:hi - train_start]
            handle.write(samples)
    return frames / RATE


def peak_rss(arguments, folder):
    """Peak resident memory (bytes) of ``python -m dashpot.cli <arguments>``, and its status."""
    process = subprocess.Popen([sys.executable, "-m", "dashpot.cli", *arguments], cwd=folder,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(process.pid, 0)  # this child's own rusage
    process.returncode = os.waitstatus_to_exitcode(status)
    error = process.stderr.read().decode(errors="replace").strip()
    process.stdout.close()
    process.stderr.close()
    return usage.ru_maxrss * 1024, process.returncode, error  # ru_maxrss is in KiB on Linux


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=60.0,
                        help="length of the recording (default 60)")
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="dashpot-bench-memory-"))
    try:
        free = shutil.disk_usage(folder).free
        needed = args.minutes * 60 * RATE * 2
        if free < 2 * needed:
            sys.exit(f"bench_memory: {free / 1e6:.0f} MB free in {folder.parent}, "
                     f"{2 * needed / 1e6:.0f} MB needed")
        seconds = write_recording(folder / "hour.wav", args.minutes)
        commands = {
            "impacts": ["impacts", "hour.wav", "-o", "impacts.csv"],
            "bounces": ["bounces", "impacts.csv", "-o", "bounces.csv"],
            "fit": ["fit", "hour.wav", "-o", "fit.h5", "--models", "IIb"],
            "analyze": ["analyze", "hour.wav", "-o", "out", "--models", "IIb"],
        }
        print(f"Peak memory per command on a {seconds / 60:.0f}-minute mono {RATE} Hz 16-bit "
              f"WAV ({(folder / 'hour.wav').stat().st_size / 1e6:.0f} MB), limit 1 GB; "
              f"baseline: before the detection figure was streamed")
        print(f"{'command':<9} {'recording':>9} {'peak RSS':>9} {'limit':>6} {'baseline':>9} "
              f"{'ratio':>6} {'time':>6}")
        failed = False
        for name, arguments in commands.items():
            start = time.perf_counter()
            peak, status, error = peak_rss(arguments, folder)
            elapsed = time.perf_counter() - start
            baseline = BASELINE[name]
            ratio = f"{peak / baseline:.2f}" if baseline else "-"
            base = f"{baseline / 1e6:.0f} MB" if baseline else "-"
            print(f"{name:<9} {seconds / 60:>7.0f} m {peak / 1e6:>6.0f} MB {'1 GB':>6} "
                  f"{base:>9} {ratio:>6} {elapsed:>5.0f}s")
            if status != 0:
                print(f"  failed (exit {status}): {error.splitlines()[-1] if error else ''}")
                failed = True
            elif peak > LIMIT:
                print(f"  over the limit of {LIMIT / 1e6:.0f} MB")
                failed = True
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
