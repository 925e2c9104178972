"""The parts every result folder shares: summary.json and observations.csv.

summary.json (one schema for every method, docs/format.md): `project`, `source`, `method`,
`sections` (the text of summary(), which the reports render), `adjustments` (one entry per
adjustment: counts, sigma0, global test, test settings, rejection log, ...), the first
adjustment's entries again at the top level, `rejection_log` of all adjustments and
`notes`; then the method's own entries.  observations.csv: one row per observation
component in the columns of baarda.quality.assessment.COLUMNS (then a method's own), or
the same table as observations.parquet (a table whose name ends in .parquet is written as
Parquet: float64 as computed, for millions of rows written in a fraction of the CSV's time
and read back in one call).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from baarda.output.atomic import write_text
from baarda.output.run_folder import RunFolder, staged
from baarda.output.tables import (
    Table,
    json_text,
    n_rows,
    write_csv,
    write_parquet,
)
from baarda.sections import Section


def summary_document(*, project: str, source: str, method: str, sections: Iterable[Section],
                     parts: list[dict], notes: Iterable[str] = (), **extra) -> dict:
    """summary.json of a result folder (module docstring); parts: to_dict() of each
    adjustment (with its name under 'adjustment')."""
    main = dict(parts[0]) if parts else {}
    doc = {"project": project, "source": source, "method": method, **main, **extra}
    doc["rejection_log"] = [s for p in parts for s in p.get("rejection_log", [])]
    doc["notes"] = list(dict.fromkeys([n for p in parts for n in p.get("notes", [])]
                                      + list(notes)))
    doc["adjustments"] = {p["adjustment"]: p for p in parts}
    doc["sections"] = [s.to_dict() for s in sections]
    return doc


def input_fingerprint(source: str | Path | None) -> dict | None:
    """The input as the reports state it: its path, the number of files and bytes and one
    SHA-256 over them (a folder: every file under it in sorted order, each as its relative
    path and its bytes; a project named by its files' common stem, as AICON's
    `example.phc`, `example.ior`, ...: those files); None when the source is none of
    these here."""
    import hashlib
    from glob import escape as glob_escape

    if not source:
        return None
    path = Path(source)
    if path.is_file():
        files, root = [path], path.parent
    elif path.is_dir():
        files, root = sorted(p for p in path.rglob("*") if p.is_file()), path
    elif path.parent.is_dir() and (stem := sorted(
            p for p in path.parent.glob(f"{glob_escape(path.name)}.*") if p.is_file())):
        files, root = stem, path.parent
    else:
        return None
    h = hashlib.sha256()
    size = 0
    for f in files:
        h.update(f.relative_to(root).as_posix().encode() + b"\0")
        with open(f, "rb") as fh:
            for chunk in iter(lambda fh=fh: fh.read(1 << 20), b""):  # type: ignore[misc]
                h.update(chunk)
                size += len(chunk)
    return {"path": str(source), "files": len(files), "bytes": size, "sha256": h.hexdigest()}


def observation_groups(obs: Table) -> dict[str, dict[str, str]]:
    """kind -> component -> the observation group of those components (control and GNSS by
    axis, model coordinates in planimetry and height, any other kind by itself:
    quality.adjusted_model.kind_groups), for summary.json 'observation_groups': the report
    draws a histogram of w per group from it."""
    from baarda.quality.adjusted_model import kind_groups

    names = set(obs.columns) if isinstance(obs, pd.DataFrame) else set(obs)
    if not {"kind", "component"} <= names or not n_rows(obs):
        return {}
    kinds, comps = _distinct_pairs(np.asarray(obs["kind"], dtype=object),
                                   np.asarray(obs["component"], dtype=object))
    group = kind_groups(kinds, comps)
    out: dict[str, dict[str, str]] = {}
    for k, c, g in zip(kinds, comps, np.asarray(group, str), strict=True):
        out.setdefault(k, {})[c] = g
    return out


def _distinct_pairs(kind: np.ndarray, comp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct (kind, component) pairs as text, in the order of their first row (a
    few pairs among millions of rows: coded by pyarrow, without a string copy per row)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    try:
        k, c = (pc.dictionary_encode(pa.array(a, pa.string())) for a in (kind, comp))
    except (pa.ArrowInvalid, pa.ArrowTypeError):  # not all text: as str()
        k, c = (pc.dictionary_encode(pa.array(a.astype(str), pa.string()))
                for a in (kind, comp))
    ki, ci = (np.asarray(a.indices.fill_null(-1)).astype(np.int64) for a in (k, c))
    code = (ki + 1) * (len(c.dictionary) + 1) + (ci + 1)
    _, first = np.unique(code, return_index=True)
    first.sort()
    text = (np.array([str(v) for v in a.dictionary.to_pylist()] + ["None"], dtype=object)
            for a in (k, c))
    kt, ct = text
    return kt[ki[first]], ct[ci[first]]


def write_folder(out: str | Path | RunFolder, summary: dict,
                 tables: Mapping[str, Table],
                 texts: Mapping[str, str] | None = None) -> list[Path]:
    """summary.json (with the run id under 'run'), the tables (CSV, or Parquet when the
    name ends in .parquet) and any texts, as one run of the folder `out`
    (output/run_folder.py); the final paths."""
    obs = next((t for n, t in tables.items() if n.startswith("observations.")), None)
    if obs is not None and "observation_groups" not in summary:
        summary = {**summary, "observation_groups": observation_groups(obs)}
    with staged(out) as run:
        write_text(run.file("summary.json"), json_text({"run": run.run_id, **summary}))
        for name, df in tables.items():  # large tables in chunks (output/tables.py)
            if name.endswith(".parquet"):
                write_parquet(run.file(name), df)
            else:
                write_csv(run.file(name), df, excel_safe=run.excel_safe)
        for name, text in (texts or {}).items():
            write_text(run.file(name), text)
        return [run.final / name for name in ["summary.json", *tables, *(texts or {})]]
