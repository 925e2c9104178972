"""Residual listings written by other programs, for the post-processor `baarda residuals`.

Formats (docs/report.md):
  generic image CSV    columns point, photo, vx, vy [, strip]   residuals in µm
  generic control CSV  columns point, vX, vY, vZ                residuals in m (cells may
                                                               be empty: height-only points)
  PhotoModeler 2D point table (Object Point ID, Photo #, ..., Residual X, Residual Y, ...)
                       residuals in pixels (PhotoModeler's pixel frame, y down); converted
                       to µm with a pixel size
  baarda observations.csv (kind, photo, point, component, residual, ...)
Every reader returns one row per residual component with the columns of observations.csv
that the statistics use: kind, photo, point, component, residual, rejected, flagged, w,
strip, line.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from baarda.errors import ProjectError
from baarda.io.observations_file import numbers, read_observations
from baarda.io.table import Table
from baarda.io.text_files import require_file

PM_HEADER = "Object Point ID"
FORMATS = ("auto", "generic", "photomodeler", "baarda")


@dataclass
class ResidualSet:
    obs: pd.DataFrame
    units: dict[str, str]
    notes: list[str] = field(default_factory=list)


def _frame(kind, photo, point, comp, v, lines, strip=None) -> pd.DataFrame:
    n = len(v)
    return pd.DataFrame({"kind": np.full(n, kind, dtype=object),
                         "photo": np.asarray(photo, dtype=object),
                         "point": np.asarray(point, dtype=object),
                         "component": np.asarray(comp, dtype=object),
                         "residual": np.asarray(v, float), "rejected": np.zeros(n, bool),
                         "flagged": np.zeros(n, bool), "w": np.full(n, np.nan),
                         "strip": (np.full(n, "", dtype=object) if strip is None
                                   else np.asarray(strip, dtype=object)),
                         "line": np.asarray(lines, np.int64)})


def _interleave(photo, point, vx, vy, lines, strip=None) -> pd.DataFrame:
    """Rows x, y, x, y, ... of image points."""
    n = len(vx)
    v = np.empty(2 * n)
    v[0::2], v[1::2] = vx, vy

    def rep(a):
        return None if a is None else np.repeat(np.asarray(a, dtype=object), 2)

    return _frame("image", rep(photo), rep(point), np.tile(["x", "y"], n), v,
                  np.repeat(lines, 2), rep(strip))


def detect(path: Path) -> str:
    """'photomodeler', 'baarda', 'generic-image' or 'generic-control'."""
    require_file(path)
    with open(path, encoding="utf-8-sig", errors="replace") as f:
        head = [f.readline() for _ in range(30)]
    for line in head:
        if line.lstrip().startswith(PM_HEADER):
            return "photomodeler"
    for line in head:
        s = line.strip()
        if s and not s.startswith("#"):
            cols = {c.strip() for c in s.split(",")}
            if {"kind", "component", "residual"} <= cols:
                return "baarda"
            if {"point", "photo", "vx", "vy"} <= cols:
                return "generic-image"
            if {"point", "vX", "vY", "vZ"} <= cols:
                return "generic-control"
            raise ProjectError(str(path), "unknown residual listing: expected a header "
                               "'point,photo,vx,vy' (image, µm), 'point,vX,vY,vZ' (control, "
                               "m), baarda's observations.csv or a PhotoModeler 2D point "
                               f"table; found '{s[:80]}'", line=head.index(line) + 1)
    raise ProjectError(str(path), "the file is empty (no header line)")


def read_generic(path: Path) -> tuple[pd.DataFrame, str]:
    """A generic image (µm) or control (m) residual CSV; returns (rows, kind)."""
    kind = detect(path)
    if kind == "generic-image":
        t = Table(path, ["point", "photo", "vx", "vy"])
        vx, vy = numbers(t, "vx"), numbers(t, "vy")
        for name, v in (("vx", vx), ("vy", vy)):
            bad = np.flatnonzero(~np.isfinite(v))
            if len(bad):
                raise ProjectError(t.path, "a residual (finite number) is required",
                                   int(t.lines[bad[0]]), name)
        strip = t.text("strip", allow_empty=True) if t.has("strip") else None
        return _interleave(t.text("photo"), t.text("point"), vx, vy, t.lines, strip), "image"
    if kind == "generic-control":
        t = Table(path, ["point", "vX", "vY", "vZ"])
        v = np.column_stack([numbers(t, c) for c in ("vX", "vY", "vZ")])
        bad = np.flatnonzero(~np.isfinite(v).any(axis=1))
        if len(bad):
            raise ProjectError(t.path, "no residual in this row", int(t.lines[bad[0]]), "vX")
        inf = np.argwhere(np.isinf(v))
        if len(inf):
            raise ProjectError(t.path, "residual is not finite", int(t.lines[inf[0, 0]]),
                               "vXYZ"[1 + inf[0, 1]])
        have = np.isfinite(v).ravel()
        n = len(t)
        pts = np.repeat(t.text("point"), 3)[have]
        return _frame("control", np.full(int(have.sum()), ""), pts,
                      np.tile(["X", "Y", "Z"], n)[have], v.ravel()[have],
                      np.repeat(t.lines, 3)[have]), "control"
    raise ProjectError(str(path), f"not a generic residual CSV (looks like {kind})")


def read_photomodeler(path: Path, pixel_size_um: float | None = None) -> pd.DataFrame:
    """PhotoModeler's 2D point table (CSV with a few title lines before the header).

    Residuals are in pixels as PhotoModeler writes them (image frame y down); with
    `pixel_size_um` they are converted to µm.  Physical lines are counted at '\\n'.
    """
    raw = Path(path).read_bytes().decode("utf-8-sig", errors="replace").split("\n")
    lines = [s.rstrip("\r") for s in raw]
    start = next((i for i, s in enumerate(lines) if s.lstrip().startswith(PM_HEADER)), None)
    if start is None:
        raise ProjectError(str(path), f"no header line starting with '{PM_HEADER}'")
    header = [h.strip() for h in next(csv.reader([lines[start]]))]
    need = [PM_HEADER, "Photo #", "Residual X", "Residual Y"]
    for c in need:
        if c not in header:
            raise ProjectError(str(path), f"missing column '{c}'", start + 1)
    col = {c: header.index(c) for c in need}
    pts, photos, vx, vy, nums = [], [], [], [], []
    for i in range(start + 1, len(lines)):
        s = lines[i]
        if not s.strip():
            continue
        row = next(csv.reader(io.StringIO(s)))
        if len(row) < len(header) - 1:  # the last column (Tagged) may be cut
            raise ProjectError(str(path), f"expected {len(header)} fields, found {len(row)}",
                               i + 1)
        vals = []
        for c in ("Residual X", "Residual Y"):
            try:
                vals.append(float(row[col[c]]))
            except ValueError:
                raise ProjectError(str(path), f"'{row[col[c]]}' is not a number", i + 1,
                                   c) from None
            if not np.isfinite(vals[-1]):
                raise ProjectError(str(path), "residual is not finite", i + 1, c)
        pts.append(row[col[PM_HEADER]].strip())
        photos.append(row[col["Photo #"]].strip())
        vx.append(vals[0])
        vy.append(vals[1])
        nums.append(i + 1)
    scale = 1.0 if pixel_size_um is None else float(pixel_size_um)
    return _interleave(photos, pts, np.array(vx) * scale, np.array(vy) * scale,
                       np.array(nums, np.int64))


def read_baarda(path: Path) -> pd.DataFrame:
    df = read_observations(path)
    df["strip"] = ""
    return df


def read_residuals(paths: list[str | Path], fmt: str = "auto",
                   pixel_size_um: float | None = None) -> ResidualSet:
    """Read and concatenate residual listings; all image residuals must share one unit."""
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)}")
    if pixel_size_um is not None and not pixel_size_um > 0:
        raise ProjectError("command line", "--pixel-size must be positive (µm)")
    parts, img_units, notes = [], set(), []
    for p in map(Path, paths):
        kind = detect(p) if fmt == "auto" else fmt
        if kind == "photomodeler":
            df = read_photomodeler(p, pixel_size_um)
            img_units.add("µm" if pixel_size_um else "px")
            notes.append(f"{p}: PhotoModeler 2D point table, {len(df) // 2} image points, "
                         + (f"pixel size {pixel_size_um:g} µm" if pixel_size_um else
                            "residuals in pixels (give --pixel-size for µm)")
                         + "; PhotoModeler's sign and pixel frame (y down) kept")
        elif kind == "baarda":
            df = read_baarda(p)
            img_units.add("µm")
            notes.append(f"{p}: baarda observations.csv, {len(df)} components")
        else:
            df, k = read_generic(p)
            if k == "image":
                img_units.add("µm")
            notes.append(f"{p}: generic {k} residuals, {len(df)} components")
        df["source"] = str(p)
        parts.append(df)
    if len(img_units) > 1:
        raise ProjectError(", ".join(map(str, paths)), "image residuals in pixels and in µm "
                           "cannot be mixed: give --pixel-size")
    obs = pd.concat(parts, ignore_index=True) if parts else _frame("image", [], [], [], [], [])
    units = {"image": img_units.pop() if img_units else "µm", "control": "m"}
    return ResidualSet(obs, units, notes)
