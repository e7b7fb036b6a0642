"""Coverage and width of reported intervals over seeded trials (shared test helper).

Coverage alone passes inflated errors (a 95.45 % interval twice too wide still covers about
100 %, inside any binomial tolerance of a few tens of trials), so every parameter is judged on
two counts:

* coverage: the number of trials whose 68.27 % (95.45 %) interval holds the truth must lie in
  the central 99.9 % range of the binomial distribution Bin(N, 0.6827) (Bin(N, 0.9545)); a
  correct method fails this 0.1 % of the time per check;
* width: the mean half-width of the 68.27 % interval, and the mean standard error, divided by
  the standard deviation of the estimates over the trials, must lie in [0.7, 1.4]. For N >= 40
  the sample standard deviation scatters by about 1/√(2N) <= 11 %, so a correct method passes
  by more than 3σ and errors inflated or deflated by 1.4× fail. The width is judged only
  where the estimates are interior: a parameter whose 68.27 % interval reaches a bound of its
  range (a noise σ fitted at or near 0) in more than AT_BOUND_SHARE of the trials has one-sided
  intervals and a piled-up, non-Gaussian spread, and only its coverage is judged (the lines
  say so).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

LEVELS = (("68", 0.6827), ("95", 0.9545))
TAIL = 0.0005  # each side: the central 99.9 % of the binomial distribution
WIDTH_RANGE = (0.7, 1.4)
AT_BOUND_SHARE = 0.1
FIELDS = ("value", "stderr", "low68", "high68", "low95", "high95")


def binomial_range(trials, rate):
    """Smallest and largest number of covering trials inside the central 99.9 % of
    Bin(trials, rate)."""
    return (int(stats.binom.ppf(TAIL, trials, rate)),
            int(stats.binom.isf(TAIL, trials, rate)))



def normal_binomial_range(trials, rate):
    """rate·N ∓ 3σ of Bin(N, rate) in the normal approximation: the range of a count of
    successes (covering trials, kept rungs) in the few-trial checks of single effects."""
    sd = (trials * rate * (1.0 - rate)) ** 0.5
    return trials * rate - 3.0 * sd, trials * rate + 3.0 * sd


def assert_covers_at_both_levels(estimates, truth, label=""):
    """The 68.27 and 95.45 % intervals of `estimates` (one per trial) hold `truth` a number of
    times inside :func:`normal_binomial_range`."""
    trials = len(estimates)
    for level, rate in LEVELS:
        inside = sum(getattr(e, f"low{level}") <= truth <= getattr(e, f"high{level}")
                     for e in estimates)
        low, high = normal_binomial_range(trials, rate)
        assert low <= inside <= min(high, trials), (label, level, inside)

def collect(estimates):
    """Arrays of FIELDS from a list of Estimate (one per trial)."""
    return {name: np.array([float(getattr(e, name)) for e in estimates]) for name in FIELDS}


def judge(estimates, truth, rates=None):
    """Measured coverage and width of one parameter over the trials, and what fails.

    Parameters
    ----------
    estimates : list of dashpot.fit.Estimate
        One per trial.
    truth : float
    rates : dict, optional
        Coverage rates asked of the "68" and "95" intervals where they are not the nominal
        0.6827 and 0.9545 (a truth on the bound of the range).

    Returns
    -------
    measured : dict
        ``covered68``, ``covered95`` (counts), ``trials``, ``halfwidth/spread``,
        ``stderr/spread``, ``at bound`` (share of trials whose 68.27 % interval ends where
        the 95.45 % one does, at a bound of the range; above AT_BOUND_SHARE the width is not
        judged).
    failures : list of str
    """
    row = collect(estimates)
    trials = row["value"].size
    spread = float(np.std(row["value"], ddof=1))
    measured = {"trials": trials}
    failures = []
    for level, rate in LEVELS:
        rate = (rates or {}).get(level, rate)
        count = int(np.sum((row["low" + level] <= truth) & (truth <= row["high" + level])))
        measured["covered" + level] = count
        low, high = binomial_range(trials, rate)
        if not low <= count <= high:
            failures.append(f"{level} % interval holds the truth in {count}/{trials} trials "
                            f"(99.9 % binomial range {low}-{high})")
    # At a bound the 68.27 % and 95.45 % intervals end at the same place (σ fitted at 0, or
    # at its floor: low68 = low95 = 0): the interval is one-sided.
    measured["at bound"] = float(np.mean((row["low68"] == row["low95"])
                                         | (row["high68"] == row["high95"])))
    if measured["at bound"] > AT_BOUND_SHARE or spread == 0.0:
        measured["halfwidth/spread"] = measured["stderr/spread"] = float("nan")
        return measured, failures
    measured["halfwidth/spread"] = float(np.mean(row["high68"] - row["low68"]) / 2.0 / spread)
    measured["stderr/spread"] = float(np.mean(row["stderr"]) / spread)
    for key in ("halfwidth/spread", "stderr/spread"):
        if not WIDTH_RANGE[0] <= measured[key] <= WIDTH_RANGE[1]:
            failures.append(f"{key} = {measured[key]:.2f} (allowed {WIDTH_RANGE[0]}-"
                            f"{WIDTH_RANGE[1]})")
    return measured, failures


def judge_all(results, truth, rates=None):
    """:func:`judge` for every parameter of `truth` over fit results (``.estimates``), with
    the coverage rates ``rates[name]`` where given.

    Returns
    -------
    lines : list of str
        One line per parameter with its measured figures.
    failures : list of str
        Each prefixed by the parameter's name.
    """
    lines, failures = [], []
    for name, true in truth.items():
        measured, failed = judge([fit.estimates[name] for fit in results], true,
                                 (rates or {}).get(name))
        trials = measured["trials"]
        lines.append(f"{name:>9}: 68 % {measured['covered68']}/{trials}, 95 % "
                     f"{measured['covered95']}/{trials}, half-width/spread "
                     f"{measured['halfwidth/spread']:.2f}, stderr/spread "
                     f"{measured['stderr/spread']:.2f}"
                     + (f" (at a bound in {measured['at bound']:.0%}: width not judged)"
                        if measured["at bound"] > AT_BOUND_SHARE else ""))
        failures += [f"{name}: {text}" for text in failed]
    return lines, failures
