"""Tests of grouped and non-conventional alternative hypotheses (Baarda 1968; FOTEF sec. 5).

An alternative hypothesis H_a: l = A x + H nabla + e with a known (n, q) matrix H.

    a  = H^T P v
    M  = H^T P Qvv P H = H^T P H - W^T W,   W = L^-1 A^T P H  (one forward substitution)
    T  = a^T M^-1 a              ~ chi2(q) under H0 (sigma0 a priori)
    nabla_hat = -M^-1 a          (estimated size of the error complex)
    q = 1:  w = -a / sqrt(M),    MDB along H: delta0 / sqrt(M)

T/q is compared with the B-method critical value of F(q, inf) (same lambda0 and beta0 as
the one-dimensional w-test).  Directions of H that the adjustment absorbs (M singular) are
dropped: q counts only the testable dimensions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.options import DEFAULT_TESTS, TestOptions
from baarda.quality.adjusted_model import AdjustedModel
from baarda.quality.distributions import b_method, multidim_test
from baarda.quality.statistics import R_MIN


@dataclass(frozen=True)
class HypothesisTest:
    name: str
    q: int  # testable dimensions
    statistic: float  # T / q
    critical: float
    p_value: float
    rejected: bool
    nabla: np.ndarray  # (q_given,) estimated bias in the units of H's columns
    w: float | None  # one-dimensional test statistic (q = 1)
    mdb: float | None  # boundary value along H (q = 1)
    parameters: bool = False  # a test of estimated parameters (significant or not)

    def summary(self) -> str:
        verdict = (("significant" if self.rejected else "not significant: may be dropped")
                   if self.parameters else ("REJECTED" if self.rejected else "accepted"))
        s = (f"{self.name}: T/q = {self.statistic:.3f} (q = {self.q}), critical "
             f"{self.critical:.3f}, p = {self.p_value:.3g} -> {verdict}")
        if self.w is not None:
            s += f"; w = {self.w:.2f}, MDB = {self.mdb:.4g}"
        return s + f"; estimated bias {np.array2string(self.nabla, precision=4)}"


def hypothesis_test(model: AdjustedModel, h: np.ndarray, name: str = "H",
                    tests: TestOptions = DEFAULT_TESTS, r_min: float = R_MIN) -> HypothesisTest:
    """Test the alternative hypothesis given by the columns of h (n, q).

    The test is carried out in the directions of H that the observations control: with
    G = H^T P H, the generalised eigenvalues of M u = lambda G u are the redundancy numbers
    of those directions (0 <= lambda <= 1); directions with lambda < r_min are absorbed by
    the adjustment (no other observation checks them) and are left out of q, as
    uncontrolled single observations are left out of the w-test.
    """
    h = np.asarray(h, float)
    if h.ndim == 1:
        h = h[:, None]
    p = np.where(model.active, 1.0 / model.sigma**2, 0.0)
    a = h.T @ (p * model.residuals)
    wmat = model.normal_forward(h)
    g = h.T @ (p[:, None] * h)
    m = g - wmat.T @ wmat
    m = 0.5 * (m + m.T)
    bm = b_method(tests.alpha0, tests.beta0)
    # whiten by G (restricted to its range), then the eigenvalues are redundancy numbers
    gv, gvec = np.linalg.eigh(0.5 * (g + g.T))
    rng = gv > 1e-12 * max(gv.max(initial=0.0), 1e-300)
    c = gvec[:, rng] / np.sqrt(gv[rng])  # (q_given, q_range): C^T G C = I
    lam, u = np.linalg.eigh(c.T @ m @ c)
    keep = lam > r_min
    q = int(keep.sum())
    if q == 0:
        return HypothesisTest(name, 0, np.nan, np.nan, np.nan, False, np.full(h.shape[1], np.nan),
                              None, None)
    cu = c @ u[:, keep]  # directions in the parameters of H
    proj = cu.T @ a
    t = float(np.sum(proj**2 / lam[keep]))
    nabla = -cu @ (proj / lam[keep])
    res = multidim_test(t, q, bm.alpha_for(q))
    w = mdb = None
    if h.shape[1] == 1:
        w = float(-a[0] / np.sqrt(m[0, 0]))
        mdb = float(bm.delta0 / np.sqrt(m[0, 0]))
    return HypothesisTest(name, q, res.statistic, res.critical, res.p_value, bool(res.rejected),
                          nabla, w, mdb)


PARAMETER_ALPHA = 0.05  # level of the significance tests of estimated parameters


def parameter_test(name: str, estimate: np.ndarray, cofactor: np.ndarray,
                   tests: TestOptions = DEFAULT_TESTS,
                   alpha: float = PARAMETER_ALPHA) -> HypothesisTest:
    """Are estimated parameters (additional parameters of a self-calibration) significant?

    T = x^T Q_xx^-1 x with their cofactor matrix Q_xx (sigma0 a priori), chi2(q) under
    H0: x = 0; T/q against the critical value of F(q, inf) at the conventional level
    `alpha` (the question is whether to keep parameters, not to find an error: the
    B-method's level grows with q and would keep more of a large set such as Ebner's 12).
    At the linear level this equals the test of the alternative hypothesis H = the
    parameters' design columns in the adjustment without them (Baarda's non-conventional
    hypothesis); the MDB (q = 1) is the B-method's."""
    x = np.atleast_1d(np.asarray(estimate, float))
    q = np.atleast_2d(np.asarray(cofactor, float))
    t = float(x @ np.linalg.solve(q, x))
    bm = b_method(tests.alpha0, tests.beta0)
    res = multidim_test(t, len(x), alpha)
    w = mdb = None
    if len(x) == 1:
        w = float(x[0] / np.sqrt(q[0, 0]))
        mdb = float(bm.delta0 * np.sqrt(q[0, 0]))
    return HypothesisTest(name, len(x), res.statistic, res.critical, res.p_value,
                          bool(res.rejected), x, w, mdb, parameters=True)


def unit_columns(n: int, rows: np.ndarray) -> np.ndarray:
    """H of the conventional hypothesis that the components `rows` are in error together."""
    h = np.zeros((n, len(rows)))
    h[rows, np.arange(len(rows))] = 1.0
    return h


def group_test(model: AdjustedModel, rows: np.ndarray, name: str,
               tests: TestOptions = DEFAULT_TESTS) -> HypothesisTest:
    """All components `rows` in error at once (an image point, a ground point, a photo)."""
    rows = np.asarray(rows)
    rows = rows[model.active[rows]]
    return hypothesis_test(model, unit_columns(model.n, rows), name, tests)


def image_point_tests(model: AdjustedModel, tests: TestOptions = DEFAULT_TESTS):
    """Test of every group (an image point: x and y together), vectorised.

    T = v^T Qvv^+ v with the k x k block Qvv = diag(sigma^2) - Q_ll^ of the group; a
    direction with (numerically) zero cofactor is not testable and drops out of q (the x
    of a two-ray point: Gruen's R2(x) = 0).  Returns (group index (g, k), T/q (g,),
    q (g,), critical value of T/q (g,), rejected (g,)).
    """
    idx, qhat = model.adjusted_cofactor_blocks()
    return block_tests(model, idx, qhat, tests)


def block_tests(model: AdjustedModel, idx: np.ndarray, qhat: np.ndarray,
                tests: TestOptions = DEFAULT_TESTS):
    """The test of groups of components `idx` (g, k) as a whole from the cofactor blocks of
    their adjusted values `qhat` (g, k, k), as image_point_tests."""
    if len(idx) == 0:
        z = np.zeros(0)
        return idx, z, z.astype(int), z, z.astype(bool)
    k = idx.shape[1]
    s2 = model.sigma[idx] ** 2
    qvv = -qhat
    qvv[:, np.arange(k), np.arange(k)] += s2
    vals, vecs = np.linalg.eigh(qvv)
    tol = 1e-6 * s2.max(axis=1, keepdims=True)
    ok = vals > tol
    proj = np.einsum("gik,gi->gk", vecs, model.residuals[idx])
    t = np.sum(np.where(ok, proj**2 / np.where(ok, vals, 1.0), 0.0), axis=1)
    q = ok.sum(axis=1)
    act = model.active[idx].all(axis=1) & (q > 0)
    bm = b_method(tests.alpha0, tests.beta0)
    crit_q = {int(d): bm.critical_F(int(d)) for d in np.unique(q[q > 0])}
    crit = np.full(len(q), np.nan)
    for d, c in crit_q.items():
        crit[q == d] = c
    stat = np.where(act, t / np.maximum(q, 1), np.nan)
    return idx, stat, q, crit, np.nan_to_num(stat) > np.nan_to_num(crit, nan=np.inf)
