"""Every statistic of the sparse independent-model adjustment against a dense brute force.

The dense reference builds A from scratch (central differences of the observation
function, not the analytic Jacobians) and computes N^-1 densely; the quality layer is the
same in both (quality.statistics / quality.hypotheses), so equal inputs must give equal
statistics.
"""

import numpy as np
import pytest
from model_dense import dense_design

from baarda.independent.independent_model import IndependentModel
from baarda.independent.model_problem import adjust_models
from baarda.quality import hypotheses as hyp
from baarda.quality.dense_model import DenseModel
from baarda.quality.statistics import analyse
from baarda.simulate.model_blocks import ModelPlan, simulate_models


def numeric_design(res, h=1e-6):
    """-d e / d unknowns by central differences of problem.linearize (flat, quality order)."""
    pb = res.problem
    qm = IndependentModel(res)
    nf, b = res.params.shape
    u0 = np.concatenate([res.params.ravel(), res.pts.ravel()])

    def flat_e(u):
        lin = pb.linearize((u[: nf * b].reshape(nf, b), u[nf * b:].reshape(res.pts.shape)))
        return np.concatenate([lin.e.ravel(), lin.ec.ravel()[qm.layout.ctrl_sel]])

    cols = []
    for i in range(len(u0)):
        du = np.zeros_like(u0)
        step = h * max(1.0, abs(u0[i])) if i < nf * b else 1e-4
        du[i] = step
        cols.append(-(flat_e(u0 + du) - flat_e(u0 - du)) / (2 * step))
    return np.column_stack(cols), flat_e(u0)


def check_against_dense(res, rtol=1e-6):
    qm = IndependentModel(res)
    a_num, e = numeric_design(res)
    a = dense_design(qm)
    np.testing.assert_allclose(a_num, a, rtol=1e-5, atol=1e-7 * np.abs(a).max())
    p = np.where(qm.active, 1 / qm.sigma**2, 0)
    grad = a.T @ (p * e)
    assert np.abs(grad).max() < 1e-8 * np.abs(a.T @ (p * np.abs(e))).max()  # optimum
    dm = DenseModel(a, qm.sigma, qm.residuals, qm.active, group=qm.group)
    qs, qd = analyse(qm), analyse(dm)
    for name in ("qvv", "redundancy_number", "w", "tau", "mdb", "lambda_bar"):
        x, y = getattr(qs, name), getattr(qd, name)
        fin = np.isfinite(y)
        np.testing.assert_array_equal(np.isfinite(x), fin)
        # q_vv and r of uncontrolled components are zero up to cancellation (~1e-8 sigma^2)
        tiny = {"qvv": 1e-7 * np.max(qm.sigma**2), "redundancy_number": 1e-7}.get(name, 0)
        np.testing.assert_allclose(x[fin], y[fin], rtol=rtol,
                                   atol=max(tiny, 1e-9 * np.abs(y[fin]).max()))
    assert qs.vtpv == pytest.approx(qd.vtpv, rel=1e-9)
    assert qs.redundancy == qd.redundancy
    assert qs.sum_redundancy_numbers == pytest.approx(qs.redundancy, rel=1e-8)
    # effect of a unit error on the observation's own point: columns of N^-1 A^T P
    eff, _ = qm.point_effect()
    full = dm.qxx @ (a.T * p[None, :])  # (u, n)
    pb = qm.problem
    nf_b = pb.system.nf * pb.b
    own = np.concatenate([pb.remap[pb.block.obs_point[pb.rows]].repeat(pb.k),
                          np.repeat(pb.remap[pb.control], pb.k)[qm.layout.ctrl_sel]])
    cols = nf_b + own[:, None] * pb.d + np.arange(pb.d)[None, :]
    ref = full[cols, np.arange(qm.n)[:, None]]
    np.testing.assert_allclose(eff[:, pb.comps], ref, rtol=1e-6, atol=1e-9 * np.abs(ref).max())
    # parameter effects, grouped tests and a general hypothesis
    h = np.random.default_rng(0).normal(size=(qm.n, 3))
    xf, xp = qm.parameter_effect(h)
    np.testing.assert_allclose(np.concatenate([xf.reshape(nf_b, 3), xp.reshape(-1, 3)]),
                               full @ h, rtol=1e-6, atol=1e-9 * np.abs(full @ h).max())
    idx = np.flatnonzero(qm.active)[::7]
    uf, up = qm.unit_effect(idx)
    np.testing.assert_allclose(np.concatenate([uf.reshape(nf_b, -1), up.reshape(-1, len(idx))]),
                               full[:, idx], rtol=1e-6, atol=1e-9 * np.abs(full).max())
    ts, td = hyp.hypothesis_test(qm, h), hyp.hypothesis_test(dm, h)
    assert ts.statistic == pytest.approx(td.statistic, rel=1e-7)
    np.testing.assert_allclose(ts.nabla, td.nabla, rtol=1e-6)
    _, t2s, q2s, _, _ = hyp.image_point_tests(qm)
    _, t2d, q2d, _, _ = hyp.image_point_tests(dm)
    np.testing.assert_array_equal(q2s, q2d)
    fin = np.isfinite(t2d)
    assert fin.sum() > 0.5 * len(t2d) > 0
    np.testing.assert_allclose(t2s[fin], t2d[fin], rtol=1e-6, atol=1e-9)
    return qm, qs


def test_3d_statistics_match_dense(small3d):
    blk, _, res = small3d
    check_against_dense(res)


def test_2d_statistics_match_dense(small2d):
    blk, _, res = small2d
    check_against_dense(res)


def test_height_statistics_match_dense(small2d):
    blk, _, res2 = small2d
    resh = adjust_models(blk, "height", mu=res2.params[:, 3])
    check_against_dense(resh)


def test_rejected_components_are_predicted(small3d):
    blk, _, res = small3d
    keep = np.ones((len(blk.obs_model), 3), bool)
    keep[[3, 10], [0, 2]] = False
    ckeep = np.ones((blk.n_points, 3), bool)
    ckeep[np.flatnonzero(blk.role == "control")[0], 1] = False
    r2 = adjust_models(blk, "3d", start=(res.params, res.pts), obs_keep=keep,
                       control_keep=ckeep)
    qm, qs = check_against_dense(r2)
    assert (~qm.active).sum() == 3
    assert np.all(qs.redundancy_number[~qm.active] > 0)


def test_full_covariance_matches_dense_gls():
    """Per-row decorrelation = generalised least squares with the full 3x3 covariances."""
    blk, _ = simulate_models(ModelPlan(strips=1, models_per_strip=3, seed=4,
                                       height_chains=1))
    rng = np.random.default_rng(1)
    m = len(blk.obs_model)
    rho = rng.uniform(-0.6, 0.6, (m, 3))
    corr = np.repeat(np.eye(3)[None], m, 0)
    for k, (i, j) in enumerate(((0, 1), (0, 2), (1, 2))):
        corr[:, i, j] = corr[:, j, i] = rho[:, k] * 0.7
    blk.obs_cov = corr * blk.obs_sigma[:, :, None] * blk.obs_sigma[:, None, :]
    res = adjust_models(blk, "3d")
    qm, qs = check_against_dense(res)
    # dense GLS in the original (correlated) observations at the same linearisation point
    pb = res.problem
    ginv = np.linalg.inv(pb.transform)
    a = dense_design(qm)
    mk = qm.m * qm.k
    a_orig = a.copy()
    a_orig[:mk] = np.einsum("mij,mjq->miq", ginv, a[:mk].reshape(qm.m, 3, -1)).reshape(mk, -1)
    v_orig = np.einsum("mij,mj->mi", ginv, res.model_residuals).ravel()
    pfull = np.zeros((qm.n, qm.n))
    cov = blk.obs_cov[pb.rows]
    for i in range(qm.m):
        pfull[3 * i:3 * i + 3, 3 * i:3 * i + 3] = np.linalg.inv(cov[i])
    pfull[mk:, mk:] = np.diag(1 / qm.sigma[mk:] ** 2)
    v = np.concatenate([v_orig, qm.residuals[mk:]])
    assert v @ pfull @ v == pytest.approx(qs.vtpv, rel=1e-9)
    n = a_orig.T @ pfull @ a_orig
    dx = np.linalg.solve(n, a_orig.T @ pfull @ v)  # GLS step from the solution: nil
    assert np.all(np.abs(dx) < 1e-6 * np.sqrt(np.diag(np.linalg.inv(n))))
    qvv = np.linalg.inv(pfull) - a_orig @ np.linalg.solve(n, a_orig.T)
    # three-dimensional test of each model point in the original coordinates
    _, t3, q3, _, _ = hyp.image_point_tests(qm)
    full = np.flatnonzero(np.isfinite(t3) & (q3 == 3))
    assert len(full) >= 10
    for i in full[::3]:
        hh = np.zeros((qm.n, 3))
        hh[3 * i:3 * i + 3] = np.eye(3)
        aa = hh.T @ pfull @ v
        mm = hh.T @ pfull @ qvv @ pfull @ hh
        assert t3[i] == pytest.approx(aa @ np.linalg.solve(mm, aa) / 3, rel=1e-6)
