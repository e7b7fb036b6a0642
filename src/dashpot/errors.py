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
