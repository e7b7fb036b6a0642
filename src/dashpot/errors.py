"""Errors raised on bad input files: one line naming the file (and row) and the problem."""

from __future__ import annotations


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
    """

    def __init__(self, path, problem, *, row=None):
        self.path = str(path)
        self.problem = problem
        self.row = row
        where = f"{self.path}, row {row}" if row is not None else self.path
        super().__init__(f"{where}: {problem}")
