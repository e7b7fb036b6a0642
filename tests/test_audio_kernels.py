"""The compiled loops of the audio impact detector against their numpy reference.

dashpot.ingest.audio_kernels runs the high-pass, the power envelope and its trigger, the AIC
onset picker and the chain's dynamic programme compiled; the numpy forms in
dashpot.ingest.envelope and dashpot.ingest.chain stay as the reference (envelope.COMPILED =
False runs them). The kernels do the same operations in the same order and take their
logarithms from numpy, so the two must agree to the last bit (the onset fit's regression, whose
reference calls LAPACK, to about 1e-9 sample): each kernel against its
reference (and the high-pass against scipy.signal.sosfilt itself) on random input, and the
whole detector on synthetic recordings with the disturbances of real ones (seeds 20261125 + k,
not tuned) and on the real recordings where ../shared/data is present.
"""

from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from scipy import signal

import dashpot
from dashpot.errors import InputError
from dashpot.ingest import audio
from dashpot.ingest import chain as chaining
from dashpot.ingest import envelope
from dashpot.ingest.audio import detect_impacts
from dashpot.synth.audio import impact_sound, write_audio

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
REAL = {"pingpong": DATA / "pingpong-erickson" / "pingpong.wav",
        "bouncy": DATA / "bouncy-ball-pfe" / "drop_0.9m.wav"}
SEED = 20261125


def _kernels():
    from dashpot.ingest import audio_kernels

    return audio_kernels


# ------------------------------------------------------------------------------ each kernel


@pytest.mark.parametrize(("order", "channels"), [(2, 1), (4, 3)])
def test_highpass_is_scipy_sosfilt_to_the_last_bit(order, channels):
    rng = np.random.default_rng(SEED)
    block = rng.normal(scale=0.1, size=(5000, channels)) + 0.3
    sos = signal.butter(order, 150.0, "highpass", fs=44100, output="sos")
    zi = rng.normal(size=(sos.shape[0], 2, channels))
    expected, expected_state = signal.sosfilt(sos, block, axis=0, zi=zi)
    filtered, state = _kernels().highpass(sos, block, zi)
    np.testing.assert_array_equal(filtered, expected)
    np.testing.assert_array_equal(state, expected_state)
    # The same memory layout: the noise estimate's einsum sums over it in layout order.
    assert filtered.strides == expected.strides


def _bursty(rng, frames, channels):
    """Noise with transients of random loudness and digitally silent stretches."""
    samples = rng.normal(scale=1e-3, size=(frames, channels))
    for start in rng.integers(100, frames - 400, size=40):
        length = int(rng.integers(20, 300))
        samples[start:start + length] *= rng.uniform(2.0, 300.0)
    samples[frames // 3:frames // 3 + 500] = 0.0
    return samples


def test_envelope_and_trigger_equal_the_reference():
    rng = np.random.default_rng(SEED + 1)
    filtered = np.asfortranarray(_bursty(rng, 20000, 2))
    settings = envelope._Settings.make(48000, 12.0, 9.0)
    rho, weights = np.array([0.3, 0.05]), 1.0 / (2 * np.array([1e-3, 2e-3]) ** 2)
    lo, hi = settings.history, filtered.shape[0] - settings.lookahead + 1
    weak = settings.min_jump / envelope._WEAK_JUMP_FACTOR / settings.background
    power, sta, triggers, jump = envelope._envelope_triggers(filtered, rho, weights, settings,
                                                             lo, hi, weak)
    found, found_triggers, found_jump = _kernels().envelope_triggers(
        filtered, rho, weights, settings.sta, settings.background, lo, hi, settings.min_power,
        weak)
    assert triggers.size > 10  # the test has triggers to compare
    np.testing.assert_array_equal(found_triggers, triggers)
    np.testing.assert_array_equal(found_jump, jump)
    # The power and STA formed from the running sum's checkpoints, everywhere.
    every = np.arange(filtered.shape[0])
    np.testing.assert_array_equal(found.sta_at(every), sta)
    np.testing.assert_array_equal(found.power_rows(np.array([0, 777]), 19000),
                                  np.stack([power[:19000], power[777:19777]]))


def test_onset_picks_equal_the_reference(monkeypatch):
    rng = np.random.default_rng(SEED + 2)
    rows, length = 300, 168
    power = rng.exponential(size=(rows, length))
    # A rise at a random split, sometimes a faint sound before it, some silent rows.
    rise = rng.integers(10, length - 10, size=rows)
    before = rng.integers(0, length, size=rows)
    columns = np.arange(length)
    power *= np.where(columns >= rise[:, None], rng.uniform(1, 1000, size=(rows, 1)), 1.0)
    power *= np.where(columns >= before[:, None], rng.uniform(1, 5, size=(rows, 1)), 1.0)
    power[:10, :40] = 0.0
    power[10:20] = 1.0  # constant rows: every split ties, the first one must win
    first = rng.integers(0, length - 2 * envelope._AIC_MARGIN - 24, size=rows)
    monkeypatch.setattr(envelope, "COMPILED", False)
    expected = envelope._onset_picks(power, first, 24, 24)
    monkeypatch.setattr(envelope, "COMPILED", True)
    found = envelope._onset_picks(power, first, 24, 24)
    assert np.unique(expected).size > 20
    np.testing.assert_array_equal(found, expected)


def _chain_inputs(rng, trend, ties=False):
    """Inputs of the chain's loop as chain._best_chain forms them, for a train with clutter
    (or, with `ties`, with clicks on a grid of equal weights, where steps tie exactly)."""
    sequence = dashpot.bounce_sequence("hybrid", beta=80.0, omega0=3000.0, g=9.81, v0=1.5,
                                       n_max=40)
    if ties:
        times = np.sort(np.concatenate([sequence.impact_times, np.arange(1.0, 60.0) / 8]))
        weights = np.ones(times.size)
    else:
        times = np.sort(np.concatenate([sequence.impact_times,
                                        rng.uniform(0, sequence.impact_times[-1], size=60)]))
        weights = rng.uniform(0.1, 3.0, size=times.size)
    n = times.size
    gaps = times[None, :] - times[:, None]
    upper = gaps > 0
    log_gap = np.log(np.where(upper, gaps, 1.0))
    jitter = 2 * chaining._ONSET_JITTER**2 / np.where(upper, gaps, 1.0) ** 2
    score = np.where(upper, weights[:, None] + weights[None, :], -np.inf)
    pointer = np.full((n, n), -1, dtype=np.int64)
    centre_t = spread_t = None
    if trend:
        coefficients, scatter = chaining._trend(sequence.impact_times)
        centre_t = (log_gap + np.polyval(coefficients, log_gap)).T.copy()
        spread_t = (scatter**2 + jitter).T.copy()
    last = np.searchsorted(times, times[1:-1] + chaining._RATIO_BOUNDS[1]
                           * (times[1:-1] - times[0]), side="right")
    return times, weights, (log_gap, jitter, weights, last, score, pointer, centre_t, spread_t)


@pytest.mark.parametrize("trend", [False, True])
@pytest.mark.parametrize(("budget", "ties"), [(1 << 20, False), (64, False), (1 << 20, True)])
def test_chain_scores_equal_the_reference(trend, budget, ties):
    # budget: the costs prepared in one batch, or in many.
    times, weights, inputs = _chain_inputs(np.random.default_rng(SEED + 3), trend, ties)
    log_gap, jitter, weights, last, score, pointer, centre_t, spread_t = inputs
    expected_score, expected_pointer = score.copy(), pointer.copy()
    chaining._relax_states(log_gap, jitter, weights, last, expected_score, expected_pointer,
                           centre_t, spread_t)
    log_lo, log_hi = np.log(chaining._RATIO_BOUNDS)
    _kernels().chain_scores(log_gap, jitter, weights, last, score, pointer, centre_t, spread_t,
                            log_lo=float(log_lo), log_hi=float(log_hi),
                            log_growth=float(np.log1p(chaining._GROWTH_ALLOWANCE)),
                            budget=budget)
    assert np.isfinite(expected_score).sum() > times.size  # chains longer than pairs exist
    np.testing.assert_array_equal(score, expected_score)
    np.testing.assert_array_equal(pointer, expected_pointer)


# ----------------------------------------------------------------------- the whole detector


def _detect(path, compiled, monkeypatch, block_seconds=30.0):
    """Impact table (or the one-line error) of one detector path, the file analysed in blocks
    of `block_seconds` (s)."""
    monkeypatch.setattr(envelope, "COMPILED", compiled)
    monkeypatch.setattr(audio, "_BLOCK_SECONDS", block_seconds)
    try:
        return detect_impacts(path)
    except InputError as error:
        return str(error)


def _assert_same_impacts(path, monkeypatch, block_seconds=30.0):
    reference = _detect(path, False, monkeypatch, block_seconds)
    compiled = _detect(path, True, monkeypatch, block_seconds)
    if isinstance(reference, str):
        assert compiled == reference
        return 0
    assert len(compiled) == len(reference)
    np.testing.assert_array_equal(compiled["amplitude"].to_numpy(),
                                  reference["amplitude"].to_numpy())
    # The onset fit's regression is the one kernel that does not reproduce its reference to
    # the last bit (see dashpot.ingest.audio_kernels): times agree to far below a sample.
    for column in ("time", "time_uncertainty"):
        np.testing.assert_allclose(compiled[column].to_numpy(), reference[column].to_numpy(),
                                   rtol=0, atol=1e-12, err_msg=column)
    assert compiled.attrs["notes"] == reference.attrs["notes"]
    return len(reference)


def _disturbed(seed, rate):
    """Samples of a train with the disturbances of tests/test_audio_disturbances.py (apex
    clicks, a rest tail, a ring, an echo at 5-200 ms, in half the trains ring bursts)."""
    from test_audio_disturbances import disturbed_train

    return disturbed_train(seed, rate)[0]


@pytest.mark.parametrize(("k", "rate", "channels", "block_seconds", "extra"), [
    (0, 22050, 1, 30.0, {}),
    (1, 48000, 2, 30.0, {}),
    (2, 44100, 2, 0.6, {}),  # many blocks: the carried samples and the later noise estimates
    (3, 44100, 1, 30.0, {"noise_color": "pink", "dc_offset": 0.05, "clip_level": 0.3}),
])
def test_compiled_detector_gives_the_reference_impacts(tmp_path, monkeypatch, k, rate, channels,
                                                       block_seconds, extra):
    seed = SEED + k
    if extra:
        rng = np.random.default_rng(seed)
        sequence = dashpot.bounce_sequence("hybrid", beta=rng.uniform(40, 150),
                                           omega0=rng.uniform(2000, 4000), g=9.81,
                                           v0=rng.uniform(1.0, 2.0), n_max=400)
        samples, _ = impact_sound(sequence.impact_times[:40], sequence.impact_speeds[:40],
                                  sample_rate=rate, seed=seed, snr_db=50.0, echo_delay=0.09,
                                  echo_level=0.4, **extra)
    else:
        samples = _disturbed(seed, rate)
    path = write_audio(tmp_path / f"train{k}.wav", samples, rate, channels=channels,
                       subtype="FLOAT")
    assert sf.info(str(path)).channels == channels
    impacts = _assert_same_impacts(path, monkeypatch, block_seconds)
    assert impacts >= 10  # a real comparison, not two identical refusals


@pytest.mark.parametrize("compiled", [True, False])
def test_a_16_bit_file_gives_what_its_samples_as_floats_give(tmp_path, monkeypatch, compiled):
    # 16-bit samples are kept as int16 and scaled by 2^-15 inside the loops; a float file
    # holding the same values (libsndfile's scaling of int16, exact) must give the same table,
    # through many blocks (the carried samples) and with a DC offset (its note).
    samples = _disturbed(SEED + 7, 22050)[:, None] * np.array([1.0, 0.6]) + 0.01
    quantized = np.round(np.clip(samples, -1.0, 1.0 - 2.0**-15) * 2**15).astype(np.int16)
    sixteen = tmp_path / "train16.wav"
    sf.write(str(sixteen), quantized, 22050, subtype="PCM_16")
    floats = tmp_path / "train_float.wav"
    sf.write(str(floats), quantized / 2.0**15, 22050, subtype="FLOAT")
    assert sf.info(str(sixteen)).subtype == "PCM_16"
    tables = [_detect(path, compiled, monkeypatch, 0.7)
              for path in (sixteen, floats)]
    assert not isinstance(tables[0], str) and len(tables[0]) >= 10
    for column in ("time", "time_uncertainty", "amplitude"):
        np.testing.assert_array_equal(tables[0][column].to_numpy(),
                                      tables[1][column].to_numpy(), err_msg=column)
    assert tables[0].attrs["notes"] == tables[1].attrs["notes"]
    assert any("DC offset" in note for note in tables[0].attrs["notes"])


@pytest.mark.parametrize("name", sorted(REAL))
def test_compiled_detector_gives_the_reference_impacts_on_real_sound(monkeypatch, name):
    path = REAL[name]
    if not path.exists():
        pytest.skip(f"{path} not found: the real recordings (../shared/data) are not available")
    assert _assert_same_impacts(path, monkeypatch) >= 30


def test_batched_polish_equals_member_by_member(monkeypatch):
    # Chains through a train with clutter within the 3 ms search of its members, so that
    # members are replaced and the members after them costed again.
    rng = np.random.default_rng(SEED + 4)
    sequence = dashpot.bounce_sequence("hybrid", beta=80.0, omega0=3000.0, g=9.81, v0=1.5,
                                       n_max=40)
    trend = chaining._trend(sequence.impact_times)
    replaced = 0
    for _ in range(50):
        times = np.sort(np.concatenate([
            sequence.impact_times,
            rng.choice(sequence.impact_times, size=30) + rng.uniform(-3e-3, 3e-3, size=30)]))
        chain = np.sort(rng.choice(times.size, size=int(rng.integers(3, 40)), replace=False))
        monkeypatch.setattr(envelope, "COMPILED", False)
        expected = chaining._polish_chain(times, chain, trend)
        monkeypatch.setattr(envelope, "COMPILED", True)
        np.testing.assert_array_equal(chaining._polish_chain(times, chain, trend), expected)
        replaced += int((expected != chain).sum())
    assert replaced > 50  # the polish did replace members


def test_onset_fit_compiled_equals_its_reference(monkeypatch):
    # Transients of random frequency, decay, phase and SNR (10-70 dB) starting anywhere within
    # a sample of the rough onset, in white or coloured noise: the compiled regression gives
    # the onsets and 1σ of the numpy one (LAPACK's Cholesky) to far below a sample.
    from dashpot.ingest.onset import _onset_posterior

    rng = np.random.default_rng(SEED + 5)
    rate, n_pre, width = 44100, 48, 96
    windows = np.empty((150, width))
    for row in windows:
        start = n_pre + rng.uniform(-1.0, 1.0)
        t = np.arange(width) - start
        tone = np.where(t > 0, np.sin(rng.uniform(0.2, 1.5) * t + rng.uniform(0, 2 * np.pi))
                        * np.exp(-t / rng.uniform(5, 60)), 0.0)
        noise = signal.lfilter([1.0], [1.0, -rng.uniform(0.0, 0.9)], rng.standard_normal(width))
        row[:] = tone / 10 ** (rng.uniform(10, 70) / 20) * 3 + noise * 1e-3 + rng.uniform(-1, 1)
    monkeypatch.setattr(envelope, "COMPILED", False)
    onset, sigma, snr = _onset_posterior(windows, n_pre, rate)
    monkeypatch.setattr(envelope, "COMPILED", True)
    compiled = _onset_posterior(windows, n_pre, rate)
    np.testing.assert_allclose(compiled[0], onset, rtol=0, atol=1e-7)
    np.testing.assert_allclose(compiled[1], sigma, rtol=0, atol=1e-7)
    np.testing.assert_array_equal(compiled[2], snr)
    assert np.ptp(onset) > 1.0  # onsets spread over the grid, not one case


def test_window_maxima_and_distinct_counts_equal_their_numpy_forms():
    rng = np.random.default_rng(SEED + 5)
    values = rng.exponential(size=400)
    first = np.minimum(np.arange(400), rng.integers(0, 400, size=400))
    np.testing.assert_array_equal(
        _kernels().window_maxima(values, first),
        [values[a:i].max(initial=0.0) for i, a in enumerate(first)])
    labels = rng.integers(0, 30, size=400)
    stops = np.maximum(np.arange(400), np.minimum(400, np.arange(400) + rng.integers(0, 40, 400)))
    np.testing.assert_array_equal(_kernels().distinct_counts(labels, stops),
                                  [np.unique(labels[i:j]).size for i, j in enumerate(stops)])
