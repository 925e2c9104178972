"""The number formats of every file baarda writes: CSV tables and JSON documents.

Result tables (`write_csv`, `csv_chunks`) keep every number as it was computed: a float64
cell is the shortest text that reads back to the same double (pyarrow's cast to string:
0.05, 6460123.456789012, 1e-300), NaN is an empty cell, infinities inf and -inf; booleans
True/False, integers in decimal, text quoted as the csv module quotes it (QUOTE_MINIMAL).
The cells are formatted column by column by pyarrow (C++, in threads for long tables) and
joined into rows by pyarrow too.  Presentation tables (plans, the screening log:
`csv_text` with a printf format) are printed by pandas.  JSON documents print floats as
Python's repr, which round-trips as well.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, TypeAlias

import numpy as np
import pandas as pd

from baarda.io.table import FORMULA_START

CHUNK_ROWS = 8_192  # rows formatted and joined at a time (32,768: +129 MB transient at
# 143,242 rows of 25 columns, 8,192: +53 MB, as fast; benchmarks/README.md round three)
THREAD_ROWS = 100_000  # tables from this many rows on format their columns in threads

#: a table as columns (name -> an array of one value per row, NumPy's or pyarrow's, or one
#: value for every row), in order: the observation table is written from the result's
#: arrays without a DataFrame
Columns: TypeAlias = Mapping[str, Any]
Table: TypeAlias = "pd.DataFrame | Columns"


def csv_text(df: pd.DataFrame, float_format: str | None = None) -> str:
    """A table as CSV text (no index, LF line ends): with `float_format` (e.g. "%.4f") as
    pandas prints it, for presentation tables; without, every number as computed
    (csv_chunks)."""
    if float_format is None:
        return b"".join(csv_chunks(df)).decode("utf-8")
    buf = io.StringIO()
    df.to_csv(buf, index=False, float_format=float_format, lineterminator="\n")
    return buf.getvalue()


def write_csv(path: str | Path, df: Table, chunk_rows: int = CHUNK_ROWS,
              excel_safe: bool = False) -> None:
    """Write a result table as CSV (csv_chunks' bytes) atomically, chunk by chunk."""
    from baarda.output.atomic import atomic_open

    chunks = csv_chunks(df, chunk_rows, excel_safe)
    with atomic_open(path, "wb") as f:
        for chunk in chunks:
            f.write(chunk)
    if n_rows(df) >= THREAD_ROWS:  # the cells' memory back to the system, not kept by pyarrow
        import pyarrow as pa

        pa.default_memory_pool().release_unused()


def write_parquet(path: str | Path, df: Table) -> None:
    """Write a table as Parquet (pyarrow, zstd; numbers as stored, float64 exactly),
    atomically."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from baarda.output.atomic import atomic_open

    table = pa.Table.from_pandas(as_frame(df), preserve_index=False)
    with atomic_open(path, "wb") as f:
        pq.write_table(table, f, compression="zstd", row_group_size=1 << 20)


def _csv_row(values: list[str]) -> str:
    """One row as the csv module writes it (QUOTE_MINIMAL, LF line end)."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(values)
    return buf.getvalue()


def spreadsheet_cell(text: str) -> str:
    """One text cell as written with --excel-safe: a cell that begins with a FORMULA_START
    character gets a single quote in front and is enclosed in double quotes (quotes
    inside doubled, OWASP's advice), any other cell as the csv module writes it."""
    text = str(text)
    if text.startswith(FORMULA_START):
        return '"\'' + text.replace('"', '""') + '"'
    return _csv_row([text])[:-1]


#: a cell that begins with a FORMULA_START character, as a regular expression (RE2)
FORMULA_PATTERN = "^[" + "".join("\\" + c if c in "\\]^-[" else c for c in FORMULA_START) + "]"


def _spreadsheet_text(arr):
    """`spreadsheet_cell` of a string array (the cells it changes, already quoted)."""
    import pyarrow.compute as pc

    risky = pc.match_substring_regex(arr, FORMULA_PATTERN)
    if not pc.any(risky).as_py():
        return _quoted_text(arr)
    doubled = pc.replace_substring(arr, '"', '""')
    enclosed = pc.binary_join_element_wise("\"'", doubled, '"', "")
    return pc.if_else(risky, enclosed, _quoted_text(arr))


def _quoted_text(arr):
    """A string array with the cells that need it quoted as the csv module quotes them
    (a delimiter, a quote or a line break inside: enclosed in quotes, quotes doubled)."""
    import pyarrow.compute as pc

    special = pc.match_substring_regex(arr, '[,"\r\n]')
    if not pc.any(special).as_py():
        return arr
    doubled = pc.replace_substring(arr, '"', '""')
    enclosed = pc.binary_join_element_wise('"', doubled, '"', "")
    return pc.if_else(special, enclosed, arr)


def _texts(values) -> list[str | None]:
    """Objects of mixed types as text cells: None and NaN empty, anything else str()."""
    return [None if v is None or (isinstance(v, float) and v != v) else str(v)
            for v in values]


def cells(s: pd.Series, excel_safe: bool = False):
    """The CSV cells of one column as a pyarrow string array (module docstring); text cells
    by `spreadsheet_cell` with `excel_safe`."""
    import pyarrow as pa
    import pyarrow.compute as pc

    dt = s.dtype
    if dt == np.float64 or dt == np.float32:
        arr = pa.array(s.to_numpy(np.float64), from_pandas=True)  # NaN: null (empty)
    elif dt == np.bool_:
        return pc.if_else(pa.array(s.to_numpy()), "True", "False")
    else:
        try:
            arr = pa.array(s, from_pandas=True)
        except (pa.ArrowInvalid, pa.ArrowTypeError):  # objects of mixed types
            arr = pa.array(_texts(s), pa.string())
        if isinstance(arr, pa.ChunkedArray):
            arr = arr.combine_chunks()
        if pa.types.is_dictionary(arr.type):
            arr = arr.dictionary_decode()
    return _arrow_cells(arr, excel_safe)


def array_cells(a: np.ndarray, excel_safe: bool = False):
    """`cells` of a NumPy array (a column of a table given as arrays, `Columns`): the same
    text as the column in a DataFrame gives; an object array holds text (str, None or NaN
    for an empty cell; any other object as str())."""
    import pyarrow as pa
    import pyarrow.compute as pc

    if a.dtype.kind == "f":
        arr = pa.array(a.astype(np.float64, copy=False), from_pandas=True)
    elif a.dtype == np.bool_:
        return pc.if_else(pa.array(a), "True", "False")
    elif a.dtype.kind in "OUS":
        try:
            arr = pa.array(a, pa.string(), from_pandas=True)
        except (pa.ArrowInvalid, pa.ArrowTypeError):
            arr = pa.array(_texts(a), pa.string())
    else:
        arr = pa.array(a)
    return _arrow_cells(arr, excel_safe)


def _arrow_cells(arr, excel_safe: bool):
    """A pyarrow array as CSV cells (module docstring)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    t = arr.type
    if pa.types.is_boolean(t):
        arr = pc.if_else(arr, "True", "False")
    elif pa.types.is_null(t):
        arr = pa.nulls(len(arr), pa.string())
    elif not (pa.types.is_string(t) or pa.types.is_large_string(t)):
        arr = pc.cast(arr, pa.string())  # floats: shortest round trip; integers: decimal
    else:
        text = arr.cast(pa.string())
        arr = _spreadsheet_text(text) if excel_safe else _quoted_text(text)
    return pc.fill_null(arr, "")


def _per_row(value) -> bool:
    """Whether a `Columns` value holds one value per row (an array: NumPy's or pyarrow's),
    not one value for every row."""
    return hasattr(value, "__len__") and not isinstance(value, (str, bytes))


def n_rows(table: Table) -> int:
    """The rows of a table given as a DataFrame or as `Columns`."""
    if isinstance(table, pd.DataFrame):
        return len(table)
    return next((len(v) for v in table.values() if _per_row(v)), 1 if table else 0)


def as_frame(table: Table) -> pd.DataFrame:
    """A table as a DataFrame (`Columns`: its arrays, a text the same in every row
    broadcast)."""
    if isinstance(table, pd.DataFrame):
        return table
    return pd.DataFrame(dict(table), columns=list(table), index=pd.RangeIndex(n_rows(table)))


def csv_chunks(df: Table, chunk_rows: int = CHUNK_ROWS,
               excel_safe: bool = False) -> Iterator[bytes]:
    """The CSV bytes of a result table: the header, then `chunk_rows` rows at a time (each
    chunk's cells formatted when it is written: the text of the whole table is never held;
    a DataFrame's column of Python objects, whose type only the whole column decides, at
    once; a `Columns`' text, whose every cell is text, chunk by chunk); text cells
    spreadsheet-safe with `excel_safe` (`spreadsheet_cell`)."""
    names = [str(c) for c in df.columns] if isinstance(df, pd.DataFrame) else list(df)
    yield _csv_row(names).encode("utf-8")
    n = n_rows(df)
    if not names or n == 0:
        return
    import pyarrow.compute as pc

    column: Callable[[int, int], Any]
    if isinstance(df, pd.DataFrame):
        series = [df.iloc[:, j] for j in range(df.shape[1])]
        whole = {j: cells(s, excel_safe) for j, s in enumerate(series) if s.dtype == object}

        def column(j: int, r0: int):
            if j in whole:
                return whole[j].slice(r0, chunk_rows)
            return cells(series[j].iloc[r0: r0 + chunk_rows], excel_safe)
    else:
        values = list(df.values())

        def column(j: int, r0: int):
            v = values[j]
            if isinstance(v, np.ndarray):
                return array_cells(v[r0: r0 + chunk_rows], excel_safe)
            if _per_row(v):  # a pyarrow array, or chunked array (text joined by pyarrow)
                part = v.slice(r0, chunk_rows)
                return _arrow_cells(part.combine_chunks() if hasattr(part, "combine_chunks")
                                    else part, excel_safe)
            return array_cells(np.full(min(chunk_rows, n - r0), v,  # the same in every row
                                       object if isinstance(v, str) else None), excel_safe)

    pool = ThreadPoolExecutor(min(len(names), os.cpu_count() or 1)) \
        if n >= THREAD_ROWS and len(names) > 1 else None
    try:
        for r0 in range(0, n, chunk_rows):
            js = range(len(names))
            parts = list(pool.map(column, js, [r0] * len(names))) if pool else \
                [column(j, r0) for j in js]
            if len(parts) == 1:  # a row of one empty cell is written "" (not a blank line)
                parts[0] = pc.if_else(pc.equal(parts[0], ""), '""', parts[0])
            rows = parts[0] if len(parts) == 1 else pc.binary_join_element_wise(*parts, ",")
            del parts
            lines = pc.binary_join_element_wise(rows, "", "\n")  # each row with its line end
            del rows
            yield _data(lines)
    finally:
        if pool:
            pool.shutdown()


def _data(arr) -> bytes:
    """The characters of a pyarrow string array, one after another."""
    import pyarrow as pa

    _, offs, data = arr.buffers()
    width = np.int64 if pa.types.is_large_string(arr.type) else np.int32
    o = np.frombuffer(offs, width)[arr.offset: arr.offset + len(arr) + 1]
    return b"" if data is None else memoryview(data)[int(o[0]): int(o[-1])].tobytes()


def json_default(o):
    """json.dumps default for NumPy scalars and arrays."""
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def json_text(doc) -> str:
    """A JSON document, indented, with NumPy values converted."""
    return json.dumps(doc, indent=2, default=json_default) + "\n"
