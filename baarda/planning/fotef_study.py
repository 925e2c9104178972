"""FOTEF's empirical reliability study (Appendix II) on simulated regular blocks.

Regular single-coverage blocks, image scale 1:5000, model coordinates 10 µm, control 5 cm,
planimetric adjustment.  For every observation (control coordinates and model coordinates
of control and tie points) the boundary value nabla (MDB, in the terrain) and the largest
effect of an error of that size on detail points, on distances within a model and on
distances between points of adjacent models, absolute and as a fraction of nabla.

    python -m baarda.planning.fotef_study          # prints the tables
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from baarda.independent.external import external_reliability
from baarda.independent.independent_model import IndependentModel
from baarda.independent.model_problem import adjust_models
from baarda.quality.statistics import analyse
from baarda.simulate.model_blocks import ModelPlan, simulate_models

# strips, models per strip, planimetric control every k bases on the long borders
BLOCKS = {"I": (2, 4, 2), "II": (3, 6, 3)}
# FOTEF Appendix II: boundary values (cm) and fractions per class of observation (ranges)
FOTEF_TABLE = {"1 + T": ((46, 47), (0.67, 0.69)), "2 + T": ((34, 36), (0.54, 0.72)),
               "2": ((37, 39), (0.18, 0.26)), "4": ((31, 32), (0.29, 0.31))}
FOTEF = {"control (1+T, 2+T)": 0.70, "tie points": 0.30, "distances": 0.50}


def study_block(strips: int, models: int, mode: str = "2d", seed: int = 0,
                **plan) -> pd.DataFrame:
    """One row per observation component with FOTEF's columns 3-12 (lengths in cm)."""
    args: dict[str, Any] = {"strips": strips, "models_per_strip": models, "image_scale": 5000.0,
            "sigma_model_um": (10.0, 10.0), "sigma_control_m": (0.05, 0.05, 0.05),
            "noise": False, "seed": seed, "kappa_rad": 0.0, "height_chains": 1,
            "layout": "fotef"}
    args.update(plan)
    blk, _ = simulate_models(ModelPlan(**args))
    res = adjust_models(blk, mode)
    qm = IndependentModel(res)
    q = analyse(qm)
    idx = np.flatnonzero(q.active & q.controlled)
    ext = external_reliability(qm, q, idx)
    nmod = blk.models_per_point()
    pindex = {p: i for i, p in enumerate(blk.points)}
    pnt = np.array([pindex[p] for p in qm.point[idx]])
    ctrl = blk.controlled[pnt][:, list(qm.problem.comps)].any(axis=1)
    kind = np.where(qm.kind[idx] == "control", "TERR", "MOD")
    return pd.DataFrame({
        "point": qm.point[idx], "models": nmod[pnt],
        "class": np.where(ctrl, [f"{n} + T" for n in nmod[pnt]],
                          [f"{n}" for n in nmod[pnt]]),
        "type": kind, "model": qm.frame[idx], "component": qm.component[idx],
        "redundancy": q.redundancy_number[idx], "nabla_cm": ext.nabla * 100,
        "point_cm": ext.point * 100, "dist_same_cm": ext.dist_same * 100,
        "dist_diff_cm": ext.dist_diff * 100, "point_prop": ext.point_prop,
        "same_prop": ext.same_prop, "diff_prop": ext.diff_prop})


def summary_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per class of observation: the largest effects (FOTEF's columns 10-12)."""
    g = df.groupby(["class", "type"])
    return pd.DataFrame({
        "n": g.size(), "r_min": g["redundancy"].min(), "nabla_cm_max": g["nabla_cm"].max(),
        "point_prop_max": g["point_prop"].max(), "same_prop_max": g["same_prop"].max(),
        "diff_prop_max": g["diff_prop"].max()}).reset_index()


def headline(df: pd.DataFrame) -> dict:
    """Largest fractions in FOTEF's three statements."""
    ctrl = df["class"].str.endswith("+ T")
    return {"control (1+T, 2+T)": float(df.loc[ctrl, "point_prop"].max()),
            "tie points": float(df.loc[~ctrl, "point_prop"].max()),
            "distances": float(np.maximum(df["same_prop"], df["diff_prop"]).max())}


def main() -> None:
    pd.set_option("display.width", 160)
    for mode in ("2d", "3d"):
        for name, (s, m, k) in BLOCKS.items():
            df = study_block(s, m, mode, control_spacing=k)
            print(f"\nBlock {name} ({s} strips x {m} models), {mode}")
            print(summary_table(df).to_string(index=False, float_format=lambda v: f"{v:.2f}"))
            h = headline(df)
            print("largest fraction: " + ", ".join(f"{k} {v:.2f} (FOTEF {FOTEF[k]:.2f})"
                                                    for k, v in h.items()))


if __name__ == "__main__":
    main()
