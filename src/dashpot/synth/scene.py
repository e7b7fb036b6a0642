"""A whole synthetic scene: a bounce train with known parameters written as a lab would record it.

One call draws the train from :func:`dashpot.bounce_sequence`, writes the recording of the chosen
kind with the writers of :mod:`dashpot.synth.audio` and :mod:`dashpot.synth.tables`, and writes a
sidecar ``truth.json`` with the generating parameters and the true impact times, so that the
readers and the fits can be checked against the truth. Deterministic for a given seed.

A light ball can bounce in air (a drag constant, or its mass and diameter): the train then has
drag-true flights (:func:`dashpot.bounce_sequence` with ``drag``) and ``truth.json`` records
the drag. Without drag the files are those of the gravity-only train, byte for byte.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..atomic import atomic_path, refuse_existing
from ..physics import bounce_sequence
from .tables import (
    write_motion_sensor,
    write_phyphox_stopwatch,
    write_photogate,
    write_timestamps,
)
from .train import air_drag

__all__ = ["SCENE_KINDS", "write_scene"]

SCENE_KINDS = ("audio", "phyphox", "timestamps", "motion_sensor", "photogate")
RECORDING_NAMES = {"audio": "recording.wav", "phyphox": "phyphox.csv",
                   "timestamps": "timestamps.csv", "motion_sensor": "motion.csv",
                   "photogate": "photogate.csv"}


def _jsonable(value):
    """Plain Python containers and numbers for json (numpy arrays and scalars converted)."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def write_scene(directory, kind, *, model="hybrid", beta, omega0, g, v0, n_max=60, v_min=0.0,
                seed=0, drag=None, ball=None, overwrite=False, **options):
    """Write one synthetic recording of a bounce train and its ``truth.json`` sidecar.

    Parameters
    ----------
    directory : str or os.PathLike
        Scene folder to create or fill.
    kind : {"audio", "phyphox", "timestamps", "motion_sensor", "photogate"}
        What the lab recorded.
    model : str, default "hybrid"
        Contact model generating the train.
    beta : float
        Damping rate β in 1/s.
    omega0 : float
        Undamped angular frequency ω0 of the contact in rad/s.
    g : float
        Acceleration towards the surface in m/s² (g·sin θ for a cart on an incline); with
        `ball`, the local gravity (buoyancy and added mass lower it).
    v0 : float
        First impact speed in m/s.
    n_max, v_min : optional
        Stopping rule of the train (see :func:`dashpot.bounce_sequence`).
    seed : int, default 0
        Seed of every random draw (noise), for reproducible files.
    drag : float, optional
        Air drag constant k_d in 1/m of a ball flying under `g` (audio, phyphox, timestamps).
    ball : dict, optional
        Instead of `drag`: the ball's ``mass`` (kg), ``diameter`` (m), ``drag_coefficient``
        (default 0.45) and ``air_density`` (kg/m³, default 1.204), see
        :func:`dashpot.synth.train.air_drag`.
    overwrite : bool, default False
        Replace the recording and ``truth.json`` if they exist. Without it, if either exists,
        neither is written.
    **options
        Passed to the writer of `kind` (e.g. ``snr_db``, ``echo_delay`` for audio,
        ``flag_length`` for a photogate).

    Returns
    -------
    pathlib.Path
        The recording written.

    Raises
    ------
    InputError
        The recording or ``truth.json`` exists and `overwrite` is false ("<path>: exists;
        pass overwrite=True to replace it"); both are left as they were.
    """
    if kind not in SCENE_KINDS:
        raise ValueError(f"kind must be one of {', '.join(SCENE_KINDS)}; got {kind!r}")
    directory = Path(directory)
    recording = directory / RECORDING_NAMES[kind]
    sidecar = directory / "truth.json"
    refuse_existing(recording, sidecar, overwrite=overwrite)  # before either is written
    drag_truth = air_drag(g, drag=drag, ball=ball)
    if drag_truth is None:
        sequence = bounce_sequence(model, beta=beta, omega0=omega0, g=g, v0=v0, n_max=n_max,
                                   v_min=v_min)
    elif kind in ("motion_sensor", "photogate"):
        # Their writers draw a cart's motion between impacts under constant acceleration.
        raise ValueError(f"air drag is modelled for a bouncing ball (audio, phyphox, "
                         f"timestamps), not for a {kind} recording of a cart")
    else:
        sequence = bounce_sequence(model, beta=beta, omega0=omega0,
                                   g=drag_truth["effective_gravity"],
                                   drag=drag_truth["drag_constant"], v0=v0, n_max=n_max,
                                   v_min=v_min)
    directory.mkdir(parents=True, exist_ok=True)
    if kind == "audio":
        # Imported here: the sound synthesis pulls in scipy.signal, which no other kind needs.
        from .audio import impact_sound, write_audio

        sample_rate = options.pop("sample_rate", 44100)
        samples, onsets = impact_sound(sequence.impact_times, sequence.impact_speeds,
                                       sample_rate=sample_rate, seed=seed, **options)
        write_audio(recording, samples, sample_rate, overwrite=overwrite)
        written = {"kind": "audio", "impact_times": onsets, "sample_rate": sample_rate, **options}
    elif kind == "phyphox":
        written = write_phyphox_stopwatch(recording, sequence.impact_times, overwrite=overwrite,
                                          **options)
    elif kind == "timestamps":
        written = write_timestamps(recording, sequence.impact_times, seed=seed,
                                   overwrite=overwrite, **options)
    elif kind == "motion_sensor":
        written = write_motion_sensor(recording, sequence, g_eff=g, seed=seed,
                                      overwrite=overwrite, **options)
    else:
        written = write_photogate(recording, sequence, g_eff=g, seed=seed, overwrite=overwrite,
                                  **options)
    truth = {
        "generator": {"model": model, "beta": beta, "omega0": omega0, "g": g, "v0": v0,
                      "n_max": n_max, "v_min": v_min, "seed": seed},
        "units": {"beta": "1/s", "omega0": "rad/s", "g": "m/s^2", "v0": "m/s",
                  "impact_times": "s", "impact_speeds": "m/s", "contact_durations": "s"},
        "sequence": {"impact_times": sequence.impact_times,
                     "impact_speeds": sequence.impact_speeds,
                     "contact_durations": sequence.contact_durations,
                     "restitution": sequence.restitution, "stop_reason": sequence.stop_reason},
        "recording": {"file": recording.name, **written},
    }
    if drag_truth is not None:
        # Only with drag: the sidecar of a gravity-only train stays as it was.
        truth["drag"] = drag_truth
        truth["units"].update(drag_constant="1/m", effective_gravity="m/s^2",
                              terminal_speed="m/s", gravity="m/s^2", mass="kg", diameter="m",
                              air_density="kg/m^3")
    with atomic_path(sidecar, overwrite=overwrite) as temporary:
        temporary.write_text(json.dumps(_jsonable(truth), indent=1, allow_nan=True))
    return recording
