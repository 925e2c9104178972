"""observations.csv (or observations.parquet) of a result folder, read back: one row per
observation component, the statistics columns as numbers (missing ones NaN / False).  Bad
cells raise ProjectError naming the file, line and column."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from baarda.errors import ProjectError
from baarda.io.table import Table
from baarda.schema import (  # the contract of the files (baarda/schema.py)
    FLAG_COLUMNS,
    FRAME_COLUMNS,
    LABEL_COLUMNS,
    NUMBER_COLUMNS,
    REQUIRED_COLUMNS,
)


def numbers(t: Table, name: str) -> np.ndarray:
    """A numeric column; empty cells are NaN, 'inf' is allowed (uncontrolled MDB)."""
    fast = t.floats(name)  # a plain file: pyarrow's parser (millions of rows)
    if fast is not None:
        return fast
    col = t.column(name)
    out = pd.to_numeric(pd.Series(col).replace("", "nan"), errors="coerce").to_numpy(float)
    bad = np.flatnonzero(np.isnan(out) & (col != "") & (np.char.lower(col) != "nan"))
    if len(bad):
        i = int(bad[0])
        raise ProjectError(t.path, f"'{col[i]}' is not a number", int(t.lines[i]), name)
    return out


def flags(t: Table, name: str) -> np.ndarray:
    """A True/False column (also 1/0, empty = False)."""
    import pyarrow.compute as pc

    arrow = t.strings(name)
    if arrow is not None:  # as written: True / False
        yes = pc.equal(arrow, "True")
        if pc.all(pc.or_(yes, pc.equal(arrow, "False"))).as_py():
            return np.asarray(yes.to_numpy(), dtype=bool)
    col = t.column(name)
    if col.dtype.kind == "U" and col.dtype.itemsize <= 4 * 5:  # 'True'/'False' as written
        yes = col == "True"
        if (yes | (col == "False")).all():
            return yes
    col = np.char.lower(col)
    yes = np.isin(col, ["true", "1", "yes"])
    bad = np.flatnonzero(~yes & ~np.isin(col, ["false", "0", "no", ""]))
    if len(bad):
        i = int(bad[0])
        raise ProjectError(t.path, f"'{t.column(name)[i]}' is not True or False",
                           int(t.lines[i]), name)
    return yes


OBS_TEXT = ["kind", "photo", "model", "point", "component"]


def _observation_frame(has, text, number, flag) -> pd.DataFrame:
    """The observation table from a file's columns: text(c) of the label columns (a missing
    one: text(c) says what), number(c) and flag(c) of those present (missing statistics
    columns become NaN / False); `frame` is the photo, else the model."""
    df = pd.DataFrame({c: text(c) for c in OBS_TEXT})
    df["frame"] = df["photo"].where(df["photo"] != "", df["model"])
    for c in NUMBER_COLUMNS:
        df[c] = number(c) if has(c) else np.nan
    for c in FLAG_COLUMNS:
        df[c] = flag(c) if has(c) else False
    for c in LABEL_COLUMNS:
        df[c] = text(c)
    return df


def _empty_residual(df: pd.DataFrame) -> int | None:
    """The row of the first empty residual, or None."""
    missing = np.flatnonzero(np.isnan(df["residual"].to_numpy()))
    return int(missing[0]) if len(missing) else None


def read_observations(path: str | Path) -> pd.DataFrame:
    """observations.csv as a DataFrame (missing statistics columns become NaN / False)."""
    t = Table(path, list(REQUIRED_COLUMNS))
    if not any(t.has(c) for c in FRAME_COLUMNS):
        raise ProjectError(t.path, "missing column 'photo' (or 'model')")
    def text(c: str):
        if not t.has(c):
            return ""
        allow_empty = c not in ("kind", "component")
        col = t.strings(c)  # pyarrow strings of a plain file: straight into the frame
        if col is not None and (allow_empty or not pc.any(pc.equal(col, "")).as_py()):
            return pd.Series(col, dtype="str")
        return t.text(c, allow_empty=allow_empty)  # NumPy strings, or the error's line

    import pyarrow.compute as pc

    df = _observation_frame(t.has, text, lambda c: numbers(t, c), lambda c: flags(t, c))
    df["line"] = t.lines
    row = _empty_residual(df)
    if row is not None:
        raise ProjectError(t.path, "empty residual", int(t.lines[row]), "residual")
    return df


def read_observations_parquet(path: str | Path) -> pd.DataFrame:
    """observations.parquet as read_observations gives observations.csv (the numbers as
    computed, not rounded to the CSV's 10 digits; `line` = row number + 2, the line the row
    would have in observations.csv)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    try:
        t = pq.read_table(path)
    except (pa.ArrowException, OSError) as e:
        raise ProjectError(str(path), f"not a readable Parquet file ({e})") from None
    names = set(t.column_names)
    for c in list(REQUIRED_COLUMNS):
        if c not in names:
            raise ProjectError(str(path), f"missing column '{c}'")
    if not names & set(FRAME_COLUMNS):
        raise ProjectError(str(path), "missing column 'photo' (or 'model')")
    n = t.num_rows

    def text(c: str) -> pd.Series:
        if c not in names:
            return pd.Series(np.full(n, "", dtype=object), dtype="str")
        col = t.column(c)
        if not (pa.types.is_string(col.type) or pa.types.is_large_string(col.type)
                or pa.types.is_null(col.type)):
            raise ProjectError(str(path), f"column '{c}' is not text ({col.type})", None, c)
        return pd.Series(col.cast(pa.string()).fill_null(""), dtype="str")

    def number(c: str) -> np.ndarray:
        col = t.column(c)
        if not (pa.types.is_floating(col.type) or pa.types.is_integer(col.type)
                or pa.types.is_null(col.type)):
            raise ProjectError(str(path), f"column '{c}' is not numeric ({col.type})", None, c)
        return col.to_numpy().astype(float)

    def flag(c: str) -> np.ndarray:
        col = t.column(c)
        if not pa.types.is_boolean(col.type):
            raise ProjectError(str(path), f"column '{c}' is not True/False ({col.type})",
                               None, c)
        return col.to_numpy(zero_copy_only=False).astype(bool)

    df = _observation_frame(names.__contains__, text, number, flag)
    df["line"] = np.arange(2, n + 2)
    row = _empty_residual(df)
    if row is not None:
        raise ProjectError(str(path), f"empty residual in row {row + 1}", None, "residual")
    return df
