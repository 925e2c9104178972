"""Reliability-model tables: approximate sqrt(qvv) per Gruen class for the modified snooping.

Two tables ship with baarda (baarda/planning/data/):

* ``gruen1980_table2.csv``: Gruen's Table 2 as printed (block means, means per image-point
  distribution, total means and which of them he recommends);
* ``baarda_study.csv``: our table, derived by ``derive_table`` from the reproduced study
  (and extendable by simulation: other patterns, overlaps, formats).

A table is looked up by design key (pattern 'nxn', overlap 'f/s' in %, stereo) and control
('single' or 'twin'); a class without its own value falls back to the class without the
control prefix, a component without its own value to the pooled 'xy'.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

from baarda.block.photo_block import Block
from baarda.errors import ProjectError
from baarda.planning.point_classes import classify, control_points, points_per_photo

DATA = resources.files("baarda.planning") / "data"
COLUMNS = ["pattern", "overlap", "stereo", "control", "class", "component", "value", "count",
           "source"]


def read_gruen_table2() -> pd.DataFrame:
    """Gruen's Table 2 as printed (wide form: b43, b73, b45, b75, m3x3, m5x5, total)."""
    with (DATA / "gruen1980_table2.csv").open("r", encoding="utf-8") as f:
        return pd.read_csv(f, comment="#")


def gruen_table() -> ReliabilityTable:
    """Gruen's recommended (starred) values as a ReliabilityTable."""
    t2 = read_gruen_table2()
    rows = []
    for _, r in t2.iterrows():
        for pat in ("3x3", "5x5"):
            value = r["total"] if r["recommended"] == "total" else r[f"m{pat}"]
            rows.append({"pattern": pat, "overlap": "60/60", "stereo": True,
                         "control": r["control"], "class": r["class"],
                         "component": r["component"], "value": float(value), "count": np.nan,
                         "source": "Gruen 1980, Table 2"})
    return ReliabilityTable(pd.DataFrame(rows, columns=COLUMNS))


def baarda_table() -> ReliabilityTable:
    """Our table derived from the reproduced study (baarda_study.csv)."""
    with (DATA / "baarda_study.csv").open("r", encoding="utf-8") as f:
        return ReliabilityTable.from_frame(pd.read_csv(f, comment="#"), "baarda_study.csv")


def read_table(path: str | Path) -> ReliabilityTable:
    """A table written by ReliabilityTable.write (or by hand in that format)."""
    path = Path(path)
    try:
        df = pd.read_csv(path, comment="#")
    except (OSError, pd.errors.ParserError) as e:
        raise ProjectError(str(path), f"cannot read reliability table: {e}") from None
    return ReliabilityTable.from_frame(df, str(path))


@dataclass
class DesignKey:
    pattern: str = "3x3"
    overlap: str = "60/60"
    stereo: bool = True
    control: str = "single"


class ReliabilityTable:
    """Approximate sqrt(qvv) values keyed by design, control, class and component."""

    def __init__(self, frame: pd.DataFrame):
        self.frame = frame.reset_index(drop=True)

    @classmethod
    def from_frame(cls, df: pd.DataFrame, where: str) -> ReliabilityTable:
        missing = [c for c in COLUMNS if c not in df.columns]
        if missing:
            raise ProjectError(where, f"reliability table lacks column(s) {', '.join(missing)}")
        for i, v in enumerate(df["value"]):
            if not (isinstance(v, (int, float)) and 0.0 <= float(v) <= 1.0):
                raise ProjectError(where, f"value {v!r} is not a number in [0, 1]", line=i + 2,
                                   column="value")
        df = df.copy()
        df["stereo"] = df["stereo"].astype(str).str.lower().isin(["true", "1", "yes"])
        return cls(df[COLUMNS])

    def keys(self) -> pd.DataFrame:
        return self.frame[["pattern", "overlap", "stereo", "control"]].drop_duplicates()

    def select(self, key: DesignKey) -> pd.DataFrame:
        """Rows for `key`; the nearest pattern and overlap when there is no exact match."""
        df = self.frame[(self.frame["stereo"] == key.stereo)]
        if df.empty:
            df = self.frame
        df = df[df["control"] == key.control] if (df["control"] == key.control).any() else df
        pats = df["pattern"].unique()
        size = int(key.pattern.split("x")[0])
        best = min(pats, key=lambda p: abs(int(str(p).split("x")[0]) - size))
        df = df[df["pattern"] == best]
        ovl = df["overlap"].unique()
        if key.overlap in ovl:
            return df[df["overlap"] == key.overlap]
        f, s = (float(v) for v in key.overlap.split("/"))
        near = min(ovl, key=lambda o: sum(abs(float(a) - b) for a, b in
                                          zip(str(o).split("/"), (f, s), strict=True)))
        return df[df["overlap"] == near]

    def lookup(self, classes: np.ndarray, components: np.ndarray, key: DesignKey) -> np.ndarray:
        """Approximate sqrt(qvv) for each (class, component); NaN where the table has none."""
        df = self.select(key)
        values = {(c, k): v for c, k, v in zip(df["class"], df["component"], df["value"],
                                               strict=True)}
        out = np.full(len(classes), np.nan)
        for i, (c, k) in enumerate(zip(classes, components, strict=True)):
            for cc in (c, c[1:] if str(c).startswith("C") else None):
                if cc is None:
                    continue
                v = values.get((cc, k), values.get((cc, "xy")))
                if v is not None:
                    out[i] = v
                    break
        return out


def design_key(block: Block, twin_distance: float | None = None) -> DesignKey:
    """The design of an existing block: points per photo, overlaps, stereo, twin control.

    Pattern: the square nearest to the median number of distinct points per photo; stereo:
    some photo measures a point twice; twin control: most control points have another control
    point closer than `twin_distance` (default: a tenth of the median base).  The overlap
    cannot be told from a project (the format is not known): 60/60, the table's nearest.
    """
    per_photo = points_per_photo(block)
    n = int(np.clip(np.rint(np.sqrt(np.median(per_photo) if len(per_photo) else 9)), 2, 9))
    rc = classify(block)
    stereo = bool(np.any(rc.inner))
    eo = block.photos.eo
    bases = []
    for s in np.unique(block.photos.strip):
        idx = np.flatnonzero(block.photos.strip == s)
        if len(idx) > 1:
            bases.append(np.median(np.linalg.norm(np.diff(eo[idx, :2], axis=0), axis=1)))
    base = float(np.median(bases)) if bases else np.nan
    ctrl = np.flatnonzero(control_points(block))
    twin = False
    if len(ctrl) > 1:
        lim = twin_distance if twin_distance is not None else (0.1 * base if np.isfinite(base)
                                                               else 0.0)
        xy = block.points.xyz[ctrl, :2]
        d = cKDTree(xy).query(xy, k=2)[0][:, 1]  # distance to the nearest other control
        twin = bool(np.mean(d < lim) > 0.5)
    return DesignKey(pattern=f"{n}x{n}", overlap="60/60", stereo=stereo,
                     control="twin" if twin else "single")
