"""scene.yaml files: what a valid one gives; a bad one gives one InputError line naming it."""

import json
import math

import numpy as np
import pytest

from dashpot.analysis import scene_impacts
from dashpot.errors import InputError
from dashpot.physics.models import MODELS
from dashpot.scene import STANDARD_GRAVITY, Known, load_scene, scene_from_mapping
from dashpot.synth.scene import write_scene

CART = dict(beta=1.87, omega0=(255 / 0.506) ** 0.5, g=2.90, v0=1.0)
BALL = dict(beta=20.0, omega0=2 * np.pi * 500, g=9.81, v0=2.0, n_max=12)

# Per sensor kind: the generating parameters, the writer's options and the scene's reader block.
KINDS = {
    "audio": (BALL, {}, {}),
    "phyphox": (BALL, {}, {}),
    # A bare "time" header in ms: only the scene's reader block says the unit.
    "timestamps": (BALL, {"unit": "ms", "declare_unit": False}, {"unit": "ms"}),
    "motion_sensor": (CART, {}, {"bumper_position": 1.0}),
    "photogate": (CART, {"flag_length": 0.02}, {"flag_length": 0.02, "gate_distance": 0.02}),
}


def _write(folder, text):
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "scene.yaml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("kind", list(KINDS))
def test_valid_scene_per_sensor_kind(tmp_path, monkeypatch, kind):
    params, options, reader = KINDS[kind]
    folder = tmp_path / f"{kind}_scene"
    recording = write_scene(folder, kind, seed=2, **params, **options)
    reader_yaml = "".join(f"  {key}: {value}\n" for key, value in reader.items())
    path = _write(folder, f"""\
name: {kind}-1
sensor: {kind}
recording: {recording.name}
models: [IIb, hybrid]
timing_resolution: 2.5e-5
accuracy: fast
apparatus:
  mass: {{value: 0.25, uncertainty: 0.001}}
  stiffness: 5e4
  gravity: 9.81
""" + (f"reader:\n{reader_yaml}" if reader else ""))
    # Relative paths are resolved against the scene's folder, not the working directory.
    monkeypatch.chdir(tmp_path)
    scene = load_scene(path)
    assert scene.name == f"{kind}-1" and scene.sensor == kind
    assert scene.recording == folder / recording.name and scene.recording.is_file()
    assert scene.models == ("IIb", "hybrid")
    assert scene.timing_resolution == 2.5e-5 and scene.accuracy == "fast"
    assert scene.mass == Known(0.25, 0.001)
    assert scene.stiffness == Known(5e4, None)
    assert scene.gravity == 9.81 and scene.driving_acceleration == 9.81
    assert scene.reader == reader
    assert scene.first_impact_speed is None and scene.known_impact_speed is None
    # The scene's sensor and reader options reach the reader.
    impacts = scene_impacts(scene.recording, scene)
    assert impacts.attrs["sensor"] == kind
    assert len(impacts) >= 3 and np.all(np.diff(impacts["time"]) > 0)
    if kind == "timestamps":
        truth = json.loads((folder / "truth.json").read_text())
        np.testing.assert_allclose(impacts["time"], truth["recording"]["impact_times"],
                                   rtol=0, atol=1e-9)
    # Provenance record is plain JSON.
    record = json.loads(json.dumps(scene.as_dict()))
    assert record["mass"] == {"value": 0.25, "uncertainty": 0.001}
    assert record["recording"] == str(folder / recording.name)


def test_incline_gives_g_sin_theta_and_drop_height_gives_the_speed(tmp_path):
    scene = load_scene(_write(tmp_path / "cart", """\
apparatus:
  gravity: 9.81
  incline_angle: 17.2
  drop_height: {value: 0.12, uncertainty: 0.003}
"""))
    g_eff = 9.81 * math.sin(math.radians(17.2))
    assert scene.incline_angle == 17.2
    assert scene.driving_acceleration == pytest.approx(g_eff, rel=1e-15)
    speed = scene.known_impact_speed
    assert speed.value == pytest.approx(math.sqrt(2 * g_eff * 0.12), rel=1e-15)
    # Linear propagation σ_v = |dv/dh| σ_h, checked against a central difference.
    step = 1e-6
    slope = (math.sqrt(2 * g_eff * (0.12 + step)) - math.sqrt(2 * g_eff * (0.12 - step))) / (
        2 * step)
    assert speed.uncertainty == pytest.approx(slope * 0.003, rel=1e-6)
    assert speed.uncertainty == pytest.approx(g_eff * 0.003 / speed.value, rel=1e-15)
    # The record of the scene carries the acceleration the fits use.
    assert scene.as_dict()["driving_acceleration"] == scene.driving_acceleration


def test_g_eff_overrides_incline_and_defaults(tmp_path):
    scene = load_scene(_write(tmp_path / "track", """\
apparatus:
  incline_angle: 30
  g_eff: 2.5
  drop_height: 0.2
"""))
    assert scene.driving_acceleration == 2.5
    # An exact height gives an exact speed (no prior, the speed is fixed).
    assert scene.known_impact_speed == Known(math.sqrt(2 * 2.5 * 0.2), None)
    # Standard gravity and no incline: g_eff = g.
    plain = load_scene(_write(tmp_path / "plain", "apparatus: {drop_height: 1.0}\n"))
    assert plain.gravity == STANDARD_GRAVITY == 9.80665
    assert plain.known_impact_speed.value == pytest.approx(math.sqrt(2 * 9.80665), rel=1e-15)


def test_priors_and_exact_values(tmp_path):
    scene = load_scene(_write(tmp_path / "ball", """\
apparatus:
  mass: 0.0567
  stiffness: {value: 2.0e5, uncertainty: 1e4}
  first_impact_speed: {value: 3, uncertainty: 1}
"""))
    assert scene.mass == Known(0.0567, None)
    assert scene.stiffness == Known(2.0e5, 1e4)
    # Integers in the file become floats, the uncertainty too.
    assert scene.first_impact_speed == Known(3.0, 1.0)
    assert isinstance(scene.first_impact_speed.uncertainty, float)
    assert scene.known_impact_speed is scene.first_impact_speed
    assert scene.drop_height is None


def test_empty_file_gives_the_default_scene_named_after_its_folder(tmp_path):
    scene = load_scene(_write(tmp_path / "run 7 (dropped)", ""))
    # The folder's name is used even though a written name could not contain spaces.
    assert scene.name == "run 7 (dropped)"
    assert scene.models == MODELS and scene.sensor is None and scene.recording is None
    assert scene.gravity == STANDARD_GRAVITY and scene.accuracy == "auto"
    assert scene.mass is None and scene.reader == {}


def test_scene_from_mapping_names_its_source():
    scene = scene_from_mapping({"models": ["Ia"], "apparatus": {"mass": 1}})
    assert scene.name == "scene" and scene.models == ("Ia",) and scene.mass == Known(1.0)
    with pytest.raises(InputError, match=r"^config\.yaml: invalid scene \(apparatus/mass"):
        scene_from_mapping({"apparatus": {"mass": 0}}, source="config.yaml")


BAD_SCENES = [
    ("yaml_syntax", "name: [unclosed\n", ["not valid YAML", "line 2"]),
    ("tab", "name: x\n\tsensor: audio\n", ["not valid YAML", "line 2"]),
    ("list", "- Ia\n- IIb\n", ["must be a mapping"]),
    ("scalar", "just words\n", ["must be a mapping"]),
    ("unknown_key", "nmae: x\n", ["invalid scene", "top level", "'nmae'"]),
    ("unknown_apparatus_key", "apparatus: {radius: 0.02}\n", ["apparatus", "'radius'"]),
    ("negative_mass", "apparatus:\n  mass: -0.1\n", ["apparatus/mass", "-0.1"]),
    ("negative_prior", "apparatus:\n  mass: {value: -0.1, uncertainty: 0.01}\n",
     ["apparatus/mass/value", "-0.1"]),
    ("zero_uncertainty", "apparatus:\n  stiffness: {value: 1.0e4, uncertainty: 0}\n",
     ["apparatus/stiffness/uncertainty"]),
    ("nan_mass", "apparatus:\n  mass: .nan\n", ["apparatus/mass", "not a finite number"]),
    ("unknown_model", "models: [IIb, IIc]\n", ["models/1", "'IIc'"]),
    ("unknown_sensor", "sensor: camera\n", ["sensor", "'camera'"]),
    ("steep_incline", "apparatus: {incline_angle: 120}\n", ["apparatus/incline_angle"]),
    ("string_number", "timing_resolution: fast\n", ["timing_resolution", "'fast'"]),
    ("both_speeds", "apparatus:\n  drop_height: 0.5\n  first_impact_speed: 3.1\n",
     ["first_impact_speed", "drop_height", "not both"]),
    # Absurd magnitudes: a typo or a unit slip, refused with the key named.
    ("gravity_1e300", "apparatus: {gravity: 1e300}\n", ["apparatus/gravity", "maximum"]),
    ("gravity_inf", "apparatus: {gravity: .inf}\n", ["apparatus/gravity"]),
    ("mass_1e308", "apparatus: {mass: 1e308}\n", ["apparatus/mass", "maximum"]),
    ("mass_in_grams", "apparatus: {mass: 2700}\n", ["apparatus/mass", "maximum of 1000"]),
    ("zero_mass", "apparatus: {mass: 0}\n", ["apparatus/mass", "minimum"]),
    ("zero_height", "apparatus: {drop_height: 0}\n", ["apparatus/drop_height", "minimum"]),
    ("height_1e9", "apparatus: {drop_height: 1e9}\n", ["apparatus/drop_height", "maximum"]),
    ("huge_prior_spread", "apparatus: {stiffness: {value: 1e5, uncertainty: 1e300}}\n",
     ["apparatus/stiffness/uncertainty", "maximum"]),
    ("speed_of_light", "apparatus: {first_impact_speed: 3e8}\n",
     ["apparatus/first_impact_speed", "maximum"]),
    ("g_eff_1e-300", "apparatus: {g_eff: 1e-300}\n", ["apparatus/g_eff", "minimum"]),
    ("flat_incline", "apparatus: {incline_angle: 1e-9}\n",
     ["apparatus/incline_angle", "less than the minimum of 0.001 m/s²"]),
    ("tiny_resolution", "timing_resolution: 1e-300\n", ["timing_resolution", "minimum"]),
    ("flag_in_mm", "reader: {flag_length: 20}\n", ["reader/flag_length", "maximum"]),
    ("bumper_far_away", "reader: {bumper_position: -1e300}\n", ["reader/bumper_position"]),
    ("huge_integer", "apparatus:\n  stiffness: 1" + "0" * 400 + "\n",
     ["apparatus/stiffness", "maximum"]),
]


@pytest.mark.parametrize("label,text,fragments", BAD_SCENES, ids=[b[0] for b in BAD_SCENES])
def test_bad_scene_is_one_line_naming_the_file(tmp_path, label, text, fragments):
    path = _write(tmp_path / label, text)
    with pytest.raises(InputError) as caught:
        load_scene(path)
    message = str(caught.value)
    assert "\n" not in message and len(message) < len(str(path)) + 300
    assert message.startswith(f"{path}: ")
    assert caught.value.path == str(path)
    for fragment in fragments:
        assert fragment in message


def test_large_and_small_but_real_apparatus_is_accepted(tmp_path):
    # A heavy cart on a nearly level track, a drop from a building, a stiff steel contact.
    scene = load_scene(_write(tmp_path / "heavy", """\
timing_resolution: 1.0e-6
reader: {flag_length: 0.5, gate_distance: 3.0, bumper_position: -8.5}
apparatus:
  mass: {value: 45.0, uncertainty: 0.5}
  stiffness: 2.0e9
  drop_height: 30
  g_eff: 0.01
"""))
    assert scene.mass == Known(45.0, 0.5) and scene.stiffness == Known(2.0e9)
    assert scene.driving_acceleration == 0.01 and scene.drop_height == Known(30.0)
    assert scene.known_impact_speed.value == pytest.approx(math.sqrt(2 * 0.01 * 30), rel=1e-15)
    tilted = load_scene(_write(tmp_path / "tilted", "apparatus: {incline_angle: 0.1}\n"))
    assert tilted.driving_acceleration == pytest.approx(
        STANDARD_GRAVITY * math.sin(math.radians(0.1)), rel=1e-15)


def test_missing_unreadable_and_binary_scene_files(tmp_path):
    missing = tmp_path / "nowhere" / "scene.yaml"
    with pytest.raises(InputError, match=r"cannot read the scene file \(No such file"):
        load_scene(missing)
    with pytest.raises(InputError) as caught:
        load_scene(tmp_path)  # a folder
    assert str(caught.value).startswith(f"{tmp_path}: cannot read the scene file")
    binary = tmp_path / "latin1.yaml"
    binary.write_bytes("name: caf\xe9\n".encode("latin-1"))
    with pytest.raises(InputError, match="not a text file in UTF-8"):
        load_scene(binary)
    for error in (caught.value,):
        assert "\n" not in str(error)


# --- Bounded YAML: bombs, deep nesting and duplicate keys are one line, fast and small. ---

def _billion_laughs():
    """The classic document: nine levels of nine aliases each, 9⁹ ≈ 3.9e8 strings expanded.

    Placed under ``models``, whose items the schema check walks (and prints), as in the
    report of a scene that ran to 8.4 GB.
    """
    lines = ['models:', '  - &l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for level in range(1, 9):
        lines.append(f"  - &l{level} [" + ", ".join([f"*l{level - 1}"] * 9) + "]")
    return "\n".join(lines) + "\n"


def test_billion_laughs_is_refused_quickly_in_small_memory(tmp_path):
    import time
    import tracemalloc

    path = _write(tmp_path / "bomb", _billion_laughs())
    tracemalloc.start()
    started = time.perf_counter()
    try:
        with pytest.raises(InputError) as caught:
            load_scene(path)
        elapsed = time.perf_counter() - started
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    message = str(caught.value)
    assert message.startswith(f"{path}: refused YAML (") and "\n" not in message
    assert "aliases expand to more than" in message
    assert elapsed < 1.0
    assert peak < 2 * 2**20


@pytest.mark.parametrize("opening,closing", [("[", "]"), ("{a: ", "}")], ids=["list", "mapping"])
def test_ten_thousand_nested_brackets_are_refused_without_recursion_error(
        tmp_path, opening, closing):
    path = _write(tmp_path / "deep", "models: " + opening * 10_000 + "Ia" + closing * 10_000 + "\n")
    with pytest.raises(InputError) as caught:
        load_scene(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: refused YAML (line 1, ") and "\n" not in message
    assert "nested deeper than" in message


def test_block_nesting_just_within_the_bound_loads_and_one_deeper_is_refused(tmp_path):
    from dashpot.safe_yaml import MAX_DEPTH, parse_yaml

    def nested(levels):
        return "".join("  " * depth + "k:\n" for depth in range(levels - 1)) + \
            "  " * (levels - 1) + "k: 1\n"

    document = parse_yaml(nested(MAX_DEPTH))
    for _ in range(MAX_DEPTH):
        document = document["k"]
    assert document == 1
    with pytest.raises(InputError, match=r"line \d+, column \d+: nested deeper than"):
        parse_yaml(nested(MAX_DEPTH + 1), "deep.yaml")


@pytest.mark.parametrize("text,key,line,first", [
    ("apparatus:\n  mass: 0.25\n  gravity: 9.81\n  mass: 0.3\n", "mass", 4, 2),
    ("name: a\nsensor: audio\nname: b\n", "name", 3, 1),
    ("reader: {unit: s, unit: ms}\n", "unit", 1, 1),
], ids=["block", "top_level", "flow"])
def test_duplicate_key_is_an_error_naming_the_key_and_lines(tmp_path, text, key, line, first):
    path = _write(tmp_path / "dup", text)
    with pytest.raises(InputError) as caught:
        load_scene(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: refused YAML (line {line}, ") and "\n" not in message
    assert f"duplicate key '{key}' (also on line {first})" in message


def test_recursive_alias_is_refused(tmp_path):
    path = _write(tmp_path / "loop", "models: &m [Ia, *m]\n")
    with pytest.raises(InputError, match="alias refers to the node that contains it"):
        load_scene(path)


def test_a_few_aliases_and_merge_keys_still_load(tmp_path):
    from dashpot.safe_yaml import load_yaml

    path = tmp_path / "config.yaml"
    path.write_text("defaults: &cart {mass: 0.5, g_eff: 0.3}\n"
                    "a: *cart\n"
                    "b: {<<: *cart, mass: 0.7}\n"
                    "stiffness: 5e4\n", encoding="utf-8")
    document = load_yaml(path)
    assert document["a"] == {"mass": 0.5, "g_eff": 0.3}
    # An explicit key overrides a merged one: that is not a duplicate.
    assert document["b"] == {"mass": 0.7, "g_eff": 0.3}
    assert document["stiffness"] == 50000.0


def test_endless_input_is_refused_at_the_size_limit(tmp_path):
    from dashpot.safe_yaml import MAX_BYTES, load_yaml

    big = tmp_path / "big.yaml"
    with big.open("w", encoding="utf-8") as stream:
        line = "# padding\n" * 1000
        for _ in range(MAX_BYTES // len(line) + 1):
            stream.write(line)
    with pytest.raises(InputError, match=r"big\.yaml: refused YAML \(larger than 16 MiB\)"):
        load_yaml(big)
    # A device that never ends is cut off at the same limit.
    with pytest.raises(InputError, match=r"^/dev/zero: refused YAML \(larger than"):
        load_yaml("/dev/zero")


def test_a_number_too_long_for_python_is_one_line(tmp_path):
    path = _write(tmp_path / "digits", "apparatus:\n  mass: " + "9" * 5000 + "\n")
    with pytest.raises(InputError) as caught:
        load_scene(path)
    assert str(caught.value).startswith(f"{path}: not valid YAML (")
    assert "\n" not in str(caught.value)
