"""Results of a block adjusted in a local frame, written in the CRS of its input."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block
from baarda.block.rotation import rad_to_angle
from baarda.io.crs import LocalFrame
from baarda.output.atomic import write_text
from baarda.output.bundle_results import photos_table, points_table, write_results
from baarda.output.tables import csv_text


def tables_in_crs(result, frame: LocalFrame, block: Block):
    """photos.csv and points.csv tables of a result adjusted in `frame`, in the CRS.

    block: the block as read (CRS coordinates), for the given coordinates of control and
    check points.  Point standard deviations are propagated with the full covariance
    blocks; those of positions of photos likewise; angle standard deviations as adjusted.
    """
    ph = photos_table(result)
    eo = frame.eo_from_local(result.eo)
    unit = result.block.settings.angle_unit
    ang = rad_to_angle(eo[:, 3:], unit)
    s2 = result.sigma0**2
    result.problem.system.ensure(result.lin)
    cf = result.problem.system.frame_covariance()[:, :3, :3] * s2
    sf = np.sqrt(np.maximum(np.diagonal(frame.covariance_from_local(result.eo[:, :3], cf),
                                        axis1=1, axis2=2), 0))
    for k, c in enumerate(("X0", "Y0", "Z0")):
        ph[c] = eo[:, k]
        ph[f"sigma_{c}"] = sf[:, k]
    for k, c in enumerate(("omega", "phi", "kappa")):
        ph[c] = ang[:, k]
    pt = points_table(result)
    xyz = frame.from_local(result.xyz)
    cp = result.problem.system.point_covariance() * s2
    sp = np.sqrt(np.maximum(np.diagonal(frame.covariance_from_local(result.xyz, cp),
                                        axis1=1, axis2=2), 0))
    given = block.points.xyz[result.problem.point_ids]
    role = block.points.role[result.problem.point_ids]
    for k, c in enumerate("XYZ"):
        pt[c] = xyz[:, k]
        pt[f"sigma_{c}"] = sp[:, k]
        pt[f"d{c}"] = np.where(role != "tie", xyz[:, k] - given[:, k], np.nan)
    return ph, pt


def write_results_crs(out, result, quality, frame: LocalFrame, block: Block) -> list:
    """write_results, with photos.csv and points.csv in the CRS of the input (the local
    frame's tables are kept as photos_local.csv and points_local.csv)."""
    out = Path(out)
    paths = write_results(out, result, quality)
    write_text(out / "photos_local.csv", csv_text(photos_table(result)))
    write_text(out / "points_local.csv", csv_text(points_table(result)))
    ph, pt = tables_in_crs(result, frame, block)
    write_text(out / "photos.csv", csv_text(ph))
    write_text(out / "points.csv", csv_text(pt))
    return paths + [out / "photos_local.csv", out / "points_local.csv"]
