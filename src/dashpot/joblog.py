"""Logging for one workflow job: everything to the job's log file, errors in one clear line.

Used by the thin scripts of ``workflow/scripts/``: a bad input (:class:`~dashpot.errors.InputError`)
and a failed read or write of a file (:class:`OSError`: a full disk, no permission) each
become one line naming the file in the log and on standard error, and the job fails (exit
status 1) without a traceback; any other error is logged with its traceback and re-raised.
"""

from __future__ import annotations

import logging
import sys
from contextlib import contextmanager
from pathlib import Path

from .errors import InputError

__all__ = ["job_log"]


@contextmanager
def job_log(path, job):
    """Send logging (and warnings) to `path` for the duration of the block.

    Parameters
    ----------
    path : str or os.PathLike
        The job's log file (replaced).
    job : str
        What the job does, for the log's first line and error messages.

    Yields
    ------
    logging.Logger
    """
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    handler = logging.FileHandler(path, mode="w", encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
    root = logging.getLogger()
    root.addHandler(handler)
    root.setLevel(logging.INFO)
    logging.captureWarnings(True)
    logger = logging.getLogger("dashpot.job")
    logger.info("%s", job)
    try:
        yield logger
    except (InputError, OSError) as error:
        if isinstance(error, OSError):
            error = InputError(error.filename or "output", error.strerror or str(error))
        # The one line goes to the log file and, through a handler of its own, to standard
        # error, where Snakemake shows it beside the failed job.
        console = logging.StreamHandler(sys.stderr)
        console.setFormatter(logging.Formatter(f"dashpot ({job}): error: %(message)s"))
        root.addHandler(console)
        try:
            logger.error("%s", error)
        finally:
            root.removeHandler(console)
        raise SystemExit(1) from None
    except Exception:
        logger.exception("%s failed", job)
        raise
    else:
        logger.info("done")
    finally:
        logging.captureWarnings(False)
        root.removeHandler(handler)
        handler.close()
