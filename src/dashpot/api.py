"""The Python API at the top of the package: read, fit and analyze one recording.

``dashpot.analyze``, ``dashpot.read_impacts``, ``dashpot.load_scene`` and ``dashpot.fit_scene``
are the functions of this module, reached lazily from ``import dashpot`` (which itself loads
none of the scientific stack). They are typed front doors to the library's own steps
(:func:`dashpot.analysis.analyze`, :func:`dashpot.ingest.read_impacts`,
:func:`dashpot.scene.load_scene`, :func:`dashpot.fit.fit_scene`) and compute exactly what they
do; where a scene is asked for, a path to a ``scene.yaml`` is accepted too.

Examples
--------
>>> import dashpot
>>> impacts, scene_fit = dashpot.analyze("drop.wav", "scene.yaml")  # doctest: +SKIP
>>> print(scene_fit.report())                     # what `dashpot analyze` prints  # doctest: +SKIP
>>> scene_fit.parameters                          # one row per model and parameter  # doctest: +SKIP

References
----------
.. [1] S. P. Bartz, "Coefficient of restitution of a linear dashpot on a rigid surface"
   (the five contact models fitted).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Union

if TYPE_CHECKING:  # annotations only: importing them loads pandas, numba and lmfit
    import pandas as pd

    from .fit.results import SceneFit
    from .scene import Scene

__all__ = ["analyze", "read_impacts", "load_scene", "fit_scene"]

PathLike = Union[str, "os.PathLike[str]"]
SceneLike = Union["Scene", str, "os.PathLike[str]", None]


def _scene(scene: SceneLike) -> Scene | None:
    """A Scene as given, or read from the path of a ``scene.yaml``."""
    if isinstance(scene, (str, os.PathLike)):
        return load_scene(scene)
    return scene


def load_scene(path: PathLike) -> Scene:
    """Read and check a ``scene.yaml`` (what is known of the apparatus of one recording).

    Parameters
    ----------
    path : str or os.PathLike
        The scene file; its keys are documented in ``config/README.md``.

    Returns
    -------
    dashpot.scene.Scene
        With ``recording`` resolved against the file's folder and ``name`` defaulting to the
        folder's name (SI units throughout: masses in kg, lengths in m, g in m/s²).

    Raises
    ------
    dashpot.errors.InputError
        A missing or unreadable file, bad YAML, or a scene that breaks the schema: one line
        naming the file and the problem.

    See Also
    --------
    dashpot.scene.load_scene : the function this calls.
    """
    from .scene import load_scene as load

    return load(path)


def read_impacts(path: PathLike, *, kind: str | None = None, flag_length: float | None = None,
                 gate_distance: float | None = None, unit: str | None = None,
                 bumper_position: float | None = None,
                 track: str | None = None) -> pd.DataFrame:
    """The impact table of a recording: one row per impact, sorted by time (SI units).

    Parameters
    ----------
    path : str or os.PathLike
        An audio recording (WAV, FLAC, OGG, MP3, ...) or a lab table (phyphox, timestamps,
        motion sensor, Tracker, photogate; CSV/TSV, .xlsx, .xls, .ods).
    kind : {"audio", "phyphox", "timestamps", "motion_sensor", "photogate"}, optional
        The reader; by default audio from the file's suffix, tables from their headers.
    flag_length : float, optional
        Length of the flag interrupting a photogate, in m (photogate logs need it).
    gate_distance : float, optional
        Distance from the photogate to the bumper, in m.
    unit : {"s", "ms"}, optional
        Time unit of a timestamp table whose header does not say.
    bumper_position : float, optional
        Position of the bumper in m for motion-sensor exports (else inferred).
    track : str, optional
        Which track of a Tracker export holding several (e.g. "mass A").

    Returns
    -------
    pandas.DataFrame
        Columns ``time`` (s), ``time_uncertainty`` (s, 1σ), ``amplitude`` (full scale 1),
        ``impact_speed``, ``rebound_speed``, ``speed_uncertainty`` (m/s, NaN where not
        measured) and ``run``; ``attrs`` holds the source, the sensor and the reader's notes
        (:mod:`dashpot.ingest` documents every column).

    Raises
    ------
    dashpot.errors.InputError
        The file is missing, not a supported recording, unusable, or holds no impact.

    See Also
    --------
    dashpot.ingest.read_impacts : the function this calls.
    """
    from .ingest import read_impacts as read

    return read(path, kind=kind, flag_length=flag_length, gate_distance=gate_distance,
                unit=unit, bumper_position=bumper_position, track=track)


def fit_scene(impacts: pd.DataFrame, scene: SceneLike = None,
              models: Sequence[str] | None = None, *,
              progress: Callable[[str], object] | None = None,
              noise: bool | None = None) -> SceneFit:
    """Fit every requested contact model to a scene's impacts and compare them.

    Parameters
    ----------
    impacts : pandas.DataFrame
        An impact table (:func:`read_impacts`).
    scene : dashpot.scene.Scene, str or os.PathLike, optional
        What is known of the apparatus, or the path of its ``scene.yaml``; by default nothing
        is known (g = 9.80665 m/s², the first impact speed fitted).
    models : sequence of str, optional
        Among "Ia", "Ib", "IIa", "IIb", "hybrid"; default the scene's (all five).
    progress : callable, optional
        Called with each model's name once it is fitted.
    noise : bool, optional
        Also fit the restitution-law ladder and the models under bounce-to-bounce scatter and
        timing jitter; default the scene's ``noise`` key (off).

    Returns
    -------
    dashpot.fit.SceneFit
        ``results`` (model -> FitResult), the selection table and verdict;
        :meth:`~dashpot.fit.SceneFit.report` gives the text summary and
        :attr:`~dashpot.fit.SceneFit.parameters` the table of every estimate (β in 1/s,
        k in N/m, ...).

    Raises
    ------
    ValueError
        Too few impacts for any fit (:func:`analyze` turns this into an InputError naming
        the file).

    See Also
    --------
    dashpot.fit.fit_scene : the function this calls.
    """
    from .fit import fit_scene as fit

    return fit(impacts, _scene(scene), models, progress=progress, noise=noise)


def analyze(recording: PathLike, scene: SceneLike = None, *,
            models: Sequence[str] | None = None, noise: bool | None = None,
            progress: Callable[[int, int, str], object] | None = None,
            ) -> tuple[pd.DataFrame, SceneFit]:
    """Impacts and every requested model fitted, for one recording (``dashpot analyze``'s
    computation, without writing files).

    Parameters
    ----------
    recording : str or os.PathLike
        A recording (any reader of :func:`read_impacts`) or an impact table written by
        ``dashpot impacts`` (read as a table whatever the scene's sensor).
    scene : dashpot.scene.Scene, str or os.PathLike, optional
        What is known of the apparatus, or the path of its ``scene.yaml``; its ``sensor`` and
        ``reader`` options choose and configure the reader.
    models : sequence of str, optional
        Default: the scene's models (all five).
    noise : bool, optional
        Also fit under the noise model; default the scene's ``noise`` key.
    progress : callable, optional
        Called as ``progress(step, total, text)`` after reading the impacts and after each fit.

    Returns
    -------
    impacts : pandas.DataFrame
        The impact table (times in s).
    scene_fit : dashpot.fit.SceneFit
        The fits: ``scene_fit.report()`` is the summary ``dashpot analyze`` prints,
        ``scene_fit.parameters`` the rows of ``<name>-parameters.csv``; write the HDF5 file
        with :func:`dashpot.store.write_scene_fit`.

    Raises
    ------
    dashpot.errors.InputError
        The recording or the scene cannot be read, its impacts are not a ball bouncing to
        rest, or they are too few to fit.

    Notes
    -----
    Of a file holding several runs only the first is fitted (a warning says so);
    :func:`dashpot.analysis.analyze_runs` fits every run on its own and all jointly.

    See Also
    --------
    dashpot.analysis.analyze : the function this calls.
    """
    from .analysis import analyze as run

    return run(recording, _scene(scene), models=models, progress=progress, noise=noise)
