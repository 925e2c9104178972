"""Errors that name the file, line and field of bad input."""

from __future__ import annotations

import os

#: below this magnitude a figure in a message keeps its fixed decimals; above, 3 significant
#: digits (a coordinate of 1e308 printed with '.0f' is a number of 309 digits)
FIXED_BELOW = 1e9


def figure(x: float, decimals: int = 0) -> str:
    """A number for a message: `decimals` fixed decimals, or 3 significant digits when its
    magnitude is FIXED_BELOW or more."""
    x = float(x)
    return f"{x:.{decimals}f}" if abs(x) < FIXED_BELOW else f"{x:.3g}"


class ProjectError(ValueError):
    """Bad input: the message names the file, the line (1-based) and the column."""

    def __init__(self, path: str | os.PathLike, message: str, line: int | None = None,
                 column: str | None = None):
        self.path, self.line, self.column, self.detail = str(path), line, column, message
        where = self.path
        if line is not None:
            where += f", line {line}"
        if column is not None:
            where += f", column '{column}'"
        super().__init__(f"{where}: {message}")


class GeometryError(ValueError):
    """The block cannot be adjusted as given (datum defect, undetermined photo or point).

    `frame`: the index of the frame (photo, model) whose unknowns are not determined, where
    the error is about one (adjustment/schur.py), else None: callers that leave such a
    photo out and try again read it here, not in the words of the message."""

    def __init__(self, *args: object, frame: int | None = None) -> None:
        super().__init__(*args)
        self.frame = frame


class OutputError(OSError):
    """A result could not be written (disk full, file too large, no permission): the
    OSError of the write with the file it was writing (`filename`)."""

    def __str__(self) -> str:
        return f"{self.filename}: could not write ({self.strerror})"
