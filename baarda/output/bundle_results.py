"""The result folder of a bundle adjustment: summary.json, photos.csv, points.csv,
observations.csv (output/results.py), and the tables in the block's CRS."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from baarda.block.rotation import rad_to_angle
from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.bundle_result import BundleResult
from baarda.output.accuracy import (
    CONTROL,
    FREE_NONE,
    FREE_SIMILARITY,
    Statement,
    statement,
    survey_accuracy,
)
from baarda.output.results import input_fingerprint, summary_document, write_folder
from baarda.output.run_folder import RunFolder
from baarda.quality.assessment import Assessment, observation_columns


def photos_table(result: BundleResult) -> pd.DataFrame:
    blk = result.block
    unit = blk.settings.angle_unit
    c = result.coordinates
    ang = rad_to_angle(c.eo[:, 3:], unit)
    std = result.scaled_std(c.frame_cofactors)
    sang = rad_to_angle(std[:, 3:], unit)
    cams = np.asarray(blk.cameras.ids, dtype=object)[blk.photos.camera]
    df = pd.DataFrame({"photo": blk.photos.ids, "strip": blk.photos.strip, "camera": cams,
                       "X0": c.eo[:, 0], "Y0": c.eo[:, 1], "Z0": c.eo[:, 2],
                       "omega": ang[:, 0], "phi": ang[:, 1], "kappa": ang[:, 2],
                       "sigma_X0": std[:, 0], "sigma_Y0": std[:, 1], "sigma_Z0": std[:, 2],
                       "sigma_omega": sang[:, 0], "sigma_phi": sang[:, 1],
                       "sigma_kappa": sang[:, 2]})
    return df


def points_table(result: BundleResult) -> pd.DataFrame:
    blk = result.block
    pb = result.problem
    ids = np.asarray(blk.points.ids, dtype=object)[pb.point_ids]
    c = result.coordinates
    std = result.scaled_std(c.point_cofactors)
    given = blk.points.xyz[pb.point_ids]
    role = blk.points.role[pb.point_ids]
    df = pd.DataFrame({"point": ids, "role": role, "X": c.xyz[:, 0],
                       "Y": c.xyz[:, 1], "Z": c.xyz[:, 2], "sigma_X": std[:, 0],
                       "sigma_Y": std[:, 1], "sigma_Z": std[:, 2],
                       "rays": blk.rays()[pb.point_ids]})
    compared = result.compared_xyz()
    for k, c in enumerate("XYZ"):
        df[f"d{c}"] = np.where(role != "tie", compared[:, k] - given[:, k], np.nan)
    return df


def tables_in_crs(result: BundleResult) -> tuple[pd.DataFrame, pd.DataFrame]:
    """photos.csv and points.csv of a result adjusted in the local frame of its block, in
    the CRS (result.block.frame).

    Point standard deviations are propagated with the full covariance blocks; those of
    positions of photos likewise; angle standard deviations as adjusted.
    """
    frame = result.block.frame
    ph = photos_table(result)
    co = result.coordinates
    assert frame is not None  # a block adjusted in a local frame
    eo = frame.eo_from_local(co.eo)
    unit = result.block.settings.angle_unit
    ang = rad_to_angle(eo[:, 3:], unit)
    s2 = result.sigma0**2
    cf = co.frame_cofactors[:, :3, :3] * s2
    sf = np.sqrt(np.maximum(np.diagonal(frame.covariance_from_local(co.eo[:, :3], cf),
                                        axis1=1, axis2=2), 0))
    for k, c in enumerate(("X0", "Y0", "Z0")):
        ph[c] = eo[:, k]
        ph[f"sigma_{c}"] = sf[:, k]
    for k, c in enumerate(("omega", "phi", "kappa")):
        ph[c] = ang[:, k]
    pt = points_table(result)
    xyz = frame.from_local(co.xyz)
    cp = co.point_cofactors * s2
    sp = np.sqrt(np.maximum(np.diagonal(frame.covariance_from_local(co.xyz, cp),
                                        axis1=1, axis2=2), 0))
    block = result.block
    given = frame.from_local(block.points.xyz[result.problem.point_ids])
    compared = frame.from_local(result.compared_xyz())  # free networks: after the similarity
    role = block.points.role[result.problem.point_ids]
    for k, c in enumerate("XYZ"):
        pt[c] = xyz[:, k]
        pt[f"sigma_{c}"] = sp[:, k]
        pt[f"d{c}"] = np.where(role != "tie", compared[:, k] - given[:, k], np.nan)
    return ph, pt


def accuracy_of(result: BundleResult, points: pd.DataFrame) -> Statement:
    """The accuracy statement (output/accuracy.py) on the check points of `points` (points.csv
    as written): their survey accuracy from the block's sigmas of the check points, the
    covariance of their mean from the adjustment (in the CRS when adjusted in a local
    frame)."""
    from baarda.bundle.check_mean import check_mean_cofactor
    from baarda.output.verdict import check_point_misses

    miss = check_point_misses(points)
    blk = result.block
    index = blk.point_index
    rows = np.array([index[str(p)] for p in miss["point"]], np.int64)
    survey = survey_accuracy(blk.points.sigma[rows]) if len(rows) else None
    if not result.free_network:
        datum = CONTROL
    else:
        datum = FREE_SIMILARITY if result.check_similarity() is not None else FREE_NONE
    cov = check_mean_cofactor(result, rows) if len(rows) else None
    if cov is not None:
        cov = cov * result.sigma0 ** 2
        if blk.frame is not None:
            centre = result.xyz[result.problem.remap[rows]].mean(axis=0)
            cov = blk.frame.covariance_from_local(centre[None], cov[None])[0]
    return statement(miss, datum, survey, cov)


def write_results(out: str | Path | RunFolder, result: Assessment[BundleResult] | BundleResult,
                  parquet: bool = False) -> list[Path]:
    """Write the result folder of a bundle adjustment (output/results.py) with photos.csv
    and points.csv, each file atomically; returns the paths.  A BundleResult without its
    assessment gives the residuals only.  parquet: observations.parquet instead of
    observations.csv (output/results.py).

    A block adjusted in a local frame of its CRS (block.frame) gets photos.csv and points.csv
    in the CRS, and the local tables as photos_local.csv and points_local.csv."""
    qc = result if isinstance(result, Assessment) else None
    res: BundleResult = result.adjustment if isinstance(result, Assessment) else result
    blk = res.block
    cam = res.cameras  # as adjusted (self-calibration) or as given
    if qc is not None:
        part, sections, obs = qc.to_dict(), qc.sections(), qc.columns()
    else:
        part, sections = {"adjustment": "bundle", **res.to_dict()}, res.sections()
        obs = observation_columns(BundleModel(res))
    crs = None
    if blk.frame is not None:  # adjusted in a local frame of a CRS
        c = blk.frame.crs
        crs = {"name": c.name, "epsg": c.to_epsg(), "heights": "ellipsoidal",
               "adjusted_in": "a local east-north-up frame of the CRS"}
    elif blk.settings.crs:
        crs = {"name": str(blk.settings.crs), "epsg": None, "heights": None,
               "adjusted_in": "the CRS's coordinates"}
    summary = summary_document(
        project=blk.settings.name, source=blk.source, method="bundle", sections=sections,
        parts=[part], angle_unit=blk.settings.angle_unit, crs=crs,
        input=input_fingerprint(blk.source),
        cameras=[{"camera": cam.ids[i], "focal_mm": float(cam.focal_mm[i]),
                  "x0_mm": float(cam.principal_point_mm[i, 0]),
                  "y0_mm": float(cam.principal_point_mm[i, 1]),
                  **({"pixel_mm": float(cam.pixel_mm[i])} if cam.pixel_mm is not None else {})}
                 for i in range(len(cam))])
    tables = {"photos.csv": photos_table(res), "points.csv": points_table(res)}
    if blk.frame is not None:  # adjusted in a local frame: the tables in the CRS as well
        ph, pt = tables_in_crs(res)
        tables = {"photos.csv": ph, "points.csv": pt, "photos_local.csv": tables["photos.csv"],
                  "points_local.csv": tables["points.csv"]}
    summary["accuracy"] = accuracy_of(res, tables["points.csv"]).to_dict()
    if res.problem.calibration.n:  # self-calibration: every camera parameter
        tables["cameras.csv"] = pd.DataFrame(res.camera_table())
    obs_name = "observations.parquet" if parquet else "observations.csv"
    return write_folder(out, summary, {**tables, obs_name: obs})
