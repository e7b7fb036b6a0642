"""Selection among the fits under the noise model, by nested steps: which effects do the data
require?

Every law or model of the noise fits adds one effect to a simpler rung (the laws' and models'
from their registry entries, :data:`dashpot.physics.laws.LAWS`; the flight effects' rungs from
theirs, :data:`dashpot.physics.effects.FLIGHT_EFFECTS`, each with the note its verdict carries):

===========================================  ==================  =========================
fit                                          effect              simpler rung
===========================================  ==================  =========================
``constant``                                 (the base)          —
``linear``, ``quadratic``, ``power``,        speed term          ``constant``
``viscoelastic-hertz``, ``hunt-crossley``
``constant+drag``                            drag                ``constant``
``constant+friction``                        friction            ``constant``
``Ia``, ``IIa``                              contact duration    ``constant``
``Ib``                                       gravity in contact  ``Ia``
``IIb``, ``hybrid``                          gravity in contact  ``IIa``
===========================================  ==================  =========================

(The drag rung is fitted only where the scene gives no mass and diameter: k_d is then free,
and drag is degenerate with a speed-dependent ε (ε = e0 − c·v² fits about as well), which the
verdict says; with them every fit carries k_d with the scene's C_d prior. The dashpot models'
gravity-free limit v* → 0 is a constant ε with no contact duration; the
gravity models' is their gravity-free counterpart's.) A fit is *kept* only if its BIC is at
least :data:`NESTED_STEP_BIC` = 6 below that of its simpler rung, or of the next simpler one
kept where that rung was not (ΔBIC ≥ 6 is "strong" evidence, 2 ln B ≥ 6 for the Bayes factor
B that ΔBIC approximates [2]_). The selected fit is the kept one of lowest BIC; an effect is
required where some fit carrying it is kept. Akaike weights are reported beside, from
:func:`dashpot.select.selection_table` (on ΔQAIC where even the best noise fit misfits its
innovations; ΔBIC is then divided by the same ĉ).

References
----------
.. [1] K. P. Burnham and D. R. Anderson, *Model Selection and Multimodel Inference*, 2nd ed.,
   Springer (2002), sec. 2.5 (QAIC) and 2.9 (Akaike weights).
.. [2] R. E. Kass and A. E. Raftery, "Bayes factors", J. Am. Statist. Assoc. 90, 773-795
   (1995), sec. 3.2 (2 ln B > 6: strong evidence) and 4.1.3 (BIC).
"""

from __future__ import annotations

import math

import numpy as np

from ._registry import LiveMapping
from .physics.effects import FLIGHT_EFFECTS
from .physics.laws import LAWS
from .select import SELECTION_COLUMNS, _misfit_scale, selection_table

__all__ = ["noise_selection_table", "NOISE_SELECTION_COLUMNS", "NESTED_STEP_BIC", "SIMPLER",
           "EFFECTS"]

NESTED_STEP_BIC = 6.0
BASE = "constant"


def _ladder(law_field, effect_field):
    """``name -> value`` of every rung, read live from the registries: `law_field` of each
    law or model with a simpler rung (RestitutionLaw.simpler, .effect), `effect_field` of each
    flight effect's rung (FlightEffect.extends, .name)."""
    return LiveMapping(lambda: {
        **{name: getattr(law, law_field) for name, law in LAWS.items()
           if law.simpler is not None},
        **{effect.rung: getattr(effect, effect_field) for effect in FLIGHT_EFFECTS.values()}})


SIMPLER = _ladder("simpler", "extends")
"""The simpler rung of each law or model (see the module notes)."""
EFFECTS = _ladder("effect", "name")
"""The effect each law or model adds to its simpler rung."""
NOISE_SELECTION_COLUMNS = SELECTION_COLUMNS + (
    "neg2_log_likelihood", "sigma_eps", "sigma_j", "effect", "simpler", "bic_gain", "kept",
    "selected")


def noise_selection_table(results):
    """Selection table and verdict of the fits under the noise model.

    Parameters
    ----------
    results : dict of str -> NoiseFitResult
        Keyed by law or model name (:func:`dashpot.fit.noise_scene.fit_noise_scene`).

    Returns
    -------
    table : pandas.DataFrame
        Columns :data:`NOISE_SELECTION_COLUMNS`: those of :func:`dashpot.select.selection_table`
        (with the timing errors taken as known: the noise fits fit them), then −2 ln L, the
        fitted σ_ε (1) and σ_j (s), the ``effect`` the fit adds and its ``simpler`` rung (the
        one compared with: empty for the base or where none was fitted), ``bic_gain`` = BIC of
        that rung − BIC of this fit (divided by ĉ where the best fit misfits; NaN where there
        is no rung or a fit failed), ``kept`` (the nested-steps rule) and ``selected``.
    verdict : str
        Plain words: the fit selected, the effects the data required and those they did not,
        each with its best ΔBIC against its simpler rung; an effect that no fit adding it
        earned on its own step but that a kept fit carries from a simpler rung (the contact
        duration of a kept Ib where Ia alone was not kept) is required, "carried by" that fit.
    """
    table, _ = selection_table(results, sigma_known=True)
    rows = {name: table[name].to_numpy() for name in SELECTION_COLUMNS}
    c_hat = _misfit_scale(rows, True)
    names = list(results)
    fits = [results[name] for name in names]
    usable = {name: bool(fit.success) and math.isfinite(fit.bic)
              for name, fit in zip(names, fits)}

    def estimate(fit, key):
        value = fit.estimates.get(key)
        return value.value if value is not None else math.nan

    table["neg2_log_likelihood"] = [float(getattr(fit, "neg2_log_likelihood", math.nan))
                                    for fit in fits]
    table["sigma_eps"] = [estimate(fit, "sigma_eps") for fit in fits]
    table["sigma_j"] = [estimate(fit, "sigma_j") for fit in fits]
    kept, simpler, gain = {}, {}, {}
    base_ok = usable.get(BASE, False)
    # Simplest first: a fit's rung is decided before the fit itself.
    for name in sorted(names, key=_depth):
        rung = SIMPLER.get(name)
        # The nearest simpler rung that was fitted and kept.
        while rung is not None and not kept.get(rung, False):
            rung = SIMPLER.get(rung)
        simpler[name] = rung or ""
        if name == BASE:
            kept[name] = usable[name]
        elif rung is None or not usable[name]:
            # No rung to compare with: kept only where there is no base at all.
            kept[name] = usable[name] and not base_ok
        else:
            gain[name] = (results[rung].bic - results[name].bic) / c_hat
            kept[name] = gain[name] >= NESTED_STEP_BIC
    table["effect"] = [EFFECTS.get(name, "") for name in names]
    table["simpler"] = [simpler[name] for name in names]
    table["bic_gain"] = [gain.get(name, math.nan) for name in names]
    table["kept"] = [kept[name] for name in names]
    candidates = [name for name in names if kept[name]]
    chosen = min(candidates, key=lambda name: results[name].bic) if candidates else None
    table["selected"] = [name == chosen for name in names]
    table = table[list(NOISE_SELECTION_COLUMNS)]
    return table, _verdict(results, table, chosen, base_ok, c_hat)


def _depth(name):
    """Steps from `name` down to the base through SIMPLER."""
    depth = 0
    while name in SIMPLER:
        name, depth = SIMPLER[name], depth + 1
    return depth


def carried_effects(name):
    """Effects a law or model carries: its own and those of its simpler rungs."""
    effects = set()
    while name in SIMPLER:
        effects.add(EFFECTS[name])
        name = SIMPLER[name]
    return effects


def _verdict(results, table, chosen, base_ok, c_hat):
    """Plain-words reading of the noise selection table."""
    if chosen is None:
        return "noise model: no law or model could be fitted to these data"
    fit = results[chosen]
    sigma_eps = fit.estimates.get("sigma_eps")
    scatter = (f", σ_ε = {100 * sigma_eps.value:.2g} %" if sigma_eps is not None else "")
    weight = float(table.loc[table["model"] == chosen, "akaike_weight"].iloc[0])
    head = (f"noise model: {chosen} selected (Akaike weight {weight:.2f}{scatter}, "
            f"χ²/ν of the innovations {fit.redchi:.3g})")
    if c_hat != 1.0:
        head += (f"; even the best fit misfits its innovations (reduced chi-square "
                 f"{c_hat:.3g}): Akaike weights and BIC steps on its scale (QAIC)")
    if not base_ok:
        return (f"{head}; the nested steps need the constant law, which was not fitted: "
                f"chosen on BIC alone")
    required, not_required = [], []
    # Kept fits, the selected one first: the one named as carrying an effect it did not add.
    kept = sorted(table.loc[table["kept"], "model"], key=lambda name: name != chosen)
    for effect in dict.fromkeys(e for e in table["effect"] if e):
        rows = table[(table["effect"] == effect) & np.isfinite(table["bic_gain"])]
        if rows.empty:
            continue
        # Gains equal at the precision shown go to the first in the table's order: which of
        # them is larger by rounding noise depends on the platform's arithmetic.
        best = rows.loc[rows["bic_gain"].round(1).idxmax()]
        text = f"{best['model']}: ΔBIC = {best['bic_gain']:.1f} against {best['simpler']}"
        # Required where some kept fit carries the effect: it adds it, or a simpler rung of
        # its own did (Ib has the contact duration of Ia even where Ia alone was not kept).
        carrier = next((name for name in kept if effect in carried_effects(name)), None)
        if bool(best["kept"]):
            required.append(f"{effect} ({text})")
        elif carrier is not None:
            required.append(f"{effect} (carried by {carrier}; {text})")
        else:
            not_required.append(f"{effect} ({text})")
    parts = [head]
    parts.append("the data required " + (", ".join(required) if required else
                                          "no effect beyond a constant restitution"))
    if not_required:
        parts.append(f"not required (ΔBIC < {NESTED_STEP_BIC:g}): " + ", ".join(not_required))
    # Each flight effect's caveat where its rung was tried, then what the selected fit
    # carries from the scene (drag with the scene's C_d prior).
    tried = set(table["effect"])
    parts += [effect.caveat for effect in FLIGHT_EFFECTS.values()
              if effect.name in tried and effect.caveat]
    for effect in FLIGHT_EFFECTS.values():
        note = effect.carried(fit, chosen) if effect.carried is not None else None
        if note:
            parts.append(note)
    return "; ".join(parts)
