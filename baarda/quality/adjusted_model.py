"""What every adjustment model hands to the quality layer.

The quality layer sees a flat vector of n observation components with residuals
v = adjusted - observed, a-priori standard deviations sigma (the weights are
p = 1 / sigma^2, sigma0 = 1 a priori) and a flag `active` (False for components that were
rejected and are only predicted).  A model supplies the cofactors of the adjusted
observations and products with N^-1; every statistic is computed from them in
quality/statistics.py, once, for all models.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np


class AdjustedModel(ABC):
    """An adjusted linear(ised) model  l + v = A x  with diagonal weights."""

    residuals: np.ndarray  # (n,) observation units
    sigma: np.ndarray  # (n,) a-priori standard deviations
    active: np.ndarray  # (n,) bool: component is in the adjustment
    n_unknowns: int
    kind: np.ndarray  # (n,) str: observation kind (image, control, model, ...)
    component: np.ndarray  # (n,) str: x, y, X, Y, Z, ...
    frame: np.ndarray  # (n,) str label of photo/model or ""
    point: np.ndarray  # (n,) str label of the point or ""
    group: np.ndarray  # (n,) int: components measured together (one image point), or -1

    @property
    def n(self) -> int:
        return len(self.residuals)

    @property
    def redundancy(self) -> int:
        return int(np.count_nonzero(self.active)) - self.n_unknowns

    @abstractmethod
    def adjusted_cofactor_diag(self) -> np.ndarray:
        """diag(A N^-1 A^T), (n,): cofactor of each adjusted observation."""

    @abstractmethod
    def normal_forward(self, h: np.ndarray) -> np.ndarray:
        """W (u, q) with W^T W = H^T P A N^-1 A^T P H for H (n, q); rows not active in P."""

    @abstractmethod
    def solve_columns(self, h: np.ndarray) -> np.ndarray:
        """A N^-1 A^T P H for H (n, q): Gruen's identity-matrix observation when H = e_i."""

    @abstractmethod
    def point_effect(self) -> tuple[np.ndarray, np.ndarray]:
        """Effect of a unit error in each component on the adjusted coordinates of a point.

        Returns (effect (n, 3) in point units per observation unit, point label (n,)):
        for the bundle, the point that the observation belongs to.
        """

    def adjusted_cofactor_blocks(self) -> tuple[np.ndarray, np.ndarray]:
        """Blocks of A N^-1 A^T for the groups: (index (g, k), blocks (g, k, k)).

        Default: from solve_columns (fine for small models); large models override it.
        """
        groups = np.unique(self.group[self.group >= 0])
        idx = np.array([np.flatnonzero(self.group == g) for g in groups])
        if idx.size == 0:
            return idx.reshape(0, 0), np.zeros((0, 0, 0))
        k = idx.shape[1]
        out = np.empty((len(idx), k, k))
        for gi, rows in enumerate(idx):
            h = np.zeros((self.n, k))
            h[rows, np.arange(k)] = 1.0
            out[gi] = self.solve_columns(h)[rows] * self.sigma[rows][None, :] ** 2
        return idx, out


class DenseModel(AdjustedModel):
    """A small model held densely: A (n, u), sigma (n,), residuals (n,).

    The brute-force reference for tests, and the engine of the small per-model adjustments
    (relative orientation, 2D transformations, strip similarity).
    """

    def __init__(self, a: np.ndarray, sigma: np.ndarray, residuals: np.ndarray,
                 active: np.ndarray | None = None, *, kind=None, component=None, frame=None,
                 point=None, group=None, point_rows: np.ndarray | None = None,
                 point_labels: list[str] | None = None):
        self.a = np.asarray(a, float)
        n, u = self.a.shape
        self.sigma = np.asarray(sigma, float)
        self.residuals = np.asarray(residuals, float)
        self.active = np.ones(n, bool) if active is None else np.asarray(active, bool)
        self.n_unknowns = u
        self.kind = np.asarray(kind if kind is not None else ["obs"] * n, dtype=object)
        self.component = np.asarray(component if component is not None else [""] * n,
                                    dtype=object)
        self.frame = np.asarray(frame if frame is not None else [""] * n, dtype=object)
        self.point = np.asarray(point if point is not None else [""] * n, dtype=object)
        self.group = np.asarray(group if group is not None else np.full(n, -1), dtype=int)
        self.p = np.where(self.active, 1.0 / self.sigma**2, 0.0)
        self.nmat = self.a.T @ (self.p[:, None] * self.a)
        self.qxx = np.linalg.inv(self.nmat)
        self.chol = np.linalg.cholesky(self.nmat)
        self.point_rows = point_rows  # (npoints, 3) unknown indices of point coordinates
        self.point_labels = point_labels

    def adjusted_cofactor_diag(self) -> np.ndarray:
        return np.sum((self.a @ self.qxx) * self.a, axis=1)

    def qll_hat(self) -> np.ndarray:
        return self.a @ self.qxx @ self.a.T

    def normal_forward(self, h: np.ndarray) -> np.ndarray:
        g = self.a.T @ (self.p[:, None] * h)
        return np.linalg.solve(self.chol, g)

    def solve_columns(self, h: np.ndarray) -> np.ndarray:
        return self.a @ (self.qxx @ (self.a.T @ (self.p[:, None] * h)))

    def point_effect(self) -> tuple[np.ndarray, np.ndarray]:
        """Largest effect over all points (dense: every point is checked)."""
        eff = self.qxx @ (self.a.T * self.p[None, :])  # (u, n) unknowns per unit error
        if self.point_rows is None:
            return np.zeros((self.n, 3)), np.array([""] * self.n, dtype=object)
        per_point = eff[self.point_rows]  # (np, 3, n)
        size = np.linalg.norm(per_point, axis=1)  # (np, n)
        best = np.argmax(size, axis=0)
        effect = per_point[best, :, np.arange(self.n)]
        labels = np.asarray(self.point_labels, dtype=object)[best]
        return effect, labels
