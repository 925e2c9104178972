"""quality.statistics.w_correlation against a dense brute-force Q_vv."""

import numpy as np
import pytest

from baarda.quality.dense_model import DenseModel
from baarda.quality.statistics import w_correlation


def brute_rho(a, sigma, active, i):
    p = np.where(active, 1 / sigma**2, 0.0)
    n = a.T @ (p[:, None] * a)
    qll = a @ np.linalg.inv(n) @ a.T
    qvv = np.diag(sigma**2) - qll  # cofactors of the residuals of the active rows
    d = np.sqrt(np.abs(np.diag(qvv)))
    return qvv[:, i] / (d * d[i])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_w_correlation_equals_dense_qvv(seed):
    rng = np.random.default_rng(seed)
    n, u = 14, 4
    a = rng.normal(size=(n, u))
    sigma = rng.uniform(0.5, 2.0, n)
    active = np.ones(n, bool)
    active[[3, 9]] = False
    model = DenseModel(a, sigma, rng.normal(size=n), active)
    for i in np.flatnonzero(active):
        rho = w_correlation(model, i)
        ref = brute_rho(a, sigma, active, i)
        assert rho[i] == pytest.approx(1.0)
        np.testing.assert_allclose(rho[active], ref[active], atol=1e-12)
        assert np.all(rho[~active] == 0.0)  # a predicted residual is uncorrelated with v_i


def test_two_rays_of_one_quantity_are_not_separable():
    """Two observations of one unknown: v1 = -v2, rho = -1 (Foerstner's separability)."""
    a = np.array([[1.0], [1.0], [0.0]])
    model = DenseModel(np.column_stack([a, [0.0, 0.0, 1.0]]), np.ones(3), np.zeros(3),
                       np.array([True, True, True]))
    assert w_correlation(model, 0)[1] == pytest.approx(-1.0)


def test_inactive_component_is_refused():
    model = DenseModel(np.eye(3)[:, :2], np.ones(3), np.zeros(3), np.array([True, True, False]))
    with pytest.raises(ValueError):
        w_correlation(model, 2)


def test_small_model_cofactors_equal_the_dense_model_and_flag_undetermined_rows():
    from baarda.screening.fit import SmallModel

    rng = np.random.default_rng(5)
    a = rng.normal(size=(12, 3))
    sigma = rng.uniform(0.5, 2.0, 12)
    und = np.zeros(12, bool)
    und[4] = True
    dense = DenseModel(a, sigma, np.zeros(12))
    small = SmallModel(a, sigma, np.zeros(12), undetermined=und)
    q = small.adjusted_cofactor_diag()
    np.testing.assert_allclose(q[~und], dense.adjusted_cofactor_diag()[~und], rtol=1e-12)
    assert np.isinf(q[4])
