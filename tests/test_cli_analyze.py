"""`dashpot analyze`: one recording to an HDF5 file, the scene figures and a printed summary;
on bad input one stderr line naming the file, exit status 2 and no output at all."""

import pytest
from cli_run import run_cli

from dashpot.store import read_fit
from dashpot.synth.scene import write_scene

BALL = dict(model="hybrid", beta=30.0, omega0=3000.0, g=9.80665, v0=1.5, n_max=10)


@pytest.fixture(scope="module")
def table_scene(tmp_path_factory):
    """A timestamp table with a scene.yaml naming the scene."""
    folder = tmp_path_factory.mktemp("analyze") / "ball"
    recording = write_scene(folder, "timestamps", seed=3, uncertainty=2e-5, **BALL)
    scene = folder / "scene.yaml"
    # Ten bounces do not determine ω0 = 3000 rad/s; the contact time (π/ω0 ≈ 1 ms) does.
    scene.write_text("name: my-ball\nsensor: timestamps\nmodels: [IIb, hybrid]\n"
                     "apparatus: {mass: {value: 0.0027, uncertainty: 0.0001},\n"
                     "            contact_time: {value: 0.001, uncertainty: 0.0003}}\n")
    return recording, scene


def test_writes_the_scene_file_figures_and_a_summary(table_scene, tmp_path):
    recording, scene = table_scene
    out = tmp_path / "out"
    status, printed, err = run_cli(["analyze", str(recording), "--scene", str(scene), "-o",
                                 str(out)])
    assert status == 0, err
    record = read_fit(out / "my-ball.h5")
    assert set(record["fits"]) == {"IIb", "hybrid"}
    assert record["attrs"]["input_file"] == recording.name
    for name in ("intervals", "restitution", "selection"):
        for ext in ("png", "pdf"):
            assert (out / "my-ball" / f"{name}.{ext}").stat().st_size > 0
    assert not (out / "my-ball" / "detection.png").exists()  # not a sound recording
    assert "β = " in printed and "k = " in printed and "ε " in printed
    assert "selection:" in printed
    assert not list(out.rglob("*.partial")) and not list(out.rglob(".*"))


def test_audio_gets_the_detection_figure_and_is_named_after_the_file(tmp_path):
    recording = write_scene(tmp_path / "rec", "audio", seed=2, **BALL)
    out = tmp_path / "out"
    status, printed, err = run_cli(["analyze", str(recording), "-o", str(out), "--models",
                                 "hybrid"])
    assert status == 0, err
    assert (out / "recording.h5").is_file()
    assert (out / "recording" / "detection.png").is_file()
    truth = BALL["beta"]
    beta = read_fit(out / "recording.h5")["fits"]["hybrid"]["parameters"].loc["beta"]
    assert beta["low95"] <= truth <= beta["high95"] or \
        abs(beta["value"] - truth) <= 3 * beta["stderr"]


@pytest.mark.parametrize("case", ["missing", "unreadable", "bad-scene", "output-is-file"])
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, table_scene, case):
    recording, scene = table_scene
    out = tmp_path / "out"
    argv = ["analyze", str(recording), "-o", str(out)]
    named = recording
    if case == "missing":
        named = tmp_path / "nothing.wav"
        argv[1] = str(named)
    elif case == "unreadable":
        named = tmp_path / "noise.wav"
        named.write_bytes(b"RIFF but not really a wave file")
        argv[1] = str(named)
    elif case == "bad-scene":
        named = tmp_path / "scene.yaml"
        named.write_text("sensor: banana\n")
        argv += ["--scene", str(named)]
    else:
        named = out
        out.write_text("a file, not a folder")
    status, printed, err = run_cli(argv)
    assert status == 2
    assert len(err.strip().splitlines()) == 1
    assert err.startswith("dashpot analyze: error: ") and str(named) in err
    if case != "output-is-file":
        assert not out.exists()


def test_says_which_file_it_analysed_when_the_scene_names_another(table_scene, tmp_path):
    """`analyze REC --scene S` where S's `recording:` is another file: REC is analysed, and
    the printed notes and the HDF5 provenance say so."""
    import h5py

    recording, scene = table_scene
    other = tmp_path / "scene.yaml"
    other.write_text(scene.read_text() + "recording: another-drop.csv\n")
    out = tmp_path / "out"
    status, printed, err = run_cli(["analyze", str(recording), "--scene", str(other), "-o",
                                    str(out)])
    assert status == 0, err
    notes = [line for line in printed.splitlines() if "another-drop.csv" in line]
    assert len(notes) == 1 and notes[0].startswith("  note: ")
    assert f"fitted {recording}" in notes[0] and "not read" in notes[0]
    with h5py.File(out / "my-ball.h5", "r") as source:
        assert source.attrs["input_file"] == recording.name
        assert not source.attrs["input_is_scene_recording"]


def test_a_scene_that_names_its_recording_is_analysed_without_it(table_scene, tmp_path):
    """`analyze --scene S` reads the recording S names (resolved against S's folder): a rerun
    needs the scene alone. Without a recording and without a scene naming one: one line."""
    import h5py

    source, scene = table_scene
    recording = tmp_path / source.name  # beside the scene, which names it relatively
    recording.write_bytes(source.read_bytes())
    named = tmp_path / "named.yaml"
    named.write_text(scene.read_text() + f"recording: {recording.name}\n")
    out = tmp_path / "out"
    status, printed, err = run_cli(["analyze", "--scene", str(named), "-o", str(out)])
    assert status == 0, err
    assert printed.startswith(f"{recording}: ")
    with h5py.File(out / "my-ball.h5", "r") as written:
        assert written.attrs["input_file"] == recording.name
        assert written.attrs["input_is_scene_recording"]
    for argv, problem in (([], "recording: missing"),
                          (["--scene", str(scene)], f"{scene}: names no recording")):
        status, _, err = run_cli(["analyze", *argv, "-o", str(tmp_path / "none")])
        assert status == 2 and problem in err and len(err.strip().splitlines()) == 1
        assert not (tmp_path / "none").exists()


@pytest.mark.parametrize("case", ["parameters", "figures", "scene-recording"])
def test_an_output_that_would_replace_an_input_is_refused(tmp_path, table_scene, case):
    """The scene's name makes the output names: `<name>-parameters.csv` as the recording was
    overwritten with the parameter table, a recording named `<name>` (no suffix) ended in
    "cannot write the output (File exists)" after the whole analysis."""
    recording, scene = table_scene
    out = tmp_path / "out"
    out.mkdir()
    named = out / {"parameters": "my-ball-parameters.csv", "figures": "my-ball",
                   "scene-recording": "my-ball.h5"}[case]
    named.write_bytes(recording.read_bytes())
    argv = ["analyze", str(named), "--scene", str(scene), "-o", str(out)]
    if case == "scene-recording":  # the scene's own recording, not the one analysed
        other = tmp_path / "scene.yaml"
        other.write_text(scene.read_text() + f"recording: {named}\n")
        argv = ["analyze", str(recording), "--scene", str(other), "-o", str(out)]
    status, printed, err = run_cli(argv)
    assert status == 2 and printed == ""
    assert err == (f"dashpot analyze: error: {named}: refusing to overwrite the input with the "
                   f"output\n")
    assert named.read_bytes() == recording.read_bytes()
    assert [p.name for p in out.iterdir()] == [named.name]


@pytest.mark.parametrize("name, status", [("SIGTERM", 143), ("SIGHUP", 129), ("SIGINT", 130)])
def test_a_stopped_run_leaves_no_staging_folder_and_says_one_line(tmp_path, table_scene, name,
                                                                  status):
    """`kill`, `timeout` or a closed terminal while the figures were drawn left the hidden
    staging folder, with the half-written outputs, in the output folder; Ctrl-C printed a
    traceback. An earlier result (replaced only at the end, as --force asks) stays as it
    was."""
    import subprocess
    import sys

    recording, scene = table_scene
    out = tmp_path / "out"
    out.mkdir()
    (out / "my-ball.h5").write_bytes(b"an earlier result")
    code = ("import os, signal, sys\n"
            "import dashpot.figures\n"
            "def stop(*args, **kwargs):\n"
            f"    os.kill(os.getpid(), signal.{name})\n"
            "dashpot.figures.save_scene_figures = stop\n"
            "from dashpot.cli import main\n"
            "sys.exit(main(sys.argv[1:]))\n")
    run = subprocess.run([sys.executable, "-c", code, "analyze", str(recording), "--scene",
                          str(scene), "-o", str(out), "-q", "--force"], capture_output=True,
                         text=True,
                         timeout=300)
    assert run.returncode == status and run.stdout == ""
    assert run.stderr == f"dashpot analyze: interrupted ({name}); unfinished outputs removed\n"
    assert [p.name for p in out.iterdir()] == ["my-ball.h5"]
    assert (out / "my-ball.h5").read_bytes() == b"an earlier result"
