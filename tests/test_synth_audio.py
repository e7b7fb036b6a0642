"""dashpot.synth.audio: synthetic impact sounds and their writer, against their own definitions.

Truth here is what the docstrings promise (onsets at lead_in + impact_times, peaks ∝ speed,
SNR = 20·log10(loudest peak / noise RMS)), measured on the returned samples independently.
"""

import numpy as np
import pytest
import soundfile as sf

from dashpot.ingest.audio import read_audio
from dashpot.synth.audio import impact_sound, write_audio

RATE = 44100
TIMES = np.array([0.0, 0.30, 0.55])
SPEEDS = np.array([2.0, 1.5, 1.0])


def test_same_seed_same_samples_other_seed_other_noise():
    first, onsets = impact_sound(TIMES, SPEEDS, seed=3)
    again, onsets_again = impact_sound(TIMES, SPEEDS, seed=3)
    other, _ = impact_sound(TIMES, SPEEDS, seed=4)
    np.testing.assert_array_equal(first, again)
    np.testing.assert_array_equal(onsets, onsets_again)
    assert not np.array_equal(first, other)


def test_onsets_are_lead_in_plus_impact_times_and_the_transient_starts_there():
    samples, onsets = impact_sound(TIMES, SPEEDS, lead_in=0.123, snr_db=300.0, ring_level=0.0)
    np.testing.assert_allclose(onsets, 0.123 + TIMES)
    for onset in onsets:
        first_after = int(np.ceil(onset * RATE))
        # Nothing but (negligible) noise before the onset, a clear signal right after it.
        assert np.abs(samples[first_after - 40:first_after]).max() < 1e-12
        assert np.abs(samples[first_after:first_after + 3]).max() > 1e-3


def test_peak_amplitude_is_proportional_to_impact_speed():
    samples, onsets = impact_sound(TIMES, SPEEDS, snr_db=120.0, ring_level=0.0, peak_level=0.6)
    peaks = [np.abs(samples[int(t * RATE):int((t + 0.01) * RATE)]).max() for t in onsets]
    # The peak over continuous time is exact; a sample can miss it by a hair.
    np.testing.assert_allclose(peaks, 0.6 * SPEEDS / SPEEDS.max(), rtol=0.02)


@pytest.mark.parametrize("snr_db", [20.0, 40.0])
@pytest.mark.parametrize("color", ["white", "pink"])
def test_snr_is_loudest_peak_over_noise_rms(snr_db, color):
    samples, onsets = impact_sound(TIMES, SPEEDS, snr_db=snr_db, ring_level=0.0,
                                   lead_in=0.5, noise_color=color, seed=1)
    noise_rms = np.sqrt(np.mean(samples[: int(0.45 * RATE)] ** 2))
    clean, _ = impact_sound(TIMES, SPEEDS, snr_db=300.0, ring_level=0.0, lead_in=0.5)
    measured = 20 * np.log10(np.abs(clean).max() / noise_rms)
    assert measured == pytest.approx(snr_db, abs=0.5)


def test_ring_echo_dc_offset_and_clipping():
    base, onsets = impact_sound([0.0], [1.0], snr_db=300.0, ring_level=0.0)
    ringing, _ = impact_sound([0.0], [1.0], snr_db=300.0, ring_level=0.3, ring_delay=0.02)
    echoed, _ = impact_sound([0.0], [1.0], snr_db=300.0, ring_level=0.0, echo_delay=0.08,
                             echo_level=0.5)
    start = int(onsets[0] * RATE)
    ring_window = slice(start + int(0.02 * RATE), start + int(0.03 * RATE))
    echo_window = slice(start + int(0.08 * RATE), start + int(0.09 * RATE))
    # The secondary transients appear at their delays, weaker than the impact.
    assert 0.1 < np.abs(ringing[ring_window] - base[ring_window]).max() / 0.5 < 0.4
    assert 0.1 < np.abs(echoed[echo_window] - base[echo_window]).max() / 0.5 < 0.5
    offset, _ = impact_sound([0.0], [1.0], dc_offset=0.1, clip_level=0.35, seed=2)
    assert offset.max() == pytest.approx(0.35)
    assert np.median(offset[: int(0.1 * RATE)]) == pytest.approx(0.1, abs=1e-3)


@pytest.mark.parametrize("bad", [dict(impact_speeds=[1.0, -1.0, 1.0]),
                                 dict(impact_speeds=[1.0, 1.0]),
                                 dict(sample_rate=4000),
                                 dict(noise_color="blue"),
                                 dict(duration=0.3)])
def test_bad_arguments_raise_value_error(bad):
    arguments = dict(impact_times=TIMES, impact_speeds=SPEEDS) | bad
    with pytest.raises(ValueError):
        impact_sound(**arguments)


FORMATS = [("wav", "PCM_U8", 2.0**-7), ("wav", "PCM_16", 2.0**-15), ("wav", "PCM_24", 2.0**-23),
           ("wav", "PCM_32", 2.0**-31), ("wav", "FLOAT", 1e-7), ("wav", "DOUBLE", 1e-15),
           ("flac", "PCM_S8", 2.0**-7), ("flac", "PCM_16", 2.0**-15),
           ("flac", "PCM_24", 2.0**-23)]


@pytest.mark.parametrize(("suffix", "subtype", "step"), FORMATS)
def test_round_trip_through_each_lossless_format(tmp_path, suffix, subtype, step):
    samples, _ = impact_sound(TIMES, SPEEDS, seed=5)
    path = write_audio(tmp_path / f"train.{suffix}", samples, RATE, subtype=subtype)
    back, rate = read_audio(path)
    assert rate == RATE and back.shape == (samples.size, 1)
    # Quantisation to the subtype's step, nothing more.
    assert np.abs(back[:, 0] - samples).max() <= step
    assert sf.info(str(path)).subtype == subtype
    assert [p.name for p in tmp_path.iterdir()] == [f"train.{suffix}"]  # no temporary left


def test_round_trip_through_ogg_vorbis_keeps_the_waveform(tmp_path):
    samples, _ = impact_sound(TIMES, SPEEDS, seed=5)
    path = write_audio(tmp_path / "train.ogg", samples, RATE)
    back, rate = read_audio(path)
    assert rate == RATE and sf.info(str(path)).subtype == "VORBIS"
    # Lossy: the waveform survives to within a small fraction of its energy.
    residual = back[: samples.size, 0] - samples
    assert np.sum(residual**2) < 0.1 * np.sum(samples**2)


def test_multichannel_mix_has_distinct_gains_and_delays(tmp_path):
    samples, _ = impact_sound(TIMES, SPEEDS, seed=6)
    path = write_audio(tmp_path / "stereo.wav", samples, RATE, channels=3, subtype="FLOAT")
    back, _ = read_audio(path)
    assert back.shape == (samples.size, 3)
    for channel in (1, 2):
        delay = 3 * channel
        expected = 0.8**channel * samples[: samples.size - delay]
        np.testing.assert_allclose(back[delay:, channel], expected, atol=1e-6)


def test_write_audio_rejects_unknown_suffix_and_bad_shapes(tmp_path):
    samples, _ = impact_sound(TIMES, SPEEDS)
    with pytest.raises(ValueError, match="format"):
        write_audio(tmp_path / "train.mp4", samples, RATE)
    with pytest.raises(ValueError, match="shape"):
        write_audio(tmp_path / "train.wav", np.ones((10, 2)), RATE, channels=3)
    with pytest.raises(ValueError, match="cannot hold"):
        write_audio(tmp_path / "train.flac", samples, RATE, subtype="FLOAT")


# ------------------------------------------------- quiet sounds besides the impacts (issue 14)


def test_disturbances_leave_the_rest_of_the_signal_unchanged_and_are_not_onsets():
    plain, onsets = impact_sound(TIMES, SPEEDS, seed=7, duration=2.0)
    disturbed, disturbed_onsets = impact_sound(
        TIMES, SPEEDS, seed=7, duration=2.0, apex_click_db=-40.0, rest_click_period=0.09,
        burst_delays=[0.007], burst_levels=[1.5])
    np.testing.assert_array_equal(onsets, disturbed_onsets)
    # Before the first onset the signal is the same noise: the disturbances' draws are apart.
    first = int(onsets[0] * RATE)
    np.testing.assert_array_equal(plain[:first], disturbed[:first])
    assert not np.array_equal(plain, disturbed)


def test_apex_click_is_40_db_under_its_impacts_near_the_midpoint():
    times, speeds = np.array([0.0, 0.4]), np.array([1.0, 1.0])
    quiet, onsets = impact_sound(times, speeds, snr_db=300.0, ring_level=0.0, seed=2)
    clicked, _ = impact_sound(times, speeds, snr_db=300.0, ring_level=0.0, seed=2,
                              apex_click_db=-40.0)
    extra = np.abs(clicked - quiet)
    # Within ±5 % of the flight around its midpoint, and nowhere else.
    midpoint = int((onsets[0] + 0.2) * RATE)
    window = slice(midpoint - int(0.021 * RATE), midpoint + int(0.03 * RATE))
    assert extra[window].max() == pytest.approx(0.5 * 1e-2, rel=0.03)
    extra[window] = 0.0
    assert extra.max() == 0.0


def test_rest_clicks_repeat_at_their_period_after_the_last_impact():
    quiet, onsets = impact_sound(TIMES, SPEEDS, snr_db=300.0, ring_level=0.0, seed=3,
                                 rest_click_period=0.09, rest_click_duration=0.5)
    clean, _ = impact_sound(TIMES, SPEEDS, snr_db=300.0, ring_level=0.0, seed=3,
                            duration=quiet.size / RATE)
    extra = np.abs(quiet - clean)
    assert extra[: int(onsets[-1] * RATE)].max() == 0.0
    # Starts of the clicks: first nonzero sample after silence.
    active = extra > 1e-9
    starts = np.flatnonzero(active[1:] & ~active[:-1]) + 1
    gaps = np.diff(np.concatenate([[onsets[-1] * RATE], starts])) / RATE
    assert gaps.size == 5
    np.testing.assert_allclose(gaps, 0.09, rtol=0.02 + 2.0 / (0.09 * RATE))
    # Each click is half as loud as the last impact (peak 0.5 × 1/2 of the loudest).
    peak = 0.5 * SPEEDS[-1] / SPEEDS.max()
    assert extra.max() == pytest.approx(0.5 * peak, rel=0.03)


def test_ring_bursts_come_at_their_delays_with_their_levels():
    base, onsets = impact_sound([0.0], [1.0], snr_db=300.0, ring_level=0.0, duration=0.5)
    bursting, burst_onsets = impact_sound([0.0], [1.0], snr_db=300.0, ring_level=0.0,
                                          duration=0.5, burst_delays=[0.007], burst_levels=[1.5])
    np.testing.assert_array_equal(onsets, burst_onsets)
    extra = np.abs(bursting - base)
    start = onsets[0] + 0.007
    assert extra[: int(np.floor(start * RATE))].max() == 0.0
    assert extra[int(np.ceil(start * RATE))] > 0.0
    assert extra.max() == pytest.approx(1.5 * 0.5, rel=0.03)


@pytest.mark.parametrize("bad", [dict(burst_delays=[0.01], burst_levels=[]),
                                 dict(burst_delays=[-0.01], burst_levels=[1.0]),
                                 dict(rest_click_period=0.0),
                                 dict(apex_click_db=float("nan"))])
def test_bad_disturbances_raise_value_error(bad):
    with pytest.raises(ValueError):
        impact_sound(TIMES, SPEEDS, **bad)
