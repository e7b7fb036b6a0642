"""Speed against accuracy end to end: accuracy levels of the fits, and uncertainty methods.

Two tables.

1. Accuracy levels (fast, standard, exact, auto) on two synthetic scenes with known truth:
   an audio recording of a light ball (written by dashpot.synth, read back by the audio
   detector, so the timing errors are the detector's) and the paper's cart on its incline as
   a motion-sensor export. Per level: CPU time of fitting all five models, the error of the
   generating model's β and k against the truth (in units of their standard error), and the
   largest shift of any model's β and ω0 from the exact level's, in units of the exact
   level's standard error. Targets: fast at least 10x faster than exact within 0.1 standard
   error of it; auto never worse than 0.1 standard error. Baseline: the exact level (exact
   solver, lmfit's MINPACK to machine precision); fast is the certified surrogate with the
   batched optimizer stopped at 0.01 standard error.
2. Uncertainty methods (covariance, profile likelihood, emcee posterior): the fraction of
   seeded synthetic trials whose 68.27 % and 95.45 % intervals of β contain the truth, and the
   mean CPU time of each method, for a well-determined scene and one close to capture.

CPU times (time.process_time) and wall times of each level: the best of at least five runs
and of about one second of runs, after a first call that loads its tables, compiled loops and
caches. Run with ``make bench``.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

import dashpot
from dashpot.fit import ACCURACY_LEVELS, fit_model, fit_scene, prepare_data
from dashpot.ingest import read_impacts
from dashpot.scene import Known, Scene
from dashpot.synth.scene import write_scene
from timing import best_cpu, best_wall

G = 9.80665
BALL = dict(model="hybrid", beta=8.0, omega0=800.0, v0=1.2)  # ṽ0 ≈ 98, 30 impacts
CART_MASS, CART_K, CART_BETA = 0.506, 255.0, 1.87
TIMING_BUDGET = 1.0  # s of repeated runs per accuracy level


def audio_scene(folder):
    path = write_scene(folder / "ball", "audio", model=BALL["model"], beta=BALL["beta"],
                       omega0=BALL["omega0"], g=G, v0=BALL["v0"], n_max=30, seed=11,
                       snr_db=40.0)
    return read_impacts(path), Scene(name="ball"), BALL["beta"], None


def cart_scene(folder):
    omega0 = math.sqrt(CART_K / CART_MASS)
    g_eff = 0.129 * omega0
    path = write_scene(folder / "cart", "motion_sensor", model="hybrid", beta=CART_BETA,
                       omega0=omega0, g=g_eff, v0=1.0, seed=3)
    scene = Scene(name="cart", g_eff=g_eff, mass=Known(CART_MASS))
    return read_impacts(path, kind="motion_sensor"), scene, CART_BETA, CART_K


def level_table(name, impacts, scene, beta_true, k_true):
    rows, exact = [], None
    for level in ("exact", "standard", "fast", "auto"):
        def run(level=level):
            return fit_scene(impacts, dataclasses.replace(scene, accuracy=level))

        # A first call loads the level's tables and compiled loops and warms caches. Then the
        # best of at least five runs and of about a second of runs per level, so that a fast
        # level's 20 ms runs get as much protection from bursts of other load as the exact
        # level's 0.2 s runs.
        first, _ = best_cpu(run, repeats=1)
        repeats = max(5, math.ceil(TIMING_BUDGET / first))
        seconds, result = best_cpu(run, repeats=repeats)
        wall = best_wall(run, repeats=repeats)
        if level == "exact":
            exact = result
        hybrid = result.results["hybrid"]
        shift = 0.0
        for model, fit in result.results.items():
            reference = exact.results[model]
            if fit.success and reference.success:
                for key in ("beta", "omega0"):
                    ref = reference.estimates[key]
                    if math.isfinite(ref.stderr) and ref.stderr > 0:
                        shift = max(shift, abs(fit.estimates[key].value - ref.value)
                                    / ref.stderr)
        beta = hybrid.estimates["beta"]
        k = hybrid.estimates.get("k")
        rows.append((level, hybrid.accuracy, seconds, wall,
                     (beta.value - beta_true) / beta.stderr,
                     (k.value - k_true) / k.stderr if k is not None and k_true else math.nan,
                     shift))
    exact_seconds, exact_wall = rows[0][2], rows[0][3]
    print(f"\n{name}: {len(impacts)} impacts, generating model hybrid "
          f"(beta = {beta_true} 1/s{f', k = {k_true} N/m' if k_true else ''})")
    header = (f"{'level':9s} {'used':9s} {'CPU s':>7s} {'speed-up':>9s} {'wall s':>7s} "
              f"{'speed-up':>9s} {'beta err/SE':>12s} {'k err/SE':>9s} "
              f"{'max shift/SE vs exact':>22s}")
    print(header)
    print("-" * len(header))
    for level, used, seconds, wall, beta_pull, k_pull, shift in rows:
        print(f"{level:9s} {used:9s} {seconds:7.3f} {exact_seconds / seconds:8.1f}x "
              f"{wall:7.3f} {exact_wall / wall:8.1f}x {beta_pull:12.2f} {k_pull:9.2f} "
              f"{shift:22.3f}")
    return rows


def coverage_table(trials=40):
    scenes = {
        "well determined (hybrid, ṽ0 ≈ 51)": dict(model="hybrid", beta=5.0, omega0=500.0,
                                                   v0=1.0, count=20),
        "close to capture (Ib, last rebound at 1.5 ṽc)": dict(model="Ib", beta=10.0,
                                                              omega0=200.0, v0=None,
                                                              count=None),
    }
    print(f"\nuncertainty of beta: coverage over {trials} seeded trials (20 us timing noise), "
          f"fast accuracy level")
    header = f"{'scene':46s} {'method':11s} {'68.27 %':>8s} {'95.45 %':>8s} {'CPU s/fit':>10s}"
    print(header)
    print("-" * len(header))
    for name, spec in scenes.items():
        spec = dict(spec)
        if spec["v0"] is None:
            critical = float(dashpot.critical_velocity("Ib", spec["beta"] / spec["omega0"]))
            spec["v0"] = 20.0 * critical * G / spec["omega0"]
            spec["count"] = dashpot.bounce_sequence(
                "Ib", beta=spec["beta"], omega0=spec["omega0"], g=G, v0=spec["v0"],
                n_max=80).impact_times.size
        hits = {method: [0, 0, 0.0] for method in ("covariance", "profile", "posterior")}
        for seed in range(trials):
            sequence = dashpot.bounce_sequence(spec["model"], beta=spec["beta"],
                                               omega0=spec["omega0"], g=G, v0=spec["v0"],
                                               n_max=spec["count"])
            noise = np.random.default_rng(seed).normal(0, 2e-5, sequence.impact_times.size)
            impacts = pd.DataFrame({"time": sequence.impact_times + noise,
                                    "time_uncertainty": 2e-5})
            fit = fit_model(prepare_data(impacts, Scene()), spec["model"], Scene(),
                            uncertainty=tuple(hits), seed=seed, accuracy="fast")
            for method, row in fit.intervals.items():
                hits[method][0] += row["low68"] <= spec["beta"] <= row["high68"]
                hits[method][1] += row["low95"] <= spec["beta"] <= row["high95"]
                hits[method][2] += row.get("cpu_seconds", 0.0) or 0.0
        for method, (in68, in95, seconds) in hits.items():
            print(f"{name:46s} {method:11s} {in68 / trials:8.2f} {in95 / trials:8.2f} "
                  f"{seconds / trials:10.3f}")


def main():
    print(f"accuracy levels: {', '.join(ACCURACY_LEVELS)} and auto; CPU time of all five fits")
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        verdicts = []
        for name, make in (("audio recording of a light ball", audio_scene),
                           ("paper's cart, motion sensor", cart_scene)):
            impacts, scene, beta_true, k_true = make(folder)
            rows = level_table(name, impacts, scene, beta_true, k_true)
            by_level = {row[0]: row for row in rows}
            verdicts.append(
                f"{name}: fast {by_level['exact'][2] / by_level['fast'][2]:.1f}x faster than "
                f"exact (wall {by_level['exact'][3] / by_level['fast'][3]:.1f}x), shift "
                f"{by_level['fast'][6]:.3f} SE; auto shift {by_level['auto'][6]:.3f} SE "
                f"(targets: >= 10x, <= 0.1 SE)")
    for line in verdicts:
        print(line)
    coverage_table()


if __name__ == "__main__":
    main()
