"""Settings shared by the fit's modules: fitted coordinates, intervals, optimizer and start-value
settings, thresholds of the notes.

They sit at the bottom of the fit's import graph (this module imports none of the others, only
the registry of restitution laws), so that the modules using them do not import each other in a
circle.
"""

from __future__ import annotations

import numpy as np

from ..physics.laws import LADDER


Z68, Z95 = 1.0, 2.0  # normal quantiles of the central 68.27 % and 95.45 % intervals
OMEGA0_RANGE = (0.1, 1e7)  # rad/s searched and allowed for ω0
PROFILE_POINTS = 9
# A gravity model's start grid of ω0 spans a factor GRAVITY_OMEGA0_SPREAD either side of its
# centre in PROFILE_POINTS steps of COARSE_OMEGA0_STEP (about 4.2).
GRAVITY_OMEGA0_SPREAD = 1e5 ** 0.5
COARSE_OMEGA0_STEP = GRAVITY_OMEGA0_SPREAD ** (2.0 / (PROFILE_POINTS - 1))
REJECTED = 1e12  # residual of a step outside the physical range
INTERVAL_SEED = 20261122
# Draws for the intervals of derived values, per level: the Monte Carlo error of a 95.45 %
# bound is about 0.02 (20 000 draws) or 0.05 (4 000) standard errors.
INTERVAL_DRAWS = {"fast": 4000, "standard": 20000, "exact": 20000}
UNCERTAINTY_METHODS = ("covariance", "profile", "posterior")
ACCURACY_LEVELS = ("fast", "standard", "exact")  # cheapest first
QUANTILES = (0.158655, 0.841345, 0.0227501, 0.9772499)  # central 68.27 % and 95.45 %
METHOD, OPTIONS = "leastsq", {"epsfcn": 1e-6}
PARAMETERS = ("zeta", "v_star", "v0", "t0")  # the fitted coordinates, in this order
# The fast level's optimizer stops once the Gauss–Newton step left is below this many standard
# errors (in the metric of the fit's own covariance), and differentiates with this step.
FAST_STEP_SE, FAST_JACOBIAN_STEP = 0.01, 1e-5
# Start values of the fast level: steps of the fits at fixed ω0, and the grid of ζ searched
# for the interval ratio (inside the surrogate tables' domain).
FAST_PROFILE_ITERATIONS = 3
ZETA_START_GRID = np.geomspace(1e-4, 0.9, 41)
ZETA_ELASTIC_GRID = np.geomspace(1e-12, 1e-4, 33)
# Relative errors above which a parameter is reported as not determined by the data.
WEAK_RELATIVE_ERROR = 0.5
STRONG_CORRELATION = 0.98
# The restitution-law ladder fitted under the noise model beside the dashpot models (``fit_scene``
# with noise=True), simplest first: every law of :data:`dashpot.physics.laws.LAWS` without a
# contact duration (a law added to the registry joins it).
NOISE_LAWS = LADDER
