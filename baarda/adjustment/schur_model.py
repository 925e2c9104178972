"""A model adjusted on a SchurSystem, seen by the quality layer as a flat observation vector.

The flat vector is: the k rows of every frame-point observation (image points, model
coordinates), then the observed rows of the point observations (control), selected by
`ctrl_sel` from their (n_control * kc) rows.  The bundle and the independent-model
adjustment describe their observations (labels, sigmas, residuals) in their subclasses;
the linear algebra they hand to baarda.quality is here, once.
"""

from __future__ import annotations

import numpy as np

from baarda.adjustment.schur import Linearization, SchurSystem
from baarda.quality.adjusted_model import AdjustedModel


class SchurModel(AdjustedModel):
    """Base of BundleModel and IndependentModel: the AdjustedModel services of a SchurSystem."""

    system: SchurSystem
    lin: Linearization
    m: int  # frame-point observations
    k: int  # rows of each
    kc: int  # rows of each point observation
    n_control: int  # point observations
    ctrl_sel: np.ndarray  # observed rows among the (n_control * kc) point-observation rows

    def split(self, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Flat (n, q) -> frame-point rows (m, k, q) and point-observation rows (nc, kc, q)."""
        q = h.shape[1]
        hm = h[: self.m * self.k].reshape(self.m, self.k, q)
        hc = np.zeros((self.n_control * self.kc, q))
        hc[self.ctrl_sel] = h[self.m * self.k:]
        return hm, hc.reshape(-1, self.kc, q)

    def flat(self, rm: np.ndarray, rc: np.ndarray) -> np.ndarray:
        """Inverse of split for (m, k, q) and (nc, kc, q) arrays."""
        q = rm.shape[-1]
        return np.concatenate([rm.reshape(self.m * self.k, q),
                               rc.reshape(-1, q)[self.ctrl_sel]])

    def parameter_effect(self, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """N^-1 A^T P H: changes of the frame (nf, b, q) and point (np, d, q) unknowns."""
        hm, hc = self.split(h)
        self.system.ensure(self.lin)
        gf, gp = self.system.apply_AtP(self.lin, hm, hc)
        return self.system.solve_normal(gf, gp)

    def _adjusted_cofactors(self) -> tuple[np.ndarray, np.ndarray]:
        """Blocks of A N^-1 A^T, computed once (statistics and grouped tests both need them)."""
        if getattr(self, "_qll", None) is None:
            self._qll = self.system.adjusted_cofactors(self.lin)
        return self._qll

    # ------------------------------------------------------------- interface
    def adjusted_cofactor_diag(self) -> np.ndarray:
        q, qc = self._adjusted_cofactors()
        return np.concatenate([np.diagonal(q, axis1=1, axis2=2).ravel(),
                               np.diagonal(qc, axis1=1, axis2=2).ravel()[self.ctrl_sel]])

    def adjusted_cofactor_blocks(self) -> tuple[np.ndarray, np.ndarray]:
        q, _ = self._adjusted_cofactors()
        return np.arange(self.m * self.k).reshape(self.m, self.k), q

    def normal_forward(self, h: np.ndarray) -> np.ndarray:
        hm, hc = self.split(h)
        self.system.ensure(self.lin)
        gf, gp = self.system.apply_AtP(self.lin, hm, hc)
        return self.system.forward(gf, gp)

    def solve_columns(self, h: np.ndarray) -> np.ndarray:
        xf, xp = self.parameter_effect(h)
        rm, rc = self.system.apply_A(self.lin, xf, xp)
        return self.flat(rm, rc)

    def point_effect_rows(self) -> np.ndarray:
        """Effect of a unit error of each component on its point's unknowns, (n, d)."""
        g, gc = self.system.point_effect(self.lin)
        d = g.shape[-1]
        return np.concatenate([g.reshape(self.m * self.k, d), gc.reshape(-1, d)[self.ctrl_sel]])
