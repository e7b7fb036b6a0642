"""The audio detector on recordings of a session: several drops, and a ball clicking at rest.

Prints two tables.

1. Recordings of 2-3 drops of one ball (``tests/test_audio_drops.py``: the disturbances of
   issue 14, 0.8-4 s from one drop's last impact to the next one's first): how many
   recordings give as many runs as drops, recall and false impacts against the truth (a
   detection within 1 ms of a true onset of its drop is that impact), and how many impacts
   differ (by more than 1 µs) from what the detector finds in each drop's stretch of the
   recording alone, from 0.15 s before its first impact to 1 s after its last.
2. Single trains followed by the steady clicks of a ball at rest (every 80-100 ms) for 3 s
   and for 10 s, with a ring and an echo: trains refused, recall, false impacts, and trains
   that gained a run.

Run with ``python benchmarks/bench_audio_sessions.py [--start SEED] [--count N] [--workers K]``
(default: 40 recordings from seed 20496001 and 100 trains from seed 20498001, one worker per
core; ``make bench`` runs the default).
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from audio_trains import hybrid_train, score_train  # noqa: E402
from test_audio_disturbances import MATCH, RATE  # noqa: E402
from test_audio_drops import drops_recording  # noqa: E402

from dashpot.errors import InputError  # noqa: E402
from dashpot.ingest.audio import detect_impacts  # noqa: E402
from dashpot.synth.audio import impact_sound, write_audio  # noqa: E402

CLICK_SECONDS = (3.0, 10.0)


def session(seed):
    """(drops, runs, impacts, found, false, differing) of the recording of drops of `seed`."""
    samples, truth, _, _ = drops_recording(seed)
    with tempfile.TemporaryDirectory() as folder:
        table = detect_impacts(write_audio(Path(folder) / "drops.wav", samples, RATE,
                                           subtype="FLOAT"))
        runs = [run["time"].to_numpy() for _, run in table.groupby("run")]
        found = false = differing = 0
        for onsets, run in zip(truth, runs):
            score = score_train(onsets, run, np.ones(run.size), MATCH)
            found, false = found + score["found"], false + score["false"]
            first = int((onsets[0] - 0.15) * RATE)
            stretch = samples[first:int((onsets[-1] + 1.0) * RATE)]
            # One scratch file, written again for each run.
            alone = detect_impacts(write_audio(Path(folder) / "alone.wav", stretch, RATE,
                                               subtype="FLOAT", overwrite=True))
            alone = alone["time"].to_numpy()
            distance = np.abs(run[:, None] - (alone + first / RATE)[None, :])
            differing += int((distance.min(axis=1) > 1e-6).sum()
                             + (distance.min(axis=0) > 1e-6).sum())
    return len(truth), len(runs), sum(o.size for o in truth), found, false, differing


def clicking(seed, seconds):
    """(refused, impacts, found, false, extra runs) of the train of `seed` followed by
    `seconds` of clicks."""
    rng = np.random.default_rng(seed)
    times, speeds = hybrid_train(rng)
    options = dict(ring_level=rng.uniform(0, 0.4), ring_delay=0.02,
                   rest_click_period=rng.uniform(0.08, 0.1), rest_click_duration=seconds,
                   echo_delay=rng.uniform(5e-3, 0.2), echo_level=rng.uniform(0.1, 0.5))
    snr_db = rng.uniform(20, 45) + 20 * np.log10(speeds.max() / speeds.min())
    samples, onsets = impact_sound(times, speeds, sample_rate=RATE, seed=seed, snr_db=snr_db,
                                   **options)
    with tempfile.TemporaryDirectory() as folder:
        path = write_audio(Path(folder) / "clicks.wav", samples, RATE, subtype="FLOAT")
        try:
            table = detect_impacts(path)
        except InputError:
            return 1, onsets.size, 0, 0, 0
    score = score_train(onsets, table["time"].to_numpy(), np.ones(len(table)), MATCH)
    return 0, onsets.size, score["found"], score["false"], int(table["run"].max())


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--start", type=int, default=20496001)
    parser.add_argument("--count", type=int, default=40)
    parser.add_argument("--click-start", type=int, default=20498001)
    parser.add_argument("--click-count", type=int, default=100)
    parser.add_argument("--workers", type=int, default=multiprocessing.cpu_count())
    options = parser.parse_args(argv)
    with multiprocessing.Pool(options.workers) as pool:
        sessions = np.array(pool.map(session, range(options.start,
                                                    options.start + options.count)))
        clicks = {seconds: np.array(pool.starmap(clicking, [
            (seed, seconds) for seed in range(options.click_start,
                                              options.click_start + options.click_count)]))
            for seconds in CLICK_SECONDS}
    drops, runs, impacts, found, false, differing = sessions.T
    print(f"recordings of several drops, seeds {options.start}-"
          f"{options.start + options.count - 1}")
    print(f"{'recordings':>11}{'drops':>7}{'runs right':>11}{'impacts':>9}{'recall':>8}"
          f"{'false':>7}{'per 500':>9}{'differ alone':>14}")
    print(f"{sessions.shape[0]:>11}{drops.sum():>7}{(runs == drops).sum():>11}"
          f"{impacts.sum():>9}{found.sum() / impacts.sum():>8.4f}{false.sum():>7}"
          f"{500 * false.sum() / impacts.sum():>9.2f}{differing.sum():>14}")
    print(f"\ntrains followed by clicks at rest, seeds {options.click_start}-"
          f"{options.click_start + options.click_count - 1}")
    print(f"{'clicks (s)':>11}{'trains':>7}{'refused':>9}{'impacts':>9}{'recall':>8}"
          f"{'false':>7}{'extra runs':>12}")
    for seconds, rows in clicks.items():
        refused, impacts, found, false, extra = rows.T
        print(f"{seconds:>11g}{rows.shape[0]:>7}{refused.sum():>9}{impacts.sum():>9}"
              f"{found.sum() / impacts.sum():>8.4f}{false.sum():>7}{extra.sum():>12}")


if __name__ == "__main__":
    main()
