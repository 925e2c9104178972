"""rho_max, its partner and the MSB of analyse() against the dense A N^-1 A^T (issue 30): the
check shared by the tests of every kind of block."""

import numpy as np
from dense import dense_system

from baarda.quality.statistics import analyse


def dense_correlations(model) -> np.ndarray:
    """|rho_ij| of every two tested components from the dense A N^-1 A^T (rejected
    components predicted: uncorrelated with the active ones)."""
    a, p = dense_system(model)
    qll = a @ np.linalg.solve(a.T @ (p[:, None] * a), a.T)
    s2 = model.sigma**2
    act = model.active
    qvv = np.where(act[:, None] & act[None, :], -qll, 0.0)
    both_out = ~act[:, None] & ~act[None, :]
    qvv = np.where(both_out, qll, qvv)
    d = np.where(act, s2 - np.diag(qll), s2 + np.diag(qll))
    with np.errstate(invalid="ignore"):  # d of an uncontrolled component (r ~ 0) may round
        rho = np.abs(qvv) / np.sqrt(np.outer(d, d))  # below 0: it is not tested
    np.fill_diagonal(rho, 0.0)
    return rho


def neighbours(model) -> np.ndarray:
    pt, fr = np.asarray(model.point, object), np.asarray(model.frame, object)
    return (((pt[:, None] == pt[None, :]) & (pt[:, None] != ""))
            | ((fr[:, None] == fr[None, :]) & (fr[:, None] != "")))


def check(model, atol=1e-6):
    q = analyse(model)
    rho = dense_correlations(model)
    tested = q.controlled
    near = neighbours(model) & tested[:, None] & tested[None, :]
    want = np.where(near, rho, 0.0).max(axis=1)
    t = np.flatnonzero(tested)
    assert np.max(np.abs(q.rho_max[t] - want[t])) < atol
    has = t[want[t] > 0]
    assert np.all(q.rho_partner[has] >= 0)
    assert np.max(np.abs(rho[has, q.rho_partner[has]] - want[has])) < atol
    assert np.all(near[has, q.rho_partner[has]])
    assert np.all(np.isnan(q.rho_max[~tested]))
    assert np.all(q.msb[t] >= q.mdb[t] * (1 - 1e-12))
    return q, rho, near
