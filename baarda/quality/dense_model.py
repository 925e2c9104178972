"""A small adjusted model held densely: the brute-force reference and the engine of the
small adjustments (relative orientation, 2D transformations, strip similarity)."""

from __future__ import annotations

import numpy as np

from baarda.errors import GeometryError
from baarda.quality.adjusted_model import AdjustedModel, weight_factors


class DenseModel(AdjustedModel):
    """A (n, u), a-priori sigma (n,), residuals (n,), active (n,), weight factors (n,).

    `refit` is exact for a linear model: with l = A x - v, the estimate with the new weights
    P' is x' = x - N'^-1 A^T P' v, so v' = v - A N'^-1 A^T P' v; nonlinear models (the
    screening fits, screening/fit.py) adjust again instead.
    """

    def __init__(self, a: np.ndarray, sigma: np.ndarray, residuals: np.ndarray,
                 active: np.ndarray | None = None, *, factors: np.ndarray | None = None,
                 kind=None, component=None, frame=None, point=None, group=None,
                 point_rows: np.ndarray | None = None, point_labels: list[str] | None = None,
                 variance_group=None):
        self.a = np.asarray(a, float)
        n, u = self.a.shape
        self.sigma_apriori = np.asarray(sigma, float)
        self.factors = weight_factors(n, factors)
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
        try:
            self.chol = np.linalg.cholesky(self.nmat)
        except np.linalg.LinAlgError:
            raise GeometryError("the unknowns are not determined by the active observations "
                                "(singular normal equations)") from None
        self.qxx = np.linalg.inv(self.nmat)
        self.point_rows = point_rows  # (npoints, 3) unknown indices of point coordinates
        self.point_labels = point_labels
        self.variance_group = None if variance_group is None else np.asarray(
            variance_group, dtype=object)

    def _labels(self) -> dict:
        return {"kind": self.kind, "component": self.component, "frame": self.frame,
                "point": self.point, "group": self.group, "point_rows": self.point_rows,
                "point_labels": self.point_labels, "variance_group": self.variance_group}

    def variance_groups(self) -> np.ndarray:
        """The groups given (variance_group), else by kind (AdjustedModel)."""
        if self.variance_group is not None:
            return self.variance_group
        return super().variance_groups()

    def refit(self, active: np.ndarray, factors: np.ndarray | None = None) -> DenseModel:
        active = np.asarray(active, bool)
        f = weight_factors(self.n, factors)
        p = np.where(active, f / self.sigma_apriori**2, 0.0)
        nmat = self.a.T @ (p[:, None] * self.a)
        try:
            dx = np.linalg.solve(nmat, self.a.T @ (p * self.residuals))
        except np.linalg.LinAlgError:
            raise GeometryError("the unknowns are not determined by the active observations "
                                "(singular normal equations)") from None
        return DenseModel(self.a, self.sigma_apriori, self.residuals - self.a @ dx, active,
                          factors=f, **self._labels())

    def adjusted_cofactor_diag(self) -> np.ndarray:
        return np.sum((self.a @ self.qxx) * self.a, axis=1)

    def adjusted_cofactor_columns(self, rows: np.ndarray) -> np.ndarray:
        """Columns of A N^-1 A^T, rejected rows included (their Jacobians are kept)."""
        rows = np.atleast_1d(np.asarray(rows))
        return self.a @ (self.qxx @ self.a[rows].T)

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


def block_diagonal(models: list[DenseModel]) -> DenseModel:
    """Independent adjustments as one DenseModel (A block-diagonal, the observation vectors
    one after the other, labels kept): what they have in common, e.g. the variance
    components of groups that every one of them observes, estimated together."""
    u = [m.n_unknowns for m in models]
    a = np.zeros((sum(m.n for m in models), sum(u)))
    r = c = 0
    for m in models:
        a[r:r + m.n, c:c + m.n_unknowns] = m.a
        r, c = r + m.n, c + m.n_unknowns
    cat = lambda name: np.concatenate([getattr(m, name) for m in models])  # noqa: E731
    groups = np.concatenate([m.variance_groups() for m in models])
    return DenseModel(a, cat("sigma_apriori"), cat("residuals"), cat("active"),
                      factors=cat("factors"), kind=cat("kind"), component=cat("component"),
                      frame=cat("frame"), point=cat("point"), variance_group=groups)
