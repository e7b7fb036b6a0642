"""Running the ``dashpot`` command in-process for the CLI tests."""

import contextlib
import io

import numpy as np

from dashpot.cli import main


def run_cli(argv):
    """main(argv) with its exit status, standard output and standard error."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
            np.errstate(over="raise", divide="raise", invalid="raise", under="ignore"):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()
