"""`dashpot fit`: an HDF5 file and the verdict on success; one stderr line, exit 2 and no
output file on bad input."""

import hashlib
import re
import subprocess
import sys

import pytest
from cli_run import run_cli, timestamp_impacts
from measurement_text import check_measurement, measurement_of

from dashpot.store import read_fit

BALL = dict(model="IIb", beta=30.0, omega0=3000.0, g=9.81, v0=1.5, n_max=15)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """A recording, its impact table from `dashpot impacts`, and `dashpot fit` on the table."""
    folder = tmp_path_factory.mktemp("cli_fit")
    recording, table = timestamp_impacts(folder, 1, **BALL)
    scene = folder / "ball" / "scene.yaml"
    scene.write_text("apparatus:\n  gravity: 9.81\n  mass: {value: 0.05, uncertainty: 0.001}\n")
    output = folder / "results" / "ball.h5"
    status, out, err = run_cli(["fit", str(table), "-o", str(output), "--scene", str(scene),
                             "--models", "Ia", "IIb"])
    return {"folder": folder, "recording": recording, "table": table, "scene": scene,
            "output": output, "status": status, "out": out, "err": err}


def test_fit_writes_the_file_and_prints_the_verdict(fitted):
    assert fitted["status"] == 0 and fitted["err"] == ""
    stored = read_fit(fitted["output"])
    assert list(stored["selection"]["model"]) == ["Ia", "IIb"]
    assert set(stored["fits"]) == {"Ia", "IIb"}
    verdict = stored["attrs"]["verdict"]
    lines = [line for line in fitted["out"].splitlines()
             if not line.lstrip().startswith("note: ")]  # the notes, tested elsewhere
    assert lines[0] == f"{fitted['table']}: 15 impacts -> {fitted['output']}"
    assert lines[-1] == f"  selection: {verdict}"
    models = [line.split(":")[0].strip() for line in lines[1:]
              if re.match(r"^ +(Ia|IIb): ", line)]
    assert models == ["Ia", "IIb"]
    # Each model's line reports the stored fit, rounded to its uncertainty (the quality of
    # the fit is tested elsewhere, the rounding in test_cli_report.py).
    for line, model in zip(lines[1:], ("Ia", "IIb")):
        attrs = stored["fits"][model]["attrs"]
        if attrs["success"]:
            parameters = stored["fits"][model]["parameters"]
            for name, symbol in (("beta", "β"), ("k", "k")):
                check_measurement(measurement_of(line, symbol), parameters.loc[name, "value"],
                                  parameters.loc[name, "stderr"],
                                  unit=parameters.loc[name, "unit"])
        else:
            assert line == f"  {model:>6}: failed: " + attrs["message"].removeprefix(
                "fit failed: ")
    # Provenance: the impact table fitted, the scene used, the mass giving k.
    assert stored["attrs"]["input_file"] == "impacts.csv"
    assert stored["attrs"]["input_sha256"] == hashlib.sha256(
        fitted["table"].read_bytes()).hexdigest()
    assert '"mass": {"uncertainty": 0.001, "value": 0.05}' in stored["attrs"]["scene"]
    assert "k" in stored["fits"]["IIb"]["parameters"].index
    assert sorted(p.name for p in fitted["output"].parent.iterdir()) == ["ball.h5"]


def test_fit_a_recording_with_the_scene_models(fitted, tmp_path):
    """A raw recording is read with the scene's reader; the scene's models are fitted."""
    scene = tmp_path / "scene.yaml"
    scene.write_text("sensor: timestamps\nmodels: [Ia]\napparatus: {gravity: 9.81}\n")
    output = tmp_path / "fit.h5"
    status, out, err = run_cli(["fit", str(fitted["recording"]), "-o", str(output),
                             "--scene", str(scene)])
    assert status == 0 and err == ""
    stored = read_fit(output)
    assert set(stored["fits"]) == {"Ia"} and stored["attrs"]["input_file"] == "timestamps.csv"
    assert "15 impacts" in out and stored["attrs"]["verdict"] in out


def _impact_table(path, times):
    path.write_text("time,time_uncertainty\n" + "".join(f"{t},1e-5\n" for t in times))
    return path


BAD_INPUTS = {
    "missing": (None, "no such file"),
    "not_impacts": ("speed,height\n1,2\n3,4\n", "not a table of impacts"),
    "binary": (bytes(range(256)) * 4, "binary"),
    "two_impacts": ("time,time_uncertainty\n0.10,1e-5\n0.40,1e-5\n", "only 2 impact(s)"),
    "backwards": ("time,time_uncertainty\n0.1,1e-5\n0.4,1e-5\n0.3,1e-5\n0.5,1e-5\n",
                  "row 3, column 'time': impact times must increase"),
    "repeated": ("time,time_uncertainty\n0.1,1e-5\n0.4,1e-5\n0.6,1e-5\n0.6,1e-5\n",
                 "row 4, column 'time': impact times must increase"),
    "not_a_number": ("time,time_uncertainty\n0.1,1e-5\nlate,1e-5\n0.6,1e-5\n",
                     "row 2, column 'time': 'late' is not a number"),
    # Raised an IndexError: every impact left out of the fit.
    "all_inferred": ("time,time_uncertainty,flag\n" + "".join(
        f"{t},1e-5,inferred\n" for t in (0.0, 0.3, 0.585, 0.85575, 1.1129625)),
        "no impact left to fit: all 5 are flagged 'inferred' or spurious"),
}


@pytest.mark.parametrize("label", list(BAD_INPUTS))
def test_bad_input_fails_cleanly(tmp_path, label):
    content, problem = BAD_INPUTS[label]
    source = tmp_path / ("lab.bin" if label == "binary" else "lab.csv")
    if isinstance(content, bytes):
        source.write_bytes(content)
    elif content is not None:
        source.write_text(content)
    output = tmp_path / "out" / "fit.h5"
    status, out, err = run_cli(["fit", str(source), "-o", str(output)])
    assert status == 2 and out == ""
    assert len(err.splitlines()) == 1
    assert err.startswith(f"dashpot fit: error: {source}")
    assert problem in err
    assert not output.exists()
    assert not list(tmp_path.rglob("*.partial"))


def test_invalid_scene_fails_cleanly_and_keeps_an_old_output(fitted, tmp_path):
    scene = tmp_path / "scene.yaml"
    scene.write_text("apparatus:\n  mass: -0.05\n")
    output = tmp_path / "fit.h5"
    output.write_bytes(b"an earlier result")
    status, out, err = run_cli(["fit", str(fitted["table"]), "-o", str(output),
                             "--scene", str(scene)])
    assert status == 2 and out == ""
    assert err == f"dashpot fit: error: {scene}: invalid scene (apparatus/mass: -0.05 is less " \
                  "than the minimum of 1e-06)\n"
    assert output.read_bytes() == b"an earlier result"
    missing = tmp_path / "no_scene.yaml"
    status, _, err = run_cli(["fit", str(fitted["table"]), "-o", str(tmp_path / "new.h5"),
                           "--scene", str(missing)])
    assert status == 2 and err.startswith(f"dashpot fit: error: {missing}: cannot read")
    assert not (tmp_path / "new.h5").exists()


def test_output_over_an_input_is_refused(fitted, tmp_path):
    for victim in (fitted["table"], fitted["scene"]):
        before = victim.read_bytes()
        status, out, err = run_cli(["fit", str(fitted["table"]), "-o", str(victim),
                                 "--scene", str(fitted["scene"])])
        assert status == 2 and out == ""
        assert err == f"dashpot fit: error: {victim}: refusing to overwrite the input with " \
                      "the output\n"
        assert victim.read_bytes() == before
    # The recording the scene names is the user's data too, fitted or not.
    recording = tmp_path / "drop.csv"
    recording.write_bytes(fitted["table"].read_bytes())
    scene = tmp_path / "named.yaml"
    scene.write_text(fitted["scene"].read_text() + f"recording: {recording}\n")
    status, out, err = run_cli(["fit", str(fitted["table"]), "-o", str(recording),
                                "--scene", str(scene)])
    assert status == 2 and out == ""
    assert err == f"dashpot fit: error: {recording}: refusing to overwrite the input with " \
                  "the output\n"
    assert recording.read_bytes() == fitted["table"].read_bytes()
    # The same file under another spelling is still the input.
    before = fitted["table"].read_bytes()
    alias = fitted["table"].parent / "." / fitted["table"].name
    assert run_cli(["fit", str(fitted["table"]), "-o", str(alias)])[0] == 2
    assert fitted["table"].read_bytes() == before


def test_output_that_is_a_folder_is_refused(fitted, tmp_path):
    status, out, err = run_cli(["fit", str(fitted["table"]), "-o", str(tmp_path)])
    assert status == 2 and len(err.splitlines()) == 1 and str(tmp_path) in err
    assert list(tmp_path.iterdir()) == []


def test_installed_command_reports_one_line(tmp_path):
    """The real entry point: exit status 2 and one line, no traceback."""
    missing = tmp_path / "nope.csv"
    run = subprocess.run([sys.executable, "-m", "dashpot.cli", "fit", str(missing), "-o",
                          str(tmp_path / "fit.h5")], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr == f"dashpot fit: error: {missing}: no such file\n"
    assert list(tmp_path.iterdir()) == []
