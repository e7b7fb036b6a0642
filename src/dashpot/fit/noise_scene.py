"""A scene's fits under the noise model: the restitution-law ladder and the requested dashpot
models, each fitted by :func:`dashpot.fit.fit_noise_model`, and their own selection table.

Opt-in (``fit_scene(..., noise=True)``, the scene key ``noise: true``, ``--noise``): the
deterministic fits and their selection are made as without it, and these fits are added beside
them. Their criteria (AIC = −2 ln L + 2K, BIC = −2 ln L + K ln n) compare the noise fits among
themselves only, never with the deterministic fits' χ²-based ones.
"""

from __future__ import annotations

import numpy as np

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
        Laws first, then the models, each once. A fit that cannot be made (no start values,
        a singular system) is kept with ``success`` false and its reason, as in the
        deterministic fits.
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
    results = {}
    for law in dict.fromkeys(tuple(laws) + tuple(models)):
        try:
            results[law] = fit_noise_model(data, law, scene, accuracy=accuracy)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as error:
            results[law] = failed_noise_fit(data, law, f"fit failed: {error}", data.notes)
        if progress is not None:
            progress(law)
    table, verdict = noise_selection_table(results)
    return results, table, verdict
