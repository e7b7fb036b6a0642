"""Speed of fitting a scene under every contact model (dashpot.fit), with uncertainties.

A 40-impact synthetic scene (hybrid model, ζ = 0.01, ω0 = 500 rad/s, v0 = 1 m/s, 20 µs timing
noise, the size of a ball recorded with a microphone) is fitted under all five models, with
start values, Levenberg–Marquardt, covariance, derived quantities and the selection table.
Prints, per model, the CPU time, the number of model evaluations and the recovered β against
the truth, then the whole scene against the target (under 1 s on one core), and the ratio
against a baseline whose fit evaluations build every predicted train impact by impact (one
collide call per impact, as :func:`dashpot.bounce_sequence` does) instead of solving it whole
by Newton from the previous evaluation's train.

Timings are CPU time (time.process_time), best of three. Run with ``make bench``.
"""

from __future__ import annotations


import numpy as np
import pandas as pd

import dashpot
from dashpot.fit import accuracy as accuracy_module
from dashpot.fit import fit_model, fit_scene, prepare_data
from dashpot.scene import Scene
from timing import best_cpu

G = 9.80665
TRUTH = dict(model="hybrid", beta=5.0, omega0=500.0, v0=1.0)
IMPACTS, SIGMA = 40, 2e-5
TARGET_SECONDS = 1.0


def scene_impacts(seed=1):
    sequence = dashpot.bounce_sequence(TRUTH["model"], beta=TRUTH["beta"],
                                       omega0=TRUTH["omega0"], g=G, v0=TRUTH["v0"],
                                       n_max=IMPACTS)
    noise = np.random.default_rng(seed).normal(0.0, SIGMA, IMPACTS)
    return pd.DataFrame({"time": 0.5 + sequence.impact_times + noise,
                         "time_uncertainty": SIGMA})


def _impact_by_impact(model, zeta, vtilde0, count, *, start=None, **options):
    """Baseline trains: ignore the start, so every train is built impact by impact."""
    del start
    return _NEWTON_TRAINS(model, zeta, vtilde0, count, start=None, **options)


_NEWTON_TRAINS = accuracy_module.impact_trains


def main():
    impacts = scene_impacts()
    scene = Scene()
    data = prepare_data(impacts, scene)
    print(f"scene: {IMPACTS} impacts of a {TRUTH['model']} train, beta = {TRUTH['beta']} 1/s, "
          f"omega0 = {TRUTH['omega0']} rad/s, v0 = {TRUTH['v0']} m/s, timing noise "
          f"{SIGMA * 1e6:.0f} us; CPU time, best of 3")
    header = (f"{'model':7s} {'CPU s':>8s} {'evals':>6s} {'beta 1/s':>10s} {'stderr':>8s} "
              f"{'(fit-truth)/stderr':>19s} {'baseline s':>11s} {'speed-up':>9s}")
    print(header)
    print("-" * len(header))
    for model in dashpot.MODELS:
        seconds, fit = best_cpu(lambda model=model: fit_model(data, model, scene,
                                                             accuracy="exact"))
        # The exact level's train solver is dashpot.fit.accuracy's impact_trains (looked up
        # per fit).
        accuracy_module.impact_trains = _impact_by_impact
        try:
            base_seconds, _ = best_cpu(
                lambda model=model: fit_model(data, model, scene, accuracy="exact"), repeats=1)
        finally:
            accuracy_module.impact_trains = _NEWTON_TRAINS
        beta = fit.estimates["beta"]
        pull = (beta.value - TRUTH["beta"]) / beta.stderr
        print(f"{model:7s} {seconds:8.3f} {fit.nfev:6d} {beta.value:10.4f} {beta.stderr:8.3f} "
              f"{pull:19.2f} {base_seconds:11.3f} {base_seconds / seconds:8.1f}x")
    seconds, result = best_cpu(lambda: fit_scene(impacts, Scene(accuracy="exact")))
    verdict = "meets" if seconds < TARGET_SECONDS else "MISSES"
    print(f"all five models with uncertainties and selection, exact level: {seconds:.3f} s "
          f"CPU ({verdict} the target of {TARGET_SECONDS:g} s on one core)")
    seconds, result = best_cpu(lambda: fit_scene(impacts, scene))
    print(f"the same at the accuracy the scene's timing needs (auto: "
          f"{result.results['hybrid'].accuracy}): {seconds:.3f} s CPU")
    print(f"verdict: {result.verdict}")


if __name__ == "__main__":
    main()
