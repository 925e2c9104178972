"""Group statistics of residuals in the manner of Salsig's VAN (1989).

For every group: number, mean (the bias; should be near zero), RMS = sqrt(mean(v^2)), and
the two extremes with the observation where each occurs.  Groups: control X, Y, Z and X+Y,
image x, y and x+y, every other kind by component and together; also per photo, per strip
and per model.  Input is an observation table with columns kind, photo (or model), point,
component, residual (image and model µm, control m) and optionally rejected; rejected
observations are left out (their residuals are predicted, not adjusted) and counted
separately.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from baarda.kinds import EXTERIOR, EXTERIOR_NAMES
from baarda.schema import UNITS
from baarda.table_data import Column, TableData, text_lines


@dataclass
class GroupStats:
    """Statistics of one group of residuals (values in `unit`)."""

    name: str
    unit: str
    count: int
    mean: float
    rms: float
    minimum: float
    min_at: str
    maximum: float
    max_at: str
    rejected: int = 0

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def obs_label(df: pd.DataFrame) -> np.ndarray:
    """'photo P point Q c' for image rows, 'model M point Q c' for model rows, 'point Q c'
    otherwise."""
    photo = df["photo"].astype(str).to_numpy()
    model = df["model"].astype(str).to_numpy() if "model" in df else np.full(len(df), "")
    head = np.where(photo != "", "photo " + photo + " ",
                    np.where(model != "", "model " + model + " ", ""))
    point = df["point"].fillna("").astype(str).to_numpy()
    kind = df["kind"].astype(str).to_numpy() if "kind" in df else np.full(len(df), "")
    mid = np.where((point == "") & np.isin(kind, EXTERIOR_NAMES), "", "point " + point + " ")
    return (head + mid + df["component"].astype(str).to_numpy()).astype(object)


def label_columns(df: pd.DataFrame) -> list[str]:
    """The columns obs_label reads (those the table has)."""
    return [c for c in ("kind", "photo", "model", "point", "component") if c in df]


class Labels:
    """obs_label of a table's rows, worked out only for the rows that are shown (a label of
    every one of millions of observations would take longer than the rest of a report):
    indexing with a mask or an index array gives the labels of those rows (still lazy), an
    integer one label, np.asarray the labels as obs_label gives them."""

    def __init__(self, df: pd.DataFrame, rows: np.ndarray | None = None):
        self.df = df
        self.rows = np.arange(len(df)) if rows is None else rows

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, key):
        if isinstance(key, int | np.integer):
            return obs_label(self.df.iloc[[int(self.rows[key])]])[0]
        return Labels(self.df, self.rows[key if isinstance(key, slice) else np.asarray(key)])

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        out = obs_label(self.df.iloc[self.rows]) if len(self.rows) else np.zeros(0, object)
        return out if dtype is None else out.astype(dtype)


def describe(values: np.ndarray, labels: np.ndarray, name: str, unit: str,
             rejected: int = 0) -> GroupStats:
    """Number, mean, RMS, minimum and maximum (with where they occur) of `values`."""
    v = np.asarray(values, float)
    if len(v) == 0:
        nan = float("nan")
        return GroupStats(name, unit, 0, nan, nan, nan, "", nan, "", rejected)
    i, j = int(np.argmin(v)), int(np.argmax(v))
    return GroupStats(name, unit, len(v), float(np.mean(v)), float(np.sqrt(np.mean(v * v))),
                      float(v[i]), str(labels[i]), float(v[j]), str(labels[j]), rejected)


def _active(df: pd.DataFrame) -> np.ndarray:
    return ~df["rejected"].to_numpy(bool) if "rejected" in df else np.ones(len(df), bool)


def group_statistics(df: pd.DataFrame, units: dict[str, str] | None = None) -> list[GroupStats]:
    """The VAN groups: control X, Y, Z, XY; image x, y, x+y; other kinds by component.
    `units`: unit of each kind's residuals (default image µm, control m)."""
    units = {**UNITS, **(units or {})}
    act = _active(df)
    kind = df["kind"].to_numpy(str)
    comp = df["component"].to_numpy(str)
    v = df["residual"].to_numpy(float)
    lab = Labels(df)
    out = []

    def add(sel: np.ndarray, name: str, unit: str) -> None:
        if sel.any():
            out.append(describe(v[sel & act], lab[sel & act], name, unit,
                                int(np.sum(sel & ~act))))

    ctl = kind == "control"
    for c in "XYZ":
        add(ctl & (comp == c), f"control {c}", units["control"])
    if (ctl & (comp == "X")).any() and (ctl & (comp == "Y")).any():
        add(ctl & np.isin(comp, ["X", "Y"]), "control X+Y", units["control"])
    img = kind == "image"
    for c in "xy":
        add(img & (comp == c), f"image {c}", units["image"])
    add(img & np.isin(comp, ["x", "y"]), "image x+y", units["image"])
    for k in sorted(set(kind) - {"image", "control"}):
        sel = kind == k
        comps = sorted(set(comp[sel]))
        for c in comps:
            add(sel & (comp == c), f"{k} {c}", units.get(k, ""))
        if len(comps) > 1:
            add(sel, f"{k} all", units.get(k, ""))
    return out


def pair_xy(df: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The x and the y rows of the image observations, aligned (one row per image point).

    Rows written in x, y pairs (as baarda and the readers write them) are paired in order;
    otherwise they are joined on photo and point (first y row of each)."""
    img = df[df["kind"] == "image"]
    x = img[img["component"] == "x"].reset_index(drop=True)
    y = img[img["component"] == "y"].reset_index(drop=True)
    if not (len(x) == len(y) and (x["photo"].to_numpy() == y["photo"].to_numpy()).all()
            and (x["point"].to_numpy() == y["point"].to_numpy()).all()):
        y = x[["photo", "point"]].merge(y.drop_duplicates(["photo", "point"]),
                                       on=["photo", "point"], how="left")
    return x, y


def vector_statistics(df: pd.DataFrame, unit: str = "µm") -> GroupStats | None:
    """Length of the image residual vector sqrt(vx^2 + vy^2) of every image point with both
    components active; RMS = sqrt(mean(vx^2 + vy^2)) (PhotoModeler's 'Overall RMS')."""
    x, y = pair_xy(df)
    ok = (~x["rejected"].to_numpy(bool) & ~y["rejected"].fillna(True).to_numpy(bool)
          & y["residual"].notna().to_numpy())
    if not ok.any():
        return None
    length = np.hypot(x["residual"].to_numpy(float), y["residual"].to_numpy(float))[ok]
    lab = ("photo " + x["photo"].astype(str) + " point " + x["point"].astype(str)).to_numpy()
    return describe(length, lab[ok], "image vector", unit)


def image_groups(df: pd.DataFrame, by: str, key: np.ndarray | None = None) -> pd.DataFrame:
    """Image residual statistics per photo (by='photo') or per strip (by='strip', key = the
    strip of every row).  Columns: number of points, mean and RMS of x and y, RMS of x+y,
    largest |v| and where, rejected components."""
    img = df["kind"].to_numpy(str) == "image"
    d = df.loc[img, ["photo", "point", "component", "residual"]].copy()
    group = d["photo"].astype(str).to_numpy() if key is None else np.asarray(key)[img]
    codes, names = pd.factorize(pd.Series(group, dtype=object))  # groups as codes, once
    names = np.asarray(names, dtype=object)
    d["group"] = codes
    d["point"] = pd.factorize(d["point"])[0]  # only counted
    d["active"] = _active(df)[img]
    v = d["residual"].to_numpy(float)
    d["abs"] = np.abs(v)
    d["v2"] = v * v
    cols = [by, "points", "mean_x", "mean_y", "rms_x", "rms_y", "rms_xy", "max_abs", "max_at",
            "rejected"]
    if d.empty:
        return pd.DataFrame(columns=cols)

    def named(r: pd.Series) -> pd.Series:
        return pd.Series(r.to_numpy(), index=names[r.index.to_numpy()])

    out = pd.DataFrame({by: sorted(names)}).set_index(by, drop=False)
    comp = d["component"].to_numpy(str)
    out["points"] = named(d[comp == "x"].groupby("group")["point"].nunique())
    a = d[d["active"].to_numpy(bool)]
    acomp = a["component"].to_numpy(str)
    for c in "xy":
        g = a[acomp == c].groupby("group")
        out[f"mean_{c}"] = named(g["residual"].mean())
        out[f"rms_{c}"] = np.sqrt(named(g["v2"].mean()))
    out["rms_xy"] = np.sqrt(named(a.groupby("group")["v2"].mean()))
    if len(a):
        top = df.loc[a.groupby("group")["abs"].idxmax().to_numpy()]
        # labelled as before: photo, point and component (not the kind)
        at = pd.Series(obs_label(top.drop(columns=[c for c in ("kind", "model") if c in top])),
                       index=names[a.loc[top.index, "group"].to_numpy()])
        out["max_abs"] = named(a.groupby("group")["abs"].max())
        out["max_at"] = at
    else:
        out["max_abs"] = np.nan
        out["max_at"] = ""
    out["rejected"] = named((~d["active"]).groupby(d["group"]).sum())
    out["points"] = out["points"].fillna(0).astype(int)
    out["rejected"] = out["rejected"].fillna(0).astype(int)
    out["max_at"] = out["max_at"].fillna("")
    return out[cols].reset_index(drop=True)


def model_groups(df: pd.DataFrame) -> pd.DataFrame:
    """Model-coordinate residual statistics per model (independent models): number of points,
    RMS of each component, largest |v| and where, rejected components."""
    sel = (df["kind"].to_numpy(str) == "model") if "model" in df else np.zeros(len(df), bool)
    d = df.loc[sel, ["model", "point", "component", "residual"]].copy()
    comps = list(dict.fromkeys(d["component"].astype(str)))
    cols = ["model", "points", *[f"rms_{c}" for c in comps], "max_abs", "max_at", "rejected"]
    if d.empty:
        return pd.DataFrame(columns=cols)
    d["active"] = _active(df)[sel]
    d["label"] = obs_label(df[sel])
    v = d["residual"].to_numpy(float)
    d["abs"], d["v2"] = np.abs(v), v * v
    out = pd.DataFrame({"model": sorted(d["model"].unique())}).set_index("model", drop=False)
    out["points"] = d.groupby("model")["point"].nunique()
    a = d[d["active"]]
    for c in comps:
        out[f"rms_{c}"] = np.sqrt(a[a["component"] == c].groupby("model")["v2"].mean())
    top = a.loc[a.groupby("model")["abs"].idxmax()].set_index("model") if len(a) else None
    out["max_abs"] = np.nan if top is None else top["abs"]
    out["max_at"] = "" if top is None else top["label"]
    out["rejected"] = (~d["active"]).groupby(d["model"]).sum().astype(int)
    out["max_at"] = out["max_at"].fillna("")
    return out[cols].reset_index(drop=True)


def model_group_table(t: pd.DataFrame, unit: str = "µm") -> TableData:
    """model_groups as a table (the text and the HTML report)."""
    rms = [c for c in t.columns if c.startswith("rms_")]
    f = _decimals(unit)
    return TableData.of([Column("model", width=10, text=True), Column("points", width=7),
                         *[Column(c, "RMS " + c[4:], f, width=9) for c in rms],
                         Column("max_abs", "max |v|", f, width=9),
                         Column("max_at", "at", text=True, width=34, gap=2),
                         Column("rejected", text_title="rej", width=4)], t)


def format_model_groups(t: pd.DataFrame, unit: str = "µm") -> str:
    """Per-model table as text."""
    lines = text_lines(model_group_table(t, unit))
    lines[0] += f"   ({unit})"
    return "\n".join(lines)


def per_photo(df: pd.DataFrame) -> pd.DataFrame:
    return image_groups(df, "photo")


def per_strip(df: pd.DataFrame, strip_of: dict[str, str]) -> pd.DataFrame:
    return image_groups(df, "strip", strips(df, strip_of))


def strips(df: pd.DataFrame, strip_of: dict[str, str]) -> np.ndarray:
    """The strip of every row ('' where its photo has none)."""
    key = {str(k): str(v) for k, v in strip_of.items()}
    photo = pd.Series(df["photo"].astype(str).to_numpy(object))
    return photo.map(key).fillna("").to_numpy(object)


def gnss_imu_per_strip(df: pd.DataFrame, strip_of: dict[str, str]) -> pd.DataFrame:
    """GNSS and IMU residuals per strip (active observations): number of positions or
    attitudes, mean and RMS of each component (GNSS m, IMU in the output's unit), largest
    |w|, rejected components; empty without such observations."""
    rows = []
    act = _active(df)
    kind = df["kind"].astype(str).to_numpy()
    strip = strips(df, strip_of)
    comp = df["component"].astype(str).to_numpy()
    v = df["residual"].to_numpy(float)
    w = df["w"].to_numpy(float) if "w" in df else np.full(len(df), np.nan)
    for k, names in ((e.name, e.components) for e in EXTERIOR):
        sel_k = kind == k
        for s in sorted(set(strip[sel_k]), key=lambda x: (len(x), x)):
            sel = sel_k & (strip == s)
            row = {"kind": k, "strip": s, "number": int((sel & (comp == names[0])).sum()),
                   "rejected": int((sel & ~act).sum())}
            for c in names:
                x = v[sel & act & (comp == c)]
                row[f"mean {c}"] = float(x.mean()) if len(x) else np.nan
                row[f"RMS {c}"] = float(np.sqrt(np.mean(x**2))) if len(x) else np.nan
            aw = np.abs(w[sel & act])
            row["max |w|"] = float(np.nanmax(aw)) if np.isfinite(aw).any() else np.nan
            rows.append(row)
    return pd.DataFrame(rows)


def format_gnss_imu(t: pd.DataFrame) -> str:
    """gnss_imu_per_strip as text (GNSS m, IMU in the output's unit), a table per kind."""
    lines = []
    for k, names in ((e.name, e.components) for e in EXTERIOR):
        part = t[t["kind"] == k] if len(t) else t
        if not len(part):
            continue
        cols = [Column("kind", text_title=k, text=True, width=6),
                Column("strip", text=True, width=8), Column("number", width=7)]
        for c in names:
            cols += [Column(f"mean {c}", fmt=".4f", width=12),
                     Column(f"RMS {c}", fmt=".4f", width=12)]
        cols += [Column("max |w|", fmt=".2f", width=9), Column("rejected", text_title="rej",
                                                              width=5)]
        lines += text_lines(TableData.of(cols, part.assign(kind="")))
    return "\n".join(lines)


def worst(df: pd.DataFrame, n: int = 10) -> pd.DataFrame:
    """The n largest |residual| per kind (active observations): the computer points at them."""
    act = df[_active(df)].copy()
    act["abs"] = np.abs(act["residual"].to_numpy(float))
    parts = [g.nlargest(n, "abs") for _, g in act.groupby("kind", sort=True)]
    return pd.concat(parts) if parts else act.iloc[:0]


def largest_rms(t: pd.DataFrame, limit: int, what: str) -> tuple[pd.DataFrame, str]:
    """A per-photo (per-strip) table, or its `limit` rows of the largest RMS x+y when it
    has more, in the same order; the words that say so (else '')."""
    if len(t) <= limit:
        return t, ""
    keep = np.sort(np.argsort(-t["rms_xy"].fillna(-1.0).to_numpy(), kind="stable")[:limit])
    return (t.iloc[keep].reset_index(drop=True),
            f" ({limit} of {len(t)} {what}: those with the largest RMS x+y)")


def first_rows(t: pd.DataFrame, limit: int) -> tuple[pd.DataFrame, str]:
    """The first `limit` rows of a table sorted worst first, and the words that say so."""
    if len(t) <= limit:
        return t, ""
    return t.iloc[:limit], f"; {limit} of {len(t)} such rows shown: the first in this order"


def weakest(obs: pd.DataFrame, n: int,
            units: dict[str, str] | None = None) -> dict[str, pd.DataFrame]:
    """The tested, active observations with the smallest redundancy numbers and with the
    largest MDB (per kind: units differ; the unit of each row's MDB in `unit`), n of each."""
    units = {**UNITS, **(units or {})}
    cols = [c for c in ("kind", "photo", "model", "frame", "point", "component", "redundancy",
                        "w", "mdb", "external_max") if c in obs]
    d = obs.loc[~obs["rejected"].to_numpy(bool) & np.isfinite(obs["w"].to_numpy(float)), cols]
    d.insert(d.columns.get_loc("mdb") + 1, "unit", [units.get(k, "") for k in d["kind"]])
    small = d.nsmallest(n, "redundancy")
    kind = d["kind"].to_numpy(str)
    large = pd.concat([d[kind == k].nlargest(n, "mdb") for k in sorted(set(kind))]
                      or [d.iloc[:0]])
    return {"smallest redundancy numbers": small, "largest MDB (per kind)": large}


# ------------------------------------------------------------------ tables
UNIT_DECIMALS = {"m": ".3f", "px": ".3f"}  # a row's unit -> its format (else .2f)


def _decimals(unit: str) -> str:
    """The format of a residual statistic in `unit`: mm-level decimals for m and px."""
    return UNIT_DECIMALS.get(unit, ".2f")


def group_table(groups: list[GroupStats]) -> TableData:
    """The VAN summary table (the text and the HTML report)."""
    def stat(key: str) -> Column:
        return Column(key, fmt=".2f", unit_fmt=UNIT_DECIMALS, width=10)

    t = TableData.of([
        Column("group", width=14, text=True), Column("unit", width=5, text=True, align=">"),
        Column("number", width=8), stat("mean"), stat("RMS"), stat("minimum"),
        Column("at (min)", text_title="at", text=True, width=28, gap=2),
        stat("maximum"),
        Column("at (max)", text_title="at", text=True, width=28, gap=2),
        Column("rejected", width=8)],
        [(g.name, g.unit, g.count, g.mean, g.rms, g.minimum, g.min_at, g.maximum, g.max_at,
          g.rejected) for g in groups])
    return replace(t, unit_key="unit")


def format_groups(groups: list[GroupStats]) -> str:
    """The VAN summary table as text."""
    return "\n".join(text_lines(group_table(groups)))


def image_group_table(t: pd.DataFrame, by: str, unit: str = "µm") -> TableData:
    """Per-photo or per-strip statistics (image_groups) as a table."""
    f = _decimals(unit)
    return TableData.of([
        Column(by, width=10, text=True), Column("points", width=7),
        Column("mean_x", "mean x", f, width=9), Column("mean_y", "mean y", f, width=9),
        Column("rms_x", "RMS x", f, width=8), Column("rms_y", "RMS y", f, width=8),
        Column("rms_xy", "RMS x+y", f, width=8, text_title="RMS xy"),
        Column("max_abs", "max |v|", f, width=9),
        Column("max_at", "at", text=True, width=30, gap=2),
        Column("rejected", text_title="rej", width=4)], t)


def format_image_groups(t: pd.DataFrame, by: str, unit: str = "µm") -> str:
    """Per-photo or per-strip table as text."""
    lines = text_lines(image_group_table(t, by, unit))
    lines[0] += f"   ({unit})"
    return "\n".join(lines)
