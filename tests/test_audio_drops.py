"""Several drops of a ball in one recording: each drop its own run of the impact table.

A lab often records a session of drops in one file: the ball bounces to rest, is picked up
and dropped again. Each drop is a bounce train of its own (the runs of
:data:`dashpot.ingest.IMPACT_COLUMNS`), analysed as the runs of a multi-run lab table are:
one fit per run and a joint fit sharing the contact parameters. The sounds around one drop
(a ball at rest, its echo, handling) must not pass for another.

Synthetic recordings: 2-3 drops of one ball (one β and ω0, a drop speed each) with the
disturbances of ``test_audio_disturbances`` (apex clicks, rest clicks, ring, echo, ring
bursts), 0.8-4 s from the last impact of one drop to the first of the next, and a session
of six drops longer than a block of the stream. The seeds were drawn once, and never used
while developing.
"""

import numpy as np
import pytest
import soundfile as sf

from audio_trains import hybrid_drops, hybrid_train, score_train
from dashpot.cli import main
from dashpot.ingest.audio import detect_impacts
from dashpot.ingest.chain import _drop_start, _periodic_members
from dashpot.store import read_fit
from dashpot.synth.audio import impact_sound, write_audio
from test_audio_disturbances import MATCH, RATE, disturbed_sound
from test_ingest_audio import BOUNCY

RECORDING_SEEDS = range(20_497_001, 20_497_013)
FIT_SEED = 20_497_101
LONG_SEED = 20_497_401


def drops_recording(seed, count=None, gaps=(0.8, 4.0)):
    """(samples, true onsets of each drop, β (1/s), ω0 (rad/s)) of a recording of `count`
    drops (2-3, drawn, by default), from `gaps` (s) apart from one's last impact to the
    next one's first."""
    rng = np.random.default_rng(seed)
    count = int(rng.integers(2, 4)) if count is None else count
    beta, omega0, drops = hybrid_drops(rng, count)
    gaps = rng.uniform(*gaps, size=count - 1)
    firsts = np.concatenate([[0.0], np.cumsum([t[-1] for t, _ in drops[:-1]] + gaps)])
    times = np.concatenate([t + first for (t, _), first in zip(drops, firsts)])
    samples, onsets, _ = disturbed_sound(rng, seed, times,
                                         np.concatenate([v for _, v in drops]))
    bounds = np.cumsum([0] + [t.size for t, _ in drops])
    return samples, [onsets[a:b] for a, b in zip(bounds[:-1], bounds[1:])], beta, omega0


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    """For each seed: the true onsets of each drop, the runs found (times, s), and what the
    detector finds in each drop's stretch of the recording alone (from 0.15 s before its
    first impact to 1 s after its last; times on the recording's clock)."""
    folder = tmp_path_factory.mktemp("drops")
    found = []
    for seed in RECORDING_SEEDS:
        samples, truth, _, _ = drops_recording(seed)
        table = detect_impacts(write_audio(folder / f"drops{seed}.wav", samples, RATE,
                                           subtype="FLOAT"))
        runs = [run["time"].to_numpy() for _, run in table.groupby("run")]
        alone = []
        for onsets in truth:
            first = int((onsets[0] - 0.15) * RATE)
            stretch = samples[first:int((onsets[-1] + 1.0) * RATE)]
            path = write_audio(folder / "alone.wav", stretch, RATE, subtype="FLOAT",
                               overwrite=True)  # one scratch file for every drop
            alone.append(detect_impacts(path)["time"].to_numpy() + first / RATE)
        found.append(dict(seed=seed, truth=truth, runs=runs, alone=alone, table=table))
    return found


def test_every_drop_is_a_run_of_its_own(recordings):
    for recording in recordings:
        truth, runs = recording["truth"], recording["runs"]
        assert len(runs) == len(truth), recording["seed"]
        for onsets, run in zip(truth, runs):
            # Every impact of a run is of its drop, or a sound during it or just after.
            assert onsets[0] - MATCH < run[0] and run[-1] < onsets[-1] + 0.5, recording["seed"]


def test_a_drop_is_timed_as_if_it_were_recorded_alone(recordings):
    """The other drops change nothing: each run holds the impacts (within 1 µs) that the
    detector finds in its drop's stretch of the recording alone, but for a few in all."""
    differing = total = 0
    for recording in recordings:
        for run, alone in zip(recording["runs"], recording["alone"]):
            distance = np.abs(run[:, None] - alone[None, :])
            differing += np.count_nonzero(distance.min(axis=1) > 1e-6) + np.count_nonzero(
                distance.min(axis=0) > 1e-6)
            total += alone.size
    assert differing <= 0.005 * total


def test_recall_and_false_impacts_of_the_drops(recordings):
    """Against the truth: recall and false impacts as on single trains (issue 14's block
    targets are 0.99 and 1 per 500; single trains reach 0.988-0.990 and 2-3 per 500)."""
    total = timed = false = 0
    for recording in recordings:
        for onsets, run in zip(recording["truth"], recording["runs"]):
            score = score_train(onsets, run, np.ones(run.size), MATCH)
            total += onsets.size
            timed += score["found"]
            false += score["false"]
    assert timed >= 0.98 * total
    assert false <= 5 * total / 500


def test_the_notes_name_the_drops_and_their_runs(recordings):
    notes = recordings[0]["table"].attrs["notes"]
    count = len(recordings[0]["truth"])
    assert f"{count} drops of the ball in the recording" in notes[1]
    assert all(note.startswith(("run ", "time:", f"{count} drops")) for note in notes)


def test_two_drops_of_the_real_bouncy_ball_are_two_runs_each_as_the_recording_alone(tmp_path):
    """The bouncy-ball recording (a drop from 0.9 m, 3.1 s before the first impact and 1.7 s
    after the last) played twice in a row: a session of two drops."""
    if not BOUNCY.exists():
        pytest.skip(f"{BOUNCY} not found: the shared recordings are not beside this checkout")
    samples, rate = sf.read(BOUNCY, dtype="int16", always_2d=True)
    path = tmp_path / "twice.wav"
    sf.write(path, np.concatenate([samples, samples]), rate, subtype="PCM_16")
    once = detect_impacts(BOUNCY)["time"].to_numpy()
    table = detect_impacts(path)
    assert sorted(table["run"].unique()) == [0, 1]
    for run, part in table.groupby("run"):
        np.testing.assert_allclose(part["time"].to_numpy() - run * samples.shape[0] / rate,
                                   once, rtol=0, atol=1e-9)


def test_a_drop_repeated_nearly_as_loud_is_a_drop_not_an_echo(tmp_path):
    """A synthetic drop, 2 s of noise, and the same drop again at 0.9 of its loudness (from a
    little lower): its impacts repeat the first's at one delay, but a drop's echo comes
    weakened by its longer path and the wall. Before, the second drop was taken for an echo
    of the first and left out, with no note."""
    rng = np.random.default_rng(20_502_201)
    times, speeds = hybrid_train(rng)
    samples, onsets = impact_sound(times, speeds, sample_rate=RATE, seed=20_502_201,
                                   snr_db=45.0)
    gap = rng.normal(scale=np.std(samples[: int(0.1 * RATE)]), size=2 * RATE)
    path = write_audio(tmp_path / "again.wav",
                       np.concatenate([samples, gap, 0.9 * samples]), RATE, subtype="FLOAT")
    table = detect_impacts(path)
    alone = detect_impacts(write_audio(tmp_path / "alone.wav", samples, RATE,
                                       subtype="FLOAT"))["time"].to_numpy()
    found = score_train(onsets, alone, np.ones(alone.size), MATCH)["found"]
    assert found >= onsets.size - 2
    assert sorted(table["run"].unique()) == [0, 1]
    first, second = (part["time"].to_numpy() for _, part in table.groupby("run"))
    np.testing.assert_allclose(first, alone, rtol=0, atol=1e-9)
    shift = (samples.size + gap.size) / RATE
    score = score_train(onsets + shift, second, np.ones(second.size), MATCH)
    assert score["found"] >= found - 1 and score["false"] <= 1


@pytest.mark.parametrize("sound", ["rest clicks for 3 s", "echo at 0.3-0.5 s",
                                   "handling clicks before the drop"])
def test_the_sounds_around_one_drop_make_no_other_run(sound, tmp_path):
    """One drop with a sound beside it that holds a chain of transients: the clicks of a
    ball at rest for 3 s (periodic; they do not shrink), an echo from a far wall beyond the
    time the detector waits after a train (a copy of the train's end), or twelve loud
    clicks of handling at random in the second before the release."""
    rng = np.random.default_rng(20_497_201)
    times, speeds = hybrid_train(rng)
    options = dict(ring_level=0.2, ring_delay=0.02, rest_click_period=0.09,
                   rest_click_duration=0.6, echo_delay=0.05, echo_level=0.2)
    if sound == "rest clicks for 3 s":
        options["rest_click_duration"] = 3.0
    elif sound == "echo at 0.3-0.5 s":
        options.update(echo_delay=rng.uniform(0.3, 0.5), echo_level=0.5)
    samples, onsets = impact_sound(times, speeds, sample_rate=RATE, seed=20_497_201,
                                   snr_db=60.0, **options)
    if sound == "handling clicks before the drop":
        release = onsets[0] - 0.5 * (onsets[1] - onsets[0])
        lead = int(1.5 * RATE)
        samples = np.concatenate([np.zeros((lead,) + samples.shape[1:]), samples])
        onsets = onsets + lead / RATE
        for moment in release + lead / RATE - rng.uniform(0.1, 1.1, size=12):
            start = int(moment * RATE)
            click = np.exp(-np.arange(int(2e-3 * RATE)) / (0.3e-3 * RATE))
            samples[start:start + click.size] += (0.5 * np.abs(samples).max() * click
                                                  * rng.choice([-1, 1])).reshape(
                                                      -1, *([1] * (samples.ndim - 1)))
        samples += 1e-5 * rng.standard_normal(samples.shape)
    table = detect_impacts(write_audio(tmp_path / "drop.wav", samples, RATE, subtype="FLOAT"))
    assert set(table["run"]) == {0}
    score = score_train(onsets, table["time"].to_numpy(), np.ones(len(table)), MATCH)
    assert score["found"] >= 0.9 * onsets.size


def test_every_drop_is_fitted_and_the_joint_fit_finds_the_ball(tmp_path, capsys):
    """`dashpot fit` on a recording of drops: a fit per run and the joint fit sharing β and
    ω0, which recovers the simulated ball within 3σ."""
    samples, truth, beta, omega0 = drops_recording(FIT_SEED)
    path = write_audio(tmp_path / "drops.wav", samples, RATE, subtype="FLOAT")
    out = tmp_path / "fit.h5"
    assert main(["fit", str(path), "--models", "hybrid", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    for run in range(len(truth)):
        assert f"run {run}:" in printed
    assert "joint (shared)" in printed
    record = read_fit(out)
    assert sorted(record["runs"]) == list(range(len(truth)))
    joint = record["joint"]["hybrid"]["parameters"]
    for name, value in (("beta", beta), ("omega0", omega0)):
        assert abs(joint.loc[name, "value"] - value) < 3 * joint.loc[name, "stderr"], name


@pytest.mark.parametrize("missed", [(), (7,), (7, 15, 16)])
def test_drop_start_keeps_one_train_whole(missed):
    """A geometric train (ratio 0.95 down to 6 ms), with impacts missed (intervals spanning two
    or three flights) and a transient taken for an impact 1 ms after one: one drop."""
    intervals = 0.15 * 0.95 ** np.arange(60)
    times = np.concatenate([[0.0], np.cumsum(intervals[intervals >= 6e-3])])
    times = np.delete(times, list(missed))
    times = np.sort(np.append(times, times[-4] + 1e-3))
    # The sound falls with the impact speed, except the transient's (a tenth as loud).
    amplitudes = np.where(np.isin(times, times[-4] + 1e-3), 0.1, 1.0) * 0.97 ** np.arange(
        times.size)
    assert _drop_start(times, amplitudes) == 0


def test_drop_start_finds_the_last_drop_behind_the_loud_impacts_of_earlier_ones():
    """A chain that took the first impacts of two earlier drops, seconds apart, then the last
    drop's train (ratio 0.94): the last drop starts at its first impact."""
    earlier = np.array([0.2, 1.8, 4.54, 5.57, 6.26])
    train = 7.09 + np.concatenate([[0.0], np.cumsum(0.157 * 0.94 ** np.arange(40))])
    times = np.concatenate([earlier, np.delete(train, 1)])  # its second impact missed
    # Each drop's sound falls with its impacts' speed; an earlier drop's first impact may be
    # as loud as the last drop's.
    loudness = np.concatenate([[1.0, 0.6, 1.0, 0.6, 0.4], 0.97 ** np.arange(times.size - 5)])
    assert _drop_start(times, loudness) == earlier.size
    assert _drop_start(train, 0.97 ** np.arange(train.size)) == 0


def test_periodic_members_are_the_clicks_after_a_train_not_its_bounces():
    """A geometric train (ratio 0.97, the evenest of the test trains) followed by clicks every
    90 ms with 0.3 ms of jitter, the first one period after the last impact: the clicks,
    and only they, are periodic."""
    rng = np.random.default_rng(20_497_301)
    train = np.concatenate([[0.0], np.cumsum(0.12 * 0.97 ** np.arange(60))])
    train = train[np.concatenate([[True], np.diff(train) >= 6e-3])]
    clicks = train[-1] + 0.09 * np.arange(1, 12) + 0.3e-3 * rng.standard_normal(11)
    times = np.concatenate([train, clicks])
    periodic = _periodic_members(times, np.arange(times.size))
    assert not periodic[:train.size].any()
    assert periodic[train.size:].all()
    assert not _periodic_members(train, np.arange(train.size)).any()


def test_a_session_longer_than_a_block_gives_every_drop(tmp_path):
    """Six drops 5-12 s apart (about a minute, streamed in 30 s blocks): six runs, each
    starting at its drop's first impact."""
    samples, truth, _, _ = drops_recording(LONG_SEED, count=6, gaps=(5.0, 12.0))
    assert samples.shape[0] > 1.5 * 30.0 * RATE  # more than one block (the default 30 s)
    table = detect_impacts(write_audio(tmp_path / "session.wav", samples, RATE,
                                       subtype="FLOAT"))
    assert table["run"].nunique() == 6
    for (_, run), onsets in zip(table.groupby("run"), truth):
        assert abs(run["time"].iat[0] - onsets[0]) < MATCH
        score = score_train(onsets, run["time"].to_numpy(), np.ones(len(run)), MATCH)
        assert score["found"] >= 0.95 * onsets.size
