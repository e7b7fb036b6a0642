"""Out-of-sample check of the noise-model fit (:mod:`dashpot.fit.prediction`): fitted on the
first two thirds of a train, the 95 % prediction band holds the last third's intervals."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dashpot.fit import prepare_data
from dashpot.fit.prediction import prediction_band
from dashpot.likelihood import TrainModel
from dashpot.physics.flight import drag_flight, gravity_flight
from dashpot.physics.laws import LAWS
from dashpot.scene import Known, Scene, load_scene

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"
G = 9.80665  # the default scene's g
TRAINS, IMPACTS = 40, 45


def simulated_trains(seed, trains=TRAINS):
    """Trains of the noise model: constant ε = 0.95, σ_ε = 0.3 %, σ_t = 20 µs (no detector σ)."""
    model = TrainModel(LAWS["constant"].bind(np.full(trains, 0.95)),
                       lambda v: gravity_flight(v, G))
    drawn = model.simulate(IMPACTS, np.random.default_rng(seed), start_time=0.3,
                           start_speed=2.0, process_sigma=0.003, jitter=20e-6)
    return [prepare_data(pd.DataFrame({"time": times}), Scene()) for times in drawn.times]


def test_band_covers_its_level_on_trains_of_the_model():
    """Pooled over trains, 95 % of the held-out intervals are inside the band. The intervals of
    one train are correlated (the speed walks), so the tolerance is that of one interval per
    train, binomial over the trains: the pooled fraction varies less than that."""
    checks = [prediction_band(data, "constant", draws=2000, seed=row)
              for row, data in enumerate(simulated_trains(seed=58113))]
    assert all(c.fitted_impacts == 30 and c.observed.size == 15 for c in checks)
    coverage = np.mean(np.concatenate([c.inside for c in checks]))
    tolerance = 3.0 * math.sqrt(0.95 * 0.05 / len(checks))
    assert coverage >= 0.95 - tolerance, coverage
    # The band is a band: ordered, and the median inside it.
    assert all(np.all((c.lower < c.median) & (c.median < c.upper)) for c in checks)


def test_half_band_holds_half_the_intervals_on_trains_of_the_model():
    """Two-sided: the central 50 % band is not wider than the spread of the model's own
    continuations (drawing the noise parameters must not inflate it). Tolerance as above, one
    interval per train."""
    checks = [prediction_band(data, "constant", level=0.5, draws=2000, seed=row)
              for row, data in enumerate(simulated_trains(seed=20261130))]
    coverage = np.mean(np.concatenate([c.inside for c in checks]))
    assert abs(coverage - 0.5) <= 3.0 * math.sqrt(0.25 / len(checks)), coverage


def test_band_with_a_fitted_drag_covers_drag_trains():
    """The `effects` path: trains flown with quadratic drag (k_d = 0.15 1/m, a light ball),
    fitted as constant+drag (k_d free) and continued with the fitted and drawn k_d: 95 % of
    the held-out intervals inside the 95 % band and half inside the 50 % band (tolerances as
    above; measured 0.924 and 0.464 on these trains)."""
    k_d, trains = 0.15, 30
    model = TrainModel(LAWS["constant"].bind(np.full(trains, 0.95)),
                       lambda v: drag_flight(v, G, k_d))
    drawn = model.simulate(IMPACTS, np.random.default_rng(20261125 + 7), start_time=0.3,
                           start_speed=3.0, process_sigma=0.003, jitter=20e-6)
    data = [prepare_data(pd.DataFrame({"time": times}), Scene()) for times in drawn.times]
    for level in (0.95, 0.5):  # and the central half: the band is not inflated either
        checks = [prediction_band(train, "constant", draws=2000, seed=row, level=level,
                                  effects=("drag",)) for row, train in enumerate(data)]
        assert all("k_d" in c.fit.estimates for c in checks)
        coverage = np.mean(np.concatenate([c.inside for c in checks]))
        spread = 3.0 * math.sqrt(level * (1.0 - level) / trains)
        assert coverage >= level - spread, (level, coverage)
        assert level > 0.9 or coverage <= level + spread, (level, coverage)


def test_band_excludes_a_train_that_changed_its_law():
    """A train whose restitution drops after the fitted part leaves the band: the check can
    fail."""
    model = TrainModel(LAWS["constant"].bind(0.95), lambda v: gravity_flight(v, G))
    head = model.simulate(31, np.random.default_rng(90210), start_time=0.3, start_speed=2.0,
                          process_sigma=0.003, jitter=20e-6)
    lower = TrainModel(LAWS["constant"].bind(0.90), lambda v: gravity_flight(v, G))
    tail = lower.simulate(15, np.random.default_rng(4471), start_time=head.true_times[-1],
                          start_speed=head.impact_speeds[-1], process_sigma=0.003,
                          jitter=20e-6)
    times = np.concatenate([head.times[:30], head.times[30:], tail.times[1:]])
    check = prediction_band(prepare_data(pd.DataFrame({"time": times}), Scene()), "constant",
                            draws=2000)
    assert check.coverage < 0.5


def test_too_short_a_train_is_refused():
    data = simulated_trains(seed=311, trains=1)[0]
    short = dataclasses.replace(data, times=data.times[:4], sigma=data.sigma[:4],
                                index=data.index[:4], impact_speed=data.impact_speed[:4],
                                rebound_speed=data.rebound_speed[:4],
                                speed_sigma=data.speed_sigma[:4])
    with pytest.raises(ValueError, match="fewer than 2 held-out intervals"):
        prediction_band(short, "constant")


def test_no_continuation_reaching_the_end_is_refused(monkeypatch):
    """A law whose every simulated continuation breaks down gives no band: a clear error, not
    an IndexError from an empty quantile."""
    data = simulated_trains(seed=20261131, trains=1)[0]
    simulate = TrainModel.simulate

    def broken(self, *args, **kwargs):
        result = simulate(self, *args, **kwargs)
        return dataclasses.replace(result, times=np.full_like(result.times, np.nan))

    monkeypatch.setattr(TrainModel, "simulate", broken)
    with pytest.raises(ValueError, match="none of the 200 continuations"):
        prediction_band(data, "constant", draws=200)


def recording_check(name, recording, law, **drag):
    path = DATA / name / recording
    if not path.is_file():
        pytest.skip(f"real recording absent: {path}")
    from dashpot.analysis import scene_impacts

    scene = load_scene(REPO / "data" / name / "scene.yaml")
    scene = dataclasses.replace(scene, **drag)
    return prediction_band(prepare_data(scene_impacts(path, scene), scene), law, scene)


@pytest.mark.xfail(strict=True, reason=(
    "measured: 14 of 18 (0.78) of the last third's intervals inside the constant law's band; "
    "the four outside (18.77, 16.73, 15.83 and 12.43 ms, after impacts 42, 44, 45 and 50) are "
    "all above it, the last bounces coming later than a constant ε predicts (14 of 17 before "
    "impact 51, past the author's picks, was timed 1.2 ms later on a sound of its own after "
    "an echo and one more impact found after it: the 12.43 ms interval). Held 16 of 17 while "
    "impacts 29 and 32 of the first two thirds were timed 0.5-0.6 ms early (their onsets now "
    "at the rise's edge, issue 14): the timing jitter σ_j those two errors made the fit find "
    "(137 µs) widened the band; with them timed right σ_j is 0 (±30 µs). Fitted on the same "
    "first two "
    "thirds, the linear law holds 16 of 18, the power law 18 of 18, the quadratic 15 of 18; "
    "the noise selection on the whole train still keeps the constant law (ΔBIC of the speed "
    "term -2.0)"))
def test_pingpong_recording_predicts_its_last_third():
    """Constant ε with the drag of a 2.7 g, 40 mm ball (Cd 0.45): ≥ 90 % of the last third's
    intervals inside the 95 % band (the issue's target)."""
    check = recording_check("pingpong-erickson", "pingpong.wav", "constant",
                            diameter=Known(0.040), drag_coefficient=Known(0.45))
    assert check.observed.size >= 15
    assert check.coverage >= 0.90, check.coverage


@pytest.mark.parametrize(("law", "effects"), [("constant", ("drag",)), ("quadratic", ())])
def test_bouncy_ball_recording_predicts_its_last_third(law, effects):
    """The fit the noise selection selects there, constant+drag (a free drag constant: the
    ball's mass and diameter are not known), and the quadratic speed law, whose speed term the
    selection also requires over the constant: ≥ 90 % of the last third's intervals inside
    the 95 % band (the issue's target). σ_ε is known to 13 % from the fitted part: with σ_ε
    held at its fit the quadratic law held 15 of 17 (two intervals 2.1 and 2.4σ above the
    median, all 17 above it)."""
    path = DATA / "bouncy-ball-pfe" / "drop_0.9m.wav"
    if not path.is_file():
        pytest.skip(f"real recording absent: {path}")
    from dashpot.analysis import scene_impacts

    scene = load_scene(REPO / "data" / "bouncy-ball-pfe" / "scene.yaml")
    check = prediction_band(prepare_data(scene_impacts(path, scene), scene), law, scene,
                            effects=effects)
    assert check.observed.size >= 15
    assert check.coverage >= 0.90, check.coverage
