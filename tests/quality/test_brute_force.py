"""Every quality statistic of the bundle equals a dense brute-force computation."""

import numpy as np
import pytest
from dense import dense_system

from baarda.pipeline import adjust, assess
from baarda.quality.dense_model import DenseModel
from baarda.quality.distributions import b_method
from baarda.quality.hypotheses import group_test, hypothesis_test, image_point_tests
from baarda.quality.statistics import analyse
from baarda.simulate.aerial import FlightPlan, simulate_block

REL = 1e-9


@pytest.fixture(scope="module")
def qc():
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=5, relief_m=40, seed=21,
                                         blunders=2, check_points=2))
    return assess(adjust(block))


@pytest.fixture(scope="module")
def dense(qc):
    a, p = dense_system(qc.model)
    qxx = np.linalg.inv(a.T @ (p[:, None] * a))
    qvv = np.diag(1 / p) - a @ qxx @ a.T
    return a, p, qxx, qvv


def close(x, ref):
    x, ref = np.asarray(x), np.asarray(ref)
    return np.allclose(x, ref, rtol=REL, atol=REL * np.nanmax(np.abs(ref)))


def test_redundancy_numbers_and_sum(qc, dense):
    a, p, qxx, qvv = dense
    r = np.diag(qvv * p[None, :])  # (Qvv P)_ii
    assert close(qc.quality.redundancy_number, r)
    assert close(qc.quality.qvv, np.diag(qvv))
    assert np.sum(r) == pytest.approx(qc.quality.redundancy, rel=1e-9)
    assert qc.quality.sum_redundancy_numbers == pytest.approx(qc.adjustment.redundancy, rel=1e-9)


def test_w_tau_mdb_external(qc, dense):
    a, p, qxx, qvv = dense
    q = qc.quality
    v = qc.model.residuals
    ok = q.controlled
    w = -v / np.sqrt(np.diag(qvv))
    assert close(q.w[ok], w[ok])
    s0 = np.sqrt(v @ (p * v) / q.redundancy)
    assert close(q.tau[ok], w[ok] / s0)
    d0 = b_method().delta0
    r = np.diag(qvv) * p
    assert close(q.mdb[ok], d0 / np.sqrt(p[ok] * r[ok]))
    assert close(q.lambda_bar[ok], d0 * np.sqrt((1 - r[ok]) / r[ok]))
    # external: effect of the MDB on the coordinates of the observed point (dense column)
    nf = qc.model.factor.system.nf
    eff_all = qxx @ (a.T * p[None, :])  # unknowns per unit error
    remap = qc.adjustment.problem.remap
    ids = qc.adjustment.block.point_index
    for i in np.flatnonzero(ok)[::7]:
        j = remap[ids[qc.model.point[i]]]
        ref = eff_all[6 * nf + 3 * j:6 * nf + 3 * j + 3, i] * q.mdb[i]
        assert close(q.external[i], ref)
        assert q.external_max[i] == pytest.approx(np.max(np.abs(ref)), rel=REL)


def test_dense_model_agrees(qc, dense):
    """The DenseModel (used by small adjustments) gives the same statistics."""
    a, p, _, _ = dense
    m = qc.model
    dm = DenseModel(a, m.sigma, m.residuals, m.active)
    q2 = analyse(dm)
    q = qc.quality
    for name in ("qvv", "redundancy_number", "w", "tau", "mdb", "lambda_bar", "p_value"):
        x, y = getattr(q, name), getattr(q2, name)
        sel = np.isfinite(x) & np.isfinite(y)
        assert close(x[sel], y[sel]), name


def test_multidimensional_tests(qc, dense):
    a, p, qxx, qvv = dense
    m = qc.model
    v = m.residuals
    # every image point (2-D) by blocks
    idx, t, qdim, crit, rej = image_point_tests(m)
    assert set(np.unique(qdim)) == {1, 2}  # two-ray points: x not testable
    for g in range(0, len(idx), 3):
        rows = idx[g]
        vals, vecs = np.linalg.eigh(qvv[np.ix_(rows, rows)])
        keep = vals > 1e-6 * np.max(1 / p[rows])
        ref = np.sum((vecs[:, keep].T @ v[rows]) ** 2 / vals[keep]) / keep.sum()
        assert qdim[g] == keep.sum()
        assert t[g] == pytest.approx(ref, rel=1e-7)
        assert crit[g] == pytest.approx(b_method().critical_F(int(keep.sum())))
    # a whole ground point and a whole photo: via one forward substitution
    for rows in (np.flatnonzero(m.point == m.point[10]), np.flatnonzero(m.frame == m.frame[0])):
        res = group_test(m, rows, "group")
        pq = p[rows][:, None] * qvv[np.ix_(rows, rows)] * p[rows][None, :]
        vals, vecs = np.linalg.eigh(pq)
        keep = vals > 1e-9 * vals.max()
        pinv = (vecs[:, keep] / vals[keep]) @ vecs[:, keep].T
        pv = p[rows] * v[rows]
        assert res.q == keep.sum()
        assert res.statistic == pytest.approx(pv @ pinv @ pv / res.q, rel=1e-7)
    # a non-conventional H (one dimension): w = H^T P v / sqrt(H^T P Qvv P H) with sign
    rng = np.random.default_rng(1)
    h = rng.normal(size=m.n)
    res = hypothesis_test(m, h)
    ref = -(h @ (p * v)) / np.sqrt(h @ (p[:, None] * qvv * p[None, :]) @ h)
    assert res.w == pytest.approx(ref, rel=1e-8)
    assert res.statistic == pytest.approx(ref**2, rel=1e-8)


def test_gruen_columns_and_group_shortcuts(qc, dense):
    from baarda.quality.statistics import qvv_columns
    a, p, qxx, qvv = dense
    rows = np.array([0, 5, len(p) - 1])
    cols = qvv_columns(qc.model, rows)
    assert np.allclose(cols, qvv[:, rows], rtol=1e-8, atol=1e-10 * np.abs(qvv).max())
    pid = qc.model.point[10]
    t = qc.point_test(pid)
    ref = group_test(qc.model, np.flatnonzero(qc.model.point == pid), "x")
    assert t.statistic == pytest.approx(ref.statistic) and t.q == ref.q
    photo = qc.model.frame[0]
    assert qc.photo_test(photo).q > 0


def test_absorbed_hypothesis_is_not_testable(qc):
    """An H that the adjustment absorbs (a shift of a tie point's ground coordinates seen
    through all its rays, i.e. A times a point correction) has no testable dimension."""
    m = qc.model
    s = m.factor.system
    j = int(np.flatnonzero(np.bincount(s.point) >= 3)[0])
    xp = np.zeros((s.np, 3, 1))
    xp[j, 2, 0] = 1.0  # a height shift of point j
    ri, rc = m.factor.apply_A(np.zeros((s.nf, 6, 1)), xp)
    h = m.layout.flat(ri, rc)[:, 0]
    res = hypothesis_test(m, h)
    assert res.q == 0 and not res.rejected
