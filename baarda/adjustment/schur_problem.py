"""What the bundle and the independent-model adjustment share as problems of the solver.

A SchurProblem has a flat observation vector (`layout`, the quality layer's order), the
a-priori standard deviations of its components, the structure of its reduced normal
equations (`system`) and the weights of one choice of active components and weight
factors.  It never changes after construction: `reweighted` returns a new problem that
shares everything but the weights.
"""

from __future__ import annotations

import copy

import numpy as np

from baarda.adjustment.schur import SchurFactor
from baarda.adjustment.schur_model import FlatLayout
from baarda.adjustment.schur_system import Linearization, SchurSystem
from baarda.errors import GeometryError


def read_only(a: np.ndarray) -> np.ndarray:
    """`a` (an array), made read-only."""
    a = np.asarray(a)
    a.flags.writeable = False
    return a


class SchurProblem:
    """Base of BundleProblem and ModelProblem (weights, reweighting, the solver's steps)."""

    layout: FlatLayout
    sigma_apriori: np.ndarray  # (n,) a-priori standard deviations of the flat components
    system: SchurSystem

    def _set_weights(self, active: np.ndarray, factors: np.ndarray) -> None:
        """Weights p = factor / sigma^2 of the active components, 0 elsewhere (w, wc)."""
        n = self.layout.n
        active = np.asarray(active, bool)
        factors = np.asarray(factors, float)
        if active.shape != (n,) or factors.shape != (n,) or not np.all(factors > 0):
            raise ValueError(f"active and factors must be {n} values (factors positive)")
        self.active, self.factors = read_only(active.copy()), read_only(factors.copy())
        with np.errstate(over="ignore", divide="ignore"):
            p = np.where(active, factors / self.sigma_apriori**2, 0.0)
        if not np.isfinite(p).all():
            raise GeometryError(
                f"a-priori standard deviation {float(np.min(self.sigma_apriori)):.3g} (in the "
                "units of its observation, mm or m) is too small: its weight 1/sigma^2 "
                "overflows (check the standard deviations of the input)")
        parts = [read_only(a) for a in self.layout.split(p)]
        self.w, self.wc = parts[:2]
        self.wx = parts[2] if len(parts) == 3 else None  # extra observations (a border)

    def reweighted(self, active: np.ndarray | None = None,
                   factors: np.ndarray | None = None):
        """The same problem with only the `active` components observed, weights times
        `factors` (None: all active / a-priori weights)."""
        new = copy.copy(self)
        n = self.layout.n
        new._set_weights(np.ones(n, bool) if active is None else active,
                         np.ones(n) if factors is None else factors)
        return new

    # ------------------------------------------------- the solver's protocol
    def factorize(self, lin: Linearization, damping: float = 0.0) -> SchurFactor:
        return self.system.factorize(lin, damping)

    def update(self, state, step, t: float):
        """(frames, points[, globals]) + t (frame step, point step[, global step])."""
        return tuple(x + t * dx for x, dx in zip(state, step, strict=True))

    def admissible(self, state) -> bool:
        return True
