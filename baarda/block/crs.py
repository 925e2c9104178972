"""Ground coordinates in a geographic or projected CRS: adjust in a local Cartesian frame.

A `LocalFrame` is the east-north-up frame tangent to the ellipsoid at an origin (the mean of
the ground points).  Coordinates of the CRS go to the CRS's own geodetic coordinates with
pyproj (no datum change), from there to earth-centred Cartesian coordinates on the same
ellipsoid and into the tangent frame; the way back inverts each step.  In that frame the
collinearity equations hold without map-projection scale or earth-curvature corrections.

* Heights of a 2D CRS are taken as ellipsoidal heights (``CRS.to_3d()``).  Compound CRSs
  with a vertical datum are refused: they need a geoid model (a constant geoid undulation
  would only shift the block).
* Exterior orientation: positions are converted as points; the rotation of a photo refers
  to the axes of the CRS at the projection centre (grid east, grid north, up for a
  projected CRS; local east, north, up for a geographic one).  The rotation between those
  axes and the local frame is the orthonormal polar factor of the Jacobian of the mapping
  (metric units), so R_crs = Q R_local.
* Results: coordinates back in the CRS; covariances of points propagated with the same
  Jacobian; angle standard deviations are those of the local frame.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError

from baarda.block.photo_block import Block
from baarda.block.rotation import angles_from_matrix, rotation_matrix
from baarda.errors import ProjectError


def _polar(j: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(j)
    return u @ vt


class LocalFrame:
    """Tangent east-north-up frame at `origin` (given in the CRS) for the CRS `crs`."""

    def __init__(self, crs: str | CRS, origin: np.ndarray):
        try:
            self.crs = CRS.from_user_input(crs)
        except CRSError as e:
            raise ProjectError(str(crs), f"not a coordinate reference system: {e}") from None
        if self.crs.is_compound or self.crs.is_vertical:
            raise ProjectError(str(crs), "compound/vertical CRS: heights must be ellipsoidal "
                               "(give the horizontal CRS; a geoid model is not applied)")
        if not (self.crs.is_geographic or self.crs.is_projected):
            raise ProjectError(str(crs), "the CRS must be geographic or projected")
        self.crs3 = self.crs.to_3d()
        assert self.crs.geodetic_crs is not None and self.crs.ellipsoid is not None
        geod = self.crs.geodetic_crs.to_3d()
        info = geod.axis_info
        self.angle = info[0].unit_conversion_factor  # radians per angle unit
        self.geographic = self.crs.is_geographic
        self._fwd = Transformer.from_crs(self.crs3, geod, always_xy=True)
        self._inv = Transformer.from_crs(geod, self.crs3, always_xy=True)
        ell = self.crs.ellipsoid
        self.a = ell.semi_major_metre
        inv_f = ell.inverse_flattening
        self.e2 = 0.0 if not np.isfinite(inv_f) or inv_f == 0 else (2 - 1 / inv_f) / inv_f
        o = np.asarray(origin, float)
        self.origin_ecef = self._ecef(o[None])[0]
        lon, lat, _ = self._geodetic(o[None])
        sl, cl = np.sin(lon[0]), np.cos(lon[0])
        sp, cp = np.sin(lat[0]), np.cos(lat[0])
        self.rot = np.array([[-sl, cl, 0.0], [-sp * cl, -sp * sl, cp], [cp * cl, cp * sl, sp]])

    # ------------------------------------------------------------ points
    def _geodetic(self, xyz: np.ndarray):
        lon, lat, h = self._fwd.transform(xyz[:, 0], xyz[:, 1], xyz[:, 2], errcheck=True)
        return (np.asarray(lon) * self.angle, np.asarray(lat) * self.angle, np.asarray(h))

    def _ecef(self, xyz: np.ndarray) -> np.ndarray:
        lon, lat, h = self._geodetic(xyz)
        n = self.a / np.sqrt(1 - self.e2 * np.sin(lat) ** 2)
        return np.column_stack([(n + h) * np.cos(lat) * np.cos(lon),
                                (n + h) * np.cos(lat) * np.sin(lon),
                                (n * (1 - self.e2) + h) * np.sin(lat)])

    def _from_ecef(self, ecef: np.ndarray) -> np.ndarray:
        x, y, z = ecef.T
        lon = np.arctan2(y, x)
        p = np.hypot(x, y)
        lat = np.arctan2(z, p * (1 - self.e2))
        for _ in range(10):
            n = self.a / np.sqrt(1 - self.e2 * np.sin(lat) ** 2)
            h = p / np.cos(lat) - n
            lat = np.arctan2(z, p * (1 - self.e2 * n / (n + h)))
        n = self.a / np.sqrt(1 - self.e2 * np.sin(lat) ** 2)
        h = np.where(np.abs(np.cos(lat)) > 1e-9, p / np.cos(lat) - n,
                     np.abs(z) - n * (1 - self.e2))
        out = self._inv.transform(lon / self.angle, lat / self.angle, h, errcheck=True)
        return np.column_stack(out)

    def to_local(self, xyz: np.ndarray) -> np.ndarray:
        """CRS coordinates (n, 3) -> local east, north, up [m]."""
        xyz = np.atleast_2d(np.asarray(xyz, float))
        out = np.full(xyz.shape, np.nan)
        ok = np.isfinite(xyz).all(axis=1)
        out[ok] = (self._ecef(xyz[ok]) - self.origin_ecef) @ self.rot.T
        return out

    def from_local(self, xyz: np.ndarray) -> np.ndarray:
        """Local east, north, up (n, 3) [m] -> CRS coordinates."""
        xyz = np.atleast_2d(np.asarray(xyz, float))
        out = np.full(xyz.shape, np.nan)
        ok = np.isfinite(xyz).all(axis=1)
        out[ok] = self._from_ecef(xyz[ok] @ self.rot + self.origin_ecef)
        return out

    # ----------------------------------------------------- axes and Jacobians
    def jacobian(self, xyz_local: np.ndarray, h: float = 1.0) -> np.ndarray:
        """d(CRS, metric) / d(local) at points (n, 3): (n, 3, 3), by central differences.

        For a geographic CRS the longitude and latitude rows are turned into metres along
        the parallel and the meridian."""
        xyz_local = np.atleast_2d(xyz_local)
        cols = []
        for k in range(3):
            e = np.zeros(3)
            e[k] = h
            cols.append((self.from_local(xyz_local + e) - self.from_local(xyz_local - e))
                        / (2 * h))
        j = np.stack(cols, axis=-1)
        if self.geographic:
            c = self.from_local(xyz_local)
            lat = c[:, 1] * self.angle
            n = self.a / np.sqrt(1 - self.e2 * np.sin(lat) ** 2)
            m = n * (1 - self.e2) / (1 - self.e2 * np.sin(lat) ** 2)
            j[:, 0] *= ((n + c[:, 2]) * np.cos(lat) * self.angle)[:, None]
            j[:, 1] *= ((m + c[:, 2]) * self.angle)[:, None]
        return j

    def axes(self, xyz_local: np.ndarray) -> np.ndarray:
        """Rotations Q (n, 3, 3) from local axes to the CRS axes at the points."""
        return np.array([_polar(j) for j in self.jacobian(xyz_local)])

    def eo_to_local(self, eo: np.ndarray) -> np.ndarray:
        pos = self.to_local(eo[:, :3])
        q = self.axes(pos)
        r = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])
        return np.column_stack([pos, angles_from_matrix(np.swapaxes(q, 1, 2) @ r)])

    def eo_from_local(self, eo: np.ndarray) -> np.ndarray:
        q = self.axes(eo[:, :3])
        r = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])
        return np.column_stack([self.from_local(eo[:, :3]), angles_from_matrix(q @ r)])

    def covariance_from_local(self, xyz_local: np.ndarray, cov: np.ndarray) -> np.ndarray:
        """Covariances (n, 3, 3) of local coordinates -> of CRS coordinates (metric)."""
        j = self.jacobian(xyz_local)
        return j @ cov @ np.swapaxes(j, 1, 2)


def localize(block: Block, crs: str | None = None) -> Block:
    """The block with ground coordinates and EO in a local frame of its CRS (block.frame).

    crs: overrides block.settings.crs.  The origin is the mean of the ground points with
    coordinates (else of the projection centres).  Sigmas of control points are kept (the
    frame is conformal up to the map scale factor).
    """
    crs = crs or block.settings.crs
    if not crs:
        raise ProjectError(block.source or block.settings.name, "no CRS given")
    pts = block.points
    known = np.isfinite(pts.xyz).all(axis=1)
    base = pts.xyz[known] if known.any() else block.photos.eo[:, :3]
    base = base[np.isfinite(base).all(axis=1)]
    if not len(base):
        raise ProjectError(block.source or block.settings.name, "no coordinates to place the "
                           "local frame")
    _check_geographic(crs, block)
    frame = LocalFrame(crs, base.mean(axis=0))
    xyz = frame.to_local(pts.xyz)
    part = np.isfinite(pts.xyz).any(axis=1) & ~known
    if part.any():
        raise ProjectError(block.source, f"point {pts.ids[int(np.flatnonzero(part)[0])]}: a "
                           "control point in a CRS needs all three coordinates")
    eo = block.photos.eo
    ok = np.isfinite(eo).all(axis=1)
    eo_l = np.full(eo.shape, np.nan)
    if ok.any():
        eo_l[ok] = frame.eo_to_local(eo[ok])
    photos = replace(block.photos, eo=eo_l)
    points = replace(pts, xyz=xyz)
    notes = list(block.notes) + [f"adjusted in a local east-north-up frame of {frame.crs.name} "
                                 "(heights ellipsoidal); results converted back"]
    gnss, imu = block.gnss, block.imu
    if len(gnss):
        gnss = replace(gnss, xyz=frame.to_local(gnss.xyz))
    if len(imu):  # attitudes turn with the frame at the photo's place
        where = eo[imu.photo, :3]
        if len(block.gnss):
            at = np.full((len(eo), 3), np.nan)
            at[block.gnss.photo] = block.gnss.xyz
            where = np.where(np.isfinite(where), where, at[imu.photo])
        where = np.where(np.isfinite(where), where, base.mean(axis=0))
        imu = replace(imu, angles=frame.eo_to_local(np.column_stack([where, imu.angles]))[:, 3:])
    return replace(block, photos=photos, points=points, notes=notes, frame=frame, gnss=gnss,
                   imu=imu)


def _check_geographic(crs: str, block: Block) -> None:
    """ProjectError when a geographic CRS is given for coordinates that are not longitude
    and latitude (metric coordinates under crs = "EPSG:4326" ended in a generic 'the
    approximations do not fit'), naming the first point or photo outside the ranges."""
    try:
        c = CRS.from_user_input(crs)
    except CRSError:
        return  # LocalFrame names the CRS that is not one
    if not c.is_geographic:
        return
    unit = c.axis_info[0].unit_conversion_factor  # radians per angle unit
    lon_max, lat_max = np.pi / unit, np.pi / 2 / unit
    pts, ph = block.points, block.photos
    for what, ids, xy in (("point", pts.ids, pts.xyz[:, :2]),
                          ("photo", ph.ids, ph.eo[:, :2])):
        bad = np.flatnonzero(np.isfinite(xy).all(axis=1) & ((np.abs(xy[:, 0]) > lon_max) |
                                                            (np.abs(xy[:, 1]) > lat_max)))
        if len(bad):
            k = int(bad[0])
            src = Path(block.source) if block.source else None
            toml = src / "project.toml" if src is not None and src.is_dir() else None
            where = str(toml) if toml is not None and toml.is_file() else \
                (block.source or block.settings.name)
            raise ProjectError(where, f"crs {crs} ({c.name}) is geographic: X and Y are "
                               f"longitude and latitude in {c.axis_info[0].unit_name}s, but "
                               f"{what} {ids[k]} has X {xy[k, 0]:.10g}, Y {xy[k, 1]:.10g} "
                               f"(outside +-{lon_max:g} and +-{lat_max:g}): give the CRS of "
                               "the coordinates (a projected CRS for metric coordinates, "
                               "e.g. EPSG:25832)", column="crs" if toml is not None else None)


def delocalize(block: Block) -> Block:
    """The inverse of `localize`: a block held in the local frame of its CRS (block.frame)
    with ground coordinates, EO, GNSS positions and IMU attitudes in the CRS again (frame
    None); a block without a frame is returned as it is.  Writers of CRS coordinates use it
    (a native project of an OpenSfM dataset)."""
    frame = block.frame
    if frame is None:
        return block
    pts = block.points
    xyz = np.where(np.isfinite(pts.xyz), 0.0, np.nan)
    full = np.isfinite(pts.xyz).all(axis=1)
    xyz[full] = frame.from_local(pts.xyz[full])
    eo = block.photos.eo
    ok = np.isfinite(eo).all(axis=1)
    eo_c = np.full(eo.shape, np.nan)
    if ok.any():
        eo_c[ok] = frame.eo_from_local(eo[ok])
    gnss, imu = block.gnss, block.imu
    if len(gnss):
        gnss = replace(gnss, xyz=frame.from_local(gnss.xyz))
    if len(imu):
        where = np.where(ok[imu.photo, None], eo[imu.photo, :3], 0.0)
        imu = replace(imu, angles=frame.eo_from_local(np.column_stack([where, imu.angles]))
                      [:, 3:])
    part = np.isfinite(pts.xyz).any(axis=1) & ~full  # e.g. planimetric: height 0 to place it
    if part.any():
        xyz[part] = np.where(np.isfinite(pts.xyz[part]), frame.from_local(
            np.nan_to_num(pts.xyz[part])), np.nan)
    return replace(block, photos=replace(block.photos, eo=eo_c),
                   points=replace(pts, xyz=xyz), frame=None, gnss=gnss, imu=imu,
                   notes=list(block.notes))
