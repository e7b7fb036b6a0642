"""Plain-words notes where the data do not pin a fitted parameter down (at a bound, unbounded,
large relative error, strongly correlated).
"""

from __future__ import annotations

import math

import numpy as np

from .settings import STRONG_CORRELATION, WEAK_RELATIVE_ERROR


def _identifiability_notes(estimates, varied, correlation, params):
    """Plain-words warnings where the data do not pin a parameter down.

    k = m omega0^2 shares omega0's notes only where a mass makes k part of the result
    (``"k"`` in `estimates`).
    """
    notes = []
    omega0_label = "omega0 (and so k)" if "k" in estimates else "omega0"
    labels = {"zeta": "zeta", "v_star": omega0_label, "v0": "v0", "t0": "t0"}
    for name in varied:
        param = params[name]
        if any(np.isfinite(bound) and abs(param.value - bound) <= 1e-3 * abs(bound)
               for bound in (param.min, param.max)):
            notes.append(f"{labels.get(name, name)} ended at its bound: not determined by "
                         f"these data")
    omega0 = estimates.get("omega0")
    if omega0 is not None and omega0.status != "fixed" and math.isinf(omega0.high95):
        notes.append(f"{omega0_label} is not bounded above at 95 %: the data are consistent "
                     f"with the gravity-free limit (v* = g/omega0 -> 0)")
    for key, label in (("omega0", omega0_label), ("zeta", "zeta"), ("beta", "beta")):
        estimate = estimates.get(key)
        if estimate is not None and estimate.status != "fixed":
            relative = estimate.stderr / estimate.value if estimate.value else math.inf
            if not relative <= WEAK_RELATIVE_ERROR:
                notes.append(f"{label} is not determined by these data (relative error "
                             f"{relative:.2g})")
    for i, first in enumerate(varied):
        for j in range(i + 1, len(varied)):
            rho = correlation[i, j]
            if np.isfinite(rho) and abs(rho) > STRONG_CORRELATION:
                notes.append(f"{labels.get(first, first)} and "
                             f"{labels.get(varied[j], varied[j])} are strongly correlated "
                             f"(rho = {rho:.3f}): the data constrain a combination of them")
    return notes
