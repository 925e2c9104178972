"""The number formats of every file baarda writes: CSV tables and JSON documents.

`csv_text` / `write_csv` print a table as pandas' ``to_csv(index=False, float_format=F,
lineterminator="\\n")`` does, byte for byte.  Tables of `FAST_ROWS` rows and more go through
the vectorised writer (`csv_chunks`: numba kernels in output/csv_kernels.py, text columns
through pyarrow): float64 columns in C's ``%.Pg`` correctly rounded (the few values whose
rounding is not certain, and those beyond 1e±13, formatted by Python), text columns quoted
as the csv module quotes them, booleans True/False, integers in decimal; a table with any
other column type, one column or no rows is written by pandas.
"""

from __future__ import annotations

import csv
import io
import json
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd

RESULT_FORMAT = "%.10g"  # result tables: 10 significant digits
FAST_ROWS = 20_000  # tables from this many rows on: the vectorised writer
CHUNK_ROWS = 262_144  # rows formatted at a time by the vectorised writer
_G_FORMAT = re.compile(r"%\.(\d+)g")
_SPECIAL = '[,"\r\n]'  # a text cell with one of these may need quotes (csv.QUOTE_MINIMAL)


def csv_text(df: pd.DataFrame, float_format: str = RESULT_FORMAT) -> str:
    """A table as CSV text (no index, LF line ends)."""
    return b"".join(_csv_bytes(df, float_format, None)).decode("utf-8")


def _csv_bytes(df: pd.DataFrame, float_format: str, fast: bool | None) -> Iterator[bytes]:
    """The CSV of a table in chunks: the vectorised writer where it takes the table (and
    `fast` is not False; None: from FAST_ROWS rows on), else pandas' text in one chunk."""
    if fast_csv_possible(df, float_format) and (len(df) >= FAST_ROWS if fast is None
                                                else fast):
        try:
            return csv_chunks(df, float_format)
        except TypeError:  # a column of objects that are not text: pandas prints them
            pass
    return iter([pandas_csv_text(df, float_format).encode("utf-8")])


def pandas_csv_text(df: pd.DataFrame, float_format: str = RESULT_FORMAT) -> str:
    """pandas' CSV of a table, the reference of the vectorised writer."""
    buf = io.StringIO()
    df.to_csv(buf, index=False, float_format=float_format, lineterminator="\n")
    return buf.getvalue()


def write_csv(path: str | Path, df: pd.DataFrame, float_format: str = RESULT_FORMAT,
              fast: bool | None = None) -> None:
    """Write a table as CSV (csv_text's bytes) atomically, in chunks of rows; `fast` forces
    (True, where possible) or avoids (False) the vectorised writer (None: from FAST_ROWS
    rows on)."""
    from baarda.output.atomic import atomic_open

    chunks = _csv_bytes(df, float_format, fast)
    with atomic_open(path, "wb") as f:
        for chunk in chunks:
            f.write(chunk)


def write_parquet(path: str | Path, df: pd.DataFrame) -> None:
    """Write a table as Parquet (pyarrow, zstd; numbers as stored, float64 exactly),
    atomically."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from baarda.output.atomic import atomic_open

    table = pa.Table.from_pandas(df, preserve_index=False)
    with atomic_open(path, "wb") as f:
        pq.write_table(table, f, compression="zstd", row_group_size=1 << 20)


def _precision(float_format: str) -> int | None:
    m = _G_FORMAT.fullmatch(float_format)
    p = int(m.group(1)) if m else 0
    return p if 1 <= p <= 12 else None


def _column_kind(s: pd.Series) -> str | None:
    dt = s.dtype
    if dt == np.float64:
        return "float"
    if dt == np.bool_:
        return "bool"
    if isinstance(dt, np.dtype) and dt.kind in "iu":
        return "int"
    if isinstance(dt, pd.StringDtype) or dt == np.dtype(object):
        return "text"
    return None


def fast_csv_possible(df: pd.DataFrame, float_format: str = RESULT_FORMAT) -> bool:
    """Whether the vectorised writer takes this table (module docstring)."""
    return (len(df) > 0 and df.shape[1] > 1 and _precision(float_format) is not None
            and df.columns.is_unique
            and all(_column_kind(df.iloc[:, j]) is not None for j in range(df.shape[1])))


def _csv_row(values: list[str]) -> str:
    """One row as the csv module writes it (QUOTE_MINIMAL, LF line end)."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(values)
    return buf.getvalue()


def _quoted(value: str) -> str:
    """A cell as the csv module writes it (QUOTE_MINIMAL)."""
    return _csv_row([value, ""])[:-2]


class _TextColumn:
    """A text, bool or integer column's cells for the vectorised writer: `cells(r0, r1)`
    gives the bytes, starts and lengths of rows r0..r1 (empty for missing values, quoted as
    the csv module quotes)."""

    def __init__(self, s: pd.Series):
        import pyarrow as pa
        import pyarrow.compute as pc

        from baarda.output.csv_kernels import any_byte

        kind = _column_kind(s)
        self.flags = None
        if kind == "bool":
            self.flags = s.to_numpy()
            return
        if kind == "int":
            self.arr = pc.cast(pa.array(s.to_numpy()), pa.string())
            return
        try:
            arr = pa.array(s, from_pandas=True)
        except (pa.ArrowInvalid, pa.ArrowTypeError):
            arr = None
        if isinstance(arr, pa.ChunkedArray):
            arr = arr.combine_chunks()
        if arr is not None and pa.types.is_null(arr.type):  # nothing but missing values
            arr = pa.nulls(len(arr), pa.string())
        if arr is None or not (pa.types.is_string(arr.type)
                               or pa.types.is_large_string(arr.type)):
            raise TypeError("not a text column")
        if arr.null_count:
            arr = pc.fill_null(arr, "")
        data, _ = _buffers(arr)
        if any_byte(data, np.frombuffer(_SPECIAL.strip("[]").encode(), np.uint8)):
            special = pc.match_substring_regex(arr, _SPECIAL).to_numpy(zero_copy_only=False)
            vals = arr.to_pylist()
            for i in np.flatnonzero(special):
                vals[i] = _quoted(vals[i])
            arr = pa.array(vals, type=pa.string())
        self.arr = arr

    def cells(self, r0: int, r1: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self.flags is not None:
            f = self.flags[r0:r1]
            return _BOOL_TEXT, np.where(f, 5, 0), np.where(f, 4, 5)
        data, offs = _buffers(self.arr)
        o = offs[r0: r1 + 1].astype(np.int64)
        return data[o[0]: o[-1]], o[:-1] - o[0], np.diff(o)


_BOOL_TEXT = np.frombuffer(b"FalseTrue", np.uint8)


def _buffers(arr) -> tuple[np.ndarray, np.ndarray]:
    """data (uint8) and offsets of a pyarrow string array (without a slice offset)."""
    import pyarrow as pa

    _, offs, data = arr.buffers()
    width = np.int64 if pa.types.is_large_string(arr.type) else np.int32
    o = np.frombuffer(offs, width)[arr.offset: arr.offset + len(arr) + 1]
    d = np.frombuffer(data, np.uint8) if data is not None else np.zeros(0, np.uint8)
    return d, o


CELL = 24  # bytes of a formatted float cell (%.12g needs at most 19)


def csv_chunks(df: pd.DataFrame, float_format: str = RESULT_FORMAT,
               chunk_rows: int = CHUNK_ROWS) -> Iterator[bytes]:
    """The CSV bytes of a table (fast_csv_possible), the header first, then chunk_rows rows
    at a time; TypeError (before any bytes) for a column of objects that are not all text."""
    precision = _precision(float_format)
    assert precision is not None
    tol = max(1e-6, 100.0 * 10.0**precision * 2.0**-53)
    cols = [df.iloc[:, j] for j in range(df.shape[1])]
    kinds = np.array([0 if _column_kind(s) == "float" else 1 for s in cols], np.int8)
    index = np.zeros(len(cols), np.int32)
    index[kinds == 0] = np.arange(int(np.sum(kinds == 0)))
    index[kinds == 1] = np.arange(int(np.sum(kinds == 1)))
    floats = [s.to_numpy(np.float64) for s, k in zip(cols, kinds, strict=True) if k == 0]
    texts = [_TextColumn(s) for s, k in zip(cols, kinds, strict=True) if k == 1]
    return _chunks(df, float_format, chunk_rows, precision, tol, kinds, index, floats, texts)


def _chunks(df, float_format, chunk_rows, precision, tol, kinds, index, floats, texts):
    from baarda.output import csv_kernels as ck

    cols = df.columns
    yield _csv_row([str(c) for c in cols]).encode("utf-8")  # the header
    n = len(df)
    nf, nt = len(floats), len(texts)
    for r0 in range(0, n, chunk_rows):
        r1 = min(n, r0 + chunk_rows)
        m = r1 - r0
        fv = np.empty((m, nf))
        for j, v in enumerate(floats):
            fv[:, j] = v[r0:r1]
        cells = np.empty((m, nf, CELL), np.uint8)
        lengths = np.empty((m, nf), np.int64)
        ck.format_floats(fv, precision, tol, cells, lengths)
        for i, j in zip(*np.nonzero(lengths < 0), strict=True):
            text = (float_format % fv[i, j]).encode("ascii")
            cells[i, j, :len(text)] = np.frombuffer(text, np.uint8)
            lengths[i, j] = len(text)
        cell_start = np.empty((nt, m), np.int64)
        cell_len = np.empty((nt, m), np.int64)
        datas, base = [], 0
        for j, col in enumerate(texts):
            d, st, ln = col.cells(r0, r1)
            datas.append(d)
            cell_start[j] = st + base
            cell_len[j] = ln
            base += len(d)
        pool = np.concatenate(datas) if datas else np.zeros(0, np.uint8)
        row_len = lengths.sum(axis=1) + cell_len.sum(axis=0) + len(cols)
        row_start = np.zeros(m + 1, np.int64)
        np.cumsum(row_len, out=row_start[1:])
        out = np.empty(int(row_start[-1]), np.uint8)
        ck.assemble_rows(kinds, index, cells, lengths, cell_start, cell_len, pool, row_start,
                         out)
        yield out.data


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
