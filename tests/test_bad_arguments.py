"""Out-of-range numbers, on the command line, in a scene or in the API: one line, exit 2, no output.

Each case was a traceback, or an empty or nonsensical table with exit status 0, before.
"""

import contextlib
import io
import math
import warnings

import numpy as np
import pytest
from scipy import signal

from dashpot.bounces import bounce_table
from dashpot.cli import main
from dashpot.errors import InputError
from dashpot.ingest.audio import MIN_SAMPLE_RATE, detect_impacts
from dashpot.ingest.tables import read_motion_sensor, read_photogate
from dashpot.physics import surrogate as sg
from dashpot.synth.audio import impact_sound, write_audio
from dashpot.synth.scene import write_scene

CART = dict(beta=1.87, omega0=(255 / 0.506) ** 0.5, g=2.90, v0=1.0)
BALL = dict(beta=20.0, omega0=2 * np.pi * 500, g=9.81, v0=2.0, n_max=12)


def _run(argv):
    """Exit status and standard error of the command (argparse's errors included)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = main([str(part) for part in argv])
        except SystemExit as stop:  # argparse refuses an option before main's own handling
            status = stop.code
    return status, err.getvalue()


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """One recording or table of each kind the cases need (seeds not tuned on)."""
    folder = tmp_path_factory.mktemp("inputs")
    made = {
        "photogate": write_scene(folder / "gate", "photogate", seed=71, flag_length=0.02,
                                 **CART),
        "motion": write_scene(folder / "motion", "motion_sensor", seed=72, **CART),
        "timestamps": write_scene(folder / "ball", "timestamps", seed=73, **BALL),
    }
    impacts = folder / "impacts.csv"
    assert _run(["impacts", made["timestamps"], "-o", impacts])[0] == 0
    made["impacts"] = impacts
    rng = np.random.default_rng(74)
    for rate in (200, 222):  # below the high-pass's limit (0.45 × rate > 100 Hz)
        made[f"wav{rate}"] = folder / f"low_{rate}.wav"
        write_audio(made[f"wav{rate}"], 0.01 * rng.standard_normal(5 * rate), rate)
    # A real bounce train at 48 kHz resampled to 4 kHz: the detector's windows collapse.
    times = np.cumsum(0.4 * 0.85 ** np.arange(10))
    sound, _ = impact_sound(times, 2.0 * 0.85 ** np.arange(10), sample_rate=48000, seed=76)
    made["wav4000"] = folder / "bounces_4000.wav"
    write_audio(made["wav4000"], np.clip(signal.resample_poly(sound, 1, 12), -1, 1), 4000)
    return made


SCENE = "apparatus:\n  {}\n"

# (id, argv with {name} placeholders for the inputs and {out} for the output, what the one
# line must contain besides the option or file it names).
CASES = [
    ("flag_length_negative", ["impacts", "{photogate}", "--flag-length", "-1"], "--flag-length"),
    ("flag_length_nan", ["impacts", "{photogate}", "--flag-length", "nan"], "--flag-length"),
    ("flag_length_inf", ["impacts", "{photogate}", "--flag-length", "inf"], "--flag-length"),
    ("flag_length_zero", ["impacts", "{photogate}", "--flag-length", "0"], "--flag-length"),
    ("flag_length_overflow", ["impacts", "{photogate}", "--flag-length", "1e400"],
     "--flag-length"),
    ("flag_length_metres_for_mm", ["impacts", "{photogate}", "--flag-length", "20"],
     "--flag-length"),
    ("flag_length_text", ["impacts", "{photogate}", "--flag-length", "2cm"], "--flag-length"),
    ("gate_distance_negative",
     ["impacts", "{photogate}", "--flag-length", "0.02", "--gate-distance", "-0.02"],
     "--gate-distance"),
    ("gate_distance_inf",
     ["impacts", "{photogate}", "--flag-length", "0.02", "--gate-distance", "inf"],
     "--gate-distance"),
    ("gate_distance_nan",
     ["impacts", "{photogate}", "--flag-length", "0.02", "--gate-distance", "nan"],
     "--gate-distance"),
    ("bumper_position_nan", ["impacts", "{motion}", "--bumper-position", "nan"],
     "--bumper-position"),
    ("bumper_position_inf", ["impacts", "{motion}", "--bumper-position", "inf"],
     "--bumper-position"),
    ("bumper_position_huge", ["impacts", "{motion}", "--bumper-position", "1e300"],
     "--bumper-position"),
    # In range but where the cart never is: no impact can be timed, and an empty table with
    # exit status 0 would look like a result.
    ("bumper_position_off_the_track", ["impacts", "{motion}", "--bumper-position", "0.5"],
     "{motion}"),
    ("contact_duration_longer_than_intervals",
     ["bounces", "{impacts}", "--contact-duration", "10"], "{impacts}"),
    ("contact_duration_negative", ["bounces", "{impacts}", "--contact-duration", "-0.001"],
     "--contact-duration"),
    ("contact_duration_nan", ["bounces", "{impacts}", "--contact-duration", "nan"],
     "--contact-duration"),
    ("g_huge", ["bounces", "{impacts}", "--g", "1e300"], "--g"),
    ("g_zero", ["bounces", "{impacts}", "--g", "0"], "--g"),
    ("sample_rate_200", ["impacts", "{wav200}"], "{wav200}"),
    ("sample_rate_222", ["impacts", "{wav222}"], "{wav222}"),
    ("sample_rate_4000", ["impacts", "{wav4000}"], "{wav4000}"),
    ("scene_gravity_1e300", ["fit", "{timestamps}", "--scene", SCENE.format("gravity: 1e300")],
     "apparatus/gravity"),
    ("scene_mass_1e308", ["fit", "{timestamps}", "--scene", SCENE.format("mass: 1e308")],
     "apparatus/mass"),
    ("scene_mass_zero", ["fit", "{timestamps}", "--scene", SCENE.format("mass: 0")],
     "apparatus/mass"),
    ("scene_prior_huge_uncertainty",
     ["fit", "{timestamps}", "--scene", SCENE.format("mass: {value: 0.1, uncertainty: 1e300}")],
     "apparatus/mass/uncertainty"),
    ("scene_drop_height_negative",
     ["fit", "{timestamps}", "--scene", SCENE.format("drop_height: -0.5")],
     "apparatus/drop_height"),
    ("scene_drop_height_zero",
     ["fit", "{timestamps}", "--scene", SCENE.format("drop_height: 0")],
     "apparatus/drop_height"),
    ("scene_stiffness_1e300",
     ["fit", "{timestamps}", "--scene", SCENE.format("stiffness: 1e300")],
     "apparatus/stiffness"),
    ("scene_g_eff_tiny", ["fit", "{timestamps}", "--scene", SCENE.format("g_eff: 1e-300")],
     "apparatus/g_eff"),
    ("scene_incline_nearly_flat",
     ["fit", "{timestamps}", "--scene", SCENE.format("incline_angle: 1e-300")],
     "apparatus/incline_angle"),
    ("scene_timing_resolution_tiny",
     ["fit", "{timestamps}", "--scene", "timing_resolution: 1e-300\n"], "timing_resolution"),
    ("scene_flag_length_huge",
     ["analyze", "{photogate}", "--scene", "reader: {flag_length: 1e300}\n"],
     "reader/flag_length"),
]


@pytest.mark.parametrize("argv,named", [case[1:] for case in CASES],
                         ids=[case[0] for case in CASES])
def test_bad_number_is_one_line_exit_2_and_no_output(tmp_path, inputs, argv, named):
    places = {name: str(path) for name, path in inputs.items()}
    argv = [places[part[1:-1]] if part[1:-1] in places else part for part in argv]
    if "--scene" in argv:  # the scene's text is written to a scene.yaml, named in the error
        scene = tmp_path / "scene.yaml"
        scene.write_text(argv[argv.index("--scene") + 1], encoding="utf-8")
        argv[argv.index("--scene") + 1] = str(scene)
        named = f"{scene}: invalid scene ({named}:"
    output = tmp_path / ("out" if argv[0] == "analyze" else
                         "out.h5" if argv[0] == "fit" else "out.csv")
    status, error = _run(argv + ["-o", output])
    assert status == 2, error
    assert len(error.strip().splitlines()) == 1, error
    assert error.startswith(f"dashpot {argv[0]}: error: ")
    assert (places[named[1:-1]] if named[1:-1] in places else named) in error
    assert "Traceback" not in error
    assert not output.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) in ([], ["scene.yaml"])


def test_low_sample_rate_message_says_the_detector_minimum(inputs):
    for rate in (200, 222, 4000):
        with pytest.raises(InputError) as caught:
            detect_impacts(inputs[f"wav{rate}"])
        message = str(caught.value)
        assert message.startswith(f"{inputs[f'wav{rate}']}: sample rate {rate} Hz is below ")
        assert f"{MIN_SAMPLE_RATE} Hz the impact detector needs" in message
    # The minimum is what the detector's shortest window needs: 4 samples in 0.5 ms.
    assert MIN_SAMPLE_RATE == 8000


def test_the_minimum_sample_rate_itself_is_read(tmp_path):
    path = tmp_path / "at_minimum.wav"
    write_audio(path, 0.01 * np.random.default_rng(75).standard_normal(5 * MIN_SAMPLE_RATE),
                MIN_SAMPLE_RATE)
    # Noise alone: refused for holding no impact, not for its sample rate.
    with pytest.raises(InputError, match="no impacts found"):
        detect_impacts(path)


@pytest.mark.parametrize("value", [-1.0, 0.0, math.nan, math.inf, 1e300, "x"])
def test_photogate_reader_refuses_a_bad_flag_length_or_gate_distance(inputs, value):
    with pytest.raises(ValueError, match=r"^flag_length must be"):
        read_photogate(inputs["photogate"], flag_length=value)
    with pytest.raises(ValueError, match=r"^gate_distance must be"):
        read_photogate(inputs["photogate"], flag_length=0.02, gate_distance=value)


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, 1e300, "x"])
def test_motion_reader_refuses_a_bad_bumper_position(inputs, value):
    with pytest.raises(ValueError, match=r"^bumper_position must be a"):
        read_motion_sensor(inputs["motion"], bumper_position=value)


def test_legitimate_reader_options_still_work(inputs):
    table = read_photogate(inputs["photogate"], flag_length=0.02, gate_distance=0.02)
    assert len(table) >= 2
    # A bumper position exactly at a bound of the range is accepted (the range is closed).
    read_motion_sensor(inputs["motion"], bumper_position=-20.0)


def test_bounce_table_refuses_a_contact_longer_than_an_interval():
    # Intervals 0.5, 0.375, 0.28125, 0.2109375 s (ε = 0.75), all exact in binary.
    impacts = {"time": np.array([0.0, 0.5, 0.875, 1.15625, 1.3671875])}
    # Just shorter than the shortest interval: positive speeds everywhere.
    table = bounce_table(impacts, g=9.81, contact_duration=0.21)
    assert np.all(table["rebound_speed"] > 0)
    with pytest.raises(ValueError, match=r"contact_duration 0\.210938 s is not shorter than the "
                                         r"interval 0\.210938 s of bounce 3 \(run 0\)"):
        bounce_table(impacts, g=9.81, contact_duration=0.2109375)


# --- an uncreatable surrogate cache: computed without it, with a note ---

SMALL_TABLE = dict(nx=16, ny=24, n_critical=60, n_certify=500)


@pytest.fixture
def blocked_cache(tmp_path):
    """A cache path under a regular file: no one, root included, can create it."""
    (tmp_path / "a_file").write_text("not a folder\n")
    sg.clear_memory_cache()
    yield tmp_path / "a_file" / "cache"
    sg.clear_memory_cache()


def test_uncreatable_cache_directory_computes_without_it(tmp_path, blocked_cache, monkeypatch):
    with pytest.warns(sg.CacheWarning, match=r"cannot use the surrogate cache .*a_file/cache "
                                             r"\(Not a directory\); the Ib fast table"):
        table = sg.load_surrogate("Ib", "fast", directory=blocked_cache, overrides=SMALL_TABLE)
    assert table.path == ""
    cached = sg.build_surrogate("Ib", "fast", overrides=SMALL_TABLE)
    np.testing.assert_array_equal(table.coef, cached.coef)
    # Kept in memory: the next use warns no more and builds nothing.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert sg.load_surrogate("Ib", "fast", directory=blocked_cache,
                                 overrides=SMALL_TABLE) is table
    # The same through $DASHPOT_CACHE_DIR, and with a file where the cache folder should be.
    sg.clear_memory_cache()
    monkeypatch.setenv("DASHPOT_CACHE_DIR", str(blocked_cache.parent))
    with pytest.warns(sg.CacheWarning, match=r"a_file \("):
        table = sg.load_surrogate("IIb", "fast", overrides=SMALL_TABLE)
    assert table.path == "" and not list(tmp_path.glob("**/*.npz"))


@pytest.mark.filterwarnings("default::dashpot.physics.surrogate.CacheWarning")
def test_cli_fit_with_an_uncreatable_cache_succeeds_with_a_note(tmp_path, inputs, blocked_cache,
                                                                monkeypatch):
    monkeypatch.setenv("DASHPOT_CACHE_DIR", str(blocked_cache))
    output = tmp_path / "fit.h5"
    status, error = _run(["fit", inputs["timestamps"], "-o", output, "--models", "IIb"])
    assert status == 0, error
    assert output.is_file()
    lines = error.strip().splitlines()
    assert lines and all(line.startswith("dashpot fit: note: cannot use the surrogate cache ")
                         for line in lines)
