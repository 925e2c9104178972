"""The bundle adjustment as an AdjustedModel for the quality layer.

Observation vector: x and y of every adjusted image point (rows of BundleProblem.obs, in
mm), then every observed control coordinate (m).  Rejected components stay in the vector
with active = False: they are predicted and tested, not adjusted.
"""

from __future__ import annotations

import numpy as np

from baarda.bundle.result import BundleResult
from baarda.quality.model import AdjustedModel


class BundleModel(AdjustedModel):
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
        self.m = m
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

    # ------------------------------------------------------------- helpers
    def _split(self, h: np.ndarray):
        """Flat (n, q) -> image (m, 2, q) and control (nc, 3, q) arrays."""
        q = h.shape[1]
        hi = h[: 2 * self.m].reshape(self.m, 2, q)
        hc = np.zeros((len(self.result.problem.control) * 3, q))
        hc[self.ctrl_sel] = h[2 * self.m:]
        return hi, hc.reshape(-1, 3, q)

    def _flat(self, ri: np.ndarray, rc: np.ndarray) -> np.ndarray:
        q = ri.shape[-1]
        return np.concatenate([ri.reshape(2 * self.m, q), rc.reshape(-1, q)[self.ctrl_sel]])

    # ------------------------------------------------------------- interface
    def adjusted_cofactor_diag(self) -> np.ndarray:
        q, qc = self.system.adjusted_cofactors(self.lin)
        return np.concatenate([np.diagonal(q, axis1=1, axis2=2).ravel(),
                               np.diagonal(qc, axis1=1, axis2=2).ravel()[self.ctrl_sel]])

    def adjusted_cofactor_blocks(self) -> tuple[np.ndarray, np.ndarray]:
        q, _ = self.system.adjusted_cofactors(self.lin)
        return np.arange(2 * self.m).reshape(self.m, 2), q

    def normal_forward(self, h: np.ndarray) -> np.ndarray:
        hi, hc = self._split(h)
        self.system.ensure(self.lin)
        gf, gp = self.system.apply_AtP(self.lin, hi, hc)
        return self.system.forward(gf, gp)

    def solve_columns(self, h: np.ndarray) -> np.ndarray:
        hi, hc = self._split(h)
        self.system.ensure(self.lin)
        gf, gp = self.system.apply_AtP(self.lin, hi, hc)
        xf, xp = self.system.solve_normal(gf, gp)
        ri, rc = self.system.apply_A(self.lin, xf, xp)
        return self._flat(ri, rc)

    def point_effect(self) -> tuple[np.ndarray, np.ndarray]:
        g, gc = self.system.point_effect(self.lin)
        eff = np.concatenate([g.reshape(2 * self.m, 3), gc.reshape(-1, 3)[self.ctrl_sel]])
        return eff, self.point
