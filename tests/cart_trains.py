"""Cart runs with rolling friction as a motion sensor measures them (shared test helper)."""

from __future__ import annotations

import pandas as pd

from dashpot.likelihood import TrainModel
from dashpot.physics.flight import track_flight
from dashpot.physics.laws import LAWS


def measured_cart_run(rng, *, eps, g_eff, friction, bounces, speed, scatter, timing,
                      speed_sigma):
    """Impact table of one cart train drawn by the noise model's simulator: constant
    restitution `eps` with bounce-to-bounce scatter `scatter`, flights up the incline at
    g_eff + f and down at g_eff − f (m/s²), `bounces` impacts from `speed` (m/s), times
    with jitter `timing` (s), and each impact's and rebound's speed measured with a Gaussian
    error `speed_sigma` (m/s), drawn from `rng` in that order after the train."""
    model = TrainModel(LAWS["constant"].bind(eps),
                       lambda v: track_flight(v, g_eff + friction, g_eff - friction))
    drawn = model.simulate(bounces, rng, start_time=0.0, start_speed=speed,
                           process_sigma=scatter, jitter=timing)
    count = drawn.times.size  # one train: the arrays are 1-D
    return pd.DataFrame({
        "time": drawn.times, "time_uncertainty": timing,
        "impact_speed": drawn.impact_speeds + rng.normal(0.0, speed_sigma, count),
        "rebound_speed": drawn.rebound_speeds + rng.normal(0.0, speed_sigma, count),
        "speed_uncertainty": speed_sigma})
