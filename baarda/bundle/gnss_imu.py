"""GNSS positions and IMU attitudes of the photos as observations of the bundle.

GNSS (m, ground frame): the antenna of photo i is observed,

    X_gnss,i = X0_i + R_i l + s_g(i) + d_s(i) t_i,

l the lever arm (Settings.gnss_lever_arm, camera frame, m), s_g a shift per block or per
strip (Settings.gnss_offsets), d_s a linear drift of strip s in m per km (Settings.gnss_drift)
with t_i the signed distance in km of photo i's approximate projection centre from the middle
of its strip along the strip (fixed when the problem is formed).

IMU (rad): the attitude of the IMU, the camera's turned by the boresight misalignment b
(Settings.imu_boresight: held at zero or estimated), is observed,

    (omega, phi, kappa)_imu,i = angles(R(omega_i, phi_i, kappa_i) R(b)),

with angles() the inverse of block/rotation.rotation_matrix.  Shifts, drifts and boresight
angles are global unknowns of the Schur system (adjustment/schur_system.py): a few columns, never a
dense matrix that grows with the block.  Every observation row depends on one photo only.
"""

from __future__ import annotations

import numpy as np

from baarda.block.photo_block import GNSS_OFFSETS as OFFSETS  # noqa: F401
from baarda.block.photo_block import IMU_BORESIGHT as BORESIGHT  # noqa: F401
from baarda.block.photo_block import Block
from baarda.block.rotation import angles_from_matrix, rotation_and_derivatives
from baarda.kinds import GNSS, IMU

COMPONENTS_GNSS = GNSS.components
COMPONENTS_IMU = IMU.components


def wrap(a: np.ndarray) -> np.ndarray:
    """Angles into (-pi, pi]."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def angle_derivatives(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3, 3): d (omega, phi, kappa) / d M_jk of angles_from_matrix at M."""
    out = np.zeros(m.shape[:-2] + (3, 3, 3))
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m12, m22 = m[..., 1, 2], m[..., 2, 2]
    a = m12**2 + m22**2  # omega = atan2(-M12, M22)
    out[..., 0, 1, 2] = -m22 / a
    out[..., 0, 2, 2] = m12 / a
    out[..., 1, 0, 2] = 1.0 / np.sqrt(np.maximum(1.0 - m02**2, 1e-300))  # phi = asin(M02)
    k = m00**2 + m01**2  # kappa = atan2(-M01, M00)
    out[..., 2, 0, 0] = m01 / k
    out[..., 2, 0, 1] = -m00 / k
    return out


def attitude(angles: np.ndarray, boresight: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """angles(R(a) R(b)) (k, 3) and its derivatives w.r.t. a (k, 3, 3) and b (k, 3, 3)."""
    r, *dr = rotation_and_derivatives(angles[:, 0], angles[:, 1], angles[:, 2])
    rb, *drb = rotation_and_derivatives(*np.asarray(boresight, float))
    m = r @ rb
    dm = angle_derivatives(m)
    da = np.stack([np.einsum("kajl,kjl->ka", dm, d @ rb) for d in dr], axis=2)
    db = np.stack([np.einsum("kajl,kjl->ka", dm, r @ d) for d in drb], axis=2)
    return angles_from_matrix(m), da, db


class GnssImu:
    """The GNSS and IMU observations of a block in the form of the adjustment.

    `first` is the first global column of their unknowns (after the camera parameters and
    the border points); `n` the number of them: shifts (3 per group), drifts (3 per strip),
    boresight (3).  `photos` (mx,) the photo of each observation row, rows ordered GNSS
    X, Y, Z of every position, then IMU omega, phi, kappa of every attitude."""

    def __init__(self, block: Block, first: int):
        s = block.settings
        gnss, imu = block.gnss, block.imu
        self.lever = np.asarray(s.gnss_lever_arm, float)
        self.n_gnss, self.n_imu = len(gnss), len(imu)
        strips = np.asarray([str(x) for x in block.photos.strip], dtype=object)
        labels = sorted(set(strips[gnss.photo].tolist())) if self.n_gnss else []
        self.first = first
        col = first
        # shifts
        self.offset_col = np.full(len(block.photos), -1)
        self.labels: list[str] = []
        if self.n_gnss and s.gnss_offsets == "block":
            self.offset_col[:] = col
            self.labels += [f"GNSS shift {c} of the block" for c in "XYZ"]
            col += 3
        elif self.n_gnss and s.gnss_offsets == "strip":
            for lab in labels:
                self.offset_col[strips == lab] = col
                self.labels += [f"GNSS shift {c} of strip {lab}" for c in "XYZ"]
                col += 3
        self.offset_groups = (["block"] if s.gnss_offsets == "block" else
                              labels if s.gnss_offsets == "strip" else [])
        # drifts along the strip
        self.drift_col = np.full(len(block.photos), -1)
        self.along_km = np.zeros(len(block.photos))
        self.drift_groups: list[str] = []
        if self.n_gnss and s.gnss_drift:
            eo = block.photos.eo
            start = np.where(np.isfinite(eo[:, :3]).all(axis=1)[:, None], eo[:, :3], np.nan)
            at = np.full((len(block.photos), 3), np.nan)
            at[gnss.photo] = gnss.xyz
            start = np.where(np.isfinite(start), start, at)
            for lab in labels:
                sel = np.flatnonzero(strips == lab)
                xy = start[sel, :2]
                ok = np.isfinite(xy).all(axis=1)
                centre = xy[ok].mean(axis=0)
                d = xy[ok] - centre
                u = np.linalg.svd(d, full_matrices=False)[2][0] if len(d) > 1 else \
                    np.array([1.0, 0.0])
                along = np.zeros(len(sel))
                along[ok] = d @ u / 1000.0
                self.along_km[sel] = along
                self.drift_col[sel] = col
                self.drift_groups.append(lab)
                self.labels += [f"GNSS drift {c} of strip {lab} (m/km)" for c in "XYZ"]
                col += 3
        # boresight
        self.boresight_col = -1
        if self.n_imu and s.imu_boresight == "estimated":
            self.boresight_col = col
            self.labels += [f"IMU boresight {a}" for a in COMPONENTS_IMU]
            col += 3
        self.n = col - first
        self.photos = np.concatenate([np.repeat(gnss.photo, 3), np.repeat(imu.photo, 3)])
        self.kind = np.array([GNSS.name] * (3 * self.n_gnss) + [IMU.name] * (3 * self.n_imu),
                             dtype=object)
        self.component = np.concatenate([np.tile(np.array(COMPONENTS_GNSS, dtype=object),
                                                 self.n_gnss),
                                         np.tile(np.array(COMPONENTS_IMU, dtype=object),
                                                 self.n_imu)]) if len(self.kind) else \
            np.zeros(0, dtype=object)
        self.sigma = np.concatenate([gnss.sigma.ravel(), imu.sigma.ravel()])
        self.gnss, self.imu = gnss, imu

    @property
    def m(self) -> int:
        return 3 * (self.n_gnss + self.n_imu)

    def boresight(self, g: np.ndarray) -> np.ndarray:
        return g[self.boresight_col:self.boresight_col + 3] if self.boresight_col >= 0 \
            else np.zeros(3)

    def rows(self, eo: np.ndarray, g: np.ndarray, ng: int, rotations: tuple | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Misclosures e = observed - predicted (mx,), jxf (mx, 1, 6), jxg (mx, 1, ng);
        rotations: rotation_and_derivatives of every photo's angles, when known."""
        k, q = self.n_gnss, self.n_imu
        e = np.zeros(self.m)
        jxf = np.zeros((self.m, 1, 6))
        jxg = np.zeros((self.m, 1, ng))
        if k:
            p = self.gnss.photo
            r, *dr = (rotation_and_derivatives(eo[p, 3], eo[p, 4], eo[p, 5])
                      if rotations is None else (a[p] for a in rotations))
            pred = eo[p, :3] + r @ self.lever
            jf = np.zeros((k, 3, 6))
            jf[:, :, :3] = np.eye(3)
            for a in range(3):
                jf[:, :, 3 + a] = dr[a] @ self.lever
            jg = np.zeros((k, 3, ng))
            oc = self.offset_col[p]
            has = oc >= 0
            for c in range(3):
                jg[np.flatnonzero(has), c, oc[has] + c] = 1.0
                if has.any():
                    pred[has, c] += g[oc[has] + c]
            dc = self.drift_col[p]
            has = dc >= 0
            t = self.along_km[p]
            for c in range(3):
                jg[np.flatnonzero(has), c, dc[has] + c] = t[has]
                if has.any():
                    pred[has, c] += g[dc[has] + c] * t[has]
            e[:3 * k] = (self.gnss.xyz - pred).ravel()
            jxf[:3 * k, 0] = jf.reshape(3 * k, 6)
            jxg[:3 * k, 0] = jg.reshape(3 * k, ng)
        if q:
            p = self.imu.photo
            pred, da, db = attitude(eo[p, 3:], self.boresight(g))
            e[3 * k:] = wrap(self.imu.angles - pred).ravel()
            jf = np.zeros((q, 3, 6))
            jf[:, :, 3:] = da
            jxf[3 * k:, 0] = jf.reshape(3 * q, 6)
            if self.boresight_col >= 0:
                jg = np.zeros((q, 3, ng))
                jg[:, :, self.boresight_col:self.boresight_col + 3] = db
                jxg[3 * k:, 0] = jg.reshape(3 * q, ng)
        return e, jxf, jxg

    def parameter_groups(self) -> list[tuple[str, np.ndarray]]:
        """(name, global columns) of each group of GNSS/IMU unknowns for the hypothesis
        tests: every shift group, every drift, the boresight."""
        out = []
        cols = np.unique(self.offset_col[self.offset_col >= 0])  # in the order of the groups
        for lab, c in zip(self.offset_groups, cols, strict=True):
            name = "the block" if lab == "block" else f"strip {lab}"
            out.append((f"GNSS shift of {name}", int(c) + np.arange(3)))
        cols = np.unique(self.drift_col[self.drift_col >= 0])
        for lab, c in zip(self.drift_groups, cols, strict=True):
            out.append((f"GNSS drift of strip {lab}", int(c) + np.arange(3)))
        if self.boresight_col >= 0:
            out.append(("IMU boresight", self.boresight_col + np.arange(3)))
        return out
