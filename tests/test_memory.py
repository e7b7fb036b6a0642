"""Bounded memory (issue 12, point 13): a zip bomb is refused before it is expanded, and the
detection figure reads the recording in blocks, keeping the extremes of each window.

Before: a 195 KB zip holding a 200 MB CSV took 187 s and 17 GB; `dashpot analyze` read a
one-hour recording whole as float64 for its figure and peaked at 4.07 GB
(benchmarks/bench_memory.py measures the commands themselves).
"""

import zipfile

import numpy as np
import pytest
import soundfile as sf

from dashpot import figures
from dashpot.envelope import channel_extremes, recording_envelope
from dashpot.errors import InputError
from dashpot.ingest import audio, read_impacts
from dashpot.synth.audio import write_audio


def _zip_with_csv(path, rows, *, name="Raw Data.csv"):
    """A zip (as phyphox exports) holding one CSV of `rows` identical rows, streamed."""
    line = b"0.123456789,1.000000000\n"
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        with archive.open(name, "w", force_zip64=True) as member:
            member.write(b"Time (s),Sound pressure level (dB)\n")
            for start in range(0, rows, 100_000):
                member.write(line * min(100_000, rows - start))
    return path


def test_a_zip_member_expanding_past_the_limit_is_refused_by_name(tmp_path):
    bomb = _zip_with_csv(tmp_path / "bomb.zip", 3_000_000)  # 72 MB in some 200 KB
    assert bomb.stat().st_size < 1_000_000
    with pytest.raises(InputError) as caught:
        read_impacts(bomb, kind="phyphox")
    message = str(caught.value)
    assert message.startswith(f"{bomb}: ") and "zip bomb" in message and "Raw Data.csv" in message
    assert "\n" not in message


def test_a_zip_member_compressed_more_than_100_times_is_refused(tmp_path):
    dense = _zip_with_csv(tmp_path / "dense.zip", 200_000)  # 5 MB, under the size limit
    with pytest.raises(InputError, match="zip bomb"):
        read_impacts(dense, kind="phyphox")


def test_a_small_zip_member_may_compress_well(tmp_path):
    """Below 1 MB the ratio does not matter: the table is read (and found not to be one)."""
    small = _zip_with_csv(tmp_path / "small.zip", 30_000)  # 720 KB, some 500 times smaller
    with zipfile.ZipFile(small) as archive:
        info = archive.infolist()[0]
        assert info.file_size > 100 * info.compress_size
    with pytest.raises(InputError) as caught:
        read_impacts(small, kind="phyphox")
    assert "zip bomb" not in str(caught.value)


@pytest.fixture
def stereo_recording(tmp_path):
    """2.3 s of stereo at 8 kHz: noise, a DC offset on one channel and a few clicks."""
    rng = np.random.default_rng(9301)
    rate = 8000
    samples = 0.01 * rng.standard_normal((int(2.3 * rate) + 5, 2))
    samples[:, 1] += 0.2
    for start in rng.integers(0, samples.shape[0] - 100, 6):
        samples[start:start + 40, 0] += 0.5 * np.exp(-np.arange(40) / 8.0)
    path = write_audio(tmp_path / "stereo.wav", samples, rate, subtype="FLOAT", channels=2)
    return path, rate


def test_the_streamed_envelope_is_the_windowed_extreme_of_the_whole_signal(stereo_recording):
    path, rate = stereo_recording
    samples, _ = sf.read(str(path), always_2d=True)
    # Blocks of 0.3 s (2400 samples: windows of 8 samples do not straddle them) and a last,
    # partial window.
    time, envelope, loudest, sample_rate = recording_envelope(path, block_seconds=0.3)
    size = 8  # 1 ms at 8 kHz
    centred = np.abs(samples - samples.mean(axis=0)).max(axis=1)
    expected = [centred[i:i + size].max() for i in range(0, centred.size, size)]
    np.testing.assert_allclose(envelope, expected, rtol=0, atol=1e-12)
    starts = np.arange(len(expected)) * size
    np.testing.assert_allclose(time, (starts + np.minimum(size, centred.size - starts) / 2
                                      - 0.5) / rate)
    assert sample_rate == rate
    assert loudest == int(np.argmax(np.abs(samples).max(axis=0)))


def test_the_close_up_keeps_the_extremes_of_every_pixel_column(stereo_recording):
    path, rate = stereo_recording
    samples, _ = sf.read(str(path), always_2d=True)
    channel = samples[:, 0]
    first, last = int(0.25 * rate), int(2.0 * rate) + 1  # 14 001 samples, 50 columns
    time, values = channel_extremes(path, 0, 0.25, 2.0, columns=50, block_seconds=0.2)
    per = -(-(last - first) // 50)
    np.testing.assert_array_equal(values, channel[np.round(time * rate).astype(int)])
    column = (np.round(time * rate).astype(int) - first) // per
    for k in range(-(-(last - first) // per)):
        run = channel[first + k * per:min(first + (k + 1) * per, last)]
        assert values[column == k].min() == run.min() and values[column == k].max() == run.max()
    assert np.all(np.diff(time) >= 0)
    # A short span comes back whole.
    time, values = channel_extremes(path, 0, 1.0, 1.01, columns=50)
    np.testing.assert_array_equal(values, channel[8000:8081])


def test_the_detection_figure_never_reads_the_whole_recording(stereo_recording, monkeypatch):
    path, _ = stereo_recording

    def whole_file(*args, **kwargs):
        raise AssertionError("the detection figure read the whole recording into memory")

    monkeypatch.setattr(audio, "read_audio", whole_file)
    data = figures.detection_figure_data(path, [0.5, 0.9, 1.25, 1.55, 1.8])
    assert data["samples"].size <= 2 * 2000 + 2
    assert data["sample_time"].min() < 1.25 < data["sample_time"].max() <= 2.3
