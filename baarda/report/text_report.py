"""The text report (`baarda report OUT --text`): summary, global test, snooping log, VAN
group statistics, histograms and the ANAPLOT table, as printer text."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from baarda.io.result_folder import Results
from baarda.kinds import EXTERIOR_NAMES
from baarda.output.verdict import failures
from baarda.report.anaplot import format_log, format_snooping, snooping_table
from baarda.report.histogram import Histogram, fitted_classes, format_histogram, histogram
from baarda.report.separability import counts_line, format_least_separable, least_separable
from baarda.report.stats import (
    Labels,
    first_rows,
    format_gnss_imu,
    format_groups,
    format_image_groups,
    format_model_groups,
    gnss_imu_per_strip,
    group_statistics,
    label_columns,
    largest_rms,
    model_groups,
    obs_label,
    per_photo,
    per_strip,
    vector_statistics,
    weakest,
    worst,
)
from baarda.schema import UNITS
from baarda.sections import render
from baarda.table_data import Column, TableData, text_lines

if TYPE_CHECKING:
    from baarda.io.residual_listings import ResidualSet


@dataclass
class ReportOptions:
    """Presentation settings (histogram classes in µm for image residuals, w unitless)."""

    width: float = 1.0
    lo: float = -25.0
    hi: float = 25.0
    line_width: int = 60
    w_width: float = 0.5
    w_lo: float = -6.0
    w_hi: float = 6.0
    top: int = 50  # rows of the snooping table besides every rejected / flagged one
    min_abs_w: float | None = None
    sort: str = "w"
    exaggeration: float | None = None  # residual vectors; None: automatic
    vector_photos: int = 8
    worst: int = 10
    # at scale (issue 16): maps draw at most max_points points (a deterministic sample
    # beyond, said in the caption); tables list at most max_rows rows (the worst)
    max_points: int = 50_000
    max_rows: int = 1_000


def image_histograms(obs: pd.DataFrame, opt: ReportOptions,
                     fit: bool = False) -> list[tuple[str, Histogram]]:
    """Histograms of the active image residuals: x, y and x+y together; `fit`: classes
    that follow the residuals' spread where the given ones do not (fitted_classes, from x
    and y together; the HTML report's figures)."""
    act = (obs["kind"] == "image") & ~obs["rejected"]
    d = obs.loc[act, label_columns(obs) + ["residual"]]  # a few columns of millions of rows
    lab = Labels(d)
    v = d["residual"].to_numpy(float)
    width, lo, hi = opt.width, opt.lo, opt.hi
    if fit:
        width, lo, hi = fitted_classes(v[d["component"].isin(["x", "y"]).to_numpy()],
                                       width, lo, hi)
    out = []
    for name, sel in (("x", d["component"] == "x"), ("y", d["component"] == "y"),
                      ("x and y", d["component"].isin(["x", "y"]))):
        sel = sel.to_numpy()
        out.append((name, histogram(v[sel], lab[sel], width, lo, hi)))
    return out


MIN_GROUP = 10  # tested components for a group's own histogram of w


def w_hists(obs: pd.DataFrame, opt: ReportOptions,
            groups: dict[str, dict[str, str]] | None = None) -> list[tuple[str, Histogram]]:
    """Histograms of w of the active, tested observations: image x, y, x and y; then per
    observation group of the other kinds with at least MIN_GROUP tested components (control
    X, Y, Z, GNSS X, Y, Z, IMU, distances, model XY and Z, ...: `groups`, kind -> component
    -> group as summary.json 'observation_groups' states them; a kind it does not name is
    one group), and all observations together."""
    d = obs.loc[~obs["rejected"] & np.isfinite(obs["w"]), label_columns(obs) + ["w"]]
    lab = Labels(d)
    kind = d["kind"].to_numpy(str)
    img = kind == "image"
    comp = d["component"].to_numpy(str)
    sels = [("image x", img & (comp == "x")), ("image y", img & (comp == "y")),
            ("image x and y", img)]
    if not img.all():
        groups = groups or {}
        flat = {f"{k}\t{c}": g for k, cs in groups.items() for c, g in cs.items()}
        group = (pd.Series(np.char.add(np.char.add(kind, "\t"), comp)).map(flat)
                 .fillna(pd.Series(kind)).to_numpy(object))
        for k in dict.fromkeys(kind[~img].tolist()):  # kinds, then axes, as they come
            names = list(dict.fromkeys(group[kind == k].tolist()))
            if k == "model":
                names.sort()  # planimetry (model XY) before height (model Z)
            sels += [(name, sel) for name in names if (sel := group == name).sum() >= MIN_GROUP]
        sels.append(("all observations", np.ones(len(d), bool)))
    w = d["w"].to_numpy(float)
    return [(n, histogram(w[s], lab[s], opt.w_width, opt.w_lo, opt.w_hi)) for n, s in sels
            if s.any()]


def summary_lines(res: Results) -> list[str]:
    """The summary as the adjustment wrote it (summary.json sections), then the files' part."""
    lines = [f"project {res.title}   (source {res.summary.get('source', '?')}, results "
             f"{res.folder})"]
    if res.sections:
        lines += ["", *render(res.sections, width=78).split("\n")]
    else:
        lines.append("summary.json has no sections: the summary is not available")
    return lines


def text_report(res: Results, opt: ReportOptions | None = None) -> str:
    opt = opt or ReportOptions()
    obs = res.obs
    out = ["BAARDA ADJUSTMENT REPORT", "=" * 78]
    out += failures(res.summary)
    if res.run:
        out.append(f"run {res.run}")
    out += summary_lines(res)
    out += [f"note: {n}" for n in res.notes]
    out += ["", "SNOOPING LOG", "-" * 78, format_log(res.summary)]
    out += ["", "GROUP STATISTICS (rejected observations left out; image and model µm, "
            "control m)", "-" * 78, format_groups(group_statistics(obs, res.units))]
    if res.photos is not None and (obs["kind"] == "image").any():
        out += ["", "PER STRIP", "-" * 78, format_image_groups(per_strip(obs, res.strip_of()),
                                                               "strip")]
    if res.photos is not None and obs["kind"].isin(EXTERIOR_NAMES).any():
        out += ["", "GNSS AND IMU PER STRIP (GNSS m, IMU residuals as in observations.csv)",
                "-" * 78, format_gnss_imu(gnss_imu_per_strip(obs, res.strip_of()))]
    if (obs["kind"] == "image").any():
        t, note = largest_rms(per_photo(obs), opt.max_rows, "photos")
        out += ["", "PER PHOTO" + note, "-" * 78, format_image_groups(t, "photo")]
    if (obs["kind"] == "model").any():
        out += ["", "PER MODEL", "-" * 78, format_model_groups(model_groups(obs))]
    out += ["", f"LARGEST RESIDUALS ({opt.worst} per kind)", "-" * 78,
            format_worst(worst(obs, opt.worst), res.units)]
    for name, h in image_histograms(obs, opt):
        out += ["", format_histogram(h, f"IMAGE {name.upper()} RESIDUALS", "µm",
                                     opt.line_width)]
    for name, h in w_hists(obs, opt, res.summary.get("observation_groups")):
        out += ["", format_histogram(h, f"STANDARDIZED RESIDUALS w, {name.upper()}", "",
                                     opt.line_width, expected=h.expected_normal(),
                                     critical=res.k_w)]
    t = snooping_table(obs, sort=opt.sort, min_abs_w=opt.min_abs_w, top=opt.top,
                       units=res.units)
    t, note = first_rows(t, opt.max_rows)
    out += ["", f"SNOOPING TABLE ({len(t)} of {len(obs)} observations: every rejected and "
            f"flagged one, and the largest |w|{note})", "-" * 78, format_snooping(t, res.k_w)]
    out += weakest_text(obs, opt, res.units)
    sep = least_separable(obs, opt.worst)
    if len(sep):
        out += ["", f"LEAST SEPARABLE ({len(sep)}; MDB and MSB in the units of the kind)",
                "-" * 78, counts_line(obs), format_least_separable(sep)]
    return "\n".join(out) + "\n"


def weakest_text(obs: pd.DataFrame, opt: ReportOptions,
                 units: dict[str, str] | None = None) -> list[str]:
    """The text report's tables of the weakest observations (largest |w|: the snooping
    table)."""
    if not obs["redundancy"].notna().any():
        return []
    out = []
    for title, t in weakest(obs, opt.worst, units).items():
        out += ["", f"{title.upper()} ({opt.worst})", "-" * 78,
                *text_lines(weakest_table(t), header=False)]
    return out


def weakest_table(t: pd.DataFrame) -> TableData:
    """One of `weakest`'s tables as the text report's lines: kind, observation, r, w, MDB
    in the unit of its kind."""
    return TableData.of([
        Column("kind", text=True, width=8), Column("label", text=True, width=36),
        Column("redundancy", fmt=".3f", width=6, gap=1, label="r "),
        Column("w", fmt=".2f", width=6, gap=2, label="w "),
        Column("mdb", fmt=".4g", width=10, gap=2, label="MDB "),
        Column("unit", text=True, gap=1)], t.assign(label=obs_label(t)))


def format_worst(t: pd.DataFrame, units: dict[str, str] | None = None) -> str:
    """The largest residuals, with w where the file has it."""
    units = {**UNITS, **(units or {})}
    w = (t["w"].astype(object).where(np.isfinite(t["w"].to_numpy(float)), None) if "w" in t
         else pd.Series(None, index=t.index, dtype=object))
    table = TableData.of([
        Column("kind", text=True, width=8), Column("label", text=True, width=36),
        Column("residual", fmt=".4f", width=12),
        Column("unit", text=True, width=3, gap=1), Column("w", fmt=".2f", width=7, gap=1,
                                                          label="w ")],
        t.assign(label=obs_label(t), unit=[units.get(k, "") for k in t["kind"]],
                 w=w))
    return "\n".join(text_lines(table, header=False)) or "none"


def residuals_report(rs: ResidualSet, width: float = 1.0, lo: float = -25.0, hi: float = 25.0,
                     line_width: int = 60, n_worst: int = 10) -> str:
    """The post-processor's text (`baarda residuals`): VAN statistics and histograms of a
    ResidualSet read by baarda.io.residual_listings."""
    obs, unit = rs.obs, rs.units["image"]
    out = ["RESIDUAL ANALYSIS (VAN)", "=" * 78, *rs.notes]
    groups = group_statistics(obs, rs.units)
    vec = vector_statistics(obs, unit)
    out += ["", f"GROUP STATISTICS (image {unit}, control m)", "-" * 78,
            format_groups(groups + ([vec] if vec is not None else []))]
    if vec is not None:
        out.append(f"image vector: length of the residual vector of each image point; RMS = "
                   f"sqrt(mean(vx^2 + vy^2)) = {vec.rms:.3f} {unit}")
    img = obs["kind"] == "image"
    if img.any():
        out += ["", "PER PHOTO", "-" * 78, format_image_groups(per_photo(obs), "photo", unit)]
        strip = obs.loc[img, "strip"].astype(str)
        if (strip != "").any():
            key = dict(zip(obs.loc[img, "photo"].astype(str), strip, strict=True))
            out += ["", "PER STRIP", "-" * 78,
                    format_image_groups(per_strip(obs, key), "strip", unit)]
    out += ["", f"LARGEST RESIDUALS ({n_worst} per kind)", "-" * 78,
            format_worst(worst(obs, n_worst), rs.units)]
    if img.any():
        opt = ReportOptions(width=width, lo=lo, hi=hi, line_width=line_width)
        for name, h in image_histograms(obs, opt):
            out += ["", format_histogram(h, f"IMAGE {name.upper()} RESIDUALS", unit,
                                         line_width)]
    return "\n".join(out) + "\n"
