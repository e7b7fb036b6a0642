"""The steps of the workflow and of ``dashpot analyze``, each one library call.

The Snakemake scripts in ``workflow/scripts/`` and the command line only move files in and
out; what happens to a scene is here:

- :func:`write_synthetic_scene`: a synthetic recording, its ``truth.json`` and the
  ``scene.yaml`` saying what the experimenter knows;
- :func:`workflow_scene`: the scene of a ``scene.yaml`` (or of a config entry), checked;
- :func:`is_audio`: whether a scene's recording is sound (it then gets a detection figure).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from .errors import InputError
from .ingest import AUDIO_SUFFIXES
from .scene import load_scene, scene_from_mapping

__all__ = ["write_synthetic_scene", "workflow_scene", "is_audio"]


def write_synthetic_scene(directory, spec, *, name, overwrite=False):
    """Write a synthetic scene folder: recording, ``truth.json`` and ``scene.yaml``.

    Parameters
    ----------
    directory : str or os.PathLike
        Folder to create.
    spec : dict
        ``kind``, ``model``, ``beta`` (1/s), ``omega0`` (rad/s), ``g`` (m/s²), ``v0`` (m/s),
        ``n_max``, ``seed`` for :func:`dashpot.synth.scene.write_scene`; ``options`` for the
        writer of `kind`; ``scene``: the scene.yaml keys of what is known (name, recording
        and sensor are filled in here).
    name : str
        Scene name.
    overwrite : bool, default False
        Replace the recording, ``truth.json`` and ``scene.yaml`` if they exist. Without it,
        if any of them exists, none is written.

    Returns
    -------
    pathlib.Path
        The ``scene.yaml`` written.

    Raises
    ------
    InputError
        The scene keys break the scene schema, or one of the files exists and `overwrite`
        is false ("<path>: exists; pass overwrite=True to replace it"); both checked before
        anything is written.
    """
    import yaml

    from .atomic import atomic_path, refuse_existing
    from .synth.scene import RECORDING_NAMES, write_scene

    spec = dict(spec)
    kind = spec.pop("kind")
    options = dict(spec.pop("options", None) or {})
    known = dict(spec.pop("scene", None) or {})
    mapping = {"name": name, "recording": RECORDING_NAMES[kind], "sensor": kind, **known}
    directory = Path(directory)
    scene_from_mapping(mapping, source=f"synthetic scene {name}", base=directory)
    target = directory / "scene.yaml"
    refuse_existing(directory / RECORDING_NAMES[kind], directory / "truth.json", target,
                    overwrite=overwrite)
    write_scene(directory, kind, **spec, **options, overwrite=overwrite)
    with atomic_path(target, overwrite=overwrite) as temporary:
        temporary.write_text("# Written by the workflow's simulate rule from config/config.yaml.\n"
                             + yaml.safe_dump(mapping, sort_keys=False), encoding="utf-8")
    return target


def workflow_scene(name, *, scene_file=None, mapping=None):
    """The checked scene of a workflow scene, named `name` unless it names itself.

    Parameters
    ----------
    name : str
        Scene name of the workflow (folder name or config key).
    scene_file : str or os.PathLike, optional
        Its ``scene.yaml``, or a folder holding one.
    mapping : dict, optional
        A config entry instead (``recording`` relative to the working directory).

    Raises
    ------
    InputError
        Unreadable or invalid scene, or no recording given.
    """
    if mapping is not None:
        source = f"config.yaml: scenes/{name}"
        scene = scene_from_mapping(mapping, source=source, base=".")
        if "name" not in mapping:
            scene = replace(scene, name=name)
    else:
        source = Path(scene_file)
        if source.is_dir():
            source = source / "scene.yaml"
        scene = load_scene(source)
    if scene.recording is None:
        raise InputError(source, "no recording given (key 'recording')")
    return scene


def is_audio(scene):
    """True if the scene's recording is sound (sensor "audio", or an audio file suffix)."""
    if scene.sensor is not None:
        return scene.sensor == "audio"
    return scene.recording is not None and Path(scene.recording).suffix.lower() in AUDIO_SUFFIXES
