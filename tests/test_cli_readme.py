"""Every `dashpot` command the README shows, run verbatim in README order.

The README's shell blocks are parsed for lines starting with ``dashpot ``; only the recordings
they name are files this test makes (a synthetic sound of a ball bouncing to rest, under each
name), and ``scene.yaml`` is the README's own example scene with its recording pointed at that
sound. The flow ``dashpot impacts recording.wav -o impacts.csv`` then ``dashpot fit impacts.csv
--scene scene.yaml -o fit.h5`` failed before ("not a readable audio file": the scene's
``sensor: audio`` was applied to the impact table).
"""

import re
import shlex
import shutil
from pathlib import Path

import pytest
from cli_run import run_cli

from dashpot.ingest import AUDIO_SUFFIXES
from dashpot.synth.scene import write_scene

README = Path(__file__).resolve().parent.parent / "README.md"
BALL = dict(model="hybrid", beta=30.0, omega0=3000.0, g=9.80665, v0=1.5, n_max=10)


def _blocks(language):
    """The README's fenced code blocks of one language, in order."""
    return re.findall(rf"^ *```{language}\n(.*?)^ *```", README.read_text(), re.M | re.S)


def readme_commands():
    """Each `dashpot ...` line of the README's shell blocks (also `.venv/bin/dashpot ...`),
    split as the shell would, without its comment."""
    commands = []
    for block in _blocks("sh"):
        for line in block.splitlines():
            words = shlex.split(line, comments=True)
            if words and Path(words[0]).name == "dashpot":
                commands.append(["dashpot", *words[1:]])
    return commands


def _run(argv):
    """Exit status, standard output and standard error of the command (--help and
    --version end by SystemExit, as from a shell)."""
    try:
        return run_cli(argv)
    except SystemExit as stop:
        return stop.code, "", ""


def readme_scene(recording):
    """The README's example scene.yaml, its recording replaced by `recording`."""
    (scene,) = [block for block in _blocks("yaml") if "sensor:" in block]
    text, count = re.subn(r"^(\s*recording:\s*)\S+", rf"\g<1>{recording}", scene, flags=re.M)
    assert count == 1
    return text


def test_the_readme_shows_the_flows():
    commands = readme_commands()
    assert {command[1] for command in commands} >= {"impacts", "bounces", "fit", "analyze"}
    fit = next(command for command in commands if command[1] == "fit")
    assert "--scene" in fit and fit[2].endswith(".csv")  # the impact table, not a recording


@pytest.fixture(scope="module")
def sound(tmp_path_factory):
    """A synthetic recording of a ball bouncing to rest (seed picked once)."""
    return write_scene(tmp_path_factory.mktemp("readme"), "audio", seed=1127, **BALL)


def test_every_readme_flow_runs(sound, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    commands = readme_commands()
    recordings = {token for command in commands for token in command[2:]
                  if Path(token).suffix.lower() in AUDIO_SUFFIXES}
    assert recordings, "the README names no recording"
    for name in recordings:
        shutil.copyfile(sound, tmp_path / name)
    scene = readme_scene(sorted(recordings)[0])
    assert "sensor: audio" in scene
    (tmp_path / "scene.yaml").write_text(scene)
    # A command the README shows twice is run once: run again, it would find its own outputs
    # and refuse them (without --force), as it should.
    distinct = list(dict.fromkeys(tuple(command) for command in commands))
    for command in distinct:
        status, _, err = _run(list(command[1:]))
        assert status == 0, f"{shlex.join(command)}: {err}"
        if "-o" not in command or command[command.index("-o") + 1] == "-":
            continue  # --help, --version, a table to standard output
        output = Path(command[command.index("-o") + 1])
        assert output.exists(), shlex.join(command)
        if output.is_dir():
            assert any(output.glob("*.h5")) and any(output.glob("*-parameters.csv"))


def test_an_impact_table_is_analysed_with_the_scene_of_its_sound(sound, tmp_path,
                                                                  monkeypatch):
    """`analyze impacts.csv --scene scene.yaml` (sensor: audio): the table is read as a table
    and no detection figure is drawn from it (it was opened as sound, and failed, before)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "scene.yaml").write_text(readme_scene(sound))
    assert run_cli(["impacts", str(sound), "-o", "impacts.csv"])[0] == 0
    # --no-noise: how the table is read and drawn does not depend on the fits, and the
    # README's scene (noise: true) would add the noise model's fits, most of this test's cost.
    status, printed, err = run_cli(["analyze", "impacts.csv", "--scene", "scene.yaml", "-o",
                                    "out", "--models", "Ia", "--no-noise"])
    assert status == 0, err
    (name,) = [path.stem for path in Path("out").glob("*.h5")]
    assert (Path("out") / name / "restitution.png").is_file()
    assert not (Path("out") / name / "detection.png").exists()
    assert "note: fitted impacts.csv; the scene's recording" in printed
