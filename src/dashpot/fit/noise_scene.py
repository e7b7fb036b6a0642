"""A scene's fits under the noise model: the restitution-law ladder and the requested dashpot
models, each fitted by :func:`dashpot.fit.fit_noise_model`, and their own selection table.

Opt-in (``fit_scene(..., noise=True)``, the scene key ``noise: true``, ``--noise``): the
deterministic fits and their selection are made as without it, and these fits are added beside
them. Their criteria (AIC = −2 ln L + 2K, BIC = −2 ln L + K ln n) compare the noise fits among
themselves only, never with the deterministic fits' χ²-based ones.

Flight effects as rungs of the ladder (:mod:`dashpot.noise_selection`): each effect of the
registry :data:`dashpot.physics.effects.FLIGHT_EFFECTS` that the scene does not put in every
fit and whose ``tried`` accepts the scene is fitted as a rung on the law it ``extends`` (the
constant law), right after that law. Where the scene gives no mass and diameter,
``constant+drag`` (the constant law with a free drag constant k_d ≥ 0) is fitted beside the
constant law; with them every fit carries k_d with the scene's C_d prior and there is no drag
rung. On cart and incline scenes (:attr:`dashpot.scene.Scene.tries_friction`)
``constant+friction`` adds the friction deceleration of the flights (a_away = g_eff + f,
a_toward = g_eff − f, g_eff with the scene's prior), as the deterministic fits do.
"""

from __future__ import annotations

import numpy as np

from ..physics.effects import FLIGHT_EFFECTS
from ..physics.laws import LAWS
from .noise_fit import failed_noise_fit, fit_noise_model
from .settings import NOISE_LAWS

__all__ = ["fit_noise_scene"]


def fit_noise_scene(data, scene, models, laws=NOISE_LAWS, *, progress=None, accuracy=None):
    """Fit every law of the ladder and every requested dashpot model under the noise model.

    Parameters
    ----------
    data : FitData
        From :func:`dashpot.fit.prepare_data`.
    scene : Scene
        Known quantities and air drag (:func:`dashpot.fit.fit_noise_model`).
    models : sequence of str
        Dashpot models, fitted after the laws.
    laws : sequence of str, default :data:`dashpot.fit.settings.NOISE_LAWS`
        Restitution laws of :data:`dashpot.physics.laws.LAWS`.
    progress : callable, optional
        Called with each law's or model's name once it is fitted.
    accuracy : {"auto", "fast", "standard", "exact"}, optional
        Evaluation of the laws in the filter (:func:`dashpot.fit.fit_noise_model`; default
        the scene's, "auto" unless it says otherwise): "auto"
        takes, per law, the cheapest level whose likelihood at the best fit is within 0.01
        of the direct evaluation's; each result records the level in ``accuracy`` and the
        measured error of its tabulated step map in ``error_bound``.

    Returns
    -------
    results : dict of str -> NoiseFitResult
        Laws first (the flight effects' rungs right after the law they extend, the last
        registered first: ``constant+friction``, ``constant+drag``), then the models, each
        once. A fit that cannot be made (no start values, a singular system) is kept with
        ``success`` false and its reason, as in the deterministic fits.
    table : pandas.DataFrame
    verdict : str
        Of :func:`dashpot.noise_selection.noise_selection_table`.

    Raises
    ------
    ValueError
        A name that is no law of :data:`dashpot.physics.laws.LAWS`.
    """
    from ..noise_selection import noise_selection_table

    unknown = [law for law in tuple(laws) + tuple(models) if law not in LAWS]
    if unknown:
        raise ValueError(f"unknown restitution law or model {unknown[0]!r}; use "
                         f"{', '.join(LAWS)}")
    fits = [(law, law, ()) for law in dict.fromkeys(tuple(laws) + tuple(models))]
    # The flight's effects as rungs right after the law each extends (module notes): each
    # inserted in front of the rungs before it.
    for effect in FLIGHT_EFFECTS.values():
        if effect.extends in laws and effect.has_rung(scene):
            at = 1 + [name for name, _, _ in fits].index(effect.extends)
            fits.insert(at, (effect.rung, effect.extends, (effect.name,)))
    results = {}
    for name, law, effects in fits:
        try:
            results[name] = fit_noise_model(data, law, scene, accuracy=accuracy,
                                            effects=effects)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as error:
            results[name] = failed_noise_fit(data, name, f"fit failed: {error}", data.notes)
        if progress is not None:
            progress(name)
    table, verdict = noise_selection_table(results)
    return results, table, verdict
