"""Which code made a result: a digest of the dashpot source that is running.

The package version names a release, not the code: between releases (and in an editable
install) the science changes under one version. :func:`source_fingerprint` is a SHA-256 over
the package's own files (every ``.py`` module and the scene schema, by their paths inside the
package and their bytes), so any change to the code that computes a result changes it. The
scene files and the summary store it (root attribute ``dashpot_source_sha256``), and the
workflow passes it to the rules that compute with the library as a parameter, a Snakemake
rerun trigger: a rerun after the code changed recomputes and redraws what it made.
"""

from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

__all__ = ["SOURCE_PATTERNS", "source_files", "source_fingerprint"]

SOURCE_PATTERNS = ("*.py", "*.yaml")
"""The package's files that the fingerprint covers (its modules and the scene schema; not
``__pycache__``, nor the cached surrogate tables, which live outside the package)."""

_PACKAGE = Path(__file__).resolve().parent


def source_files(package=_PACKAGE):
    """The files of `package` (a folder) the fingerprint covers, sorted by their path in it.

    Parameters
    ----------
    package : str or os.PathLike, default the running dashpot package

    Returns
    -------
    list of pathlib.Path
    """
    package = Path(package)
    files = {path for pattern in SOURCE_PATTERNS for path in package.rglob(pattern)
             if "__pycache__" not in path.relative_to(package).parts and path.is_file()}
    return sorted(files, key=lambda path: path.relative_to(package).as_posix())


def _digest(package):
    digest = hashlib.sha256()
    for path in source_files(package):
        # Path and length first: no two trees give the same byte stream.
        name = path.relative_to(package).as_posix().encode("utf-8")
        content = path.read_bytes()
        digest.update(b"%d:%s:%d:" % (len(name), name, len(content)))
        digest.update(content)
    return digest.hexdigest()


@lru_cache(maxsize=1)
def _running():
    # The modules a process has imported do not change while it runs: read them once.
    return _digest(_PACKAGE)


def source_fingerprint(package=None):
    """Hex SHA-256 of the dashpot source that is running (or of another copy of it).

    Parameters
    ----------
    package : str or os.PathLike, optional
        A folder holding a copy of the package, read on every call; default the package
        this module was imported from, read once per process (about 100 small files).

    Returns
    -------
    str
        64 hex digits over the relative path, size and bytes of each of
        :func:`source_files`; the same source gives the same digest wherever it lies.
    """
    return _running() if package is None else _digest(Path(package).resolve())
