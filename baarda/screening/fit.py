"""Small dense adjustments of the screening stages, solved by the one solver.

Every stage describes its observations (`Observations`: observed values, sigmas and the
labels of the quality layer) and a function f(x) -> (computed, Jacobian) (`SmallProblem`).
`SmallProblem.fit(active)` adjusts with the active components and hands the quality layer
a `SmallModel` (a DenseModel that knows how to adjust itself again); the stages run
baarda.quality.iterative.iterative_snooping on it, and judge separability with `separable`
(quality.statistics.w_correlation).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from baarda.adjustment.dense import DenseLeastSquares
from baarda.adjustment.solve import solve
from baarda.errors import GeometryError
from baarda.options import DEFAULT_TESTS, SolveOptions, TestOptions
from baarda.quality.adjusted_model import weight_factors
from baarda.quality.dense_model import DenseModel
from baarda.quality.statistics import analyse, w_correlation

# converged when max |dx| <= 1e-12 (1 + max |x|) or v'Pv changes by less than 1e-13; when no
# step lowers v'Pv any more, converged if max |dx| <= 1e-6 (1 + max |x|) (rounding), else
# diverged
SOLVE = SolveOptions(max_iterations=50, tolerance=1e-12, flat_cost=1e-13, stall_tolerance=1e-6,
                     min_step=1e-6, cost_rtol=1e-10, final_step=True)


@dataclass(frozen=True)
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


Function = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def least_squares(func: Function, x0: np.ndarray, obs: Observations, active: np.ndarray,
                  factors: np.ndarray | None = None, what: str = "small adjustment"):
    """Weighted least squares of observed = f(x) with the `active` components: the solver's
    Solution (state = x, lin.f = f(x), lin.a = the Jacobian at x).  Raises GeometryError
    when N is singular or the iteration does not converge."""
    f = weight_factors(obs.n, factors)
    p = np.where(active, f / obs.sigma**2, 0.0)
    sol = solve(DenseLeastSquares(func, obs.observed, p, what=what),
                np.asarray(x0, float).copy(), SOLVE)
    if not sol.converged:
        raise GeometryError(f"{what}: Gauss-Newton {sol.message}")
    return sol


class SmallModel(DenseModel):
    """A DenseModel of a small nonlinear adjustment that adjusts itself again (`refit`).

    When rejections leave a point with one ray, its other components cannot be predicted
    or checked (`undetermined`): their adjusted cofactor is infinite, so that the quality
    layer treats them as uncontrolled (r = 0), neither tested nor restored.  `x` is the
    solution; `refit(active, factors)` calls `problem.fit` from it.
    """

    func: Callable[[np.ndarray], np.ndarray]  # set by Intersection.fit (tests)
    unknowns: np.ndarray

    def __init__(self, *args, problem=None, x=None, undetermined: np.ndarray | None = None,
                 **kwargs):
        super().__init__(*args, **kwargs)
        self.problem, self.x = problem, x
        self.undetermined = (np.zeros(self.n, bool) if undetermined is None
                             else np.asarray(undetermined, bool))

    def refit(self, active: np.ndarray, factors: np.ndarray | None = None) -> SmallModel:
        return self.problem.fit(active, factors, start=self.x)

    def adjusted_cofactor_diag(self) -> np.ndarray:
        return np.where(self.undetermined, np.inf, super().adjusted_cofactor_diag())


def small_model(a: np.ndarray, obs: Observations, computed: np.ndarray, active: np.ndarray,
                factors: np.ndarray | None = None, *, problem=None, x=None,
                undetermined: np.ndarray | None = None, point_rows: np.ndarray | None = None,
                point_labels: list[str] | None = None) -> SmallModel:
    """The quality layer's view: v = computed - observed (0 where undetermined)."""
    und = np.zeros(obs.n, bool) if undetermined is None else undetermined
    v = np.where(und, 0.0, computed - obs.observed)
    return SmallModel(a, obs.sigma, v, active & ~und, factors=factors, kind=obs.kind,
                      component=obs.component, frame=obs.frame, point=obs.point,
                      group=obs.group, point_rows=point_rows, point_labels=point_labels,
                      problem=problem, x=x, undetermined=und)


class SmallProblem:
    """observed = f(x) for the observations `obs`, started from `start`: fit -> SmallModel."""

    def __init__(self, func: Function, start: np.ndarray, obs: Observations,
                 what: str = "small adjustment"):
        self.func, self.start, self.obs, self.what = func, np.asarray(start, float), obs, what

    def fit(self, active: np.ndarray, factors: np.ndarray | None = None,
            start: np.ndarray | None = None) -> SmallModel:
        active = np.asarray(active, bool)
        sol = least_squares(self.func, self.start if start is None else start, self.obs,
                            active, factors, self.what)
        return small_model(sol.lin.a, self.obs, sol.lin.f, active, factors, problem=self,
                           x=sol.state)


def largest_test(model: SmallModel, rows: np.ndarray, tests: TestOptions = DEFAULT_TESTS,
                 statistic: str = "w") -> tuple[int, float, float]:
    """Row of `rows` with the largest |w| (or |tau|), its value and the critical value."""
    q = analyse(model, tests)
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
