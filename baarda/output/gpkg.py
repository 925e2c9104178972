"""The block as a GeoPackage for GIS (QGIS): adjusted points, projection centres and
image-residual vectors, in the project's CRS (`baarda adjust --gpkg`).

Layers:
* `points` (Point Z): every adjusted ground point with role, standard deviations (m), rays
  and the differences to given coordinates (dX, dY, dZ);
* `projection_centres` (Point Z): every photo with strip, camera, attitude (the project's
  angle unit) and standard deviations;
* `image_residuals` (LineString): for every image point, a line from its ground point (X, Y)
  showing the image residual (vx, vy) as it lies on the ground: turned by the photo's
  rotation into the object frame, scaled by the photo's image scale (distance / c) and
  exaggerated by EXAGGERATION; with the residuals in µm, their w-tests and whether the
  component was rejected.
Without a CRS the coordinates are the local ones and the layers carry none.  Written with
pyogrio (GDAL's GeoPackage driver) and shapely for the geometries.

The accuracy statement on the check points (ASPRS Edition 2, as in summary.json and the
reports) goes into the GeoPackage's metadata tables as ISO 19157 data quality
(output/gpkg_metadata.py).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import cast

import numpy as np

from baarda.block.rotation import rotation_matrix
from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.bundle_result import BundleResult
from baarda.output.bundle_results import accuracy_of, photos_table, points_table, tables_in_crs
from baarda.output.gpkg_metadata import write_quality_metadata
from baarda.quality.assessment import Assessment

EXAGGERATION = 1000.0  # residual vectors on the ground, times this


def write_gpkg(path: str | Path, qc: Assessment[BundleResult],
               exaggeration: float = EXAGGERATION) -> Path:
    """Write the three layers and the accuracy metadata (module docstring) into the
    GeoPackage `path`."""
    import pyogrio.raw as ogr
    import shapely

    res = qc.adjustment
    block = res.block
    crs = block.settings.crs if block.frame is not None else None
    ph, pt = tables_in_crs(res) if block.frame is not None else (photos_table(res),
                                                                 points_table(res))
    path = Path(path)

    def write(layer: str, geometry, table, geometry_type: str, append: bool) -> None:
        cols = list(table.columns)
        values = [_column(table[c].to_numpy()) for c in cols]
        with warnings.catch_warnings():  # no CRS: local coordinates, said in the docstring
            warnings.filterwarnings("ignore", message="'crs' was not provided")
            ogr.write(str(path), shapely.to_wkb(geometry), values, cols, layer=layer,
                      driver="GPKG", geometry_type=geometry_type, crs=crs, append=append)

    write("points", shapely.points(pt[["X", "Y", "Z"]].to_numpy(float)), pt, "Point Z",
          False)
    write("projection_centres", shapely.points(ph[["X0", "Y0", "Z0"]].to_numpy(float)), ph,
          "Point Z", True)
    lines, table = _residual_vectors(qc, pt, exaggeration)
    write("image_residuals", lines, table, "LineString", True)
    write_quality_metadata(path, accuracy_of(res, pt))
    return path


def _column(a: np.ndarray) -> np.ndarray:
    """A field array pyogrio writes: strings as str, numbers as float, flags as int."""
    if a.dtype == object:
        return np.array(["" if v is None else str(v) for v in a], dtype=object)
    if a.dtype == bool:
        return a.astype(np.int32)
    return a


def _residual_vectors(qc: Assessment[BundleResult], pt, exaggeration: float):
    """Lines from each image point's ground point along its residual on the ground."""
    import pandas as pd
    import shapely

    res, m, q = qc.adjustment, cast(BundleModel, qc.model), qc.quality
    block = res.block
    img = np.flatnonzero(m.image_row >= 0)
    rows = m.image_row[img]
    xrows = img[m.component[img] == "x"]
    yrows = img[m.component[img] == "y"]
    # pair x and y of an image row
    by_row = {int(m.image_row[i]): i for i in yrows}
    pairs = [(i, by_row[int(m.image_row[i])]) for i in xrows if int(m.image_row[i]) in by_row]
    if not pairs:
        return shapely.linestrings(np.zeros((0, 2, 2))), pd.DataFrame()
    ix, iy = (np.array(a) for a in zip(*pairs, strict=True))
    rows = m.image_row[ix]
    im = block.image
    photo, point = im.photo[rows], im.point[rows]
    eo = res.eo[photo]
    xyz_local = res.points_xyz()[point]
    r = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])
    v = np.column_stack([m.residuals[ix], m.residuals[iy], np.zeros(len(ix))])  # mm
    scale = np.linalg.norm(xyz_local - eo[:, :3], axis=1) / block.cameras.focal_mm[
        block.photos.camera[photo]]  # m on the ground per mm in the image
    d = np.einsum("nij,nj->ni", r, v)[:, :2] * scale[:, None] * exaggeration
    ids = np.asarray(block.points.ids, dtype=object)
    ground = pt.set_index("point")[["X", "Y"]].loc[ids[point]].to_numpy(float)
    start = ground
    lines = shapely.linestrings(np.stack([start, start + d], axis=1))
    table = pd.DataFrame({
        "photo": np.asarray(block.photos.ids, dtype=object)[photo], "point": ids[point],
        "vx_um": m.residuals[ix] * 1e3, "vy_um": m.residuals[iy] * 1e3,
        "w_x": q.w[ix], "w_y": q.w[iy], "rejected": ~(q.active[ix] & q.active[iy]),
        "exaggeration": np.full(len(ix), exaggeration)})
    return lines, table
