"""Errors that name the file, line and field of bad input."""

from __future__ import annotations

import os


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
    """The block cannot be adjusted as given (datum defect, undetermined photo or point)."""


class OutputError(OSError):
    """A result could not be written (disk full, file too large, no permission): the
    OSError of the write with the file it was writing (`filename`)."""

    def __str__(self) -> str:
        return f"{self.filename}: could not write ({self.strerror})"
