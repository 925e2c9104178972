"""The one least-squares solver of baarda: Gauss-Newton with step halving, or damped.

Every adjustment (bundle, independent models, relative orientation, the screening fits,
space resection) describes itself by a small protocol and is solved here:

    lin = problem.linearize(state)            # residuals and Jacobians; lin.cost = v'Pv
    factor = problem.factorize(lin, damping)  # normal equations, reduced and factored
    step = factor.step()                      # the Gauss-Newton correction
    state = problem.update(state, step, t)    # state + t * step
    problem.correction_size(state, step)      # dimensionless, compared with the tolerance
    problem.admissible(state)                 # e.g. every point in front of its cameras

Converged when the correction computed at the current estimate is negligible (see
SolveOptions): the estimate is then the solution, and the normal equations factored there
(undamped) are the ones the statistics use, so residuals, Jacobians and factor belong
together.  The solver changes nothing it is given; each call returns a new Solution.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from baarda.errors import GeometryError
from baarda.options import SolveOptions

DEFAULT_OPTIONS = SolveOptions()
# Levenberg-Marquardt where Gauss-Newton diverged (solve_continued): its damping at the start
# and its iteration limit (the bundle's SOLVE_LM)
CONTINUATION = SolveOptions(max_iterations=100, damping=1e-3)
MAX_DAMPING = 1e16  # Levenberg-Marquardt gives up beyond this lambda


class Factor(Protocol):
    def step(self) -> Any: ...


class Problem(Protocol):
    """What a least-squares problem tells the solver (module docstring)."""

    def linearize(self, state: Any) -> Any: ...

    def factorize(self, lin: Any, damping: float) -> Factor: ...

    def update(self, state: Any, step: Any, t: float) -> Any: ...

    def correction_size(self, state: Any, step: Any) -> float: ...

    def admissible(self, state: Any) -> bool: ...


@dataclass(frozen=True)
class Iteration:
    """One accepted step: the sum of squares after it, the correction and its length t."""

    number: int
    cost: float
    correction: float
    step: float
    damping: float


@dataclass(frozen=True)
class Solution:
    """The estimate, its linearisation and its (undamped) factored normal equations."""

    state: Any
    lin: Any
    factor: Any
    iterations: int
    converged: bool
    reason: str  # converged | stalled | diverged | inadmissible | iterations
    message: str
    history: tuple[Iteration, ...]

    @property
    def cost(self) -> float:
        return float(self.lin.cost)


def _quiet(message: str) -> None:
    pass


def solve(problem: Problem, start: Any, options: SolveOptions = DEFAULT_OPTIONS,
          progress: Callable[[str], None] | None = None, label: str = "") -> Solution:
    """Minimise v'Pv of `problem` from `start`; see the module docstring and SolveOptions.

    Raises GeometryError when the residuals at the start are not finite or the normal
    equations are singular (the problem's factorize names the cause); a solution that
    did not converge is returned with converged = False and the reason in `message`.
    """
    say = progress or _quiet
    describe = getattr(problem, "describe", None)
    state = start
    lin = problem.linearize(state)
    if not np.isfinite(lin.cost):
        raise GeometryError(f"{label}the residuals at the approximate values are not finite")
    damping = float(options.damping or 0.0)
    drop = np.inf  # relative decrease of the cost by the last accepted step
    history: list[Iteration] = []
    it = 0
    before = None  # (state, lin) of the last estimate whose normal equations were regular
    while it < options.max_iterations:
        it += 1
        factor = None  # the previous factorisation's storage can serve this one
        try:
            factor = problem.factorize(lin, damping)
        except GeometryError as err:
            if before is None:  # singular at the start: the problem as given
                raise
            if damping > 0.0 and damping * 10.0 <= MAX_DAMPING:
                # Levenberg-Marquardt: a damped system that is not positive definite at an
                # accepted estimate (rounding in a nearly singular block) takes more damping,
                # as a step that does not lower the cost does
                damping *= 10.0
                say(f"{label}iteration {it}: the damped normal equations are singular "
                    f"({err}); damping raised to {damping:g}")
                continue
            return _diverged(problem, before, it, err, tuple(history), say, label)
        before = (state, lin, damping)
        step = factor.step()
        size = float(problem.correction_size(state, step))
        if size <= options.tolerance or (drop <= options.flat_cost
                                         and size <= options.flat_tolerance):
            if damping == 0.0:
                say(f"{label}iteration {it}: converged, vTPv = {lin.cost:.6g}, remaining "
                    f"correction {describe(state, step, 1.0) if describe else f'{size:.3g}'}")
                if options.final_step:
                    state, lin, factor = _final_step(problem, state, step, lin, factor)
                return Solution(state, lin, factor, it, True, "converged", "converged",
                                tuple(history))
            damping = 0.0  # confirm with the undamped normal equations
            continue
        found = _search(problem, state, step, lin.cost, options)
        if found is None:
            if damping > 0.0:
                damping *= 10.0
                if damping <= MAX_DAMPING:
                    continue
                try:  # the undamped correction; singular: the last damped one stands
                    factor = problem.factorize(lin, 0.0)
                    step = factor.step()
                    size = float(problem.correction_size(state, step))
                except GeometryError:
                    pass
            if size <= options.stall_tolerance:
                reason, message = "stalled", "converged (at the rounding floor)"
            elif _any_admissible(problem, state, step, options):
                reason, message = "diverged", ("diverged: no step along the correction "
                                               "lowers the sum of squares")
            else:
                reason, message = "inadmissible", ("diverged: no step along the correction "
                                                   "keeps the estimate admissible")
            say(f"{label}iteration {it}: {message}")
            return Solution(state, lin, factor, it, reason == "stalled", reason, message,
                            tuple(history))
        t, state, new = found
        drop = (lin.cost - new.cost) / max(lin.cost, 1e-300)
        lin = new
        if damping > 0.0 and t == 1.0:  # a whole damped step: less damping next time
            damping = damping / 10.0 if damping > 1e-12 else damping
        history.append(Iteration(it, float(lin.cost), size * t, t, damping))
        say(f"{label}iteration {it}: vTPv = {lin.cost:.6g}, max correction "
            + (describe(state, step, t) if describe else f"{t * size:.3g}")
            + ("" if t == 1.0 else f" (step {t:g})"))
    # iterations used up: the normal equations at the last estimate, for the statistics
    factor = None
    try:
        factor = problem.factorize(lin, 0.0)
    except GeometryError as err:
        if before is None:
            raise
        return _diverged(problem, before, it, err, tuple(history), say, label)
    size = float(problem.correction_size(state, factor.step()))
    converged = size <= max(options.tolerance, options.stall_tolerance)
    message = "converged" if converged else \
        f"not converged after {options.max_iterations} iterations"
    return Solution(state, lin, factor, it, converged, "converged" if converged else
                    "iterations", message, tuple(history))


def solve_continued(problem: Problem, start: Any, options: SolveOptions = DEFAULT_OPTIONS,
                    progress: Callable[[str], None] | None = None, label: str = "",
                    damped: SolveOptions = CONTINUATION) -> tuple[Solution, Solution | None]:
    """`solve`; where undamped Gauss-Newton diverges, Levenberg-Marquardt (`damped`'s
    damping and iteration limit) continues from its last sound estimate, the iterations of
    both counted.  Returns (the solution, the Gauss-Newton solution that diverged or None):
    the two are the same when the damped solver cannot start there or leaves the admissible
    region.  `solve_notes` says in words what happened."""
    sol = solve(problem, start, options, progress, label)
    if sol.reason != "diverged" or options.damping:
        return sol, None
    (progress or _quiet)(f"{label}Gauss-Newton diverged: Levenberg-Marquardt continues from "
                         "the last sound estimate")
    lm_options = replace(options, damping=damped.damping,
                         max_iterations=damped.max_iterations)
    try:
        lm = solve(problem, sol.state, lm_options, progress, label)
    except GeometryError:
        return sol, sol
    if lm.reason == "inadmissible":
        return sol, sol
    return replace(lm, iterations=sol.iterations + lm.iterations,
                   history=sol.history + lm.history), sol


def solve_notes(sol: Solution, gn: Solution | None) -> list[str]:
    """The notes of `solve_continued`'s answer, in this order: the Levenberg-Marquardt
    continuation; why the solution is not converged; where Levenberg-Marquardt could not
    start, the advice to ask for it from the start."""
    notes = []
    if gn is not None and sol is not gn:
        notes.append(f"Gauss-Newton {gn.message}; Levenberg-Marquardt continued from the last "
                     f"sound estimate: {sol.message} after {sol.iterations - gn.iterations} "
                     "iteration(s)")
    if not sol.converged:
        notes.append(sol.message)
    if sol is gn:
        notes.append("Gauss-Newton diverged from these approximations: Levenberg-Marquardt "
                     "(--damping lm, or solve=\"lm\") may reach the minimum")
    return notes


def _diverged(problem: Problem, before: tuple, it: int, err: GeometryError,
              history: tuple, say: Callable[[str], None], label: str) -> Solution:
    """The normal equations became singular during the iterations (a point or photo ran
    away: the iteration diverges): the last estimate whose normal equations were regular,
    factored again (undamped) for the statistics, as not converged.  A damped iteration can
    reach estimates whose undamped normal equations are singular: the damped ones, which
    were regular there, then stand (the statistics are those of the damped system)."""
    state, lin, damping = before
    message = f"diverged at iteration {it}: {err}; the estimate before it is reported"
    try:
        factor = problem.factorize(lin, 0.0)
    except GeometryError as undamped:
        if not damping:
            raise
        factor = problem.factorize(lin, damping)
        message += (f" (its normal equations are singular without damping: {undamped}; the "
                    f"statistics are those of the damped normal equations, lambda {damping:g})")
    say(f"{label}iteration {it}: {message}")
    return Solution(state, lin, factor, it, False, "diverged", message, history)


def _final_step(problem: Problem, state: Any, step: Any, lin: Any, factor: Any):
    """The converged estimate with its negligible correction applied, linearised and factored
    there (unchanged when that estimate is not admissible)."""
    new_state = problem.update(state, step, 1.0)
    if not problem.admissible(new_state):
        return state, lin, factor
    new = problem.linearize(new_state)
    if not np.isfinite(new.cost):
        return state, lin, factor
    return new_state, new, problem.factorize(new, 0.0)


def _search(problem: Problem, state: Any, step: Any, cost: float, options: SolveOptions):
    """(t, new state, its linearisation) of the longest step t = 1, 1/2, ... >= min_step
    that is admissible and does not raise the cost; None if there is none.  A damped step
    is halved too: tried at t = 1 only, Levenberg-Marquardt's x10 / /10 schedule
    oscillated (every other step refused) at a damping too large to converge in 100
    iterations where Gauss-Newton converged in 26 (6 cameras of BAL Ladybug-49, issue 43);
    the damping is lowered after a whole step only."""
    t = 1.0
    limit = cost * (1.0 + options.cost_rtol)
    while t >= options.min_step:
        new_state = problem.update(state, step, t)
        if problem.admissible(new_state):
            new = problem.linearize(new_state)
            if np.isfinite(new.cost) and new.cost <= limit:
                return t, new_state, new
        t *= 0.5
    return None


def _any_admissible(problem: Problem, state: Any, step: Any, options: SolveOptions) -> bool:
    t = 1.0
    while t >= options.min_step:
        if problem.admissible(problem.update(state, step, t)):
            return True
        t *= 0.5
    return False
