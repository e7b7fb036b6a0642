"""Impacts of a bouncing ball from a sound recording (WAV, FLAC, OGG, MP3, AIFF, CAF, ...).

:func:`detect_impacts` streams the file in blocks of 30 s and returns the impact table of
:mod:`dashpot.ingest`; :func:`read_audio` reads a whole (short) recording into memory. Both
raise :class:`dashpot.errors.InputError` on files that cannot be used.

Method, in five steps, each explained where it is implemented: reading in
:mod:`.audio_file`, steps 1-2 (the power envelope and its trigger) in :mod:`.envelope`, step 3
(the chain of impacts) in :mod:`.chain`, step 4 (the onset fit) in :mod:`.onset`; this module
runs them over the file.

1. Detection. Every channel is high-passed (causal Butterworth, 100 Hz: removes DC offset, hum
   and handling rumble without moving an onset earlier), whitened by the lag-1 prediction of
   its own noise and divided by the noise level; the channels are combined as the mean of
   these noise-normalised powers, the statistic of an energy detector for a signal of unknown
   shape in independent noise, which cannot cancel between channels the way a sum of the
   waveforms can (the two microphones of a stereo recording hear the same impact with
   different delays and polarities). No channel's noise is taken below the quantization
   noise of the file's samples (step/√12), and a channel that records less (a dead input:
   digital silence, save rare one-step blips) is left out of the mean and of the timing
   while another channel records noise (:func:`.envelope._heard`). A channel whose loudest
   sounds rise more than 10 dB less over its noise than the best channel's is left out of
   the mean in that block (:func:`.envelope._shares`: a channel of noise alone, or one far
   from the impacts, would add its noise and little of their sound), and only channels
   within 3 dB of the best SNR time the onsets. A transient is a jump of this power over
   0.5 ms against the 2 ms before it (an STA/LTA trigger [1]_): strong above 9 dB, weak
   above 6 dB.
2. Rough onset: the Akaike-information-criterion picker [2]_ on the 3 ms before each trigger
   (but not into the transient triggered before it) finds where the power leaves the level
   before it, which catches a weak first arrival preceding the loud part of a transient;
   where that stretch lasts 0.5 ms or more and the power then jumps 3 dB over it, it is a
   sound of its own (the ring or echo of an earlier impact) and the onset is the later jump.
   Triggers within 1 ms of a kept onset belong to that transient unless 9 dB louder.
3. Selection by physics: the impacts of a ball bouncing to rest are the best chain of strong
   transients whose successive intervals shrink roughly geometrically, found by dynamic
   programming against a smooth trend of the interval ratio; ringing, echoes and rattles
   (weaker, and at a fixed delay after their impact) and noise break that trend. Members
   are then swapped for nearby transients that fit the trend better; its last impacts are
   chosen again among all transients, weak ones included; and the chain is followed past its
   end where the trend, refitted on fitted onsets, predicts further impacts, leaving out
   transients at the recurring delay of a ring or echo after an impact. Members at the
   recurring delay of a ring's burst or an echo after a louder transient left out are then
   moved onto it (:func:`_back_to_louder_causes`). Finally the trend, refitted robustly on
   the timed impacts, is walked once more: where it predicts an impact
   that no transient marks (the last bounces, a few ms apart, barely rise over the decaying
   sound of the earlier ones) or an impact was timed at the start of a ring or echo
   beginning just before it, the file is read again around the predicted time and probed
   with a trigger measured against the quietest 0.5 ms before it, or against the ring or
   echo since its start (:func:`_fill_impacts`; an impact's onset less than 2 ms after a
   ring's burst or an echo began may be on that sound's rise, and is probed again past its
   start); an impact whose onset does not rise out of that ring or echo (nor shows in the
   error of a linear predictor of it, below) is left out (a gap the fit flags as a missed
   impact), never placed where the trend predicts it: that would be circular evidence for
   the fit that follows.
   No sound after the rest time the trend gives its last impacts is one
   (:func:`_rest_time`); the train then ends before its first interval that grows and
   after which the sounds do not come back to shorter intervals, and does not end on a
   sound at the delay of a recurring ring, burst or echo after an earlier impact that is
   no louder than such a secondary, nor on one that sets off none of the secondaries every
   impact before it sets off (:func:`_train_end`). An impact that starts on the loud ring
   of the one before barely raises the power; it is looked for in the error of a linear
   predictor of that sound [6]_ (a ring is a sum of damped sinusoids, which the predictor
   continues; a new impact is an impulse into the same resonances): one recurring burst
   delay before each burst the chain took (:func:`_hidden_causes`), and wherever the trend
   predicts an impact the whitened power does not show. A sound that sets off an impact's
   secondaries is an impact whatever ring or echo falls on it
   (:func:`_sets_off_secondaries`). A chain refused as no bounce train is chosen once more
   without the transients at a recurring secondary delay after louder ones
   (:func:`_explained_secondaries`: evenly spaced bursts and rings form a chain of their
   own), a third time with the delays measured after that second
   chain's impacts, a fourth without the first chain's members that are echoes of louder
   transients (:func:`_echoing_members`; each taken only if it passes), then each again
   with the weak transients too, and last without the transients at a recurring delay
   after one they may outsound (a ring's burst louder than its impact), and judged again
   once bursts hiding impacts and missed impacts are resolved. A chain that passes is
   chosen once more without its members that echo louder transients it left out (it
   followed an echo of the train), and that choice taken if it passes too and at most one
   in ten of its members is a secondary of its own impacts; where it is not, once more
   without every transient at that echo's delay after a louder one, the weak transients
   just after those counting as strong, and taken on the same terms if it holds at least
   the impacts the first chain held besides its echoes. There is no fixed dead time.
4. Onset time: the posterior of the onset under a Bayesian change-point model of the rising
   edge, fitted to the high-passed waveform of the channel with the best onset SNR (see
   :func:`_onset_posterior`). It gives sub-sample times and a 1σ uncertainty from the local
   noise and the steepness of the edge, with floors for the misfit of the edge model and for
   the sub-sample error, calibrated so that about 68 % / 95 % of the true errors of synthetic
   impacts fall within 1σ / 2σ. The onset of an impact is where its first burst starts: a
   real impact sound may open with a burst a third to four fifths as loud as a second one
   1-2 ms later, and the fit, whose window sits on one rising edge, may have timed the
   second. Each impact's stretch of the file is read again, and where a burst rises through
   a fifth of the impact's peak from 2 ms to 0.25 ms before the fitted onset and lasts into
   it, the onset is fitted again on that burst (:func:`_retime_on_first_burst`). An onset
   fitted on a faint sound of its own that dies away before the impact's rise through a
   fifth of its peak, or late on that rise, is timed at the rise's edge; where the rise is
   not clear of the sound before it, the 1σ covers the gap to it. The stated 1σ counts the
   fit's at half its width on a sharp edge (rising within a sample), where its posterior
   reaches back over slower starts the edge did not take, and covers the onset's ambiguity
   where a ring, burst or echo of an earlier impact starts near it (:func:`_stated_sigmas`).
5. Drops: steps 3-4 run on the whole recording, and again on the stretches before and after
   the train found, for other drops of the same ball (:func:`_impact_table`); each is a run.
   A chain refused as no bounce train is also chosen again without the periodic clicks it
   followed (a ball at rest, a clock; :func:`dashpot.ingest.chain._periodic_members`).

References
----------
.. [1] R. V. Allen, "Automatic earthquake recognition and timing from single traces", Bull.
   Seismol. Soc. Am. 68(5), 1521-1532 (1978).
.. [2] R. Sleeman and T. van Eck, "Robust automatic P-phase picking: an on-line implementation
   in the analysis of broadband seismogram recordings", Phys. Earth Planet. Inter. 113,
   265-275 (1999) (the AIC picker of N. Maeda, Zisin 38, 365-379, 1985).
.. [3] C. M. Bishop, "Pattern Recognition and Machine Learning", Springer (2006), sections
   3.3-3.5 (Bayesian linear regression and its marginal likelihood).
.. [4] S. O. Rice, "Mathematical analysis of random noise", Bell Syst. Tech. J. 23, 282-332
   (1944) (mean-square frequency from the variance of the derivative).
.. [5] T. Erickson, "Modeling a bouncing ball with exponential functions and infinite
   series", Mathematics Teacher 113(3), 233-236 (2020) (geometric shrinking of the intervals).
.. [6] J. Glover, V. Lazzarini and J. Timoney, "Real-time detection of musical onsets with
   linear prediction and sinusoidal modeling", EURASIP J. Adv. Signal Process. 2011, 68
   (2011).
.. [7] M. Bosi and R. E. Goldberg, "Introduction to Digital Audio Coding and Standards",
   Kluwer (2003) (pre-echo: a transform block's quantization noise spread before a
   transient, and the short blocks coders switch to at transients).
"""

from __future__ import annotations

import copy
import warnings

import numpy as np
import pandas as pd
from scipy import signal

from ..errors import InputError
from ..plausibility import NOT_A_BOUNCE_TRAIN, bounce_train_problem
from . import IMPACT_COLUMNS
from .audio_file import _blocks, _open, _quantization_noise, _Recording, read_audio
from .chain import (_MASK_SECONDS, _SECONDARY_MARGIN, _SECONDARY_SECONDS, _drop_start,
                    _echoed_tail, _echoing_members, _explained_secondaries, _fill_impacts,
                    _first_pass, _fixed_delays, _hidden_causes, _loudest_before, _louder_between,
                    _one_per_impact, _periodic_members, _probe, _rest_time, _robust_trend,
                    _recurring_secondaries, _select_bounces, _train_end)
from .chain import _best_chain  # noqa: F401 - where the plausibility tests import it from
from .envelope import (_AIC_MARGIN, _HIGHPASS_ORDER, _MERGE_SECONDS, _NOISE_FLOOR,
                       _STA_SECONDS, MIN_SAMPLE_RATE, _heard, _process, _Settings, _Stream)
from .onset import (_AMBIGUITY_REACH_SECONDS, _BURST_BACKGROUND, _BURST_BACKGROUND_SECONDS,
                    _BURST_MIN_LEAD_SECONDS, _BURST_REACH_SECONDS, _edge_samples, _first_burst,
                    _one_sound, _onset_posterior, _onset_reach, _rise_crossing, _rise_samples,
                    _stated_sigma)


__all__ = ["read_audio", "detect_impacts"]

# A rise this long after a ring or echo of an earlier impact starts may be that sound's.
_SECONDARY_REACH_SECONDS = 2e-3
_RESETTLE_SECONDS = 0.02  # s of the file read before a stretch, for the high-pass to settle
# A transient this long (s) before one this many times louder is that one's pre-echo
# (_without_pre_echoes).
_PRE_ECHO_SECONDS = 6e-3
_PRE_ECHO_LOUDNESS = 10.0
# The file is analysed in blocks of this length (s): the noise each is judged against is its
# own, so the blocks are fixed on the file's timeline and no option moves them.
_BLOCK_SECONDS = 30.0
_FILL_PASSES = 3  # passes of the search for impacts the trend predicts, at most
_END_IMPACTS = 4  # the last impacts, whose change lets a further pass go on past them
_SHORT_CHOICE = 0.5  # a passing choice with fewer than this share of the first's members
_SECONDARY_MEMBERS_SHARE = 0.1  # of a chain chosen without an echo that may be secondaries
# Several drops in one recording (_other_drop): another train holds this many impacts at least,
_MIN_RUN_IMPACTS = 6
_RUN_COUNT_FACTOR = 3.0  # ... and as many as the first train found within this factor;
_RUN_RATIO_SPREAD = 0.1  # its median interval ratio is the first's within this, in log;
_RUN_SHRINK = 0.5  # its last interval is less than this share of its first;
_RUN_LOUDNESS = 10.0  # its loudest impact is within this factor of the first train's;
_FIRST_PASS_SHARE = 0.5  # of its impacts, at least, the chain's first pass finds
_MAX_REST_RATIO = 0.99  # flight ratio after the last impact of a train, for its rest time
_ECHO_TOLERANCE_SECONDS = 0.3e-3  # an echo's impacts repeat its source's at one delay,
_ECHO_WEAKENING = 1.5  # ... each this many times fainter at least (3.5 dB)
# and lies this long (s) past the last impact of the one before: its rings and echoes (2 ×
# the longest secondary delay, as chain._echoing_members looks for them).
_AFTER_TRAIN_SECONDS = 2 * _SECONDARY_SECONDS

# --------------------------------------------------------------------------------------------
# Public entry point


def detect_impacts(path, *, highpass_hz=100.0, min_snr_db=12.0, min_jump_db=9.0,
                   block_seconds=None):
    """Impact table of a recording of a ball bouncing to rest.

    Parameters
    ----------
    path : str or os.PathLike
        A recording libsndfile decodes (WAV, FLAC, OGG, MP3, AIFF, CAF, ...); sample rate at
        least :data:`MIN_SAMPLE_RATE` (8 kHz); 8/16/24/32-bit integer or float samples; any
        number of channels.
    highpass_hz : float, default 100
        Cut-off (Hz) of the 2nd-order causal Butterworth high-pass applied before detection
        and timing: removes DC offset and rumble. Being causal it cannot move an onset
        earlier. Mains hum and buzz (lines at 50 or 60 Hz and their harmonics to 1 kHz, found
        at the file's start) are notched out with it, and a note lists the lines.
    min_snr_db : float, default 12
        A transient must carry at least this power over the noise floor in its first 0.5 ms
        (dB, noise-normalised power averaged over channels).
    min_jump_db : float, default 9
        ... and its power must jump by at least this much over the 2 ms before it (dB).
    block_seconds : None
        Deprecated, without effect (a FutureWarning says so): it set the length of the
        blocks the file was analysed in, and results depended on it. The blocks are now
        30 s of the file's timeline whatever is given (see Notes).

    Returns
    -------
    pandas.DataFrame
        One row per impact with the columns of :data:`dashpot.ingest.IMPACT_COLUMNS`:

        * ``time`` (s from the start of the file): the onset of the impact transient, i.e.
          the posterior mean of the instant t0 at which the high-passed waveform of the
          timing channel leaves the noise under the change-point model of
          :func:`_onset_posterior` (sub-sample; the first arrival of the impact's sound at
          the microphone, earlier than the loud part of the transient);
        * ``time_uncertainty`` (s): its 1σ, half the central 68 % posterior interval, from
          the local noise (level and colour) and the steepness of the edge, plus the width of
          the sound's rise (a real impact sound may take a millisecond to rise from the
          noise; the onset lies somewhere within it) and floors for the edge model's misfit
          and sub-sample error (see :func:`_onset_posterior`); on a sharp edge, where the
          posterior overstates the error, at half its width, and with 0.1 ms in quadrature
          where a ring, burst or echo of an earlier impact starts near the onset (see
          :func:`dashpot.ingest.onset._stated_sigma`);
        * ``amplitude`` (full scale = 1): the largest deviation of the raw samples from their
          level just before the onset within 3 ms after it, over all channels (DC offset
          excluded; a lower bound where the recording clipped);
        * ``impact_speed``, ``rebound_speed``, ``speed_uncertainty``: NaN (sound does not
          measure speed);
        * ``run``: the drop of the ball the impact belongs to, 0, 1, ... in time order (0
          throughout for a recording of one drop; see Notes).

        ``attrs``: ``source`` (the file), ``sensor`` = "audio", ``notes`` (list of str: the
        timing channel, transients left out and why, clipped impacts; with several drops,
        each note names its run).

    Raises
    ------
    InputError
        The file cannot be read (missing, empty, truncated, not audio, corrupt), is sampled
        below :data:`MIN_SAMPLE_RATE`, holds no impact (silence, noise only), or a single
        impact, which is not a bounce sequence.
    ValueError
        An option is out of range.

    Notes
    -----
    Channels: detection uses all of them (mean noise-normalised power) but those that record
    less noise than their samples resolve (a dead input, while another channel is live),
    and those whose SNR is more than 10 dB under the best channel's; times come from the
    single channel, within 3 dB of the best SNR, whose onsets are the most precise (smallest
    median uncertainty). Averaging channels would overstate the precision when their noise is
    shared (room noise heard by both microphones, or one microphone mixed to several
    channels), and the channels of a stereo pair hear each impact at different delays.

    Selection: among all transients, the impacts are those of the best chain whose successive
    interval ratios stay within [0.45, 1.2] and follow a smooth trend (see
    :func:`_select_bounces`). Ringing, echoes and rattles, which come at a fixed delay after
    their impact, and noise are left out and counted in the notes.

    Several drops: a recording may hold a session of drops, the ball bouncing to rest, picked
    up and dropped again. Each is a run: the train of the best chain is found, then other
    drops before and after it, each a train of the same ball that comes to rest before the
    next is released (see :func:`_impact_table`); a chain that took the loud first impacts
    of earlier drops before a train is cut where an interval is longer than any number of
    missed flights can make it (:func:`dashpot.ingest.chain._drop_start`).

    Blocks: the file is decoded and analysed in blocks of 30 s, so that memory stays bounded
    however long the recording (a last block shorter than 15 s is analysed with the one
    before). Each block's transients are judged against its own noise (level and colour),
    which may change over a long recording; the blocks are fixed on the file's timeline, so
    that the same file always gives the same impacts.

    Lossy files (MP3, Ogg Vorbis, Opus): libsndfile's seeking in them is not sample-exact
    (Vorbis reads after a seek came 1664 frames off), and the later steps read stretches of
    the file again; such a file is decoded once, in order, into a temporary copy that they
    read instead. A transform codec also spreads a loud transient's noise up to a block before
    it (pre-echo): in any file, a transient up to 6 ms before one ten times louder is left out
    as that one's pre-echo (:func:`_without_pre_echoes`; the files decoded from lossy ones
    gain most), and in a lossy file a sound that leads into an impact's rise is not taken for
    its onset (:func:`_retime_on_first_burst`). On 12 disturbed trains kept
    apart (tests/test_audio_lossy.py), MP3 at 55 kb/s and Vorbis and Opus at 120-135 kb/s
    find 0.95-0.99 of the impacts with 1-3 % false ones, where the WAV finds 0.99 with 1 %
    (before: MP3 0.86 and Vorbis 0.84, with 10-12 % false). The codec's own error is not in
    the stated 1σ, and a note says so: the bouncy-ball recording coded as Vorbis at
    libsndfile's default quality times its onsets 0.4 ms RMS from the WAV's, against a stated
    0.07 ms.

    Speed: the work per sample is a few vectorized passes (high-pass, running sums); the fits
    run on the selected impacts only, and the probes of predicted impacts take a few tens of
    ms of the recording each (from the samples kept in memory, for recordings up to 64 MiB
    of samples; from the file, for longer ones).
    """
    if block_seconds is not None:
        warnings.warn("detect_impacts: block_seconds is deprecated and has no effect; the "
                      f"file is analysed in blocks of {_BLOCK_SECONDS:g} s of its timeline, "
                      "so that its impacts do not depend on an option", FutureWarning,
                      stacklevel=2)
    for name, value in (("highpass_hz", highpass_hz), ("min_snr_db", min_snr_db),
                        ("min_jump_db", min_jump_db)):
        if not np.isfinite(value) or value <= 0:
            raise ValueError(f"{name} must be a positive number; got {value!r}")
    with _open(path) as handle:
        sample_rate = int(handle.samplerate)
        if sample_rate < MIN_SAMPLE_RATE:
            raise InputError(path, f"sample rate {sample_rate} Hz is below the "
                                   f"{MIN_SAMPLE_RATE} Hz the impact detector needs (the first "
                                   f"{_STA_SECONDS * 1e3:g} ms of a transient must span "
                                   f"{_AIC_MARGIN} samples)")
        if highpass_hz >= 0.45 * sample_rate:
            raise ValueError(f"highpass_hz must be below 0.45 × the sample rate "
                             f"({0.45 * sample_rate:g} Hz); got {highpass_hz!r}")
        settings = _Settings.make(sample_rate, min_snr_db, min_jump_db)
        sos = signal.butter(_HIGHPASS_ORDER, highpass_hz, "highpass", fs=sample_rate,
                            output="sos")
        # 16-bit samples are kept as read (a quarter of float64's memory, which costs as much
        # to touch the first time as to filter); the kernels scale them by 2⁻¹⁵, exactly.
        sixteen_bit = handle.subtype == "PCM_16"
        scale = 2.0**-15 if sixteen_bit else 1.0
        stream = _Stream(settings=settings, channels=handle.channels, sos=sos, scale=scale,
                         lossy_codec=handle.lossy_codec,
                         noise_floor=max(_quantization_noise(handle.subtype), _NOISE_FLOOR),
                         recording=_Recording(path, handle.frames, scale))
        block_frames = max(int(round(_BLOCK_SECONDS * sample_rate)), settings.carry)
        pending = None
        # One block of look-ahead, so that the last one is processed as final. A last block
        # shorter than half a block is processed with the one before: a few seconds that the
        # bounce train fills have too few quiet stretches for a noise estimate of their own.
        for block in _blocks(handle, path, block_frames,
                             dtype="int16" if sixteen_bit else "float64"):
            if pending is None:
                stream.notch_mains_hum(block)
            stream.recording.keep(block)
            if pending is not None:
                if block.shape[0] < block_frames // 2:
                    pending = np.concatenate([pending, block])
                    continue
                _process(stream, pending, final=False)
            pending = block
        _process(stream, pending, final=True)
        stream.recording.close()
        duration = handle.frames / sample_rate
        repair_note = handle.repair_note
    stream.candidates = _without_pre_echoes(stream.candidates, sample_rate)
    table = _impact_table(path, stream, sample_rate, duration)
    # What a user must see beside any fit of these impacts, as well as in the notes.
    must_see = [note for note in (repair_note,
                                  stream.lossy_codec and _lossy_note(stream.lossy_codec))
                if note]
    table.attrs["notes"] += must_see
    if must_see:
        table.attrs["warnings"] = must_see
    return table


def _without_pre_echoes(candidates, sample_rate):
    """The stored transients without those that come just before one ten times louder.

    A transform codec spreads the quantization noise of a block over all of it, so a loud
    transient is heard faintly up to a block before it (pre-echo [7]_): a transient within
    :data:`_PRE_ECHO_SECONDS` (6 ms, the short blocks of MP3, AAC and Vorbis at 32-48 kHz)
    before one 10 times louder is that one's pre-echo. This holds for any file, since a
    recording decoded from a lossy one (a phone's AAC converted to WAV) no longer says so;
    and whatever the file, impacts grow quieter along a train, so that no impact comes that
    soon before one 10 times louder (a sound there is a pre-echo, an apex click or an echo).
    """
    onsets = np.array([c["onset"] for c in candidates]) / sample_rate
    amplitude = np.array([c["amplitude"] for c in candidates])
    # The loudest transient in the stretch after each: the reversed train's loudest before.
    loudest_after = _loudest_before(-onsets[::-1], amplitude[::-1], _PRE_ECHO_SECONDS)[::-1]
    return [candidate for candidate, echo in
            zip(candidates, loudest_after >= _PRE_ECHO_LOUDNESS * amplitude) if not echo]


def _lossy_note(codec):
    """The note on a recording coded by the lossy `codec` (libsndfile's subtype name)."""
    name = {"VORBIS": "Vorbis", "OPUS": "Opus"}.get(codec, "MP3")
    return (f"lossy-coded recording ({name}): the codec spreads its noise over a few ms around "
            f"each impact and may drop quiet impacts that louder ones mask, so onsets may be "
            f"off by more than their stated 1σ; record in WAV or FLAC for timing (a fit's "
            f"timing jitter takes up the extra scatter)")


def _fitted_onsets(stream):
    """Function giving the fitted onset (s) of the stored transients of given indices.

    Each transient is fitted (:func:`_onset_posterior`) on its channel of best onset SNR;
    results are remembered, so that asking again costs nothing. The function's attribute
    ``fits`` maps each index fitted so far to (onset in samples from the start of the
    window, its 1σ in samples, channel): the final timing reuses them (the fit of a window
    does not depend on the others fitted with it).
    """
    candidates, settings = stream.candidates, stream.settings
    known, fits = {}, {}

    def fitted(indices):
        todo = [int(i) for i in np.unique(indices).tolist() if i not in known]
        if todo:
            windows = np.stack([candidates[i]["windows"] for i in todo])  # (K, C, W)
            pre, post = windows[:, :, : settings.pre], windows[:, :, settings.pre:]
            snr = np.abs(post - pre.mean(axis=2, keepdims=True)).max(axis=2) / np.maximum(
                pre.std(axis=2), stream.noise_floor)
            # Only among the channels the detection heard (a dead one's blip would be timed).
            onsets = np.array([candidates[i]["onset"] for i in todo]) / settings.sample_rate
            best = np.argmax(np.where(stream.timed_at(onsets), snr, -np.inf), axis=1)
            rows = np.arange(len(todo))
            onset, sigma, _ = _onset_posterior(windows[rows, best], settings.pre,
                                               settings.sample_rate)
            starts = np.array([candidates[i]["window_starts"][c] for i, c in zip(todo, best)])
            known.update(zip(todo, ((starts + onset) / settings.sample_rate).tolist()))
            fits.update(zip(todo, zip(onset.tolist(), sigma.tolist(), best.tolist())))
        return np.array([known[i] for i in np.atleast_1d(indices).tolist()])

    fitted.fits = fits
    return fitted


def _impact_table(path, stream, sample_rate, duration):
    """Select the impacts among the stored transients, time them, and build the table: one
    run per drop of the ball that the recording holds, in time order.

    The train of the best chain over the whole recording is found first (:func:`_drop_in`).
    Other drops are looked for in the stretches before and after it
    (:func:`_other_drop`); where there are any, each train is found again on its own stretch
    of the recording (from the release of its ball to the release of the next one), so that
    no train's result depends on the others'.
    """
    candidates = stream.candidates
    if not candidates:
        raise InputError(path, f"no impacts found in {duration:.3f} s: silence or noise only "
                               f"(no transient rose {10 * np.log10(stream.settings.min_jump):.0f}"
                               f" dB over the level before it and "
                               f"{10 * np.log10(stream.settings.min_power):.0f} dB over the "
                               f"noise floor)")
    rough = np.array([c["onset"] for c in candidates]) / sample_rate
    first = _drop_in(path, stream, rough, sample_rate, 0.0, duration)
    trains = [first]
    amplitude = np.array([c["amplitude"] for c in candidates])
    stretches = _stretches_around(first, rough, amplitude, first, 0.0, duration)
    while stretches:
        start, end = stretches.pop()
        other = _other_drop(path, stream, rough, amplitude, sample_rate, start, end, trains)
        if other is not None:
            trains.append(other)
            stretches += _stretches_around(other, rough, amplitude, first, start, end)
    if len(trains) == 1:
        return first
    trains.sort(key=lambda train: train["time"].iat[0])
    bounds = [0.0] + [_release(train["time"].to_numpy()) for train in trains[1:]] + [duration]
    again = []
    for train, start, end in zip(trains, bounds[:-1], bounds[1:]):
        try:
            again.append(_drop_in(path, stream, rough, sample_rate, start, end))
        except InputError:
            again.append(train)  # the whole recording's choice stands
    return _joined_runs(again)


def _release(times):
    """When the ball of the train of impacts at `times` (s) was released (s): at least half its
    first interval (its fall from rest; the rebound rises less) before its first impact."""
    return times[0] - 0.5 * (times[1] - times[0])


def _drop_in(path, stream, rough, sample_rate, start, end):
    """The impact table of the last drop's train in the stretch [`start`, `end`) (s) of the
    recording, whose transients have the rough onsets `rough` (s).

    The train of the best chain there (:func:`_train_table`; raises InputError where there
    is none). Where its impacts end in periodic clicks (a ball at rest, a clock:
    :func:`dashpot.ingest.chain._periodic_members`), the train is found again without them;
    where they hold the first impacts of earlier drops
    (:func:`dashpot.ingest.chain._drop_start`), again from the release of the last drop on
    (the earlier ones are looked for apart). Where either finds no train, the one before
    stands.
    """
    train = _train_table(path, _within(stream, rough, start, end), sample_rate, end)
    times = train["time"].to_numpy()
    periodic = _periodic_members(times, np.arange(times.size))
    if periodic.any():
        kept = (rough >= start) & (rough < end)
        kept[np.abs(rough[:, None] - times[periodic][None, :]).argmin(axis=0)] = False
        try:
            train = _train_table(path, _subset(stream, kept), sample_rate, end)
        except InputError:
            pass
    cut = _drop_start(train["time"].to_numpy(), train["amplitude"].to_numpy())
    while cut:
        release = _release(train["time"].to_numpy()[cut:])
        try:
            train = _train_table(path, _within(stream, rough, release, end), sample_rate, end)
        except InputError:
            break
        cut = _drop_start(train["time"].to_numpy(), train["amplitude"].to_numpy())
    return train


def _stretches_around(train, rough, amplitude, first, start, end):
    """The stretches (s) of [`start`, `end`) before and after `train` (an impact table) in
    which another drop may lie: before the release of its ball, and from the time its rings
    and echoes last past its last impact. Only those are kept whose transients (rough onsets
    `rough`, s, and `amplitude`, full scale) could make a drop of the ball of the `first`
    train found (:func:`_other_drop`): as many transients as that drop needs impacts, and
    one as loud as its loudest impact must be."""
    times = train["time"].to_numpy()
    stretches = [(start, _release(times)), (times[-1] + _AFTER_TRAIN_SECONDS, end)]
    needed = max(_MIN_RUN_IMPACTS, len(first) / _RUN_COUNT_FACTOR)
    loud = amplitude * _RUN_LOUDNESS >= first["amplitude"].max()
    return [(lo, hi) for lo, hi in stretches
            if np.count_nonzero((rough >= lo) & (rough < hi)) >= needed
            and np.any(loud & (rough >= lo) & (rough < hi))]


def _within(stream, rough, start, end):
    """The stream with only its transients whose rough onsets `rough` (s) lie in [`start`,
    `end`)."""
    return _subset(stream, (rough >= start) & (rough < end))


def _subset(stream, kept):
    """The stream with only the transients `kept` (bool per transient)."""
    part = copy.copy(stream)
    part.candidates = [candidate for candidate, keep in zip(stream.candidates, kept) if keep]
    return part


def _other_drop(path, stream, rough, amplitude, sample_rate, start, end, trains):
    """The impact table of a drop of the ball in [`start`, `end`) (s), or None.

    A train found there (:func:`_train_table`) is another drop only if it is one beyond
    doubt, since a recording holds a single drop as a rule and the sounds around one (the
    ball rolling or at rest, echoes, speech, handling) must not pass for another. It is a
    drop of the same ball as the `trains` found (impact tables, the first that of the best
    chain over the whole recording):

    * it comes to rest before the ball of the next is released, or is released after the
      one before came to rest (:func:`_rest`, :func:`_release`), and is no echo of one
      (:func:`_echo_of`);
    * it has as many impacts as the first within a factor :data:`_RUN_COUNT_FACTOR` (the
      count grows only with the logarithm of the drop height), and at least
      :data:`_MIN_RUN_IMPACTS`;
    * the median ratio of its successive intervals (the restitution) is the first's within
      :data:`_RUN_RATIO_SPREAD` in log;
    * its intervals shrink to less than :data:`_RUN_SHRINK` of the first (a ball bouncing to
      rest; periodic clicks do not shrink);
    * its loudest impact is within a factor :data:`_RUN_LOUDNESS` of the first's (the sound
      grows with the impact speed: a tenth of it is a drop from a hundredth of the height; a
      chain can take the steady clicks of a ball at rest at multiples of their period).
    """
    # A train needs as many impacts in the first pass of the chain as it finds, but for
    # those the later passes add (:data:`_FIRST_PASS_SHARE`): where the first pass is
    # shorter, the full search (the fits, the probes of the file) is not made.
    needed = max(_MIN_RUN_IMPACTS, len(trains[0]) / _RUN_COUNT_FACTOR)
    inside = (rough >= start) & (rough < end)
    candidates = _within(stream, rough, start, end).candidates
    chain, _ = _first_pass(rough[inside], np.array([c["strength"] for c in candidates])
                           / stream.settings.min_power, amplitude[inside],
                           np.array([c["strong"] for c in candidates], dtype=bool))
    if chain.size < _FIRST_PASS_SHARE * needed:
        return None
    try:
        train = _drop_in(path, stream, rough, sample_rate, start, end)
    except InputError:
        return None
    times, known = train["time"].to_numpy(), trains[0]["time"].to_numpy()
    if times.size < needed:
        return None
    intervals = np.diff(times)
    if intervals[-1] >= _RUN_SHRINK * intervals[0]:
        return None
    if abs(np.log(_median_ratio(times) / _median_ratio(known))) > _RUN_RATIO_SPREAD:
        return None
    if train["amplitude"].max() * _RUN_LOUDNESS < trains[0]["amplitude"].max():
        return None
    for other in trains:
        # One ball: each drop has come to rest before the next is released.
        before, after = sorted((times, other["time"].to_numpy()), key=lambda t: t[0])
        if _rest(before) > _release(after):
            return None
        if _echo_of(train, other):
            return None
    return train


def _echo_of(train, source):
    """Whether at least half the impacts of `train` (an impact table) come one common delay
    (to :data:`_ECHO_TOLERANCE_SECONDS`) after an impact of `source` at least
    :data:`_ECHO_WEAKENING` times as loud: an echo copies the train (from a far wall, at any
    delay), weakened, since its path is longer and the wall absorbs part of the sound; a
    drop that repeats the one before as loud is a drop."""
    delays = train["time"].to_numpy()[:, None] - source["time"].to_numpy()[None, :]
    louder = (source["amplitude"].to_numpy()[None, :]
              >= _ECHO_WEAKENING * train["amplitude"].to_numpy()[:, None])
    member, column = np.nonzero(louder & (delays > 0))
    if member.size == 0:
        return False
    # Each impact counts once per delay bin, and in the bins on either side (a delay near a
    # bin's edge).
    bins = np.round(delays[member, column] / _ECHO_TOLERANCE_SECONDS).astype(np.int64)
    pairs = np.unique(np.stack([np.tile(member, 3), np.concatenate([bins - 1, bins, bins + 1])]),
                      axis=1)
    return 2 * int(np.unique(pairs[1], return_counts=True)[1].max()) >= train.shape[0]


def _rest(times):
    """When the ball of the train of impacts at `times` (s) comes to rest (s): its flights
    after the last impact shrink by the median ratio r of its last five intervals (at most
    :data:`_MAX_REST_RATIO`) and sum to T·r/(1 − r) after the last flight T (a geometric
    series [5]_)."""
    ratio = min(_median_ratio(times[-6:]), _MAX_REST_RATIO)
    return times[-1] + (times[-1] - times[-2]) * ratio / (1.0 - ratio)


def _median_ratio(times):
    """Median ratio of successive intervals between the impacts at `times` (s)."""
    intervals = np.diff(times)
    return float(np.median(intervals[1:] / intervals[:-1]))


def _joined_runs(trains):
    """One impact table of the `trains` (impact tables in time order), run k the k-th; notes
    of each run named as its."""
    table = pd.concat([train.assign(run=run) for run, train in enumerate(trains)],
                      ignore_index=True)
    starts = ", ".join(f"{train['time'].iat[0]:.3f}" for train in trains)
    notes = [trains[0].attrs["notes"][0],
             f"{len(trains)} drops of the ball in the recording, each its own run (0 to "
             f"{len(trains) - 1}, first impacts at {starts} s); the notes below name the run "
             f"they are about"]
    for run, train in enumerate(trains):
        notes += [f"run {run}: {note}" for note in train.attrs["notes"][1:]]
    table.attrs.update(trains[0].attrs, notes=notes)
    return table


def _train_table(path, stream, sample_rate, duration):
    """Select the impacts of one train among the stored transients (of a recording, or its
    stretch, ending at `duration`, s), time them, and build the table."""
    candidates = stream.candidates
    rough = np.array([c["onset"] for c in candidates]) / sample_rate
    strength = np.array([c["strength"] for c in candidates])
    amplitude = np.array([c["amplitude"] for c in candidates])
    strong = np.array([c["strong"] for c in candidates])
    precise = _fitted_onsets(stream)
    # A chain that fails the check of a bounce train is chosen again once the transients
    # explained as the rings, bursts and echoes of louder ones (at the delays at which they
    # recur after the first choice's impacts) are set aside: where secondaries come at
    # evenly spaced delays, they form a chain of their own as long as the train's tail. Where
    # that one fails too, a third choice measures the delays after its impacts instead (a
    # first chain that took secondaries for impacts measures them wrong, and sets impacts
    # aside), with the first choice's members selectable, and a fourth sets aside the first
    # choice's members that are echoes of louder transients; each is taken only if it
    # passes. A first choice that passes is chosen again without its members that are
    # echoes of louder transients it left out: a chain that took the first impacts and then
    # their echo (a copy of the train's intervals that outlasts it by the delay) passes the
    # check, and the train passes without the echo. Taken only where at most one in ten of
    # its members is itself a ring, burst or echo of its impacts (`accepted`): without the
    # echo, a chain may take those instead.
    def choose(selectable, weak_too=False):
        return selectable, _choose(path, stream, candidates, rough, strength, amplitude,
                                   strong | weak_too, precise, selectable)

    def passes(choice):
        return not choice[1][-1]

    def accepted(choice):
        members = choice[1][0]
        return passes(choice) and (_explained_secondaries(rough, amplitude, members)[
            members].sum() <= _SECONDARY_MEMBERS_SHARE * members.size)

    choices = [choose(np.arange(len(candidates)))]
    first_chain = choices[0][1][0]
    if passes(choices[0]):
        echoing = _echoing_members(rough, amplitude, first_chain, causes_in_chain=False)
        if echoing.sum() >= max(3, first_chain.size / 4):
            alternative = choose(np.flatnonzero(~echoing))
            if not accepted(alternative):
                # The other echoes at that delay are set aside too (an echo of an early
                # impact the first chain skipped, else taken where the train's impacts are
                # set aside), and the weak transients within 5 ms after any of them count
                # as strong: an impact landing on an echo jumps less over it than a strong
                # trigger. Taken only if it holds at least the impacts the first chain held
                # besides its echoes.
                impacts_held = first_chain.size - echoing[first_chain].sum()
                echoing = _echoing_members(rough, amplitude, first_chain, causes_in_chain=False,
                                           everywhere=True)
                lag = rough[:, None] - rough[None, echoing]
                alternative = choose(np.flatnonzero(~echoing), weak_too=np.any(
                    (lag > 0) & (lag <= _MASK_SECONDS), axis=1))
                if alternative[1][0].size < impacts_held:
                    alternative = None
            if alternative is not None and accepted(alternative):
                choices.append(alternative)
    if not passes(choices[0]):
        explained = _explained_secondaries(rough, amplitude, first_chain)
        if explained.any():
            choices.append(choose(np.flatnonzero(~explained)))
        # Without the periodic clicks it followed (a ball at rest, a clock), where that
        # choice passes.
        periodic = _periodic_members(rough, first_chain)
        if periodic.any() and not passes(choices[-1]):
            alternative = choose(np.flatnonzero(~periodic))
            if passes(alternative):
                choices.append(alternative)
    later = []
    # A choice that passes with fewer than half the first one's members may have set aside
    # impacts with the secondaries (an echo's delay that sums of the train's intervals
    # match): the choices below are made too, and one that passes with more members is
    # taken instead.
    short = (passes(choices[-1]) and not passes(choices[0])
             and choices[-1][1][0].size < _SHORT_CHOICE * first_chain.size)
    if not passes(choices[-1]) or short:
        if len(choices) == 2:
            # The delays measured after the second choice's impacts instead.
            explained = _explained_secondaries(rough, amplitude, choices[1][1][0])
            explained[first_chain] = False
            if explained.any():
                later.append(np.flatnonzero(~explained))
        # Without the first choice's members that follow louder transients at a recurring
        # delay: it followed an echo or ring of the train (with louder impacts left out
        # between its members, or stepping from one impact onto its echo).
        echoing = _echoing_members(rough, amplitude, first_chain)
        if echoing.any():
            later.append(np.flatnonzero(~echoing))
    for selectable in later:
        choice = choose(selectable)
        if passes(choice) and (not short or choice[1][0].size > choices[-1][1][0].size):
            # Taken only if it passes; else the last of the first two is judged again
            # below, once the impacts its bursts hide are found.
            choices.append(choice)
            later = []
            break
    if not passes(choices[-1]):
        # Before the train is refused, each choice is made again with the weak transients
        # too: an impact that lands on an echo or a ring jumps less over the sound before it
        # than a strong trigger, and a chain of strong transients alone breaks at it.
        for selectable in [choice[0] for choice in choices] + later:
            choice = choose(selectable, weak_too=True)
            if passes(choice):
                choices.append(choice)
                break
    if not passes(choices[-1]):
        # Last, without the transients at a recurring delay after one they may outsound
        # (a ring's burst louder than its impact, up to twice its usual level), the first
        # choice's members still selectable: a chain can step from an impact onto such a
        # burst, or onto an echo and a ring in place of the impact between them.
        explained = _explained_secondaries(rough, amplitude, first_chain, louder=True)
        explained[first_chain] = False
        if explained.any():
            choice = choose(np.flatnonzero(~explained))
            if passes(choice):
                choices.append(choice)
    selectable, (chain, skipped, times, sigmas, amplitudes, clipped_flags, timing,
                 problem) = choices[-1]
    set_aside = len(candidates) - selectable.size
    order = np.argsort(times)
    filled, retimed = [], []  # added rows; results of impacts timed again (None: left out)

    def probe(moment, tolerance, not_before=None, predicted_sound=False, expected=False,
              any_jump=False, impulse=False):
        return _probe(stream, moment, tolerance, timing, not_before, predicted_sound,
                      expected, any_jump, impulse)

    delays, levels = _recurring_secondaries(rough, amplitude, chain)
    uncovered = 0
    if chain.size >= 4:
        # Members that are the ring bursts of impacts hidden under the burst before them
        # are replaced by those impacts.
        causes, spreads, loudness, flats = _hidden_causes(
            times[order], amplitudes[order], delays, levels, rough, amplitude, probe)
        for position in np.flatnonzero(np.isfinite(spreads)):
            times[order[position]], sigmas[order[position]] = causes[position], spreads[position]
            amplitudes[order[position]] = loudness[position]
            clipped_flags[order[position]] = bool(flats[position])
        uncovered = int(np.isfinite(spreads).sum())
        # The last impacts may have no trigger of their own: look for them in the file where
        # the trend, fitted on the timed impacts, puts them. Where impacts were timed again
        # or left out, the trend's predictions past them change: further passes follow, and
        # go on past the last impact only where the last ones were among those changed.
        stop = duration
        for _ in range(_FILL_PASSES):
            count = times.size
            times, sigmas, amplitudes, clipped_flags, added, again = _fill_pass(
                times, sigmas, amplitudes, clipped_flags, delays, levels, probe, duration,
                stop)
            filled += added
            retimed += list(again.values())
            if not again:
                break
            if max(again) < count - _END_IMPACTS:
                stop = times.max() + _MERGE_SECONDS

    order = _one_per_impact(times, sigmas)
    times, sigmas, amplitudes = times[order], sigmas[order], amplitudes[order]
    # A chosen chain that is no bounce train is judged again once its members that are the
    # bursts of impacts hidden under them, and the impacts it missed, are found: those make
    # the intervals of a true train scatter like clicks'.
    if problem and (uncovered or filled or retimed):
        problem = bounce_train_problem(times, sigmas)
    if problem:
        raise InputError(path, f"{NOT_A_BOUNCE_TRAIN}: {problem}")
    clipped_flags = [clipped_flags[k] for k in order]
    dropped_end = dropped_secondaries = dropped_faint = dropped_rest = dropped_copy = 0
    if times.size >= 5:
        # No echo of the train after the ball came to rest.
        original = _echoed_tail(times, sigmas, amplitudes, rough, amplitude, precise)
        dropped_copy = int((~original).sum())
        times, sigmas, amplitudes = times[original], sigmas[original], amplitudes[original]
        clipped_flags = [flag for flag, kept in zip(clipped_flags, original) if kept]
        coefficients, scatter = _robust_trend(times)
        # Nothing after the ball has come to rest (a run of echoes continuing the intervals).
        rested = _rest_time(times, coefficients, scatter)
        dropped_rest = times.size - rested
        times, sigmas, amplitudes = times[:rested], sigmas[:rested], amplitudes[:rested]
        clipped_flags = clipped_flags[:rested]
        probed = np.isin(times, [row[0] for row in filled + retimed if row is not None])
        kept, dropped_end, dropped_secondaries, dropped_faint = _train_end(
            times, sigmas, amplitudes, scatter, delays, levels, probe, probed, duration)
        times, sigmas, amplitudes = times[:kept], sigmas[:kept], amplitudes[:kept]
        clipped_flags = clipped_flags[:kept]
    # Where each ring or echo recurring after the impacts would start, and how loud it may be
    # (as in _drop_trailing_secondaries; unknown loudness: any).
    secondaries = (times[:, None] + delays[None, :]).ravel()
    loudest = (_SECONDARY_MARGIN * amplitudes[:, None]
               * np.where(np.isfinite(levels), levels, np.inf)[None, :]).ravel()
    order = np.argsort(secondaries)
    times, sigmas, moved = _retime_on_first_burst(path, stream, times, sigmas, timing,
                                                  secondaries[order], loudest[order])
    table = pd.DataFrame({
        "time": times,
        "time_uncertainty": sigmas,
        "amplitude": amplitudes,
        "impact_speed": np.nan,
        "rebound_speed": np.nan,
        "speed_uncertainty": np.nan,
        "run": 0,
    }, columns=list(IMPACT_COLUMNS))
    table = table.sort_values("time", ignore_index=True)

    notes = [f"time: onset of each impact transient (Bayesian change-point fit of the rising "
             f"edge of its first burst), {sample_rate} Hz recording"]
    silent = np.flatnonzero(~np.any([_heard(noise, stream.noise_floor)
                                     for _, noise, _ in stream.noise_blocks], axis=0))
    if stream.channels > 1 and silent.size:
        notes.append(f"{stream.channels} channels: transients detected on those that recorded "
                     f"noise, times taken from channel {timing} (the best signal-to-noise "
                     f"ratio at the onsets); channel{'s' if silent.size > 1 else ''} "
                     f"{', '.join(map(str, silent))} recorded less than the quantization noise"
                     f" of the samples (a dead input: digital silence, perhaps with rare "
                     f"one-step blips) and {'were' if silent.size > 1 else 'was'} left out")
    elif stream.channels > 1:
        notes.append(f"{stream.channels} channels: transients detected on all of them, times "
                     f"taken from channel {timing} (the best signal-to-noise ratio at the "
                     f"onsets)")
    if stream.dc_offset > 1e-3:
        notes.append(f"DC offset of about {stream.dc_offset:.3g} (full scale) removed by the "
                     f"high-pass; amplitudes are measured from the local level")
    if stream.hum.size:
        notes.append(f"mains hum notched out before detection: {stream.hum.size} line(s) at "
                     f"{', '.join(f'{frequency:.1f}' for frequency in stream.hum)} Hz")
    left_out = len(candidates) - chain.size
    if left_out:
        delay, count = _fixed_delays(rough, chain)
        remark = (f"{left_out} transients not counted as impacts: they break the geometric "
                  f"shrinking of the intervals (ringing, echo, rattle or noise)")
        if count >= 3:
            remark += (f"; {count} of them come {delay * 1e3:.0f} ms after an impact "
                       f"(ringing or echo)")
        notes.append(remark)
    if skipped:
        notes.append(f"{skipped} impacts predicted by the interval trend have no transient of "
                     f"their own (lost under ringing or echo, or too faint); the intervals "
                     f"around them span two or more bounces")
    if retimed:
        untimed_count = sum(row is None for row in retimed)
        notes.append(f"{len(retimed)} impacts timed again: their first onset was that of a ring "
                     f"or echo of an earlier impact starting just before them"
                     + (f"; {untimed_count} of them have no onset of their own above it and are "
                        f"left out (missed impacts: the intervals around each span two bounces)"
                        if untimed_count else ""))
    if set_aside:
        notes.append(f"{set_aside} transients set aside before the impacts were chosen: they "
                     f"come at the delays at which rings, bursts or echoes recur after louder "
                     f"sounds, and the chain through them was no bounce train or followed "
                     f"an echo of one")
    if uncovered:
        notes.append(f"{uncovered} impacts found under the ring's burst of the impact before "
                     f"them (in the error of a linear prediction of that sound): the selection "
                     f"had taken their own bursts, one recurring delay later")
    if filled:
        notes.append(f"{len(filled)} faint impacts found where the interval trend predicts them "
                     f"(their sound jumps over the decaying sound before it less than a "
                     f"trigger's)")
    if dropped_copy:
        notes.append(f"{dropped_copy} transients at the end left out: each is the echo of a "
                     f"louder sound one common delay before it (an echo of the train after the "
                     f"ball came to rest)")
    if dropped_rest:
        notes.append(f"{dropped_rest} transients after the ball came to rest left out: later "
                     f"than the end of the flights the interval trend leaves after the last "
                     f"impacts (a run of echoes that continues the intervals, a rest click)")
    if dropped_end:
        notes.append(f"{dropped_end} transients after the last impact left out: the interval "
                     f"before them grew beyond the timing noise and the ratios' scatter (a "
                     f"ball coming to rest bounces ever more often)")
    if dropped_secondaries:
        notes.append(f"{dropped_secondaries} transients at the end left out: they come at the "
                     f"delay at which a ring's burst, a ring or an echo recurs after the impacts, "
                     f"no louder than such a secondary, or lack the secondary every impact "
                     f"before them sets off")
    if dropped_faint:
        notes.append(f"{dropped_faint} transients at the end left out: more than 6 dB fainter "
                     f"than an impact after the interval before them is (the sound grows with "
                     f"the impact speed, and the speed with the flight before the impact)")
    if moved:
        notes.append(f"{moved} impacts timed again at their first burst: their sound opened "
                     f"with a burst before the rising edge fitted first")
    clipped = [i for i, flag in enumerate(clipped_flags) if flag]
    if clipped:
        notes.append(f"{len(clipped)} impacts clipped (flat tops): their amplitude is a lower "
                     f"bound")
    table.attrs.update(source=str(path), sensor="audio", notes=notes)
    return table


def _choose(path, stream, candidates, rough, strength, amplitude, strong, precise, selectable):
    """The chain of impacts among the transients `selectable` (indices), timed: chain (indices
    into the transients), impacts skipped, times (s), 1σ (s), amplitudes, clip flags, the
    timing channel, and why it is not a bounce train ("" if it is)."""
    sample_rate = stream.settings.sample_rate

    def fitted(indices):
        return precise(selectable[indices])

    chain, skipped = _select_bounces(rough[selectable], strength[selectable]
                                     / stream.settings.min_power, amplitude[selectable],
                                     strong[selectable], fitted)
    chain = selectable[chain]
    if chain.size < 3:
        # Two transients cannot be told from an impact and its ring or echo: without a third,
        # no interval ratio confirms a bounce.
        strongest = int(np.argmax(strength))
        raise InputError(path, f"{'only one impact' if chain.size < 2 else 'only two transients'}"
                               f" found (the loudest at {rough[strongest]:.3f} s): not a bounce "
                               f"sequence, which needs at least three impacts")

    chosen = [candidates[i] for i in chain]
    windows = np.stack([c["windows"] for c in chosen])  # (impacts, channels, width)
    # Timing channel: the best median SNR of the impacts' onsets (the precision of an onset
    # scales with its SNR), so that one fit per impact suffices.
    pre = windows[:, :, : stream.settings.pre]
    post = windows[:, :, stream.settings.pre:]
    snr = np.abs(post - pre.mean(axis=2, keepdims=True)).max(axis=2) / np.maximum(
        pre.std(axis=2), stream.noise_floor)
    timed = stream.timed_at(rough[chain])
    timing = int(np.argmax(np.median(np.where(timed, snr, -np.inf), axis=0)))
    # Impacts already fitted on the timing channel during the selection keep that fit.
    onset, sigma = np.zeros(chain.size), np.zeros(chain.size)
    done = np.array([precise.fits.get(int(i), (0.0, 0.0, -1))[2] == timing for i in chain],
                    dtype=bool)
    for position in np.flatnonzero(done):
        onset[position], sigma[position], _ = precise.fits[int(chain[position])]
    if not done.all():
        onset[~done], sigma[~done], _ = _onset_posterior(windows[~done, timing],
                                                         stream.settings.pre, sample_rate)
    starts = np.array([c["window_starts"][timing] for c in chosen])

    times = (starts + onset) / sample_rate
    sigmas = sigma / sample_rate
    amplitudes = np.array([c["amplitude"] for c in chosen])
    clipped_flags = [c["clipped"] for c in chosen]
    order = np.argsort(times)
    # Only a chain whose intervals shrink as a bouncing ball's do is a bounce train: random
    # clicks also hold chains within the ratio bounds.
    problem = bounce_train_problem(times[order], sigmas[order]) or _louder_between(
        rough, strength / stream.settings.min_power, amplitude, strong, chain)
    return chain, skipped, times, sigmas, amplitudes, clipped_flags, timing, problem


def _fill_pass(times, sigmas, amplitudes, clipped_flags, delays, levels, probe, duration, stop):
    """One pass of :func:`_fill_impacts` over the impacts (none looked for past `stop`, s, in
    a recording of `duration`, s), applied: times (s), 1σ (s), amplitudes, clip flags with
    the impacts it timed again, left out or added; the added rows and the retimed ones."""
    order = np.argsort(times)
    coefficients, scatter = _robust_trend(times[order], timed_off=True)
    filled, retimed = _fill_impacts(times[order], amplitudes[order], coefficients, scatter,
                                    delays, probe, duration, levels, stop=stop)
    times, sigmas, amplitudes = times.copy(), sigmas.copy(), amplitudes.copy()
    clipped_flags = list(clipped_flags)
    for position, result in retimed.items():
        if result is None:  # no onset of its own: left out below, a gap in the train
            continue
        times[order[position]], sigmas[order[position]] = result[0], result[1]
        amplitudes[order[position]], clipped_flags[order[position]] = result[2], result[3]
    untimed = [order[position] for position, result in retimed.items() if result is None]
    keep = np.setdiff1d(np.arange(times.size), untimed)
    times, sigmas, amplitudes = times[keep], sigmas[keep], amplitudes[keep]
    clipped_flags = [clipped_flags[k] for k in keep]
    if filled:
        extra = np.array([row[:3] for row in filled])
        times = np.concatenate([times, extra[:, 0]])
        sigmas = np.concatenate([sigmas, extra[:, 1]])
        amplitudes = np.concatenate([amplitudes, extra[:, 2]])
        clipped_flags = clipped_flags + [row[3] for row in filled]
    return times, sigmas, amplitudes, clipped_flags, filled, retimed


def _retime_on_first_burst(path, stream, times, sigmas, timing, secondaries, loudest):
    """Onsets fitted again on the impacts' first bursts, or on the edge of their rise.

    Each impact's stretch of the file (2 ms before its onset to 3 ms after, with the fit's
    noise window and 20 ms for the high-pass to settle, some nine of its time constants) is
    read again and filtered as in the stream. Where a first burst rises before the fitted
    edge (:func:`_first_burst`), the change-point fit is done again with its window on that
    burst (its rough onset a sample before the burst's crossing of a fifth of the peak). A
    burst is not the impact's where a ring or echo of an earlier impact, at a delay at which
    they recur (`secondaries`: the impacts' times plus those delays, s, sorted), starts from
    2 ms before it to the onset and may be as loud as the burst (`loudest`: twice the usual
    level of that secondary against its impact, times the impact's amplitude, full scale):
    that sound, which the chain told from the impact, may still be going on there (rings and
    echoes rise and decay over milliseconds). No onset is moved within the merge window (1 ms)
    of another row's: a sound there is that row's.

    Otherwise the onset is checked against the edge of the impact's rise: the fit is done again
    with its window a sample before the sound's crossing of a fifth of its peak
    (:func:`_rise_crossing`) wherever the fitted onset lies out of that fit's reach of it (more
    than 0.1 ms before it, or after it) and the level clears the sound before four times over
    (as a first burst's must; a crossing of a level that does not is as likely the
    background's: a fitted onset before it then stays, its 1σ covering the stretch to the
    crossing as a uniform uncertainty, width/√12). Of the two onsets, the earlier is the
    impact's when the sound from it to the later one is one sound (:func:`_one_sound`): a
    fitted onset before the rise that leads into it (a real impact may open with a quieter
    sound a few tenths of a millisecond long), or the edge of the rise where the fit started
    late on it (0.25 ms at most: an earlier sound is a first burst's to claim). Where the sound
    falls back to the background in between, the earlier onset is that of a faint sound of its
    own (or of a fluctuation of the background), and the later one is kept. On the synthetic
    sounds of :mod:`dashpot.synth.audio` the fit times the rise's edge within its reach (100
    disturbed trains of a development block: one onset of 3,600 moved, from 1.1 ms early onto
    its impact); on the real recordings, onsets fitted 0.5-0.6 ms early on a faint sound before
    the rise put 0.04 into an interval ratio, and onsets fitted up to 0.18 ms late on the rise
    about 0.01.

    Returns the times (s), their stated 1σ (s; :func:`_stated_sigmas`) and how many were
    moved to a first burst.
    """
    settings, sample_rate = stream.settings, stream.settings.sample_rate
    before, after = (int(round(s * sample_rate)) for s in _BURST_REACH_SECONDS)
    lead = settings.pre + before + int(_RESETTLE_SECONDS * sample_rate)
    tail = after + settings.span + settings.pre
    # RMS of the timing channel's noise at each impact (the estimate of its block).
    noise, rho = stream.noise_at(times)
    noise_rms = noise[:, timing] / np.sqrt(np.maximum(1.0 - rho[:, timing] ** 2, 1e-6))
    starts = np.round(times * sample_rate).astype(np.int64) - lead
    length = lead + tail
    inside = np.flatnonzero((starts >= 0) & (starts + length <= stream.recording.frames))
    raw = stream.recording.stretches(starts[inside], length, timing)
    # All stretches filtered at once (as the channels of one block), each from the filter at
    # rest on its first sample.
    filtered = stream.highpass_from_rest(raw.T).T
    onset = lead
    levels = filtered[:, onset - settings.pre - before:onset - before].mean(axis=1)
    magnitude = np.abs(filtered - levels[:, None])
    bursts = _first_burst(magnitude, onset, noise_rms[inside], sample_rate)
    crossings, rise_levels = _rise_crossing(magnitude, onset, sample_rate)
    reach = _onset_reach(sample_rate)
    quiet = int(round(_BURST_BACKGROUND_SECONDS * sample_rate))
    longest_late = _BURST_MIN_LEAD_SECONDS * sample_rate
    times, sigmas = times.copy(), sigmas.copy()
    windows, offsets, moved, checks = [], [], [], []
    for row, k in enumerate(inside):
        burst = int(bursts[row])
        if burst >= 0:
            lo, hi = np.searchsorted(secondaries, [(starts[k] + burst) / sample_rate
                                                   - _SECONDARY_REACH_SECONDS, times[k]])
            if np.any(magnitude[row, burst:onset].max() <= loudest[lo:hi]):
                burst = -1
        if burst >= 0:
            rough = burst - 1  # a sharp edge starts within a sample before its crossing
            check = None
        else:
            rise, fitted = int(crossings[row]), times[k] * sample_rate - starts[k]
            if rise < 0 or rise - 1 - reach <= fitted <= rise:
                continue  # no rise after the onset, or the fit timed its edge already
            # The sound in the millisecond before the earlier of the two onsets.
            end = int(min(rise, np.floor(fitted))) - 2
            background = max(noise_rms[k],
                             np.sqrt(np.mean(magnitude[row, end - quiet:end] ** 2)))
            if rise_levels[row] < _BURST_BACKGROUND * background:
                if fitted < rise:
                    # Whether the fitted onset or the rise starts the impact cannot be told:
                    # the fitted onset stays, its 1σ covering the stretch to the rise as a
                    # uniform uncertainty (width/√12).
                    sigmas[k] = np.hypot(sigmas[k] * sample_rate,
                                         (rise - fitted) / np.sqrt(12.0)) / sample_rate
                continue
            rough = rise - 1
            check = (row, fitted, background)
        windows.append(filtered[row, rough - settings.pre:rough + settings.span])
        offsets.append(starts[k] + rough - settings.pre)
        moved.append(int(k))
        checks.append(check)
    if not moved:
        return times, _stated_sigmas(times, sigmas, starts, inside, filtered - levels[:, None],
                                     noise_rms, secondaries, sample_rate), 0
    onset, sigma, _ = _onset_posterior(np.stack(windows), settings.pre, sample_rate)
    timed = times.copy()
    for k, offset, refit, spread, check in zip(moved, offsets, onset, sigma, checks):
        # A sound within the merge window of another row is that row's (an impact, or an
        # echo or ring the table holds as one): an onset is never moved onto it.
        near = np.abs(timed - (offset + refit) / sample_rate) < _MERGE_SECONDS
        near[k] = False  # its own onset
        if near.any():
            continue
        if check is not None:
            row, fitted, background = check
            edge = offset - starts[k] + refit  # the refitted onset, in the stretch
            one = _one_sound(magnitude[row], min(fitted, edge), max(fitted, edge),
                             background, sample_rate)
            if edge < fitted:
                # The fit started late on the rise, if the sound from its edge is one.
                keep = not one or fitted - edge > longest_late
            else:
                # The fitted onset is that of a sound of its own before the rise, unless
                # that sound leads into the rise; in a lossy file such a lead is as likely
                # the codec's noise spread before the transient (pre-echo), up to a block
                # of the codec earlier, and the rise is the impact's.
                keep = one and not stream.lossy_codec
            if keep:
                continue
        times[k] = (offset + refit) / sample_rate
        sigmas[k] = spread / sample_rate
    return (times, _stated_sigmas(times, sigmas, starts, inside, filtered - levels[:, None],
                                  noise_rms, secondaries, sample_rate),
            sum(check is None for check in checks))


def _stated_sigmas(times, sigmas, starts, inside, centred, noise_rms, secondaries,
                   sample_rate):
    """The 1σ stated for the impacts' onsets (:func:`_stated_sigma`), from their fits' 1σ.

    `times` and `sigmas` (s) are the onsets and their fits' 1σ; `centred` holds the
    high-passed stretches (level removed) read for the impacts `inside` (row i: impact
    ``inside[i]``, from sample ``starts[inside[i]]``; as in :func:`_retime_on_first_burst`),
    `noise_rms` the RMS of the noise at each impact in its units; `secondaries` (s, sorted)
    are where the rings, bursts and echoes of the impacts start. An impact whose stretch was
    not read keeps its fit's 1σ.
    """
    sigmas = sigmas.copy()
    if inside.size == 0:
        return sigmas
    span = int(round(1e-3 * sample_rate))  # the first millisecond of each sound
    first = np.clip(np.floor(times[inside] * sample_rate - starts[inside]).astype(np.int64),
                    0, centred.shape[1] - span)
    sound = centred[np.arange(inside.size)[:, None], first[:, None] + np.arange(span)]
    noise = noise_rms[inside]
    rise, edge = _rise_samples(np.abs(sound), noise), _edge_samples(sound, noise)
    lead = np.full(inside.size, np.nan)
    latest = np.searchsorted(secondaries, times[inside] + _AMBIGUITY_REACH_SECONDS[1],
                             side="right") - 1
    known = latest >= 0
    lead[known] = times[inside[known]] - secondaries[latest[known]]
    sigmas[inside] = _stated_sigma(sigmas[inside], rise, edge, lead, sample_rate)
    return sigmas
