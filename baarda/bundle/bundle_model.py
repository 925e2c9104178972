"""The bundle adjustment as an AdjustedModel for the quality layer.

Observation vector: x and y of every adjusted image point (rows of BundleProblem.obs, in
mm), then every observed control coordinate (m).  Rejected components stay in the vector
with active = False: they are predicted and tested, not adjusted.
"""

from __future__ import annotations

import numpy as np

from baarda.adjustment.schur_model import SchurModel
from baarda.bundle.bundle_result import BundleResult


class BundleModel(SchurModel):
    def __init__(self, result: BundleResult):
        self.result = result
        pb = result.problem
        blk = result.block
        lin = result.lin
        self.system = pb.system
        self.lin = lin
        self.system.ensure(lin)  # the statistics need S factored at the solution
        m = len(pb.obs)
        im = blk.image
        sig_c = blk.points.sigma[pb.control]
        self.ctrl_sel = np.flatnonzero(np.isfinite(sig_c).ravel())  # into (nc*3)
        self.m, self.k, self.kc, self.n_control = m, 2, 3, len(pb.control)
        self.residuals = np.concatenate([result.image_residuals.ravel(),
                                         result.control_residuals.ravel()[self.ctrl_sel]])
        s_img = np.repeat(im.sigma_mm[pb.obs], 2)
        self.sigma_apriori = np.concatenate([s_img, sig_c.ravel()[self.ctrl_sel]])
        factor = np.concatenate([pb.image_factor[pb.obs].ravel(),
                                 pb.control_factor[pb.control].ravel()[self.ctrl_sel]])
        self.sigma = self.sigma_apriori / np.sqrt(factor)  # = a priori unless re-weighted
        keep_img = pb.image_keep[pb.obs].ravel()
        keep_c = pb.control_keep[pb.control].ravel()[self.ctrl_sel]
        self.active = np.concatenate([keep_img, keep_c])
        self.n_unknowns = pb.system.n_unknowns
        nc = len(self.ctrl_sel)
        photos = np.asarray(blk.photos.ids, dtype=object)
        pids = np.asarray(blk.points.ids, dtype=object)
        self.kind = np.array(["image"] * (2 * m) + ["control"] * nc, dtype=object)
        self.component = np.concatenate([np.tile(np.array(["x", "y"], dtype=object), m),
                                         np.tile(np.array(["X", "Y", "Z"], dtype=object),
                                                 len(pb.control))[self.ctrl_sel]])
        self.frame = np.concatenate([np.repeat(photos[im.photo[pb.obs]], 2),
                                     np.full(nc, "", dtype=object)])
        self.point = np.concatenate([np.repeat(pids[im.point[pb.obs]], 2),
                                     np.repeat(pids[pb.control], 3)[self.ctrl_sel]])
        self.group = np.concatenate([np.repeat(np.arange(m), 2), np.full(nc, -1)])
        # index of each component back into block tables
        self.image_row = np.concatenate([np.repeat(pb.obs, 2), np.full(nc, -1)])
        self.control_index = np.concatenate([np.full(2 * m, -1),
                                             np.repeat(pb.control, 3)[self.ctrl_sel]])

    def point_effect(self) -> tuple[np.ndarray, np.ndarray]:
        return self.point_effect_rows(), self.point
