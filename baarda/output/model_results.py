"""Result files of a model block: summary.json, models.csv, points.csv, observations.csv,
hypotheses.csv and preadjustment.csv (each written atomically)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from baarda.block.rotation import rad_to_angle
from baarda.independent.workflow import BlockQuality
from baarda.output.accuracy import CONTROL, Statement, statement, survey_accuracy
from baarda.output.results import summary_document, write_folder
from baarda.output.run_folder import RunFolder


def models_table(bq: BlockQuality) -> pd.DataFrame:
    """Transformation of every model: 3d/2d position [m], rotations, scale [m per mm];
    height: shift and tilts [µm at the model edge]."""
    bl = bq.block
    unit = bl.settings.angle_unit
    df = pd.DataFrame({"model": bl.models, "strip": bl.strip})
    for part in bq.parts:
        res = part.adjustment
        p, sd = res.terrain_params, res.param_std
        if part.mode == "3d":
            ang, sang = rad_to_angle(p[:, 3:6], unit), rad_to_angle(sd[:, 3:6], unit)
            cols = {"TX": p[:, 0], "TY": p[:, 1], "TZ": p[:, 2], "omega": ang[:, 0],
                    "phi": ang[:, 1], "kappa": ang[:, 2], "scale": 1 / p[:, 6],
                    "sigma_TX": sd[:, 0], "sigma_TY": sd[:, 1], "sigma_TZ": sd[:, 2],
                    "sigma_omega": sang[:, 0], "sigma_phi": sang[:, 1],
                    "sigma_kappa": sang[:, 2], "sigma_scale": sd[:, 6] / p[:, 6] ** 2}
        elif part.mode == "2d":
            cols = {"TX": p[:, 0], "TY": p[:, 1], "kappa": rad_to_angle(p[:, 2], unit),
                    "scale": 1 / p[:, 3], "sigma_TX": sd[:, 0], "sigma_TY": sd[:, 1],
                    "sigma_kappa": rad_to_angle(sd[:, 2], unit),
                    "sigma_scale": sd[:, 3] / p[:, 3] ** 2}
        else:
            cols = {"h_shift_um": p[:, 0] * 1e3, "h_tilt_x_um": p[:, 1] * 1e3,
                    "h_tilt_y_um": p[:, 2] * 1e3, "sigma_h_shift_um": sd[:, 0] * 1e3,
                    "sigma_h_tilt_x_um": sd[:, 1] * 1e3, "sigma_h_tilt_y_um": sd[:, 2] * 1e3}
        for k, v in cols.items():
            df[k] = v
    if bq.tilts is not None:
        df["levelled_by"] = rad_to_angle(bq.tilts, unit)
    return df


def points_table(bq: BlockQuality) -> pd.DataFrame:
    bl = bq.block
    n = bl.n_points
    xyz = np.full((n, 3), np.nan)
    std = np.full((n, 3), np.nan)
    for part in bq.parts:
        res = part.adjustment
        pb = res.problem
        xyz[np.ix_(pb.point_ids, pb.comps)] = res.xyz
        std[np.ix_(pb.point_ids, pb.comps)] = res.xyz_std
    df = pd.DataFrame({"point": bl.points, "role": bl.role,
                       "kind": np.where(bl.pc, "pc", "point"), "models": bl.models_per_point(),
                       "X": xyz[:, 0], "Y": xyz[:, 1], "Z": xyz[:, 2], "sigma_X": std[:, 0],
                       "sigma_Y": std[:, 1], "sigma_Z": std[:, 2]})
    for k, c in enumerate("XYZ"):
        df[f"d{c}"] = np.where(bl.role != "tie", xyz[:, k] - bl.xyz[:, k], np.nan)
    return df


def accuracy_of(bq: BlockQuality, points: pd.DataFrame) -> Statement:
    """The accuracy statement (output/accuracy.py) on the check points of `points`, their
    survey accuracy from the block's sigmas of the check points (the mean is not tested:
    the model block does not give the covariance of the check points' mean)."""
    from baarda.output.verdict import check_point_misses

    miss = check_point_misses(points)
    index = {str(p): i for i, p in enumerate(bq.block.points)}
    rows = np.array([index[str(p)] for p in miss["point"]], np.int64)
    survey = survey_accuracy(bq.block.sigma[rows]) if len(rows) else None
    return statement(miss, CONTROL, survey)


def write_results(out: str | Path | RunFolder, bq: BlockQuality) -> list[Path]:
    """Write the result folder of a model block (output/results.py) with models.csv,
    points.csv, hypotheses.csv, preadjustment.csv and report.txt; returns the paths."""
    pre = pd.DataFrame([f.to_dict() for f in bq.pre.findings],
                       columns=["step", "kind", "model", "point", "discrepancy", "ratio"])
    if len(pre):
        pre["discrepancy"] = [" ".join(f"{v:.6g}" for v in d) for d in pre["discrepancy"]]
    bl = bq.block
    own = bq.to_dict()
    del own["adjustments"]  # summary_document makes them from the parts
    summary = summary_document(
        project=bl.settings.name, source=bl.source, method=f"independent models ({bq.mode})",
        sections=bq.sections(), parts=[p.to_dict() for p in bq.parts],
        notes=own.pop("notes"), angle_unit=bl.settings.angle_unit, **own)
    hyp = pd.concat([p.hypotheses_table() for p in bq.parts], ignore_index=True)
    points = points_table(bq)
    summary["accuracy"] = accuracy_of(bq, points).to_dict()
    tables = {"models.csv": models_table(bq), "points.csv": points,
              "observations.csv": pd.concat([p.table() for p in bq.parts], ignore_index=True),
              "hypotheses.csv": hyp, "preadjustment.csv": pre}
    return write_folder(out, summary, tables, {"report.txt": bq.summary() + "\n"})
