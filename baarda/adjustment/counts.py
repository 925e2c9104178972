"""Counts shared by the results of every model adjusted on a SchurSystem."""

from __future__ import annotations

from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from baarda.adjustment.schur_problem import SchurProblem
    from baarda.adjustment.schur_system import Linearization


class AdjustmentCounts:
    """Mixin: observation and unknown counts, vTPv and sigma0 from `lin` and `problem.system`.

    Components with zero weight (not observed, or rejected) are not observations.  The
    counts and vTPv are computed once per result (a result is immutable): a table that
    asks sigma0 for each of thousands of cameras must not sum the whole observation
    vector each time.
    """

    problem: SchurProblem
    lin: Linearization

    @cached_property
    def n_observations(self) -> int:
        n = np.count_nonzero(self.lin.w) + np.count_nonzero(self.lin.wc)
        if self.lin.wx is not None:
            n += np.count_nonzero(self.lin.wx)
        return int(n)

    @property
    def n_left_out(self) -> int:
        """Components of the observation vector without weight (rejected by snooping)."""
        return int(self.problem.layout.n) - self.n_observations

    def observations_text(self) -> str:
        """'observations 594 (4 rejected components left out), unknowns 426, redundancy
        168' for the summaries."""
        out = self.n_left_out
        return (f"observations {self.n_observations}"
                + (f" ({out} rejected component(s) left out)" if out else "")
                + f", unknowns {self.n_unknowns}, redundancy {self.redundancy}")

    @property
    def n_unknowns(self) -> int:
        return self.problem.system.n_unknowns

    @property
    def redundancy(self) -> int:
        return self.n_observations - self.n_unknowns

    @cached_property
    def vtpv(self) -> float:
        """v'Pv over every observation: image (or model) rows, control, and the extra rows
        (GNSS, IMU, distances, observations of border points); the direct constraints that
        hold the datum or fixed coordinates are not observations and are left out."""
        lin = self.lin
        total = float(np.sum(lin.w * lin.e**2) + np.sum(lin.wc * lin.ec**2))
        if lin.wx is not None and lin.ex is not None:
            total += float(np.sum(lin.wx * lin.ex**2))
        return total

    @property
    def sigma0(self) -> float:
        """A-posteriori sigma0 (unitless: 1 means the a-priori precision was right)."""
        return float(np.sqrt(self.vtpv / self.redundancy)) if self.redundancy > 0 else np.nan

    def scaled_std(self, q: np.ndarray) -> np.ndarray:
        """Standard deviations sigma0 sqrt(diag) of cofactor blocks q (..., d, d)."""
        return self.sigma0 * np.sqrt(np.maximum(np.diagonal(q, axis1=-2, axis2=-1), 0))
