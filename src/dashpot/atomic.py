"""Atomic file writes: every output of dashpot appears whole or not at all.

An output is written to a temporary file with a unique name in the destination's own folder
(so the final rename stays on one file system, where :func:`os.replace` is atomic) and renamed
over the destination only when the writer finished without error; on any error the temporary
is removed and an existing destination is left as it was. Unique names keep two processes
that write the same output at once from writing into one shared temporary: the destination
ends up holding one writer's complete file.
"""

from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_path", "TEMPORARY_SUFFIX"]

TEMPORARY_SUFFIX = ".partial"  # temporaries are ".<name>.<random>.partial"


def _umask():
    """The process's file-mode creation mask, read without changing it where the OS allows."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)  # no other portable way to read it: set and restore at once
    os.umask(mask)
    return mask


@contextmanager
def atomic_path(path):
    """Yield a new temporary path beside `path`; rename it to `path` if the block succeeds.

    Parameters
    ----------
    path : str or os.PathLike
        Destination file. Its folder is created if missing.

    Yields
    ------
    pathlib.Path
        An empty file named ``.<name>.<random>.partial`` in the destination's folder, with the
        permissions a new file gets (0o666 less the umask, not mkstemp's private 0o600).
        Write the output to it (by name: writers that open it with "w" truncate it).

    Notes
    -----
    On any exception (including KeyboardInterrupt) the temporary is removed and the
    exception propagates (an OSError naming no file or the temporary then names the
    destination); the destination is replaced only after the block returned.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    descriptor, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                                        suffix=TEMPORARY_SUFFIX)
    temporary = Path(name)
    try:
        os.close(descriptor)
        os.chmod(temporary, 0o666 & ~_umask())
        yield temporary
        os.replace(temporary, path)
    except BaseException as error:
        temporary.unlink(missing_ok=True)
        if isinstance(error, OSError) and error.filename in (None, name, temporary):
            # A failed write names no file, or the temporary: the user knows the output.
            error.filename = str(path)
        raise
