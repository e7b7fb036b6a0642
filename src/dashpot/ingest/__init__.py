"""Readers that turn what a lab recorded into one table of impacts.

Every reader returns a :class:`pandas.DataFrame` with one row per impact, sorted by time, and
these columns (SI units):

=====================  ======  =============================================================
column                 unit    meaning
=====================  ======  =============================================================
``time``               s       impact time (audio: onset of the impact transient)
``time_uncertainty``   s       1σ uncertainty of ``time``
``amplitude``          1       peak amplitude of the transient, full scale = 1 (NaN if none)
``impact_speed``       m/s     measured speed just before the impact (NaN if not measured)
``rebound_speed``      m/s     measured speed just after the impact (NaN if not measured)
``speed_uncertainty``  m/s     1σ uncertainty of the speeds (NaN if not measured)
``run``                –       run index for files holding several runs side by side (0 if one)
``flag`` (optional)    –       "ok", or why the impact is less certain: "few_samples" (a motion
                               sensor's reversal with fewer than two free-flight samples on a
                               side: timed from what there is, speeds NaN where unmeasured),
                               "inferred" (a contact whose reversal the samples do not show,
                               placed where the flight before it must have ended)
=====================  ======  =============================================================

Optional columns of the speeds' correlated errors (the motion reader writes
MOTION_SPEED_ERROR_COLUMNS, between ``run`` and ``flag``; a table without them has
independent speed errors of σ ``speed_uncertainty``; NaN where the speed is not measured):

============================  ====  ========================================================
column                        unit  meaning
============================  ====  ========================================================
``impact_speed_shared_<j>``   m/s   shift of ``impact_speed`` per +1σ of the run's j-th
                                    shared error (j = 1, 2, ...; the run's errors are
                                    independent N(0, 1) and common to all its rows; the
                                    motion reader's: its two fitted leg accelerations, as
                                    two independent components, and its bumper position)
``rebound_speed_shared_<j>``  m/s   the same for ``rebound_speed``
``impact_speed_own``          m/s   1σ of the rest of ``impact_speed``'s error (without it:
                                    what ``speed_uncertainty`` leaves after the shared
                                    parts)
``rebound_speed_own``         m/s   the same for ``rebound_speed``
``flight_correlation``        1     correlation of this row's rebound-speed own error with
                                    the next row's (same run) impact-speed own error: both
                                    are read from the flight between them (empty: none)
============================  ====  ========================================================

``DataFrame.attrs`` holds ``source`` (the file), ``sensor`` (the reader's kind) and ``notes``
(a list of plain-words remarks, e.g. which time unit was inferred); ``warnings``, where
present, are those of the notes a user must see beside any result drawn from the table (a
lossy-coded recording, a WAV read past its broken header), which ``dashpot fit`` and
``analyze`` print with their fits. Bad input raises
:class:`dashpot.errors.InputError` naming the file, the row where it applies, and the problem.
"""

IMPACT_COLUMNS = ("time", "time_uncertainty", "amplitude", "impact_speed", "rebound_speed",
                  "speed_uncertainty", "run")
FLAG_COLUMN = "flag"
"""Optional last column of a reader that grades its impacts (the motion sensor's)."""
SPEED_OWN_COLUMNS = ("impact_speed_own", "rebound_speed_own")
FLIGHT_CORRELATION_COLUMN = "flight_correlation"
SHARED_SPEED_COLUMN = r"(impact|rebound)_speed_shared_([1-9][0-9]*)"
"""Regular expression of the shared-error columns (group 1 the speed, group 2 j)."""
MOTION_SPEED_ERROR_COLUMNS = (
    tuple(f"{speed}_speed_shared_{j}" for speed in ("impact", "rebound") for j in (1, 2, 3))
    + SPEED_OWN_COLUMNS + (FLIGHT_CORRELATION_COLUMN,))
"""The columns of the speeds' correlated errors the motion reader writes, in order, between
``run`` and ``flag``."""


def is_speed_error_column(name):
    """True for a column of the speeds' correlated errors (this module's docstring)."""
    import re

    name = str(name)
    return (name in SPEED_OWN_COLUMNS or name == FLIGHT_CORRELATION_COLUMN
            or re.fullmatch(SHARED_SPEED_COLUMN, name) is not None)

import shlex
from pathlib import Path

from ..errors import InputError, require_file

AUDIO_SUFFIXES = (".wav", ".wave", ".flac", ".ogg", ".oga", ".opus", ".mp3", ".aif", ".aiff",
                  ".aifc", ".caf", ".au", ".snd", ".w64", ".rf64")
"""File names read as audio: what the libsndfile bundled with soundfile decodes (its
``available_formats()``: WAV, FLAC, Ogg Vorbis/Opus, MP3, AIFF, CAF, AU, W64, RF64)."""
UNREADABLE_MEDIA = (".m4a", ".mp4", ".m4v", ".aac", ".mov", ".avi", ".mkv", ".webm", ".3gp",
                    ".wma", ".wmv", ".amr")
"""Phone and camera recordings libsndfile cannot decode (AAC, AMR or WMA sound; video
containers): refused with the conversion command to a WAV file."""
KINDS = ("audio", "phyphox", "timestamps", "motion_sensor", "photogate")

# The first bytes of the containers libsndfile decodes, whatever a file is named (a Broadcast
# WAV saved as .bwf, a recording without a suffix): (offset, bytes) pairs that must all match.
_AUDIO_SIGNATURES = (((0, b"RIFF"), (8, b"WAVE")), ((0, b"RIFX"), (8, b"WAVE")),
                     ((0, b"RF64"),), ((0, b"BW64"),), ((0, b"riff"),),
                     ((0, b"FORM"), (8, b"AIF")), ((0, b"fLaC"),), ((0, b"OggS"),),
                     ((0, b"caff"),), ((0, b".snd"),), ((0, b"ID3"),))
# ... and of those it does not: MP4 / M4A / 3GP / MOV ('ftyp' box), Matroska / WebM (EBML),
# AMR, ASF (WMA / WMV).
_UNREADABLE_SIGNATURES = {"MP4 / M4A": ((4, b"ftyp"),),
                          "Matroska / WebM": ((0, b"\x1aE\xdf\xa3"),),
                          "AMR": ((0, b"#!AMR"),),
                          "ASF (WMA / WMV)": ((0, b"\x30\x26\xb2\x75\x8e\x66\xcf\x11"),)}


def sniff_media(path):
    """What the first bytes of `path` say it holds: "audio" (a container libsndfile decodes),
    the name of a container it does not decode (:data:`UNREADABLE_MEDIA`), or None (no
    sound file: a table, or unknown).

    Container signatures: WAV/RIFF, RF64/BW64, Sony Wave64, AIFF/AIFC (``FORM``), FLAC,
    Ogg, CAF, Sun AU, MP3 (an ID3 tag or an MPEG audio frame of layer II or III); ISO base
    media (``ftyp``), EBML, AMR and ASF headers for those it does not.
    """
    with open(path, "rb") as handle:
        head = handle.read(16)

    def matches(signature):
        return all(head[offset:offset + len(magic)] == magic for offset, magic in signature)

    for container, signature in _UNREADABLE_SIGNATURES.items():
        if matches(signature):
            return container
    # An MPEG audio frame starts with 11 set sync bits, then the version and the layer: layer
    # III or II (bits 01, 10). Layer I (11) is left out: its FF FE-FF FF start is a UTF-16
    # byte order mark, with which a spreadsheet's "Unicode text" table begins.
    mpeg_frame = (len(head) >= 2 and head[0] == 0xFF and head[1] & 0xE0 == 0xE0
                  and head[1] & 0x06 in (0x02, 0x04))
    if mpeg_frame or any(matches(signature) for signature in _AUDIO_SIGNATURES):
        return "audio"
    return None


def read_impacts(path, *, kind=None, flag_length=None, gate_distance=None, unit=None,
                 bumper_position=None, track=None):
    """Impact table of any supported recording, choosing the reader from the file.

    Parameters
    ----------
    path : str or os.PathLike
        Audio recording (WAV, FLAC, OGG, MP3, AIFF, CAF, ...: see ``AUDIO_SUFFIXES``) or lab
        table (CSV/TSV/semicolon text, .xlsx, .xls, .ods, Tracker text export).
    kind : {"audio", "phyphox", "timestamps", "motion_sensor", "photogate"}, optional
        Reader to use; by default audio from the file suffix, tables by their headers
        ("motion_sensor" also reads Tracker's video-analysis exports).
    flag_length : float, optional
        Length of the flag interrupting a photogate, in m (required for photogate logs).
    gate_distance : float, optional
        Distance from the photogate to the bumper in m (times photogate impacts exactly).
    unit : {"s", "ms"}, optional
        Time unit of a timestamp table, where its header does not say.
    bumper_position : float, optional
        Position of the bumper in m for motion-sensor exports (else inferred).
    track : str, optional
        Which track of a Tracker export holding several (e.g. "mass A"); needed only where
        more than one track has points.

    Returns
    -------
    pandas.DataFrame
        The impact table described in this module's docstring.

    Raises
    ------
    InputError
        The file does not exist, is not a supported recording (a phone's .m4a or a video:
        the message gives the ffmpeg command that extracts a WAV), its content is unusable,
        it holds no impact (an empty table is never returned: its reader's notes say why), or
        an option is given that the reader of this kind of file does not use (it would be
        ignored: `flag_length` and `gate_distance` are for photogates, `unit` for timestamp
        tables, `bumper_position` and `track` for motion sensors).
    """
    impacts = _read(path, kind, flag_length, gate_distance, unit, bumper_position, track)
    if impacts.empty:
        notes = "; ".join(impacts.attrs.get("notes", []))
        raise InputError(path, "no impacts found" + (f" ({notes})" if notes else ""))
    return impacts


def unreadable_media_problem(path, container=None):
    """The one-line problem for a recording libsndfile cannot decode, with its conversion.

    Parameters
    ----------
    path : str or os.PathLike
        The recording (e.g. a phone's ``.m4a`` or a video whose sound track holds the impacts).
    container : str, optional
        The container its first bytes show (:func:`sniff_media`), where its name does not.

    Returns
    -------
    str
        What is wrong and the ffmpeg command that extracts the sound as a WAV file.
    """
    path = Path(path)
    kind = "video" if path.suffix.lower() in (".mp4", ".m4v", ".mov", ".avi", ".mkv", ".webm",
                                              ".3gp", ".wmv") else "audio"
    what = f"{path.suffix.lower()} {kind}" if container is None else f"{container} file"
    # Quoted for the shell: phone recordings are often named with spaces ("New Recording 3").
    # A file named .wav that is none is converted to another name, never onto itself.
    target = (path.with_name(f"{path.stem}-converted.wav") if path.suffix.lower() == ".wav"
              else path.with_suffix(".wav"))
    source, target = shlex.quote(path.name), shlex.quote(target.name)
    return (f"{what} cannot be decoded here (readable: WAV, FLAC, OGG, "
            f"MP3, AIFF, CAF, ...); convert its "
            f"sound to WAV first, e.g. `ffmpeg -i {source} -vn -c:a pcm_s16le {target}`")


# The reader each option is for: an option given for another reader would be ignored, and
# the user would believe it applied.
_READER_OPTIONS = {"flag_length": "photogate", "gate_distance": "photogate",
                   "unit": "timestamps", "bumper_position": "motion_sensor",
                   "track": "motion_sensor"}


def _check_reader_options(path, kind, **options):
    """Raise InputError naming the first of `options` given (not None) that the reader
    `kind` does not use."""
    for name, value in options.items():
        if value is not None and _READER_OPTIONS[name] != kind:
            raise InputError(path, f"{name} (--{name.replace('_', '-')}) is for "
                                   f"{_READER_OPTIONS[name].replace('_', '-')} files, and "
                                   f"this file is read as {kind.replace('_', '-')}: leave it "
                                   f"out, or give the kind of file (--kind)")


def _read(path, kind, flag_length, gate_distance, unit, bumper_position, track):
    """The impact table of the reader `kind` chooses (see read_impacts)."""
    path = Path(path)
    require_file(path)
    if path.suffix.lower() in UNREADABLE_MEDIA:
        raise InputError(path, unreadable_media_problem(path))
    media = sniff_media(path)
    if media not in (None, "audio"):
        raise InputError(path, unreadable_media_problem(path, media))
    if kind is None:
        if path.suffix.lower() in AUDIO_SUFFIXES or media == "audio":
            kind = "audio"
        else:
            from .tables import sniff_table

            kind = sniff_table(path)
    if kind not in KINDS:
        raise InputError(path, f"unknown kind {kind!r}; use one of {', '.join(KINDS)}")
    _check_reader_options(path, kind, flag_length=flag_length, gate_distance=gate_distance,
                          unit=unit, bumper_position=bumper_position, track=track)
    if kind == "audio":
        from .audio import detect_impacts

        return detect_impacts(path)
    from . import tables

    if kind == "phyphox":
        return tables.read_phyphox(path)
    if kind == "timestamps":
        return tables.read_timestamps(path, unit=unit)
    if kind == "motion_sensor":
        return tables.read_motion_sensor(path, bumper_position=bumper_position, track=track)
    if flag_length is None:
        raise InputError(path, "a photogate log needs the flag length (--flag-length, in m)")
    return tables.read_photogate(path, flag_length=flag_length, gate_distance=gate_distance)
