"""Outputs of `baarda plan`: text report, CSV tables and maps (all written atomically).

    plan_report.txt        summary, class means, precision, advice
    plan_observations.csv  per observation component: class, r, sqrt(qvv), MDB (µm / m),
                           external reliability (m)
    plan_classes.csv       Gruen class means of sqrt(qvv)
    plan_points.csv        expected standard deviations of the ground points (m)
    plan_photos.csv        per photo: points, coverage, weakest sqrt(qvv)
    plan_what_if.csv       (flight plans) the remedies recomputed
    plan_maps.png          maps: weakest sqrt(qvv), largest MDB, largest external effect,
                           expected sigma Z per ground point
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pandas as pd

from baarda.output.atomic import write_bytes, write_text
from baarda.output.run_folder import RunFolder, staged
from baarda.output.tables import csv_text
from baarda.planning.advice import Advice
from baarda.planning.design_reliability import PlanResult
from baarda.planning.reliability_tables import ReliabilityTable


def _csv(df: pd.DataFrame) -> str:
    return csv_text(df, "%.6g")


def report_text(plan: PlanResult, advice: list[Advice],
                what_if: pd.DataFrame | None = None, title: str = "") -> str:
    q = plan.qc.quality
    res = plan.adjustment
    obs = plan.image()
    ok = obs["redundancy"] >= 1e-3
    lines = [f"Design-stage reliability{': ' + title if title else ''}", "=" * 72,
             plan.block.summary(),
             f"observations {res.n_observations}, unknowns {res.n_unknowns}, redundancy "
             f"{q.redundancy}; sum of redundancy numbers {q.sum_redundancy_numbers:.4f}",
             f"alpha0 {q.alpha0}, beta0 {q.beta0}: delta0 {q.delta0:.3f} (MDB = delta0 sigma / "
             "sqrt(r)); no measurement used: sqrt(qvv) = sqrt(r) at unit weight", "",
             "Gruen point classes: mean sqrt(qvv) (x, y, pooled; count; lowest)"]
    cm = plan.class_means()
    wide = cm.pivot_table(index="class", columns="component", values="mean")
    cnt = cm[cm["component"] == "xy"].set_index("class")
    for cls in wide.index:
        x, y, xy = (wide.loc[cls].get(c, np.nan) for c in ("x", "y", "xy"))
        n, lo = int(cnt.loc[cls, "count"]), cnt.loc[cls, "min"]
        lines.append(f"  {cls:8s} x {x:5.2f}  y {y:5.2f}  xy {xy:5.2f}  n {n:6d}  min {lo:5.2f}")
    tested = obs[ok]
    lines += ["", "Image observations",
              f"  sqrt(qvv) mean {obs['sqrt_qvv'].mean():.3f}, lowest tested "
              f"{tested['sqrt_qvv'].min():.3f}; {int((~ok).sum())} uncontrolled (r = 0)",
              f"  MDB mean {tested['mdb'].mean():.1f} µm, largest {tested['mdb'].max():.1f} µm",
              "  largest effect of an MDB on a ground point "
              f"{tested['external_max'].max():.3f} m"]
    pts = plan.points
    for role in ("control", "tie"):
        p = pts[pts["role"] == role]
        if len(p):
            rms = np.sqrt((p[["sigma_X", "sigma_Y", "sigma_Z"]] ** 2).mean())
            lines.append(f"  expected precision of {role} points (RMS, sigma0 = 1): X "
                         f"{rms['sigma_X']:.3f} m, Y {rms['sigma_Y']:.3f} m, Z "
                         f"{rms['sigma_Z']:.3f} m")
    if what_if is not None and len(what_if):
        lines += ["", "What if (the remedies recomputed)", what_if.to_string(
            index=False, float_format=lambda v: f"{v:.3f}")]
    lines += ["", "Advice"] + ([a.text() for a in advice] or ["  no weak places found"])
    return "\n".join(lines) + "\n"


def plan_maps(plan: PlanResult) -> bytes:
    """PNG with four maps over the ground: per point the weakest sqrt(qvv), largest MDB,
    largest external effect of its observations and its expected sigma Z."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    obs = plan.image()
    ok = obs["redundancy"] >= 1e-3
    g = obs.groupby("point")
    per = pd.DataFrame({"X": g["X"].first(), "Y": g["Y"].first(),
                        "min_sqrt": g["sqrt_qvv"].min(),
                        "mdb": obs[ok].groupby("point")["mdb"].max(),
                        "ext": obs[ok].groupby("point")["external_max"].max()})
    pts = plan.points.set_index("point")
    per["sigma_Z"] = pts["sigma_Z"].reindex(per.index)
    ctrl = pts[pts["role"] == "control"]
    ph = plan.photos
    fig, axes = plt.subplots(2, 2, figsize=(12, 10), constrained_layout=True)
    panels = [("min_sqrt", "weakest sqrt(qvv) of the point's observations", "RdYlGn"),
              ("mdb", "largest MDB (µm)", "viridis_r"),
              ("ext", "largest external effect (m)", "magma_r"),
              ("sigma_Z", "expected sigma Z (m)", "cividis")]
    for ax, (col, title, cmap) in zip(axes.ravel(), panels, strict=True):
        sc = ax.scatter(per["X"], per["Y"], c=per[col], cmap=cmap, s=28)
        ax.plot(ph["X0"], ph["Y0"], "k+", ms=6, alpha=0.5, label="photo centres")
        ax.plot(ctrl["X"], ctrl["Y"], "^", mfc="none", mec="b", ms=10, label="control")
        ax.set_title(title)
        ax.set_aspect("equal")
        ax.set_xlabel("X (m)")
        ax.set_ylabel("Y (m)")
        fig.colorbar(sc, ax=ax, shrink=0.8)
    axes[0, 0].legend(loc="upper right", fontsize=8)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


def write_plan(out: str | Path | RunFolder, plan: PlanResult, advice: list[Advice],
               what_if: pd.DataFrame | None = None, title: str = "",
               plots: bool = True) -> list[Path]:
    """Write the planning outputs as one run of folder `out`; the final paths."""
    files = {
        "plan_report.txt": report_text(plan, advice, what_if, title),
        "plan_observations.csv": _csv(plan.observations),
        "plan_classes.csv": _csv(plan.class_means()),
        "plan_points.csv": _csv(plan.points),
        "plan_photos.csv": _csv(plan.photos),
    }
    files["plan_advice.csv"] = _csv(pd.DataFrame(
        [{"topic": a.topic, "finding": a.finding, "remedy": a.remedy,
          "where": "; ".join(a.where)} for a in advice],
        columns=["topic", "finding", "remedy", "where"]))
    if what_if is not None:
        files["plan_what_if.csv"] = _csv(what_if)
    with staged(out) as run:
        for name, text in files.items():
            write_text(run.file(name), text)
        if plots:
            write_bytes(run.file("plan_maps.png"), plan_maps(plan))
            files["plan_maps.png"] = ""
        return [run.final / name for name in files]


def write_reliability_table(path: str | Path, table: ReliabilityTable, header: str = "") -> None:
    """A reliability-model table as CSV with '# ' header lines (planning/reliability_tables.py)."""
    lines = "".join(f"# {h}\n" for h in header.splitlines() if h)
    write_text(path, lines + csv_text(table.frame, "%.4f"))


def write_modified_snooping(out: str | Path | RunFolder, table: pd.DataFrame,
                            text: str) -> list[Path]:
    """modified_snooping.csv and modified_snooping.txt of `baarda modified-snoop`, one
    run of folder `out`; the final paths."""
    with staged(out) as run:
        write_text(run.file("modified_snooping.csv"), _csv(table))
        write_text(run.file("modified_snooping.txt"), text)
        return [run.final / "modified_snooping.csv", run.final / "modified_snooping.txt"]
