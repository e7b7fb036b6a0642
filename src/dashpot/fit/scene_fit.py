"""Every requested model fitted to one scene, and the model-selection table over them.
"""

from __future__ import annotations

from ..scene import Scene
from .data import prepare_data
from .model_fit import fit_model
from .results import SceneFit


def fit_scene(impacts, scene=None, models=None, *, progress=None):
    """Fit every requested model to a scene's impacts and compare them.

    Parameters
    ----------
    impacts : pandas.DataFrame
        Impact table of :mod:`dashpot.ingest`.
    scene : Scene, optional
    models : sequence of str, optional
        Default: the scene's models (all five unless it says otherwise).
    progress : callable, optional
        Called with each model's name once it is fitted.

    Returns
    -------
    SceneFit
    """
    from ..select import selection_table

    scene = scene or Scene()
    models = tuple(models or scene.models)
    data = prepare_data(impacts, scene)
    results = {}
    for model in models:
        results[model] = fit_model(data, model, scene)
        if progress is not None:
            progress(model)
    selection, verdict = selection_table(results, sigma_known=data.sigma_known)
    return SceneFit(scene=scene, data=data, results=results, selection=selection,
                    verdict=verdict)
