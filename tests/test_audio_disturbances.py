"""Impacts from sound with the quiet sounds of real recordings, on seeds kept apart (issue 14).

Every train carries the disturbances of :func:`dashpot.synth.audio.impact_sound` that fooled
the detector on real recordings: a faint click near each apex (−40 dB), a steady click tail
after rest (period 80-100 ms), a ring, and an echo with a delay drawn across 5-200 ms; half the
trains also have a burst inside each impact's ring 5-8 ms after it, up to 1.5 times as loud as
the impact's first burst. Truth: the onsets impact_sound returns (the start of each impact's
first burst). The block of seeds below was drawn once at random and was never used while
developing the detector; it must not be changed to make a test pass.

Targets (issue 14): at SNR >= 20 dB (the weakest impact), recall >= 99 %, at most one false
impact per 500, and the stated 1σ / 2σ covering the true errors at 68.3 % / 95.4 % (to three
binomial standard deviations).
"""

import numpy as np
import pandas as pd
import pytest

from audio_trains import hybrid_train, onset_near, score_train, timed_at_a_secondary
from dashpot.errors import InputError
from dashpot.ingest import audio, chain
from dashpot.ingest.audio import detect_impacts
from dashpot.ingest.chain import (_back_to_louder_causes, _drop_faint_between,
                                  _drop_trailing_secondaries, _drop_unexcited_end,
                                  _every_bounce,
                                  _echoed_tail, _echoing_members, _extend_chain,
                                  _fill_impacts, _hidden_causes, _sets_off_secondaries,
                                  _move_to_causes, _rest_time, _robust_trend,
                                  _secondary_delays, _secondary_levels, _shift_to_causes,
                                  _train_end, _trend, _trend_step, _trim_growing_end,
                                  _without_members_secondaries)
from dashpot.plausibility import ratio_trend
from dashpot.synth.audio import impact_sound, write_audio

HELD_OUT_SEEDS = range(640_211, 640_311)  # 100 trains, drawn once; never used in development
RATE = 22050  # Hz: the modes (2-4.9 kHz) stay below 0.45 × the rate; 4× faster than 44.1 kHz
MATCH = 1e-3  # s: a detection within this of a true onset is that impact
# The target of nothing after the last impact is not met yet; the figures its expected
# failure states:
MEASURED = (
    "measured on this block: recall 0.9902 (3946 of 3985 impacts timed within 1 ms), 6 false "
    "impacts (one per 500 allows 7: test_at_most_one_false_impact_per_500), 3 of them after "
    "the last impact, no train refused, 1σ / 2σ coverage 0.692 / 0.957. The same trains at "
    "44.1 / 48 kHz: recall 0.9892 / 0.9900, 12 / 9 false (7 / 4 after the last impact). "
    "This block is easier than most: on the development blocks (seeds 20471001 on, 200-600 "
    "trains each, at 22.05 and 48 kHz; figures per block in the changelog) recall was "
    "0.989-0.994 and false impacts 10-17 per 100 trains (1.3-2.1 per 500 impacts), a "
    "quarter to two thirds of them after the last impact. Every false impact is a "
    "ring, ring burst or echo of an impact, or an impact timed more than 1 ms off (none is "
    "a quiet click: see test_no_quiet_click_is_reported); most are in the trains with a "
    "ring burst 5-8 ms after each impact at least 0.7 as loud as it. There the last "
    "intervals come down to the burst's delay, so the last impacts start on the burst of "
    "the one before and are timed on it or lost under it (timed 0.3-0.7 ms off, the last "
    "impact leaves its own burst more than the 0.3 ms the end's check allows off the "
    "burst's delay after it), and a burst, ring or echo of the last impacts (or an echo of "
    "an early, louder impact) that starts on the decaying sound of the impacts before it "
    "measures louder than such a secondary usually is and passes for one more bounce")


def disturbed_train(seed, rate=RATE):
    """(samples, true onsets, options) of one train with the disturbances of issue 14, sampled
    at `rate` (Hz)."""
    rng = np.random.default_rng(seed)
    times, speeds = hybrid_train(rng)
    return disturbed_sound(rng, seed, times, speeds, rate)


def disturbed_sound(rng, seed, times, speeds, rate=RATE):
    """(samples, true onsets, options) of the impacts at `times` (s) with `speeds` (m/s), with
    the disturbances of issue 14 drawn from `rng`, the weakest impact 20-45 dB over the
    noise."""
    weakest_db = rng.uniform(20.0, 45.0)
    options = dict(apex_click_db=-40.0, rest_click_period=rng.uniform(0.08, 0.1),
                   rest_click_duration=0.6, echo_delay=rng.uniform(5e-3, 0.2),
                   echo_level=rng.uniform(0.1, 0.5), ring_level=rng.uniform(0.0, 0.4),
                   ring_delay=rng.uniform(0.01, 0.03))
    if rng.uniform() < 0.5:
        options.update(burst_delays=[rng.uniform(5e-3, 8e-3)],
                       burst_levels=[rng.uniform(0.3, 1.5)])
    samples, onsets = impact_sound(times, speeds, sample_rate=rate, seed=seed,
                                   snr_db=weakest_db + 20 * np.log10(speeds.max() / speeds.min()),
                                   **options)
    return samples, onsets, options


def detected_score(folder, seed):
    """:func:`audio_trains.score_train` of the detector on the disturbed train of `seed`,
    written as a float WAV in `folder`, and that train's true onsets (s)."""
    samples, onsets, _ = disturbed_train(seed)
    path = write_audio(folder / f"train{seed}.wav", samples, RATE, subtype="FLOAT")
    return score_train(onsets, detect_impacts(path)["time"].to_numpy(), np.ones(onsets.size),
                       MATCH), onsets


@pytest.fixture(scope="module")
def held_out(tmp_path_factory):
    folder = tmp_path_factory.mktemp("disturbed")
    total = found_count = false = after_rest = refused = clicks = 0
    z = []
    for seed in HELD_OUT_SEEDS:
        samples, onsets, options = disturbed_train(seed)
        path = write_audio(folder / f"train{seed}.wav", samples, RATE, subtype="FLOAT")
        total += onsets.size
        try:
            table = detect_impacts(path)
        except InputError:
            refused += 1
            continue
        score = score_train(onsets, table["time"].to_numpy(),
                            table["time_uncertainty"].to_numpy(), MATCH)
        found_count += score["found"]
        false += score["false"]
        after_rest += score["after"]
        clicks += _not_an_impacts_sound(score["false_times"], onsets, options).sum()
        z.append(score["z"])
    z = np.concatenate(z)
    return dict(total=total, recall=found_count / total, false=false, after_rest=after_rest,
                refused=refused, within_1=np.mean(z < 1), within_2=np.mean(z < 2), n=z.size,
                clicks=int(clicks))


def _not_an_impacts_sound(moments, onsets, options):
    """Which of `moments` (s) start on none of the sounds an impact makes: its own (an onset
    timed up to 2.5 ms late is still that impact's), its ring, its ring's bursts and its
    echo (from 0.5 ms before each starts to 2.5 ms after). What is left is a quiet click,
    near an apex or in the rest tail."""
    delays = [0.0, options["ring_delay"], options["echo_delay"], *options.get("burst_delays", [])]
    starts = (onsets[:, None] + np.asarray(delays)[None, :]).ravel()
    lag = np.asarray(moments)[:, None] - starts[None, :]
    return ~np.any((lag >= -0.5e-3) & (lag <= 2.5e-3), axis=1)


def _binomial_band(p, n):
    return 3.0 * np.sqrt(p * (1 - p) / n)


def test_recall_at_least_99_percent(held_out):
    assert held_out["refused"] == 0
    assert held_out["recall"] >= 0.99


def test_at_most_one_false_impact_per_500(held_out):
    assert held_out["false"] <= held_out["total"] / 500


@pytest.mark.xfail(strict=True, reason=MEASURED)
def test_nothing_after_the_last_impact_is_reported(held_out):
    # The rest-tail clicks, and the rings, bursts and echoes of the last impacts, come after it.
    assert held_out["after_rest"] == 0


def test_no_quiet_click_is_reported(held_out):
    # Issue 14's quiet sounds: the apex clicks (40 dB under the impacts) and the rest tail's
    # clicks. Every false impact of the block is a ring, a burst or an echo of an impact (or
    # an impact timed more than 1 ms off), which the targets above count.
    assert held_out["clicks"] == 0


def test_uncertainties_cover_at_their_stated_rates(held_out):
    n = held_out["n"]
    assert abs(held_out["within_1"] - 0.683) <= _binomial_band(0.683, n)
    assert abs(held_out["within_2"] - 0.954) <= _binomial_band(0.954, n)


def test_a_member_far_fainter_than_both_neighbours_is_not_an_impact():
    # Impacts fading by 5 % per bounce, with sounds 40 dB under them chained in between.
    loudness = 0.5 * 0.95 ** np.arange(6)
    amplitude = np.empty(11)
    amplitude[0::2] = loudness
    amplitude[1::2] = 0.01 * np.sqrt(loudness[:-1] * loudness[1:])
    kept = _drop_faint_between(amplitude, np.arange(11))
    np.testing.assert_array_equal(kept, np.arange(0, 11, 2))
    # A train fading smoothly, however far, keeps every member.
    fading = 0.5 * 0.8 ** np.arange(20)
    np.testing.assert_array_equal(_drop_faint_between(fading, np.arange(20)), np.arange(20))


def test_echoes_splitting_the_first_intervals_leave_the_chain():
    # Impacts 12 % shorter apart each bounce (the 8th interval exactly 60 ms), each echoed
    # 60 ms later at 0.3 of its loudness; the chain took the echoes of the first two
    # impacts, each splitting the interval after its impact in two.
    intervals = 0.060 / 0.88**7 * 0.88 ** np.arange(19)
    impacts = np.concatenate([[0.0], np.cumsum(intervals)])
    loudness = 0.5 * 0.97 ** np.arange(impacts.size)
    echoes = np.delete(impacts + 0.060, 7)  # the 7th impact's lands on the 8th
    times = np.concatenate([impacts, echoes])
    amplitude = np.concatenate([loudness, 0.3 * np.delete(loudness, 7)])
    order = np.argsort(times)
    times, amplitude = times[order], amplitude[order]
    at = np.searchsorted(times, impacts)
    chain = np.sort(np.concatenate([at, np.searchsorted(times, impacts[:2] + 0.060)]))
    # Both go; every impact stays, the one 60 ms after the impact before it too.
    np.testing.assert_array_equal(_without_members_secondaries(times, amplitude, chain), at)
    # An echo as loud as the impacts around it cannot be told from one and stays; the other
    # still goes.
    amplitude[chain[1]] = loudness[0]
    kept = _without_members_secondaries(times, amplitude, chain)
    assert chain[1] in kept and chain[3] not in kept
    # The train alone is left as it is.
    np.testing.assert_array_equal(_without_members_secondaries(times, amplitude, at), at)


def test_a_chain_of_ring_bursts_moves_back_onto_the_impacts():
    # Impacts shrinking geometrically, each followed 7 ms later by a louder burst; the chain
    # found the bursts. Rings of the impacts at 20 ms are there too, and are not causes.
    impacts = np.cumsum(0.25 * 0.85 ** np.arange(14))
    times = np.sort(np.concatenate([impacts, impacts + 7e-3, impacts + 20e-3]))
    bursts = np.searchsorted(times, impacts + 7e-3)
    moved = _shift_to_causes(times, bursts)
    # Every interval (36-250 ms) holds its member's cause, 7 ms before it.
    np.testing.assert_array_equal(times[moved], impacts)
    # A true chain of impacts stays: the delays back to the rings and bursts of earlier
    # impacts change from bounce to bounce.
    chain = np.searchsorted(times, impacts)
    np.testing.assert_array_equal(_shift_to_causes(times, chain), chain)


def bursting_train(delay, level):
    """Impacts shrinking by 0.9 from 0.2 s, fading by 3 % per bounce, each followed `delay`
    (s) later by a burst `level` times as loud: all the transients' times (s) and amplitudes,
    and the indices of the impacts among them."""
    impacts = np.cumsum(0.2 * 0.9 ** np.arange(30))
    loudness = 0.5 * 0.97 ** np.arange(30)
    times = np.concatenate([impacts, impacts + delay])
    amplitude = np.concatenate([loudness, level * loudness])
    order = np.argsort(times)
    return times[order], amplitude[order], np.flatnonzero(order < impacts.size)


def test_members_that_are_the_bursts_of_louder_sounds_left_out_move_onto_them():
    # Impacts 3 and 4, on the long first intervals, were passed over for their bursts 7 ms
    # later (0.8 times as loud), a few % off the trend that 0.15 s intervals give.
    times, amplitude, impacts = bursting_train(7e-3, 0.8)
    chain = impacts.copy()
    chain[3:5] = impacts[3:5] + 1  # the burst follows its impact
    np.testing.assert_array_equal(_back_to_louder_causes(times, amplitude, chain), impacts)
    # The chain of the impacts themselves stays.
    np.testing.assert_array_equal(_back_to_louder_causes(times, amplitude, impacts), impacts)


def test_a_member_one_delay_after_the_burst_of_the_member_before_stays():
    # Bursts 1.2 times as loud as their impact, half an interval late: impact 21 comes one
    # burst delay after the burst of impact 20, a louder sound left out of the chain. That
    # burst is impact 20's own secondary, not an impact passed over.
    interval = 0.2 * 0.9**20
    times, amplitude, impacts = bursting_train(0.5 * interval, 1.2)
    np.testing.assert_array_equal(_back_to_louder_causes(times, amplitude, impacts), impacts)


def test_a_burst_is_not_moved_onto_an_impact_the_member_before_already_stands_for():
    # The chain took a sound 2 ms before impact 10 for it, and impact 10's burst for the next
    # bounce. Moved onto impact 10, that member would be a second one for the same impact, 2 ms
    # after the first: within the back-search time of a member, the polish weighs its options.
    times, amplitude, impacts = bursting_train(7e-3, 0.8)
    times = np.append(times, times[impacts[10]] - 2e-3)
    amplitude = np.append(amplitude, 0.3 * amplitude[impacts[10]])
    order = np.argsort(times)
    times, amplitude = times[order], amplitude[order]
    impacts = np.argsort(order)[impacts]
    chain = impacts.copy()
    chain[10] = impacts[10] - 1  # the sound before impact 10
    chain[11] = impacts[10] + 1  # impact 10's burst
    assert times[chain[10]] == times[impacts[10]] - 2e-3
    assert times[chain[11]] == times[impacts[10]] + 7e-3
    np.testing.assert_array_equal(_back_to_louder_causes(times, amplitude, chain), chain)


def test_the_burst_of_the_member_before_is_not_an_impact_hidden_under_it():
    # Bursts 4 ms after each impact, 1.2 times as loud; the last impact comes two burst
    # delays after the one before, so one delay before it lies that impact's own burst,
    # where a hidden impact would start. The onset found there is the burst's: the last
    # member stays an impact, and the others find no onset one delay before them.
    delay = 4e-3
    impacts = np.cumsum(0.05 * 0.9 ** np.arange(14))
    impacts = np.append(impacts, impacts[-1] + 2 * delay)
    bursts = impacts + delay
    sounds = np.sort(np.concatenate((impacts, bursts)))
    loudness = np.where(np.isin(sounds, bursts), 1.2, 1.0)

    def probe(moment, tolerance, not_before=None, predicted_sound=False, expected=False,
              impulse=False):
        return onset_near(sounds, moment, tolerance, 1.2)

    times, sigmas, _, _ = _hidden_causes(impacts, np.ones(impacts.size), np.array([delay]),
                                         np.array([1.2]), sounds, loudness, probe)
    np.testing.assert_array_equal(times, impacts)
    assert np.isnan(sigmas).all()


def test_a_run_of_bursts_to_the_end_of_the_train_moves_onto_its_impacts_on_a_tie():
    # Bursts 8 ms after each impact, 1.3 times as loud. From impact 19 on the chain took the
    # bursts, and impacts 26-29 are hidden under the bursts before them (no transient of
    # their own), so the run of bursts goes on to the end. Moved onto impacts 19-25, the
    # chain breaks the trend once where it rejoins the bursts (impact 25 to burst 26), as
    # the chain as found does where it left the impacts (impact 18 to burst 19): the two
    # fit about equally well, and the causes are taken.
    delay, intervals = 8e-3, 0.2 * 0.9 ** np.arange(30)
    impacts = np.cumsum(intervals)
    bursts = impacts + delay
    times = np.sort(np.concatenate([impacts[:26], bursts]))
    amplitude = np.where(np.isin(times, bursts), 1.3, 1.0)
    chain = np.searchsorted(times, np.concatenate([impacts[:19], bursts[19:]]))
    moved = _move_to_causes(times, amplitude, chain)
    expected = np.searchsorted(times, np.concatenate([impacts[:26], bursts[26:]]))
    np.testing.assert_array_equal(moved, expected)


def test_a_burst_between_two_impacts_on_the_trend_is_left_out():
    # Bursts recur 6.4 ms after the impacts; the burst of impact 20 was timed besides the
    # impacts, and impact 21 comes 0.3 ms before the trend's time (within its tolerance),
    # so that the burst is not followed by a missed or late impact: it is left out.
    delay = 6.4e-3
    impacts = np.cumsum(0.2 * 0.9 ** np.arange(30))
    impacts[21:] -= 0.3e-3
    timed = np.sort(np.append(impacts, impacts[20] + delay))
    coefficients, scatter = _robust_trend(impacts)

    def silent(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
               impulse=False):
        return None

    added, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                                   np.array([delay]), silent, timed[-1] + 1.0)
    assert retimed == {21: None} and not added


def test_a_sound_just_before_an_impact_on_the_trend_is_left_out():
    # A sound 2.5 ms before impact 21, at no recurring delay, was timed besides the impacts:
    # impact 21 is where the trend puts it, and two impacts 2.5 ms apart after a 19 ms
    # bounce would make an interval ratio far below the bounds of successive bounces.
    impacts = np.cumsum(0.2 * 0.9 ** np.arange(30))
    timed = np.sort(np.append(impacts, impacts[21] - 2.5e-3))
    coefficients, scatter = _robust_trend(impacts)

    def silent(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
               impulse=False):
        return None

    added, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                                   np.array([6.4e-3]), silent, timed[-1] + 1.0)
    assert retimed == {21: None} and not added


def test_an_impact_timed_on_the_rise_of_a_burst_is_timed_again_where_it_rises_out_of_it():
    # Bursts 6 ms after each impact. Impact 18 starts 1.5 ms into the burst of impact 17 and
    # was timed 0.6 ms into that burst, on its rise (0.9 ms early, 0.3 ms from no recurring
    # delay). Probed past the burst's start, the impact's own onset rises out of it.
    delay = 6e-3
    impacts = np.cumsum(0.05 * 0.9 ** np.arange(22))
    timed = impacts.copy()
    timed[18] = impacts[17] + delay + 0.6e-3
    assert 0.8e-3 < impacts[18] - timed[18] < 1e-3

    def probe(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
              impulse=False):
        if not_before is None:
            return onset_near(timed, predicted, tolerance)
        later = impacts[impacts > not_before]
        return onset_near(later, predicted, tolerance) if later.size else None

    coefficients, scatter = _robust_trend(impacts)
    added, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                                   np.array([delay]), probe, impacts[-1] + 1.0)
    assert not added and sorted(retimed) == [18] and retimed[18][0] == impacts[18]


def test_an_impact_at_a_secondary_delay_that_sets_off_its_own_secondary_stays():
    # Bursts 6.5 ms after each impact. Impact 18 comes 1 ms before the trend's time, exactly
    # one burst delay after impact 17: where the burst of impact 17 would be. No onset of its
    # own rises out of that burst, but it sets off a burst 6.5 ms later, as every impact
    # does: it is an impact, and stays as timed.
    impacts = np.cumsum(0.05 * 0.9 ** np.arange(22))
    timed = impacts.copy()
    timed[18] = impacts[18] - 1e-3
    delay = timed[18] - timed[17]
    bursts = timed + delay

    def probe(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
              impulse=False):
        if not_before is not None:
            return None  # nothing rises out of the burst
        return onset_near(bursts if predicted_sound else timed, predicted, tolerance)

    coefficients, scatter = _robust_trend(impacts)
    _, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                               np.array([delay]), probe, impacts[-1] + 1.0, np.array([1.0]))
    assert 18 not in retimed


def test_an_impact_on_a_burst_off_the_trend_is_found_in_the_prediction_error():
    # Bursts 6 ms after each impact, louder than them. Impact 18 starts 1.5 ms into the burst
    # of impact 17, which was timed for it (off the trend, at the burst's delay). Its power
    # does not rise out of the burst, but in the error of a predictor of the burst's sound
    # it is an impulse: found there, it replaces the burst.
    delay = 6e-3
    impacts = np.cumsum(0.05 * 0.9 ** np.arange(22))
    timed = impacts.copy()
    timed[18] = impacts[17] + delay
    assert abs(impacts[18] - timed[18] - 1.5e-3) < 1e-4

    def probe(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
              impulse=False):
        if predicted_sound:
            return onset_near(impacts, predicted, tolerance)
        return None if not_before is not None else onset_near(timed, predicted, tolerance)

    coefficients, scatter = _robust_trend(impacts)
    _, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                               np.array([delay]), probe, impacts[-1] + 1.0)
    assert sorted(retimed) == [18] and retimed[18] is not None
    assert retimed[18][0] == impacts[18]


def test_the_train_ends_before_an_interval_grows():
    times = np.concatenate([np.cumsum(0.2 * 0.9 ** np.arange(20)), [0.0]])
    times[-1] = times[-2] + 1.1 * (times[-2] - times[-3])  # a click after the last bounce
    sigma = np.full(times.size, 20e-6)
    assert _trim_growing_end(times, sigma, 0.01) == times.size - 1
    assert _trim_growing_end(times[:-1], sigma[:-1], 0.01) == times.size - 1


def test_a_last_interval_spanning_two_bounces_is_a_missed_impact_not_growth():
    # Bounces shrinking by 0.9, the second-to-last one lost under the ring of the one before:
    # the last interval is two bounces of the trend (0.9 + 0.81 = 1.71 times the one before).
    times = np.cumsum(np.concatenate([[0.0], 0.2 * 0.9 ** np.arange(20)]))
    gap = np.delete(times, times.size - 2)
    sigma = np.full(gap.size, 20e-6)
    assert _trim_growing_end(gap, sigma, 0.01) == gap.size
    # A click one and a half bounces late is neither one nor two bounces: it goes.
    late = np.append(times[:-1], times[-2] + 1.3 * (times[-2] - times[-3]))
    assert _trim_growing_end(late, np.full(late.size, 20e-6), 0.01) == late.size - 1


def test_a_run_of_ring_bursts_in_the_chain_moves_back_onto_their_impacts():
    # Impacts shrinking by 0.9; each followed 6.5 ms later by a burst as loud as itself. The
    # chain holds the impacts, except for a run of six bursts in its middle.
    impacts = np.cumsum(0.2 * 0.9 ** np.arange(24))
    times = np.sort(np.concatenate([impacts, impacts + 6.5e-3]))
    amplitude = np.ones(times.size)
    chain = np.searchsorted(times, impacts)
    run = np.arange(10, 16)
    chain[run] = np.searchsorted(times, impacts[run] + 6.5e-3)
    moved = _move_to_causes(times, amplitude, chain)
    np.testing.assert_array_equal(times[moved], impacts)
    # A true chain stays, and so does a burst that is its own train's extra member.
    true_chain = np.searchsorted(times, impacts)
    np.testing.assert_array_equal(_move_to_causes(times, amplitude, true_chain), true_chain)


def test_runs_of_ring_bursts_in_the_chain_are_judged_one_run_at_a_time():
    # Impacts shrinking by 0.9, each followed 6.5 ms later by a burst as loud as itself; the
    # chain took the bursts of impacts 1 and 2 (on the long first intervals the trend barely
    # tells them apart). A click 6.5 ms before impact 18, left out, is no cause: moving
    # that member breaks the trend, and must not keep the first run from moving.
    impacts = np.cumsum(0.2 * 0.9 ** np.arange(24))
    click = impacts[18] - 6.5e-3
    times = np.sort(np.concatenate([impacts, impacts + 6.5e-3, [click]]))
    amplitude = np.ones(times.size)
    chain = np.searchsorted(times, impacts)
    chain[1:3] = np.searchsorted(times, impacts[1:3] + 6.5e-3)
    moved = _move_to_causes(times, amplitude, chain)
    np.testing.assert_array_equal(times[moved], impacts)


def test_the_chain_goes_on_through_an_impact_far_louder_than_the_echo_it_meets():
    # Impacts shrinking by 0.9, each echoed at a fifth of its loudness; the echo delay
    # happens to be the span from impact 10 to impact 15, so impact 15 (five times louder
    # than that echo) comes exactly where an echo of the chain is due. Followed on from the
    # first 15 impacts, the chain takes it and goes on to the end.
    impacts = np.cumsum(0.2 * 0.9 ** np.arange(24))
    echo_delay = impacts[15] - impacts[10]
    echoes = np.delete(impacts + echo_delay, 10)
    times = np.concatenate([impacts, echoes])
    amplitude = np.concatenate([np.ones(impacts.size), np.full(echoes.size, 0.2)])
    order = np.argsort(times)
    times, amplitude = times[order], amplitude[order]
    chain = np.searchsorted(times, impacts[:15])
    delays = _secondary_delays(times, chain)
    levels = _secondary_levels(times, amplitude, chain, delays)
    extended, _ = _extend_chain(times, amplitude, chain, _trend(times[chain]), None, delays,
                                levels)
    np.testing.assert_allclose(times[extended], impacts)


def test_the_ratio_trend_is_not_bent_by_ring_bursts_taken_for_impacts():
    # 21 impacts shrinking by 0.87 with a 1 % scatter; the last seven also have the burst of
    # their ring, 6.4 ms later, among them (14 ratios of 0.1-10). The scatter about the
    # trend is that of the bounces, not one bent by the bursts' ratios.
    rng = np.random.default_rng(20261125)
    intervals = 0.13 * np.cumprod(0.87 * np.exp(0.01 * rng.standard_normal(20)))
    impacts = np.cumsum(np.concatenate([[0.0], intervals]))
    times = np.sort(np.concatenate([impacts, impacts[-7:] + 6.4e-3]))
    _, scatter = ratio_trend(times)
    assert scatter < 0.02


def test_a_ring_burst_standing_in_for_an_impact_is_timed_at_the_impact_or_left_out():
    # Impacts shrinking by 0.9; impacts 20-23 were passed over and their rings' bursts, 6.5 ms
    # later, stand in for them (the burst of every impact recurs at that delay).
    impacts = np.cumsum(0.2 * 0.9 ** np.arange(30))
    timed = impacts.copy()
    timed[20:24] += 6.5e-3
    coefficients, scatter = _robust_trend(np.delete(timed, np.arange(20, 24)))

    def probe(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
              impulse=False):
        # The impacts' own onsets are in the file, where the trend puts them.
        return onset_near(impacts, predicted, tolerance)

    added, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                                   np.array([6.5e-3]), probe, impacts[-1] + 1.0)
    assert sorted(retimed) == [20, 21, 22, 23]
    np.testing.assert_allclose([retimed[k][0] for k in range(20, 24)], impacts[20:24])

    def silent(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
               impulse=False):
        return None

    # No onset where the trend puts them: the bursts are left out (gaps), never kept as
    # impacts nor replaced by predicted times.
    added, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                                   np.array([6.5e-3]), silent, impacts[-1] + 1.0)
    assert retimed == {20: None, 21: None, 22: None, 23: None} and not added


def test_a_late_impact_on_a_loose_trend_is_not_taken_for_a_secondary_of_the_predicted_one():
    # Long first intervals (0.1-0.2 s) whose ratios scatter by 0.02: the trend places an
    # impact to within 3 × 0.02 of its interval, some 7 ms. Impact 6 comes 9 ms late, 1.5 ms
    # from "the ring's burst, 7.5 ms after the predicted impact", but an impact anywhere in
    # that window fits the prediction about as well: a delay under twice the tolerance does
    # not tell a secondary from the impact, and with no other onset near, it stays as timed.
    impacts = np.cumsum(0.2 * 0.9 ** np.arange(25))
    timed = impacts.copy()
    timed[6] += 9e-3
    coefficients, _ = _robust_trend(impacts)
    scatter = 0.02
    tolerance = 3.0 * scatter * (impacts[6] - impacts[5]) + 0.2e-3
    assert 9e-3 > tolerance > 0.5 * 7.5e-3 and abs(9e-3 - 7.5e-3) < tolerance

    def silent(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
               impulse=False):
        return None

    _, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                               np.array([7.5e-3]), silent, timed[-1] + 1.0)
    assert 6 not in retimed


def _ending_one_burst_after():
    """Impacts shrinking by 0.85 (times, s), the bursts' delay (s: where the next bounce
    would come), the impacts as timed with one more sound that delay after the last, and the
    impacts' trend (coefficients, scatter)."""
    impacts = np.cumsum(0.1 * 0.85 ** np.arange(18))
    burst = 0.1 * 0.85**18
    return (impacts, burst, np.append(impacts, impacts[-1] + burst), *_robust_trend(impacts))


def test_the_burst_of_the_last_impact_is_not_one_more_bounce():
    # The last sound of the train is the ring burst of the last impact, at the delay at which
    # the bursts of all impacts recur, which happens to be where the next bounce would come:
    # nothing after it tells it from a bounce but that delay.
    impacts, burst, timed, coefficients, scatter = _ending_one_burst_after()

    def silent(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
               impulse=False):
        return None

    added, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                                   np.array([burst]), silent, timed[-1] + 1.0)
    assert retimed == {timed.size - 1: None} and not added
    # Where the bursts recur at another delay, the same last bounce stays.
    _, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                               np.array([burst + 1e-3]), silent, timed[-1] + 1.0)
    assert not retimed


def test_a_last_impact_one_burst_delay_after_the_one_before_that_sets_off_its_own_burst_stays():
    # The last bounce comes one burst delay after the impact before it, where that impact's
    # burst sounds too: a burst sets off no burst of its own, an impact does.
    impacts, burst, timed, coefficients, scatter = _ending_one_burst_after()

    def bursts_of(sounds):
        def probe(predicted, tolerance, not_before=None, predicted_sound=False,
                  expected=False, impulse=False):
            return onset_near(sounds + burst, predicted, tolerance)
        return probe

    added, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                                   np.array([burst]), bursts_of(timed), timed[-1] + 1.0,
                                   np.array([1.0]))
    assert not retimed and not added
    # Followed by no burst of its own, it is the burst of the impact before.
    _, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                               np.array([burst]), bursts_of(impacts), timed[-1] + 1.0,
                               np.array([1.0]))
    assert retimed == {timed.size - 1: None}


def test_a_last_impact_shows_its_burst_when_the_search_for_more_impacts_stops_before_it():
    # A later pass of the search looks for no impact past the last one (`stop`), but the
    # burst that tells the last impact from the burst of the one before comes after it, and
    # is still looked for (up to the recording's end).
    impacts, burst, timed, coefficients, scatter = _ending_one_burst_after()

    def probe(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
              impulse=False):
        return onset_near(timed + burst, predicted, tolerance)

    added, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                                   np.array([burst]), probe, timed[-1] + 1.0, np.array([1.0]),
                                   stop=timed[-1] + 1e-3)
    assert not retimed and not added


def test_a_burst_an_impact_lands_on_is_not_asked_of_the_impact_before_it():
    # The last interval is the bursts' delay, the one before 1/0.85 of it: the burst of the
    # impact two before the last comes about 1 ms before the impact in between, whose onset
    # the probe finds instead. That impact shows nothing either way; the last impact sets off
    # its own burst and stays.
    impacts, burst, timed, coefficients, scatter = _ending_one_burst_after()
    lead = timed[-2] - (timed[-3] + burst)
    assert 0.5e-3 < lead < 1e-3

    def probe(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
              impulse=False):
        # An impact starting within the search's reach (its tolerance and the 0.5 ms window
        # after it) is what the probe finds; else the nearest burst.
        reach = (timed > predicted - tolerance) & (timed <= predicted + tolerance + 0.5e-3)
        if reach.any():
            return (timed[reach][0], 1e-5, 1.0, False)
        return onset_near(timed + burst, predicted, tolerance)

    added, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                                   np.array([burst]), probe, timed[-1] + 1.0, np.array([1.0]))
    assert not retimed and not added


def test_a_trend_stepped_outside_its_intervals_stays_within_the_ratio_bounds(tmp_path):
    # A parabola fitted on a chain that scatters widely (log ratio 3.5 + 2.3 ln T + 0.3 ln² T)
    # gives absurd ratios away from its intervals: 1.28 at 0.15 s, 34 at 1 s, 617 at 3 s,
    # and stepped on a few times past float range.
    step = _trend_step(np.array([0.305, 2.305, 3.524]), 7e-4)
    for interval in (0.15, 1.0, 3.0, 1e-4):
        assert 0.45 * interval <= step(interval) <= 1.2 * interval
    # A train whose chain came out like that (seed 20271148, never tuned on) crashed the
    # search for the impacts the trend predicts with an OverflowError.
    samples, _, _ = disturbed_train(20271148)
    path = write_audio(tmp_path / "train.wav", samples, RATE, subtype="FLOAT")
    try:
        detect_impacts(path)
    except InputError:
        pass  # refusing such a chain as no bounce train is an answer too


def test_a_last_impact_at_the_delay_of_an_earlier_ones_ring_is_judged_by_its_loudness():
    # Bounces shrinking by 0.9, all equally loud, with a ring at 0.3 of its impact's loudness
    # recurring after each at the sum of the last three intervals: the last impact, not
    # timed yet, falls on the ring of the impact three bounces before it.
    impacts = np.cumsum(0.1 * 0.9 ** np.arange(20))
    timed = impacts[:-1]
    coefficients, scatter = _robust_trend(timed)
    delays, levels = np.array([impacts[-1] - impacts[-4]]), np.array([0.3])

    def found(loudness):
        def probe(predicted, tolerance, not_before=None, predicted_sound=False,
                  expected=False, impulse=False):
            if not_before is not None and not_before >= impacts[-1]:
                return None  # nothing rises out of the sound past its own onset
            return onset_near(impacts, predicted, tolerance, loudness)
        added, _ = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter, delays,
                                 probe, impacts[-1] + 1.0, levels)
        return [row[0] for row in added]

    # As loud as the impacts before it: more than twice what the ring is, so no ring.
    np.testing.assert_allclose(found(0.95), [impacts[-1]])
    # As faint as that ring may be: it may be the ring, and is left out.
    assert found(0.5) == []
    # One delay after the impact just before it, a sound however loud is that impact's ring
    # burst or echo: no impact follows it to tell them apart.
    delays = np.array([impacts[-1] - impacts[-2]])
    assert found(0.95) == []


def test_anchors_jammed_inside_the_train_do_not_end_the_search_for_its_last_impacts():
    # Bounces shrinking by 0.9; impact 10 is followed by three sounds 1.05 ms apart (a rattle
    # taken among the impacts), and the last impact has no onset timed yet. The trend stepped
    # on from the rattle's intervals predicts none longer than the merge window, which only
    # past the last impact ends the train: the search goes on to the last impact.
    impacts = np.cumsum(0.2 * 0.9 ** np.arange(25))
    rattle = impacts[10] + 1.05e-3 * np.arange(1, 4)
    timed = np.sort(np.concatenate([impacts[:-1], rattle]))
    coefficients, scatter = _robust_trend(impacts[:-1])

    def probe(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
              impulse=False):
        return onset_near(impacts, predicted, tolerance)

    added, _ = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter, np.zeros(0),
                             probe, impacts[-1] + 1.0)
    np.testing.assert_allclose([row[0] for row in added], [impacts[-1]])


def test_a_predicted_time_next_to_a_timed_impact_is_that_impact():
    # Bounces shrinking by 0.9, impact 17 on 0.8 ms later than the trend (outside the
    # tolerance of its prediction); the ring burst of impact 16, 5 ms after it, is timed among
    # the impacts and left out, and the predicted time that stands in for it lies 0.8 ms
    # before impact 17: both are that impact. The three impacts after it, not timed yet, are
    # found where the trend puts them from impact 17 itself.
    impacts = np.cumsum(0.1 * 0.9 ** np.arange(21))
    impacts[17:] += 0.8e-3
    delay = 5e-3
    timed = np.sort(np.append(impacts[:18], impacts[16] + delay))
    coefficients, scatter = _robust_trend(impacts[:17])

    def probe(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
              impulse=False):
        later = impacts if not_before is None else impacts[impacts > not_before]
        return onset_near(later, predicted, tolerance) if later.size else None

    added, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                                   np.array([delay]), probe, impacts[-1] + 1.0)
    assert retimed == {17: None}
    np.testing.assert_allclose([row[0] for row in added], impacts[18:])


def test_no_impact_is_reported_after_the_ball_has_come_to_rest():
    # Bounces shrinking by 0.9 down to 8 ms, then the echoes of the last five, 200 ms later:
    # their intervals continue the train's, but they come long after the flights the trend
    # leaves after the last impacts (about 60 ms).
    impacts = np.cumsum(0.1 * 0.9 ** np.arange(25))
    times = np.concatenate([impacts, impacts[-5:] + 0.2])
    coefficients, scatter = _robust_trend(times)
    assert _rest_time(times, coefficients, scatter) == impacts.size
    # The train alone keeps its last bounce.
    assert _rest_time(impacts, *_robust_trend(impacts)) == impacts.size


def test_the_rest_time_holds_where_a_close_pair_of_sounds_after_the_train_bends_its_trend():
    # Bounces shrinking by 0.88 down to 6 ms; 80-120 ms after the last one, sounds of the
    # rest tail, two of them 1.2 ms apart. The trend's parabola, fitted with the train's
    # ratio nearly constant, climbs back to 1 at intervals near 1 ms: stepped on from the
    # last flights down to there, the flights stopped shrinking and no rest time was found.
    # Held at each flight's own ratio, the flights after the last impact sum to about 45 ms.
    impacts = np.cumsum(0.06 * 0.88 ** np.arange(19))
    tail = impacts[-1] + np.array([0.080, 0.092, 0.104, 0.1188, 0.120])
    times = np.concatenate([impacts, tail])
    coefficients = np.array([0.013, 0.084, -0.01])  # log ratio against log interval (s)
    assert _rest_time(times, coefficients, 0.02) == impacts.size


def test_the_train_ends_at_the_first_grown_interval_though_the_sounds_after_it_shrink():
    # Bounces shrinking by 0.88 down to 6.4 ms, then the rings of the last five, 29.7 ms
    # after each: the interval into the first ring grows (8.4 ms), and the rings repeat the
    # train's earlier intervals, so the last ratios shrink again.
    impacts = np.cumsum(0.06 * 0.88 ** np.arange(19))
    rings = impacts[-4:] + 0.0297
    times = np.concatenate([impacts, rings])
    sigma = np.full(times.size, 60e-6)
    assert _trim_growing_end(times, sigma, 0.02) == impacts.size
    # Sounds close together 75-86 ms after the last bounce: their intervals come back under
    # the train's, but no bounces of it span 75 ms after 6.4 ms flights.
    late = np.concatenate([impacts, impacts[-1] + np.array([0.0754, 0.0831, 0.0856])])
    assert _trim_growing_end(late, np.full(late.size, 60e-6), 0.02) == impacts.size


def test_an_echo_of_the_trains_tail_longer_than_a_quarter_of_it_is_left_out():
    # Twenty bounces shrinking by 0.86 down to 6 ms and the echoes of the last thirteen,
    # from a far wall: a copy of the train's tail, more than a third of the sounds. The first
    # echo comes 9 ms after the last bounce (about two bounces of the trend), the next one
    # 60 ms after that: no bounces of the train.
    impacts = np.cumsum(0.2 * 0.86 ** np.arange(20))
    echoes = impacts[-13:] + (impacts[-1] - impacts[-13] + 9e-3)
    times = np.concatenate([impacts, echoes])
    assert times.size - impacts.size > times.size / 3
    sigma = np.full(times.size, 30e-6)
    assert _trim_growing_end(times, sigma, 0.02) in (impacts.size, impacts.size + 1)


def _train_with_echo(delay, factor=0.3):
    """Thirty bounces shrinking by 0.9 from 0.2 s (times, s; amplitudes ∝ interval) and their
    echoes `delay` (s) later, `factor` as loud: (impacts, amplitudes, echoes, echo
    amplitudes)."""
    intervals = 0.2 * 0.9 ** np.arange(30)
    impacts = np.concatenate([[0.0], np.cumsum(intervals)])
    amplitudes = 0.5 * np.concatenate([[intervals[0]], intervals]) / intervals[0]
    return impacts, amplitudes, impacts + delay, factor * amplitudes


def _as_transients(rng, sounds):
    """Rough onsets (s, 0.2 ms off the fitted ones) and the fitted onsets' function."""
    rough = sounds + rng.normal(0.0, 0.2e-3, sounds.size)
    return rough, lambda indices: sounds[np.asarray(indices)]


def test_echoes_of_the_train_after_it_ended_are_left_out():
    # An echo from a far wall, 0.15 s after each impact: the chain went on past the last
    # bounce through the echoes of the ones before, and the transients hold the echoes of
    # the others too. The copy repeats its sources' fitted onsets to within a few µs.
    rng = np.random.default_rng(20261126)
    impacts, amplitudes, echoes, echo_amplitudes = _train_with_echo(0.15)
    after = echoes > impacts[-1]
    times = np.concatenate([impacts, echoes[after]])
    loudness = np.concatenate([amplitudes, echo_amplitudes[after]])
    sigmas = np.full(times.size, 5e-6)
    sounds = np.concatenate([impacts, echoes])
    rough, fitted = _as_transients(rng, sounds)
    keep = _echoed_tail(times + rng.normal(0.0, 3e-6, times.size), sigmas, loudness, rough,
                        np.concatenate([amplitudes, echo_amplitudes]), fitted)
    np.testing.assert_array_equal(keep, np.arange(times.size) < impacts.size)


def test_a_copy_of_the_train_holding_two_echoes_timed_off_in_a_row_is_left_out():
    # As above, two echoes in the middle of the copy timed 0.8 ms off their sources (an
    # echo's onset taken on the ring it landed on): the run of echoes goes on past them, and
    # they stay, being no longer where the echo repeats its sources.
    rng = np.random.default_rng(20261129)
    impacts, amplitudes, echoes, echo_amplitudes = _train_with_echo(0.15)
    after = np.flatnonzero(echoes > impacts[-1])
    timed_off = after[after.size // 2:after.size // 2 + 2]
    moved = echoes.copy()
    moved[timed_off] += 0.8e-3
    times = np.concatenate([impacts, moved[after]])
    loudness = np.concatenate([amplitudes, echo_amplitudes[after]])
    rough, fitted = _as_transients(rng, np.concatenate([impacts, echoes]))
    keep = _echoed_tail(times + rng.normal(0.0, 3e-6, times.size), np.full(times.size, 5e-6),
                        loudness, rough, np.concatenate([amplitudes, echo_amplitudes]), fitted)
    np.testing.assert_array_equal(keep, (np.arange(times.size) < impacts.size)
                                  | np.isin(np.arange(times.size),
                                            impacts.size + np.searchsorted(after, timed_off)))


def test_impacts_among_the_echoes_of_the_train_stay():
    # A nearer wall, 40 ms: the echoes of the train's middle come among its last bounces,
    # which stay; only the echoes go.
    rng = np.random.default_rng(20261127)
    impacts, amplitudes, echoes, echo_amplitudes = _train_with_echo(0.04)
    taken = echoes > impacts[-8]  # the echoes the chain took with the last bounces
    times = np.concatenate([impacts, echoes[taken]])
    order = np.argsort(times)
    is_echo = (np.arange(times.size) >= impacts.size)[order]
    loudness = np.concatenate([amplitudes, echo_amplitudes[taken]])[order]
    rough, fitted = _as_transients(rng, np.concatenate([impacts, echoes]))
    keep = _echoed_tail(times[order], np.full(times.size, 5e-6), loudness, rough,
                        np.concatenate([amplitudes, echo_amplitudes]), fitted)
    np.testing.assert_array_equal(keep, ~is_echo)


def test_sounds_that_fit_a_delay_only_by_chance_are_no_echo_of_the_train():
    # The last bounces among many louder transients (a ring's bursts, clicks; one every 3 ms
    # on average): some delay puts several bounces within 1 ms of them, but none repeats their
    # fitted onsets.
    rng = np.random.default_rng(20261128)
    impacts, amplitudes, _, _ = _train_with_echo(0.15)
    sounds = np.sort(rng.uniform(0.0, impacts[-1], int(impacts[-1] / 3e-3)))
    loudness = rng.uniform(1.0, 3.0, sounds.size)
    rough, fitted = _as_transients(rng, sounds)
    keep = _echoed_tail(impacts, np.full(impacts.size, 5e-6), amplitudes, rough, loudness,
                        fitted)
    assert keep.all()


def test_an_impact_timed_off_in_the_last_quarter_does_not_end_the_train():
    # Bounces shrinking by 0.9; impact 24 of 30 timed 1 ms early (on a ring before it) and
    # impacts 26-27 timed 0.6 ms late: the intervals around each grow and shrink back, and
    # every pair of them is two bounces.
    times = np.cumsum(0.1 * 0.9 ** np.arange(30))
    sigma = np.full(times.size, 20e-6)
    timed = times.copy()
    timed[24] -= 1e-3
    timed[26:28] += 0.6e-3
    assert _trim_growing_end(timed, sigma, 0.02) == times.size


def test_a_chain_that_is_no_bounce_train_is_judged_again_once_its_bursts_are_resolved(tmp_path):
    # A development train (seed 20281227) with ring bursts 1.14 times as loud as their
    # impacts 6.9 ms after them and an echo at 66 ms: the first chain took bursts and echoes
    # for impacts, and the one chosen again without the echoes still held bursts of
    # impacts hidden under them, so the file was refused as clicks. Those impacts are found
    # in the error of a predictor of the burst before them; judged on the impacts so found,
    # the chain is a bounce train.
    samples, onsets, _ = disturbed_train(20281227)
    path = write_audio(tmp_path / "bursts.wav", samples, RATE, subtype="FLOAT")
    found = detect_impacts(path)["time"].to_numpy()
    distance = np.abs(onsets[:, None] - found[None, :])
    assert np.all(distance.min(axis=1) < MATCH)
    assert np.all(distance.min(axis=0) < MATCH)


def test_an_impact_on_a_louder_burst_between_two_impacts_is_found(tmp_path):
    # A development train (seed 20321307) whose ring bursts, 5.2 ms after each impact, are
    # 1.47 times as loud as it: the second-to-last impact starts on the burst of the one
    # before and rises over it in the error of a predictor of that sound only as much as a
    # weak trigger. Between two impacts timed on the trend the ball did bounce there: a weak
    # trigger's jump suffices, and the impact is found rather than left a gap.
    samples, onsets, options = disturbed_train(20321307)
    assert options["burst_levels"][0] > 1.4
    path = write_audio(tmp_path / "louder-bursts.wav", samples, RATE, subtype="FLOAT")
    found = detect_impacts(path)["time"].to_numpy()
    distance = np.abs(onsets[:, None] - found[None, :])
    assert np.all(distance.min(axis=1) < MATCH)
    assert np.all(distance.min(axis=0) < MATCH)


def test_a_late_impact_is_not_taken_for_a_secondary_at_a_short_delay():
    # A rattle 1.3 ms after each impact recurs (the real bouncy-ball drop); the last impact
    # comes 1.5 ms later than the trend predicts, 0.2 ms from "the rattle of the predicted
    # impact". Delays under 3 ms are an impact's own sound: it stays as timed.
    impacts = np.cumsum(0.2 * 0.9 ** np.arange(25))
    timed = impacts.copy()
    timed[-1] += 1.5e-3
    coefficients, scatter = _robust_trend(impacts[:-1])

    def probe(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
              impulse=False):
        return (timed[-1], 1e-5, 1.0, False)  # the only onset near: the impact itself

    _, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                               np.array([1.3e-3]), probe, timed[-1] + 1.0)
    assert not retimed


def test_a_spanning_last_interval_does_not_license_a_longer_one_after_it():
    # Bounces shrinking by 0.9 down to 11 ms; the next impact is heard three bounces later
    # (two missed in between), then a click 1.7 times that interval after it. Stepping the
    # trend on from the spanning interval took the click for two more bounces.
    times = np.cumsum(np.concatenate([[0.0], 0.1 * 0.9 ** np.arange(22)]))
    bounce = times[-1] - times[-2]
    times = np.append(times, times[-1] + bounce * (0.9 + 0.9**2 + 0.9**3))
    times = np.append(times, times[-1] + 1.7 * (times[-1] - times[-2]))
    sigma = np.full(times.size, 20e-6)
    assert _trim_growing_end(times, sigma, 0.02) == times.size - 1


def test_the_train_does_not_end_on_a_secondary_of_its_last_impacts():
    # Bounces shrinking by 0.9, each followed 6.4 ms later by a ring burst at 0.8 of its
    # loudness; the last burst is left, 0.9 times the last interval after the last impact.
    impacts = np.cumsum(0.1 * 0.9 ** np.arange(20))
    loudness = 0.5 * 0.93 ** np.arange(20)
    delay = 0.9 * (impacts[-1] - impacts[-2])
    times = np.append(impacts, impacts[-1] + delay)
    amplitudes = np.append(loudness, 0.8 * loudness[-1])
    kept = _drop_trailing_secondaries(times, amplitudes, np.array([delay]), np.array([0.8]))
    assert kept == impacts.size
    # A last bounce as loud as the impacts before it stays, whatever its delay: the sums of
    # the last intervals come close to any delay.
    louder = np.append(loudness, 0.93 * loudness[-1])
    assert _drop_trailing_secondaries(times, louder, np.array([delay]),
                                      np.array([0.3])) == times.size
    # ... and so does a sound at no recurring delay.
    assert _drop_trailing_secondaries(times, amplitudes, np.array([delay + 1e-3]),
                                      np.array([0.8])) == times.size


def test_a_last_impact_that_lands_on_a_faint_ring_is_no_ring():
    # Bounces shrinking by 0.9, fading by 5 % each, with a ring at 0.4 of its impact's
    # loudness; the last bounce comes one ring delay after the fourth impact from the end.
    # Measured at three quarters of the impacts before it, it is closer to them than to the
    # ring (0.44 of them) and stays, though no louder than twice the ring; a sound at half
    # their loudness is closer to the ring and goes.
    impacts = np.cumsum(0.1 * 0.9 ** np.arange(20))
    loudness = 0.5 * 0.95 ** np.arange(20)
    delay = np.array([impacts[-1] - impacts[-4]])
    recent = np.median(loudness[-4:-1])
    impact = np.append(loudness[:-1], 0.75 * recent)
    assert _drop_trailing_secondaries(impacts, impact, delay, np.array([0.4])) == impacts.size
    ring = np.append(loudness[:-1], 0.5 * recent)
    assert _drop_trailing_secondaries(impacts, ring, delay, np.array([0.4])) == impacts.size - 1


def test_a_sound_left_last_by_the_later_checks_is_judged_for_a_secondary_delay_again():
    # Bounces shrinking by 0.9, fading by 5 % each; 6.4 ms after the last one its ring burst
    # at 0.8 of its loudness, and after that a click far fainter than a bounce (a tenth of
    # the last impact's loudness). The click is left out as too faint; the burst is then
    # the last sound, at the burst's delay and no louder than a burst: it goes too.
    impacts = np.cumsum(0.1 * 0.9 ** np.arange(20))
    loudness = 0.5 * 0.95 ** np.arange(20)
    delay = 6.4e-3
    burst = impacts[-1] + delay
    times = np.r_[impacts, burst, burst + 0.9 * (burst - impacts[-1])]
    amplitudes = np.r_[loudness, 0.8 * loudness[-1], 0.1 * loudness[-1]]
    sigmas = np.full(times.size, 20e-6)

    def probe(moment, tolerance, not_before=None, predicted_sound=False, expected=False,
              any_jump=False):
        return None  # no further sound in the file: no check on secondaries can be made

    kept, grown_out, secondaries_out, faint_out = _train_end(
        times, sigmas, amplitudes, 0.01, np.array([delay]), np.array([0.8]), probe,
        np.zeros(times.size, dtype=bool), times[-1] + 1.0)
    assert kept == impacts.size
    assert (grown_out, secondaries_out, faint_out) == (0, 1, 1)


def test_a_train_whose_first_two_chains_are_no_bounce_train_is_chosen_a_third_time(tmp_path):
    # A development train (seed 20291333) with a ring burst as loud as the impact 7.6 ms
    # after it, a ring at 17.7 ms and an echo at 42 ms: the first chain took the first burst
    # and then the rings for impacts, and measured from it the secondaries' delays were
    # wrong; chosen without those, the chain still followed the rings. Chosen once more
    # without the secondaries of that second chain, the first chain's members kept, it is
    # the train: every impact is found, and the file is not refused as clicks.
    samples, onsets, _ = disturbed_train(20291333)
    path = write_audio(tmp_path / "rings.wav", samples, RATE, subtype="FLOAT")
    found = detect_impacts(path)["time"].to_numpy()
    assert np.all(np.abs(onsets[:, None] - found[None, :]).min(axis=1) < MATCH)


def test_the_members_of_a_chain_that_followed_an_echo_of_the_train_are_found():
    # Impacts shrinking by 0.85, fading by 4 % each, each with an echo at half its loudness
    # 145 ms later; a chain took the first impact and then the echoes (a copy of the train's
    # intervals, longer by the delay). The echoes are found as such; the first impact, and
    # the impacts left out, are not.
    impacts = 0.2 + np.cumsum(np.r_[0.0, 0.116 * 0.85 ** np.arange(18)])
    loudness = 0.5 * 0.96 ** np.arange(impacts.size)
    echoes = impacts + 0.145
    order = np.argsort(np.r_[impacts, echoes])
    times = np.r_[impacts, echoes][order]
    amplitude = np.r_[loudness, 0.5 * loudness][order]
    is_echo = np.r_[np.zeros(impacts.size, bool), np.ones(impacts.size, bool)][order]
    chain = np.r_[0, np.flatnonzero(is_echo)]
    echoing = _echoing_members(times, amplitude, chain)
    np.testing.assert_array_equal(echoing, is_echo)
    # A chain of the impacts has no louder sound one recurring delay before its members.
    assert not _echoing_members(times, amplitude, np.flatnonzero(~is_echo)).any()
    # With the echo 0.18 s later, impact 3 falls on the echo of impact 1 (one sound), and the
    # chain takes impacts 0-3 and then the echoes from that of impact 2 on. Impact 3 is
    # marked only where the chain's own members count as causes; so are the echoes of
    # impacts 2 and 3, and those of the impacts left out are marked either way.
    delay = impacts[3] - impacts[1]
    echoes = np.delete(impacts + delay, 1)
    order = np.argsort(np.r_[impacts, echoes])
    times = np.r_[impacts, echoes][order]
    amplitude = np.r_[loudness, 0.5 * np.delete(loudness, 1)][order]
    position = np.argsort(order)  # where each impact and echo went
    chain = np.r_[position[:4], position[impacts.size + 1:]]
    assert _echoing_members(times, amplitude, chain)[position[3]]
    echoing = _echoing_members(times, amplitude, chain, causes_in_chain=False)
    np.testing.assert_array_equal(np.flatnonzero(echoing), position[impacts.size + 3:])


def test_a_passing_chain_that_followed_an_echo_of_the_train_gives_way_to_the_train(tmp_path):
    # A development train (seed 20381462) with an echo at 0.42 of the loudness 165 ms after
    # each impact: the chain took impacts 0 and 3 and then the echoes of the impacts from
    # the second on, which continue its intervals and outlast the train, so it passed as a
    # bounce train with 10 of the 21 impacts. Chosen again without the members that echo a
    # louder sound it left out, it is the train.
    score, onsets = detected_score(tmp_path, 20381462)
    assert score["found"] == onsets.size
    assert score["false"] == 0


def test_a_train_just_past_the_first_block_is_timed_as_in_a_short_file(tmp_path):
    # A train (seed 20451010) starting 29.8 s into a recording streamed in the default 30 s
    # blocks: the second block held little more than the train, too few quiet stretches for a
    # noise estimate of its own, and 5 of its 22 impacts were lost. A last block shorter than
    # half a block is now processed with the one before.
    samples, onsets, _ = disturbed_train(20451010)
    rng = np.random.default_rng(20451010)
    lead = rng.normal(scale=np.std(samples[:int(0.1 * RATE)]), size=int(29.6 * RATE))
    found = []
    for name, recording, shift in (("short", samples, 0.0),
                                   ("long", np.concatenate([lead, samples]), lead.size / RATE)):
        path = write_audio(tmp_path / f"{name}.wav", recording, RATE, subtype="FLOAT")
        found.append(score_train(onsets + shift, detect_impacts(path)["time"].to_numpy(),
                                 np.ones(onsets.size), MATCH)["found"])
    assert found[0] >= onsets.size - 1
    assert found[1] == found[0]


@pytest.mark.parametrize("seed", [20441002, 20441009])
def test_loud_noise_after_the_train_does_not_change_how_its_impacts_are_looked_for(
        tmp_path, monkeypatch, seed):
    # The recording streamed in blocks of 1 s, with 3 s of noise 30 dB over the train's after
    # it (someone speaking once the ball is at rest): the search for the impacts the trend
    # predicts and the retiming on first bursts took the noise level of the last block, and
    # lost 6-11 impacts of these trains. Each moment is now judged against the noise of its
    # own block.
    samples, onsets, _ = disturbed_train(seed)
    rng = np.random.default_rng(seed)
    monkeypatch.setattr(audio, "_BLOCK_SECONDS", 1.0)
    found = []
    for level in (0.0, 0.02):
        noisy = np.concatenate([samples, rng.normal(scale=level, size=3 * RATE)])
        path = write_audio(tmp_path / f"noise{level}.wav", noisy, RATE, subtype="FLOAT")
        table = detect_impacts(path)
        found.append(score_train(onsets, table["time"].to_numpy(), np.ones(len(table)),
                                 MATCH)["found"])
    assert found[0] >= onsets.size - 1
    assert found[1] >= found[0] - 1


@pytest.mark.parametrize("seed", [20431475, 20361079])
def test_a_train_whose_impacts_land_on_its_echo_is_not_refused(tmp_path, seed):
    # Trains (seeds 20431475, 20361079) refused as no bounce train: the first chain took the
    # first impact and then the echo of the train (159 ms later, half as loud), and chosen
    # again without the echoes it skipped the impacts that land a few ms after an echo or a
    # ring: those jump too little over the sound before them for a strong trigger, and the
    # chain of strong transients alone scattered like clicks. Before refusing, the choices
    # are made again with the weak transients too.
    score, onsets = detected_score(tmp_path, seed)
    assert score["found"] >= onsets.size - 1
    assert score["false"] <= 1


@pytest.mark.parametrize("seed", [20401258, 20401270])
def test_no_two_impacts_are_timed_within_the_merge_window(tmp_path, seed):
    # Development trains where an impact's onset was moved back onto a first burst that was
    # the echo the table also held (seed 20401258, its impact then missing), or onto another
    # row's onset (20401270): two rows at one time, a zero interval.
    samples, onsets, _ = disturbed_train(seed)
    path = write_audio(tmp_path / "train.wav", samples, RATE, subtype="FLOAT")
    found = detect_impacts(path)["time"].to_numpy()
    assert np.diff(found).min() >= 1e-3


def test_a_chain_chosen_without_the_echo_that_takes_rings_instead_is_not_taken(tmp_path):
    # A development train (seed 20401271): the first chain took the echoes of the last
    # impacts; chosen without them, the chain took the rings and bursts of impacts 10-12 and
    # stopped at impact 13 of 22, and passed. Five of its 19 members are secondaries of its
    # own impacts: the first chain is kept, and its later checks find the train.
    score, onsets = detected_score(tmp_path, 20401271)
    assert score["found"] >= onsets.size - 1


def test_a_chain_that_followed_an_echo_of_the_train_is_chosen_again_without_it(tmp_path):
    # A development train (seed 20301443) with an echo at half the loudness 145 ms after
    # each impact: the chain took the first impact and then the echoes, and the louder
    # impacts between its members made the file refused as clicks.
    samples, onsets, _ = disturbed_train(20301443)
    path = write_audio(tmp_path / "echo.wav", samples, RATE, subtype="FLOAT")
    found = detect_impacts(path)["time"].to_numpy()
    distance = np.abs(onsets[:, None] - found[None, :])
    assert np.mean(distance.min(axis=1) < MATCH) >= 0.9
    assert np.sum(distance.min(axis=0) >= MATCH) <= 1


# Trains at 22.05 kHz that lost many impacts, or were refused, each found while measuring a
# block of seeds (in the id), and what went wrong there.
WHOLE_TRAINS = [
    # An echo 51 ms after each impact, 0.43 as loud, a ring at 19.6 ms, a burst at 6.2 ms.
    # The first chain stepped from impact 2 onto its echo and on through echoes and rings
    # (22 members, 8 of them secondaries) and failed the bounce-train check, and no louder
    # sound lay between its members to set aside the echoes it followed: the file was
    # refused. Chosen without the members that follow a louder transient at a recurring
    # delay, the chain is the train.
    pytest.param(20_513_059, 16, id="refused-echo-20513001"),
    # An echo half as loud as its impact, 168.6 ms (151 ms) after it. The first chain followed
    # the train, then stepped onto its echo and on to the echo's end (7 and 16 of the
    # impacts timed, 7 and 6 false ones). Chosen without its echoing members, the chain took
    # the echoes of the early impacts it had skipped (in the first train it also broke where
    # an impact lands 2.3 ms after an echo, its trigger weak), and that choice was not
    # taken. Chosen without every echo of the train, the weak transients just after one
    # counting as strong, the chain is the train.
    pytest.param(20_514_492, 27, id="along-echo-20514001"),
    pytest.param(20_513_187, 22, id="along-echo-20513001"),
    # An echo 193 ms after each impact, half as loud, near the sum of the first two
    # intervals. The first chain followed the echo; chosen without its echoing members, it
    # took every other bounce (a train of ratio ρ² passes the bounce-train check), and the
    # impact at 0.632 s, on which the echo of the one at 0.439 s lands, was set aside with
    # the echoes: one of the chain's intervals held no stepped-over bounce, and the run of
    # five that tells a halved chain broke (8 of 21 impacts timed). Five of six intervals
    # now tell it.
    pytest.param(20_515_706, 21, id="halved-20515301"),
    # An echo 76.9 ms after each impact, 0.38 as loud. The echo of the impact at 1.3905 s
    # lands 1.7 ms before the one at 1.4691 s; the chain took both, the trend bent by them
    # put the impact at the echo, and the search for the impacts after it stopped on the
    # two sounds 1.7 ms apart (25 of 32 impacts timed). Two sounds too close to both be
    # bounces, the first an echo of an earlier impact and the second no secondary of any,
    # are an echo and an impact, whatever the trend says.
    pytest.param(20_515_774, 32, id="echo-before-impact-20515301"),
    # A ring burst 5.3 ms after each impact, 1.3 times as loud, an echo at 50.8 ms (on a
    # block measured to check the changes above). Every choice took an echo and a ring in
    # place of the impact between them (twice), or the bursts of the last impacts, and
    # failed the bounce-train check: the file was refused. The bursts outsound their
    # impacts, so they were never set aside as secondaries; set aside up to twice their
    # usual level, the chain is the train.
    pytest.param(20_517_532, 16, id="refused-louder-bursts-20517001"),
    # A ring burst 5-8 ms after each impact, about as loud (1.08 times). The last four
    # impacts, on the decaying sound of the ones before, jumped in the error of a predictor
    # of that sound only as much as a weak trigger's, where past the last impact a strong
    # one's was asked: the search for them ended (19 of 23 timed). A weak jump now does
    # where the sound sets off the secondaries of an impact itself.
    pytest.param(20_517_477, 23, id="weak-last-impacts-20517001"),
    # An echo 51.3 ms after each impact, 0.37 as loud (a ring at 24 ms, a burst at 6.6 ms).
    # The first chain took the echoes of the first three impacts, each splitting the long
    # interval after its impact in two (ratios near 1 where the train's are 0.87), and
    # passed the bounce-train check; the search for the impacts the trend predicts then left
    # out two impacts and took a ring and a burst in their place (20 of 22 timed, 6 false
    # impacts). A member at a recurring delay after an earlier one, fainter than both
    # members around it, whose ratio is an outlier of the chain's trend and without which
    # the chain follows its trend better, is that member's echo or ring.
    pytest.param(20_519_152, 22, id="echoes-splitting-intervals-20519001"),
    # An echo 197 ms after each impact, 0.2 as loud: the echo of the impact at 0.346 s,
    # midway between those at 0.476 and 0.590 s, was taken, and later the burst of the
    # impact at 0.928 s (27 of 27 timed, 2 false impacts).
    pytest.param(20_519_215, 27, id="echo-splitting-an-interval-20519001"),
    # A ring 13 ms after each impact, 0.3 as loud (a burst at 5.2 ms, 1.26 as loud, an
    # echo at 153 ms): a ring in the chain at 1.528 s (25 of 30 timed, 4 false impacts).
    pytest.param(20_517_197, 30, id="ring-splitting-an-interval-20517001"),
]


# Trains that ended on one sound more than their bounces, past the last impact.
OVERRUN_TRAINS = [
    # A ring burst 7.9 ms after each impact, 1.14 as loud as it, and a train with no burst
    # (a ring at 12.6 ms, an echo at 95.5 ms): where the next bounce would come, the
    # decaying sound of the last impacts, their bursts and echoes swelled into an onset that
    # jumped in the predictor's error as much as a weak trigger's, and passed for one more
    # bounce. Its impulse is 0.07 of those of the impacts before it.
    pytest.param(20_518_485, 37, id="weak-swell-20518001"),
    pytest.param(20_518_511, 26, id="weak-swell-no-burst-20518001"),
    # An echo 170 / 106.5 ms after each impact, 0.4 / 0.46 as loud (no burst). Where the
    # next bounce would come, an echo of an impact 15 / 10 bounces earlier had begun 1 ms
    # before: the probe's window opened on its rise and found its swell, which passed for
    # one more bounce (no onset of its own rises out of the echo there).
    pytest.param(20_518_225, 36, id="echo-swell-20518001"),
    pytest.param(20_518_441, 26, id="echo-swell-2-20518001"),
]


def assert_timed_whole(folder, seed, impacts):
    score, onsets = detected_score(folder, seed)
    assert onsets.size == impacts
    assert score["found"] == onsets.size
    assert score["false"] == 0


@pytest.mark.parametrize("seed, impacts", WHOLE_TRAINS)
def test_every_impact_of_a_train_once_lost_or_refused_is_timed(tmp_path, seed, impacts):
    assert_timed_whole(tmp_path, seed, impacts)


@pytest.mark.parametrize("seed, impacts", OVERRUN_TRAINS)
def test_a_train_once_overrun_by_a_swell_ends_on_its_last_impact(tmp_path, seed, impacts):
    assert_timed_whole(tmp_path, seed, impacts)


def test_a_probe_asked_again_at_the_same_moment_reuses_its_stretch(tmp_path, monkeypatch):
    # The search past the last impact probes a moment again with a weaker threshold: the
    # stretch, its filtering and its predictor are kept from the first probe, and the table
    # is the same to the last bit as with each probe computed afresh.
    samples, _, _ = disturbed_train(20_517_477)
    path = write_audio(tmp_path / "train.wav", samples, RATE, subtype="FLOAT")
    computed = []
    prepare = chain._probed_stretch

    def counted(*args):
        computed.append(args[1])
        return prepare(*args)

    monkeypatch.setattr(chain, "_probed_stretch", counted)
    kept = detect_impacts(path)
    reused = len(computed)
    probe = audio._probe

    def afresh(stream, *args, **kwargs):
        stream.probe_memo = None
        return probe(stream, *args, **kwargs)

    monkeypatch.setattr(audio, "_probe", afresh)
    computed.clear()
    pd.testing.assert_frame_equal(detect_impacts(path), kept, check_exact=True)
    assert reused < len(computed)


def test_the_level_of_a_recurring_secondary_is_its_loudness_against_its_impact():
    # Impacts fading by 7 % per bounce, each with a ring 12 ms later at 0.35 of its loudness
    # and, on every other impact, a click at 0.9 of it 30 ms later.
    impacts = np.cumsum(0.2 * 0.9 ** np.arange(12))
    loudness = 0.5 * 0.93 ** np.arange(12)
    times = np.concatenate([impacts, impacts + 12e-3, impacts[::2] + 30e-3])
    amplitude = np.concatenate([loudness, 0.35 * loudness, 0.9 * loudness[::2]])
    order = np.argsort(times)
    chain = np.searchsorted(times[order], impacts)
    levels = _secondary_levels(times[order], amplitude[order], chain,
                               np.array([12e-3, 30e-3, 50e-3]))
    np.testing.assert_allclose(levels[:2], [0.35, 0.9])
    assert np.isnan(levels[2])  # no sound recurs at 50 ms


def test_an_impact_timed_at_a_ring_just_before_it_is_timed_again_on_its_own_onset():
    # Impacts shrinking by 0.9; the ring of impact 10 recurs at a delay that puts it 0.9 ms
    # before impact 12, whose onset was taken at the ring's start: on the trend (to well
    # within its tolerance), but not the impact's own onset.
    impacts, delay, timed, (coefficients, scatter) = timed_at_a_secondary(10, 0.9e-3)

    def probe(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
              impulse=False):
        # The file holds the impacts' onsets; past a ring's start only a later onset counts.
        later = impacts[impacts > (not_before if not_before is not None else -np.inf)]
        return onset_near(later, predicted, tolerance)

    added, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                                   np.array([delay]), probe, impacts[-1] + 1.0)
    assert sorted(retimed) == [12] and not added
    assert retimed[12][0] == impacts[12]

    # Where no onset of its own rises out of the ring (nor shows in the error of a predictor
    # of it), the impact stays as timed.
    def ring_only(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
                  impulse=False):
        return None if not_before is not None or predicted_sound else probe(predicted,
                                                                             tolerance)

    _, retimed = _fill_impacts(timed, np.ones(timed.size), coefficients, scatter,
                               np.array([delay]), ring_only, impacts[-1] + 1.0)
    assert not retimed


def impulse_probe(impulses, powers, weak):
    """A probe of the error of a predictor of the sound: at each of `impulses` (s) the error's
    power over its first 0.5 ms is `powers` (over the floor); it jumps as a weak trigger
    where that power is at least `weak`."""
    impulses, powers = np.asarray(impulses), np.asarray(powers)

    def probe(moment, tolerance, not_before=None, predicted_sound=False, expected=False,
              any_jump=False):
        assert predicted_sound
        near = np.flatnonzero(np.abs(impulses - moment) <= tolerance)
        if near.size == 0 or not (any_jump or powers[near[0]] >= weak):
            return None
        return impulses[near[0]], 1e-5, float(powers[near[0]]) if any_jump else 0.02, False
    return probe


def test_the_train_does_not_end_on_a_swell_of_the_beating_of_its_last_sounds():
    impacts = 1.0 + np.cumsum(0.02 * 0.93 ** np.arange(12))
    # Past the last bounce the modes of the decaying sound beat: a swell of power one flight
    # later, probed as an onset, which the predictor of that sound continues (an error near
    # its floor).
    swell = impacts[-1] + 0.9 * (impacts[-1] - impacts[-2])
    times = np.r_[impacts, swell]
    loud = impulse_probe(times, np.r_[np.full(impacts.size, 30.0), 2.0], weak=4.0)
    assert _drop_unexcited_end(times, loud) == impacts.size
    assert _drop_unexcited_end(impacts, loud) == impacts.size
    # In a faint train the impacts' impulses barely clear the floor; a last impact whose
    # impulse falls short of a weak trigger's jump is still one where it is at least a
    # quarter of those of the impacts before it (the last bounces, of one speed, sound alike).
    faint = impulse_probe(impacts, np.r_[np.full(impacts.size - 1, 10.0), 3.5], weak=4.0)
    assert _drop_unexcited_end(impacts, faint) == impacts.size
    # A swell there, far below them, goes.
    faint = impulse_probe(times, np.r_[np.full(impacts.size, 10.0), 1.5], weak=4.0)
    assert _drop_unexcited_end(times, faint) == impacts.size
    # So does one that jumps as much as a weak trigger's where the impacts before it are
    # loud, but whose impulse is under a tenth of theirs; at a fifth of theirs it stays.
    for share, kept in ((0.08, impacts.size), (0.2, times.size)):
        swelling = impulse_probe(times, np.r_[np.full(impacts.size, 60.0), 60.0 * share],
                                 weak=4.0)
        assert _drop_unexcited_end(times, swelling) == kept
    # Where the error cannot be probed (the end of the file), the last sound stays.
    untestable = impulse_probe(impacts, np.full(impacts.size, 30.0), weak=4.0)
    assert _drop_unexcited_end(times, untestable) == times.size
    # Only sounds found by probing the file are tested: the stream's transients rose over the
    # mean power before them.
    stream = np.zeros(times.size, dtype=bool)
    assert _drop_unexcited_end(times, loud, stream) == times.size
    assert _drop_unexcited_end(times, loud, ~stream) == impacts.size


def test_only_secondaries_the_impacts_before_set_off_are_asked_of_a_sound():
    # A burst 6 ms and a ring 18 ms after every impact; the ring, of low modes landing on the
    # sounds of the last bounces, does not stand out after any of them.
    impacts = 1.0 + np.cumsum(0.008 * 0.93 ** np.arange(8))
    delays, levels = np.array([6e-3, 18e-3]), np.array([1.0, 0.3])
    only_bursts = np.sort(impacts + delays[0])

    def probe(moment, tolerance, not_before=None, predicted_sound=False, expected=False,
              impulse=False):
        return onset_near(only_bursts, moment, tolerance)

    last, end = impacts[-1], impacts[-1] + 1.0
    before = [(moment, 1.0) for moment in impacts[-3:-1]]
    assert not _sets_off_secondaries(probe, last, 1.0, delays, levels, end)
    assert _sets_off_secondaries(probe, last, 1.0, delays, levels, end, before)
    # A secondary the impacts before do set off is still asked of it.
    with_rings = np.sort(np.r_[only_bursts, impacts[:-1] + delays[1]])

    def probe_rings(moment, tolerance, not_before=None, predicted_sound=False,
                    expected=False, impulse=False):
        return onset_near(with_rings, moment, tolerance)

    assert not _sets_off_secondaries(probe_rings, last, 1.0, delays, levels, end, before)


def test_a_probed_last_bounce_at_a_burst_delay_is_asked_only_for_secondaries_seen_before_it():
    # The last bounce, not timed by the stream, comes one burst delay after the impact before
    # it. Every impact sets off its burst; the ring 20 ms later stands out after none of them.
    intervals = 0.1 * 0.85 ** np.arange(18)
    impacts = np.cumsum(intervals)
    burst = 0.1 * 0.85**18
    last = impacts[-1] + burst
    sounds = np.sort(np.r_[impacts, last, impacts + burst, last + burst])
    coefficients, scatter = _robust_trend(impacts)

    def probe(predicted, tolerance, not_before=None, predicted_sound=False, expected=False,
              impulse=False):
        return onset_near(sounds, predicted, tolerance)

    added, _ = _fill_impacts(impacts, np.ones(impacts.size), coefficients, scatter,
                             np.array([burst, 0.02]), probe, last + 1.0, np.array([1.0, 0.3]))
    assert [row[0] for row in added] == [last]



def test_a_chain_of_every_other_bounce_gets_the_bounces_it_stepped_over():
    # Bounces shrinking by 0.9, fading by 2 % per bounce: a chain of the even ones is a
    # train of ratio 0.81 whose fit would give the square of the restitution.
    bounces = np.cumsum(0.2 * 0.9 ** np.arange(24))
    loudness = 0.5 * 0.98 ** np.arange(24)
    # Each with a ring 20 ms later (0.3 as loud) and a burst 7 ms later (as loud), which
    # sits midway in the intervals of 12-16 ms.
    times = np.concatenate([bounces, bounces + 20e-3, bounces + 7e-3])
    amplitude = np.concatenate([loudness, 0.3 * loudness, loudness])
    order = np.argsort(times)
    times, amplitude = times[order], amplitude[order]
    index = np.flatnonzero(order < bounces.size)  # the bounces among the transients
    even = index[::2]
    filled = _every_bounce(times, amplitude, even)
    # Only bounces are added, and most of those stepped over (one whose delay after a member
    # happens to recur may be left for the later search for predicted impacts).
    assert np.isin(filled, index).all()
    assert filled.size - even.size >= 0.8 * (even.size - 1)
    # The chain of every bounce stays as it is: the bursts midway in its last intervals come
    # at a delay that recurs after every member.
    np.testing.assert_array_equal(_every_bounce(times, amplitude, index), index)
    # A chain of every other bounce over four intervals only is kept: bursts and echoes
    # can sit midway in a few successive intervals.
    np.testing.assert_array_equal(_every_bounce(times, amplitude, even[:5]), even[:5])


def test_a_chain_of_every_other_bounce_missing_one_stepped_over_bounce_gets_the_others():
    # Bounces shrinking by 0.9: the chain of the even ones, and among the transients the odd
    # ones except those of `gone` (set aside with an echo landing on them).
    bounces = np.cumsum(0.2 * 0.9 ** np.arange(24))
    even = np.arange(0, 24, 2)
    for gone, filled_in in [([7, 17], True), ([5, 11, 17], False)]:
        present = np.setdiff1d(np.arange(24), gone)
        times, amplitude = bounces[present], np.full(present.size, 0.3)
        chain = np.searchsorted(times, bounces[even])
        found = _every_bounce(times, amplitude, chain)
        if filled_in:  # five of six successive intervals hold their bounce (no five in a row)
            np.testing.assert_array_equal(times[found], bounces[present[present <= even[-1]]])
        else:  # two of any six intervals are empty: no sign of a halved train
            np.testing.assert_array_equal(found, chain)


@pytest.mark.parametrize("seed", [20461163, 20461221])
def test_a_train_is_not_timed_on_every_other_bounce(tmp_path, seed):
    # Trains of a fresh block (seeds 20461163 and 20461221, bursts about as loud as their
    # impacts 7-8 ms after them) where the first chain took an echo and then bursts for
    # impacts, and the chain chosen without their delays took every other bounce from the
    # first on: 15 and 17 impacts lost, a train that passes every check of its intervals.
    score, onsets = detected_score(tmp_path, seed)
    assert score["found"] >= onsets.size - 1
    assert score["false"] <= 1


@pytest.mark.parametrize("seed", range(4))
def test_the_trend_of_the_last_impacts_is_not_bent_by_onsets_timed_off(seed):
    # A train shrinking by 0.9 whose last impacts are timed 0.4 ms early or late, one in
    # three (on a ring's burst before them, or late on their rise): each moves the ratio
    # between its intervals by about 2δ/T and the two around it by δ/T the other way. Left
    # out alone, the first bent the trend at the train's end by 2-10 % (0.81-0.99 where the
    # predictions of the last impacts are made).
    impacts = np.concatenate([[0.0], np.cumsum(0.2 * 0.9 ** np.arange(40))])
    timed = impacts.copy()
    off = np.arange(impacts.size - 14, impacts.size, 3)
    timed[off] += 0.4e-3 * np.random.default_rng(20481000 + seed).choice([-1.0, 1.0], off.size)
    coefficients, _ = _robust_trend(timed, timed_off=True)
    near_end = np.log(np.diff(impacts)[-4:])
    np.testing.assert_allclose(np.exp(np.polyval(coefficients, near_end)), 0.9, atol=0.025)


def test_a_choice_that_set_impacts_aside_with_the_secondaries_is_not_taken(tmp_path):
    # A development train (found while measuring seeds 20507001-20507200): its echo at 23.9
    # ms matches sums of the train's intervals, a ring burst 7.8 ms after each impact is as
    # loud as it. The first chain took echoes and failed the bounce-train check; the choice
    # without the transients at the secondaries' delays passed with its first 5 impacts
    # only (4 of 21 timed), having set aside the others with the echoes. Every impact is
    # timed once the chain without the train's echoes, which passes with more, is taken.
    score, onsets = detected_score(tmp_path, 20_507_143)
    assert onsets.size == 21
    assert score["found"] == onsets.size
    assert score["false"] == 0



def test_an_impact_just_into_a_burst_is_searched_for_past_the_bursts_start(tmp_path):
    # A development train at 22.05 kHz (found while measuring seeds 20509001-20509200): a
    # ring burst 7.9 ms after each impact, 1.08 times as loud. Impacts 41 and 42 start 0.78
    # and 0.28 ms into the burst of the one before; the search of the predictor's error
    # from 0.3 ms past the burst's start had its onset picked on that start (the picker
    # looks back 0.36 ms before its window) and found nothing, and both were missed. The
    # error is now searched once more from 0.6 ms past the start.
    score, onsets = detected_score(tmp_path, 20_509_062)
    assert onsets.size == 48
    assert score["found"] == onsets.size
    assert score["false"] == 0


def test_an_impact_timed_late_on_a_ring_it_starts_on_is_timed_on_its_impulse(tmp_path):
    # A development train at 22.05 kHz (found while measuring seeds 20507001-20507200): a
    # ring 17.7 ms after each impact, 0.39 as loud, and a ring burst 7.9 ms after it, 1.34
    # times as loud. Two of the last impacts start less than 2 ms after a ring or burst of an
    # earlier impact began; their onsets were fitted more than 1 ms late, on the trend but
    # past its time, and two false impacts followed. Their impulses in the error of a
    # predictor of that sound, closer to the trend's time, time them now.
    score, onsets = detected_score(tmp_path, 20_507_078)
    assert onsets.size == 42
    assert score["found"] >= onsets.size - 1
    assert score["false"] == 0

@pytest.mark.parametrize("seed, count", [
    # Seeds 20507001-20507200: a ring burst 7.1 ms after each impact, 0.7 as loud. Between the
    # last impacts the chain took, impacts probed where the trend put them were found early,
    # on a swell of the burst of the impact before; the predictions drifted, 3 impacts were
    # missed and 4 sounds taken instead. The impact's own onset rising out of the burst is
    # taken instead.
    (20_507_104, 71),
    # Seeds 20509001-20509200: a ring burst 7.5 ms after each impact, 0.7 as loud. The last 4
    # impacts start within 1.2 ms of the burst of the one before; their onsets were found on
    # the swell of a burst, and an onset of their own rising out of it was that same swell.
    # In the error of a predictor of the burst each is an impulse, which in its first samples
    # jumps as much as a weak trigger's (the ball bounced there): 4 impacts missed before.
    (20_509_127, 48),
])
def test_a_probed_onset_on_the_swell_of_a_burst_gives_way_to_the_impacts_own(tmp_path, seed,
                                                                              count):
    # Development trains at 48 kHz, found while measuring the blocks named.
    samples, onsets, _ = disturbed_train(seed, rate=48_000)
    path = write_audio(tmp_path / "train.wav", samples, 48_000, subtype="FLOAT")
    table = detect_impacts(path)
    score = score_train(onsets, table["time"].to_numpy(), table["time_uncertainty"].to_numpy(),
                        MATCH)
    assert onsets.size == count
    assert score["found"] == onsets.size
    assert score["false"] == 0


def test_an_impulse_louder_than_the_faint_ring_it_falls_on_is_an_impact(tmp_path):
    # A development train at 22.05 kHz (found while measuring seeds 20511001-20511300): a ring
    # 29 ms after each impact, 0.3 as loud, and a burst 7.2 ms after it, 1.07 as loud. Past the
    # chain's last impact, the first impact probed for starts 1.9 ms into the burst of the one
    # before and shows only in the error of a predictor of it; its impulse there lies 0.2 ms
    # off the faint ring of an impact 29 ms earlier, and was taken for that ring's start. The
    # impact was looked for past it, a swell 0.7 ms later was taken instead, and the
    # predictions drifted off the train: its last 8 impacts were missed. An impulse more than
    # twice as loud as that ring usually is, is no ring.
    samples, onsets, _ = disturbed_train(20_511_045)
    path = write_audio(tmp_path / "train.wav", samples, RATE, subtype="FLOAT")
    table = detect_impacts(path)
    times = table["time"].to_numpy()
    score = score_train(onsets, times, table["time_uncertainty"].to_numpy(), MATCH)
    assert onsets.size == 64
    assert np.abs(times - onsets[-8]).min() < MATCH  # the impact on the ring's delay
    assert score["found"] >= onsets.size - 1  # was 56
    assert score["false"] == 0
