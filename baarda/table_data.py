"""A table as data (statsmodels' `Summary`): its columns with their titles, units and
number formats, and its rows, built once; the text, HTML and PDF reports render it
(`text_lines` here; report/html_base.html_table, report/quality_pdf._table) and no renderer
formats a number or a unit itself: every cell is `TableData.cells()`.

Number rules (`cell`): a fixed number of decimals per column (format specs like ".3f"), no
"-0", no "True"/"False" (yes / blank), "-" for a missing value.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np


def num(x: float, decimals: int) -> str:
    """Fixed decimals without a negative zero."""
    return f"{round(float(x), decimals) + 0.0:.{decimals}f}"


def cell(v: Any, f: str | None = None) -> str:
    """A table cell as text by the number rules (module docstring); f: a format spec
    ("inf": an infinite value shown as ∞)."""
    if isinstance(v, bool | np.bool_):
        return "yes" if v else ""
    if isinstance(v, float | np.floating | int | np.integer) and not isinstance(v, bool):
        x = float(v)
        if not np.isfinite(x):
            return "∞" if np.isinf(x) and x > 0 and f == "inf" else "-"
        if isinstance(v, int | np.integer) and not f:
            return str(int(v))
        f = f or ".4g"
        m = re.fullmatch(r"([+]?)\.(\d+)f", f)
        if m:
            s = num(x, int(m.group(2)))
            return ("+" + s if m.group(1) and not s.startswith("-") else s)
        s = format(x, f)
        return s[1:] if re.fullmatch(r"-0(\.0*)?(e[+-]?0+)?", s) else s
    return "" if v is None else str(v)


@dataclass(frozen=True)
class Column:
    """One column: `key` of the rows' values, its `title` (the text report's header
    `text_title` where it differs), its number format `fmt` (`unit_fmt`: the format by the
    unit of the row, table.unit_key, over `fmt`), whether it holds words (`text`: left
    aligned) and, for the text report, its width in characters, the spaces before it and
    the words that precede each cell (`label`, e.g. "MDB ")."""

    key: str
    title: str = ""
    fmt: str | None = None
    unit_fmt: Mapping[str, str] = field(default_factory=dict)
    text: bool = False
    width: int = 0
    gap: int = 0
    label: str = ""
    align: str = ""  # "<" or ">" in the text report; default: words left, numbers right
    text_title: str | None = None

    @property
    def head(self) -> str:
        return self.title or self.key


@dataclass(frozen=True)
class TableData:
    """A table: its columns and rows (tuples in the columns' order); `unit_key`: the key
    of the rows' unit where a column's format depends on it; `row_class`: a word per row
    (the HTML's row classes: rejected, flagged)."""

    columns: tuple[Column, ...]
    rows: tuple[tuple, ...]
    unit_key: str = ""
    row_class: tuple[str, ...] = ()

    @staticmethod
    def of(columns: Sequence[Column], rows) -> TableData:
        """A table from rows given as mappings (by the columns' keys) or sequences; a
        pandas DataFrame's rows by its column names."""
        cols = tuple(columns)
        if hasattr(rows, "itertuples"):  # a DataFrame
            keys = [str(c) for c in rows.columns]
            pos = [keys.index(c.key) for c in cols]
            out = tuple(tuple(r[k] for k in pos) for r in rows.itertuples(index=False))
        else:
            out = tuple(tuple(r[c.key] for c in cols) if isinstance(r, Mapping)
                        else tuple(r) for r in rows)
        return TableData(cols, out)

    @staticmethod
    def from_frame(df, fmt: Mapping[str, str] | None = None,
                   text: Sequence[str] = ()) -> TableData:
        """Every column of a DataFrame, formats by column name, `text`: word columns."""
        fmt = fmt or {}
        cols = [Column(str(c), fmt=fmt.get(str(c)), text=str(c) in text) for c in df.columns]
        return TableData(tuple(cols), tuple(tuple(r) for r in df.itertuples(index=False)))

    def with_row_class(self, classes: Sequence[str]) -> TableData:
        return TableData(self.columns, self.rows, self.unit_key, tuple(classes))

    @property
    def titles(self) -> list[str]:
        return [c.head for c in self.columns]

    def _fmt(self, c: Column, row: tuple) -> str | None:
        if c.unit_fmt and self.unit_key:
            unit = row[[x.key for x in self.columns].index(self.unit_key)]
            return c.unit_fmt.get(str(unit), c.fmt)
        return c.fmt

    def cells(self) -> list[list[str]]:
        """Every cell as text by the number rules and the columns' formats."""
        return [[cell(v, self._fmt(c, r)) for c, v in zip(self.columns, r, strict=True)]
                for r in self.rows]


def text_lines(t: TableData, header: bool = True) -> list[str]:
    """The table as fixed-width text lines (the text report): each column padded to its
    width, after its gap and label; trailing blanks removed."""
    def one(c: Column, s: str) -> str:  # an empty cell: no label either
        align = c.align or ("<" if c.text else ">")
        return " " * c.gap + (c.label if s else " " * len(c.label)) + f"{s:{align}{c.width}}"

    out = []
    if header:
        out.append("".join(one(c, c.head if c.text_title is None else c.text_title)
                           for c in t.columns).rstrip())
    for row in t.cells():
        out.append("".join(one(c, s) for c, s in zip(t.columns, row, strict=True)).rstrip())
    return out
