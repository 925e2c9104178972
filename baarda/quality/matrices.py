"""The full matrix Qvv P of a small adjusted model and its critical error transfers
(Kratky and El-Hakim 1983, eq. 5-6, Figures 3 and 5).

    Qvv P = I - A N^-1 A^T P,      dv = -Qvv P dl

Column j holds the effect of a unit error in observation j on every residual (with opposite
sign); its diagonal element is the redundancy number r_j.  A transfer j -> i is critical when
an off-diagonal element of column j matches or exceeds the diagonal one in size: the error in
j then shows at i at least as large as at j, and the size of the residuals points at the
wrong observation.  Dense: for the small per-model systems only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.quality.adjusted_model import AdjustedModel

MAX_DENSE = 4000  # components; larger models must not form an n x n matrix


def qvv_p_matrix(model: AdjustedModel) -> np.ndarray:
    """Qvv P (n, n) of `model`, dimensionless.

    For an active column j, column j is the negated change of all residuals per unit error in
    observation j.  A rejected (inactive) component has weight 0: its column is e_j (its
    predicted residual takes the whole error and nothing else moves), its row the predicted
    residual's response to errors in the active observations.
    """
    n = model.n
    if n > MAX_DENSE:
        raise ValueError(f"qvv_p_matrix is for small models (n = {n} > {MAX_DENSE})")
    return np.eye(n) - model.solve_columns(np.eye(n))


@dataclass(frozen=True)
class Transfer:
    """A critical error transfer: an error in `source` shows at `target` with `value` (per
    unit error, signed), at least as large as at `source` itself (`diagonal`)."""

    source: int
    target: int
    value: float
    diagonal: float

    @property
    def ratio(self) -> float:
        return abs(self.value) / self.diagonal if self.diagonal > 0 else np.inf


def critical_transfers(qvvp: np.ndarray, level: float = 1.0, rtol: float = 1e-6,
                       active: np.ndarray | None = None) -> list[Transfer]:
    """Transfers j -> i (i != j) with |(Qvv P)_ij| >= level * (Qvv P)_jj.

    level = 1 is Kratky's critical transfer (off-diagonal matches or exceeds the diagonal);
    a lower level lists also the less critical but still misleading ones.  `rtol` lets exact
    ties (symmetric patterns) count as matches despite rounding.  Columns and rows of inactive
    components are skipped.  Sorted by decreasing ratio |value| / diagonal.
    """
    m = np.asarray(qvvp, float)
    n = m.shape[0]
    act = np.ones(n, bool) if active is None else np.asarray(active, bool)
    diag = np.diag(m)
    thr = level * diag * (1.0 - rtol)
    hit = (np.abs(m) >= thr[None, :]) & ~np.eye(n, dtype=bool)
    hit &= act[:, None] & act[None, :] & (diag[None, :] > 0)
    tgt, src = np.nonzero(hit)
    out = [Transfer(int(j), int(i), float(m[i, j]), float(diag[j])) for i, j in zip(tgt, src,
                                                                                    strict=True)]
    return sorted(out, key=lambda t: (-t.ratio, t.source, t.target))
