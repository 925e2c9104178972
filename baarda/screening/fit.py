"""Small dense adjustments of the screening stages: Gauss-Newton and the DenseModel.

Every stage describes its observations (`Observations`: observed values, sigmas and the
labels of the quality layer) and a function f(x) -> (computed, Jacobian).  Its `refit(active)`
solves the adjustment with the active components (`gauss_newton`) and hands the quality layer
a DenseModel (`dense_model`); the stages run baarda.quality.iterative.iterative_snooping with
that refit, and judge separability with `separable` (quality.statistics.w_correlation).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from baarda.errors import GeometryError
from baarda.quality.adjusted_model import DenseModel
from baarda.quality.statistics import analyse, w_correlation


@dataclass
class Observations:
    """Flat observation vector of a small adjustment with its labels."""

    observed: np.ndarray  # (n,)
    sigma: np.ndarray  # (n,)
    kind: np.ndarray  # (n,) object: image | constraint | control
    component: np.ndarray  # (n,) object
    frame: np.ndarray  # (n,) object: photo label or ""
    point: np.ndarray  # (n,) object: point label
    group: np.ndarray  # (n,) int: components rejected together

    @property
    def n(self) -> int:
        return len(self.observed)


class SmallModel(DenseModel):
    """A DenseModel in which some components belong to undetermined unknowns.

    When rejections leave a point with one ray, its other components cannot be predicted
    or checked: their adjusted cofactor is infinite, so that the quality layer treats them
    as uncontrolled (r = 0), neither tested nor restored.
    """

    def __init__(self, *args, undetermined: np.ndarray | None = None, **kwargs):
        super().__init__(*args, **kwargs)
        self.undetermined = (np.zeros(self.n, bool) if undetermined is None
                             else np.asarray(undetermined, bool))

    def adjusted_cofactor_diag(self) -> np.ndarray:
        return np.where(self.undetermined, np.inf, super().adjusted_cofactor_diag())


Function = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def gauss_newton(func: Function, x0: np.ndarray, obs: Observations, active: np.ndarray, *,
                 max_iterations: int = 50, tol: float = 1e-12,
                 what: str = "small adjustment") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted least squares of observed = f(x) with the `active` components.

    Returns x, f(x) and the Jacobian at x.  The step is halved while the weighted sum of
    squares grows.  Converged when the largest correction is below tol times (1 + |x|) or the
    sum of squares no longer changes (1e-13 relative).  Raises GeometryError when N is
    singular or it does not converge.
    """
    x = np.asarray(x0, float).copy()
    p = np.where(active, 1.0 / obs.sigma**2, 0.0)
    f, a = func(x)
    e = np.where(active, obs.observed - f, 0.0)
    cost = float(np.sum(p * e**2))
    for _ in range(max_iterations):
        n = a.T @ (p[:, None] * a)
        try:
            c = np.linalg.cholesky(n)
        except np.linalg.LinAlgError:
            raise GeometryError(f"{what}: the unknowns are not determined by the "
                                "observations (singular normal equations)") from None
        dx = np.linalg.solve(c.T, np.linalg.solve(c, a.T @ (p * e)))
        step = 1.0
        for _halve in range(20):  # step halving when the weighted sum of squares grows
            x_new = x + step * dx
            f_new, a_new = func(x_new)
            e_new = np.where(active, obs.observed - f_new, 0.0)
            cost_new = float(np.sum(p * e_new**2))
            if np.isfinite(cost_new) and cost_new <= cost * (1 + 1e-10) + 1e-20:
                break
            step *= 0.5
        else:  # no step lowers it: at the minimum (to rounding), or diverging
            if np.max(np.abs(dx), initial=0.0) <= 1e-6 * (1.0 + np.max(np.abs(x), initial=0.0)):
                return x, f, a
            raise GeometryError(f"{what}: Gauss-Newton diverged")
        small = np.max(np.abs(step * dx), initial=0.0) <= tol * (1.0 + np.max(np.abs(x_new),
                                                                            initial=0.0))
        flat = abs(cost - cost_new) <= 1e-13 * max(cost, 1e-300)
        x, f, a, e, cost = x_new, f_new, a_new, e_new, cost_new
        if small or flat:
            return x, f, a
    raise GeometryError(f"{what}: Gauss-Newton did not converge")


def dense_model(a: np.ndarray, obs: Observations, computed: np.ndarray, active: np.ndarray,
                undetermined: np.ndarray | None = None,
                point_rows: np.ndarray | None = None,
                point_labels: list[str] | None = None) -> SmallModel:
    """The quality layer's view: v = computed - observed (0 where undetermined)."""
    und = np.zeros(obs.n, bool) if undetermined is None else undetermined
    v = np.where(und, 0.0, computed - obs.observed)
    try:
        return SmallModel(a, obs.sigma, v, active & ~und, kind=obs.kind,
                          component=obs.component, frame=obs.frame, point=obs.point,
                          group=obs.group, point_rows=point_rows, point_labels=point_labels,
                          undetermined=und)
    except np.linalg.LinAlgError:
        raise GeometryError("the unknowns are not determined by the active observations "
                            "(singular normal equations)") from None


def largest_test(model: SmallModel, rows: np.ndarray, alpha0: float, beta0: float,
                 statistic: str = "w") -> tuple[int, float, float]:
    """Row of `rows` with the largest |w| (or |tau|), its value and the critical value."""
    q = analyse(model, alpha0, beta0)
    stat = q.w if statistic == "w" else q.tau
    crit = q.k_w if statistic == "w" else q.k_tau
    mag = np.abs(np.nan_to_num(stat[rows]))
    i = int(rows[int(np.argmax(mag))])
    return i, float(stat[i]), float(crit)


def separable(model: SmallModel, i: int, others: np.ndarray, rho_max: float) -> tuple[bool, float]:
    """Whether an error in component i can be told from errors in `others` (|rho| < rho_max)."""
    others = np.asarray(others, int)
    if len(others) == 0:
        return True, 0.0
    rho = w_correlation(model, i)[others]
    worst = float(np.max(np.abs(rho)))
    return worst < rho_max, worst
