"""Uncertainty from the profile likelihood: intervals of β where χ², minimised over the other
parameters at fixed β, rises by 1 and 4.

References
----------
Numbered as in :mod:`dashpot.fit`.

.. [5] W. H. Press et al., *Numerical Recipes*, 3rd ed., Cambridge (2007), sec. 15.6
   (confidence regions from Δχ² = 1 and 4 for one parameter).
"""

from __future__ import annotations

import math

import lmfit
import numpy as np

from .settings import METHOD, OPTIONS


def _profile_beta(residual, result, g, chisqr_scale=1.0, points=17, span=4.0):
    """Profile likelihood of β: the best χ² over the other parameters at each fixed β.

    β is put in as a parameter (ζ = βv*/g) on a grid of ±`span` standard errors in ln β
    around the fit, each point started from its neighbour; the 68.27 % and 95.45 % intervals
    are where the profile, χ²/`chisqr_scale`, rises by 1 and 4 above its minimum (linear
    interpolation in ln β), unbounded where it does not within the grid [5]_.
    """
    params = result.params.copy()
    beta_hat = params["zeta"].value * g / params["v_star"].value
    params.add("beta", value=beta_hat, vary=False)
    params["zeta"].set(expr=f"beta * v_star / {g!r}")
    spread = math.hypot(*(result.params[name].stderr / result.params[name].value
                          if result.params[name].stderr else 0.0
                          for name in ("zeta", "v_star")))
    spread = min(max(spread, 1e-6), 2.0)
    offsets = np.linspace(-span, span, points) * spread
    profile = np.full(points, np.inf)
    centre = points // 2
    for order in (range(centre, points), range(centre, -1, -1)):
        trial = params.copy()
        for i in order:
            trial["beta"].set(value=beta_hat * math.exp(offsets[i]))
            fitted = lmfit.minimize(residual, trial, method=METHOD, max_nfev=400, **OPTIONS)
            profile[i] = fitted.chisqr
            trial = fitted.params
    rise = (profile - min(profile.min(), result.chisqr)) / chisqr_scale
    row = {}
    for level, label in ((1.0, "68"), (4.0, "95")):
        for side, key in ((-1, "low"), (1, "high")):
            row[key + label] = _crossing(offsets, rise, level, side, centre, beta_hat)
    return row


def _crossing(offsets, rise, level, side, centre, beta_hat):
    """β where the profile first rises past `level` going from the centre towards `side`."""
    index = range(centre, len(offsets)) if side > 0 else range(centre, -1, -1)
    previous = None
    for i in index:
        if rise[i] >= level and previous is not None:
            fraction = (level - rise[previous]) / (rise[i] - rise[previous])
            return beta_hat * math.exp(offsets[previous]
                                       + fraction * (offsets[i] - offsets[previous]))
        previous = i
    return 0.0 if side < 0 else math.inf
