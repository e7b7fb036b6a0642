"""Every requested model fitted to one scene, and the model-selection table over them.
"""

from __future__ import annotations

from dataclasses import replace

from ..scene import Scene
from .covariance import _misfit_bound
from .data import prepare_data
from .model_fit import fit_model
from .noise_scene import fit_noise_scene
from .observability import GRAVITY_FREE_COUNTERPART, gravity_effect_note
from .results import SceneFit
from .settings import NOISE_LAWS


def fit_scene(impacts, scene=None, models=None, *, progress=None, noise=None,
              noise_laws=NOISE_LAWS):
    """Fit every requested model to a scene's impacts and compare them.

    Parameters
    ----------
    impacts : pandas.DataFrame
        Impact table of :mod:`dashpot.ingest`.
    scene : Scene, optional
    models : sequence of str, optional
        Default: the scene's models (all five unless it says otherwise).
    progress : callable, optional
        Called with each model's name once it is fitted (and with each noise fit's).
    noise : bool or "auto", optional
        Also fit the restitution-law ladder and every requested model under the noise model
        (:func:`dashpot.fit.noise_scene.fit_noise_scene`), with their own selection table;
        default: the scene's ``noise`` key. "auto" fits them where the deterministic fits
        cannot describe the data (:func:`noise_model_needed`), and a note in the data's
        notes says which way it went and why. The deterministic fits and their selection are
        the same either way.
    noise_laws : sequence of str, default :data:`dashpot.fit.settings.NOISE_LAWS`
        The ladder's laws fitted under the noise model.

    Returns
    -------
    SceneFit
        The note of :func:`~dashpot.fit.observability.gravity_effect_note` (gravity in contact
        against the bounce-to-bounce scatter) is added to the data's notes and to those of each
        gravity model fitted.
    """
    from ..select import selection_table

    scene = scene or Scene()
    models = tuple(models or scene.models)
    data = prepare_data(impacts, scene)
    results = {}
    for model in models:
        results[model] = fit_model(data, model, scene, uncertainty=scene.uncertainty)
        if progress is not None:
            progress(model)
    # Said once for the scene (printed with its notes) and kept with each gravity model's fit.
    note = gravity_effect_note(data, results)
    if note:
        data.notes.append(note)
        for model, fit in results.items():
            if model in GRAVITY_FREE_COUNTERPART and fit.success:
                fit.notes.append(note)
    selection, verdict = selection_table(results, sigma_known=data.sigma_known)
    scene_fit = SceneFit(scene=scene, data=data, results=results, selection=selection,
                         verdict=verdict)
    setting = scene.noise if noise is None else noise
    if setting == "auto":
        setting, why = noise_model_needed(data, results)
        data.notes.append(why)
    if setting:
        # The note on gravity in contact weighs the deterministic fits (their ζ, v* and
        # misfit): the fits under the noise model start from the scene's notes without it, so
        # that their rows in summary.csv do not say that "every fit misses the data".
        noise_data = (replace(data, notes=[said for said in data.notes if said != note])
                      if note else data)
        (scene_fit.noise_results, scene_fit.noise_selection,
         scene_fit.noise_verdict) = fit_noise_scene(noise_data, scene, models, noise_laws,
                                                    progress=progress)
    return scene_fit


def noise_model_needed(data, results):
    """Whether a scene's impacts need the noise model, judged on its deterministic fits.

    They do where the timing uncertainties are stated and every fitted model misses them: the
    best fit's χ² lies beyond 3σ of its χ² distribution (ν + 3√(2ν)), the size of misfit that
    bounce-to-bounce scatter accumulating along a train produces (Durbin and Koopman, *Time
    Series Analysis by State Space Methods*, 2nd ed., Oxford (2012), ch. 2: a random walk
    fitted as a deterministic trend). Where the uncertainties are not stated the fits scale
    them to the scatter, and χ² cannot tell: the deterministic fits are kept.

    Returns
    -------
    needed : bool
    why : str
        A note saying which way it went, with the best fit's χ²/ν.
    """
    fitted = [fit for fit in results.values() if fit.success]
    if not data.sigma_known:
        return False, ("noise model not fitted (noise: auto): the impact times state no "
                       "uncertainties, so the deterministic fits cannot show a misfit; "
                       "noise: true fits it anyway")
    if not fitted:
        return True, "noise model fitted (noise: auto): no deterministic fit succeeded"
    best = min(fitted, key=lambda fit: fit.chisqr)
    dof = max(best.ndata - best.nvarys, 1)
    if best.chisqr > _misfit_bound(dof):
        return True, (f"noise model fitted (noise: auto): every deterministic fit misses the "
                      f"impact times' stated uncertainties (best chi2/nu = {best.redchi:.3g} "
                      f"for {dof} degrees of freedom)")
    return False, (f"noise model not fitted (noise: auto): the deterministic train describes "
                   f"the impact times within their stated uncertainties (best chi2/nu = "
                   f"{best.redchi:.3g}); noise: true fits it anyway")
