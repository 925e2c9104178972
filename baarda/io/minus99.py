"""Text files of records ended by a line ``-99`` (PAT-B and BINGO, the aerial-triangulation
exchange formats of Inpho/Match-AT, Metashape and Pix4D): blank-separated fields (a
fixed-format file whose columns are separated by blanks reads the same), one record a line.

`Lines` reads them line by line with errors that name the file, the line and the field;
`groups` splits a file of header + rows groups, each ended by -99.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from baarda.errors import ProjectError
from baarda.io.records import finite_numbers
from baarda.io.text_files import ENCODING, whole_lines

END = "-99"


def is_end(tokens: list[str]) -> bool:
    """Whether a line's tokens are the record end -99 (also written -99.0)."""
    if len(tokens) != 1:
        return False
    try:
        return float(tokens[0]) == -99.0
    except ValueError:
        return False


@dataclass(frozen=True)
class Row:
    """One data line: its 1-based number and its blank-separated tokens."""

    line: int
    tokens: list[str]

    def numbers(self, path: str, start: int, names: tuple[str, ...]) -> np.ndarray:
        """The tokens start.. as finite floats, one per name (the error names the field)."""
        out = np.empty(len(names))
        for k, name in enumerate(names):
            out[k] = finite_numbers(self.tokens[start + k:start + k + 1], path, self.line,
                                    name)[0]
        return out


@dataclass(frozen=True)
class Group:
    """A header line and the rows after it, up to its -99."""

    header: Row
    rows: list[Row]


def data_rows(path: Path, encoding: str = ENCODING) -> list[Row]:
    """The non-blank lines of a file written whole (io/text_files.whole_lines), numbered; '#'
    starts a comment line."""
    lines = whole_lines(path, encoding)
    return [Row(k + 1, s.split()) for k, s in enumerate(lines)
            if s.strip() and not s.lstrip().startswith("#")]


def rows_to_end(path: Path, rows: list[Row], what: str) -> list[Row]:
    """The rows of a file that is one list of records ended by -99: ProjectError when the
    -99 is missing (a truncated file) or data follow it."""
    for k, r in enumerate(rows):
        if is_end(r.tokens):
            if k + 1 < len(rows):
                raise ProjectError(str(path), f"data after the closing {END}",
                                   rows[k + 1].line)
            return rows[:k]
    last = rows[-1].line if rows else 1
    raise ProjectError(str(path), f"the file ends without the closing {END} after its "
                       f"{what} (a truncated file, or a record line missing its end)", last, END)


def groups(path: Path, rows: list[Row], what: str, closing: bool) -> list[Group]:
    """The header + rows groups of a file, each ended by -99; `closing`: the file ends with
    one more -99 (an empty group).  ProjectError naming the line where a -99 is missing."""
    out: list[Group] = []
    k = 0
    while k < len(rows):
        head = rows[k]
        if is_end(head.tokens):
            if not closing:
                raise ProjectError(str(path), f"a {END} where a {what} header is expected",
                                   head.line, what)
            if k + 1 < len(rows):
                raise ProjectError(str(path), f"data after the closing {END}",
                                   rows[k + 1].line)
            return out
        body: list[Row] = []
        k += 1
        while k < len(rows) and not is_end(rows[k].tokens):
            body.append(rows[k])
            k += 1
        if k == len(rows):
            raise ProjectError(str(path), f"{what} {head.tokens[0]} (line {head.line}) is not "
                               f"ended by {END} (a truncated file, or a missing {END})",
                               rows[-1].line, END)
        out.append(Group(head, body))
        k += 1
    if closing:
        last = rows[-1].line if rows else 1
        raise ProjectError(str(path), f"the file ends without the closing {END} after its "
                           f"last {what} (a truncated file)", last, END)
    return out
