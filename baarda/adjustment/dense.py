"""Small dense least-squares problems for the one solver (adjustment/solve.py).

`DenseLeastSquares` is observed = f(x) with diagonal weights p, for the adjustments whose
normal equations are small enough to hold densely: relative orientations, space resections,
2D and 3D transformations, the strip steps of the screening.  The normal equations are
solved by Cholesky (`method="cholesky"`, with an optional condition check of the
column-scaled N) or, for problems that may start far off, by least squares on the weighted,
column-scaled Jacobian (`method="lstsq"`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from baarda.errors import GeometryError

Function = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]  # x -> (f (n,), A (n, u))


@dataclass(frozen=True)
class DenseLinearization:
    """f(x), its Jacobian A, misclosures e = observed - f (0 where p = 0) and v'Pv."""

    x: np.ndarray
    f: np.ndarray
    a: np.ndarray
    e: np.ndarray
    p: np.ndarray

    @property
    def cost(self) -> float:
        return float(np.sum(self.p * self.e**2))


class DenseFactor:
    """The (damped) normal equations of one linearisation, factored."""

    def __init__(self, lin: DenseLinearization, damping: float, method: str,
                 max_condition: float | None, what: str):
        self.lin, self.method, self.damping = lin, method, damping
        a, p, e = lin.a, lin.p, lin.e
        if method == "lstsq":
            sp = np.sqrt(p)
            aw = sp[:, None] * a
            scale = np.maximum(np.linalg.norm(aw, axis=0), 1e-300)
            if damping:
                aw = np.vstack([aw / scale, np.sqrt(damping) * np.eye(a.shape[1])])
                rhs = np.concatenate([sp * e, np.zeros(a.shape[1])])
            else:
                aw, rhs = aw / scale, sp * e
            self._step = np.linalg.lstsq(aw, rhs, rcond=None)[0] / scale
            return
        n = a.T @ (p[:, None] * a)
        if damping:
            n[np.diag_indices_from(n)] *= 1.0 + damping
        if max_condition is not None:
            d = np.sqrt(np.diag(n))
            if not np.all(d > 0) or np.linalg.cond(n / np.outer(d, d)) > max_condition:
                raise GeometryError(f"{what}: the unknowns are not determined by the "
                                    "observations (singular normal equations)")
        try:
            c = np.linalg.cholesky(n)
        except np.linalg.LinAlgError:
            raise GeometryError(f"{what}: the unknowns are not determined by the "
                                "observations (singular normal equations)") from None
        self._step = np.linalg.solve(c.T, np.linalg.solve(c, a.T @ (p * e)))

    def step(self) -> np.ndarray:
        return self._step


def relative_correction(x: np.ndarray, dx: np.ndarray) -> float:
    """The default correction size: max |dx| / (1 + max |x|)."""
    return float(np.max(np.abs(dx), initial=0.0) /
                 (1.0 + np.max(np.abs(x), initial=0.0)))


class DenseLeastSquares:
    """observed = f(x) with weights p (0 = not observed): the solver's protocol.

    correction: the correction size of a step (default relative_correction);
    admissible: whether an estimate may be accepted (default: always).
    """

    def __init__(self, func: Function, observed: np.ndarray, weights: np.ndarray, *,
                 method: str = "cholesky", max_condition: float | None = None,
                 correction: Callable[[np.ndarray, np.ndarray], float] | None = None,
                 admissible: Callable[[np.ndarray], bool] | None = None,
                 what: str = "small adjustment"):
        if method not in ("cholesky", "lstsq"):
            raise ValueError("method must be 'cholesky' or 'lstsq'")
        self.func, self.what, self.method = func, what, method
        self.observed = np.asarray(observed, float)
        self.p = np.asarray(weights, float)
        self.max_condition = max_condition
        self._correction = correction or relative_correction
        self._admissible = admissible

    def linearize(self, x: np.ndarray) -> DenseLinearization:
        f, a = self.func(x)
        e = np.where(self.p > 0, self.observed - f, 0.0)
        return DenseLinearization(x, f, a, e, self.p)

    def factorize(self, lin: DenseLinearization, damping: float = 0.0) -> DenseFactor:
        return DenseFactor(lin, damping, self.method, self.max_condition, self.what)

    def update(self, x: np.ndarray, dx: np.ndarray, t: float) -> np.ndarray:
        return x + t * dx

    def correction_size(self, x: np.ndarray, dx: np.ndarray) -> float:
        return self._correction(x, dx)

    def admissible(self, x: np.ndarray) -> bool:
        return True if self._admissible is None else bool(self._admissible(x))
