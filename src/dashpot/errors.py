"""Errors raised on bad input files: one line naming the file (and row) and the problem."""

from __future__ import annotations

from pathlib import Path


class InputError(ValueError):
    """A recording or table that cannot be used, with the file and the problem in one line.

    Parameters
    ----------
    path : str or os.PathLike
        The offending file.
    problem : str
        What is wrong, in plain words.
    row : int, optional
        1-based data row (after the header) where the problem is, for tables.
    column : str, optional
        Header of the column where the problem is, for tables.
    """

    def __init__(self, path, problem, *, row=None, column=None):
        self.path = str(path)
        self.problem = problem
        self.row = row
        self.column = column
        where = self.path
        if row is not None:
            where += f", row {row}"
        if column is not None:
            where += f", column '{column}'"
        super().__init__(f"{where}: {problem}")


def require_file(path):
    """Raise :class:`InputError` unless `path` is a file (or a link to one).

    Parameters
    ----------
    path : str or os.PathLike
        An input the user named.

    Raises
    ------
    InputError
        "no such file", or "is a folder, not a file" for a folder (a folder named like a
        table is not missing: saying so would send the user looking in the wrong place).
    """
    path = Path(path)
    if path.is_dir():
        raise InputError(path, "is a folder, not a file")
    if not path.is_file():
        raise InputError(path, "no such file")
