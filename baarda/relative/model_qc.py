"""Quality control of one oriented model: every statistic from the shared quality layer.

Redundancy numbers, standardized residuals (w with sigma0 a priori, or Pope's tau), MDBs come
from baarda.quality.statistics.analyse on the model's DenseModel; the full Qvv P and the
critical error transfers from baarda.quality.matrices.  The point to remeasure is the one
with the largest significant standardized residual (not the largest parallax).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from baarda.options import DEFAULT_TESTS, TestOptions
from baarda.quality.assessment import Assessment
from baarda.quality.matrices import Transfer, critical_transfers, qvv_p_matrix
from baarda.quality.statistics import analyse
from baarda.relative.orientation import Orientation


@dataclass(frozen=True)
class ModelQC(Assessment[Orientation]):
    """QC of one model: the Assessment of its orientation (arrays aligned with
    Orientation.residuals: y of all points, x of ties) with the full Qvv P, the critical
    error transfers and the point to remeasure."""

    qvvp: np.ndarray | None = None  # (k, k) Qvv P
    transfers: tuple[Transfer, ...] = ()  # critical transfers (level 1)
    statistic: str = "w"  # "w" or "tau"
    remeasure_index: int | None = None  # observation with the largest significant statistic
    variance_left_out: tuple[str, ...] = ()  # left out of the strip's variance components

    @property
    def orientation(self) -> Orientation:
        return self.adjustment

    @property
    def significance(self) -> np.ndarray:
        """The tested statistic (w or tau) of every observation, signed like the error."""
        return self.quality.w if self.statistic == "w" else self.quality.tau

    @property
    def critical_value(self) -> float:
        return self.quality.k_w if self.statistic == "w" else self.quality.k_tau

    @property
    def flagged(self) -> np.ndarray:
        s = np.abs(np.nan_to_num(self.significance))
        return self.quality.controlled & (s > self.critical_value)

    @property
    def remeasure(self) -> str | None:
        """Point to remeasure, or None when no observation is significant."""
        if self.remeasure_index is None:
            return None
        return self.orientation.points[self.orientation.obs_point[self.remeasure_index]]

    @property
    def expected(self) -> np.ndarray:
        """EXPD: statistically expected size of each parallax, sigma_v = sigma sqrt(r), µm."""
        return self.quality.sigma_residual

    def label(self, i: int) -> str:
        o = self.orientation
        return f"{o.points[o.obs_point[i]]}{o.obs_component[i]}"


def assess_model(orientation: Orientation, tests: TestOptions = DEFAULT_TESTS,
                 statistic: str = "w") -> ModelQC:
    """Data snooping of one model with the quality layer (tests: alpha0 and beta0)."""
    if statistic not in ("w", "tau"):
        raise ValueError("statistic must be 'w' or 'tau'")
    model = orientation.dense_model()
    q = analyse(model, tests)
    m = qvv_p_matrix(model)
    qc = ModelQC(orientation, model, q, name=f"model {orientation.name}", qvvp=m,
                 transfers=tuple(critical_transfers(m)), statistic=statistic)
    s = np.abs(np.nan_to_num(qc.significance))
    cand = np.flatnonzero(qc.flagged)
    if len(cand):
        qc = replace(qc, remeasure_index=int(cand[np.argmax(s[cand])]))
    return qc
