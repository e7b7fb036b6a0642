"""Fit the damping β and stiffness k of a linear spring-dashpot contact to a bounce train.

For each contact model the impact times of a scene are fitted with lmfit (Levenberg–Marquardt,
MINPACK) by the predicted train: parameters ζ and the characteristic speed v* = g/ω0 (in which
the misfit valley is nearly straight), the first impact speed v0 and the time t0 of the first
impact. Quantities the scene knows are fixed, or enter as a Gaussian prior when the scene gives
their uncertainty. Residuals are the impact-time misfits divided by their 1σ uncertainties,
plus the measured impact and rebound speeds where the sensor gives them (motion sensors,
photogates). The numerical accuracy of the predicted trains is a level (fast and standard
certified surrogates, or exact) chosen per scene or derived from its timing noise.

Start values come from the data (the interval ratios give ε and so ζ; the first interval or the
drop height gives v0; fits at fixed ω0 over a grid, batched, pick the stiffness), so fits need
no hand tuning. A fit that fails is returned with ``success=False`` and the reason; it never
raises for bad data and never returns NaN parameters as if they were results.

Modules, one concept each (``settings`` and ``results`` at the bottom: they import none of the
others):

=========================  ===================================================================
``settings``               constants shared by the others (coordinates, quantiles, levels, ...)
``results``                FitData, Estimate, FitResult, SceneFit
``data``                   :func:`prepare_data`
``trains``                 predicted trains of a model for many parameter sets at once
``residuals``              the likelihood: normalized residuals of times, speeds and priors
``accuracy``               :func:`choose_accuracy`: the accuracy levels and their train solvers
``start``                  start values from the data
``levenberg_marquardt``    the fast level's batched optimizer (the others use lmfit's leastsq)
``covariance``             intervals from the covariance (Gaussian and seeded draws), its
                           scaling under a misfit, linear error propagation
``profile_likelihood``     intervals of β from the profile likelihood
``posterior``              intervals of β from emcee's posterior samples
``uncertainty``            the registry of β's interval methods beyond the covariance
``identifiability``        notes where the data do not determine a parameter
``model_fit``              :func:`fit_model`: one model fitted to one scene
``scene_fit``              :func:`fit_scene`: every model fitted, and the selection table
``joint_fit``              :func:`fit_runs`: each run of a multi-run table fitted on its own,
                           and :func:`fit_joint`: the runs fitted at once sharing ζ and ω0
``noise_settings``         the noise fits' constants (at the bottom, as ``settings``)
``noise_results``          NoiseFitResult, and the result of a noise fit that failed
``noise_likelihood``       a noise fit's parameter layout and −2 ln L of many parameter sets
                           at once (the law enters only through its registry spec)
``newton``                 the noise fits' batched damped Newton optimizer
``noise_fit``              a law or model fitted under bounce-to-bounce scatter and timing
                           jitter (:mod:`dashpot.likelihood`): starts, σ_ε, profiles, results
``noise_scene``            the law ladder and the models fitted under the noise model, for
                           ``fit_scene(..., noise=True)`` (selection in
                           :mod:`dashpot.noise_selection`)
``prediction``             :func:`prediction_band`: a noise fit to the start of a train, the
                           rest against its 95 % prediction band (out-of-sample check)
=========================  ===================================================================

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface"
   (the models and the recursive use of each model on experimental data).
.. [2] M. Newville et al., LMFIT: Non-Linear Least-Squares Minimization and Curve-Fitting for
   Python, Zenodo, doi:10.5281/zenodo.598352.
.. [3] K. P. Burnham and D. R. Anderson, *Model Selection and Multimodel Inference*, 2nd ed.,
   Springer (2002), sec. 2.2 (AIC with known variance: χ² + 2K) and 2.9 (Akaike weights).
.. [4] P. R. Bevington and D. K. Robinson, *Data Reduction and Error Analysis for the Physical
   Sciences*, 3rd ed. (2003), sec. 3.2 (propagation of errors).
.. [5] W. H. Press et al., *Numerical Recipes*, 3rd ed., Cambridge (2007), sec. 15.6
   (confidence regions from Δχ² = 1 and 4 for one parameter).
.. [6] D. Foreman-Mackey et al., "emcee: The MCMC Hammer", PASP 125, 306 (2013).
.. [7] D. W. Marquardt, "An algorithm for least-squares estimation of nonlinear parameters",
   J. SIAM 11, 431 (1963).
.. [8] H. B. Nielsen, "Damping parameter in Marquardt's method", IMM-REP-1999-05, Technical
   University of Denmark (1999).
.. [9] C. J. F. ter Braak and J. A. Vrugt, "Differential Evolution Markov Chain with snooker
   updater and fewer chains", Statistics and Computing 18, 435 (2008).
"""

from __future__ import annotations

from .accuracy import choose_accuracy
from .data import prepare_data
from .joint_fit import JointFit, RunsFit, fit_joint, fit_runs, split_runs
from .levenberg_marquardt import _levenberg_marquardt  # noqa: F401 (used by the tests)
from .model_fit import fit_model
from .noise_fit import NoiseFitResult, fit_noise_model, fit_noise_models  # noqa: F401
from .prediction import PredictionCheck, prediction_band  # noqa: F401
from .results import Estimate, FitData, FitResult, SceneFit
from .scene_fit import fit_scene
from .settings import (ACCURACY_LEVELS, FAST_STEP_SE, PARAMETERS,  # noqa: F401
                       QUANTILES, UNCERTAINTY_METHODS)

__all__ = ["FitData", "FitResult", "Estimate", "prepare_data", "fit_model", "fit_scene",
           "SceneFit", "choose_accuracy", "ACCURACY_LEVELS", "UNCERTAINTY_METHODS", "JointFit",
           "RunsFit", "fit_joint", "fit_runs", "split_runs"]
