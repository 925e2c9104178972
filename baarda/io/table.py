"""A CSV table reader that remembers where every value came from.

Blank lines and lines starting with '#' are skipped; values are stripped of surrounding
blanks; every record is one line.  Every later check names file, line and column.

Two ways to read, with the same result: a plain machine-written file (UTF-8, no comments,
quotes or blanks) is parsed by pyarrow's CSV reader (two million image points in well under
a second), and its line numbers are worked out only when an error needs one; any other file,
and any file the fast reader does not take as it is, is read line by line here (the
reference, which also gives the exact error).
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np

from baarda.errors import ProjectError
from baarda.io.records import Columns
from baarda.io.text_files import (
    C0_DEL,
    ENCODING,
    decode_text,
    file_bytes,
    is_utf8,
    no_nul,
    split_lines,
)

# quotes, blanks, comments, CR, blank lines, lines that start with a comma (or consist of
# commas): the line-by-line reader
NOT_PLAIN = (b'"', b" ", b"\t", b"#", b"\r", b"\n\n", b"\n,")
MAX_FIELDS_FACTOR = 4  # a line with more than this many times the header's fields is refused


#: the control characters records.CONTROL refuses, as UTF-8 bytes (C1 as \xc2\x80-\x9f)
CONTROL_BYTES = re.compile(f"[{C0_DEL}]".encode("ascii") + b"|\xc2[\x80-\x9f]")


#: the first characters that make a spreadsheet read a cell as a formula (OWASP, CSV
#: injection): with --excel-safe such a text cell is written with a single quote before it
#: (output/tables.spreadsheet_cell), and read back without it
FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def unquoted_formulas(values: np.ndarray) -> np.ndarray:
    """Text cells of a table written with --excel-safe as they were given: a single quote
    before a FORMULA_START character taken off."""
    out = values.astype(object)
    for k in np.flatnonzero(np.char.startswith(values.astype(str), "'")):
        v = str(values[k])
        if v[1:2] and v[1] in FORMULA_START:
            out[k] = v[1:]
    return out.astype(str)


class Table(Columns):
    """Columns of a CSV file as string arrays, with line numbers; the text cells of a table
    that a run wrote with --excel-safe (its run.json says so) as they were given."""

    def __init__(self, path: str | Path, required: list[str], encoding: str = ENCODING):
        from baarda.io.run_manifest import written_excel_safe

        self.path = str(path)
        self._excel_safe = written_excel_safe(Path(path).parent)
        data = file_bytes(path)
        while data.startswith(b"\xef\xbb\xbf"):  # a byte-order mark (two: files joined)
            data = data[3:]
        if not is_utf8(encoding):  # the readers below take UTF-8
            data = decode_text(data, self.path, encoding).encode("utf-8")
        if CONTROL_BYTES.search(data):  # NUL, ESC, BEL ...: named with line and column
            text = data.decode("utf-8", "replace")
            no_nul(text, self.path, [c.strip() for c in split_lines(text)[0].split(",")])
        self._arrow = None
        if plain(data):
            self._arrow = _read_arrow(data)
        if self._arrow is not None:
            self.header = list(self._arrow.column_names)
            self._header_line = 1
            self._columns: dict[str, np.ndarray] = {}
            self._lines: np.ndarray | None = None
        else:
            self._read_lines(data)
        self._check_header(required)

    # ---------------------------------------------------------------- reading
    def _read_lines(self, data: bytes) -> None:
        text = decode_text(data, self.path)
        header, header_line, width = None, 0, 0
        rows, lines = [], []
        for no, line in enumerate(split_lines(text), start=1):
            s = line.strip()
            if not s.replace(",", "").strip() or s.startswith("#"):
                continue
            if header is not None and line.count(",") + 1 > MAX_FIELDS_FACTOR * width:
                raise ProjectError(self.path, f"expected {width} fields, found "
                                   f"{line.count(',') + 1}", no)
            try:
                row = ([c.strip() for c in line.split(",")] if '"' not in line else
                       [c.strip() for c in next(csv.reader([line], skipinitialspace=True))])
            except csv.Error as e:
                raise ProjectError(self.path, f"not a CSV record: {e}", no) from None
            if header is None:
                header, header_line, width = row, no, len(row)
                continue
            if len(row) != width:
                raise ProjectError(self.path, f"expected {width} fields, found {len(row)}", no)
            rows.append(row)
            lines.append(no)
        if header is None:
            raise ProjectError(self.path, "the file is empty (no header line)")
        self.header, self._header_line = header, header_line
        self._lines = np.asarray(lines, dtype=np.int64)
        table = np.asarray(rows, dtype=object).reshape(len(rows), width)
        self._columns = {h: self._as_given(table[:, i].astype(str))
                         for i, h in enumerate(header)}

    def _check_header(self, required: list[str]) -> None:
        for name in required:
            if name not in self.header:
                raise ProjectError(self.path, f"missing column '{name}' (header: "
                                   f"{', '.join(self.header)})", line=self._header_line)
        seen = set()
        for name in self.header:
            if name in seen:
                raise ProjectError(self.path, "duplicate column", self._header_line, name)
            seen.add(name)

    # ------------------------------------------------------------ the columns
    @property
    def lines(self) -> np.ndarray:  # type: ignore[override]  # worked out on first use
        """1-based line number of every row (worked out on first use for the fast path)."""
        if self._lines is None:  # the fast path has no blank or comment lines
            self._lines = np.arange(2, len(self) + 2, dtype=np.int64)
        return self._lines

    @property
    def columns(self) -> dict[str, np.ndarray]:  # type: ignore[override]
        return {h: self.column(h) for h in self.header}

    def column(self, name: str) -> np.ndarray:
        if name not in self._columns:  # the fast path: turned into strings on first use
            assert self._arrow is not None  # the fast path
            col = self._arrow.column(name).to_numpy(zero_copy_only=False)
            self._columns[name] = self._as_given(col.astype(str))
        return self._columns[name]

    def _as_given(self, values: np.ndarray) -> np.ndarray:
        return unquoted_formulas(values) if self._excel_safe else values

    def has(self, name: str) -> bool:
        return name in self.header

    def __len__(self) -> int:
        return self._arrow.num_rows if self._arrow is not None else len(self._lines)  # type: ignore[arg-type]  # the slow path sets _lines

    def numbers(self, name: str, allow_empty: bool = False) -> np.ndarray:
        out = self.floats(name)
        if out is not None:
            nan = np.isnan(out)
            if np.isfinite(out[~nan]).all() and (allow_empty or not nan.any()):
                return out
        return super().numbers(name, allow_empty)  # the exact reading, and its error

    def strings(self, name: str):
        """A column as pyarrow strings, or None where the fast reader did not take the file
        (for millions of rows: no NumPy strings on the way)."""
        return None if self._arrow is None else self._arrow.column(name)

    def floats(self, name: str) -> np.ndarray | None:
        """A column as floats parsed by pyarrow (empty -> NaN; inf and nan as written), or
        None where the fast reader did not take the file or a value is not a number (read
        it with numbers() or the caller's own reading, which name the line)."""
        if self._arrow is None:
            return None
        import pyarrow as pa
        import pyarrow.compute as pc

        col = self._arrow.column(name)  # a string column: _read_arrow reads every one so
        try:
            vals = pc.cast(pc.if_else(pc.equal(col, ""), pa.scalar(None, pa.string()), col),
                           pa.float64())
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
            return None
        return vals.to_numpy(zero_copy_only=False).astype(float)

    def codes(self, name: str) -> tuple[np.ndarray, list[str]]:
        """(index of every row's value among the distinct values (int64), the distinct
        values in the order they first appear); empty values are an error."""
        if self._arrow is not None:
            import pyarrow.compute as pc

            enc = pc.dictionary_encode(self._arrow.column(name)).combine_chunks()
            uniques = enc.dictionary.to_pylist()
            if "" not in uniques:
                return enc.indices.to_numpy().astype(np.int64), uniques
        col = self.text(name)
        import pandas as pd

        codes, uniques = pd.factorize(col)
        return np.asarray(codes, np.int64), [str(u) for u in uniques]

    def unique_ids(self, name: str) -> list[str]:
        """Column of identifiers that must be unique."""
        codes, uniques = self.codes(name)
        if len(uniques) == len(codes):
            return uniques
        first = np.full(len(uniques), -1)
        for i, c in enumerate(codes):
            if first[c] >= 0:
                raise ProjectError(self.path, f"duplicate id '{uniques[c]}' (first on line "
                                   f"{int(self.lines[first[c]])})", int(self.lines[i]), name)
            first[c] = i
        return uniques  # pragma: no cover

    def lookup(self, name: str, index: dict[str, int], what: str) -> np.ndarray:
        """Map a reference column through `index`; unknown ids are an error."""
        codes, uniques = self.codes(name)
        mapped = np.array([index.get(u, -1) for u in uniques], dtype=np.int64)
        out = mapped[codes] if len(codes) else np.zeros(0, np.int64)
        bad = np.flatnonzero(out < 0)
        if len(bad):
            i = int(bad[0])
            raise ProjectError(self.path, f"unknown {what} '{uniques[codes[i]]}'",
                               int(self.lines[i]), name)
        return out


def plain(data: bytes) -> bool:
    """A file the fast reader reads as the line-by-line one does."""
    return bool(data) and not data.startswith((b"\n", b",")) and \
        not any(s in data for s in NOT_PLAIN)


def _read_arrow(data: bytes):
    """The table read by pyarrow with every column as strings, or None when the file is
    not one pyarrow reads as this module does (a different field count on a line, bytes
    that are not UTF-8, ...): the line-by-line reader then gives the exact error."""
    import io

    import pyarrow as pa
    import pyarrow.csv as pcsv

    head = data[:data.find(b"\n")] if b"\n" in data else data
    try:  # pyarrow checks the values, not the column names
        names = head.decode("utf-8").split(",")
    except UnicodeDecodeError:
        return None
    if len(set(names)) != len(names) or "\ufeff" in head.decode("utf-8"):
        return None  # the line-by-line reader names the duplicate column or the mark
    try:  # the names as read here, every column a string (pyarrow drops a byte-order mark
        # and would infer the types of columns whose names it then sees otherwise)
        return pcsv.read_csv(
            io.BytesIO(data), read_options=pcsv.ReadOptions(use_threads=True,
                                                            column_names=names,
                                                            skip_rows=1),
            parse_options=pcsv.ParseOptions(delimiter=",", quote_char=False),
            convert_options=pcsv.ConvertOptions(
                column_types={n: pa.string() for n in names}, strings_can_be_null=False,
                quoted_strings_can_be_null=False))
    except (pa.ArrowInvalid, pa.ArrowKeyError, UnicodeDecodeError):
        return None

