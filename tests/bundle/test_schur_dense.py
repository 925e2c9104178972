"""The sparse Schur machinery equals dense brute force on a small block."""

import numpy as np
import pytest
from dense import dense_system

from baarda.bundle.bundle_model import BundleModel
from baarda.pipeline import adjust
from baarda.simulate.aerial import FlightPlan, simulate_block


@pytest.fixture(scope="module")
def model():
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=4, relief_m=30,
                                         stereo=True, side_overlap=0.6, seed=3))
    return BundleModel(adjust(block))


def test_solution_is_stationary(model):
    a, p = dense_system(model)
    # at convergence A^T P v = 0
    g = a.T @ (p * model.residuals)
    assert np.max(np.abs(g)) < 1e-7 * np.max(np.abs(a.T @ (p * np.abs(model.residuals))))


def test_covariances_equal_dense_inverse(model):
    a, p = dense_system(model)
    qxx = np.linalg.inv(a.T @ (p[:, None] * a))
    s = model.factor.system
    nf = s.nf
    sff = model.factor.frame_covariance()
    spp = model.factor.point_covariance()
    for k in range(nf):
        ref = qxx[6 * k:6 * k + 6, 6 * k:6 * k + 6]
        assert np.allclose(sff[k], ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())
    for j in range(s.np):
        ref = qxx[6 * nf + 3 * j:6 * nf + 3 * j + 3, 6 * nf + 3 * j:6 * nf + 3 * j + 3]
        assert np.allclose(spp[j], ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())
    qhat = np.einsum("ij,jk,ik->i", a, qxx, a)
    assert np.allclose(model.adjusted_cofactor_diag(), qhat, rtol=1e-9,
                       atol=1e-12 * qhat.max())
    idx, blocks = model.adjusted_cofactor_blocks()
    full = a @ qxx @ a.T
    ref = full[idx[:, :, None], idx[:, None, :]]
    assert np.allclose(blocks, ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())


def test_column_products_equal_dense(model):
    a, p = dense_system(model)
    nmat = a.T @ (p[:, None] * a)
    rng = np.random.default_rng(0)
    h = rng.normal(size=(model.n, 3))
    ref = a @ np.linalg.solve(nmat, a.T @ (p[:, None] * h))
    assert np.allclose(model.solve_columns(h), ref, rtol=1e-8, atol=1e-10 * np.abs(ref).max())
    w = model.normal_forward(h)
    g = a.T @ (p[:, None] * h)
    assert np.allclose(w.T @ w, g.T @ np.linalg.solve(nmat, g), rtol=1e-9)
