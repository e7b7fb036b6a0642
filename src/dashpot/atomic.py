"""Atomic file writes: every output of dashpot appears whole or not at all, and replaces an
existing file only when asked to.

An output is written to a temporary file with a unique name in the destination's own folder
(so the final rename stays on one file system, where :func:`os.replace` is atomic) and renamed
over the destination only when the writer finished without error; on any error the temporary
is removed and an existing destination is left as it was. Unique names keep two processes
that write the same output at once from writing into one shared temporary: the destination
ends up holding one writer's complete file.

An existing destination is replaced only with ``overwrite=True``: a result of hours of work,
or a file of the user's that carries the output's name, is never lost to a call that did not
say so. Without it, a destination that exists is refused before the temporary is made, and
the final step puts the temporary in place with a hard link (:func:`os.link` fails if the
name exists, so a file that appeared while the output was written is not clobbered either;
the temporary's name is then removed; on Windows a plain rename, which never replaces).
Where the file system has no hard links the final step checks once more and renames, which
leaves a window of a few microseconds.
"""

from __future__ import annotations

import errno
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

from .errors import InputError

__all__ = ["atomic_path", "move_into_place", "refuse_existing", "TEMPORARY_SUFFIX",
           "EXISTS_PROBLEM"]

TEMPORARY_SUFFIX = ".partial"  # temporaries are ".<name>.<random>.partial"

EXISTS_PROBLEM = "exists; pass overwrite=True to replace it"
"""The problem of :class:`~dashpot.errors.InputError` for a destination that exists."""

# What os.link raises on a file system without hard links (FAT, some network and FUSE
# mounts); any other error of the link is the write's own.
_NO_HARD_LINKS = {errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.ENOSYS}


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


def refuse_existing(*paths, overwrite=False):
    """Raise :class:`~dashpot.errors.InputError` for the first of `paths` that exists, unless
    `overwrite`.

    Writers of several files call it for all of them before writing any, so that a refusal
    leaves nothing half done.

    Parameters
    ----------
    *paths : str or os.PathLike
        Destinations about to be written.
    overwrite : bool, default False
        Existing destinations may be replaced: nothing is checked.

    Raises
    ------
    InputError
        "<path>: exists; pass overwrite=True to replace it". A dangling symbolic link counts
        as existing (replacing it would lose where it pointed).
    """
    if overwrite:
        return
    for path in map(Path, paths):
        if path.exists() or path.is_symlink():
            raise InputError(path, EXISTS_PROBLEM)


def move_into_place(source, destination, *, overwrite=False):
    """Rename the complete file `source` to `destination` in the same folder's file system.

    Parameters
    ----------
    source : str or os.PathLike
        A finished file (a temporary of :func:`atomic_path`, or a staged output).
    destination : str or os.PathLike
        Where it goes; on the same file system as `source`.
    overwrite : bool, default False
        Replace an existing `destination` (:func:`os.replace`). Without it the file is
        linked to `destination`, which fails if that name exists, even if it appeared a
        moment ago, and `source` is then unlinked.

    Raises
    ------
    InputError
        `destination` exists and `overwrite` is false; `source` is left where it was.
    """
    if overwrite:
        os.replace(source, destination)
        return
    if os.name == "nt":  # Windows' rename never replaces: FileExistsError if the name exists
        try:
            os.rename(source, destination)
        except FileExistsError:
            raise InputError(destination, EXISTS_PROBLEM) from None
        return
    try:
        os.link(source, destination)
    except FileExistsError:
        raise InputError(destination, EXISTS_PROBLEM) from None
    except (AttributeError, NotImplementedError, OSError) as error:
        if isinstance(error, OSError) and error.errno not in _NO_HARD_LINKS:
            raise
        # No hard links here: check, then rename (not atomic against a writer that creates
        # the destination in between, the best this file system allows).
        refuse_existing(destination)
        os.replace(source, destination)
        return
    os.unlink(source)


@contextmanager
def atomic_path(path, *, overwrite=False):
    """Yield a new temporary path beside `path`; move it to `path` if the block succeeds.

    Parameters
    ----------
    path : str or os.PathLike
        Destination file. Its folder is created if missing.
    overwrite : bool, default False
        Replace `path` if it exists. Without it an existing `path` is refused before anything
        is written, and again at the end if it appeared meanwhile (see
        :func:`move_into_place`).

    Yields
    ------
    pathlib.Path
        An empty file named ``.<name>.<random>.partial`` in the destination's folder, with the
        permissions a new file gets (0o666 less the umask, not mkstemp's private 0o600).
        Write the output to it (by name: writers that open it with "w" truncate it).

    Raises
    ------
    InputError
        `path` exists and `overwrite` is false ("<path>: exists; pass overwrite=True to
        replace it"); the existing file is left as it was, and no temporary is left behind.

    Notes
    -----
    On any exception (including KeyboardInterrupt) the temporary is removed and the
    exception propagates (an OSError naming no file or the temporary then names the
    destination); the destination is replaced only after the block returned.
    """
    path = Path(path)
    refuse_existing(path, overwrite=overwrite)
    path.parent.mkdir(parents=True, exist_ok=True)
    descriptor, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                                        suffix=TEMPORARY_SUFFIX)
    temporary = Path(name)
    try:
        os.close(descriptor)
        os.chmod(temporary, 0o666 & ~_umask())
        yield temporary
        move_into_place(temporary, path, overwrite=overwrite)
    except BaseException as error:
        temporary.unlink(missing_ok=True)
        if isinstance(error, OSError) and error.filename in (None, name, temporary):
            # A failed write names no file, or the temporary: the user knows the output.
            error.filename = str(path)
        raise
