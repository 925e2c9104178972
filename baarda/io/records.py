"""Reading delimited text records of foreign formats with file/line/field errors.

`Records` splits each non-comment line of a text file into a fixed list of named fields
(comma or whitespace separated) and converts columns on demand; every problem raises
ProjectError naming the file, the 1-based line and the field.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from baarda.errors import ProjectError
from baarda.io.text_files import (
    decode_text,
    file_bytes,
    is_number,
    refuse_cut_short,
    split_lines,
    whole_lines,
)


def check_pixel_options(pixel_mm: float, sigma_px: float) -> None:
    """The nominal pixel size (mm) and image sigma (px) of the formats without a physical
    pixel size (COLMAP, BAL, OpenSfM; --pixel-mm, --sigma-px) must be positive."""
    if not (pixel_mm > 0 and sigma_px > 0):
        raise ProjectError("command line", "pixel size and image sigma must be positive")


class Columns:
    """Columns of a text file as string arrays (`columns`), with the 1-based line number of
    every row (`lines`), so that each later check names file, line and column."""

    path: str
    lines: np.ndarray
    columns: dict[str, np.ndarray]

    def __len__(self) -> int:
        return len(self.lines)

    def has(self, name: str) -> bool:
        return name in self.columns

    def column(self, name: str) -> np.ndarray:
        """The strings of one column."""
        return self.columns[name]

    def text(self, name: str, allow_empty: bool = False) -> np.ndarray:
        col = self.column(name)
        if not allow_empty:
            bad = np.flatnonzero(col == "")
            if len(bad):
                raise ProjectError(self.path, "empty value", int(self.lines[bad[0]]), name)
        return col

    def numbers(self, name: str, allow_empty: bool = False) -> np.ndarray:
        """Column as finite floats; empty cells become NaN when allowed, else an error."""
        return to_numbers(self.column(name), self.path, self.lines, name, allow_empty)

    def integers(self, name: str) -> np.ndarray:
        col = self.text(name)
        out = np.empty(len(col), dtype=np.int64)
        for i, s in enumerate(col):
            try:
                out[i] = int(s)
            except ValueError:
                raise ProjectError(self.path, f"'{s}' is not an integer",
                                   int(self.lines[i]), name) from None
        return out


class Records(Columns):
    """Named fields of the data lines of a text file.

    sep: ',' (commas, surrounding blanks ignored) or None (any whitespace).  Lines that are
    blank or start with `comment` are skipped.  `min_fields`..len(fields) fields per line
    are accepted; missing trailing fields are empty strings.  whole: the file is one a
    program writes whole (whole_lines: empty, or a last line without its line end, refused).
    """

    def __init__(self, path: str | Path, fields: list[str], sep: str | None = ",",
                 comment: str = "#", min_fields: int | None = None,
                 lines: Iterable[tuple[int, str]] | None = None, whole: bool = False):
        self.path = str(path)
        self.fields = list(fields)
        need = len(fields) if min_fields is None else min_fields
        ends_a_line = True
        if lines is None:
            if whole:
                lines = enumerate(whole_lines(path), start=1)
            else:
                text = decode_text(file_bytes(path), str(path))
                ends_a_line = not text or text.endswith(("\n", "\r"))
                lines = enumerate(split_lines(text), start=1)
        rows, numbers, sizes = [], [], []
        for no, line in lines:
            text = line.strip()
            if not text or (comment and text.startswith(comment)):
                continue
            parts = ([p.strip() for p in text.split(sep)] if sep else text.split())
            if len(parts) < need or len(parts) > len(fields):
                expect = (str(len(fields)) if need == len(fields)
                          else f"{need} to {len(fields)}")
                raise ProjectError(self.path, f"expected {expect} fields "
                                   f"({', '.join(fields)}), found {len(parts)}", no)
            rows.append(parts + [""] * (len(fields) - len(parts)))
            sizes.append(len(parts))  # the fields as given, before the padding
            numbers.append(no)
        if rows and not ends_a_line:
            refuse_cut_short(self.path, False, numbers[-1],
                             [r[:n] for r, n in zip(rows, sizes, strict=True)])
        self.lines = np.asarray(numbers, dtype=np.int64)
        data = np.asarray(rows, dtype=object).reshape(len(rows), len(fields))
        self.columns = {f: data[:, i].astype(str) for i, f in enumerate(fields)}


def refuse_repeats(keys: Iterable, where: list[tuple[str, int]], what: Callable[[int], str],
                   column: str | None = None) -> None:
    """One rule for a measurement given twice: a ProjectError at the second row whose key
    repeats an earlier one, naming both lines.  keys: one hashable per row; where[i]: the
    (file, line) of row i; what(i): the measurement in words ("point 12 on image 3")."""
    seen: dict = {}
    for i, k in enumerate(keys):
        j = seen.setdefault(k, i)
        if j != i:
            (p0, l0), (p1, l1) = where[j], where[i]
            first = f"line {l0}" if p0 == p1 else f"{p0}, line {l0}"
            raise ProjectError(p1, f"{what(i)} given twice (first on {first})", l1, column)


def first_appearance(values: Iterable[str]) -> tuple[list[str], dict[str, int]]:
    """Distinct values in the order they first appear, and the index of each."""
    index: dict[str, int] = {}
    for v in values:
        index.setdefault(v, len(index))
    return list(index), index


def to_numbers(col: np.ndarray, path: str, lines: np.ndarray, name: str,
               allow_empty: bool = False) -> np.ndarray:
    """Strings to finite floats; ProjectError naming the first bad value."""
    col = np.asarray(col, dtype=str)
    empty = col == ""
    try:
        out = np.where(empty, "nan", col).astype(float)
        if (allow_empty or not empty.any()) and np.isfinite(out[~empty]).all():
            return out
    except ValueError:
        pass
    out = np.full(len(col), np.nan)
    for i, s in enumerate(col):
        if s == "":
            if not allow_empty:
                raise ProjectError(path, "empty value, a number is required", int(lines[i]),
                                   name)
            continue
        try:
            out[i] = float(s)
        except ValueError:
            raise ProjectError(path, f"'{s}' is not a number", int(lines[i]), name) from None
        if not np.isfinite(out[i]):
            raise ProjectError(path, f"'{s}' is not a finite number", int(lines[i]), name)
    return out


def finite_numbers(tokens: list[str], path: str, line: int, what: str) -> np.ndarray:
    """The tokens of one line as finite floats; ProjectError naming the file, the line, the
    field `what` and the first token that is no number."""
    try:
        out = np.array(tokens, dtype=float)
    except ValueError:
        bad = next(t for t in tokens if not is_number(t))
        raise ProjectError(path, f"'{bad}' is not a number", line, what) from None
    if not np.isfinite(out).all():
        raise ProjectError(path, "not a finite number", line, what)
    return out


def parse_number(text: str, path: str, line: int | None, name: str) -> float:
    """One finite number from a string, or ProjectError."""
    try:
        v = float(text)
    except (TypeError, ValueError):
        raise ProjectError(path, f"'{text}' is not a number", line, name) from None
    if not np.isfinite(v):
        raise ProjectError(path, f"'{text}' is not a finite number", line, name)
    return v


def numbers_in(text: str, path: str, line: int | None, name: str,
               count: int | None = None) -> list[float]:
    """Comma/blank separated numbers of one field (e.g. '26.577,38.811')."""
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    if count is not None and len(parts) != count:
        raise ProjectError(path, f"expected {count} numbers, found '{text.strip()}'", line,
                           name)
    return [parse_number(p, path, line, name) for p in parts]
