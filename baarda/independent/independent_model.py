"""An independent-model adjustment as an AdjustedModel for the quality layer.

Observation vector: the k components of every model row of the adjustment (model
coordinates, mm; decorrelated components when a full covariance was given), then every
observed control component (m) (ModelProblem.layout).  Rejected components stay in the
vector with active = False: they are predicted and tested, not adjusted.
"""

from __future__ import annotations

import numpy as np

from baarda.adjustment.schur_model import SchurModel
from baarda.independent.model_result import ModelResult
from baarda.quality.adjusted_model import kind_groups


class IndependentModel(SchurModel):
    """The quality layer's view of a ModelResult; labels come from its problem."""

    units = {"model": (1e3, "µm"), "control": (1.0, "m")}
    frame_kind = "model"

    def __init__(self, result: ModelResult):
        self.result = result
        pb = result.problem
        self.problem, self.factor, self.layout, self.lin = pb, result.factor, pb.layout, result.lin
        self.m, self.k = pb.layout.m, pb.k
        self.residuals = self.layout.flat(result.model_residuals,
                                          np.nan_to_num(result.control_residuals))
        self.sigma_apriori, self.factors, self.active = pb.sigma_apriori, pb.factors, pb.active
        self.n_unknowns = pb.system.n_unknowns
        self.kind, self.component, self.frame = pb.kind, pb.component, pb.frame_label
        self.point, self.group = pb.point_label, pb.group
        self.block_row, self.block_point, self.xyz_col = pb.block_row, pb.block_point, pb.xyz_col
        # terrain units per observation unit (model: m per mm = 1 / mu of the model)
        mu = (result.params[:, -1] if pb.mode != "height" else pb.mu)[pb.frame]
        nc = len(pb.layout.ctrl_sel)
        self.terrain_per_unit = np.concatenate([np.repeat(1.0 / mu, self.k), np.ones(nc)])

    def variance_groups(self) -> np.ndarray:
        """(n,) the group of every component for variance-component estimation: model
        coordinates in planimetry ('model XY': x, y) and height ('model Z': z), the
        projection centres ('model PC', when observed), control X, Y, Z."""
        pb = self.problem
        out = kind_groups(self.kind, self.component)  # model XY, model Z, control X, Y, Z
        mod = np.asarray(self.kind, dtype=object) == "model"
        row = np.asarray(self.block_row)
        pc = np.zeros(self.n, bool)
        pc[row >= 0] = pb.block.pc[pb.block.obs_point[row[row >= 0]]]
        out[mod & pc] = "model PC"
        return out

    def refit(self, active: np.ndarray, factors: np.ndarray | None = None) -> IndependentModel:
        return IndependentModel(self.result.refit(active, factors))

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
        flat_c = self.layout.ctrl_sel[index[~mod] - self.m * self.k]
        ci, cc = np.divmod(flat_c, self.k)
        gp[pb.remap[pb.control[ci]], :, col[~mod]] = lin.jc[ci, cc] * lin.wc[ci, cc][:, None]
        return self.factor.solve_normal(gf, gp)

    def point_effect(self) -> tuple[np.ndarray, np.ndarray]:
        out = np.zeros((self.n, 3))
        out[:, self.problem.comps] = self.point_effect_rows()
        return out, self.point
