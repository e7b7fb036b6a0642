"""Speed against accuracy of ``dashpot.collide``, per model and method.

Prints one table: for each model and method (exact; ode at rtol 1e-6, 1e-9, 1e-12) the maximum
relative error against the committed 40-digit reference (tests/reference/collide_reference.csv),
the evaluations per second on one core, and the ratio against a per-point baseline:

* exact vs scipy.optimize.brentq called point by point on the same closed-form end condition
  (the straightforward way to write it), after the same closed-form bracketing;
* ode vs scipy.integrate.solve_ivp called point by point with a terminal event.

A second table puts the exact gravity models against the closed forms (Ia, IIa) at the same
batch sizes: the ratio "slowest gravity model / closed form" of evaluations per second, with the
target of issue 16 (<= 8x against the faster closed form) and the baseline of the array code
before the root finding was compiled (commit 3830686: 7-15x, 1.1e6-2.0e6 evaluations/s for the
gravity models against 1.5e7-2e7 for the closed forms), and the CPU time per point of the
slowest gravity model and of the fastest closed form. Measured after the gravity models' collide
became one compiled pass: 4.5x / 12.3x / 3.5x at 1e3 / 1e4 / 1e5 points against the faster closed
form (2.8x / 6.7x / 2.3x against the slower), about 160 ns per gravity point against Ia's 13 ns
at 1e4 points, where numpy's vectorized exp makes Ia cheapest (numba's inlining took a tenth off
the gravity models but made their first compile 20 s instead of 3.6 s: not used).

Timings are CPU time (time.process_time) of the best of three runs, so that other load on the
machine distorts them less. Run with ``make bench``.
"""

from __future__ import annotations

import csv
import math
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import dashpot
from dashpot.physics import models as exact_models

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "tests" / "reference" / "collide_reference.csv"
N_POINTS = 100_000  # points per exact timing run
N_ODE = 5_000  # points per vectorized ode timing run
N_BASELINE = 2_000  # points for the per-point brentq baseline
N_BASELINE_ODE = 200  # points for the per-point solve_ivp baseline
ODE_TOLERANCES = (1e-6, 1e-9, 1e-12)


def workload(n, seed=1):
    """Log-uniform ζ in [1e-3, 10] and ṽ in [0.1, 1e6]: light to heavy damping, slow to fast."""
    rng = np.random.default_rng(seed)
    return 10 ** rng.uniform(-3, 1, n), 10 ** rng.uniform(-1, 6, n)


def cpu_rate(func, n, repeats=3):
    """Evaluations per CPU second of `func()`, which evaluates `n` points (best of `repeats`)."""
    best = math.inf
    for _ in range(repeats):
        start = time.process_time()
        func()
        best = min(best, time.process_time() - start)
    return n / max(best, 1e-9)


def load_reference():
    rows = {}
    if not REFERENCE.exists():
        return rows
    with REFERENCE.open() as handle:
        for row in csv.DictReader(handle):
            if row.get("kind", "grid") != "grid":
                continue
            rows.setdefault(row["model"], []).append(row)
    return rows


def max_errors(model, rows, method, rtol=None, ode_subset=False):
    """Largest relative errors in ε, 1 − ε and contact time over the reference rows."""
    zeta = np.array([float(r["zeta"]) for r in rows])
    vtilde = np.array([float(r["vtilde"]) for r in rows])
    keep = np.ones(zeta.size, bool)
    if ode_subset:
        # The stacked integration is not meant for contacts lasting 1e4 natural periods
        # (ζ within 1e-6 of 1) or for extreme speeds; the table says so in its header.
        keep = (zeta >= 1e-4) & (zeta <= 100) & (np.abs(zeta - 1) > 1e-5) & (vtilde <= 1e6)
    zeta, vtilde = zeta[keep], vtilde[keep]
    selected = [r for r, k in zip(rows, keep) if k]
    captured = np.array([r["captured"] == "1" for r in selected])
    eps_ref = np.array([float(r["eps"]) for r in selected])
    one_minus_ref = np.array([float(r["one_minus_eps"]) for r in selected])
    tau_ref = np.array([float(r["contact_time"]) for r in selected])
    result = dashpot.collide(model, zeta, vtilde, method=method, rtol=rtol)
    both = ~captured & ~result.captured & (eps_ref > 1e-300)
    mismatched_capture = int(np.sum(captured != result.captured))

    def rel(got, ref):
        return float(np.max(np.abs(got[both] / ref[both] - 1.0))) if both.any() else 0.0

    return (rel(result.eps, eps_ref), rel(result.one_minus_eps, one_minus_ref),
            rel(result.contact_time, tau_ref), mismatched_capture, int(both.sum()))


# --- baselines ---------------------------------------------------------------------------------

def brentq_baseline(model, zeta, vtilde):
    """Per-point brentq on the closed-form end condition (after the same bracketing)."""
    if model in ("Ia", "IIa"):
        # Closed forms: the per-point baseline is plain math in a loop.
        out = []
        for z in zeta:
            omega = math.sqrt((1 - z) * (1 + z)) if z < 1 else 0.0
            tau = math.pi / omega if model == "Ia" and omega else 2 * math.atan2(omega, z) / max(
                omega, 1e-300)
            out.append(math.exp(-z * tau))
        return out
    if model == "Ib":
        lower, upper, xi_max = exact_models._ib_bracket(zeta, vtilde)
        usable = xi_max > 0
    else:
        lower, upper, force_min = exact_models._iib_bracket(zeta, vtilde)
        usable = force_min < 0
    roots = []
    for z, v, lo, hi, ok in zip(zeta, vtilde, lower, upper, usable):
        if not ok:
            roots.append(math.inf)
            continue
        roots.append(brentq(_scalar_end_condition, lo, hi, args=(model, z, v), xtol=1e-300,
                            rtol=4 * np.finfo(float).eps))
    return roots


def _scalar_end_condition(t, model, z, v):
    """ξ(t) (Ib) or F/(mg) (IIb, hybrid) written the straightforward way, with the math module."""
    if z < 1:
        w = math.sqrt((1 - z) * (1 + z))
        c, s = math.exp(-z * t) * math.cos(w * t), math.exp(-z * t) * math.sin(w * t) / w
    elif z > 1:
        w = math.sqrt((z - 1) * (z + 1))
        c, s = math.exp(-z * t) * math.cosh(w * t), math.exp(-z * t) * math.sinh(w * t) / w
    else:
        c, s = math.exp(-t), t * math.exp(-t)
    if model == "Ib":
        return c + (z - v) * s - 1.0
    return 1.0 + (2 * z * v - 1) * c + (z + v * (1 - 2 * z * z)) * s


def solve_ivp_baseline(model, zeta, vtilde, rtol):
    """Per-point solve_ivp with a terminal event at the end of contact."""
    gravity = 1.0 if model in ("Ib", "IIb", "hybrid") else 0.0
    force_end = model not in ("Ia", "Ib")
    out = []
    for z, v in zip(zeta, vtilde):
        def rhs(_t, y, z=z):
            return [y[1], -gravity - y[0] - 2 * z * y[1]]

        def event(_t, y, z=z):
            return y[0] + 2 * z * y[1] if force_end else y[0]

        event.terminal = True
        event.direction = 1
        sol = solve_ivp(rhs, (0, 200.0), [0.0, -v], rtol=rtol, atol=1e-3 * rtol * max(v, 1),
                        events=event, method="DOP853")
        out.append(sol.t_events[0][0] if sol.t_events[0].size else math.inf)
    return out


def main():
    reference = load_reference()
    zeta, vtilde = workload(N_POINTS)
    header = (f"{'model':7s} {'method':12s} {'max|Δε/ε|':>10s} {'max|Δ(1-ε)|':>12s} "
              f"{'max|Δτ/τ|':>10s} {'capture≠':>8s} {'points':>7s} {'eval/s':>10s} "
              f"{'baseline/s':>10s} {'ratio':>7s}")
    print(f"reference: {REFERENCE.relative_to(ROOT)} "
          f"({'found' if reference else 'MISSING: errors not measured'})")
    print(f"workload: ζ log-uniform in [1e-3, 10], ṽ log-uniform in [0.1, 1e6]; exact on "
          f"{N_POINTS} points, ode on {N_ODE}; baselines on {N_BASELINE} (brentq) and "
          f"{N_BASELINE_ODE} (solve_ivp) points; CPU time, best of 3")
    print("ode errors are over reference rows with 1e-4 <= ζ <= 100, |ζ - 1| > 1e-5, ṽ <= 1e6")
    print(header)
    print("-" * len(header))
    for model in dashpot.MODELS:
        base_z, base_v = zeta[:N_BASELINE], vtilde[:N_BASELINE]
        baseline = cpu_rate(lambda: brentq_baseline(model, base_z, base_v), N_BASELINE, 1)
        rate = cpu_rate(lambda: dashpot.collide(model, zeta, vtilde), N_POINTS)
        errors = (max_errors(model, reference[model], "exact") if model in reference
                  else (math.nan,) * 3 + (0, 0))
        print(f"{model:7s} {'exact':12s} {errors[0]:10.1e} {errors[1]:12.1e} {errors[2]:10.1e} "
              f"{errors[3]:8d} {errors[4]:7d} {rate:10.3g} {baseline:10.3g} "
              f"{rate / baseline:7.1f}")
        ode_z, ode_v = zeta[:N_ODE], vtilde[:N_ODE]
        for rtol in ODE_TOLERANCES:
            base_ode = cpu_rate(lambda: solve_ivp_baseline(model, ode_z[:N_BASELINE_ODE],
                                                            ode_v[:N_BASELINE_ODE], rtol),
                                N_BASELINE_ODE, 1)
            rate = cpu_rate(lambda: dashpot.collide(model, ode_z, ode_v, method="ode",
                                                    rtol=rtol), N_ODE, 1)
            errors = (max_errors(model, reference[model], "ode", rtol, ode_subset=True)
                      if model in reference else (math.nan,) * 3 + (0, 0))
            print(f"{'':7s} {f'ode {rtol:.0e}':12s} {errors[0]:10.1e} {errors[1]:12.1e} "
                  f"{errors[2]:10.1e} {errors[3]:8d} {errors[4]:7d} {rate:10.3g} "
                  f"{base_ode:10.3g} {rate / base_ode:7.1f}")
    print("target: >= 1e6 exact evaluations per second on one core for Ib, IIb and hybrid")
    gravity_ratio_table()
    surrogate_table(reference)


# --- gravity models against the closed forms ---------------------------------------------------

GRAVITY_RATIO_TARGET = 8.0  # issue 16
GRAVITY_RATIO_BASELINE = "7-15x (commit 3830686, vectorized numpy Halley iteration)"
RATIO_BATCHES = (1_000, 10_000, 100_000)


def gravity_ratio_table(rounds=5):
    """Evaluations/s of every model at the same batch sizes, and slowest gravity / closed form.

    The compiled solver is warmed up (compiled or loaded from its cache) before timing. The
    models are timed in turn, `rounds` times, keeping each one's best: a burst of other load on
    the machine then slows every model alike instead of one.
    """
    zeta, vtilde = workload(max(RATIO_BATCHES), seed=3)
    for model in dashpot.MODELS:
        dashpot.collide(model, zeta[:10], vtilde[:10])
    closed, gravity = ("Ia", "IIa"), ("Ib", "IIb", "hybrid")
    header = (f"{'points':>8s} " + " ".join(f"{m + ' /s':>10s}" for m in dashpot.MODELS)
              + f" {'slowest gravity / fastest closed':>33s} {'/ slowest closed':>17s}"
              + f" {'ns/point: gravity':>18s} {'closed':>7s}")
    print()
    print("exact gravity models against the closed forms, same workload and batch sizes "
          f"(CPU time, best of {rounds} interleaved); target <= {GRAVITY_RATIO_TARGET:g}x against the faster "
          f"closed form (issue 16); baseline {GRAVITY_RATIO_BASELINE}")
    print(header)
    print("-" * len(header))
    for n in RATIO_BATCHES:
        z, v = zeta[:n], vtilde[:n]
        calls = max(1, 100_000 // n)
        rates = dict.fromkeys(dashpot.MODELS, 0.0)
        for _ in range(rounds):
            for model in dashpot.MODELS:
                rate = cpu_rate(lambda model=model: [dashpot.collide(model, z, v)
                                                     for _ in range(calls)], n * calls, 1)
                rates[model] = max(rates[model], rate)
        slowest = min(rates[m] for m in gravity)
        worst = max(rates[m] for m in closed) / slowest
        best = min(rates[m] for m in closed) / slowest
        verdict = "meets" if worst <= GRAVITY_RATIO_TARGET else "MISSES"
        print(f"{n:8d} " + " ".join(f"{rates[m]:10.3g}" for m in dashpot.MODELS)
              + f" {worst:26.1f}x {verdict:>6s} {best:16.1f}x"
              + f" {1e9 / slowest:18.0f} {1e9 / max(rates[m] for m in closed):7.1f}")


# --- surrogate (dashpot.physics.surrogate) -----------------------------------------------------

def surrogate_errors(model, rows, level):
    """max_errors for surrogate_collide (all reference rows; off-table rows use the exact path)."""
    from dashpot.physics.surrogate import surrogate_collide

    zeta = np.array([float(r["zeta"]) for r in rows])
    vtilde = np.array([float(r["vtilde"]) for r in rows])
    captured = np.array([r["captured"] == "1" for r in rows])
    refs = [np.array([float(r[k]) for r in rows]) for k in ("eps", "one_minus_eps",
                                                             "contact_time")]
    result = surrogate_collide(model, zeta, vtilde, level=level)
    both = ~captured & ~result.captured & (refs[0] > 1e-300)
    rel = [float(np.max(np.abs(got[both] / ref[both] - 1.0))) if both.any() else 0.0
           for got, ref in zip((result.eps, result.one_minus_eps, result.contact_time), refs)]
    return (*rel, int(np.sum(captured != result.captured)), int(both.sum()))


def per_call_us(func, n, repeats=200):
    """CPU µs per call of func() on n points (best of 3 runs of `repeats` calls)."""
    return 1e6 / cpu_rate(lambda: [func() for _ in range(repeats)], repeats)


def surrogate_table(reference):
    """Pareto rows: exact vs surrogate levels — error, throughput, per-call cost, build cost."""
    from dashpot.physics.surrogate import (LEVELS, SURROGATE_MODELS, load_surrogate,
                                           surrogate_collide)

    zeta, vtilde = workload(N_POINTS)
    rng = np.random.default_rng(2)
    header = (f"{'model':7s} {'method':18s} {'bound':>8s} {'max|Δε/ε|':>10s} {'max|Δ(1-ε)|':>12s} "
              f"{'max|Δτ/τ|':>10s} {'capture≠':>8s} {'eval/s':>9s} {'µs@10':>7s} {'µs@100':>7s} "
              f"{'µs@1000':>8s} {'build s':>7s} {'bytes':>9s}")
    print()
    print("surrogate: errors over all reference rows (off-table rows take the exact path); "
          "eval/s on the workload above (off-table points are exact); µs per call at n "
          "points with ζ log-uniform in [1e-3, 2], ṽ log-uniform in [1, 1e5]")
    print(header)
    print("-" * len(header))
    calls = {n: (10 ** rng.uniform(-3, np.log10(2), n), 10 ** rng.uniform(0, 5, n))
             for n in (10, 100, 1000)}
    for model in dashpot.MODELS:
        methods = [("exact", None)] + [(f"surrogate {level}", level) for level in LEVELS]
        for name, level in methods:
            if level is None:
                def run(z, v):
                    return dashpot.collide(model, z, v)
                bound, build, size = exact_models.EXACT_RTOL, math.nan, 0
                errors = (max_errors(model, reference[model], "exact") if model in reference
                          else (math.nan,) * 3 + (0, 0))
            else:
                def run(z, v, level=level):
                    return surrogate_collide(model, z, v, level=level)
                if model in SURROGATE_MODELS:
                    table = load_surrogate(model, level)
                    bound, build, size = table.bound, table.build_seconds, table.nbytes
                else:
                    bound, build, size = exact_models.EXACT_RTOL, 0.0, 0
                errors = (surrogate_errors(model, reference[model], level)
                          if model in reference else (math.nan,) * 3 + (0, 0))
            rate = cpu_rate(lambda: run(zeta, vtilde), N_POINTS)
            timings = [per_call_us(lambda z=z, v=v: run(z, v), n, 50 if n < 1000 else 10)
                       for n, (z, v) in calls.items()]
            print(f"{model:7s} {name:18s} {bound:8.1e} {errors[0]:10.1e} {errors[1]:12.1e} "
                  f"{errors[2]:10.1e} {errors[3]:8d} {rate:9.3g} {timings[0]:7.0f} "
                  f"{timings[1]:7.0f} {timings[2]:8.0f} {build:7.2f} {size:9d}")


if __name__ == "__main__":
    main()
