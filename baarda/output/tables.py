"""The number formats of every file baarda writes: CSV tables and JSON documents."""

from __future__ import annotations

import io
import json

import numpy as np
import pandas as pd

RESULT_FORMAT = "%.10g"  # result tables: 10 significant digits


def csv_text(df: pd.DataFrame, float_format: str = RESULT_FORMAT) -> str:
    """A table as CSV text (no index, LF line ends)."""
    buf = io.StringIO()
    df.to_csv(buf, index=False, float_format=float_format, lineterminator="\n")
    return buf.getvalue()


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
