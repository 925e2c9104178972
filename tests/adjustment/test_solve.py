"""The one solver (adjustment/solve.py): Gauss-Newton with step halving, Levenberg-Marquardt
damping, convergence rules, and results that never change afterwards."""

import copy
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from baarda.adjustment.dense import DenseLeastSquares
from baarda.adjustment.solve import solve
from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.bundle_problem import SOLVE, SOLVE_LM, BundleProblem
from baarda.options import SolveOptions
from baarda.quality.dense_model import DenseModel
from baarda.quality.statistics import analyse
from baarda.simulate.aerial import FlightPlan, simulate_block


@pytest.fixture(scope="module")
def problem():
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=6, relief_m=60, seed=5))
    return BundleProblem(block)


def test_damped_and_undamped_reach_the_same_minimum(problem):
    eo, xyz = problem.approximations
    rng = np.random.default_rng(1)
    start = (eo + rng.normal(0, [5, 5, 5, 0.02, 0.02, 0.02], eo.shape), xyz.copy())
    before = (start[0].copy(), start[1].copy())
    gn = problem.fit(start)
    lm = problem.fit(start, options=replace(SOLVE, damping=1e-3))
    assert np.array_equal(start[0], before[0]) and np.array_equal(start[1], before[1])
    assert gn.converged and lm.converged
    assert lm.factor.damping == 0.0 and gn.factor.damping == 0.0  # statistics undamped
    assert lm.vtpv == pytest.approx(gn.vtpv, rel=1e-10)
    assert np.allclose(lm.eo, gn.eo, atol=1e-6) and np.allclose(lm.xyz, gn.xyz, atol=1e-6)


def test_converged_solution_is_the_factored_point(problem):
    res = problem.fit()
    dxf, dxp = res.factor.step()  # the correction at the solution is negligible
    assert problem.correction_size((res.eo, res.xyz), (dxf, dxp)) <= SOLVE.tolerance
    lin = problem.linearize((res.eo, res.xyz))
    assert np.array_equal(lin.e, res.lin.e)


def test_iteration_limit_is_reported(problem):
    res = problem.fit(options=replace(SOLVE, max_iterations=1))
    assert not res.converged
    assert any("not converged after 1 iterations" in n for n in res.notes)


def test_a_result_never_changes(problem):
    first = problem.fit()
    model = BundleModel(first)
    q1 = analyse(model)
    std = first.eo_std.copy()
    out = np.flatnonzero(q1.redundancy_number > 0.4)[:10]  # well controlled ones
    assert len(out) == 10
    active = model.active.copy()
    active[out] = False
    second = model.refit(active)
    q2 = analyse(second)
    assert second.redundancy == model.redundancy - 10
    assert problem.active.all() and first.problem.active.all()  # problems do not change
    assert not second.result.problem.active[out].any()
    assert np.array_equal(first.eo_std, std)  # the first factorisation is its own
    assert np.array_equal(analyse(model).w, q1.w, equal_nan=True)
    assert q2.sigma0_hat != q1.sigma0_hat
    with pytest.raises(ValueError):
        problem.active[0] = False  # read-only


def test_dense_refit_is_the_least_squares_solution_with_new_weights():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(20, 3))
    obs = a @ [1.0, 2.0, -1.0] + rng.normal(0, 0.1, 20)
    sigma = np.full(20, 0.1)
    xh = np.linalg.lstsq(a, obs, rcond=None)[0]
    model = DenseModel(a, sigma, a @ xh - obs)
    active = np.ones(20, bool)
    active[[3, 7]] = False
    f = rng.uniform(0.5, 2.0, 20)
    new = model.refit(active, f)
    p = np.where(active, f / sigma**2, 0.0)
    x2 = np.linalg.solve(a.T @ (p[:, None] * a), a.T @ (p * obs))
    assert np.allclose(new.residuals, a @ x2 - obs, atol=1e-12)
    assert np.allclose(new.sigma, sigma / np.sqrt(f))


def test_dense_problem_final_step_and_stall():
    """Rosenbrock-like curve fit: Gauss-Newton from a poor start; final_step makes the
    solution accurate to the rounding floor."""
    t = np.linspace(0, 2, 30)
    truth = np.array([2.0, -1.3])
    obs = truth[0] * np.exp(truth[1] * t)

    def func(x):
        e = np.exp(x[1] * t)
        return x[0] * e, np.column_stack([e, x[0] * t * e])

    prob = DenseLeastSquares(func, obs, np.ones(30))
    options = SolveOptions(tolerance=1e-6, min_step=1e-6)
    loose = solve(prob, np.array([1.0, 0.0]), options)
    tight = solve(prob, np.array([1.0, 0.0]), replace(options, final_step=True))
    assert loose.converged and tight.converged
    assert np.max(np.abs(tight.state - truth)) < 1e-12 < np.max(np.abs(loose.state - truth))
    assert len(loose.history) == loose.iterations - 1  # the last one found it converged


class _Runaway:
    """y = a x + b with the normal equations declared singular at one factorisation (as
    when a point has run away at that estimate), regular again at the earlier estimate."""

    def __init__(self, fail_from: int):
        self.calls, self.fail_from = 0, fail_from
        self.x = np.linspace(0.0, 1.0, 8)
        self.y = 2.0 * self.x + 1.0 + 0.01 * np.sin(7 * self.x)

    def linearize(self, state):
        a = np.column_stack([self.x, np.ones_like(self.x)])
        e = self.y - a @ state
        return type("Lin", (), {"a": a, "e": e, "cost": float(e @ e)})()

    def factorize(self, lin, damping):
        from baarda.errors import GeometryError

        self.calls += 1
        if self.calls == self.fail_from:
            raise GeometryError("1 point(s) cannot be intersected: P7")
        step = np.linalg.solve(lin.a.T @ lin.a, lin.a.T @ lin.e) * 0.5  # half steps
        return type("F", (), {"step": lambda _self: step, "damping": damping})()

    def update(self, state, step, t):
        return state + t * step

    def correction_size(self, state, step):
        return float(np.abs(step).max())

    def admissible(self, state):
        return True


def test_divergence_during_the_iterations_is_not_converged():
    """Normal equations that become singular during the iterations end the solution as
    not converged (diverged), with the last estimate whose normal equations were regular and
    their factorisation, not as an error about the input (exit 3, results written)."""
    from baarda.errors import GeometryError

    problem = _Runaway(fail_from=3)
    sol = solve(problem, np.zeros(2), SolveOptions(tolerance=1e-12))
    assert not sol.converged and sol.reason == "diverged"
    assert "diverged at iteration 3" in sol.message and "P7" in sol.message
    assert len(sol.history) == 2
    # the estimate reported is the one after two half steps, factored again
    assert problem.calls == 4
    assert sol.cost == pytest.approx(problem.linearize(sol.state).cost)
    with pytest.raises(GeometryError, match="P7"):  # singular at the start: the input
        solve(_Runaway(fail_from=1), np.zeros(2), SolveOptions(tolerance=1e-12))


class _SingularUndamped(_Runaway):
    """Damped normal equations regular everywhere; the undamped ones singular from the
    `fail_from`-th undamped factorisation on (a damped iteration that reaches an estimate
    where a point has run away: BAL Ladybug-49 with free intrinsics, issue 26)."""

    def __init__(self, fail_from: int):
        super().__init__(fail_from)
        self.undamped = 0

    def factorize(self, lin, damping):
        from baarda.errors import GeometryError

        self.calls += 1
        if not damping:
            self.undamped += 1
            if self.undamped >= self.fail_from:
                raise GeometryError("1 point(s) cannot be intersected: P7")
        n = lin.a.T @ lin.a
        n = n + damping * np.diag(np.diag(n))
        step = np.linalg.solve(n, lin.a.T @ lin.e) * 0.5
        return type("F", (), {"step": lambda _self: step, "damping": damping})()


def test_a_damped_run_that_meets_singular_normal_equations_ends_not_converged():
    """Levenberg-Marquardt whose undamped normal equations become singular ends like an
    undamped run (not converged, the last sound estimate, its damped factorisation for the
    statistics, the reason in the message), not with an exception from inside the solver."""
    sol = solve(_SingularUndamped(fail_from=1), np.zeros(2),
                SolveOptions(tolerance=1e-12, damping=1e-3))
    assert not sol.converged and sol.reason == "diverged"
    assert "singular without damping" in sol.message and "P7" in sol.message
    assert sol.factor.damping > 0


class SingularOnce:
    """The problem, but its normal equations at the third factorisation are 'not positive
    definite' (as rounding in a nearly singular photo block made them in a BAL problem of
    5,000 cameras)."""

    def __init__(self, problem):
        self.problem, self.calls, self.refused = problem, 0, []

    def __getattr__(self, name):
        return getattr(self.problem, name)

    def factorize(self, lin, damping=0.0):
        from baarda.errors import GeometryError

        self.calls += 1
        if self.calls == 3:
            self.refused.append(damping)
            raise GeometryError("the exterior orientation of photo 7 is not determined")
        return self.problem.factorize(lin, damping)


def test_levenberg_marquardt_raises_the_damping_of_a_singular_system(problem):
    """A damped system that cannot be factored takes more damping (as a step that does not
    lower the cost does) instead of ending the adjustment as diverged; Gauss-Newton, which
    has no damping to raise, reports the estimate before it as diverged."""
    eo, xyz = problem.approximations
    rng = np.random.default_rng(1)
    start = (eo + rng.normal(0, [5, 5, 5, 0.02, 0.02, 0.02], eo.shape), xyz.copy())
    gn = solve(problem, start, SOLVE)
    flaky = SingularOnce(problem)
    lines = []
    lm = solve(flaky, start, replace(SOLVE, damping=1e-3), lines.append)
    assert len(flaky.refused) == 1
    raised = [s for s in lines if "damping raised to" in s]
    assert len(raised) == 1 and f"raised to {10 * flaky.refused[0]:g}" in raised[0]
    assert lm.converged and lm.reason == "converged" and lm.factor.damping == 0.0
    assert lm.lin.cost == pytest.approx(gn.lin.cost, rel=1e-10)
    assert np.allclose(lm.state[0], gn.state[0], atol=1e-6)
    # Gauss-Newton has no damping to raise: the same failure ends it as diverged
    flaky = SingularOnce(problem)
    out = solve(flaky, start, SOLVE)
    assert flaky.refused == [0.0]
    assert not out.converged and out.reason == "diverged" and "photo 7" in out.message


BAL49 = next((p for p in (Path(__file__).resolve().parents[3] / "shared" / "data" / "bal" /
                          "problem-49-7776-pre.txt.bz2",
                          Path("/work/shared/data/bal/problem-49-7776-pre.txt.bz2"))
              if p.is_file()), None)


@pytest.mark.skipif(BAL49 is None, reason="BAL Ladybug-49 is not on this machine")
def test_levenberg_marquardt_converges_where_gauss_newton_does(tmp_path):
    """Issue 43: 6 cameras of BAL Ladybug-49 and 400 points seen 3+ times: Gauss-Newton
    converged in 26 iterations, Levenberg-Marquardt ended NOT CONVERGED after 100 (damped
    steps tried whole only: the x10 / /10 schedule refused every other step at a damping
    too large to converge).  Damped steps are now halved as Gauss-Newton's are."""
    from baarda.io.bal import BalProblem, read_bal
    from baarda.output.format_files import write_bal
    from baarda.pipeline import adjust, read

    p = read_bal(BAL49)
    cams = np.arange(6)
    sel = np.isin(p.obs_camera, cams)
    pts = np.flatnonzero(np.bincount(p.obs_point[sel], minlength=len(p.points)) >= 3)[:400]
    keep = sel & np.isin(p.obs_point, pts)
    index = np.full(len(p.points), -1)
    index[pts] = np.arange(len(pts))
    write_bal(BalProblem(p.cameras[cams], p.points[pts], p.obs_camera[keep],
                         index[p.obs_point[keep]], p.obs_xy[keep]), tmp_path / "sub.txt")
    block = read(tmp_path / "sub.txt")
    options = replace(SOLVE, max_iterations=100)
    gn = adjust(block, options)
    lm = adjust(block, replace(options, damping=1e-3))
    assert gn.converged and gn.iterations == 26
    assert lm.converged and lm.iterations == 42
    assert lm.vtpv == pytest.approx(gn.vtpv, rel=1e-12)
    assert np.allclose(lm.xyz, gn.xyz, atol=1e-6)


class _RefusedOnce(BundleProblem):
    """The bundle, but its undamped normal equations at the third factorisation are 'not
    positive definite' (rounding in a nearly singular block: BAL-scale 5,000 cameras): the
    Gauss-Newton iteration diverges there."""

    def factorize(self, lin, damping=0.0):
        from baarda.errors import GeometryError

        self.calls = getattr(self, "calls", 0) + 1
        if self.calls == 3 and not damping:
            raise GeometryError("the exterior orientation of photo 7 is not determined")
        return super().factorize(lin, damping)


def test_gauss_newton_divergence_continues_with_levenberg_marquardt(problem):
    """Issue 40: a Gauss-Newton adjustment that diverges continues with Levenberg-Marquardt
    from the last sound estimate; it reaches the minimum `--damping lm` reaches from the
    start (v'Pv to 1e-9), is converged, and the notes say what happened."""
    eo, xyz = problem.approximations
    rng = np.random.default_rng(1)
    start = (eo + rng.normal(0, [5, 5, 5, 0.02, 0.02, 0.02], eo.shape), xyz.copy())
    flaky = copy.copy(problem)
    flaky.__class__ = _RefusedOnce
    gn = solve(flaky, start, SOLVE)
    assert gn.reason == "diverged" and gn.iterations == 3  # what Gauss-Newton alone does
    flaky.calls = 0
    lines = []
    res = flaky.fit(start, progress=lines.append)
    lm = problem.fit(start, options=SOLVE_LM)
    assert res.converged and lm.converged and res.factor.damping == 0.0
    assert res.vtpv == pytest.approx(lm.vtpv, rel=1e-9)
    assert np.allclose(res.eo, lm.eo, atol=1e-6)
    assert res.iterations > gn.iterations
    note = [n for n in res.notes if n.startswith("Gauss-Newton diverged at iteration 3")]
    assert len(note) == 1 and "photo 7" in note[0]
    assert "Levenberg-Marquardt continued from the last sound estimate: converged" in note[0]
    assert not any("--damping lm" in n for n in res.notes)
    assert any("Levenberg-Marquardt continues" in s for s in lines)
    # a run that converges by Gauss-Newton is untouched: the same numbers, no note
    plain = problem.fit(start)
    assert plain.converged and plain.notes == problem.notes
