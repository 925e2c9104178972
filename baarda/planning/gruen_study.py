"""Gruen's (1980) reliability-model study, reproduced.

Blocks 4x4 and 7x7 photos with 3x3 and 5x5 image points per photo ("43", "73", "45", "75"),
60 % / 60 % overlap, stereo mode (twin rays), c = 150 mm, format 230 mm, vertical photos over
flat terrain, image coordinates uncorrelated and of equal precision, control free of errors.
Three control distributions per block (Figure 1, lost in the OCR, reconstructed from Figure 9
and the text): full control on the perimeter of the four-fold area every i base lengths and
height control at the interior positions of the same grid, i = L/3, L/2, L for a block of
L bases (43 and 45: i = 1, 1.5, 3; 73 and 75: i = 2, 3, 6); each once with single and once
with twin control.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from baarda.planning.design import ControlLayout, design_block
from baarda.planning.design_reliability import PlanResult, analyse_design
from baarda.planning.reliability_tables import (
    COLUMNS,
    DesignKey,
    ReliabilityTable,
    read_gruen_table2,
)
from baarda.simulate.aerial import FlightPlan

STUDY_BLOCKS = {"43": (4, 3), "73": (7, 3), "45": (4, 5), "75": (7, 5)}
GRUEN_ROWS = [("R2", "x"), ("R2", "y"), ("RO3", "x"), ("RO3", "y"), ("RI3", "xy"),
              ("RO4/9", "xy"), ("RI4/9", "xy"), ("CRO4/9", "xy"), ("CRI4/9", "xy")]
TOLERANCE = 0.05  # acceptance: class means within 0.05 of Table 2


def study_plan(photos: int, pattern: int, **kw) -> FlightPlan:
    """Gruen's flight plan: photos x photos, 60/60 overlap, c = 150 mm, stereo mode."""
    args: dict[str, Any] = dict(
        strips=photos, photos_per_strip=photos, forward_overlap=0.6, side_overlap=0.6,
        focal_mm=150.0, format_mm=230.0, image_scale=10_000.0, pattern=pattern,
        stereo=True, sigma_image_um=5.0, name=f"gruen-{photos}{pattern}")
    args.update(kw)
    return FlightPlan(**args)


def spacings(photos: int) -> tuple[float, float, float]:
    """Bridging distances i (base lengths) of the three control distributions: L/3, L/2, L."""
    length = photos - 1
    return (length / 3, length / 2, float(length))


@dataclass
class StudyCase:
    block: str  # "43", ...
    spacing: float
    control: str  # single | twin
    plan: PlanResult
    key: DesignKey = field(default_factory=DesignKey)


@dataclass
class Study:
    cases: list[StudyCase] = field(default_factory=list)

    def case_means(self) -> pd.DataFrame:
        """Class means of every case: block, spacing, control, class, component, mean, ..."""
        out = []
        for c in self.cases:
            m = c.plan.class_means()
            m.insert(0, "control", c.control)
            m.insert(0, "spacing", c.spacing)
            m.insert(0, "block", c.block)
            out.append(m)
        return pd.concat(out, ignore_index=True)

    def block_means(self) -> pd.DataFrame:
        """Mean over the three control distributions (Gruen's 'block means'), wide form:
        class, component, control, b43, b73, b45, b75, m3x3, m5x5, total."""
        cm = self.case_means()
        bm = cm.groupby(["block", "control", "class", "component"])["mean"].mean()
        rows = []
        for ctl in ("single", "twin"):
            for cls, comp in GRUEN_ROWS:
                r: dict[str, Any] = {"class": cls, "component": comp, "control": ctl}
                for b in STUDY_BLOCKS:
                    r[f"b{b}"] = bm.get((b, ctl, cls, comp), np.nan)
                r["m3x3"] = np.nanmean([r["b43"], r["b73"]])
                r["m5x5"] = np.nanmean([r["b45"], r["b75"]])
                r["total"] = np.nanmean([r["m3x3"], r["m5x5"]])
                rows.append(r)
        return pd.DataFrame(rows)

    def side_by_side(self) -> pd.DataFrame:
        """Ours next to Gruen's Table 2: one row per (class, component, control, column)."""
        ours = self.block_means()
        g = read_gruen_table2()
        rows = []
        for _, o in ours.iterrows():
            gr = g[(g["class"] == o["class"]) & (g["component"] == o["component"])
                   & (g["control"] == o["control"])].iloc[0]
            for col in ("b43", "b73", "b45", "b75", "m3x3", "m5x5", "total"):
                if np.isnan(gr[col]) and col == "total":
                    continue
                rows.append({"class": o["class"], "component": o["component"],
                             "control": o["control"], "column": col, "ours": o[col],
                             "gruen": gr[col], "difference": o[col] - gr[col]})
        return pd.DataFrame(rows)

    def checks(self) -> pd.DataFrame:
        """Per case: largest sqrt(qvv) of R2(x), sum of redundancy numbers, redundancy."""
        rows = []
        for c in self.cases:
            obs = c.plan.image()
            r2x = obs[(obs["class"].isin(["R2", "CR2"])) & (obs["component"] == "x")]
            rows.append({"block": c.block, "spacing": c.spacing, "control": c.control,
                         "n_R2x": len(r2x),
                         "max_R2x": float(r2x["sqrt_qvv"].max()) if len(r2x) else np.nan,
                         "sum_r": c.plan.sum_redundancy_numbers,
                         "sum_r_image": float(obs["redundancy"].sum()),
                         "redundancy": c.plan.redundancy})
        return pd.DataFrame(rows)

    def derive_table(self, source: str = "baarda study (Gruen 1980 set-up)") -> ReliabilityTable:
        """Our reliability table: per pattern and control, the mean of the block means."""
        return derive_table(self.cases, source)


def run_study(blocks: tuple[str, ...] = tuple(STUDY_BLOCKS), controls=("single", "twin"),
              interior: str = "height", partial_as_control: bool = True) -> Study:
    """Adjust every block of the study and collect the class means."""
    study = Study()
    for b in blocks:
        photos, pattern = STUDY_BLOCKS[b]
        study.cases += simulate_cases(study_plan(photos, pattern), spacings(photos), controls,
                                      label=b, interior=interior,
                                      partial_as_control=partial_as_control)
    return study


def plan_key(plan: FlightPlan, control: str) -> DesignKey:
    """The design key of a flight plan: pattern, overlaps in %, stereo, control."""
    return DesignKey(pattern=f"{plan.pattern}x{plan.pattern}",
                     overlap=f"{plan.forward_overlap * 100:.0f}/{plan.side_overlap * 100:.0f}",
                     stereo=plan.stereo, control=control)


def simulate_cases(plan: FlightPlan, bridging: tuple[float, ...], controls=("single", "twin"),
                   label: str = "", interior: str = "height",
                   partial_as_control: bool = True) -> list[StudyCase]:
    """The plan with each control distribution (bridging distances in bases), adjusted."""
    cases = []
    for ctl in controls:
        for i in bridging:
            layout = ControlLayout(spacing=i, interior=interior, twin=ctl == "twin")
            res = analyse_design(design_block(plan, layout),
                                 partial_as_control=partial_as_control)
            cases.append(StudyCase(label or plan.name, i, ctl, res, plan_key(plan, ctl)))
    return cases


def derive_table(cases: list[StudyCase], source: str) -> ReliabilityTable:
    """Our reliability table: per design key, the mean over the cases of their class means
    (each block and control distribution weighs the same), for x, y and pooled 'xy'."""
    rows = []
    for c in cases:
        k = c.key
        rows.append(c.plan.class_means().assign(pattern=k.pattern, overlap=k.overlap,
                                                stereo=k.stereo, control=k.control))
    df = pd.concat(rows, ignore_index=True)
    g = df.groupby(["pattern", "overlap", "stereo", "control", "class", "component"])
    out = g.agg(value=("mean", "mean"), count=("count", "sum")).reset_index()
    out["source"] = source
    return ReliabilityTable(out[COLUMNS])


def tolerance_check(study: Study, table: ReliabilityTable, k_q: float = 0.25,
                    controls: tuple[str, ...] = ("single",)) -> pd.DataFrame:
    """Gruen's Figure 9 check: individual sqrt(qvv) outside +-k_q of the table value.

    One row per observation outside the band: block, spacing, control, class, component,
    photo, point, sqrt_qvv, reference, half_coverage (of its photo).
    """
    rows = []
    for c in study.cases:
        if c.control not in controls:
            continue
        obs = c.plan.image()
        ref = table.lookup(obs["class"].to_numpy(), obs["component"].to_numpy(), c.key)
        test = np.isfinite(ref) & (ref > 0)
        out = test & (np.abs(obs["sqrt_qvv"].to_numpy() - ref) > k_q * ref)
        half = dict(zip(c.plan.photos["photo"], c.plan.photos["half_coverage"], strict=True))
        sel = obs[out]
        rows.append(pd.DataFrame({
            "block": c.block, "spacing": c.spacing, "control": c.control,
            "class": sel["class"], "component": sel["component"], "photo": sel["photo"],
            "point": sel["point"], "sqrt_qvv": sel["sqrt_qvv"], "reference": ref[out],
            "low": sel["sqrt_qvv"].to_numpy() < ref[out],
            "half_coverage": [bool(half[p]) for p in sel["photo"]],
            "tested": int(test.sum())}))
    return pd.concat(rows, ignore_index=True) if rows else pd.DataFrame()


def format_side_by_side(sbs: pd.DataFrame, tolerance: float = TOLERANCE) -> str:
    """Text table: for each class and control, 'ours/Gruen' per column; * beyond tolerance."""
    cols = ["b43", "b73", "b45", "b75", "m3x3", "m5x5", "total"]
    head = f"{'class':10s} {'ctl':6s} " + " ".join(f"{c[1:] if c[0] == 'b' else c:>11s}"
                                                  for c in cols)
    lines = [head, "-" * len(head)]
    for (cls, comp, ctl), g in sbs.groupby(["class", "component", "control"], sort=False):
        cells = []
        for c in cols:
            r = g[g["column"] == c]
            if r.empty:
                cells.append(f"{'':>11s}")
                continue
            r = r.iloc[0]
            flag = "*" if abs(r["difference"]) > tolerance else " "
            cells.append(f"{r['ours']:.2f}/{r['gruen']:.2f}{flag}".rjust(11))
        lines.append(f"{cls + '(' + comp + ')':10s} {ctl:6s} " + " ".join(cells))
    return "\n".join(lines)


def side_by_side_markdown(sbs: pd.DataFrame, tolerance: float = TOLERANCE) -> str:
    """Markdown table: 'ours / Gruen' (ours to 3 decimals), bold beyond the tolerance."""
    cols = ["b43", "b73", "b45", "b75", "m3x3", "m5x5", "total"]
    names = ["43", "73", "45", "75", "3x3", "5x5", "total"]
    lines = ["| class | control | " + " | ".join(names) + " |",
             "|---|---|" + "---|" * len(cols)]
    for (cls, comp, ctl), g in sbs.groupby(["class", "component", "control"], sort=False):
        cells = []
        for c in cols:
            r = g[g["column"] == c]
            if r.empty:
                cells.append("")
                continue
            r = r.iloc[0]
            cell = f"{r['ours']:.3f} / {r['gruen']:.2f}"
            cells.append(f"**{cell}**" if abs(r["difference"]) > tolerance else cell)
        lines.append(f"| {cls}({comp}) | {ctl} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def photo_grid(case: StudyCase, counts: dict[str, int]) -> str:
    """A map of the photos (strips as rows): the number per photo, '.' for none."""
    ph = case.plan.photos
    lines = []
    for s in pd.unique(ph["strip"]):
        row = ph[ph["strip"] == s]
        lines.append(" ".join(f"{counts.get(p, 0) or '.':>2}" for p in row["photo"]))
    return "\n".join(lines)


# Gruen's analytic mean curves of the control-point classes over the bridging distance i
# (base lengths): sqrt(qvv) = a + b i  (text after Figure 8)
GRUEN_CONTROL_FITS = {
    ("CRO4/9", "3x3", "single"): (0.735, -0.018), ("CRO4/9", "5x5", "single"): (0.825, -0.013),
    ("CRI4/9", "3x3", "single"): (0.885, -0.004), ("CRI4/9", "5x5", "single"): (0.920, -0.002),
    ("CRO4/9", "3x3", "twin"): (0.835, -0.015), ("CRO4/9", "5x5", "twin"): (0.870, -0.008),
    ("CRI4/9", "3x3", "twin"): (0.920, -0.010), ("CRI4/9", "5x5", "twin"): (0.940, -0.007),
}


def control_curves(study: Study) -> pd.DataFrame:
    """Per case the control-class means next to Gruen's fitted lines a + b i."""
    cm = study.case_means()
    rows = []
    for c in study.cases:
        for cls in ("CRO4/9", "CRI4/9"):
            sel = cm[(cm["block"] == c.block) & (cm["spacing"] == c.spacing)
                     & (cm["control"] == c.control) & (cm["class"] == cls)
                     & (cm["component"] == "xy")]
            a, b = GRUEN_CONTROL_FITS[(cls, c.key.pattern, c.control)]
            rows.append({"block": c.block, "control": c.control, "i": c.spacing, "class": cls,
                         "ours": float(sel["mean"].iloc[0]) if len(sel) else np.nan,
                         "gruen_fit": a + b * c.spacing})
    df = pd.DataFrame(rows)
    df["difference"] = df["ours"] - df["gruen_fit"]
    return df
