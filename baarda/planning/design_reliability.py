"""Design-stage reliability of a block: every statistic that needs no measurement.

Adjusts an error-free design block (baarda.planning.design), takes the redundancy numbers,
MDBs and external reliability from baarda.quality (via baarda.bundle.bundle_quality.assess) and
adds Gruen's point classes and the expected precision of the ground points (sigma0 = 1 a
priori: the a-priori image sigmas are taken as right).

sqrt(qvv) is given in Gruen's unit-weight sense: sqrt(qvv / sigma^2) = sqrt(r).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
import pandas as pd

from baarda.block.photo_block import Block
from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.bundle_quality import assess
from baarda.bundle.bundle_result import BundleResult
from baarda.errors import GeometryError
from baarda.options import TestOptions
from baarda.planning.design import ControlLayout, design_block, design_from_project
from baarda.planning.point_classes import (
    RowClasses,
    classify,
    half_coverage_photos,
    points_per_photo,
)
from baarda.quality.assessment import Assessment
from baarda.simulate.aerial import FlightPlan


@dataclass(frozen=True)
class PlanResult:
    """Reliability and precision of a planned block."""

    block: Block
    adjustment: BundleResult
    qc: Assessment[BundleResult]
    classes: RowClasses
    observations: pd.DataFrame  # one row per observation component
    points: pd.DataFrame  # expected precision per ground point
    photos: pd.DataFrame  # per photo: points, coverage, weakest observation

    @property
    def redundancy(self) -> int:
        return self.qc.quality.redundancy

    @property
    def sum_redundancy_numbers(self) -> float:
        return self.qc.quality.sum_redundancy_numbers

    def image(self) -> pd.DataFrame:
        return self.observations[self.observations["kind"] == "image"]

    def class_means(self, pooled: bool = True) -> pd.DataFrame:
        """Gruen's point means: mean sqrt(qvv) per class and component (x, y; 'xy' pooled)."""
        return class_means(self.image(), pooled)


def class_means(obs: pd.DataFrame, pooled: bool = True) -> pd.DataFrame:
    """Mean, min, max and count of sqrt_qvv per (class, component) of image observations."""
    frames = [obs]
    if pooled:
        frames.append(obs.assign(component="xy"))
    df = pd.concat(frames, ignore_index=True)
    g = df.groupby(["class", "component"], sort=True)["sqrt_qvv"]
    out = g.agg(["mean", "min", "max", "count"]).reset_index()
    return out


def analyse_design(block: Block, tests: TestOptions | None = None, *,
                   partial_as_control: bool = True) -> PlanResult:
    """Adjust the error-free `block` and collect its reliability and precision."""
    try:
        result = BundleProblem(block).fit()
    except GeometryError as e:
        raise GeometryError(
            f"{e}\nThe planned block cannot be adjusted as designed.  With flat terrain and a "
            "single row of tie points between neighbouring strips the strips can turn about "
            "that row (a hinge): add height control on the rows between strips "
            "(--bridging-y 0.5), fly 60 % side overlap, or model the terrain (--relief).",
            frame=e.frame) from None
    qc = assess(result, tests)
    rc = classify(block, partial_as_control)
    return PlanResult(block, result, qc, rc, observation_table(qc, rc),
                      point_table(result), photo_table(block, qc, rc))


def plan(flight: FlightPlan | Block, layout: ControlLayout | None = None,
         tests: TestOptions | None = None, *, adjusted: bool = False) -> PlanResult:
    """Design-stage reliability (`baarda plan` before its advice) of a flight plan with its
    control layout, or of a project's block: its error-free observations at the given
    approximations, or with `adjusted`, at the adjusted orientations and points."""
    if isinstance(flight, FlightPlan):
        return analyse_design(design_block(flight, layout), tests)
    start = None
    if adjusted:
        res = BundleProblem(flight).fit()
        start = (res.eo, res.points_xyz())
    return analyse_design(design_from_project(flight, start), tests)


def observation_table(qc: Assessment[BundleResult], rc: RowClasses) -> pd.DataFrame:
    """Per component: class, rays, r, sqrt(qvv), MDB (µm / m), external reliability (m)."""
    m, q = cast(BundleModel, qc.model), qc.quality
    blk = qc.adjustment.block
    img = m.image_row >= 0
    rows = np.where(img, m.image_row, 0)
    scale = np.where(img, 1e3, 1.0)
    cls = np.where(img, rc.label[rows], "control")
    xy = blk.image.xy_mm[rows]
    comp_idx = np.where(m.component == "y", 1, 0)
    res = qc.adjustment
    pts = res.points_xyz()
    pidx = blk.point_index
    pxyz = pts[[pidx[p] for p in m.point]]
    r = np.clip(q.redundancy_number, 0.0, None)
    return pd.DataFrame({
        "kind": m.kind, "photo": m.frame, "point": m.point, "component": m.component,
        "class": cls, "rays": np.where(img, rc.rays[rows], 0),
        "inner": np.where(img, rc.inner[rows], False),
        "control": np.where(img, rc.control[rows], True),
        "image_mm": np.where(img, xy[np.arange(len(rows)), comp_idx], np.nan),
        "X": pxyz[:, 0], "Y": pxyz[:, 1],
        "sigma": q.sigma * scale, "redundancy": r, "sqrt_qvv": np.sqrt(r),
        "mdb": q.mdb * scale, "external_max": q.external_max,
        "external_point": q.external_point, "controlled": q.controlled,
    })


def point_table(result: BundleResult) -> pd.DataFrame:
    """Expected standard deviations (m) of the adjusted points with sigma0 = 1 a priori."""
    blk = result.block
    pb = result.problem
    cov = result.factor.point_covariance()
    std = np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 0.0))
    return pd.DataFrame({
        "point": np.asarray(blk.points.ids, dtype=object)[pb.point_ids],
        "role": blk.points.role[pb.point_ids], "rays": blk.rays()[pb.point_ids],
        "X": result.xyz[:, 0], "Y": result.xyz[:, 1], "Z": result.xyz[:, 2],
        "sigma_X": std[:, 0], "sigma_Y": std[:, 1], "sigma_Z": std[:, 2]})


def photo_table(block: Block, qc: Assessment[BundleResult], rc: RowClasses) -> pd.DataFrame:
    """Per photo: measurements, distinct points, half coverage, weakest sqrt(qvv)."""
    m, q = cast(BundleModel, qc.model), qc.quality
    n = len(block.photos)
    im = block.image
    img = m.image_row >= 0
    ph = im.photo[m.image_row[img]]
    sq = np.sqrt(np.clip(q.redundancy_number[img], 0, None))
    tested = sq > 0.0
    weakest = np.full(n, np.inf)
    np.minimum.at(weakest, ph[tested], sq[tested])
    mean = np.bincount(ph, sq, minlength=n) / np.maximum(np.bincount(ph, minlength=n), 1)
    distinct = points_per_photo(block)
    return pd.DataFrame({
        "photo": block.photos.ids, "strip": block.photos.strip,
        "X0": block.photos.eo[:, 0], "Y0": block.photos.eo[:, 1],
        "measurements": np.bincount(im.photo, minlength=n), "points": distinct,
        "half_coverage": half_coverage_photos(block),
        "mean_sqrt_qvv": mean, "min_sqrt_qvv": np.where(np.isfinite(weakest), weakest, np.nan)})
