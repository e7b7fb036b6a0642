"""Reading sound files for the impact detector: every container libsndfile decodes, blocks
of samples, and one-line errors for files that cannot be used (truncated, corrupt, empty)."""

from __future__ import annotations

import atexit
import os
import re
import shutil
import tempfile
from collections import OrderedDict
from pathlib import Path

import numpy as np
import soundfile as sf

from ..errors import InputError


# Every container the bundled libsndfile decodes, except header-less RAW (it cannot be opened
# without being told its layout).
_FILE_FORMATS = set(sf.available_formats()) - {"RAW"}

# Lossy codecs whose seeking libsndfile does not make sample-exact: Vorbis lands up to a
# lapped block off (libsndfile issue 885, open in 1.2.2: reads after a seek were 1664 frames
# off, or garbled); Opus and MP3 decode from a seek point after a pre-roll that need not
# reproduce the sequential decode to the last bit. Such a file is decoded once, in order,
# into a temporary copy, which every later read seeks in.
_INEXACT_SEEK_SUBTYPES = {"VORBIS", "OPUS", "MPEG_LAYER_I", "MPEG_LAYER_II", "MPEG_LAYER_III"}
_SLIPPED_BYTES = 4096  # a stated file size this far off is a writer's slip, not a cut
_MPEG_FIRST_FRAME_BYTES = 2881  # the longest MPEG audio frame (layer III, 320 kbit/s, 8 kHz)
_DECODED_COPIES_KEPT = 4  # most recently opened lossy files whose copies are kept
_DECODE_BLOCK_FRAMES = 1 << 18
_DECODED_PREFIX = "dashpot-decoded-"  # then the owning process's id and a random part


# --------------------------------------------------------------------------------------------
# Reading


_UNSET_SIZES = (0, 0xFFFFFFFF)  # sizes a recorder writes before it knows (or never closed)


class _PatchedHeaderFile:
    """A read-only file object: `header` in place of the file's first bytes, then the file.

    Lets libsndfile read a WAV whose header sizes were never filled in, without copying the
    samples.
    """

    def __init__(self, path, header):
        self._file = open(path, "rb")
        self._header = bytes(header)
        self._size = Path(path).stat().st_size
        self._position = 0

    def seek(self, offset, whence=0):
        base = {0: 0, 1: self._position, 2: self._size}[whence]
        self._position = max(0, base + offset)
        return self._position

    def tell(self):
        return self._position

    def read(self, size=-1):
        if size is None or size < 0:
            size = max(0, self._size - self._position)
        data = self._header[self._position:self._position + size]
        if len(data) < size:
            self._file.seek(self._position + len(data))
            data += self._file.read(size - len(data))
        self._position += len(data)
        return data

    def close(self):
        self._file.close()


class _RepairedSoundFile(sf.SoundFile):
    """SoundFile over a _PatchedHeaderFile that closes it too; ``repair_note`` says why."""

    def __init__(self, source, repair_note):
        super().__init__(source)
        self.source = source
        self.repair_note = repair_note

    def close(self):
        super().close()
        self.source.close()


def _wav_with_unset_sizes(path):
    """Repaired header and a note for a WAV whose data size is 0 or 0xFFFFFFFF while samples
    follow the data chunk's header (a recorder that crashed or was never stopped); None for
    any other file. The samples are taken to run to the end of the file (whole frames)."""
    size = Path(path).stat().st_size
    with open(path, "rb") as handle:
        head = handle.read(1 << 16)
    if head[:4] != b"RIFF" or head[8:12] != b"WAVE":
        return None
    position, block_align = 12, 1
    while position + 8 <= len(head):  # loop over the chunks before the samples
        chunk, length = head[position:position + 4], int.from_bytes(head[position + 4:position + 8],
                                                                    "little")
        if chunk == b"fmt " and position + 22 <= len(head):
            block_align = max(1, int.from_bytes(head[position + 20:position + 22], "little"))
        if chunk == b"data":
            break
        position += 8 + length + (length & 1)
    else:
        return None
    start = position + 8
    present = (size - start) // block_align * block_align
    if present <= 0 or length not in _UNSET_SIZES:
        return None
    header = bytearray(head[:start])
    header[4:8] = (start + present - 8).to_bytes(4, "little")
    header[position + 4:position + 8] = present.to_bytes(4, "little")
    note = (f"the WAV header gives {'no' if length == 0 else 'an unset (0xFFFFFFFF)'} size for "
            f"the samples (a recording that was not closed properly): read the {present} bytes "
            f"of samples that follow it")
    return bytes(header), note


class _DecodedCopies:
    """Temporary 32-bit float WAV copies of lossy recordings, decoded once each, in order.

    Keyed by the file's resolved path, size and modification time (an edited file is decoded
    again); the least recently used beyond :data:`_DECODED_COPIES_KEPT` are deleted, and all
    of them when the process exits. A copy takes 4 bytes per sample and channel (a
    10-minute stereo recording at 48 kHz: 230 MB) in the system's temporary folder. The
    decoders of these codecs output 32-bit floats, so the copy holds exactly the samples a
    sequential read gives. A process forked from another keeps copies of its own. The folder
    is named after its process; one whose process ended without its exit handlers (killed,
    or a worker that left through ``os._exit``) is deleted when another process makes its own.
    """

    def __init__(self):
        self._folder = None
        self._owner = None  # the process the folder and its copies belong to
        self._copies = OrderedDict()

    def copy_of(self, path, handle):
        """Path of the decoded copy of `path`, open as `handle` (read from its start)."""
        if self._owner != os.getpid():
            self._folder, self._owner, self._copies = None, os.getpid(), OrderedDict()
        stat = path.stat()
        key = (str(path.resolve()), stat.st_size, stat.st_mtime_ns)
        if key in self._copies and self._copies[key].is_file():
            self._copies.move_to_end(key)
            return self._copies[key]
        if self._folder is None:
            _remove_orphaned_copies()
            self._folder = Path(tempfile.mkdtemp(prefix=f"{_DECODED_PREFIX}{os.getpid()}-"))
            atexit.register(shutil.rmtree, self._folder, ignore_errors=True)
        # A name of its own (mkstemp): two files of one name and time must not share a copy.
        descriptor, name = tempfile.mkstemp(suffix=".wav", dir=self._folder)
        os.close(descriptor)
        copy = Path(name)
        try:
            with sf.SoundFile(str(copy), "w", samplerate=handle.samplerate,
                              channels=handle.channels, subtype="FLOAT", format="WAV") as out:
                for block in _blocks(handle, path, _DECODE_BLOCK_FRAMES, dtype="float32"):
                    out.write(block)
        except BaseException:
            copy.unlink(missing_ok=True)
            raise
        self._copies[key] = copy
        while len(self._copies) > _DECODED_COPIES_KEPT:
            _, oldest = self._copies.popitem(last=False)
            oldest.unlink(missing_ok=True)
        return copy


_DECODED = _DecodedCopies()


def _remove_orphaned_copies():
    """Delete the decoded-copy folders of processes that no longer run (POSIX only: Windows
    has no harmless probe of a process id)."""
    if os.name != "posix":
        return
    for folder in Path(tempfile.gettempdir()).glob(f"{_DECODED_PREFIX}*-*"):
        owner = folder.name[len(_DECODED_PREFIX):].split("-", 1)[0]
        if not owner.isdigit():
            continue
        try:
            os.kill(int(owner), 0)
        except ProcessLookupError:
            shutil.rmtree(folder, ignore_errors=True)
        except (PermissionError, OverflowError):  # another user's process, or not a pid
            continue


def _open(path):
    """Open `path` with libsndfile, turning every reason it cannot be used into InputError.

    A WAV whose header sizes were never filled in (0 or 0xFFFFFFFF, as a crashed recorder
    leaves them) is read from the samples present; the handle's ``repair_note`` says so. A
    lossy recording (Vorbis, Opus, MP3), whose seeking libsndfile does not make exact, is
    opened as its decoded copy (:class:`_DecodedCopies`; its ``lossy_codec`` names the codec,
    "" for other files).
    """
    from . import UNREADABLE_MEDIA, sniff_media, unreadable_media_problem

    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    if path.suffix.lower() in UNREADABLE_MEDIA:
        raise InputError(path, unreadable_media_problem(path))
    if path.stat().st_size == 0:
        raise InputError(path, "empty file (0 bytes)")
    media = sniff_media(path)
    if media not in (None, "audio"):
        raise InputError(path, unreadable_media_problem(path, media))
    try:
        repair = _wav_with_unset_sizes(path)
        if repair is None:
            handle = sf.SoundFile(str(path))
            handle.repair_note = ""
        else:
            handle = _RepairedSoundFile(_PatchedHeaderFile(path, repair[0]), repair[1])
    except (sf.LibsndfileError, RuntimeError, TypeError) as error:
        raise InputError(path, f"not a readable audio file (WAV, FLAC, OGG, MP3, AIFF, CAF or "
                               f"another format libsndfile decodes expected): "
                               f"{' '.join(str(error).split())}") from None
    if handle.format not in _FILE_FORMATS:
        handle.close()
        raise InputError(path, f"unsupported audio format {handle.format}: WAV, FLAC, OGG, "
                               f"MP3, AIFF or CAF expected")
    problem = _truncation(handle.extra_info)
    if problem:
        handle.close()
        raise InputError(path, problem)
    if handle.frames == 0:
        handle.close()
        raise InputError(path, "empty recording: the file holds no samples")
    codec = handle.subtype
    if codec in _INEXACT_SEEK_SUBTYPES:
        with handle:
            copy = _DECODED.copy_of(path, handle)
        handle = sf.SoundFile(str(copy))
        handle.repair_note = ""
    handle.lossy_codec = codec if codec in _INEXACT_SEEK_SUBTYPES else ""
    return handle


def _truncation(extra_info):
    """Plain-words problem if libsndfile's header log shows a cut-off file, else ''."""
    # The chunk of samples claims more bytes than the file holds (WAV "data : 352800 (should
    # be 176360)", AIFF "SSND", AU "Data Size"); libsndfile then silently shortens the
    # recording.
    for claimed, present in re.findall(r"^\s*(?:data|SSND|Data Size)\s*:\s*(\d+)\s*"
                                       r"\(should be (\d+)\)", extra_info, flags=re.MULTILINE):
        if int(claimed) > int(present):
            return (f"truncated file: the header announces {claimed} bytes of samples but only "
                    f"{present} are present")
    # Wave64 and RF64 state only the whole file's size ("riff : 340702 (should be 204421)"):
    # a cut where it falls short by more than a writer's slip (a pad byte, a trailing chunk).
    for claimed, present in re.findall(r"^\s*(?:riff|Riff size)\s*:\s*(\d+)\s*"
                                       r"\(should be (\d+)\)", extra_info, flags=re.MULTILINE):
        if int(claimed) - int(present) > max(_SLIPPED_BYTES, 0.01 * int(claimed)):
            return (f"truncated file: the header announces {claimed} bytes but only {present} "
                    f"are present")
    # OGG: a complete stream ends with a page carrying the end-of-stream flag.
    if "Last page lacks an end-of-stream bit" in extra_info:
        return "truncated file: the Ogg stream ends without its end-of-stream page"
    return ""


def _counts_its_frames(handle, path):
    """Whether the file states its number of frames, so that fewer read means a cut.

    Every container does but MP3: libsndfile takes an MP3's count from the Xing/Info (or
    VBRI) frame an encoder writes first, and without one estimates it from the file's size
    and the first frame's bit rate, which a complete file need not meet. The tag is looked
    for in the first frame, after an ID3v2 tag (its size is a 28-bit syncsafe integer,
    ID3v2.4 section 3.1).
    """
    if handle.format != "MP3":
        return True
    with open(path, "rb") as stream:
        head = stream.read(10)
        tagged = head[:3] == b"ID3" and len(head) == 10
        stream.seek(10 + sum((head[6 + k] & 0x7F) << (7 * (3 - k)) for k in range(4))
                    if tagged else 0)
        first_frame = stream.read(_MPEG_FIRST_FRAME_BYTES)
    return any(tag in first_frame for tag in (b"Xing", b"Info", b"VBRI"))


def _blocks(handle, path, block_frames, dtype="float64"):
    """Yield consecutive blocks of shape (frames, channels) until the end of file: float64
    in full scale, or, with ``dtype="int16"``, a 16-bit file's samples as stored."""
    expected = handle.frames
    seen = 0
    # Integer samples cannot be NaN or infinite: only float files are checked.
    integer = handle.subtype.startswith("PCM_") or handle.subtype in ("ULAW", "ALAW")
    while True:
        try:
            block = handle.read(block_frames, dtype=dtype, always_2d=True)
        except (sf.LibsndfileError, RuntimeError) as error:
            # The block read at once fails as a whole: where inside it is not known.
            end = min(seen + block_frames, max(expected, seen))
            raise InputError(path, f"truncated or corrupt file: decoding failed between "
                                   f"{seen / handle.samplerate:.3f} s and "
                                   f"{end / handle.samplerate:.3f} s ({error})") from None
        if block.shape[0] == 0:
            break
        if not integer and not np.all(np.isfinite(block)):
            bad = seen + int(np.argmax(~np.all(np.isfinite(block), axis=1)))
            raise InputError(path, f"non-finite sample (NaN or infinity) at "
                                   f"{bad / handle.samplerate:.6f} s")
        seen += block.shape[0]
        yield block
        if block.shape[0] < block_frames:
            break
    if seen < expected and _counts_its_frames(handle, path):
        raise InputError(path, f"truncated file: the header announces {expected} frames, only "
                               f"{seen} could be read")



# Largest recording (bytes of its samples as read) whose samples the detection keeps in memory
# for the stretches its later steps read again: 64 MiB, about 5.8 min of 16-bit stereo at
# 48 kHz (the stream holds 23 MB of float64 for a 30 s block at any length).
_KEPT_BYTES = 64 * 2**20
_JOIN_READS_SECONDS = 0.05  # stretches of the file closer than this (s) are read as one


class _Recording:
    """The samples of a recording that the later steps of the detection read again.

    The probes of predicted impacts and the retiming of onsets read stretches of a few ms
    around each impact. Where the whole recording's samples as read by :func:`_blocks` take
    at most :data:`_KEPT_BYTES`, those blocks are kept (:meth:`keep`, then :meth:`close`) and
    the stretches are taken from them: opening the file and seeking in it costs more than the
    stretch itself. Longer recordings are read again from the file, so that memory stays
    bounded. Either way the values are the same: libsndfile converts a 16-bit sample to float
    as the sample times 2⁻¹⁵ (exact), as here, and the other formats are kept as the float64
    it decoded.

    Parameters
    ----------
    path : str or os.PathLike
        The recording (opened with :func:`_open`).
    frames : int
        Its length (frames).
    scale : float
        Full scale per unit of the blocks kept (2⁻¹⁵ for int16, else 1).
    """

    def __init__(self, path, frames, scale=1.0):
        self.path, self.frames, self.scale = path, int(frames), float(scale)
        self._blocks, self._bytes = [], 0
        self._firsts = None  # first frame of each block kept, once all are

    def keep(self, block):
        """Keep the next `block` (frames, channels) of the file as read, while the recording
        fits :data:`_KEPT_BYTES`."""
        if self._blocks is None:
            return
        self._bytes += block.nbytes
        self._blocks = self._blocks + [block] if self._bytes <= _KEPT_BYTES else None

    def close(self):
        """End of the file: the blocks kept are used if they hold the whole recording."""
        if self._blocks:
            lengths = [block.shape[0] for block in self._blocks]
            if sum(lengths) == self.frames:
                self._firsts = np.cumsum([0] + lengths[:-1])
                for block in self._blocks:
                    block.flags.writeable = False
                return
        self._blocks = None

    @property
    def kept(self):
        """Whether the stretches come from the samples kept in memory."""
        return self._firsts is not None

    def _kept_frames(self, start, stop):
        """Frames `start` to `stop` (within the recording) of the blocks kept, as read: a view
        where they lie in one block."""
        first = int(np.searchsorted(self._firsts, start, side="right")) - 1
        offset = start - int(self._firsts[first])
        block = self._blocks[first]
        if stop - start <= block.shape[0] - offset:
            return block[offset:offset + stop - start]
        pieces, remaining = [], stop - start
        while remaining > 0:
            piece = self._blocks[first][offset:offset + remaining]
            pieces.append(piece)
            remaining -= piece.shape[0]
            first, offset = first + 1, 0
        return np.concatenate(pieces)

    def _as_read(self, samples):
        """Kept samples as float64 full scale, as ``read(dtype="float64")`` gives them."""
        return samples.astype(np.float64) * self.scale if self.scale != 1.0 else samples

    def stretch(self, start, stop):
        """Frames `start` to `stop` (clipped to the recording): (first frame, samples as
        float64 full scale, shape (frames, channels); read-only where kept)."""
        start, stop = max(0, int(start)), min(self.frames, int(stop))
        if self.kept and start < self.frames:
            return start, self._as_read(self._kept_frames(start, max(stop, start)))
        with _open(self.path) as handle:
            handle.seek(start)
            return start, handle.read(max(stop - start, 0), dtype="float64", always_2d=True)

    def stretches(self, starts, length, channel):
        """Channel `channel` of the stretches of `length` frames from each of `starts`
        (frames, all within the recording), as float64 full scale: shape (starts, length)."""
        starts = np.asarray(starts, dtype=np.int64)
        if self.kept and len(self._blocks) == 1:
            return np.array(self._as_read(
                self._blocks[0][starts[:, None] + np.arange(length)[None, :], channel]))
        out = np.empty((starts.size, length))
        if self.kept:
            for row, start in enumerate(starts.tolist()):
                out[row] = self._as_read(self._kept_frames(start, start + length)[:, channel])
            return out
        with _open(self.path) as handle:
            # Stretches less than 50 ms apart are read in one piece (a read costs about as
            # much as decoding that long a stretch).
            gap = int(_JOIN_READS_SECONDS * handle.samplerate)
            breaks = np.flatnonzero(np.diff(starts) > length + gap) + 1
            for group in np.split(np.arange(starts.size), breaks):
                if group.size == 0:
                    continue
                first = int(starts[group[0]])
                handle.seek(first)
                piece = handle.read(int(starts[group[-1]]) + length - first, dtype="float64",
                                    always_2d=True)[:, channel]
                out[group] = piece[(starts[group] - first)[:, None] + np.arange(length)[None, :]]
        return out


# Subtypes stored as integers of the width their name ends with.
_INTEGER_SUBTYPE = re.compile(r"(?:PCM|ALAC|DWVW|DPCM)_[SU]?(\d+)")
# Float subtypes: the spacing of their values just below full scale (1), eps/2 of the type.
_FLOAT_STEPS = {"FLOAT": np.finfo(np.float32).eps / 2, "DOUBLE": np.finfo(np.float64).eps / 2}


def _quantization_noise(subtype):
    """RMS of the rounding error of a sample format: step/√12 (full scale).

    A stored sample pins its signal down to a step of the format only: the rounding error is
    spread uniformly over the step, with this RMS [1]_. So no channel is judged against less
    noise than this, whatever its quiet stretches measure: one that measures less (digital
    silence with rare one-step blips, as an unconnected input of some interfaces records)
    holds nothing a noise level could be estimated from, and against its estimate (about
    zero) its blips would be enormous transients.

    Parameters
    ----------
    subtype : str
        libsndfile's name of the sample format (``SoundFile.subtype``).

    Returns
    -------
    float
        Step of the format (full scale = 1) over √12: 2⁻⁽ᵇ⁻¹⁾/√12 for b-bit integers. Floats
        have no fixed step (it shrinks with the level); they take the spacing of their values
        just below full scale (2⁻²⁴ for 32 bits, whose 24 significant bits resolve a
        full-scale sound as finely as 25-bit integers), finer than the step of the 24-bit
        converters that record any real sound. Codecs that libsndfile decodes into 16-bit
        words (µ-law, A-law, ADPCM, GSM, G.72x) take the 16-bit step, a lower bound of their
        coarser resolution.

    References
    ----------
    .. [1] B. Widrow and I. Kollár, "Quantization Noise", Cambridge University Press (2008)
       (the uniform model of the quantization error and its variance, q²/12).
    """
    if subtype in _FLOAT_STEPS:
        step = float(_FLOAT_STEPS[subtype])
    else:
        integer = _INTEGER_SUBTYPE.fullmatch(subtype)
        bits = int(integer.group(1)) if integer else 16
        step = 2.0 ** -(bits - 1)
    return step / np.sqrt(12.0)


def _check_block_seconds(block_seconds):
    if not np.isfinite(block_seconds) or block_seconds <= 0:
        raise ValueError(f"block_seconds must be a positive number of seconds; got "
                         f"{block_seconds!r}")


def read_audio(path, *, block_seconds=10.0):
    """Samples and sample rate of a recording libsndfile decodes (WAV, FLAC, OGG, MP3, AIFF, …).

    Parameters
    ----------
    path : str or os.PathLike
        The recording: any sample rate; 8/16/24/32-bit integer or 32/64-bit float samples;
        any number of channels.
    block_seconds : float, default 10
        Length of the blocks the file is decoded in (s). The whole recording ends up in memory;
        :func:`detect_impacts` streams instead.

    Returns
    -------
    samples : ndarray of float64, shape (frames, channels)
        Full scale = 1 (integer formats map to [-1, 1)).
    sample_rate : int
        Samples per second (Hz).

    Raises
    ------
    InputError
        Missing, empty (0 bytes or no samples), truncated, non-audio or corrupt file, or
        non-finite samples.
    """
    _check_block_seconds(block_seconds)
    with _open(path) as handle:
        block_frames = max(1, int(round(block_seconds * handle.samplerate)))
        samples = np.concatenate(list(_blocks(handle, path, block_frames)), axis=0)
        return samples, int(handle.samplerate)


