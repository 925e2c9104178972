"""Qvv P and critical transfers against brute force: re-adjust with a unit error in each
observation and watch every residual move (Kratky and El-Hakim 1983, eq. 5)."""

import numpy as np
import pytest

from baarda.quality.dense_model import DenseModel
from baarda.quality.matrices import critical_transfers, qvv_p_matrix


def _lsq_residuals(a, sigma, l, active):
    """v = A x - l with x from weighted least squares over the active rows only."""
    w = np.where(active, 1.0 / sigma, 0.0)
    x = np.linalg.lstsq(a * w[:, None], l * w, rcond=None)[0]
    return a @ x - l


@pytest.mark.parametrize("rejected", [None, 3])
def test_qvvp_matches_readjustment(rejected):
    rng = np.random.default_rng(7)
    n, u = 12, 4
    a = rng.normal(size=(n, u))
    sigma = rng.uniform(0.5, 2.0, n)
    l = rng.normal(size=n)
    active = np.ones(n, bool)
    if rejected is not None:
        active[rejected] = False
    v0 = _lsq_residuals(a, sigma, l, active)
    model = DenseModel(a, sigma, v0, active)
    m = qvv_p_matrix(model)
    brute = np.empty((n, n))
    for j in range(n):
        lj = l.copy()
        lj[j] += 1.0
        brute[:, j] = -(_lsq_residuals(a, sigma, lj, active) - v0)
    np.testing.assert_allclose(m, brute, atol=1e-12)
    # diagonal of the active part = redundancy numbers, trace = redundancy
    assert np.trace(m[np.ix_(active, active)]) == pytest.approx(model.redundancy)


def test_critical_transfers_explicit_loop():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(7, 5))
    model = DenseModel(a, np.ones(7), np.zeros(7))
    m = qvv_p_matrix(model)
    for level in (1.0, 0.5):
        got = {(t.source, t.target) for t in critical_transfers(m, level)}
        want = {(j, i) for j in range(7) for i in range(7)
                if i != j and abs(m[i, j]) >= level * m[j, j] * (1 - 1e-6)}
        assert got == want
    # a matched value counts (symmetric case): column (1, -1)/2 of a one-redundancy pair
    m2 = np.array([[0.5, -0.5], [-0.5, 0.5]])
    assert {(t.source, t.target) for t in critical_transfers(m2)} == {(0, 1), (1, 0)}
    assert critical_transfers(np.eye(3)) == []
