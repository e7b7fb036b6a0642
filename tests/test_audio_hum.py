"""Mains hum and buzz under a bounce train: the detector finds their lines at the start of
the file and notches them out, so the quiet last impacts are not lost under them.

The 100 Hz high-pass alone attenuates a 50 Hz hum by 12 dB only: a hum of -26 dBFS then
stands over the last impacts of a train and hides them. The recordings here are synthetic
(dashpot.synth.audio, hum added as a sum of sines), the seeds drawn once."""

from __future__ import annotations

import numpy as np
import pytest

from dashpot.ingest import envelope
from dashpot.ingest.audio import detect_impacts
from dashpot.synth.audio import impact_sound, write_audio

RATE = 44100


def _train(seed, **hum):
    """A 20-impact drop (intervals 0.4 s × 0.9ⁿ, impact speeds 0.9ⁿ) at 40 dB SNR."""
    times = np.concatenate([[0.0], np.cumsum(0.4 * 0.9 ** np.arange(19))])
    return impact_sound(times, 0.9 ** np.arange(20), sample_rate=RATE, snr_db=40.0,
                        lead_in=1.2, seed=seed, **hum)


def _matched(found, onsets, tolerance=1e-3):
    """Number of true onsets with a found time within `tolerance` (s), and of found times
    with no true onset within it."""
    distance = np.abs(found[:, None] - onsets[None, :])
    return int((distance.min(axis=0) <= tolerance).sum()), int(
        (distance.min(axis=1) > tolerance).sum())


@pytest.mark.parametrize(("hum_hz", "harmonics", "seed"),
                         [(50.0, 1, 20520931), (60.0, 4, 20520932), (50.3, 10, 20520933)])
def test_the_lines_of_a_hum_are_found_at_their_frequencies(hum_hz, harmonics, seed):
    samples, _ = _train(seed, hum_level=0.02, hum_hz=hum_hz, hum_harmonics=harmonics)
    found = envelope._mains_hum(samples[:, None], RATE)
    # Named by the nominal mains frequency (a notch of Q 15 spans the tenths of a hertz a
    # grid wanders by, times the harmonic's number).
    nominal = 10.0 * round(hum_hz / 10.0)
    np.testing.assert_array_equal(found, nominal * np.arange(1, harmonics + 1))


@pytest.mark.parametrize("seed", range(20520941, 20520946))
@pytest.mark.parametrize("color", ["white", "pink"])
def test_no_hum_is_found_where_there_is_none(seed, color):
    samples, _ = _train(seed, noise_color=color)
    stereo = np.column_stack([samples, np.roll(samples, 7)])
    assert envelope._mains_hum(stereo, RATE).size == 0
    # A tone that is no mains harmonic (a fan at 75 Hz) is not notched either.
    time = np.arange(samples.size) / RATE
    assert envelope._mains_hum((samples + 0.05 * np.sin(2 * np.pi * 75.0 * time))[:, None],
                               RATE).size == 0


@pytest.mark.parametrize(("hum_hz", "level", "harmonics", "seed"),
                         [(50.0, 0.05, 1, 20520951), (60.0, 0.05, 1, 20520952),
                          (60.0, 0.02, 10, 20520953), (59.9, 0.1, 3, 20520954)])
def test_every_impact_of_a_train_under_hum_is_found(tmp_path, monkeypatch, hum_hz, level,
                                                     harmonics, seed):
    samples, onsets = _train(seed, hum_level=level, hum_hz=hum_hz, hum_harmonics=harmonics)
    path = write_audio(tmp_path / "hum.wav", samples, RATE)
    table = detect_impacts(path)
    timed, false = _matched(table["time"].to_numpy(), onsets)
    assert (timed, false) == (onsets.size, 0)
    notes = [note for note in table.attrs["notes"] if note.startswith("mains hum")]
    nominal = 10.0 * round(hum_hz / 10.0)
    assert len(notes) == 1 and f"{harmonics} line(s) at {nominal:.1f}" in notes[0]
    # The high-pass alone, without the notches, loses impacts under the same hum.
    monkeypatch.setattr(envelope, "_HUM_LINE_RATIO", np.inf)
    timed_without, _ = _matched(detect_impacts(path)["time"].to_numpy(), onsets)
    assert timed_without < onsets.size


def test_the_synthetic_hum_is_a_sum_of_sines_and_off_by_default():
    quiet, _ = _train(20520961)
    default, _ = _train(20520961, hum_level=0.0, hum_hz=60.0, hum_harmonics=3)
    assert np.array_equal(quiet, default)
    hummed, _ = _train(20520961, hum_level=0.05, hum_hz=60.0, hum_harmonics=3)
    time = np.arange(quiet.size) / RATE
    lines = sum(0.05 / k * np.sin(2 * np.pi * 60.0 * k * time + k) for k in (1, 2, 3))
    np.testing.assert_allclose(hummed - quiet, lines, atol=1e-12, rtol=0)
    for bad in ({"hum_level": -0.1}, {"hum_hz": 0.0}, {"hum_harmonics": 0},
                {"hum_harmonics": 2.5}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            _train(20520961, **bad)
