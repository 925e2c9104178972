"""The bundle adjustment as an AdjustedModel for the quality layer.

Observation vector: x and y of every adjusted image point (rows of BundleProblem.obs, in
mm), then every observed control coordinate (m) (BundleProblem.layout).  Rejected
components stay in the vector with active = False: they are predicted and tested, not
adjusted.
"""

from __future__ import annotations

import numpy as np

from baarda.adjustment.schur_model import SchurModel
from baarda.bundle.bundle_result import BundleResult
from baarda.quality.adjusted_model import kind_groups


class BundleModel(SchurModel):
    """The quality layer's view of a BundleResult; labels come from its problem."""

    frame_kind = "photo"

    def __init__(self, result: BundleResult):
        self.result = result
        pb = result.problem
        self.units = pb.units  # every kind as shown (IMU in the project's angle unit)
        self.factor, self.layout = result.factor, pb.layout
        self.residuals = self.layout.flat(result.image_residuals,
                                          np.nan_to_num(result.control_residuals),
                                          result.extra_residuals)
        self.sigma_apriori, self.factors, self.active = pb.sigma_apriori, pb.factors, pb.active
        self.n_unknowns = pb.system.n_unknowns
        self.kind, self.component, self.frame = pb.kind, pb.component, pb.frame
        self.point, self.group = pb.point, pb.group
        self.image_row, self.control_index = pb.image_row, pb.control_index

    def refit(self, active: np.ndarray, factors: np.ndarray | None = None) -> BundleModel:
        return BundleModel(self.result.refit(active, factors))

    def image_xy(self) -> np.ndarray:
        xy = np.full((self.n, 2), np.nan)
        img = self.image_row >= 0
        xy[img] = self.result.block.image.xy_mm[self.image_row[img]]
        return xy

    def variance_groups(self) -> np.ndarray:
        """(n,) the group of every component for variance-component estimation: image per
        camera, control X, Y, Z, GNSS X, Y, Z, IMU, distances."""
        pb = self.result.problem
        block = pb.block
        out = kind_groups(self.kind, self.component)
        if len(block.cameras) > 1:
            img = self.image_row >= 0
            cams = np.asarray(block.cameras.ids, dtype=object)
            cam = cams[block.photos.camera[block.image.photo[self.image_row[img]]]]
            out[img] = "image camera " + cam
        return out

    def other_cofactor_blocks(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The GNSS positions of the photos, X, Y, Z together (a 3D test of each)."""
        pb = self.result.problem
        n = pb.gnss_imu.n_gnss
        if not n:
            return []
        lay = self.layout
        first = lay.m * lay.k + len(lay.ctrl_sel)  # the first extra row in the flat vector
        start = pb.extra_range["gnss_imu"].start  # GNSS rows: the extra rows of that kind
        rows = start + np.arange(3 * n).reshape(n, 3)
        return [(first + rows, self.factor.extra_cofactor_blocks(rows))]

    def point_effect(self) -> tuple[np.ndarray, np.ndarray]:
        """Effect of a unit error of each component on its point (d = 3); a GNSS or IMU
        component's on the projection centre of its photo (labelled "photo P")."""
        effect, labels = self.point_effect_rows(), self.point
        pb, lin = self.result.problem, self.factor.lin
        gi = pb.gnss_imu
        if not gi.m:
            return effect, labels
        lay = self.layout
        rows = pb.extra_range["gnss_imu"].start + np.arange(gi.m)  # their extra rows
        flat = lay.m * lay.k + len(lay.ctrl_sel) + rows
        f = gi.photos
        assert lin.jxf is not None and lin.wx is not None
        jxf = lin.jxf[rows, 0, :]
        e = np.einsum("mab,mb->ma", self.factor.frame_covariance()[f], jxf)
        if pb.system.ng:
            assert lin.jxg is not None
            e += np.einsum("mag,mg->ma", self.factor.frame_global_covariance()[f],
                           lin.jxg[rows, 0, :])
        effect = effect.copy()
        effect[flat] = e[:, :3] * lin.wx[rows, 0][:, None]
        labels = np.array(labels, dtype=object)
        labels[flat] = ["photo " + p for p in np.asarray(pb.block.photos.ids, dtype=object)[f]]
        return effect, labels
