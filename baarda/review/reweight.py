"""A rejection or restoration answered from the factorisation before it (docs/review.md).

Rejecting (restoring) c observation components changes the normal equations at the earlier
solution x0 by a term of rank c: N' = N0 + A_c^T D A_c (A_c: the components' Jacobian rows
at x0, D: their weight changes, -p to reject, +p to restore).  With the factor of N0 that
the earlier adjustment kept and Woodbury's identity, on the on-line bundle's low-rank
machinery (online/lowrank.py, online/rows.py),

    N'^-1 g = y - U (D^-1 + A_c U)^-1 A_c y,     y = N0^-1 g,   U = N0^-1 A_c^T

(one solve for the c columns U, then one a step), the re-weighted problem is iterated from
x0 with these fixed normal equations and the gradient g = A^T P' e at the current estimate
(the chord method: it converges linearly, at the rate of the Jacobian's change between x0
and the solution, a few 1e-4 a step for a rejected blunder).  Once its correction is below
TIGHT x the solver's tolerance the normal equations are factored once at the estimate (for
the statistics) and the solver's own test is made there: the correction computed with them
is below its tolerance, the estimate is what `solve` would accept (else the solver goes on
from there).  One factorisation instead of the three of a warm-started Gauss-Newton
adjustment: the block's numbers are those of a full re-adjustment
(tests/review/test_reweight.py, to 1e-8).

A re-measurement changes observed values only: the Jacobian at x0, and so N0, is that of
the block re-measured; with no weight changed (c = 0) the iteration is the chord method
with N0 itself.
"""

from __future__ import annotations

import copy
import time

import numpy as np

from baarda.adjustment.schur import SchurFactor
from baarda.adjustment.schur_system import Linearization
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.bundle_result import BundleResult
from baarda.online.lowrank import LowRank, times
from baarda.online.rows import factor_rows

TIGHT = 1e-3  # chord iterations until the correction is below TIGHT x the solver's tolerance
MAX_CHORD = 30  # chord iterations before the solver takes over


def weights(problem: BundleProblem) -> np.ndarray:
    """The weights p of the flat observation components (0 where inactive)."""
    with np.errstate(over="ignore", divide="ignore"):
        return np.where(problem.active, problem.factors / problem.sigma_apriori**2, 0.0)


def gradient(factor: SchurFactor, lin: Linearization) -> tuple[np.ndarray, ...]:
    """A^T P e of a linearisation of the factor's system (its own weights), in the factor's
    parts (nf, b, 1), (np, d, 1)[, (ng, 1)]: the right-hand side of the normal equations,
    with the direct observations of frame, point and global unknowns."""
    s = factor.system
    probe = copy.copy(factor)  # apply_AtP reads the Jacobians and weights of `lin`
    probe.lin = lin
    ex = lin.ex[:, :, None] if s.mx and lin.ex is not None else None
    parts = list(probe.apply_AtP(lin.e[:, :, None], lin.ec[:, :, None], ex))
    if lin.wf is not None and lin.ef is not None:
        parts[0][:, :, 0] += lin.wf * lin.ef
    if lin.wp is not None and lin.ep is not None:
        parts[1][:, :, 0] += lin.wp * lin.ep
    if len(parts) == 3 and s.ng and lin.wg is not None and lin.eg is not None:
        parts[2][:, 0] += lin.wg * lin.eg
    return tuple(parts)


def refit(problem: BundleProblem, before: BundleResult) -> BundleResult | None:
    """`problem` (the problem of `before` re-weighted: some components rejected or restored;
    or prepared again with components measured again: the same observation vector, other
    values) adjusted from `before`'s solution with its factor (module docstring); None where
    it is not the same observation vector or the chord iteration does not converge (the
    caller adjusts in full)."""
    t0 = time.perf_counter()
    old = before.problem
    f0 = before.factor
    s = f0.system
    la, lb = problem.layout, old.layout
    if (la.m, la.k, la.n_control, la.kc, la.mx, la.kx) != \
            (lb.m, lb.k, lb.n_control, lb.kc, lb.mx, lb.kx) or \
            not np.array_equal(la.ctrl_sel, lb.ctrl_sel) or not all(
            np.array_equal(getattr(problem.system, a), getattr(s, a))
            for a in ("frame", "point", "control_point")):
        return None  # not the same observation vector and unknowns
    p_old, p_new = weights(old), weights(problem)
    changed = np.flatnonzero(p_old != p_new)
    rows = factor_rows(old, f0, changed)
    u = LowRank(f0).solve(rows)  # N0^-1 A_c^T
    m = times(rows, *u)  # A_c N0^-1 A_c^T
    small = np.diag(1.0 / (p_new[changed] - p_old[changed])) + m
    options = problem.solve_options
    state = tuple(np.array(x, float) for x in before.state)
    iterations = 0
    while True:
        iterations += 1
        lin = problem.linearize(state)
        y = f0.solve_normal(*gradient(f0, lin))
        z = np.linalg.solve(small, times(rows, *_three(y, s.ng)))
        step = (y[0] - u[0] @ z, y[1] - u[1] @ z) + \
            ((y[2] - u[2] @ z,) if s.ng else ())
        step = tuple(x[..., 0] for x in step)
        state = problem.update(state, step, 1.0)
        if problem.correction_size(state, step) <= TIGHT * options.tolerance:
            break
        if iterations == MAX_CHORD:
            return None
    lin = problem.linearize(state)
    if not np.isfinite(lin.cost):
        return None
    factor = problem.factorize(lin, 0.0)
    if problem.correction_size(state, factor.step()) > options.tolerance:
        return None
    return BundleResult(problem, state, lin, factor, iterations, True, tuple(problem.notes),
                        time.perf_counter() - t0)


def _three(y: tuple, ng: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(xf, xp, xg) of a solve's answer, xg (0, q) without global unknowns."""
    if len(y) == 3:
        return y[0], y[1], y[2]
    return y[0], y[1], np.zeros((ng, y[0].shape[2]))
