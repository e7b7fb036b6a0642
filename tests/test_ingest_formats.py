"""File formats as labs have them: legacy Excel and OpenDocument workbooks, more audio
containers, and recordings that cannot be decoded here.

phyphox's "Excel" export is a legacy BIFF8 ``.xls`` (one sheet per export set). The workbooks
here are built sheet by sheet from the ``.xlsx`` that dashpot.synth writes (read back with
openpyxl, not with dashpot's readers) and saved with xlwt (BIFF8) and pandas' odf writer (.ods),
so that every phyphox layout the reader supports is checked in all three workbook types against
the times the writer returns. Audio in AIFF, CAF, AU and MP3 is written by libsndfile itself.
"""

from __future__ import annotations

import re
import shlex

import numpy as np
import openpyxl
import pandas as pd
import pytest
import soundfile as sf
import xlwt

import dashpot
from cli_run import run_cli
from dashpot.errors import InputError
from dashpot.ingest import read_impacts
from dashpot.ingest.tables import read_phyphox, sniff_table
from dashpot.synth.audio import impact_sound
from dashpot.synth.tables import write_phyphox_collision, write_phyphox_stopwatch

STIFF = dict(model="Ib", beta=8.0, omega0=300.0, g=0.5, v0=0.5, v_min=0.05)


@pytest.fixture(scope="module")
def stiff():
    return dashpot.bounce_sequence(**STIFF)


def sheets_of(xlsx):
    """{sheet name: rows of cell values} of an .xlsx, read with openpyxl."""
    book = openpyxl.load_workbook(xlsx, read_only=True, data_only=True)
    sheets = {sheet.title: [list(row) for row in sheet.iter_rows(values_only=True)]
              for sheet in book.worksheets}
    book.close()
    return sheets


def save_as(sheets, path):
    """The same sheets as a legacy .xls (xlwt, BIFF8) or an .ods (pandas' odf writer).

    Empty cells and NaN padding stay empty, as a spreadsheet shows them.
    """
    def cell(value):
        if value is None or (isinstance(value, float) and np.isnan(value)):
            return None
        if isinstance(value, str) and value.strip().lower() == "nan":
            return None
        return value

    if path.suffix == ".xls":
        book = xlwt.Workbook()
        for name, rows in sheets.items():  # a few sheets of a few rows
            sheet = book.add_sheet(name)
            for i, row in enumerate(rows):
                for j, value in enumerate(row):
                    if cell(value) is not None:
                        sheet.write(i, j, cell(value))
        book.save(str(path))
    else:
        with pd.ExcelWriter(path, engine="odf") as writer:
            for name, rows in sheets.items():
                frame = pd.DataFrame([[cell(v) for v in row] for row in rows[1:]],
                                     columns=rows[0])
                frame.to_excel(writer, sheet_name=name, index=False)
    return path


LAYOUTS = ["clicks", "multiple", "simple", "collision"]


@pytest.mark.parametrize("suffix", [".xls", ".ods"])
@pytest.mark.parametrize("layout", LAYOUTS)
def test_phyphox_workbooks_in_every_layout(tmp_path, stiff, layout, suffix):
    xlsx = tmp_path / "export.xlsx"
    if layout == "collision":
        truth = write_phyphox_collision(xlsx, stiff.impact_times[:4], excel=True)
    else:
        truth = write_phyphox_stopwatch(xlsx, stiff.impact_times,
                                        layout="clicks" if layout == "clicks" else "multiple",
                                        excel=True)
    sheets = sheets_of(xlsx)
    if layout == "simple":  # a workbook holding the "Simple" set only
        sheets.pop("Multiple")
    path = save_as(sheets, tmp_path / f"export{suffix}")
    if suffix == ".xls":
        assert path.read_bytes()[:8] == b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1"  # OLE2 / BIFF8
    frame = read_phyphox(path)
    expected = np.array(truth["impact_times"])
    if layout == "simple":
        expected = expected[:2]  # Start and Stop
    assert len(frame) == expected.size
    # The workbook cells hold the floats themselves: exact to rounding.
    np.testing.assert_allclose(frame["time"], expected, rtol=1e-12, atol=0)
    assert sniff_table(path) == "phyphox"
    variant = "Excel 97-2003 (.xls)" if suffix == ".xls" else "OpenDocument spreadsheet"
    assert variant in frame.attrs["notes"][1 if layout == "clicks" else 0]
    # Identical to reading the .xlsx it was made from.
    if layout != "simple":
        np.testing.assert_array_equal(frame["time"], read_phyphox(xlsx)["time"])


def test_damaged_legacy_workbook_is_one_line(tmp_path):
    path = tmp_path / "export.xls"
    path.write_bytes(b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1" + b"\x00" * 600)
    with pytest.raises(InputError, match=r"export\.xls: not a readable Excel 97-2003 \(\.xls\) "
                                         r"workbook") as error:
        read_phyphox(path)
    assert "\n" not in str(error.value)


# ------------------------------------------------------------------------------------ audio

@pytest.mark.parametrize(("suffix", "container", "subtype", "rate"),
                         [("aiff", "AIFF", "PCM_16", 44100), ("aif", "AIFF", "PCM_24", 48000),
                          ("caf", "CAF", "PCM_24", 48000), ("caf", "CAF", "FLOAT", 44100),
                          ("au", "AU", "PCM_16", 22050), ("mp3", "MP3", "MPEG_LAYER_III", 44100)])
def test_audio_containers_libsndfile_reads(tmp_path, suffix, container, subtype, rate):
    times, speeds = np.array([0.0, 0.2, 0.36, 0.49]), np.array([1.0, 0.9, 0.8, 0.72])
    samples, onsets = impact_sound(times, speeds, sample_rate=rate, snr_db=45.0, seed=2)
    path = tmp_path / f"train.{suffix}"
    sf.write(str(path), samples, rate, format=container, subtype=subtype)
    table = read_impacts(path)
    # MP3 (lossy) smears a transient over its 576-sample granule; the others are exact.
    tolerance = 1e-3 if suffix == "mp3" else 0.2e-3
    assert len(table) == onsets.size
    np.testing.assert_allclose(table["time"], onsets, atol=tolerance, rtol=0)


@pytest.mark.parametrize("suffix", [".m4a", ".mp4", ".avi", ".mov", ".aac"])
def test_media_libsndfile_cannot_read_get_the_conversion_command(tmp_path, suffix):
    path = tmp_path / f"bounce{suffix}"
    path.write_bytes(b"\x00\x00\x00\x20ftypM4A \x00\x00\x00\x00" + bytes(200))
    output = tmp_path / "impacts.csv"
    status, out, err = run_cli(["impacts", str(path), "-o", str(output)])
    assert status == 2 and not output.exists()
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert str(path) in lines[0]
    assert f"ffmpeg -i bounce{suffix} -vn -c:a pcm_s16le bounce.wav" in lines[0]
    assert "readable: WAV, FLAC, OGG, MP3," in lines[0]
    with pytest.raises(InputError, match="convert its sound to WAV"):
        read_impacts(path, kind="audio")


def test_the_conversion_command_runs_as_given_on_a_name_with_spaces(tmp_path):
    # Phones name their recordings "New Recording 3.m4a": the command must quote the names.
    path = tmp_path / "New Recording 3.m4a"
    path.write_bytes(b"\x00\x00\x00\x20ftypM4A \x00\x00\x00\x00" + bytes(200))
    status, _, err = run_cli(["impacts", str(path), "-o", str(tmp_path / "impacts.csv")])
    assert status == 2
    command = re.search(r"`(ffmpeg [^`]*)`", err).group(1)
    assert shlex.split(command) == ["ffmpeg", "-i", "New Recording 3.m4a", "-vn", "-c:a",
                                    "pcm_s16le", "New Recording 3.wav"]


# MPEG-1 layer III bit rates (kbit/s) by the 4-bit index of a frame header (ISO/IEC 11172-3,
# 2.4.2.3); a frame is 144 · bit rate / sample rate bytes, plus one of padding.
_LAYER3_KBITS = (0, 32, 40, 48, 56, 64, 80, 96, 112, 128, 160, 192, 224, 256, 320)


def _drop_train(rate, seed):
    times = 0.3 + np.cumsum(0.4 * 0.9 ** np.arange(12)) - 0.4
    samples, onsets = impact_sound(times, 0.9 ** np.arange(12), sample_rate=rate, snr_db=45.0,
                                   seed=seed)
    return samples, onsets


def test_an_mp3_without_the_frame_that_counts_its_frames_is_read_whole(tmp_path):
    """A constant-bit-rate MP3 as a plain recorder writes it, with no Xing/Info frame first:
    libsndfile estimates its length from the file's size, and a complete file that falls
    short of the estimate is no cut file. One that states its length and is cut is."""
    rate = 44100
    samples, onsets = _drop_train(rate, seed=20520901)
    tagged = tmp_path / "tagged.mp3"
    sf.write(str(tagged), samples, rate, format="MP3", subtype="MPEG_LAYER_III",
             bitrate_mode="CONSTANT", compression_level=0.3)  # 224 kbit/s
    data = tagged.read_bytes()
    assert data[:3] != b"ID3" and data[0] == 0xFF  # the first frame starts the file
    length = 144 * 1000 * _LAYER3_KBITS[data[2] >> 4] // rate + (data[2] >> 1 & 1)
    assert b"Info" in data[:length] or b"Xing" in data[:length]
    plain = tmp_path / "recorder.mp3"
    plain.write_bytes(data[length:])
    with sf.SoundFile(str(plain)) as handle:  # the estimate overshoots what decodes
        decoded = iter(lambda: handle.read(4096, dtype="float32").shape[0], 0)
        assert handle.frames > sum(decoded)
    table = read_impacts(plain)
    assert len(table) == onsets.size
    # Without the frame that states the encoder's delay, the decoder cannot remove it: every
    # time is late by that delay (LAME's 1105 samples, 25 ms), the intervals are kept.
    delay = table["time"].to_numpy() - onsets
    assert 0.0 <= np.median(delay) < 0.05
    np.testing.assert_allclose(delay, np.median(delay), atol=1e-3, rtol=0)

    cut = tmp_path / "cut.mp3"
    cut.write_bytes(data[: len(data) * 6 // 10])
    with pytest.raises(InputError, match=r"cut\.mp3: truncated file: the header announces"):
        read_impacts(cut)


@pytest.mark.parametrize("name", ["take 1.bwf", "take1", "take1.dat"])
def test_audio_is_known_by_its_first_bytes_whatever_its_name(tmp_path, name):
    # A Broadcast WAV (.bwf), a recording saved without a suffix or under an odd one.
    rate = 48000
    samples, onsets = _drop_train(rate, seed=20520902)
    path = tmp_path / name
    sf.write(str(path), samples, rate, format="WAV", subtype="PCM_24")
    table = read_impacts(path)
    assert len(table) == onsets.size
    np.testing.assert_allclose(table["time"], onsets, atol=0.2e-3, rtol=0)


@pytest.mark.parametrize(("name", "head", "container", "converted"), [
    ("bounce.wav", b"\x00\x00\x00\x20ftypM4A \x00\x00\x00\x00", "MP4 / M4A",
     "bounce-converted.wav"),
    ("bounce", b"\x00\x00\x00\x20ftypisom\x00\x00\x02\x00", "MP4 / M4A", "bounce.wav"),
    ("bounce.weba", b"\x1a\x45\xdf\xa3\x9f\x42\x86\x81\x01\x42\xf7\x81", "Matroska / WebM",
     "bounce.wav"),
    ("bounce.mka", b"\x1a\x45\xdf\xa3\x9f\x42\x86\x81\x01\x42\xf7\x81", "Matroska / WebM",
     "bounce.wav"),
    ("bounce.txt", b"#!AMR\n" + bytes(10), "AMR", "bounce.wav")])
def test_media_known_by_their_first_bytes_get_the_conversion_command(tmp_path, name, head,
                                                                     container, converted):
    # The conversion never writes onto the file it reads (a .m4a saved as .wav).
    path = tmp_path / name
    path.write_bytes(head + bytes(200))
    output = tmp_path / "impacts.csv"
    status, _, err = run_cli(["impacts", str(path), "-o", str(output)])
    assert status == 2 and not output.exists()
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert f"{path}: {container} file cannot be decoded here" in lines[0]
    command = re.search(r"`(ffmpeg [^`]*)`", lines[0]).group(1)
    assert shlex.split(command) == ["ffmpeg", "-i", name, "-vn", "-c:a", "pcm_s16le", converted]
    with pytest.raises(InputError, match="convert its sound to WAV"):
        read_impacts(path, kind="audio")


@pytest.mark.parametrize(("suffix", "container", "subtype"),
                         [("aif", "AIFF", "PCM_24"), ("aifc", "AIFF", "FLOAT"),
                          ("au", "AU", "PCM_16"), ("w64", "W64", "PCM_16"),
                          ("rf64", "RF64", "PCM_16"), ("wav", "WAV", "PCM_16")])
def test_a_cut_file_of_any_container_is_refused_not_read_short(tmp_path, suffix, container,
                                                              subtype):
    # libsndfile reads a cut AIFF, AU, Wave64 or RF64 as a shorter recording without a word;
    # its header log shows the sizes the header states against those present.
    rate = 22050
    samples, onsets = _drop_train(rate, seed=20520903)
    whole = tmp_path / f"whole.{suffix}"
    sf.write(str(whole), samples, rate, format=container, subtype=subtype)
    assert len(read_impacts(whole)) == onsets.size
    data = whole.read_bytes()
    cut = tmp_path / f"cut.{suffix}"
    cut.write_bytes(data[: len(data) * 6 // 10])
    output = tmp_path / "impacts.csv"
    status, _, err = run_cli(["impacts", str(cut), "-o", str(output)])
    assert status == 2 and not output.exists()
    assert err.strip().splitlines() == [err.strip()]
    assert f"{cut}: truncated file: the header announces" in err


def test_a_cut_flac_says_where_its_decoding_failed(tmp_path):
    # FLAC frames fail to decode where the file is cut: the error names the stretch of the
    # recording being read, not the start of the file.
    rate = 22050
    samples, _ = _drop_train(rate, seed=20520904)
    whole = tmp_path / "whole.flac"
    sf.write(str(whole), samples, rate, format="FLAC", subtype="PCM_16")
    data = whole.read_bytes()
    cut = tmp_path / "cut.flac"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError) as error:
        read_impacts(cut)
    message = str(error.value)
    assert "\n" not in message and message.startswith(f"{cut}: truncated")
    start, end = (float(value) for value in re.search(
        r"decoding failed between (\d+\.\d+) s and (\d+\.\d+) s", message).groups())
    assert start <= 0.5 * samples.size / rate <= end
