# Scenes of the workflow: folders of scenes_dir, entries of `scenes:` and synthetic scenes.
# Nothing here reads a scene fully: a broken scene.yaml or recording must fail only that
# scene's jobs (the library checks them there), so the DAG is built from a tolerant peek.
import os
import re
import sys
from pathlib import Path

import yaml

from dashpot.ingest import AUDIO_SUFFIXES
from dashpot.synth.scene import RECORDING_NAMES


def _peek(path):
    """The mapping of a scene.yaml, or {} if it cannot be read (its job will say why)."""
    try:
        mapping = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return {}
    return mapping if isinstance(mapping, dict) else {}


def _entry(source, scene_file, mapping, recording):
    sensor = mapping.get("sensor") if isinstance(mapping.get("sensor"), str) else None
    audio = sensor == "audio" if sensor else (
        recording is not None and Path(recording).suffix.lower() in AUDIO_SUFFIXES)
    return {"source": source, "scene_file": scene_file, "recording": recording, "audio": audio}


def _recording_of(mapping, base):
    recording = mapping.get("recording")
    if not isinstance(recording, str):
        return None
    return os.path.normpath(os.path.join(base, recording))


def _collect_scenes():
    scenes = {}
    real = set(config.get("real_scenes", []))
    use_real = config.get("real_data", True)
    shared = config.get("shared_data", "../shared/data")
    if use_real and not os.path.isdir(shared):
        print(f"dashpot: {shared} not found: skipping the real recordings "
              f"({', '.join(sorted(real))}); set real_data: false to silence this",
              file=sys.stderr)
        use_real = False
    for scene_file in sorted(Path(config.get("scenes_dir", "data")).glob("*/scene.yaml")):
        name = scene_file.parent.name
        if name in real and not use_real:
            continue
        mapping = _peek(scene_file)
        scenes[name] = _entry("folder", str(scene_file), mapping,
                              _recording_of(mapping, str(scene_file.parent)))
    for name, mapping in config.get("scenes", {}).items():
        if name in scenes:
            raise ValueError(f"config.yaml: scene {name!r} is both a folder and a config entry")
        scenes[name] = _entry("config", None, mapping, _recording_of(mapping, "."))
    for name, spec in config.get("synthetic", {}).items():
        if name in scenes:
            raise ValueError(f"config.yaml: synthetic scene {name!r} has the name of another scene")
        recording = f"results/synthetic/{name}/{RECORDING_NAMES[spec['kind']]}"
        scenes[name] = _entry("synthetic", None, {"sensor": spec["kind"]}, recording)
    return scenes


SCENES = _collect_scenes()
AUDIO_SCENES = [name for name, scene in SCENES.items() if scene["audio"]]
SCENE_FIGURES = ["intervals", "restitution", "selection"]
THEORY_FIGURES = ["contact_time", "restitution", "critical_speed", "restitution_vs_speed"]


wildcard_constraints:
    scene="|".join(re.escape(name) for name in SCENES) or "(?!x)x",


def fit_input(wildcards):
    """The scene's definition (scene.yaml or synthetic folder) and its recording if present.

    A missing recording is left out, not demanded: the fit job then fails with the reader's
    message in its log, and the other scenes go on (with --keep-going).
    """
    scene = SCENES[wildcards.scene]
    if scene["source"] == "synthetic":
        return {"scene": f"results/synthetic/{wildcards.scene}"}
    inputs = {}
    if scene["scene_file"]:
        inputs["scene"] = scene["scene_file"]
    if scene["recording"] and os.path.isfile(scene["recording"]):
        inputs["recording"] = scene["recording"]
    return inputs


def config_scene(wildcards):
    """The config entry of a scene given in config.yaml, else None."""
    return config.get("scenes", {}).get(wildcards.scene)


def recording_input(wildcards):
    """The recording of an audio scene (for its detection figure), if present (as fit_input)."""
    scene = SCENES[wildcards.scene]
    if scene["source"] == "synthetic":
        return f"results/synthetic/{wildcards.scene}"
    return [scene["recording"]] if os.path.isfile(scene["recording"]) else []


def all_outputs():
    """Every file of a full run: scene files, summary, figures, theory."""
    outputs = expand("results/{scene}.h5", scene=SCENES)
    outputs += ["results/summary.h5", "results/summary.csv"]
    if config.get("scene_plots", True):
        outputs += expand("results/plots/{scene}/{figure}.{ext}", scene=SCENES,
                          figure=SCENE_FIGURES, ext=["png", "pdf"])
        outputs += expand("results/plots/{scene}/detection.{ext}", scene=AUDIO_SCENES,
                          ext=["png", "pdf"])
    outputs += expand("results/theory/{figure}.{ext}", figure=THEORY_FIGURES,
                      ext=["png", "pdf"])
    outputs += ["results/theory/critical_velocity.csv", "results/theory/restitution_vs_zeta.csv"]
    return outputs
