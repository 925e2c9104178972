"""An independent-model adjustment as an AdjustedModel for the quality layer.

Observation vector: the k components of every model row of the adjustment (model
coordinates, mm; decorrelated components when a full covariance was given), then every
observed control component (m).  Rejected components stay in the vector with active =
False: they are predicted and tested, not adjusted.
"""

from __future__ import annotations

import numpy as np

from baarda.adjustment.schur_model import SchurModel
from baarda.independent.model_problem import COMPONENTS, CORRELATED
from baarda.independent.model_result import ModelResult


class IndependentModel(SchurModel):
    def __init__(self, result: ModelResult):
        self.result = result
        pb = result.problem
        bl = pb.block
        self.problem, self.system, self.lin = pb, pb.system, result.lin
        m, k = len(pb.rows), pb.k
        self.m, self.k, self.kc, self.n_control = m, k, k, len(pb.control)
        sig_c = np.where(pb.wc_full > 0, 1.0 / np.sqrt(np.where(pb.wc_full > 0, pb.wc_full, 1)),
                         np.nan)
        self.ctrl_sel = np.flatnonzero(np.isfinite(sig_c).ravel())  # into (nc * k)
        nc = len(self.ctrl_sel)
        self.residuals = np.concatenate([result.model_residuals.ravel(),
                                         result.control_residuals.ravel()[self.ctrl_sel]])
        self.sigma = np.concatenate([pb.sigma_obs.ravel(), sig_c.ravel()[self.ctrl_sel]])
        keep = pb.obs_keep[pb.rows][:, pb.comps].ravel()
        keep_c = pb.control_keep[pb.control][:, pb.comps].ravel()[self.ctrl_sel]
        self.active = np.concatenate([keep, keep_c])
        self.n_unknowns = pb.system.n_unknowns
        models = np.asarray(bl.models, dtype=object)
        pids = np.asarray(bl.points, dtype=object)
        names = CORRELATED[pb.mode] if pb.transform is not None else COMPONENTS[pb.mode]
        upper = np.array(["X", "Y", "Z"], dtype=object)[pb.comps]
        self.kind = np.array(["model"] * (m * k) + ["control"] * nc, dtype=object)
        self.component = np.concatenate([np.tile(np.array(names, dtype=object), m),
                                         np.tile(upper, len(pb.control))[self.ctrl_sel]])
        self.frame = np.concatenate([np.repeat(models[pb.frame], k),
                                     np.full(nc, "", dtype=object)])
        self.point = np.concatenate([np.repeat(pids[bl.obs_point[pb.rows]], k),
                                     np.repeat(pids[pb.control], k)[self.ctrl_sel]])
        self.group = np.concatenate([np.repeat(np.arange(m), k), np.full(nc, -1)])
        # back into the block tables: model row (or -1), control point (or -1), xyz column
        self.block_row = np.concatenate([np.repeat(pb.rows, k), np.full(nc, -1)])
        self.block_point = np.concatenate([np.full(m * k, -1),
                                           np.repeat(pb.control, k)[self.ctrl_sel]])
        self.xyz_col = np.concatenate([np.tile(pb.comps, m),
                                       np.tile(pb.comps, len(pb.control))[self.ctrl_sel]])
        # terrain units per observation unit (model: m per mm = 1 / mu of the model)
        mu = (result.params[:, -1] if pb.mode != "height" else pb.mu)[pb.frame]
        self.terrain_per_unit = np.concatenate([np.repeat(1.0 / mu, k), np.ones(nc)])

    def unit_effect(self, index: np.ndarray):
        """N^-1 A^T P e_i for the components `index` (cheaper than parameter_effect with unit
        columns: A^T P e_i is one weighted row of A, nonzero in one frame and one point)."""
        pb, lin = self.problem, self.lin
        q = len(index)
        gf = np.zeros((pb.system.nf, pb.b, q))
        gp = np.zeros((pb.system.np, pb.d, q))
        col = np.arange(q)
        mod = index < self.m * self.k
        r, c = np.divmod(index[mod], self.k)
        wt = lin.w[r, c]
        gf[pb.frame[r], :, col[mod]] = lin.jf[r, c] * wt[:, None]
        pts = pb.remap[pb.block.obs_point[pb.rows[r]]]
        gp[pts, :, col[mod]] = lin.jp[r, c] * wt[:, None]
        flat_c = self.ctrl_sel[index[~mod] - self.m * self.k]
        ci, cc = np.divmod(flat_c, self.k)
        gp[pb.remap[pb.control[ci]], :, col[~mod]] = lin.jc[ci, cc] * lin.wc[ci, cc][:, None]
        self.system.ensure(self.lin)
        return self.system.solve_normal(gf, gp)

    def point_effect(self) -> tuple[np.ndarray, np.ndarray]:
        out = np.zeros((self.n, 3))
        out[:, self.problem.comps] = self.point_effect_rows()
        return out, self.point
