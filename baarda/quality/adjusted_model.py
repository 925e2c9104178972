"""What every adjustment model hands to the quality layer.

The quality layer sees a flat vector of n observation components with residuals
v = adjusted - observed, standard deviations sigma (the weights are p = 1 / sigma^2,
sigma0 = 1 a priori) and a flag `active` (False for components that were rejected and are
only predicted).  A model supplies the cofactors of the adjusted observations and products
with N^-1; every statistic is computed from them in quality/statistics.py, once, for all
models.  A model is immutable: `refit(active, factors)` adjusts the same observation vector
again and returns a new model; data snooping and robust re-weighting work through it.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator

import numpy as np

from baarda.kinds import BY_AXIS  # kinds whose axes are variance groups of their own


def kind_groups(kind, component) -> np.ndarray:
    """(n,) the variance-component group of every component by its kind and component
    alone: control and GNSS by axis ('control X', 'gnss Z'), model coordinates in
    planimetry ('model XY': x, y) and height ('model Z'), any other kind by itself.  The
    models refine them (AdjustedModel.variance_groups); the report's histograms of w use
    them as they are."""
    kind = np.asarray(kind, dtype=object)
    comp = np.asarray(component, dtype=object)
    out = np.where(np.isin(kind, BY_AXIS), kind + " " + comp, kind).astype(object)
    mod = kind == "model"
    if mod.any():
        height = np.array([str(c).startswith("z") for c in comp[mod]], bool)
        out[mod] = np.where(height, "model Z", "model XY")
    return out


class AdjustedModel(ABC):
    """An adjusted linear(ised) model  l + v = A x  with diagonal weights."""

    residuals: np.ndarray  # (n,) observation units
    sigma_apriori: np.ndarray  # (n,) a-priori standard deviations
    factors: np.ndarray  # (n,) weight factors of robust re-weighting (1: a-priori weight)
    active: np.ndarray  # (n,) bool: component is in the adjustment
    n_unknowns: int
    kind: np.ndarray  # (n,) str: observation kind (image, control, model, ...)
    component: np.ndarray  # (n,) str: x, y, X, Y, Z, ...
    frame: np.ndarray  # (n,) str label of photo/model or ""
    point: np.ndarray  # (n,) str label of the point or ""
    group: np.ndarray  # (n,) int: components measured together (one image point), or -1
    # how tables and summaries show each kind: kind -> (factor to the shown unit, unit)
    units: dict[str, tuple[float, str]] = {}
    frame_kind: str = "frame"  # what `frame` labels: photo (bundle) or model

    @property
    def n(self) -> int:
        return len(self.residuals)

    @property
    def sigma(self) -> np.ndarray:
        """(n,) standard deviations of the adjustment's weights: a priori / sqrt(factor)."""
        return self.sigma_apriori / np.sqrt(self.factors)

    @property
    def redundancy(self) -> int:
        return int(np.count_nonzero(self.active)) - self.n_unknowns

    def variance_groups(self) -> np.ndarray:
        """(n,) the group of every component for variance-component estimation
        (quality/variance_components.py): kind_groups (its kind, control and GNSS by axis,
        model coordinates XY and Z)."""
        return kind_groups(self.kind, self.component)

    @property
    def converged(self) -> bool:
        """Whether the adjustment reached its least-squares solution (a linear model always
        does; an iterated one says so)."""
        return True

    @property
    def convergence_note(self) -> str:
        """Why the adjustment did not converge, in words ("" when it did)."""
        return ""

    def refit(self, active: np.ndarray, factors: np.ndarray | None = None) -> AdjustedModel:
        """The same observations adjusted again with only the `active` components, weights
        p_i * factors_i (None: a-priori weights); a new model, this one is unchanged.

        Raises GeometryError when the active components do not determine the unknowns.
        """
        raise NotImplementedError(f"{type(self).__name__} cannot be adjusted again")

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

    def image_xy(self) -> np.ndarray:
        """(n, 2) measured image coordinates [mm] of image components, NaN elsewhere."""
        return np.full((self.n, 2), np.nan)

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

    # ------------------------------------------ cofactors of pairs (quality/separability.py)
    def local_cofactor_diag(self) -> np.ndarray | None:
        """(n,) the part of diag(A N^-1 A^T) that stays when every unknown but the
        component's own point is known (bundle: jp M^-1 jp^T), or None: the rest bounds the
        cofactors of pairs on one frame with different points (quality/separability.py)."""
        return None

    def adjusted_cofactor_columns(self, rows: np.ndarray) -> np.ndarray:
        """Columns `rows` of A N^-1 A^T (n, len(rows)).  Default: from solve_columns (a
        rejected row's column is then zero: small models override it)."""
        rows = np.atleast_1d(np.asarray(rows))
        h = np.zeros((self.n, len(rows)))
        h[rows, np.arange(len(rows))] = 1.0
        return self.solve_columns(h) * self.sigma[rows][None, :] ** 2

    def point_pair_cofactors(self) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """(i, j, (A N^-1 A^T)_ij) of every two components of one point (label), i < j, in
        chunks.  Default: from adjusted_cofactor_columns (small models)."""
        yield from _label_pairs(self, np.asarray(self.point, dtype=object),
                                np.arange(self.n))

    def frame_pair_cofactors(self, rows: np.ndarray
                             ) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """(i, j, (A N^-1 A^T)_ij) of every two components on the frames (photos, models)
        of the components `rows`, i < j, in chunks."""
        yield from _label_pairs(self, np.asarray(self.frame, dtype=object), rows)

    def other_cofactor_blocks(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Other groups tested as a whole, each (index (g, k), cofactor blocks (g, k, k))
        (a bundle's GNSS positions); none by default."""
        return []


def _label_pairs(model: AdjustedModel, labels: np.ndarray, rows: np.ndarray):
    """Pairs of components with one (non-empty) label among the labels of `rows`."""
    want = set(labels[np.asarray(rows, int)].tolist()) - {""}
    idx = np.flatnonzero(np.array([x in want for x in labels.tolist()], bool))
    if not len(idx):
        return
    cols = model.adjusted_cofactor_columns(idx)[idx]
    same = labels[idx][:, None] == labels[idx][None, :]
    a, c = np.nonzero(np.triu(same, 1))
    yield idx[a], idx[c], cols[a, c]


def weight_factors(n: int, factors: np.ndarray | None) -> np.ndarray:
    """(n,) weight factors, ones when None; checked positive."""
    if factors is None:
        return np.ones(n)
    f = np.asarray(factors, float)
    if f.shape != (n,) or not np.all(f > 0):
        raise ValueError(f"weight factors must be {n} positive numbers")
    return f
