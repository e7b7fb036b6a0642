"""Speed of the fits under the noise model (dashpot.fit.noise_fit) at every accuracy level.

Two scenes: a 50-impact synthetic train drawn from the noise model (hybrid dashpot, ζ = 0.02,
v* = 5 mm/s, v0 = 1 m/s, σ_ε = 0.3 %, detector σ 10 µs plus 20 µs jitter, seed fixed) and, where
the shared data are present, the ping-pong recording (../shared/data/pingpong-erickson, 53
impacts). Each law of the ladder, the drag rung (``constant+drag``: the constant law with a
free drag constant, as :func:`dashpot.fit.noise_scene.fit_noise_scene` fits it where the scene
gives no mass and diameter) and each dashpot model is fitted (with profile intervals) at
the fast, standard and exact levels and at auto. Prints per law the CPU time at each level, how
far the fast and standard fits are from the exact one (|Δ(−2 ln L)| and the largest parameter
shift in standard errors), then the whole ladder plus the five models at auto against the
target (under 1 s of CPU), the ratio exact/fast (target >= 10) and the ratio against the
baseline.

Baseline: commit 3830686, before the accuracy levels (the law, contact time and flight
evaluated at every impact, two exact collisions per step for a dashpot model). Its figures on
the ping-pong recording, measured on the machine this benchmark was written on: about 55 s of
CPU for the ladder and the five models (constant 0.8 s, linear 1.2, viscoelastic Hertz 0.8,
Hunt–Crossley 10, Ia 2, IIb 10, hybrid 12.4). With ``--baseline`` the script measures that
commit itself (exported with ``git archive`` into a temporary directory and run in a
subprocess, about two minutes) instead of quoting those figures.

Timings are CPU time (time.process_time), best of two at fast, standard and auto, one run at
exact. The surrogate tables of the dashpot models are built and cached on their first use
(seconds), which a warm-up run takes out of the figures. Run with ``make bench``.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd

from dashpot.fit import prepare_data
from dashpot.fit.noise_fit import fit_noise_model
from dashpot.fit.settings import NOISE_LAWS
from dashpot.likelihood import TrainModel
from dashpot.physics.flight import gravity_flight
from dashpot.physics.laws import LAWS, dashpot_contact_time
from dashpot.physics.models import MODELS
from dashpot.scene import Scene
from timing import best_cpu

ROOT = Path(__file__).resolve().parents[1]
RECORDING = ROOT.parent / "shared" / "data" / "pingpong-erickson" / "pingpong.wav"
G = 9.80665
TRUTH = dict(zeta=0.02, v_star=0.005, v0=1.0, sigma_eps=0.003)
IMPACTS, DETECTOR, JITTER, SEED = 50, 10e-6, 20e-6, 20261125
TARGET_SECONDS, TARGET_RATIO = 1.0, 10.0
BASELINE_COMMIT = "3830686"
BASELINE_PINGPONG = {"constant": 0.8, "linear": 1.2, "viscoelastic-hertz": 0.8,
                     "hunt-crossley": 10.0, "Ia": 2.0, "IIb": 10.0, "hybrid": 12.4}
BASELINE_PINGPONG_TOTAL = 55.0
FITTED = (NOISE_LAWS[0], "constant+drag") + tuple(NOISE_LAWS[1:]) + tuple(MODELS)


def fit(data, name, **options):
    """A law, model or flight rung ("law+effect") of the ladder fitted under the noise model."""
    law, *effects = name.split("+")
    return fit_noise_model(data, law, effects=tuple(effects), **options)


def synthetic_data():
    params = (np.array([TRUTH["zeta"]]), np.array([TRUTH["v_star"]]))
    model = TrainModel(LAWS["hybrid"].bind(*params), lambda v: gravity_flight(v, G),
                       lambda u: dashpot_contact_time("hybrid", u, *params, G))
    train = model.simulate(IMPACTS, np.random.default_rng(SEED), start_time=0.3,
                           start_speed=TRUTH["v0"], process_sigma=TRUTH["sigma_eps"],
                           jitter=JITTER, detector_sigma=DETECTOR)
    return prepare_data(pd.DataFrame({"time": train.times[0], "time_uncertainty": DETECTOR}),
                        Scene())


def recording_data():
    from dashpot.analysis import scene_impacts

    return prepare_data(scene_impacts(RECORDING), Scene())


def shifts(fit, exact):
    """|Δ(−2 ln L)| and the largest |Δ parameter| in the exact fit's standard errors."""
    largest = 0.0
    for name, reference in exact.estimates.items():
        if name in ("omega0", "beta") or not (math.isfinite(reference.stderr)
                                              and reference.stderr > 0.0):
            continue
        largest = max(largest, abs(fit.estimates[name].value - reference.value)
                      / reference.stderr)
    return abs(fit.neg2_log_likelihood - exact.neg2_log_likelihood), largest


def measure(data):
    """Per law: CPU s at each level and auto, the auto level, and the shifts from exact."""
    rows = {}
    for law in FITTED:
        fit(data, law, accuracy="fast")  # warm-up: compiled loops, surrogate tables
        row = {}
        fits = {}
        for level in ("fast", "standard", "auto", "exact"):
            row[level], fits[level] = best_cpu(
                lambda law=law, level=level: fit(data, law, accuracy=level),
                repeats=1 if level == "exact" else 2)
        row["auto level"] = fits["auto"].accuracy
        for level in ("fast", "standard"):
            row[f"{level} shift"] = shifts(fits[level], fits["exact"])
        rows[law] = row
    return rows


BASELINE_WORKER = textwrap.dedent("""
    import json, sys, time
    import numpy as np, pandas as pd
    from pathlib import Path
    from dashpot.fit import prepare_data
    from dashpot.fit.noise_fit import fit_noise_model
    from dashpot.scene import Scene
    which, laws = sys.argv[1], sys.argv[2].split(",")
    if which == "recording":
        from dashpot.analysis import scene_impacts
        data = prepare_data(scene_impacts(Path(sys.argv[3])), Scene())
    else:
        table = pd.read_json(sys.argv[3])
        data = prepare_data(table, Scene())
    out = {}
    for law in laws:
        start = time.process_time()
        fit_noise_model(data, law)
        out[law] = time.process_time() - start
    print(json.dumps(out))
""")


def measure_baseline(data_source):
    """CPU s per law of commit BASELINE_COMMIT on one scene (run in a subprocess)."""
    with tempfile.TemporaryDirectory() as directory:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", BASELINE_COMMIT, "src"],
                                 check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", directory], input=archive, check=True)
        which, argument = data_source
        if which == "synthetic":
            path = Path(directory) / "scene.json"
            argument.to_json(path)
            argument = str(path)
        result = subprocess.run(
            [sys.executable, "-c", BASELINE_WORKER, which,
             ",".join(name for name in FITTED if "+" not in name), str(argument)],
            check=True, capture_output=True, text=True,
            env={"PYTHONPATH": str(Path(directory) / "src"), "PATH": "/usr/bin:/bin"})
    return json.loads(result.stdout.strip().splitlines()[-1])


def report(title, rows, baseline=None, baseline_total=None):
    print(f"\n{title}")
    header = (f"{'law':19s} {'fast s':>7s} {'std s':>7s} {'exact s':>8s} {'auto s':>7s} "
              f"{'auto':>8s} {'exact/fast':>10s} {'fast: d2lnL, shift/SE':>22s} "
              f"{'std: d2lnL, shift/SE':>21s} {'baseline s':>10s}")
    print(header)
    print("-" * len(header))
    for law, row in rows.items():
        known = (baseline or {}).get(law)
        fast_shift, standard_shift = row["fast shift"], row["standard shift"]
        print(f"{law:19s} {row['fast']:7.3f} {row['standard']:7.3f} {row['exact']:8.3f} "
              f"{row['auto']:7.3f} {row['auto level']:>8s} {row['exact'] / row['fast']:9.1f}x "
              f"{fast_shift[0]:10.1e}, {fast_shift[1]:9.1e} "
              f"{standard_shift[0]:10.1e}, {standard_shift[1]:8.1e} "
              f"{'' if known is None else f'{known:10.1f}'}")
    totals = {level: sum(row[level] for row in rows.values())
              for level in ("fast", "standard", "exact", "auto")}
    verdict = "meets" if totals["auto"] < TARGET_SECONDS else "MISSES"
    ratio = totals["exact"] / totals["fast"]
    print(f"ladder + five dashpot models, with profile intervals: auto {totals['auto']:.2f} s "
          f"CPU ({verdict} the target of {TARGET_SECONDS:g} s); fast {totals['fast']:.2f} s, "
          f"standard {totals['standard']:.2f} s, exact {totals['exact']:.2f} s")
    print(f"exact/fast: {ratio:.1f}x ({'meets' if ratio >= TARGET_RATIO else 'MISSES'} the "
          f">= {TARGET_RATIO:g}x target)")
    if baseline_total is not None:
        print(f"baseline (commit {BASELINE_COMMIT}): {baseline_total:.1f} s; at auto "
              f"{baseline_total / totals['auto']:.0f}x faster")


def main():
    measure_base = "--baseline" in sys.argv[1:]
    print("noise-model fits, CPU time (best of 2; exact once); shifts: |d(-2 ln L)| and the "
          "largest parameter shift from the exact fit in its standard errors")
    data = synthetic_data()
    rows = measure(data)
    baseline = None
    if measure_base:
        table = pd.DataFrame({"time": data.times + data.time_origin,
                              "time_uncertainty": data.sigma})
        baseline = measure_baseline(("synthetic", table))
    report(f"synthetic scene: {IMPACTS} impacts, hybrid zeta = {TRUTH['zeta']}, v* = "
           f"{TRUTH['v_star']} m/s, sigma_eps = {TRUTH['sigma_eps']:.1%}, seed {SEED}", rows,
           baseline, None if baseline is None else sum(baseline.values()))
    if not RECORDING.exists():
        print(f"\nping-pong recording absent ({RECORDING}): skipped")
        return
    data = recording_data()
    rows = measure(data)
    if measure_base:
        baseline = measure_baseline(("recording", RECORDING))
        total = sum(baseline.values())
    else:
        baseline, total = BASELINE_PINGPONG, BASELINE_PINGPONG_TOTAL
    report(f"ping-pong recording ({data.count} impacts); baseline "
           f"{'measured' if measure_base else 'as quoted in the module notes'}",
           rows, baseline, total)


if __name__ == "__main__":
    main()
