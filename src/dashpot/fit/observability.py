"""What a scene's data can and cannot say about the contact: β and k where ω0 is not determined,
and the size of gravity's effect in contact against the bounce-to-bounce scatter.

* ω0 not determined: a fitted ω0 (not fixed; with or without a prior from the scene's
  stiffness or contact time) whose 95.45 % interval is unbounded above (the data allow the
  gravity-free limit v* = g/ω0 → 0) or whose relative error exceeds ``WEAK_RELATIVE_ERROR``
  gives no number for β = ζω0, k = mω0² and γ = 2mβ: the value the fit ended at is wherever
  the optimizer wandered along a flat valley. A prior bounds ω0 in all but a misfit the prior
  cannot outweigh. :func:`not_determined` says so, with the bound the
  data give (the ends of the quantity's own 95.45 % interval that are finite; a lower end
  alone is a 97.7 % one-sided bound).
* Gravity in contact changes ε by O(v*/v) [1]_: :func:`gravity_effect_note` compares, for each
  gravity model fitted, |ε_model − ε_gravity-free| at the slowest fitted impact with the
  robust scatter of the interval ratios about their trend
  (:func:`dashpot.plausibility.ratio_trend`), and says in plain words when the data cannot see
  it, or that a size the fits imply is no evidence where every fit misses the data or a
  gravity-free fit (its own ζ taking up most of the effect) fits about as well.

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface"
   (gravity in contact: ε of Ib, IIb and the hybrid approach Ia's and IIa's like v*/v).
"""

from __future__ import annotations

import math

import numpy as np

from .settings import WEAK_RELATIVE_ERROR

__all__ = ["not_determined", "omega0_note", "gravity_effect_note", "GRAVITY_FREE_COUNTERPART",
           "CONTACT_QUANTITIES"]

# The contact quantities that carry ω0 (symbol, unit for the bound's text).
CONTACT_QUANTITIES = {"beta": ("β", "1/s"), "k": ("k", "N/m"), "gamma": ("γ", "kg/s")}
# ΔAIC below which a gravity-free model is said to fit about as well as a gravity model: where
# the selection's verdict says no more than that it "is not excluded" (ΔAIC <= 4).
FITS_AS_WELL_AIC = 4.0
# The gravity-free model with the same end of contact as each gravity model.
GRAVITY_FREE_COUNTERPART = {"Ib": "Ia", "IIb": "IIa", "hybrid": "IIa"}


def _omega0_undetermined(omega0):
    """True if a fitted ω0 (with value, stderr, high95, status) is not determined."""
    # A fit under the noise model derives ω0 = g/v* from its fitted v* ("derived"): it is as
    # (un)determined as v* is, and judged alike, so that summary.csv says what the printed
    # summary says.
    if omega0 is None or omega0.status not in ("fitted", "prior", "derived"):
        return False
    relative = omega0.stderr / omega0.value if omega0.value else math.inf
    return not math.isfinite(omega0.high95) or not relative <= WEAK_RELATIVE_ERROR


def bound_text(symbol, unit, estimate, number="{:.3g}".format):
    """The bound the data give, from the finite ends of the 95.45 % interval (text); `unit`
    is appended after a space unless empty, numbers written by `number`."""
    unit = f" {unit}" if unit else ""
    low, high = estimate.low95, estimate.high95
    low_ok, high_ok = math.isfinite(low) and low > 0, math.isfinite(high)
    if low_ok and high_ok:
        return f"{number(low)} to {number(high)}{unit} at 95 %"
    if low_ok:
        return f"{symbol} > {number(low)}{unit} at 95 %, no upper bound"
    if high_ok:
        return f"{symbol} < {number(high)}{unit} at 95 %"
    return "no bound at 95 %"


def not_determined(estimates):
    """β, k and γ that the data do not determine, each with the reason and the data's bound.

    Parameters
    ----------
    estimates : mapping of str -> Estimate-like
        A fit's estimates (:class:`dashpot.fit.Estimate`, or any object with ``value``,
        ``stderr``, ``low95``, ``high95`` and ``status``), keyed by name as in
        :attr:`dashpot.fit.FitResult.estimates`.

    Returns
    -------
    dict of str -> str
        For each of ``beta``, ``k``, ``gamma`` present while ω0 is not determined (see the
        module notes): "not determined (<bound>; <why>)", e.g. "not determined (β > 12.3 1/s
        at 95 %, no upper bound; omega0 unbounded above at 95 %)". Empty where ω0 is
        determined or fixed.
    """
    omega0 = estimates.get("omega0")
    if not _omega0_undetermined(omega0):
        return {}
    why = _why_omega0_undetermined(omega0)
    return {key: f"not determined ({bound_text(symbol, unit, estimates[key])}; {why})"
            for key, (symbol, unit) in CONTACT_QUANTITIES.items() if key in estimates}


def omega0_note(omega0):
    """Why a fitted ω0 is not determined, with the data's bound on it, or ''.

    ω0 itself keeps the value and error the fit ended at (an error that is often infinite);
    this note says what they mean, as :func:`not_determined` does for β, k and γ.

    Parameters
    ----------
    omega0 : Estimate-like or None
        A fit's ``omega0`` estimate (any object with ``value``, ``stderr``, ``low95``,
        ``high95`` and ``status``).

    Returns
    -------
    str
        "not determined (<bound>; <why>)", e.g. "not determined (ω0 > 5.36e+03 rad/s at
        95 %, no upper bound; omega0 unbounded above at 95 %)"; '' where ω0 is determined or
        fixed (see the module notes).
    """
    if not _omega0_undetermined(omega0):
        return ""
    return (f"not determined ({bound_text('ω0', 'rad/s', omega0)}; "
            f"{_why_omega0_undetermined(omega0)})")


def _why_omega0_undetermined(omega0):
    """The reason, in words, that an undetermined ω0 is not determined."""
    if math.isfinite(omega0.high95):
        relative = omega0.stderr / omega0.value if omega0.value else math.inf
        why = f"omega0's relative error {relative:.2g}"
    else:
        why = "omega0 unbounded above at 95 %"
    if omega0.status == "prior":
        why += " even with the scene's prior"
    return why


def gravity_effect(model, zeta, v_star, speed):
    """|ε_model(ṽ) − ε_gravity-free(ṽ)| at impact speed `speed` (m/s), ṽ = speed/v*.

    Parameters
    ----------
    model : {"Ib", "IIb", "hybrid"}
    zeta : float
        Fitted damping ratio (1).
    v_star : float
        Fitted characteristic speed g/ω0 (m/s).
    speed : float
        Impact speed (m/s).

    Returns
    -------
    float
        The difference in ε (1); NaN where the gravity model captures the ball at that speed.
    """
    from ..physics.models import collide

    vtilde = speed / v_star
    with_gravity = collide(model, zeta, vtilde)
    if bool(np.any(with_gravity.captured)):
        return math.nan
    free = collide(GRAVITY_FREE_COUNTERPART[model], zeta, vtilde)
    # From 1 − ε, which keeps its digits where ε is close to 1.
    return float(abs(np.asarray(with_gravity.one_minus_eps) - np.asarray(free.one_minus_eps)))


def gravity_effect_note(data, results):
    """Plain-words note on gravity in contact against the bounce-to-bounce scatter, or ''.

    Parameters
    ----------
    data : FitData
    results : dict of str -> FitResult
        The scene's fits; the successful gravity models (Ib, IIb, hybrid) are judged at their
        fitted ζ and v*, at their predicted speed of the slowest impact fitted; one whose ω0
        is not determined (see :func:`not_determined`) is said to fit as well in the
        gravity-free limit instead.

    Returns
    -------
    str
        '' without a successful gravity model; else "the data cannot see gravity in contact:
        its effect on ε at the slowest bounce (<v> m/s), X (model), ..., is below the
        bounce-to-bounce scatter, Y" when every model's effect is below the scatter Y of the
        interval ratios (ln-ratio scatter times the ratio at the slowest bounces), else the same
        numbers with "gravity in contact is visible in these data" (or, where every fit misses
        the data by more than 3σ of its χ², that this is no evidence of it, and where a
        gravity-free fit is within ΔAIC = 4 of the best gravity model, that it fits about as
        well, so that the data do not show it); with fewer than
        eight impacts (six ratios) the effects alone, and that the scatter cannot be measured. Where
        no gravity model's ω0 is determined: "the data cannot see gravity in contact: <models>
        fit as well in the gravity-free limit (omega0 not determined)".
    """
    from ..plausibility import _MIN_RATIOS_FOR_SCATTER, ratio_trend

    effects, slowest, undetermined = {}, [], []
    for model, fit in results.items():
        if model not in GRAVITY_FREE_COUNTERPART or not fit.success:
            continue
        if _omega0_undetermined(fit.estimates.get("omega0")):
            # The gravity-free limit fits: the effect at the ω0 the fit ended at means nothing.
            undetermined.append(model)
            continue
        zeta, v_star = fit.estimates["zeta"].value, fit.estimates["v_star"].value
        speeds = np.asarray(fit.predicted["speeds"], float)[data.index]
        speed = float(np.min(speeds))
        if not (zeta >= 0 and v_star > 0 and speed > 0):
            continue
        effect = gravity_effect(model, zeta, v_star, speed)
        if math.isfinite(effect):
            effects[model] = effect
            slowest.append(speed)
    free_limit = (f"{', '.join(undetermined)} fit{'s' if len(undetermined) == 1 else ''} "
                  f"as well in the gravity-free limit (omega0 not determined)"
                  if undetermined else "")
    if not effects:
        return f"the data cannot see gravity in contact: {free_limit}" if free_limit else ""
    free_limit = f"; {free_limit}" if free_limit else ""
    sizes = ", ".join(f"{effect:.2g} ({model})" for model, effect in effects.items())
    where = f"at the slowest bounce ({min(slowest):.3g} m/s)"
    if data.times.size - 2 < _MIN_RATIOS_FOR_SCATTER:
        # Fewer ratios cannot tell a trend from scatter (as in the plausibility check).
        return (f"gravity in contact changes ε {where} by {sizes}; {data.times.size} impacts "
                f"are too few to measure the bounce-to-bounce scatter against it{free_limit}")
    _, log_scatter = ratio_trend(data.times)
    ratios = np.diff(data.times)[1:] / np.diff(data.times)[:-1]
    # The scatter of ln r about its trend, in units of r (≈ ε) at the slowest bounces.
    scatter = float(log_scatter * np.median(ratios[-min(5, ratios.size):]))
    if max(effects.values()) < scatter:
        return (f"the data cannot see gravity in contact: its effect on ε {where}, {sizes}, "
                f"is below the bounce-to-bounce scatter, {scatter:.2g}{free_limit}")
    misfit = _shared_misfit(data, results)
    free_fit = _gravity_free_fits_as_well(results, effects)
    if free_fit and not misfit:
        # The effect is |ε_gravity − ε_free| at the same ζ; a gravity-free fit's own ζ takes
        # up its mean over the train, and what is left may be below what the data show.
        return (f"gravity in contact would change ε {where} by {sizes} at the fitted "
                f"parameters, above the bounce-to-bounce scatter, {scatter:.2g}; but {free_fit}, "
                f"so the data do not show it{free_limit}")
    if misfit:
        # ζ and v* of fits that miss the data are what the misfit drove them to.
        return (f"gravity in contact would change ε {where} by {sizes} at the fitted "
                f"parameters, above the bounce-to-bounce scatter, {scatter:.2g}; but every fit "
                f"misses the data (reduced chi-square >= {misfit:.3g}), so this is no evidence "
                f"of it{free_limit}")
    return (f"gravity in contact is visible in these data: its effect on ε {where}, {sizes}, "
            f"against a bounce-to-bounce scatter of {scatter:.2g}{free_limit}")


def _gravity_free_fits_as_well(results, effects):
    """"<model> fits about as well (ΔAIC = x against <gravity model>)" where a successful
    gravity-free fit is within :data:`FITS_AS_WELL_AIC` of the best gravity model among
    `effects`, else ''."""
    free = [(fit.aic, model) for model, fit in results.items()
            if model in GRAVITY_FREE_COUNTERPART.values() and fit.success
            and math.isfinite(fit.aic)]
    gravity = [(results[model].aic, model) for model in effects
               if math.isfinite(results[model].aic)]
    if not free or not gravity:
        return ""
    (free_aic, free_model), (gravity_aic, gravity_model) = min(free), min(gravity)
    if free_aic - gravity_aic > FITS_AS_WELL_AIC:
        return ""
    return (f"a gravity-free model fits about as well ({free_model}: ΔAIC = "
            f"{free_aic - gravity_aic:.1f} against {gravity_model})")


def _shared_misfit(data, results):
    """The smallest reduced χ² of the successful fits if every one lies beyond 3σ of its χ²
    distribution (timing errors known), else 0."""
    if not data.sigma_known:
        return 0.0
    fits = [fit for fit in results.values() if fit.success]
    beyond = [fit.chisqr > (dof := max(fit.ndata - fit.nvarys, 1)) + 3.0 * math.sqrt(2.0 * dof)
              for fit in fits]
    return min(fit.redchi for fit in fits) if fits and all(beyond) else 0.0
