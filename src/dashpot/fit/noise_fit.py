"""A restitution law or dashpot model fitted under the two-source noise model: bounce-to-bounce
scatter σ_ε of the rebound speeds and timing noise on each impact.

The likelihood is that of :class:`dashpot.likelihood.TrainModel` (an extended Kalman filter over
impact time and speed), with the start time integrated out. Fitted, for one law of
:data:`dashpot.physics.laws.LAWS`:

=============  =========================================================  =================
parameter      meaning                                                    fitted as
=============  =========================================================  =================
law's own      e (constant ε), ζ and v* = g/ω0 (dashpot models), ...      itself
``v0``         speed of the first impact in m/s                           itself
``sigma_eps``  σ_ε, relative 1σ scatter of each rebound speed             ln σ_ε; and = 0
``sigma_j``    σ_j in s, timing jitter added in quadrature to the         ln σ_j
               detector's σ_i: timing variance σ_i² + σ_j²
=============  =========================================================  =================

Timing noise: a jitter, not a scale on σ_i. It works where the detector gives no uncertainty
(σ_i = 0: σ_j is then the whole timing noise) as where it does (σ_j is what the detector did
not report), and σ_j = 0 is the detector taken at its word.

Known quantities of the scene enter as in :func:`dashpot.fit.fit_model`: a first impact speed
(or drop height) fixes v0, or is a Gaussian prior where the scene gives its uncertainty; a
stiffness with a mass fixes or gives a prior on v* of the dashpot models. Priors add
((p − c)/sd)² to −2 ln L. Where the scene models air drag (mass and diameter) the flight is the
drag flight at the scene's g_eff and the drag constant ``k_d`` (1/m) is fitted with the scene's
Gaussian prior (C_d 0.45 ± 0.05 by default, :attr:`dashpot.scene.Scene.drag`; fixed where the
scene states C_d exactly). ``effects`` adds the flight's effects as parameters of their own
(:func:`dashpot.physics.flight.track_flight`): "drag" a free k_d ≥ 0 where the scene gives no
mass and diameter (degenerate then with a speed-dependent ε, which the notes say), "friction"
g_eff (the scene's prior) and a friction deceleration f with a_away = g_eff + f and
a_toward = g_eff − f. They are columns of the step map, tabulated with the law's parameters.

Accuracy: the law and flight are evaluated exactly at every step, or at "fast" and "standard"
from a tabulated step map; "auto" takes the cheapest level whose −2 ln L and predicted times
at the best fit are close enough to the direct evaluation's (:mod:`dashpot.fit.noise_likelihood`,
where the levels and their measured errors are described).

Optimizer. Every evaluation of the likelihood is a loop over the impacts with numpy over a
batch of parameter sets, so a thousand parameter sets cost about as much as one (3 ms for 40
impacts of a ladder law, 15 ms for a dashpot model at the exact level, about 1 ms for either
from a tabulated step map). lmfit's scalar minimizers evaluate one set
at a time (Nelder–Mead: hundreds to thousands of calls), so the minimization is a damped Newton
method with central-difference gradient and Hessian, all the stencil's points in one batch, and
several starts of the noise parameters at once (from one start a fit can stop where σ_t → 0,
on the flat part of the likelihood). Where noise parameters are held (``fixed``), one further
start takes the law's parameters and v0 from a fit with them released: with the noise held a
single start can slide to a bound (a dashpot model's v* to its gravity-free limit on a train
without scatter), where from broad noise down the fit finds them. lmfit Parameters carry the
names, bounds, values and errors of the result (``NoiseFitResult.params``), as in the other
fits. Coordinates are
rescaled every iteration to the current standard errors, so one step size fits laws whose
parameters differ by orders of magnitude; a law's parameter the data do not determine (no
curvature: v* near the gravity-free limit) is left out of the covariance and gets its
interval from its profile alone, followed out to its bounds. σ_ε is fitted as ln σ_ε, and
again with σ_ε = 0 exactly (the deterministic train, a fit of its own). Trains of several data
sets are fitted in one batch (:func:`fit_noise_models`), which is what makes coverage checks by
simulation cheap.

Noise estimates. The maximum-likelihood σ_ε is biased low with a few tens of impacts: the
fitted law and v0 take up part of the scatter (its random walk lies partly along what they
absorb), as the maximum-likelihood variance of a regression is low by the fitted parameters'
share; and the choice of σ_ε = 0 on the plain likelihood inherits that bias. σ_ε is estimated
where the adjusted profile −2 ln L_p(σ_ε) + ln det H_mm(σ_ε) is least, H_mm the Hessian of
−2 ln L in the law's (and the flight's) parameters and v0 that the data determine (not a v*
at its gravity-free limit), at their best fit given σ_ε (Cox and Reid [4]_; in a linear
Gaussian model this is the restricted likelihood, REML [5]_): among σ_ε = 0, the best fit's
σ_ε and the points of σ_ε's profile (below), the least refined by a parabola in ln σ_ε through
it and its neighbours. The law's parameters, v0 and σ_j are then
fitted with σ_ε held there, and those are the values reported (as a mixed model's fixed effects
at the REML variance). σ_ε = 0, the deterministic train (reported with a note), is chosen
where its adjusted value is the least or the least lies at σ_ε's floor. Without profile
intervals (``profile=False``) the choice is between σ_ε = 0 and the best fit alone, whose values
are then reported. ``neg2_log_likelihood`` and the criteria are those of the likelihood's
maximum (σ_ε at its maximum-likelihood value, or 0), as AIC and BIC are defined; the
innovations, χ² and predictions those of the reported parameters. Measured over the seeded
trains of tests/test_noise_coverage.py (σ_ε = 0.3 %): the mean fitted σ_ε lies 0.40 of its
spread below the truth on 15-impact trains of model Ib (0.92 on the maximum likelihood, which
put σ_ε at 0 in 9 of 40 trains, now in none), 0.51 at 25 impacts (0.87) and 0.03 on 40-impact
trains of the constant law (0.31); without scatter σ_ε is 0 in 49 of 60 trains of the
constant law (60 of 60 on the plain likelihood), and in none of 40 of model Ib's (40 of 40),
whose adjusted profile is least a little above 0 (1e-5 to 2e-4 in the ten looked at).

Intervals. 68.27 % and 95.45 % intervals of the law's parameters, σ_ε and σ_j are those of
the profile likelihood (−2 ln L minimized over the others rises by 1 and 4) [2]_, found on a
grid of fixed values (a law's parameters continued outward from the best fit, for the curved
valleys of the dashpot models' ζ and v*) and interpolated in the signed root of the rise, which
is linear where the profile is parabolic. σ_ε's profile is the adjusted one above, from its
own minimum: the plain profile's intervals of a variance parameter run short with a few tens
of impacts (62 % and 92 % coverage at 40 impacts; 75 % and 96 % adjusted, over 100 trains).
Its lower bound is 0 where σ_ε = 0 is within the level, else where the signed root crosses the
level, interpolated linearly in σ_ε between σ_ε = 0 and the profile's lowest point if no grid
point below the estimate reaches it. The law's parameters and v0 take their spread at the
adjusted σ_ε: the rows of the covariance (2H⁻¹ at the best fit) of those are rescaled to the
variances of the fit with σ_ε held there, and the profile intervals of the law's parameters
(whose curvature is the best fit's, at the maximum-likelihood σ_ε) are rescaled about the
reported value by the ratio of the two spreads. v0 gets the Gaussian interval; the standard
errors of all come from this covariance (σ_ε's is half its 68 % interval; a noise parameter
at 0, its 68 % upper bound). Where σ_ε = 0 is chosen, the law's parameters and v0 keep the
deterministic train's curvature. (Integrating them over σ_ε's adjusted likelihood instead, a
flat prior on σ_ε, was measured: it made the 68 % intervals of ε and v0 2.6 and 1.6 times
the spread of the estimates on trains without scatter, where the data cannot tell σ_ε = 0 from a
few 1e-5 and the conditional spreads grow fast with σ_ε; and with the adjusted choice σ_ε = 0
is not chosen on the 0.3 % trains above.) Derived ω0 = g/v* and β = ζω0 of the dashpot models
are carried by linear propagation. Measured coverage (68 %, 95 % intervals; mean 68 %
half-width over the spread of the estimates): ε at 40 impacts 70/100 and 95/100 (1.01); on
15-impact trains of model Ib v0 27/40 and 35/40 (1.04), β 24/40 and 35/40 (0.79), ζ and v*
0.87-0.93, where the maximum-likelihood σ_ε gave v0 19/40 and 30/40, β 18/40 and 31/40 and
widths 0.58-0.77.

Goodness of fit: the standardized innovations z_n = r_n/√S_n are independent N(0, 1) under the
model; ``chisqr`` is Σz² over the n scored innovations (the first impact anchors the train
and scores none; where the table carries measured speeds, their standardized innovations
count too, :mod:`dashpot.fit.noise_likelihood`) and ``redchi`` Σz²/(n − K_m), K_m the fitted
law's (and flight's) parameters and v0 the data determine: at the adjusted σ_ε, as at a
REML variance, Σz² ≈ n − K_m (at the maximum-likelihood noise it would be ≈ n). Measured
over the coverage test's trains: mean ``redchi`` 0.998 for 40 impacts of the constant law and
1.02 for 15 of model Ib (Σz²/n: 0.95 and 0.80). |z| > 4 are flagged in the notes by impact
and kept.
AIC = −2 ln L + 2K and BIC = −2 ln L + K ln n (n the scored times and speeds) with K the
fitted parameters (the integrated start time is not one); these are comparable between laws
under this noise model, not with the deterministic fit's χ²-based criteria.

References
----------
.. [1] J. Durbin and S. J. Koopman, *Time Series Analysis by State Space Methods*, 2nd ed.,
   Oxford University Press (2012), §7.3 (maximum likelihood of state-space models).
.. [2] W. H. Press et al., *Numerical Recipes*, 3rd ed., Cambridge (2007), sec. 15.6
   (confidence regions from Δχ² = 1 and 4 for one parameter).
.. [3] K. P. Burnham and D. R. Anderson, *Model Selection and Multimodel Inference*, 2nd ed.,
   Springer (2002), sec. 2.2 (AIC).
.. [4] D. R. Cox and N. Reid, "Parameter orthogonality and approximate conditional
   inference", J. R. Statist. Soc. B 49, 1-39 (1987) (the adjusted profile likelihood).
.. [5] H. D. Patterson and R. Thompson, "Recovery of inter-block information when block sizes
   are unequal", Biometrika 58, 545-554 (1971) (restricted maximum likelihood).
"""

from __future__ import annotations

import math

import lmfit
import numpy as np

from ..physics.laws import LAWS
from ..scene import Scene
from .newton import _newton, _pick, positive_definite
from .noise_likelihood import NoiseProblem
from .noise_results import NoiseFitResult, failed_noise_fit
from .noise_settings import (
    CONVERGED,
    FLAT_GRIDS,
    FLIGHT_EFFECTS,
    FLIGHT_PARAMETERS,
    GRID_LOG_STEPS,
    LEVEL_LIKELIHOOD_TOLERANCE,
    LEVEL_TIMING_TOLERANCE,
    NEWTON_ITERATIONS,
    NOISE_STARTS,
    OUTLIER_Z,
    PROFILE_ITERATIONS,
    PROFILE_OFFSETS,
    PROFILE_STAGES,
    SIGMA_EPS_FLOOR,
    SIGMA_J_FLOOR,
)
from .results import Estimate
from .settings import ACCURACY_LEVELS, Z68, Z95

__all__ = ["NoiseFitResult", "failed_noise_fit", "fit_noise_model", "fit_noise_models"]


def fit_noise_model(data, law, scene=None, *, fixed=None, profile=True, accuracy=None,
                    effects=()):
    """Fit one restitution law or dashpot model under the two-source noise model.

    Parameters
    ----------
    data : FitData
        From :func:`dashpot.fit.prepare_data`.
    law : str
        A key of :data:`dashpot.physics.laws.LAWS` ("constant", ..., "Ia", ..., "hybrid").
    scene : Scene, optional
        Known quantities (fixed or priors) and air drag; default: nothing known.
    fixed : dict, optional
        Parameters held at given values in natural units, e.g. ``{"sigma_eps": 0.0}`` (the
        deterministic train) or ``{"sigma_j": 0.0}`` (the detector's σ taken at its word).
    profile : bool, default True
        Profile-likelihood intervals of the law's parameters and σ_ε (else the Hessian's).
    accuracy : {"auto", "fast", "standard", "exact"}, optional
        How the law and flight are evaluated in the filter
        (:mod:`dashpot.fit.noise_likelihood`, *Accuracy*);
        default the scene's (``Scene.accuracy``, itself "auto" by default), as in
        :func:`dashpot.fit.fit_model`:
        "exact" at every step, "fast" and "standard" from a table of the step map with
        nodes 1/8 and 1/32 apart in ln u; "auto" takes the cheapest level whose −2 ln L at
        the best fit is within 0.01 of the direct evaluation's and whose predicted times are
        within 1 % of the smallest timing σ (else it refits at the next level).
    effects : sequence of {"drag", "friction"}, default ()
        Flight effects fitted beyond the scene's own: "drag" a free drag constant k_d ≥ 0
        (1/m) where the scene gives no mass and diameter (with them k_d is always fitted,
        with the scene's C_d prior: :attr:`dashpot.scene.Scene.drag`); "friction" the flight's
        two accelerations a_away = g_eff + f and a_toward = g_eff − f (``g_eff`` with the
        scene's prior, :attr:`dashpot.scene.Scene.flight_acceleration`; ``friction`` f ≥ 0),
        the model of :func:`dashpot.fit.fit_model`. The result's ``model`` is then the law's
        name with "+drag", "+friction" appended.

    Returns
    -------
    NoiseFitResult
        ``estimates`` holds the law's parameters, the flight's (``k_d``, ``g_eff``,
        ``friction``) where fitted, ``v0`` (m/s), ``sigma_eps`` (1), ``sigma_j``
        (s), and for the dashpot models ``omega0`` (rad/s) and ``beta`` (1/s); see the module
        notes for the intervals, residuals and criteria. ``normalized_residuals`` are the
        standardized innovations (NaN for the first impact, which anchors the train).
        ``accuracy`` is the level used; ``error_bound`` the largest relative error of the
        tabulated step map (duration to the next impact and its speed) on the train's speeds
        at the best fit (0 at "exact"), ``numerical_tolerance`` that times the number of
        impacts; the notes give the differences to the direct evaluation at the best fit.

    Raises
    ------
    ValueError
        Unknown law, a fixed parameter the law does not have, or a negative fixed σ.
    """
    return fit_noise_models([data], law, scene, fixed=fixed, profile=profile,
                            accuracy=accuracy, effects=effects)[0]


def fit_noise_models(datasets, law, scene=None, *, fixed=None, profile=True, accuracy=None,
                     effects=()):
    """Fit one law to each of several data sets of one scene, all in one batch.

    Parameters
    ----------
    datasets : sequence of FitData
        Trains of the same scene (the same g); each is fitted on its own.
    law, scene, fixed, profile, accuracy, effects
        As in :func:`fit_noise_model`. With "auto" the batch is refitted at the next level
        if any of its trains needs it.

    Returns
    -------
    list of NoiseFitResult
        One per data set, in order.
    """
    if law not in LAWS:
        raise ValueError(f"law must be one of {', '.join(map(repr, LAWS))}; got {law!r}")
    scene = scene or Scene()
    accuracy = accuracy or getattr(scene, "accuracy", "auto")
    if accuracy not in ("auto", *ACCURACY_LEVELS):
        raise ValueError(f"accuracy must be auto, {', '.join(ACCURACY_LEVELS)}; got "
                         f"{accuracy!r}")
    datasets = list(datasets)
    if not datasets:
        return []
    effects = tuple(dict.fromkeys(effects))
    unknown = [e for e in effects if e not in FLIGHT_EFFECTS]
    if unknown:
        raise ValueError(f"unknown flight effect {unknown[0]!r}; use "
                         f"{', '.join(FLIGHT_EFFECTS)}")
    fixed = dict(fixed or {})
    levels = ACCURACY_LEVELS if accuracy == "auto" else (accuracy,)
    missed = []
    for level in levels:
        problem = _Problem(datasets, law, scene, fixed, level, effects)
        results = problem.solve(profile)
        if accuracy != "auto" or all(problem.accurate.values()):
            break
        missed.append(level)
    if accuracy == "auto":
        for result in results:
            result.notes.append(f"accuracy auto: {result.accuracy or 'none'}" + (
                f" ({', '.join(missed)} not within the tolerances)" if missed else
                " (within the tolerances)"))
    return results


class _Problem(NoiseProblem):
    """The fit of one law to a batch of trains: the optimizer's starts, σ_ε's adjusted choice,
    the profiles, intervals and the results (the layout and objective are
    :class:`dashpot.fit.noise_likelihood.NoiseProblem`'s)."""

    # --- the fit ----------------------------------------------------------------------------

    def solve(self, profile):
        trains = np.arange(len(self.datasets))
        base = self.starts()
        i_eps, i_j = self.index("sigma_eps"), self.index("sigma_j")
        # Every train from every start of the noise parameters (those not fixed), in one
        # batch.
        noise_starts = sorted({tuple(value for i, value in zip((i_eps, i_j), pair)
                                     if self.names[i] not in self.fixed)
                               for pair in NOISE_STARTS})
        starts = np.repeat(base[:, None, :], len(noise_starts), axis=1)
        varied_noise = [i for i in (i_eps, i_j) if self.names[i] not in self.fixed]
        for k, values in enumerate(noise_starts):
            for i, value in zip(varied_noise, values):
                starts[:, k, i] = math.log(value)
        free = self.free()
        held = [i for i in (i_eps, i_j) if self.names[i] in self.fixed]
        if held:
            starts = np.concatenate([starts, self.released_starts(base, held, trains)[:, None]],
                                    axis=1)
        starts[..., free] = np.clip(starts[..., free], self.step_lower[free],
                                    self.step_upper[free])
        fits = _newton(self.objective, starts, free, self.units(starts)[..., free], trains,
                       self.step_lower, self.step_upper, NEWTON_ITERATIONS, soft=self.soft)
        best = _pick(fits, trains, np.argmin(fits.value, axis=1))
        # The law's parameters the data do not determine at the best fit (no curvature, or
        # at a bound), per train: left out of the adjustment of σ_ε's profile.
        self.undetermined = [set(self.covariance(best.hessian[t], best.params[t], free)[2])
                             for t in range(trains.size)]
        # The deterministic train (σ_ε = 0 exactly), started from the best fit.
        zero = None
        if "sigma_eps" not in self.fixed:
            start = best.params.copy()
            start[:, i_eps] = -math.inf
            columns = [free.index(f) for f in free if f != i_eps]
            zero = _newton(self.objective, start[:, None, :], self.free("sigma_eps"),
                           best.units[:, None, columns], trains, self.step_lower,
                           self.step_upper, NEWTON_ITERATIONS, reference=best.value,
                           soft=self.soft)
            zero = _pick(zero, trains, np.zeros(trains.size, int))
        self.eps_points = None
        profiles = self.profiles(best, zero, trains) if profile else {}
        chosen, spent = self.adjusted_choice(best, zero, trains)
        # Likelihood evaluations per train (each batch row is one).
        evaluations = (fits.evaluations + (zero.evaluations if zero is not None else 0)
                       + spent + sum(p[2] for p in profiles.values())) // trains.size
        return [self.result(t, best, zero, chosen, profiles, evaluations) for t in trains]

    def adjusted_choice(self, best, zero, trains):
        """σ_ε of each train where the adjusted profile −2 ln L + ln det H_mm is least (module
        notes, *Noise estimates*), and the law's parameters, v0 and σ_j fitted there.

        The candidates are σ_ε = 0 (the deterministic train), the best fit and the points of
        σ_ε's profile (where it was computed); the least of these with its neighbours on the
        profile is refined by a parabola in ln σ_ε, and the others are fitted again with σ_ε
        held there. A σ_ε at its floor (SIGMA_EPS_FLOOR) is σ_ε = 0. Without profiles the
        choice is between σ_ε = 0 and the best fit.

        Returns
        -------
        chosen : list of dict
            Per train: ``params`` (the reported row), ``at_zero`` (σ_ε = 0 chosen) and, where
            fitted again, ``refit``: (−2 ln L, its Hessian in the free columns but σ_ε).
        evaluations : int
            Likelihood evaluations of the refits.
        """
        count = trains.size
        free = self.free()
        i_eps = self.index("sigma_eps")
        chosen = [dict(params=best.params[t].copy(), at_zero=False) for t in range(count)]
        if zero is None:
            return chosen, 0
        zero_free = [f for f in free if f != i_eps]
        with np.errstate(invalid="ignore"):
            a_best = best.value + self._mean_log_det(best.hessian, free)
            a_zero = zero.value + self._mean_log_det(zero.hessian, zero_free)
        a_best = np.where(np.isfinite(a_best), a_best, np.inf)
        a_zero = np.where(np.isfinite(a_zero), a_zero, np.inf)
        # Where no adjusted value is finite (no positive-definite Hessian block), the plain
        # likelihood decides.
        plain_zero = zero.value <= best.value + 10 * CONVERGED
        points = self.eps_points
        refit_rows, refit_starts = [], []
        for t in range(count):
            xs = np.array([best.params[t, i_eps]])
            values, rows = np.array([a_best[t]]), best.params[t][None]
            if points is not None:
                xs = np.concatenate([points["grid"][t], xs])
                values = np.concatenate([points["adjusted"][t], values])
                rows = np.concatenate([points["fitted"].params[t], rows])
            usable = np.isfinite(values) & np.isfinite(xs)
            order = np.argsort(xs[usable])
            xs, values, rows = xs[usable][order], values[usable][order], rows[usable][order]
            lowest, where = math.inf, None
            if xs.size:
                k = int(np.argmin(values))
                lowest, where, row = values[k], xs[k], rows[k]
                if 0 < k < xs.size - 1 and np.all(np.diff(xs[k - 1:k + 2]) > 0):
                    # The vertex of the parabola through the least point and its neighbours,
                    # kept between them; the refit starts from the others interpolated
                    # quadratically between their three fits, near where it ends.
                    near = slice(k - 1, k + 2)
                    a, b, _ = np.polyfit(xs[near] - xs[k], values[near], 2)
                    if a > 0:
                        where = float(np.clip(xs[k] - b / (2.0 * a), xs[k - 1], xs[k + 1]))
                        row = _lagrange_weights(xs[near], where) @ rows[near]
            at_zero = (a_zero[t] <= lowest + 10 * CONVERGED
                       if math.isfinite(a_zero[t]) or math.isfinite(lowest)
                       else bool(plain_zero[t]))
            at_zero = at_zero or (where is not None and where <= math.log(SIGMA_EPS_FLOOR) + 1.0)
            if at_zero:
                chosen[t].update(params=zero.params[t].copy(), at_zero=True)
            elif points is not None and where is not None:
                start = row.copy()
                start[i_eps] = where
                refit_rows.append(t)
                refit_starts.append(start)
        if not refit_rows:
            return chosen, 0
        index = np.array(refit_rows)
        columns = [free.index(f) for f in zero_free]
        refit = _newton(self.objective, np.array(refit_starts)[:, None, :], zero_free,
                        best.units[index][:, None, columns], trains[index], self.step_lower,
                        self.step_upper, NEWTON_ITERATIONS, soft=self.soft)
        for k, t in enumerate(refit_rows):
            if np.isfinite(refit.value[k, 0]):
                chosen[t]["params"] = refit.params[k, 0].copy()
                chosen[t]["refit"] = (float(refit.value[k, 0]), refit.hessian[k, 0])
        return chosen, refit.evaluations

    def released_starts(self, base, held, trains):
        """A further start (trains, P) for a fit whose noise parameters `held` are held: the
        law's parameters and v0 of a fit with those released (from NOISE_STARTS), the held
        values put back. With the noise held, a single start may slide to a bound (a dashpot
        model's v* to its gravity-free limit on a train without scatter, where its start
        values are far off); with the noise free the fit follows the likelihood from broad
        noise, where the law's parameters are found, down to the noise of the data."""
        starts = np.repeat(base[:, None, :], len(NOISE_STARTS), axis=1)
        for k, pair in enumerate(NOISE_STARTS):
            starts[:, k, [self.index("sigma_eps"), self.index("sigma_j")]] = np.log(pair)
        free = sorted(self.free() + held)
        starts[..., free] = np.clip(starts[..., free], self.step_lower[free],
                                    self.step_upper[free])
        fits = _newton(self.objective, starts, free, self.units(starts)[..., free], trains,
                       self.step_lower, self.step_upper, NEWTON_ITERATIONS, soft=self.soft)
        released = _pick(fits, trains, np.argmin(fits.value, axis=1)).params
        released[:, held] = base[:, held]
        return released

    def profiled_names(self):
        return [n for n in self.law.parameter_names + tuple(self.flight_start)
                + ("sigma_eps", "sigma_j") if n not in self.fixed]

    def profiles(self, best, zero, trains):
        """Profile −2 ln L of each profiled parameter on a grid around each train's best fit.

        Returns
        -------
        dict
            {name: (grid (trains, points) in the fitted coordinate, rise (trains, points),
            likelihood evaluations, the profile's minimum (trains,), the rise at σ_ε = 0
            (trains,) or None)}.
        """
        out = {}
        free = self.free()
        covariance = np.stack([self.covariance(best.hessian[t], best.params[t], free)[0]
                               for t in range(trains.size)])
        for name in self.profiled_names():
            i = self.index(name)
            k = free.index(i)
            sd = np.sqrt(np.maximum(covariance[:, k, k], 0.0))
            centre = best.params[:, i]
            offsets = np.concatenate([-PROFILE_OFFSETS[::-1], PROFILE_OFFSETS])
            with np.errstate(invalid="ignore"):
                grid = centre[:, None] + offsets[None, :] * sd[:, None]
            undetermined = ~np.isfinite(sd)
            if undetermined.any() and name not in ("sigma_eps", "sigma_j"):
                # No curvature: the profile is followed out to the law's bounds.
                grid[undetermined] = _span(centre[undetermined], self.lower[i],
                                           self.upper[i], PROFILE_OFFSETS.size)
            if name in ("sigma_eps", "sigma_j"):
                # At (or near) σ = 0 the curvature in ln σ says nothing: a fixed grid.
                floor = SIGMA_EPS_FLOOR if name == "sigma_eps" else SIGMA_J_FLOOR
                flat = ~(sd > 0) | ~np.isfinite(sd) | (sd > 3.0) | (
                    centre <= math.log(floor) + 1.0)
                if name == "sigma_eps" and zero is not None:
                    flat |= zero.value <= best.value + 10 * CONVERGED
                grid[flat] = np.log(FLAT_GRIDS[name])
            grid = np.clip(grid, self.lower[i], self.upper[i])
            others = [f for f in free if f != i]
            units = best.units[:, [free.index(f) for f in others]]
            # The others start at their conditional optimum given the fit's covariance,
            # Δothers = Σ_oi/Σ_ii·Δp, and after that along the path found so far.
            with np.errstate(invalid="ignore", divide="ignore"):
                slope = covariance[:, [free.index(f) for f in others], k] / covariance[
                    :, k, k, None]
            slope = np.where(np.isfinite(slope), slope, 0.0)
            if name in ("sigma_eps", "sigma_j"):
                # The noise parameters' profiles are smooth: every point at once.
                fitted = self._profile_points(best.params[:, None, :], grid, i, others,
                                              slope[:, None, :],
                                              units, trains, best.value)
                values, evaluations = fitted.value, fitted.evaluations
            else:
                # A law's parameters may lie in a curved valley (ζ and v* of a dashpot model
                # near the gravity-free limit): continued outward from the best fit, both
                # sides at once, in stages (PROFILE_STAGES), the points of a stage started
                # from the outermost point of the one before, along the path found there.
                size = PROFILE_OFFSETS.size
                values = np.full(grid.shape, np.inf)
                previous = np.repeat(best.params[:, None, :], 2, axis=1)
                path = np.repeat(slope[:, None, :], 2, axis=1)
                evaluations = 0
                for stage in PROFILE_STAGES:
                    count = len(stage)
                    columns = [size - 1 - k for k in stage] + [size + k for k in stage]
                    fitted = self._profile_points(
                        np.repeat(previous, count, axis=1), grid[:, columns], i, others,
                        np.repeat(path, count, axis=1), units, trains, best.value)
                    values[:, columns] = fitted.value
                    evaluations += fitted.evaluations
                    outer = [count - 1, 2 * count - 1]
                    with np.errstate(invalid="ignore", divide="ignore"):
                        moved = (fitted.params[:, outer][..., others] - previous[..., others]) / (
                            grid[:, [columns[k] for k in outer]] - previous[..., i])[..., None]
                    path = np.where(np.isfinite(moved), moved, path)
                    previous = fitted.params[:, outer]
            reference = best.value if zero is None or name != "sigma_eps" else np.minimum(
                best.value, zero.value)
            rise, centre, zero_rise = values - reference[:, None], best.params[:, i], None
            if name == "sigma_eps":
                rise, centre, zero_rise = self._adjusted(best, zero, fitted, grid, others)
                self.eps_points = dict(grid=grid, fitted=fitted, adjusted=(
                    fitted.value + self._mean_log_det(fitted.hessian, others)))
            out[name] = (grid, rise, evaluations, centre, zero_rise)
        return out

    def _mean_log_det(self, hessian, free):
        """ln det of the Hessian block (trains, ...) of the law's parameters and v0 the data
        determine in each train (``undetermined`` left out: its curvature is noise), NaN
        where not positive definite; natural coordinates."""
        out = np.full(hessian.shape[:-2], np.nan)
        for t in range(hessian.shape[0]):
            mean = [k for k, f in enumerate(free) if f <= self.index("v0")
                    and f not in self.undetermined[t]]
            sign, value = np.linalg.slogdet(np.nan_to_num(
                hessian[t][..., mean, :][..., mean], nan=0.0))
            out[t] = np.where(sign > 0, value, np.nan)
        return out

    def _adjusted(self, best, zero, fitted, grid, others):
        """Rise of σ_ε's profile adjusted for the fitted law and v0 (Cox and Reid [4]_):
        −2 ln L + ln det H_mm, H_mm the Hessian of those mean parameters at each point. The
        maximum-likelihood σ_ε is biased low by about K/n (the law's and v0's errors are taken
        out of the scatter); the adjustment removes most of that bias, and the intervals are
        where the adjusted profile rises by 1 and 4 from its own minimum.

        Returns the rise (trains, points), the adjusted profile's minimum (ln σ_ε, −inf at
        σ_ε = 0) and the rise at σ_ε = 0 (trains,)."""
        free = self.free()
        points = fitted.value + self._mean_log_det(fitted.hessian, others)
        candidates = [best.value + self._mean_log_det(best.hessian, free)]
        where = [best.params[:, self.index("sigma_eps")]]
        if zero is not None:
            zero_free = [f for f in free if f != self.index("sigma_eps")]
            candidates.append(zero.value + self._mean_log_det(zero.hessian, zero_free))
            where.append(np.full(grid.shape[0], -math.inf))
        candidates = np.column_stack(candidates + [points])
        where = np.column_stack(where + [grid])
        finite = np.where(np.isfinite(candidates), candidates, np.inf)
        lowest = np.argmin(finite, axis=1)
        rows = np.arange(grid.shape[0])
        minimum = finite[rows, lowest]
        zero_rise = (candidates[:, 1] - minimum if zero is not None
                     else np.full(grid.shape[0], np.inf))
        return points - minimum[:, None], where[rows, lowest], np.nan_to_num(zero_rise,
                                                                             nan=np.inf)

    def _profile_points(self, previous, targets, i, others, path, units, trains, reference):
        """Fits with parameter i held at `targets` (trains, points), the others started from
        `previous` (trains, points or 1, P) moved along `path` (∂others/∂p_i)."""
        start = np.array(np.broadcast_to(previous, targets.shape + previous.shape[-1:]))
        shift = targets - start[..., i]
        start[..., others] += path * shift[..., None]
        start[..., others] = np.clip(start[..., others], self.step_lower[others],
                                     self.step_upper[others])
        start[..., i] = targets
        return _newton(self.objective, start, others, units[:, None, :], trains,
                       self.step_lower, self.step_upper, PROFILE_ITERATIONS,
                       reference=reference, soft=self.soft)

    def result(self, t, best, zero, chosen, profiles, evaluations):
        data = self.datasets[t]
        notes = list(data.notes) + list(self.notes)
        notes.append("noise model: rebound scatter sigma_eps and timing jitter sigma_j added in "
                     "quadrature to the detector's uncertainty; start time integrated out")
        free = self.free()
        i_eps = self.index("sigma_eps")
        choice = chosen[t]
        params_row = choice["params"].copy()
        at_zero = choice["at_zero"]
        # The criteria's −2 ln L: the likelihood's maximum (with σ_ε = 0 as a candidate).
        value = float(best.value[t]) if zero is None else float(min(best.value[t],
                                                                     zero.value[t]))
        # The covariance: the best fit's (σ_ε fitted; its rows of the law's parameters and v0
        # rescaled below), or the deterministic train's where σ_ε = 0 is chosen.
        fit, fit_free = best, free
        if at_zero:
            notes.append("sigma_eps at 0: the deterministic train suffices")
            fit, fit_free = zero, [f for f in free if f != i_eps]
        if not np.isfinite(value):
            return self.failed(t, "fit failed: no finite likelihood from any start", notes)
        # The filter at the best fit, evaluated directly: innovations, predictions; and how
        # far the level's filter is from it there.
        relative, likelihood, timing, run = self.level_errors(params_row, t)
        timing_floor = float(np.min(np.sqrt(self.detector[t, data.index] ** 2
                                            + math.exp(2.0 * params_row[self.index("sigma_j")]))))
        self.accurate[t] = (likelihood <= LEVEL_LIKELIHOOD_TOLERANCE
                            and timing <= LEVEL_TIMING_TOLERANCE * timing_floor)
        if self.level == "exact":
            notes.append("accuracy exact: the law and flight evaluated at every step")
        elif self.has_speeds:
            notes.append(
                f"accuracy {self.level}: with measured speeds the law and flight are evaluated "
                f"at every step" + ("" if self.law.contact is None else
                                    f" (the collisions from the {self.level} surrogate tables, "
                                    f"relative error {relative:.1e}; at the best fit -2 ln L "
                                    f"within {likelihood:.1e} of the exact collisions)"))
        else:
            notes.append(
                f"accuracy {self.level}: step map tabulated {1.0 / GRID_LOG_STEPS[self.level]:g} "
                f"nodes per e-fold of speed, relative error {relative:.1e}; at the best fit "
                f"-2 ln L within {likelihood:.1e} and predicted times within {timing:.1e} s "
                f"({timing / timing_floor:.1e} of the smallest timing sigma) of the direct "
                f"evaluation" + ("" if self.accurate[t] else " (more than the 0.01 allowed)"))
        observed = data.index
        z = run.standardized[0, observed]
        scored = run.scored[0, observed]
        innovations = run.innovations[0, observed]
        chisqr = float(np.sum(z[scored] ** 2))
        ndata = int(scored.sum())
        if self.has_speeds:
            # The measured speeds' standardized innovations count as data too.
            speed_z = run.speed_standardized[0, observed]
            speed_scored = run.speed_scored[0, observed]
            chisqr += float(np.sum(speed_z[speed_scored] ** 2))
            ndata += int(speed_scored.sum())
            far = np.argwhere(speed_scored & (np.abs(np.nan_to_num(speed_z)) > OUTLIER_Z))
            if far.size:
                notes.append(f"{far.shape[0]} speed innovation(s) with |z| > {OUTLIER_Z:g}: "
                             + ", ".join(f"{('impact', 'rebound')[k]} speed of impact {n}"
                                         for n, k in far)
                             + " (impacts counted from 0; kept in the fit)")
        # Degrees of freedom of Σz² at the adjusted σ_ε: n less the fitted mean parameters
        # the data determine (module notes, *Goodness of fit*).
        dof = max(ndata - sum(1 for f in fit_free if f <= self.index("v0")
                              and f not in self.undetermined[t]), 1)
        outliers = np.flatnonzero(scored & (np.abs(np.nan_to_num(z)) > OUTLIER_Z))
        if outliers.size:
            notes.append(f"{outliers.size} innovation(s) with |z| > {OUTLIER_Z:g} at impact(s) "
                         f"{', '.join(map(str, outliers))} (counted from 0; kept in the fit)")
        full, keep, dropped = self.covariance(fit.hessian[t], fit.params[t], fit_free)
        cov = full[np.ix_(keep, keep)]
        hessian_ok = bool(keep) or not fit_free
        for f in dropped:
            notes.append(f"{self.names[f]}: no curvature of the likelihood at the best fit (or "
                         f"at a bound), not determined by these data (its interval from the "
                         f"profile alone)")
        # The law's parameters and v0 at the adjusted σ_ε (module notes, *Intervals*): the
        # covariance's rows of those rescaled to their spread fitted with σ_ε held there, and
        # the law's profile intervals (whose curvature is the best fit's) widened by the
        # ratio of that spread to the best fit's.
        widen = {}
        scale = np.ones(len(keep))
        kept_columns = [fit_free[k] for k in keep]
        if "refit" in choice:
            zero_free = [f for f in free if f != i_eps]
            held, held_keep, _ = self.covariance(choice["refit"][1], params_row, zero_free)
            best_full, best_keep, _ = self.covariance(best.hessian[t], best.params[t], free)
            best_variance = {free[k]: best_full[k, k] for k in best_keep}
            for k in held_keep:
                f = zero_free[k]
                if f > self.index("v0"):
                    continue
                if f in kept_columns:
                    scale[kept_columns.index(f)] = math.sqrt(
                        held[k, k] / cov[kept_columns.index(f), kept_columns.index(f)])
                if best_variance.get(f, 0.0) > 0.0:
                    widen[f] = math.sqrt(held[k, k] / best_variance[f])
        eps_interval = None
        if "sigma_eps" in profiles:
            grid, rise, spent, _, zero_rise = profiles["sigma_eps"]
            centre = np.full(len(self.datasets), -math.inf if at_zero else params_row[i_eps])
            eps_interval = self.profile_interval("sigma_eps", t, (grid, rise, spent, centre,
                                                                  zero_rise), at_zero)
        cov = cov * np.outer(scale, scale)
        sd = np.sqrt(np.abs(np.diag(cov)))
        sd_of = {self.names[fit_free[k]]: float(s) for k, s in zip(keep, sd)}
        estimates = {}
        params = lmfit.Parameters()
        for i, name in enumerate(self.names):
            is_noise = name in ("sigma_eps", "sigma_j")
            value_i = float(np.exp(params_row[i]) if is_noise else params_row[i])
            unit = {"v0": "m/s", "sigma_j": "s", "sigma_eps": "1"}.get(
                name, (self.law.parameters[i].unit if i < len(self.law.parameters) else
                       FLIGHT_PARAMETERS.get(name, ("",))[0]) or "1")
            status = "fitted"
            if name in self.fixed:
                estimates[name] = Estimate(value_i, 0.0, value_i, value_i, value_i, value_i,
                                           unit, "fixed", "held at a given value")
            else:
                if any(p[0] == name for p in self.priors):
                    status = "prior"
                s = sd_of.get(name, math.inf)
                if is_noise:
                    # Gaussian in ln σ; the standard error by linear propagation.
                    low68, high68, low95, high95 = (0.0, math.inf, 0.0, math.inf)
                    if math.isfinite(s) and s < 50.0:
                        low68, high68, low95, high95 = (
                            value_i * math.exp(sign * z_ * s)
                            for z_, sign in ((Z68, -1), (Z68, 1), (Z95, -1), (Z95, 1)))
                    stderr = value_i * s
                    note = "Gaussian in ln sigma (Hessian)"
                else:
                    low68, high68 = value_i - Z68 * s, value_i + Z68 * s
                    low95, high95 = value_i - Z95 * s, value_i + Z95 * s
                    stderr, note = s, "Gaussian (Hessian)"
                if name in profiles:
                    low68, high68, low95, high95 = (
                        eps_interval if name == "sigma_eps" else self.profile_interval(
                            name, t, profiles[name], at_zero))
                    note = ("profile likelihood adjusted for the fitted law and v0 (Cox-Reid)"
                            if name == "sigma_eps" else "profile likelihood")
                    centre = best.params[t, i]
                    if not is_noise and (i in widen or value_i != centre):
                        # About the reported value (refitted at the adjusted σ_ε, where the
                        # profile was made about the maximum-likelihood fit): the plain
                        # profile's shape, the spread at the adjusted σ_ε where known.
                        # A bound at the range's end (the profile never reached the level
                        # there) stays at that end.
                        ratio = widen.get(i, 1.0)
                        low68, high68, low95, high95 = (
                            float(b) if not self.lower[i] < b < self.upper[i] else
                            float(np.clip(value_i + ratio * (b - centre), self.lower[i],
                                          self.upper[i]))
                            for b in (low68, high68, low95, high95))
                        note += (" rescaled to the spread at the adjusted sigma_eps"
                                 if i in widen else " moved to the value at the adjusted "
                                 "sigma_eps")
                if name == "sigma_eps" and at_zero:
                    value_i = 0.0
                if name == "sigma_eps" and eps_interval is not None and not at_zero:
                    # The adjusted profile's, as its interval.
                    stderr = 0.5 * (high68 - low68) / Z68
                elif is_noise and (name not in sd_of or (name == "sigma_eps" and at_zero)):
                    # At 0: no curvature; the 68 % upper bound stands for the error.
                    stderr = high68
                estimates[name] = Estimate(value_i, stderr, low68, high68, low95, high95, unit,
                                           status, note)
            lower = 0.0 if name in ("sigma_eps", "sigma_j") else self.lower[i]
            upper = math.exp(self.upper[i]) if name in ("sigma_eps", "sigma_j") else self.upper[i]
            params.add(name, value=estimates[name].value, min=lower, max=upper,
                       vary=name not in self.fixed)
            params[name].stderr = estimates[name].stderr
        kept = [fit_free[k] for k in keep]
        if self.law.derived is not None:
            self.derived(estimates, params_row, cov, kept)
        sigma_j = estimates["sigma_j"]
        if "sigma_j" not in self.fixed and params_row[self.index("sigma_j")] <= math.log(
                SIGMA_J_FLOOR) + 1.0:
            notes.append("sigma_j at 0: the detector's uncertainties account for the timing "
                         "noise")
        # The correlation matrix is that of `varied`: the fitted parameters not at a floor;
        # K counts every fitted one (a noise parameter fitted to 0 was fitted all the same).
        varied = tuple(self.names[f] for f in kept)
        with np.errstate(invalid="ignore", divide="ignore"):
            correlation = cov / np.outer(sd, sd)
        nvarys = len(free)
        law = self.law(np.maximum(run.filtered_speeds[0], 0.0), *params_row[:len(
            self.law.parameters)])
        speeds = run.filtered_speeds[0]
        top = float(np.nanmax(speeds))
        bottom = float(np.nanmin(speeds[speeds > 0])) if np.any(speeds > 0) else top
        curve_speed = np.geomspace(bottom, top, 200) if top > bottom else np.array([top])
        curve = self.law(curve_speed, *params_row[:len(self.law.parameters)])
        contact = np.zeros(speeds.size)
        if self.law.contact is not None:
            contact = self.law.contact(np.maximum(speeds, 0.0),
                                       *params_row[:len(self.law.parameters)], g=self.g)[2]
        timing_sigma = np.sqrt(self.detector[t, observed] ** 2 + sigma_j.value ** 2)
        predicted_at = run.predicted_times[0, observed]
        # The first impact anchors the train: it predicts itself.
        predicted_at = np.where(scored, predicted_at, data.times)
        return NoiseFitResult(
            model=self.model_name, success=hessian_ok, message=(
                "converged" if hessian_ok else "no positive-definite Hessian at the best fit"),
            estimates=estimates, varied=varied,
            correlation=np.where(np.isfinite(correlation), correlation, np.nan), chisqr=chisqr,
            redchi=chisqr / dof, aic=value + 2 * nvarys,
            bic=value + nvarys * math.log(max(ndata, 1)), ndata=ndata, nvarys=nvarys,
            nfev=evaluations, time_residuals=np.where(scored, innovations, np.nan),
            normalized_residuals=np.where(scored, z, np.nan),
            predicted={"times": data.time_origin + run.predicted_times[0],
                       "speeds": speeds, "restitution": law.eps,
                       "contact_durations": contact, "at_data": data.time_origin + predicted_at},
            eps_curve={"speed": curve_speed, "eps": curve.eps, "captured": curve.eps <= 0.0},
            notes=notes, numerical_tolerance=relative * data.count, error_bound=relative,
            accuracy=self.level,
            intervals={"profile": {n: {"low68": estimates[n].low68,
                                       "high68": estimates[n].high68,
                                       "low95": estimates[n].low95,
                                       "high95": estimates[n].high95}
                                   for n in profiles}},
            neg2_log_likelihood=value, params=params, outliers=outliers,
            timing_sigma=timing_sigma)

    def covariance(self, hessian, row, free):
        """Covariance 2H⁻¹ of the parameters the data determine, from −2 ln L's Hessian in
        the `free` columns (natural coordinates) at parameter row `row`.

        A noise parameter at its floor has no curvature in ln σ; a law's parameter may have
        none where the data do not see it (v* of a dashpot model near the gravity-free
        limit). Those are left out, the least curved first (in units of its own value or
        step), until the rest has a positive-definite Hessian; their rows and columns are
        inf (their intervals come from their profiles). So is a law's parameter the fit left
        at one of its bounds (within the stencil's margin): the difference stencil there
        is squeezed to rounding size, and the curvature it measures is noise.

        Returns
        -------
        covariance : ndarray, shape (free, free)
        keep : list of int
            Positions in `free` of the parameters kept.
        dropped : list of int
            Columns (parameter indices) left out other than noise parameters at their floor.
        """
        floors = {self.index("sigma_eps"): SIGMA_EPS_FLOOR, self.index("sigma_j"): SIGMA_J_FLOOR}
        keep = [k for k, f in enumerate(free)
                if not (f in floors and row[f] <= math.log(floors[f]) + 1.0)]
        law_count = self.law_count
        dropped = [f for f in free if f < law_count and (
            row[f] - self.lower[f] <= 2.0 * (self.step_lower[f] - self.lower[f])
            or self.upper[f] - row[f] <= 2.0 * (self.upper[f] - self.step_upper[f]))]
        keep = [k for k in keep if free[k] not in dropped]
        # Curvature per squared unit of each parameter's own scale: comparable across them.
        scale = np.array([abs(row[f]) if f < self.index("sigma_eps") and row[f] != 0.0
                          else 1.0 for f in free])
        while keep:
            block = hessian[np.ix_(keep, keep)]
            if np.all(np.isfinite(block)) and positive_definite(block):
                break
            curvature = np.nan_to_num(np.diag(block) * scale[keep] ** 2, nan=-np.inf)
            dropped.append(free[keep.pop(int(np.argmin(curvature)))])
        covariance = np.full((len(free), len(free)), np.inf)
        if keep:
            covariance[np.ix_(keep, keep)] = 2.0 * np.linalg.inv(hessian[np.ix_(keep, keep)])
        return covariance, keep, dropped

    def profile_interval(self, name, t, profile, at_zero):
        """68.27 % and 95.45 % bounds from a profile: where the signed root of the rise
        crosses ±1 and ±2, interpolated linearly between grid points.

        σ_ε at 0 (`centre` −inf): the profile is scanned upward from σ_ε = 0, put at the
        grid's first point less one e-fold (1e-5/e: nothing distinguishes it from 0).
        """
        grid, rise, centre = profile[0][t], profile[1][t], float(profile[3][t])
        zero_rise = 0.0 if at_zero else (math.inf if profile[4] is None else profile[4][t])
        if not np.isfinite(centre):
            centre = float(np.min(grid)) - 1.0
        # Grid points the profile could not fit (non-finite) are left out.
        usable = np.isfinite(rise)
        grid, rise = grid[usable], rise[usable]
        order = np.argsort(grid)
        grid, rise = grid[order], np.maximum(rise[order], 0.0)
        root = np.sign(grid - centre) * np.sqrt(rise)
        below, above = grid < centre, grid > centre
        bounds = []
        for level in (1.0, 2.0):
            for side, mask in ((-1, below), (1, above)):
                xs = np.concatenate([grid[mask], [centre]]) if side < 0 else np.concatenate(
                    [[centre], grid[mask]])
                rs = np.concatenate([root[mask], [0.0]]) if side < 0 else np.concatenate(
                    [[0.0], root[mask]])
                bounds.append(_crossing(xs, rs, side * level, side))
        low68, low95 = bounds[0], bounds[2]
        high68, high95 = bounds[1], bounds[3]
        if name in ("sigma_eps", "sigma_j"):
            # No crossing below: the interval reaches down to 0 (within the floor).
            low68, high68, low95, high95 = (math.exp(b) if math.isfinite(b) else (
                0.0 if b < 0 else math.inf) for b in (low68, high68, low95, high95))
            if name == "sigma_j":
                return low68, high68, low95, high95
            # σ_ε = 0 is inside an interval where the deterministic train is within its level;
            # where it is not and the grid's points below the centre never reach the level,
            # the bound lies between σ_ε = 0 and the lowest of them (or the centre): the
            # signed root interpolated linearly in σ_ε there.
            lowest = grid[below]
            x_low, r_low = ((math.exp(lowest[0]), root[below][0]) if lowest.size
                            else (math.exp(centre), 0.0))
            out = []
            for bound, level in ((low68, 1.0), (low95, 2.0)):
                if zero_rise < level ** 2:
                    bound = 0.0
                elif bound == 0.0 and math.isfinite(zero_rise):
                    zero_root = -math.sqrt(zero_rise)
                    bound = x_low * (-level - zero_root) / (r_low - zero_root)
                out.append(bound)
            return out[0], high68, out[1], high95
        lower, upper = self.lower[self.index(name)], self.upper[self.index(name)]
        return tuple(float(np.clip(b, lower, upper)) for b in (low68, high68, low95, high95))

    def derived(self, estimates, row, cov, kept):
        """The law's derived quantities (:attr:`RestitutionLaw.derived`: ω0 = g/v* and β = ζω0
        of a dashpot model).

        A quantity mapped from a parameter's interval (ω0 from v*'s: a monotone map keeps a
        profile likelihood's intervals) takes those bounds; the others are Gaussian, clipped at
        their physical lower bound. Standard errors by linear propagation from the covariance
        of the determined parameters `kept`; a fitted parameter it depends on that the data do
        not determine makes it inf (a propagated interval then [lower bound, inf]).
        """
        values = dict(zip(self.law.parameter_names, row[:len(self.law.parameters)]))
        for quantity in self.law.derived(values, self.g):
            depends = [self.index(name) for name in quantity.gradient]
            undetermined = [i for i in depends if self.names[i] not in self.fixed
                            and i not in kept]
            gradient = np.zeros(len(kept))
            for i, slope in zip(depends, quantity.gradient.values()):
                if i in kept:
                    gradient[kept.index(i)] = slope
            variance = gradient @ cov @ gradient if np.all(np.isfinite(cov)) else math.inf
            spread = (math.sqrt(variance) if np.isfinite(variance) and variance >= 0
                      and not undetermined else math.inf)
            value = quantity.value
            if quantity.interval_of is not None:
                source = estimates[quantity.interval_of]
                ends = ((source.high68, source.low68, source.high95, source.low95)
                        if quantity.decreasing else
                        (source.low68, source.high68, source.low95, source.high95))
                bounds = [quantity.through(b) for b in ends]
            else:
                floor = quantity.lower
                low = ((lambda z: max(value - z * spread, floor)) if math.isfinite(spread)
                       else (lambda z: floor))
                bounds = [low(Z68), value + Z68 * spread, low(Z95), value + Z95 * spread]
            estimates[quantity.name] = Estimate(value, spread, *bounds, quantity.unit,
                                                "derived", quantity.note)

    def failed(self, t, message, notes):
        return failed_noise_fit(self.datasets[t], self.model_name, message, notes)


def _span(centre, lower, upper, count):
    """Grids (rows, 2·count) from each centre out to both bounds, sorted, centre excluded:
    geometric where the bounds are positive, else linear."""
    fractions = np.arange(1, count + 1) / count
    out = []
    for bound in (lower, upper):
        if lower > 0.0:
            out.append(centre[:, None] * (bound / centre[:, None]) ** fractions)
        else:
            out.append(centre[:, None] + (bound - centre[:, None]) * fractions)
    return np.concatenate([out[0][:, ::-1], out[1]], axis=1)


def _lagrange_weights(nodes, x):
    """Weights of the values at three `nodes` that interpolate them quadratically at x."""
    weights = np.ones(3)
    for i in range(3):
        for j in range(3):
            if j != i:
                weights[i] *= (x - nodes[j]) / (nodes[i] - nodes[j])
    return weights


def _crossing(xs, roots, level, side):
    """x where the signed root first passes `level` going outward from the centre (xs sorted
    ascending; the centre is the last point on the low side, the first on the high side)."""
    order = range(len(xs) - 1, -1, -1) if side < 0 else range(len(xs))
    previous = None
    for i in order:
        if previous is not None and side * roots[i] >= side * level:
            fraction = (level - roots[previous]) / (roots[i] - roots[previous])
            return float(xs[previous] + fraction * (xs[i] - xs[previous]))
        previous = i
    return -math.inf if side < 0 else math.inf
