"""Running the ``dashpot`` command in-process for the CLI tests."""

import contextlib
import io

import numpy as np

from dashpot.cli import main
from dashpot.synth.scene import write_scene


def run_cli(argv):
    """main(argv) with its exit status, standard output and standard error."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
            np.errstate(over="raise", divide="raise", invalid="raise", under="ignore"):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()


def timestamp_impacts(folder, seed, **ball):
    """A synthetic timestamp recording of `ball` (:func:`dashpot.synth.scene.write_scene`
    arguments) in ``folder/ball`` and the impact table ``dashpot impacts`` writes of it
    (``folder/impacts.csv``): their paths."""
    recording = write_scene(folder / "ball", "timestamps", seed=seed, **ball)
    impacts = folder / "impacts.csv"
    status, _, err = run_cli(["impacts", str(recording), "-o", str(impacts)])
    assert status == 0, err
    return recording, impacts
