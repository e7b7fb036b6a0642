"""Settings of the fits under the noise model (:mod:`dashpot.fit.noise_fit`): the fitted
noise and flight parameters, the optimizer's steps and tolerances, the profile grids and the
accuracy levels' step-map tables.

They sit at the bottom of the noise fit's imports (this module imports none of the fit's
modules; the flight effects come from their registry, :mod:`dashpot.physics.effects`), so that
the likelihood, the optimizer and the fit driver share them without importing each other in a
circle.
"""

from __future__ import annotations

import numpy as np

from ..physics.effects import EFFECT_PARAMETERS, FLIGHT_EFFECTS  # noqa: F401

NOISE_PARAMETERS = ("v0", "sigma_eps", "sigma_j")
# FLIGHT_EFFECTS: the flight effects a fit may add (``effects`` of
# :func:`dashpot.fit.noise_fit.fit_noise_model`), the registry of :mod:`dashpot.physics.effects`;
# FLIGHT_PARAMETERS = EFFECT_PARAMETERS: unit and meaning of their parameters, by name.
FLIGHT_PARAMETERS = EFFECT_PARAMETERS
OUTLIER_Z = 4.0  # standardized innovations beyond this are flagged in the notes
# Floors of the fitted ln σ: below them a noise source is indistinguishable from none.
SIGMA_EPS_FLOOR, SIGMA_J_FLOOR = 1e-7, 1e-9
# Starts of (σ_ε, σ_j), all fitted at once; the best is kept.
NOISE_STARTS = ((3e-3, 1e-4), (3e-3, 1e-5), (1e-2, 3e-5))
STEP = 0.02  # finite-difference step in standard errors
NEWTON_ITERATIONS, PROFILE_ITERATIONS = 80, 40
CONVERGED = 1e-6  # in −2 ln L: a Newton step predicted to gain less than this ends the fit
FAR = 50.0  # −2 ln L this far above the best fit is outside every interval reported
SOFT_UNIT_MAX = 3.0  # largest unit of ln σ: a flat direction must not send the steps afar
# Profile grid, in standard errors of the profiled coordinate either side of the best fit.
PROFILE_OFFSETS = np.array([0.75, 1.5, 2.25, 3.0, 4.5])
# A law parameter's profile is continued outward in these stages (indices into
# PROFILE_OFFSETS): the points of a stage are fitted at once.
PROFILE_STAGES = ((0, 1, 2), (3, 4))
# Profile grids of a noise parameter at (or near) 0, where its curvature says nothing.
FLAT_GRIDS = {"sigma_eps": np.geomspace(1e-5, 0.1, 2 * PROFILE_OFFSETS.size),
              "sigma_j": np.geomspace(1e-7, 1e-2, 2 * PROFILE_OFFSETS.size)}
# Accuracy levels: spacing in ln u of the nodes of the tabulated step map (the exact level
# evaluates the law at every step instead).
GRID_LOG_STEPS = {"fast": 1.0 / 8.0, "standard": 1.0 / 32.0}
# The grid spans the speeds the data imply (g·interval/2) widened by these factors; a filter
# that leaves it is evaluated directly.
GRID_BELOW, GRID_ABOVE = 1.0 / 16.0, 4.0
# A level is accurate enough where, at the best fit, its −2 ln L is within this of the direct
# evaluation's and its predicted times within this fraction of the smallest timing σ.
LEVEL_LIKELIHOOD_TOLERANCE, LEVEL_TIMING_TOLERANCE = 0.01, 0.01
# Steps a tabulated filter row may have evaluated directly (where the table cannot give them)
# before the whole row is.
PATCHES = 8
FILTER_FIELDS = ("neg2_log_likelihood", "innovations", "innovation_variance", "predicted_times",
                 "predicted_speeds", "filtered_speeds", "scored")
