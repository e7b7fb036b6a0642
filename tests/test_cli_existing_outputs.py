"""An output that already exists is refused, before any work, unless ``--force`` is given.

Every subcommand that writes files replaced an earlier run's result (or a file of the user's
that carried the output's name) without a word before.
"""

import numpy as np
import pytest
from cli_run import run_cli, timestamp_impacts


BALL = dict(beta=20.0, omega0=2 * np.pi * 500, g=9.81, v0=2.0, n_max=12)
EARLIER = b"an earlier result"


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A timestamp table, the impact table of it, and a scene naming the outputs."""
    folder = tmp_path_factory.mktemp("existing")
    recording, impacts = timestamp_impacts(folder, 1201, **BALL)
    scene = folder / "scene.yaml"
    scene.write_text("name: my-ball\nsensor: timestamps\nmodels: [Ia]\n")
    return recording, impacts, scene


def _argv(command, inputs, output):
    """The command's arguments writing `output` (one quick model for the fits)."""
    recording, impacts, scene = inputs
    return {"impacts": ["impacts", str(recording)],
            "bounces": ["bounces", str(impacts)],
            "fit": ["fit", str(impacts), "--models", "Ia"],
            "analyze": ["analyze", str(recording), "--scene", str(scene)],
            }[command] + ["-o", str(output)]


def _no_analysis(monkeypatch):
    """Make any analysis fail the test: a refusal must come before the work."""
    import dashpot.analysis
    import dashpot.ingest

    def forbidden(*args, **kwargs):
        raise AssertionError("the work was started")

    monkeypatch.setattr(dashpot.analysis, "analyze_runs", forbidden)
    monkeypatch.setattr(dashpot.analysis, "read_impact_table", forbidden)
    monkeypatch.setattr(dashpot.ingest, "read_impacts", forbidden)


@pytest.mark.parametrize("command, name", [("impacts", "impacts.csv"),
                                           ("bounces", "bounces.csv"),
                                           ("fit", "fit.h5")])
def test_an_existing_output_file_is_refused_then_replaced_with_force(inputs, tmp_path,
                                                                      monkeypatch, command,
                                                                      name):
    output = tmp_path / name
    output.write_bytes(EARLIER)
    with monkeypatch.context() as patched:
        _no_analysis(patched)
        status, printed, err = run_cli(_argv(command, inputs, output))
    assert status == 2 and printed == ""
    assert err == f"dashpot {command}: error: {output}: exists; pass --force to replace it\n"
    assert output.read_bytes() == EARLIER
    assert [path.name for path in tmp_path.iterdir()] == [name]

    status, _, err = run_cli([*_argv(command, inputs, output), "--force"])
    assert status == 0, err
    assert output.read_bytes() != EARLIER
    assert [path.name for path in tmp_path.iterdir()] == [name]


@pytest.mark.parametrize("existing", ["my-ball.h5", "my-ball-parameters.csv", "my-ball"])
def test_analyze_refuses_each_existing_output_then_replaces_it_with_force(inputs, tmp_path,
                                                                          monkeypatch,
                                                                          existing):
    out = tmp_path / "out"
    out.mkdir()
    earlier = out / existing
    if existing == "my-ball":  # the figures' folder, with an earlier figure
        earlier.mkdir()
        (earlier / "restitution.png").write_bytes(EARLIER)
    else:
        earlier.write_bytes(EARLIER)
    with monkeypatch.context() as patched:
        _no_analysis(patched)
        status, printed, err = run_cli(_argv("analyze", inputs, out))
    assert status == 2 and printed == ""
    assert err == f"dashpot analyze: error: {earlier}: exists; pass --force to replace it\n"
    assert [path.name for path in out.iterdir()] == [existing]

    status, _, err = run_cli([*_argv("analyze", inputs, out), "--force"])
    assert status == 0, err
    assert sorted(path.name for path in out.iterdir()) == [
        "my-ball", "my-ball-parameters.csv", "my-ball.h5"]
    assert (out / "my-ball.h5").read_bytes() != EARLIER
    assert (out / "my-ball" / "restitution.png").read_bytes() != EARLIER


def test_analyze_writes_into_a_folder_holding_other_results(inputs, tmp_path):
    """The output folder is shared by scenes: only this scene's outputs are checked."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "other-ball.h5").write_bytes(EARLIER)
    status, _, err = run_cli(_argv("analyze", inputs, out))
    assert status == 0, err
    assert (out / "other-ball.h5").read_bytes() == EARLIER
    assert (out / "my-ball.h5").is_file()


def test_a_dangling_link_is_an_existing_output(inputs, tmp_path):
    """Replacing a link that points nowhere (yet) would lose where it pointed."""
    output = tmp_path / "impacts.csv"
    output.symlink_to(tmp_path / "elsewhere" / "impacts.csv")
    status, _, err = run_cli(_argv("impacts", inputs, output))
    assert status == 2 and "exists; pass --force to replace it" in err
    assert output.is_symlink()


def test_an_output_replacing_an_input_is_refused_even_with_force(inputs, tmp_path):
    recording, impacts, _ = inputs
    before = impacts.read_bytes()
    status, _, err = run_cli(["bounces", str(impacts), "-o", str(impacts), "--force"])
    assert status == 2 and "refusing to overwrite the input with the output" in err
    assert impacts.read_bytes() == before


def test_analyze_with_force_leaves_no_figure_of_the_earlier_run(inputs, tmp_path):
    # An earlier run drew a figure this one does not (a detection figure of a recording,
    # where a table is analysed now): replaced with --force, the figures' folder holds this
    # run's figures only.
    out = tmp_path / "out"
    assert run_cli(_argv("analyze", inputs, out))[0] == 0
    drawn = sorted(path.name for path in (out / "my-ball").iterdir())
    (out / "my-ball" / "detection.png").write_bytes(EARLIER)
    status, _, err = run_cli([*_argv("analyze", inputs, out), "--force"])
    assert status == 0, err
    assert sorted(path.name for path in (out / "my-ball").iterdir()) == drawn
    assert sorted(path.name for path in out.iterdir()) == [
        "my-ball", "my-ball-parameters.csv", "my-ball.h5"]


def test_analyze_with_force_puts_the_earlier_figures_back_if_it_cannot_finish(
        inputs, tmp_path, monkeypatch):
    out = tmp_path / "out"
    assert run_cli(_argv("analyze", inputs, out))[0] == 0
    earlier = {path.name: path.read_bytes() for path in (out / "my-ball").iterdir()}
    import dashpot.cli

    def full_disk(staging, out, *, force):
        raise dashpot.cli._cannot_write(out, OSError(28, "No space left on device"))

    monkeypatch.setattr(dashpot.cli, "_move_into_place", full_disk)
    status, _, err = run_cli([*_argv("analyze", inputs, out), "--force"])
    assert status != 0 and "No space left on device" in err
    assert {path.name: path.read_bytes() for path in (out / "my-ball").iterdir()} == earlier
    assert sorted(path.name for path in out.iterdir()) == [
        "my-ball", "my-ball-parameters.csv", "my-ball.h5"]
