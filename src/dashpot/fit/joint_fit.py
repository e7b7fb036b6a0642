"""One contact model fitted jointly to several runs of one apparatus: the runs share the
contact parameters (ζ and ω0, hence β, and k with a known mass), and each keeps its own first
impact speed v0 and time t0.

The likelihood is that of the single-run fit (:mod:`dashpot.fit.residuals`): each run's
normalized residuals of impact times and measured speeds, concatenated, with the scene's
priors on ω0 once and on v0 once per run. Runs are independent measurements, so χ² is the sum
of the runs' χ² and the joint fit's covariance is that of the stacked residuals [4]_: the
shared parameters are determined by every run's impacts at once.

References
----------
Numbered as in :mod:`dashpot.fit`.

.. [3] K. P. Burnham and D. R. Anderson, *Model Selection and Multimodel Inference*, 2nd ed.,
   Springer (2002), sec. 2.2 (AIC with known variance: χ² + 2K).
.. [4] P. R. Bevington and D. K. Robinson, *Data Reduction and Error Analysis for the Physical
   Sciences*, 3rd ed. (2003), sec. 3.2 (propagation of errors) and 8.5 (errors from the
   curvature of χ²).
.. [5] W. H. Press et al., *Numerical Recipes*, 3rd ed., Cambridge (2007), sec. 15.6
   (confidence regions from Δχ² = 1 and 4 for one parameter).
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, field

import lmfit
import numpy as np

from ..physics.effects import FLIGHT_EFFECTS
from ..scene import Scene
from .accuracy import choose_accuracy
from .covariance import (_interval_row, _linear_estimate, _misfit_bound, _propagated_sd,
                         _scaled_covariance)
from .profile_likelihood import _profile_beta
from .residuals import _residual_rows
from .settings import METHOD, OPTIONS
from .trains import _TrainPredictor

__all__ = ["JointFit", "RunsFit", "fit_joint", "fit_runs", "split_runs"]

SHARED = ("zeta", "v_star")  # the contact parameters every run shares (fitted coordinates)


@dataclass
class JointFit:
    """One model fitted jointly to several runs. See :func:`fit_joint`.

    Attributes
    ----------
    model : str
    success : bool
    message : str
    estimates : dict of str -> Estimate
        Shared contact parameters: ``zeta`` (1), ``v_star`` (m/s), ``omega0`` (rad/s),
        ``beta`` (1/s), with a known mass ``k`` (N/m) and ``gamma`` (kg/s).
    run_estimates : dict of run -> dict of str -> Estimate
        Each run's own ``v0`` (m/s) and ``t0`` (s, on the table's clock).
    chisqr, redchi, aic, bic : float
    ndata, nvarys, nfev : int
    varied : tuple of str
    correlation : ndarray
    notes : list of str
    intervals : dict of str -> dict
        Intervals of β (1/s) by method, as :attr:`FitResult.intervals`: ``covariance``
        always, ``profile`` where the scene asks for it (:attr:`Scene.uncertainty`).
    """

    model: str
    success: bool
    message: str
    estimates: dict
    run_estimates: dict
    chisqr: float
    redchi: float
    aic: float
    bic: float
    ndata: int
    nvarys: int
    nfev: int
    varied: tuple
    correlation: np.ndarray
    notes: list = field(default_factory=list)
    intervals: dict = field(default_factory=dict)


def _failed(model, message, runs):
    return JointFit(model=model, success=False, message=message, estimates={},
                    run_estimates={run: {} for run in runs}, chisqr=math.inf,
                    redchi=math.inf, aic=math.inf, bic=math.inf, ndata=0, nvarys=0, nfev=0,
                    varied=(), correlation=np.zeros((0, 0)), notes=[message])


def fit_joint(datas, model, scene=None, starts=None, *, max_nfev=4000):
    """Fit one contact model to several runs at once, the runs sharing ζ and ω0.

    Parameters
    ----------
    datas : dict of run -> FitData
        Each run's prepared impacts (:func:`dashpot.fit.prepare_data` of that run alone);
        at least two runs.
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    scene : Scene, optional
        What is known of the apparatus, as for :func:`dashpot.fit.fit_model`: an exact
        stiffness and mass (or contact time) fix ω0, uncertain ones give it a prior; a known
        first impact speed fixes v0 of every run or gives each run its prior.
    starts : dict of run -> FitResult, optional
        Each run's own fit of `model` (:func:`dashpot.fit.fit_model`), the start values: ζ
        and v* the median of the successful runs', v0 and t0 each run's own; where that fit
        misses the data (χ² more than 3σ above its distribution's mean, with known timing
        errors) it is started again from each run's own ζ and v* and the best kept.
    max_nfev : int, default 4000

    Returns
    -------
    JointFit
        Estimates with 1σ errors by linear propagation from the covariance of the stacked
        residuals [4]_ (scaled by χ²/ν where the timing uncertainties are unknown, or where
        the fit misses the data by more than 3σ of its χ² distribution), Gaussian 68.27 % and
        95.45 % intervals. AIC = χ² + 2K and BIC = χ² + K ln N with known timing errors [3]_.
        A fit that cannot be made is returned with ``success=False`` and the reason. Where
        the scene's ``uncertainty`` asks for ``profile``, ``intervals`` adds the profile
        likelihood's intervals of β over the joint χ² (Δχ² = 1 and 4 [5]_; the posterior is
        sampled for each run's own fit only).

    Notes
    -----
    The runs share every flight effect of the registry
    :data:`dashpot.physics.effects.FLIGHT_EFFECTS` that the scene puts in every fit, with the
    columns the effect sets up from the scene (``estimates`` adds its parameters and derived
    quantities): air drag where the scene models it, the drag constant k_d (1/m) with the
    scene's prior or fixed where exact. An effect the single-run fits try as a nested step
    (rolling friction on cart scenes) is left out (a note says so).
    """
    scene = scene or Scene()
    runs = list(datas)
    if len(runs) < 2:
        raise ValueError(f"a joint fit needs at least two runs; got {len(runs)}")
    starts = starts or {}
    usable = [run for run in runs if run in starts and starts[run].success]
    if not usable:
        return _failed(model, "joint fit not made: no run's own fit succeeded to start from",
                       runs)
    notes = [f"joint fit without {effect.label} in flight (the single-run fits try it)"
             for effect in FLIGHT_EFFECTS.values() if effect.steps_in(scene)]
    g = datas[runs[0]].g
    sigma_known = all(data.sigma_known for data in datas.values())
    level, trains_solver, _, reason = choose_accuracy(datas[runs[0]], scene.accuracy, model)
    notes.append(f"accuracy {reason} (from run {runs[0]})")

    mass, stiffness, contact_time = scene.mass, scene.stiffness, scene.contact_time
    if stiffness is not None and mass is None:
        stiffness = None
    if contact_time is not None and stiffness is not None:
        contact_time = None
    fixed_v_star = None
    shared_priors = []
    if stiffness is not None:
        omega0 = math.sqrt(stiffness.value / mass.value)
        if stiffness.uncertainty is None and mass.uncertainty is None:
            fixed_v_star = g / omega0
        else:
            sd = math.hypot(stiffness.uncertainty or 0.0,
                            stiffness.value * (mass.uncertainty or 0.0) / mass.value)
            shared_priors.append(("v_star", g / omega0, g / omega0 * 0.5 * sd / stiffness.value))
    elif contact_time is not None:
        if contact_time.uncertainty is None:
            fixed_v_star = g * contact_time.value / math.pi
        else:
            shared_priors.append(("v_star", g * contact_time.value / math.pi,
                                  g * contact_time.uncertainty / math.pi))
    known_v0 = scene.known_impact_speed
    fixed_v0 = known_v0 is not None and known_v0.uncertainty is None
    run_priors = ([("v0", known_v0.value, known_v0.uncertainty)]
                  if known_v0 is not None and not fixed_v0 else [])

    # The flight effects the scene puts in every fit, shared by every run (one body): their
    # columns as the effects set them up (empty: gravity's flight).
    shared_effects, columns = [], []
    for effect in FLIGHT_EFFECTS.values():
        setup = effect.columns(scene, g, False) if effect.in_every_fit(scene) else None
        if setup is None:
            continue
        shared_effects.append(effect)
        columns.extend(setup.columns)
        units = {p.name: p.unit for p in effect.parameters}
        shared_priors.extend((column.name, column.start, column.prior)
                             for column in setup.columns
                             if not column.fixed and column.prior is not None)
        notes.append(f"{effect.label} in flight shared by every run: " + ", ".join(
            f"{column.name} = {column.start:.3g} {units[column.name]}, exact" if column.fixed
            else f"{column.name} fitted free" if column.prior is None
            else f"{column.name} with the scene's prior {column.start:.3g} +- "
                 f"{column.prior:.2g} {units[column.name]}"
            for column in setup.columns))
    flight = tuple(column.name for column in columns)

    params = lmfit.Parameters()
    params.add("zeta", value=float(np.median([starts[r].estimates["zeta"].value
                                              for r in usable])))
    params.add("v_star", value=fixed_v_star if fixed_v_star is not None else float(np.median(
        [starts[r].estimates["v_star"].value for r in usable])), vary=fixed_v_star is None)
    pooled_v0 = float(np.median([starts[r].estimates["v0"].value for r in usable]))
    for i, run in enumerate(runs):
        own = starts.get(run)
        own = own if own is not None and own.success else None
        params.add(f"v0_{i}", value=known_v0.value if fixed_v0 else (
            own.estimates["v0"].value if own else pooled_v0), vary=not fixed_v0)
        params.add(f"t0_{i}", value=(own.estimates["t0"].value - datas[run].time_origin
                                     if own else 0.0))

    for column in columns:
        params.add(column.name, value=column.start, vary=not column.fixed)
    rows = []
    for i, run in enumerate(runs):
        predictor = _TrainPredictor(model, g, datas[run].count, trains_solver, shared_effects)
        # The first run's rows carry the shared priors; every run its own v0 prior.
        priors = run_priors + (shared_priors if i == 0 else [])
        rows.append(functools.partial(_residual_rows, data=datas[run], predictor=predictor,
                                      priors=priors))

    def residual(p):
        values = p.valuesdict()
        shared = [values[name] for name in flight]
        return np.concatenate([
            row(np.array([[values["zeta"], values["v_star"], values[f"v0_{i}"],
                           values[f"t0_{i}"], *shared]]))[0] for i, row in enumerate(rows)])

    def minimize(start):
        return lmfit.minimize(residual, start, method=METHOD, max_nfev=max_nfev, **OPTIONS,
                              scale_covar=not sigma_known)

    result = minimize(params)
    if sigma_known and result.chisqr > _misfit_bound(result.nfree) and len(usable) > 1:
        # The runs' median missed (a run whose own fit did not determine ω0 can pull it far
        # off): start again from each run's own ζ and v*, and keep the best.
        for run in usable:
            again = params.copy()
            again["zeta"].set(value=starts[run].estimates["zeta"].value)
            if fixed_v_star is None:
                again["v_star"].set(value=starts[run].estimates["v_star"].value)
            retry = minimize(again)
            if np.all(np.isfinite(retry.residual)) and retry.chisqr < result.chisqr:
                result = retry
                notes.append(f"started again from run {run}'s own fit (the runs' median "
                             f"start ended with a larger misfit)")
    values = result.params.valuesdict()
    if not np.all(np.isfinite(result.residual)) or np.max(np.abs(result.residual)) >= 1e11:
        return _failed(model, "joint fit failed: ended outside the physical range", runs)
    varied = tuple(result.var_names)
    cov, chisqr_scale = _scaled_covariance(result, sigma_known, notes,
                                "the runs do not share one contact within their uncertainties")

    def sd_of(gradient):
        """1σ of a quantity from its gradient {parameter: ∂q/∂p} (linear propagation)."""
        return _propagated_sd(cov, varied, gradient)

    zeta, v_star = values["zeta"], values["v_star"]
    omega0 = g / v_star
    status = "fitted" if fixed_v_star is None else "fixed"
    estimates = {
        "zeta": _linear_estimate(zeta, sd_of({"zeta": 1.0}), "1", "fitted",
                                 "shared by every run"),
        "v_star": _linear_estimate(v_star, sd_of({"v_star": 1.0}), "m/s", status,
                                   "characteristic speed g/omega0, shared"),
        "omega0": _linear_estimate(omega0, sd_of({"v_star": -omega0 / v_star}), "rad/s",
                                   status, "omega0 = g/v_star, shared"),
        "beta": _linear_estimate(zeta * omega0, sd_of({"zeta": omega0,
                                                       "v_star": -zeta * omega0 / v_star}),
                                 "1/s", "derived", "beta = zeta * omega0"),
    }
    if mass is not None:
        mass_sd = (mass.uncertainty or 0.0) / mass.value
        k = mass.value * omega0 ** 2
        estimates["k"] = _linear_estimate(
            k, math.hypot(sd_of({"v_star": -2.0 / v_star}), mass_sd) * k, "N/m", "derived",
            "k = m * omega0^2")
        gamma = 2.0 * mass.value * zeta * omega0
        estimates["gamma"] = _linear_estimate(
            gamma, math.hypot(sd_of({"zeta": 1.0 / zeta, "v_star": -1.0 / v_star}), mass_sd)
            * gamma, "kg/s", "derived", "gamma = 2 m beta")
    held = {column.name: ("fixed" if column.fixed else "fitted" if column.prior is None
                          else "prior") for column in columns}
    for parameter in (p for effect in shared_effects for p in effect.parameters):
        estimates[parameter.name] = _linear_estimate(
            values[parameter.name], sd_of({parameter.name: 1.0}), parameter.unit,
            held[parameter.name], f"{parameter.description}, shared")
    for quantity in (q for effect in shared_effects for q in effect.derived):
        estimates[quantity.name] = _linear_estimate(
            quantity.value(values), sd_of(quantity.gradient(values)), quantity.unit, "derived",
            f"{quantity.description}, shared")
    run_estimates = {}
    for i, run in enumerate(runs):
        run_estimates[run] = {
            "v0": _linear_estimate(values[f"v0_{i}"], sd_of({f"v0_{i}": 1.0}), "m/s",
                                   "fixed" if fixed_v0 else "fitted", f"run {run}'s own"),
            "t0": _linear_estimate(datas[run].time_origin + values[f"t0_{i}"],
                                   sd_of({f"t0_{i}": 1.0}), "s", "fitted", f"run {run}'s own"),
        }
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.sqrt(np.diag(cov))
        correlation = cov / np.outer(scale, scale)
    correlation = np.where(np.isfinite(correlation), correlation, np.nan)
    nvarys, ndata, chisqr = len(varied), int(result.ndata), float(result.chisqr)
    if sigma_known:
        aic, bic = chisqr + 2 * nvarys, chisqr + nvarys * math.log(ndata)
    else:
        aic, bic = float(result.aic), float(result.bic)
    intervals = {"covariance": _interval_row(estimates["beta"])}
    if "profile" in scene.uncertainty and "v_star" in varied and result.success:
        started = time.process_time()
        intervals["profile"] = _profile_beta(residual, result, g, chisqr_scale)
        intervals["profile"]["cpu_seconds"] = time.process_time() - started
    if "posterior" in scene.uncertainty:
        notes.append("no posterior intervals for the joint fit (each run's fit has them)")
    notes.append(f"{len(runs)} runs share zeta and omega0; each run its own v0 and t0")
    return JointFit(model=model, success=bool(result.success), message=result.message,
                    estimates=estimates, run_estimates=run_estimates, chisqr=chisqr,
                    redchi=float(result.redchi), aic=aic, bic=bic, ndata=ndata, nvarys=nvarys,
                    nfev=int(result.nfev), varied=varied, correlation=correlation, notes=notes,
                    intervals=intervals)


@dataclass
class RunsFit:
    """Every run of a multi-run recording fitted on its own, and the joint fits.

    Attributes
    ----------
    runs : dict of run -> SceneFit
        Each run's own fits (:func:`dashpot.fit.fit_scene` of that run's impacts alone), in
        increasing run number.
    joint : dict of model -> JointFit
        Each model fitted to every run at once (:func:`fit_joint`); empty with one run.
    notes : list of str
    """

    runs: dict
    joint: dict
    notes: list = field(default_factory=list)

    @property
    def first(self):
        """The first run's SceneFit (what a single-run file holds)."""
        return next(iter(self.runs.values()))


def split_runs(impacts):
    """The impact table of each run, in increasing run number (one run: the table).

    Parameters
    ----------
    impacts : pandas.DataFrame
        Impact table of :mod:`dashpot.ingest`, optional column ``run``.

    Returns
    -------
    dict of run -> pandas.DataFrame
        Each with the table's ``attrs`` (copied) and its rows in order (a reader may sort the
        rows of several runs by time, interleaving them).
    """
    if "run" not in impacts or impacts["run"].nunique() <= 1:
        run = int(impacts["run"].iloc[0]) if "run" in impacts and len(impacts) else 0
        return {run: impacts}
    out = {}
    for run in np.unique(impacts["run"].to_numpy()):
        part = impacts[impacts["run"].to_numpy() == run].reset_index(drop=True)
        part.attrs = {key: (list(value) if isinstance(value, list) else value)
                      for key, value in impacts.attrs.items()}
        out[int(run)] = part
    return out


def fit_runs(impacts, scene=None, models=None, *, progress=None, noise=None):
    """Each run of an impact table fitted on its own, and each model fitted to all at once.

    Parameters
    ----------
    impacts : pandas.DataFrame
        Impact table (column ``run`` for several runs; without it, or with one run, the
        result holds that run's fit and no joint fit).
    scene : Scene, optional
    models : sequence of str, optional
    progress : callable, optional
        Passed to :func:`dashpot.fit.fit_scene` for each run; also called with
        ``"<model> (joint)"`` after each joint fit.
    noise : bool, optional
        As in :func:`dashpot.fit.fit_scene`.

    Returns
    -------
    RunsFit

    Raises
    ------
    ValueError
        A run cannot be prepared for fitting (fewer than three impacts): the message names
        the run.
    """
    from .scene_fit import fit_scene

    scene = scene or Scene()
    models = tuple(models or scene.models)
    parts = split_runs(impacts)
    runs = {}
    for run, table in parts.items():
        try:
            runs[run] = fit_scene(table, scene, models, progress=progress, noise=noise)
        except ValueError as error:
            if len(parts) == 1:
                raise
            raise ValueError(f"run {run}: {error}") from None
    joint = {}
    notes = []
    if len(runs) > 1:
        notes.append(f"{len(runs)} runs: each fitted on its own, and every model fitted to "
                     f"all runs at once sharing zeta and omega0")
        datas = {run: fit.data for run, fit in runs.items()}
        for model in models:
            starts = {run: fit.results[model] for run, fit in runs.items()}
            try:
                joint[model] = fit_joint(datas, model, scene, starts)
            except (ValueError, ArithmeticError, RuntimeError, np.linalg.LinAlgError) as error:
                joint[model] = _failed(model, f"joint fit failed: {error}", list(datas))
            if progress is not None:
                progress(f"{model} (joint)")
    return RunsFit(runs=runs, joint=joint, notes=notes)
