"""One contact model fitted to one scene's impacts: known quantities fixed or as priors, start
values, the level's optimizer, restarts (from the gravity-free limit after a capture, from a
finer grid of ω0 after a misfit), estimates with their intervals by the requested
uncertainty methods, and a failed fit kept with its reason.

References
----------
Numbered as in :mod:`dashpot.fit`.

.. [3] K. P. Burnham and D. R. Anderson, *Model Selection and Multimodel Inference*, 2nd ed.,
   Springer (2002), sec. 2.2 (AIC with known variance: χ² + 2K) and 2.9 (Akaike weights).
.. [4] P. R. Bevington and D. K. Robinson, *Data Reduction and Error Analysis for the Physical
   Sciences*, 3rd ed. (2003), sec. 3.2 (propagation of errors).
.. [5] W. H. Press et al., *Numerical Recipes*, 3rd ed., Cambridge (2007), sec. 15.6
   (confidence regions from Δχ² = 1 and 4 for one parameter).
.. [6] D. Foreman-Mackey et al., "emcee: The MCMC Hammer", PASP 125, 306 (2013).
.. [10] J. Schäfer, S. Dippel and D. E. Wolf, "Force schemes in simulations of granular
   materials", J. Phys. I France 6, 5 (1996) (linear spring-dashpot: contact time π/ω_d).
.. [11] T. Schwager and T. Pöschel, "Coefficient of restitution and linear-dashpot model
   revisited", Granular Matter 9, 465 (2007) (the contact ends where the force vanishes).
.. [12] R. E. Kass and A. E. Raftery, "Bayes factors", J. Am. Stat. Assoc. 90, 773 (1995)
   (ΔBIC of 6-10: strong evidence).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import lmfit
import numpy as np

from ..physics.effects import FLIGHT_EFFECTS
from ..physics.models import GRAVITY_MODELS, MODELS
from ..scene import Scene
from .accuracy import choose_accuracy
from .covariance import (_draws, _interval_row, _linear_estimate, _misfit_bound,
                         _propagated_sd, _sampled, _scaled_covariance)
from .data import flight_notes
from .identifiability import _identifiability_notes
from .levenberg_marquardt import _levenberg_marquardt
from .residuals import _residual_rows, _residual_size
from .results import FitResult
from .settings import (COARSE_OMEGA0_STEP, INTERVAL_DRAWS, INTERVAL_SEED, METHOD, OPTIONS,
                       PARAMETERS, UNCERTAINTY_METHODS)
from .start import _start_values
from .trains import _fit_track, _TrainPredictor, _restitution
from .uncertainty import IntervalInputs, beta_intervals

EFFECT_STEP_BIC = 6.0
"""ΔBIC that keeps a flight effect tried as a nested step (rolling friction on a cart), as the
noise fits' nested steps (:data:`dashpot.noise_selection.NESTED_STEP_BIC`): strong evidence on
the scale of Kass and Raftery [12]_."""

_SAME_MINIMUM_CHISQR = 1e-3
"""Δχ² under which a restarted fit found the minimum it started from again: a thousandth of
the change that moves a parameter by one standard error."""


def fit_model(data, model, scene=None, *, max_nfev=2000, uncertainty=("covariance",),
              seed=0, accuracy=None, effects=()):
    """Fit one contact model to a scene's impacts.

    Parameters
    ----------
    data : FitData
        From :func:`prepare_data`.
    model : {"Ia", "Ib", "IIa", "IIb", "hybrid"}
    scene : Scene, optional
        What is known of the apparatus (default: nothing but standard gravity). Its stiffness
        and mass fix ω0 or give it a prior; else its contact time τ does, through the
        gravity-free relation τ = π/ω_d ≈ π/ω0 [10]_ (a Gaussian prior on τ is one on v* =
        gτ/π).
    max_nfev : int, default 2000
        Largest number of model evaluations.
    uncertainty : sequence of {"covariance", "profile", "posterior"}
        Methods for the intervals of β, at increasing cost: the Gaussian approximation from
        the Jacobian (always computed; it fills ``estimates``), the profile likelihood (χ²
        minimised over the other parameters at fixed β; intervals where it rises by 1 and 4
        [5]_), and posterior sampling with emcee (flat priors, seeded by `seed`) [6]_. Each
        method's intervals of β (1/s) and its CPU time go to ``intervals``.
    seed : int, default 0
        Seed of the posterior sampler.
    accuracy : {"auto", "fast", "standard", "exact"}, optional
        Numerical accuracy of the predicted trains (default: the scene's); see
        :func:`choose_accuracy`. The level, its solver and the error it guarantees are
        recorded in ``accuracy``, ``notes`` and ``numerical_tolerance``.
    effects : sequence of str, default ()
        Flight effects of the registry :data:`dashpot.physics.effects.FLIGHT_EFFECTS` the fit
        carries beside those the scene puts in every fit and those it tries as a step (below).

    Returns
    -------
    FitResult
        ``estimates`` holds ``zeta`` (1), ``omega0`` (rad/s), ``beta`` (1/s), ``v0`` (m/s),
        ``t0`` (s), ``v_star`` (m/s), and with a known mass ``k`` (N/m) and ``gamma``
        (kg/s), each with its 1σ error by linear propagation [4]_ and central 68.27 % and
        95.45 % intervals: Gaussian for the fitted ζ, v*, v0 and t0, and for the derived ones
        the quantiles of seeded draws from that Gaussian (ω0 = g/v* is unbounded above where
        v* = 0 is inside). ``predicted`` holds the model's train (impact ``times`` in s,
        ``speeds`` m/s, ``restitution``, ``contact_durations`` s) and ``at_data`` (predicted
        times of the observed impacts); ``eps_curve`` ε against impact speed (m/s) over the
        predicted range. Information criteria follow [3]_: with known timing errors AIC =
        χ² + 2K and BIC = χ² + K ln N; otherwise N ln(χ²/N) + 2K and N ln(χ²/N) + K ln N.

        The flight between impacts carries every effect of the registry
        :data:`dashpot.physics.effects.FLIGHT_EFFECTS` that the scene puts in every fit or
        `effects` asks for, each set up from the scene by the effect (start, a prior or a
        fixed value, the note): the trains fly the track law their ``enter`` gives, and
        ``estimates`` adds each effect's parameters and derived quantities. Air drag is in
        every fit where the scene models it (:attr:`Scene.drag`: the drag constant ``k_d``,
        1/m, with the scene's prior, a Gaussian penalty as the prior on v0). An effect the
        scene tries as a nested step (its ``stepped``: rolling friction where
        :attr:`Scene.tries_friction`, cart scenes) is fitted again with the model and kept
        only where it lowers the BIC by at least EFFECT_STEP_BIC; for friction ``estimates``
        then adds ``g_eff`` (the scene's incline angle its prior, or fixed where the scene
        states g_eff), ``friction`` f, and the flight's two accelerations ``a_away`` = g_eff
        + f away from the bumper and ``a_toward`` = g_eff − f back (m/s²). A note says which
        was kept.

    Raises
    ------
    ValueError
        An unknown model, uncertainty method or flight effect.
    """
    scene = scene or Scene()
    if model not in MODELS:
        raise ValueError(f"model must be one of {', '.join(MODELS)}; got {model!r}")
    unknown = set(uncertainty) - set(UNCERTAINTY_METHODS)
    if unknown:
        raise ValueError(f"unknown uncertainty method {sorted(unknown)[0]!r}; use "
                         f"{', '.join(UNCERTAINTY_METHODS)}")
    missing = [name for name in effects if name not in FLIGHT_EFFECTS]
    if missing:
        raise ValueError(f"unknown flight effect {missing[0]!r}; use "
                         f"{', '.join(FLIGHT_EFFECTS)}")
    notes = list(data.notes) + flight_notes(scene)
    carried = tuple(effects)
    try:
        result = _fit(data, model, scene, list(notes), max_nfev, tuple(uncertainty), seed,
                      accuracy, carried)
        # Nested steps, in the registry's order: each effect the scene tries is kept only
        # where it lowers the BIC of the fit kept so far by EFFECT_STEP_BIC.
        for effect in list(FLIGHT_EFFECTS.values()):
            if not result.success or effect.name in carried or not effect.steps_in(scene):
                continue
            with_effect = _fit(data, model, scene, list(notes), max_nfev, tuple(uncertainty),
                               seed, accuracy, carried + (effect.name,))
            result, kept = _effect_step(result, with_effect, effect)
            carried += (effect.name,) if kept else ()
        return result
    except (ValueError, ArithmeticError, RuntimeError, np.linalg.LinAlgError) as error:
        return _failed(model, f"fit failed: {error}", notes, data)


def _shown_unit(unit):
    """A unit as the notes print it (m/s² for m/s^2)."""
    return unit.replace("^2", "²").replace("^3", "³")


def _effect_step(without, with_effect, effect):
    """The fit with `effect` where it lowers the BIC by EFFECT_STEP_BIC, else the one
    without, and whether the effect was kept; a note says which and why (with the effect's
    derived quantities, else its parameters, where kept)."""
    gain = without.bic - with_effect.bic
    if with_effect.success and gain >= EFFECT_STEP_BIC:
        shown = [quantity.name for quantity in effect.derived] or list(effect.parameter_names)
        values = ", ".join(
            f"{name} = {with_effect.estimates[name].value:.4g} +- "
            f"{with_effect.estimates[name].stderr:.2g} "
            f"{_shown_unit(with_effect.estimates[name].unit)}" for name in shown)
        with_effect.notes.append(
            f"{effect.label} kept: BIC without it minus BIC with it = {gain:.3g} (>= "
            f"{EFFECT_STEP_BIC:g}); {values}")
        return with_effect, True
    why = (f"BIC without it minus BIC with it = {gain:.3g} (< {EFFECT_STEP_BIC:g})"
           if with_effect.success else f"its fit failed ({with_effect.message})")
    without.notes.append(f"{effect.label} not kept, fixed at zero: {why}")
    return without, False


def _failed(model, message, notes, data):
    """A fit that could not be made: kept in the output with its reason, same layout."""
    empty = np.full(data.times.size, np.nan)
    nothing = np.zeros(0)
    return FitResult(model=model, success=False, message=message, estimates={}, varied=(),
                     correlation=np.zeros((0, 0)), chisqr=math.inf, redchi=math.inf,
                     aic=math.inf, bic=math.inf, ndata=int(data.times.size), nvarys=0, nfev=0,
                     time_residuals=empty, normalized_residuals=empty,
                     predicted={"times": nothing, "speeds": nothing, "restitution": nothing,
                                "contact_durations": nothing, "at_data": empty},
                     eps_curve={"speed": nothing, "eps": nothing,
                                "captured": np.zeros(0, bool)},
                     notes=notes + [message], numerical_tolerance=math.nan,
                     error_bound=math.nan)


def _flight_setup(scene, g, effects):
    """The flight of a fit: the registry's effects it carries and their columns.

    Every effect of :data:`dashpot.physics.effects.FLIGHT_EFFECTS` that the scene puts in
    every fit or `effects` names sets its columns up from the scene (its ``setup``), in the
    registry's order.

    Returns
    -------
    carried : tuple of FlightEffect
        The effects in the fit (empty: gravity's flight, no columns).
    columns : tuple of Column
        Their columns, in order: start values, whether held, priors, why held.
    notes : list of str
        The notes of a dashpot model's fit on them.
    """
    carried, columns, notes = [], [], []
    for effect in FLIGHT_EFFECTS.values():
        setup = effect.columns(scene, g, effect.name in effects)
        if setup is None:
            continue
        carried.append(effect)
        columns.extend(setup.columns)
        if setup.dashpot_note:
            notes.append(setup.dashpot_note)
    return tuple(carried), tuple(columns), notes


@dataclass(frozen=True)
class _KnownContact:
    """What the scene fixes or constrains of a fit: mass (kg), stiffness (N/m), contact time
    (s) and first impact speed (m/s) as given (None where not, or where overruled), ω0 (rad/s)
    and v0 (m/s) where held exactly, and the ω0 any prior is centred on."""

    mass: object
    stiffness: object
    contact_time: object
    known_v0: object
    fixed_omega0: float | None
    fixed_v0: float | None
    known_omega0: float | None


def _known_contact(scene, notes):
    """The scene's knowledge of the contact, with a note where one key overrules another:
    ω0 = √(k/m) needs both k and m, and a stiffness overrules a contact time."""
    mass, stiffness, contact_time = scene.mass, scene.stiffness, scene.contact_time
    known_v0 = scene.known_impact_speed
    if stiffness is not None and mass is None:
        notes.append("stiffness known but mass not: omega0 = sqrt(k/m) needs both; omega0 fitted")
        stiffness = None
    fixed_omega0 = (math.sqrt(stiffness.value / mass.value)
                    if stiffness is not None and stiffness.uncertainty is None
                    and mass.uncertainty is None else None)
    if contact_time is not None and stiffness is not None:
        notes.append("contact time and stiffness both known: omega0 from the stiffness")
        contact_time = None
    if contact_time is not None and contact_time.uncertainty is None:
        fixed_omega0 = math.pi / contact_time.value
    fixed_v0 = known_v0.value if known_v0 is not None and known_v0.uncertainty is None else None
    known_omega0 = (math.sqrt(stiffness.value / mass.value) if stiffness is not None
                    else None if contact_time is None else math.pi / contact_time.value)
    return _KnownContact(mass, stiffness, contact_time, known_v0, fixed_omega0, fixed_v0,
                         known_omega0)


def _contact_priors(known, scene, g, notes):
    """Why ω0 and v0 are held where they are, and the Gaussian priors (name, centre, sd) the
    scene puts on v* and v0."""
    fixed, priors = {}, []
    if known.fixed_omega0 is not None:
        fixed["omega0"] = ("stiffness and mass known exactly: omega0 = sqrt(k/m)"
                           if known.contact_time is None else
                           "contact time known exactly: omega0 = pi/tau")
    if known.fixed_v0 is not None:
        fixed["v0"] = ("first impact speed known" if scene.first_impact_speed is not None
                       else "drop height known: v0 = sqrt(2 g_eff h)")
    stiffness, mass, contact_time = known.stiffness, known.mass, known.contact_time
    if stiffness is not None and known.fixed_omega0 is None:
        sd = math.hypot(stiffness.uncertainty or 0.0,
                        stiffness.value * (mass.uncertainty or 0.0) / mass.value)
        prior_v_star = g / math.sqrt(stiffness.value / mass.value)
        priors.append(("v_star", prior_v_star, prior_v_star * 0.5 * sd / stiffness.value))
        notes.append("prior on omega0 from the known stiffness and mass")
    if contact_time is not None and known.fixed_omega0 is None:
        # The gravity-free contact duration τ = π/ω_d ≈ π/ω0 [10]_, so v* = g/ω0 = gτ/π: a
        # Gaussian prior on τ is one on v*, exactly. It is the duration of Ia's contact; IIa's
        # (and IIb's, the hybrid's) ends where the force vanishes, shorter by about 2ζ/ω0 [11]_,
        # and gravity changes every one by O(v*/v): both far inside a prior of tens of %.
        priors.append(("v_star", g * contact_time.value / math.pi,
                       g * contact_time.uncertainty / math.pi))
        notes.append("prior on omega0 = pi/tau from the scene's contact time")
    if known.known_v0 is not None and known.fixed_v0 is None:
        priors.append(("v0", known.known_v0.value, known.known_v0.uncertainty))
        notes.append("prior on v0 from the scene's first impact speed"
                     if scene.first_impact_speed is not None else
                     "prior on v0 = sqrt(2 g_eff h) from the scene's drop height")
    return fixed, priors


def _fit(data, model, scene, notes, max_nfev, uncertainty, seed, accuracy, effects=()):
    known = _known_contact(scene, notes)
    fixed_omega0, fixed_v0 = known.fixed_omega0, known.fixed_v0
    unknowns = 2 + (fixed_omega0 is None) + (fixed_v0 is None)
    measured = data.times.size + int(np.isfinite(data.impact_speed).sum()
                                     + np.isfinite(data.rebound_speed).sum())
    if measured <= unknowns:
        return _failed(model, f"fit failed: {measured} measured values cannot determine "
                              f"{unknowns} unknowns (zeta, t0"
                              + (", omega0" if fixed_omega0 is None else "")
                              + (", v0" if fixed_v0 is None else "")
                              + "); give more impacts or known quantities in the scene",
                       notes, data)
    level, trains_solver, bound, reason = choose_accuracy(data, accuracy or scene.accuracy, model)
    notes.append(f"accuracy {reason}")
    carried, columns, flight_notes_of_fit = _flight_setup(scene, data.g, effects)
    flight_names = tuple(column.name for column in columns)
    names = PARAMETERS + flight_names  # the columns of the residual function
    # The flight of the start values: the effects' track at their columns' starts.
    flight_start = _fit_track(carried, data.g, [column.start for column in columns])
    known_v0 = None if known.known_v0 is None else known.known_v0.value
    start, how = _start_values(model, data, known_v0, known.known_omega0,
                               fit_v0=fixed_v0 is None, trains_solver=trains_solver,
                               level=level, flight=flight_start)
    if start is None:
        return _failed(model, f"fit failed: {how}", notes, data)
    notes.append(how)

    # Fitted as ζ and the characteristic speed v* = g/ω0: gravity's effect on ε grows like
    # v*/v and the contact time like 1/ω0 ∝ v*, so the misfit valley is nearly straight in
    # (ζ, v*); in (ln ζ, ln ω0) it is a banana along which Levenberg–Marquardt crawls.
    g = data.g
    params = lmfit.Parameters()
    # No bounds: lmfit maps bounded parameters through sqrt or sine transforms, which bend the
    # valley again (ζ ≈ u²/2 near 0). A step to a non-physical value is rejected instead, by
    # the residual function returning an enormous misfit there.
    params.add("zeta", value=start["zeta"])
    params.add("v_star", value=g / start["omega0"], vary=fixed_omega0 is None)
    params.add("v0", value=start["v0"], vary=fixed_v0 is None)
    params.add("t0", value=start["t0"])
    for column in columns:
        params.add(column.name, value=column.start, vary=not column.fixed)
    fixed, priors = _contact_priors(known, scene, g, notes)
    fixed.update({column.name: column.reason for column in columns if column.fixed})
    priors.extend((column.name, column.start, column.prior) for column in columns
                  if not column.fixed and column.prior is not None)
    notes.extend(flight_notes_of_fit)

    # Each train is that of the level's map to machine precision (Newton's method, or the
    # compiled impact-by-impact pass over the surrogate tables): the finite-difference
    # Jacobians difference trains whose parameters differ by ~1e-8 to 1e-5.
    predictor = _TrainPredictor(model, data.g, data.count, trains_solver, carried)
    predictor.start = start["ratios"]
    # What the fitted times can be off by, relative to the span of the train.
    tolerance = bound * data.count
    residual_rows = functools.partial(_residual_rows, data=data, predictor=predictor,
                                      priors=priors)

    def residual(p):
        """lmfit's residual function: one parameter set."""
        values = p.valuesdict()
        return residual_rows(np.array([[values[name] for name in names]]))[0]

    # ∂r/∂t0: the time offset enters linearly, only the impact-time rows.
    t0_column = np.zeros(_residual_size(data, priors))
    t0_column[: data.times.size] = -1.0 / data.sigma

    def minimize(start):
        if level == "fast":
            return _levenberg_marquardt(residual_rows, start, {"t0": t0_column},
                                        max_nfev=max_nfev, sigma_known=data.sigma_known)
        return lmfit.minimize(residual, start, method=METHOD, max_nfev=max_nfev, **OPTIONS,
                              scale_covar=not data.sigma_known)

    def captures(fitted):
        """True if the fitted train ends in capture before the last observed impact."""
        values = fitted.params.valuesdict()
        if not (values["zeta"] >= 0 and values["v_star"] > 0 and values["v0"] > 0):
            return True
        flight = [values[name] for name in flight_names]
        if not np.all(predictor.accepts(*flight)):
            return True
        trains, *_ = predictor(values["zeta"], g / values["v_star"], values["v0"], *flight)
        return int(trains.impacts[0]) < data.count

    result = minimize(params)
    held_at_limit = False  # ω0 held at the gravity-free limit: every freer fit captured
    if model in GRAVITY_MODELS and fixed_omega0 is None:
        result, held_at_limit = _restarted_after_capture(result, params, minimize, captures,
                                                         data, notes)
        if data.sigma_known and result.chisqr > _misfit_bound(result.nfree):
            result = _restarted_on_finer_grid(result, params, minimize, captures, model, data,
                                              known, start, trains_solver, level,
                                              flight_start, notes)
    stated_priors = list(priors)
    if (any(name == "v_star" for name, *_ in priors) and data.sigma_known
            and result.chisqr > _misfit_bound(result.nfree)):
        # Under a misfit the errors are scaled by the Birge ratio √ĉ (below), so the data weigh
        # as χ²/ĉ: a prior on ω0 weighed against the raw χ² would be swamped and ω0 wander as
        # without it. Its sd shrunk by √ĉ gives it its stated weight against χ²/ĉ (and, after
        # the scaling, its stated sd in the covariance); refitted from where the fit ended.
        c_hat = float(result.redchi)
        priors[:] = [(name, centre, spread / math.sqrt(c_hat) if name == "v_star" else spread)
                     for name, centre, spread in priors]
        result = minimize(result.params)
        notes.append(f"prior on omega0 weighed against chi-square / {c_hat:.3g} (the fit "
                     f"misses the data by more than their uncertainties)")
    values = result.params.valuesdict()
    if not np.all(np.isfinite(result.residual)):
        return _failed(model, "fit failed: the model gave non-finite residuals", notes, data)
    zeta, v_star = values["zeta"], values["v_star"]
    omega0 = g / v_star
    flight = [values[name] for name in flight_names]
    trains, times, speeds, _ = predictor(zeta, omega0, values["v0"], *flight)
    impacts = int(trains.impacts[0])
    times, speeds = times[0], speeds[0]
    message = result.message
    success = bool(result.success)
    if impacts < data.count:
        success = False
        message = (f"the model captures the ball after {impacts} impacts but the "
                   f"data have {data.count}")

    varied = tuple(result.var_names)
    cov, chisqr_scale = _scaled_covariance(
        result, data.sigma_known, notes,
        "the model misses the data by more than their uncertainties")
    for name, centre, spread in stated_priors:
        value = result.params[name].value
        if abs(value - centre) > 3.0 * spread:
            label = "omega0" if name == "v_star" else name
            shown = (g / value, g / centre) if name == "v_star" else (value, centre)
            unit = {"v_star": " rad/s", "v0": " m/s"}.get(name, "")
            notes.append(f"fitted {label} = {shown[0]:.4g}{unit} disagrees with the scene's "
                         f"{shown[1]:.4g}{unit} by more than 3 sigma of the prior")
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.sqrt(np.diag(cov))
        correlation = cov / np.outer(scale, scale)
    correlation = np.where(np.isfinite(correlation), correlation, np.nan)

    def status(name):
        if name in varied:
            return ("prior" if any(p[0] == name for p in priors) else "fitted"), ""
        return "fixed", fixed.get({"v_star": "omega0"}.get(name, name), "")

    estimates = _estimates(values, varied, cov, status, data, known.mass, level, carried,
                           held_at_limit)
    notes.extend(_identifiability_notes(estimates, varied, correlation, result.params))

    nvarys = len(varied)
    ndata = int(result.ndata)
    chisqr = float(result.chisqr)
    if data.sigma_known:
        aic, bic = chisqr + 2 * nvarys, chisqr + nvarys * math.log(ndata)
    else:
        aic, bic = float(result.aic), float(result.bic)
    predicted_at_data = values["t0"] + times[data.index]  # since the origin
    intervals = beta_intervals(
        uncertainty if success else (),
        IntervalInputs(model=model, data=data, result=result, residual=residual, priors=priors,
                       start_ratios=predictor.start, seed=seed, chisqr_scale=chisqr_scale,
                       notes=notes, flight_effects=carried),
        _interval_row(estimates["beta"]))
    top = float(np.max(speeds))
    bottom = float(np.min(speeds[speeds > 0])) if np.any(speeds > 0) else top
    curve_speed = np.geomspace(bottom, top, 200) if top > bottom else np.array([top])
    curve_eps, curve_captured = _restitution(trains_solver, model, zeta,
                                             curve_speed / v_star)
    return FitResult(
        model=model, success=success, message=message, estimates=estimates, varied=varied,
        correlation=correlation, chisqr=chisqr, redchi=float(result.redchi), aic=aic, bic=bic,
        ndata=ndata, nvarys=nvarys, nfev=int(result.nfev),
        time_residuals=data.times - predicted_at_data,
        normalized_residuals=np.asarray(result.residual, float),
        predicted={"times": data.time_origin + (values["t0"] + times[:impacts]),
                   "speeds": speeds[:impacts],
                   "restitution": trains.restitution[0, :impacts],
                   "contact_durations": trains.contact_times[0, :impacts] / omega0,
                   "at_data": data.time_origin + predicted_at_data},
        eps_curve={"speed": curve_speed, "eps": curve_eps, "captured": curve_captured},
        notes=notes, numerical_tolerance=tolerance, error_bound=predictor.error_bound,
        intervals=intervals, accuracy=level)


def _restarted_after_capture(result, params, minimize, captures, data, notes):
    """A gravity model's fit that ended in capture before the last impact, started again from
    the gravity-free limit; returns the fit kept and whether ω0 is held at that limit."""
    if not captures(result):
        return result, False
    # Ended where the model captures the ball before the data end: a local minimum, as every
    # gravity model reaches the gravity-free one when ω0 grows. Start again from there (ṽ ≈ 1e4
    # at the slowest impact, ω0 held until the rest has settled).
    notes.append("first fit ended in capture; restarted from the gravity-free limit")
    restart = params.copy()  # the fast optimizer updates its start in place
    restart["v_star"].set(value=0.5 * data.g * np.min(np.diff(data.times)) * 1e-4, vary=False)
    limit = minimize(restart)
    freed = limit.params.copy()
    freed["v_star"].set(vary=True)
    retry = minimize(freed)
    if not captures(retry):
        if retry.chisqr < result.chisqr or captures(result):
            result = retry
        return result, False
    # Under a misfit (junk impacts at the end of a real train) a capture before the last
    # impact can lower chi-square: no fit of this model describes every impact. Keep the
    # limit, which does, and say that ω0 is held there (not determined).
    notes.append("freeing omega0 from the gravity-free limit ends in capture before the last "
                 "impact again: omega0 held at that limit, not determined by these data")
    return limit, True


def _restarted_on_finer_grid(result, params, minimize, captures, model, data, known, start,
                             trains_solver, level, flight, notes):
    """A gravity model's misfit started again from the best of a finer grid of ω0; the better
    of the two fits."""
    # Where the slowest impacts come near capture, a gravity model's misfit has local minima
    # just above the capture edge in ω0, and the step from a start on the coarse grid can jump
    # past the true valley into one (χ² in the thousands where the truth gives ~ν). Start
    # again from the best of a grid of ω0 between the start's neighbours on the coarse grid.
    finer, _ = _start_values(model, data,
                             None if known.known_v0 is None else known.known_v0.value,
                             start["omega0"], fit_v0=known.fixed_v0 is None,
                             trains_solver=trains_solver, level=level,
                             omega0_spread=COARSE_OMEGA0_STEP, flight=flight)
    if finer is None:
        return result
    again = params.copy()
    for name, value in (("zeta", finer["zeta"]), ("v_star", data.g / finer["omega0"]),
                        ("v0", finer["v0"]), ("t0", finer["t0"])):
        again[name].set(value=value)
    retry = minimize(again)
    if retry.chisqr < result.chisqr and not captures(retry):
        # The same minimum reached again differs in χ² by rounding only (and by the machine's
        # arithmetic): only a clearly lower χ² was another minimum.
        if retry.chisqr < result.chisqr - _SAME_MINIMUM_CHISQR:
            notes.append("first fit ended in a local minimum of the misfit; restarted from a "
                         "finer grid of omega0")
        return retry
    return result


def _estimates(values, varied, cov, status, data, mass, level, effects, held_at_limit):
    """Every reported quantity of a fit with its 68.27 % and 95.45 % intervals.

    Standard errors by linear propagation [4]_; intervals of the derived quantities (ω0, β, k,
    γ) from draws of the Gaussian approximation in the fitted coordinates (ζ, v*, v0, t0),
    where the likelihood is closest to Gaussian. ω0 = g/v* is unbounded above when v* = 0 (the
    gravity-free limit) lies inside the interval, and the intervals say so. `status(name)`
    gives each parameter's status and why. The flight `effects` add their parameters (unit
    and meaning from their specs) and their derived quantities, by linear propagation.
    """
    g = data.g
    zeta, v_star = values["zeta"], values["v_star"]
    omega0 = g / v_star

    def sd_of(**gradient):
        """1σ of q from ∂q/∂p (of ln q from ∂ln q/∂p, for a relative error)."""
        return _propagated_sd(cov, varied, gradient)

    draws = _draws(values, varied, cov, INTERVAL_DRAWS[level])
    mass_draws = (1.0 if mass is None else mass.value + (mass.uncertainty or 0.0)
                  * np.random.default_rng(INTERVAL_SEED + 1).standard_normal(
                      INTERVAL_DRAWS[level]))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        omega_draws = np.where(draws["v_star"] > 0, g / draws["v_star"], np.inf)
        beta_draws = np.where(draws["zeta"] > 0, np.maximum(draws["zeta"], 0) * omega_draws,
                              0.0)
    estimates = {}
    st, why = status("zeta")
    estimates["zeta"] = _sampled(zeta, sd_of(zeta=1.0 / zeta) * zeta, draws["zeta"], "1", st,
                                 why)
    st, why = status("v_star")
    estimates["omega0"] = _sampled(omega0, sd_of(v_star=-1.0 / v_star) * omega0, omega_draws,
                                   "rad/s", st, why)
    estimates["v_star"] = _linear_estimate(v_star, sd_of(v_star=1.0), "m/s", st,
                                           why or "characteristic speed g/omega0")
    estimates["beta"] = _sampled(zeta * omega0,
                                 sd_of(zeta=1.0 / zeta, v_star=-1.0 / v_star) * zeta * omega0,
                                 beta_draws, "1/s", "derived", "beta = zeta * omega0")
    st, why = status("v0")
    estimates["v0"] = _linear_estimate(values["v0"], sd_of(v0=1.0), "m/s", st, why)
    # Times on output are on the table's clock again.
    estimates["t0"] = _linear_estimate(data.time_origin + values["t0"], sd_of(t0=1.0), "s",
                                       "fitted")
    if mass is not None:
        mass_sd = (mass.uncertainty or 0.0) / mass.value
        k = mass.value * omega0 ** 2
        k_sd = math.hypot(sd_of(v_star=-2.0 / v_star), mass_sd) * k
        with np.errstate(over="ignore", invalid="ignore"):
            estimates["k"] = _sampled(k, k_sd, mass_draws * omega_draws ** 2, "N/m", "derived",
                                      "k = m * omega0^2")
            gamma = 2.0 * mass.value * zeta * omega0
            gamma_sd = math.hypot(sd_of(zeta=1.0 / zeta, v_star=-1.0 / v_star), mass_sd) * gamma
            estimates["gamma"] = _sampled(gamma, gamma_sd, 2.0 * mass_draws * beta_draws,
                                          "kg/s", "derived", "gamma = 2 m beta")
    for parameter in (p for effect in effects for p in effect.parameters):
        st, why = status(parameter.name)
        estimates[parameter.name] = _linear_estimate(
            values[parameter.name], sd_of(**{parameter.name: 1.0}), parameter.unit, st,
            why or parameter.meaning)
    for quantity in (q for effect in effects for q in effect.derived):
        estimates[quantity.name] = _linear_estimate(
            quantity.value(values), sd_of(**quantity.gradient(values)), quantity.unit,
            "derived", quantity.description)
    if held_at_limit:
        # ω0 sits at a limit the fit was held at, not at a minimum: no error and no bound,
        # and β, k and γ, which scale with it, are not determined either.
        for name in ("omega0", "v_star", "beta", "k", "gamma"):
            if name in estimates:
                estimates[name] = replace(estimates[name], stderr=math.inf, low68=math.nan,
                                          high68=math.inf, low95=math.nan, high95=math.inf,
                                          status="fitted" if name in ("omega0", "v_star")
                                          else estimates[name].status)
    return estimates
