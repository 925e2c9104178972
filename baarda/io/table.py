"""A CSV table reader that remembers where every value came from.

Blank lines and lines starting with '#' are skipped.  Values are kept as strings with
the 1-based line number of their row so that every later check can name file, line and
column.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from baarda.errors import ProjectError
from baarda.io.records import Columns


class Table(Columns):
    """Columns of a CSV file as string arrays, with line numbers."""

    def __init__(self, path: str | Path, required: list[str]):
        self.path = str(path)
        if not Path(path).is_file():
            raise ProjectError(self.path, "file not found")
        rows, lines = [], []
        with open(path, newline="", encoding="utf-8-sig") as f:
            reader = csv.reader(f, skipinitialspace=True)
            header = None
            for row in reader:
                if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
                    continue
                if header is None:
                    header = [h.strip() for h in row]
                    header_line = reader.line_num
                    continue
                rows.append([c.strip() for c in row])
                lines.append(reader.line_num)
        if header is None:
            raise ProjectError(self.path, "the file is empty (no header line)")
        for name in required:
            if name not in header:
                raise ProjectError(self.path, f"missing column '{name}' (header: "
                                   f"{', '.join(header)})", line=header_line)
        seen = set()
        for name in header:
            if name in seen:
                raise ProjectError(self.path, "duplicate column", header_line, name)
            seen.add(name)
        width = len(header)
        for row, line in zip(rows, lines, strict=True):
            if len(row) != width:
                raise ProjectError(self.path, f"expected {width} fields, found {len(row)}", line)
        self.header = header
        self.lines = np.asarray(lines, dtype=np.int64)
        data = np.asarray(rows, dtype=object).reshape(len(rows), width)
        self.columns = {h: data[:, i].astype(str) for i, h in enumerate(header)}

    def unique_ids(self, name: str) -> list[str]:
        """Column of identifiers that must be unique."""
        col = self.text(name)
        seen: dict[str, int] = {}
        for i, s in enumerate(col):
            if s in seen:
                raise ProjectError(self.path, f"duplicate id '{s}' (first on line {seen[s]})",
                                   int(self.lines[i]), name)
            seen[s] = int(self.lines[i])
        return list(col)

    def lookup(self, name: str, index: dict[str, int], what: str) -> np.ndarray:
        """Map a reference column through `index`; unknown ids are an error."""
        col = self.text(name)
        out = np.empty(len(col), dtype=np.int64)
        for i, s in enumerate(col):
            j = index.get(s)
            if j is None:
                raise ProjectError(self.path, f"unknown {what} '{s}'", int(self.lines[i]), name)
            out[i] = j
        return out
