"""Every requested model fitted to one scene, and the model-selection table over them.
"""

from __future__ import annotations

from ..scene import Scene
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
    noise : bool, optional
        Also fit the restitution-law ladder and every requested model under the noise model
        (:func:`dashpot.fit.noise_scene.fit_noise_scene`), with their own selection table;
        default: the scene's ``noise`` key (off). The deterministic fits and their selection
        are the same either way.
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
    if scene.noise if noise is None else noise:
        (scene_fit.noise_results, scene_fit.noise_selection,
         scene_fit.noise_verdict) = fit_noise_scene(data, scene, models, noise_laws,
                                                    progress=progress)
    return scene_fit
