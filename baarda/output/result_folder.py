"""Reading an adjustment output folder (written by baarda.output.bundle_results) for the report.

The report renders what the adjustment wrote; it never recomputes w, r or MDB.  Bad or
missing files raise ProjectError naming the file, line and column.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from baarda.errors import ProjectError
from baarda.io.table import Table
from baarda.output.run_folder import MANIFEST, verify_run
from baarda.schema import (  # the contract of the files (baarda/schema.py)
    FLAG_COLUMNS,
    FRAME_COLUMNS,
    LABEL_COLUMNS,
    NUMBER_COLUMNS,
    REQUIRED_COLUMNS,
    UNITS,
)
from baarda.sections import Section


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
    for c in REQUIRED_COLUMNS:
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


def _table_frame(path: Path, required: list[str], numeric: list[str]) -> pd.DataFrame:
    t = Table(path, required)
    df = pd.DataFrame({c: t.column(c) for c in t.header})
    for c in numeric:
        if t.has(c):
            df[c] = numbers(t, c)
    return df


NOT_CONVERGED = ("NOT CONVERGED: the adjustment stopped before its corrections became "
                 "negligible; the coordinates, residuals and tests in this report are not a "
                 "least-squares solution")


@dataclass
class Results:
    """Everything the report shows, as read from an output folder."""

    folder: Path
    summary: dict
    obs: pd.DataFrame
    photos: pd.DataFrame | None = None
    points: pd.DataFrame | None = None
    cameras: dict[str, dict] = field(default_factory=dict)
    angle_unit: str | None = None
    notes: list[str] = field(default_factory=list)
    run: str | None = None  # the run id (run.json), None for folders without one

    @property
    def title(self) -> str:
        return str(self.summary.get("project") or self.folder.name)

    @property
    def k_w(self) -> float:
        k = self.summary.get("k_w")
        return float(k) if k is not None else float("nan")

    @property
    def sections(self) -> list[Section]:
        """The summary's sections as the adjustment wrote them (summary.json)."""
        return [Section.from_dict(s) for s in self.summary.get("sections", [])]

    def global_test_lines(self) -> list[str]:
        """The global test of every adjustment, in the words the adjustment wrote."""
        return [line for s in self.sections for line in s.lines
                if line.startswith("global test")]

    @property
    def global_test_passed(self) -> bool | None:
        """Every adjustment's global test accepted (None: no global test in the results)."""
        parts = self.summary.get("adjustments") or {"": self.summary}
        tests = [p.get("global_test") for p in parts.values() if p.get("global_test")]
        return None if not tests else all(gt.get("passed") for gt in tests)

    @property
    def units(self) -> dict[str, str]:
        """The unit of each kind's residuals in observations.csv (summary.json 'units')."""
        return {**UNITS, **(self.summary.get("units") or {})}

    @property
    def failures(self) -> list[str]:
        """What keeps this run from being a result, in words, for the first lines of every
        report: an adjustment that did not converge (with the solver's reason), snooping
        that stopped at its step limit."""
        parts = self.summary.get("adjustments") or {"": self.summary}
        out = []
        for name, p in parts.items():
            if not isinstance(p, dict):
                continue
            of = f" ({name})" if name and len(parts) > 1 else ""
            if p.get("converged", True) is False:
                why = [n for n in p.get("notes", []) if "diverged" in str(n)
                       or "not converged" in str(n)]
                out.append(NOT_CONVERGED + of + (f": {why[0]}" if why else ""))
            text = str(p.get("snooping_incomplete") or "")
            if text:  # "snooping incomplete: N component(s) still significant ..."
                head, _, rest = text.partition(":")
                out.append(f"{head.upper()}{of}:{rest}")
        return out

    @property
    def converged(self) -> bool:
        """Every adjustment of the run converged (folders without the entry count as
        converged)."""
        parts = self.summary.get("adjustments") or {"": self.summary}
        return all(p.get("converged", True) is not False for p in parts.values()
                   if isinstance(p, dict))

    def strip_of(self) -> dict[str, str]:
        """photo id -> strip label ('' when unknown)."""
        if self.photos is None or "strip" not in self.photos:
            return {}
        return dict(zip(self.photos["photo"], self.photos["strip"], strict=True))


def _cameras_from_project(source: Path, notes: list[str]) -> tuple[dict, str | None]:
    """Fallback for folders written before summary.json carried the cameras."""
    from baarda.io.project import read_project

    try:
        blk = read_project(source)
    except (ProjectError, OSError) as e:
        notes.append(f"project {source} could not be read for the cameras: {e}")
        return {}, None
    cams = {c: {"focal_mm": float(blk.cameras.focal_mm[i]),
                "x0_mm": float(blk.cameras.principal_point_mm[i, 0]),
                "y0_mm": float(blk.cameras.principal_point_mm[i, 1])}
            for i, c in enumerate(blk.cameras.ids)}
    return cams, blk.settings.angle_unit


def read_results(folder: str | Path) -> Results:
    """Read summary.json, observations.csv (or observations.parquet, written by adjust
    --parquet) and (when present) photos.csv, points.csv."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ProjectError(str(folder), "not an output folder (run baarda adjust -o FOLDER)")
    sp = folder / "summary.json"
    if not sp.is_file():
        raise ProjectError(str(sp), "file not found (not a baarda output folder?)")
    run = verify_run(folder, ["summary.json", "observations.csv", "observations.parquet",
                              "photos.csv", "points.csv"])
    try:
        summary = json.loads(sp.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise ProjectError(str(sp), f"not valid JSON: {e.msg}", e.lineno) from None
    if not isinstance(summary, dict):
        raise ProjectError(str(sp), "expected a JSON object")
    if (folder / "observations.parquet").is_file() and not (folder / "observations.csv").is_file():
        obs = read_observations_parquet(folder / "observations.parquet")
    else:
        obs = read_observations(folder / "observations.csv")
    notes: list[str] = []
    if run is None:
        notes.append(f"{folder} has no run manifest ({MANIFEST}: written by an earlier "
                     "version of baarda): its files were not checked to be of one run")
    photos = points = None
    photo_block = (obs["kind"] == "image").any()  # photos, cameras and footprints apply
    if (folder / "photos.csv").is_file():
        photos = _table_frame(folder / "photos.csv", ["photo", "X0", "Y0", "Z0"],
                              ["X0", "Y0", "Z0", "omega", "phi", "kappa"])
        if "strip" not in photos:
            photos["strip"] = ""
    elif photo_block:
        notes.append("photos.csv missing: no per-strip statistics and no photo footprints")
    if (folder / "points.csv").is_file():
        points = _table_frame(folder / "points.csv", ["point", "X", "Y", "Z"],
                              ["X", "Y", "Z", "dX", "dY", "dZ", "rays"])
        if "role" not in points:
            points["role"] = "tie"
    else:
        notes.append("points.csv missing: no maps")
    cams = {c["camera"]: c for c in summary.get("cameras", []) if "camera" in c}
    unit = summary.get("angle_unit")
    if not cams and photo_block and summary.get("source"):
        src = Path(summary["source"])
        if not src.is_absolute() and not src.is_dir():
            src = folder.parent / src
        if src.is_dir():
            cams, unit = _cameras_from_project(src, notes)
    if not cams and photo_block:
        notes.append("no camera data (summary.json 'cameras'): photo footprints not drawn")
    if obs["x_mm"].isna().all() and (obs["kind"] == "image").any():
        notes.append("observations.csv has no image coordinates (x_mm, y_mm): image-space "
                     "residual plots not drawn (re-run baarda adjust)")
    return Results(folder, summary, obs, photos, points, cams, unit, notes, run)
