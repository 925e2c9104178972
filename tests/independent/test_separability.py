"""w-test correlations of an independent-model block (issue 30) against a dense brute force:
pairs of one point and of one model, 3D with projection centres and planimetric."""

import numpy as np
import pytest
from model_dense import dense_design

from baarda.independent.independent_model import IndependentModel
from baarda.independent.model_problem import adjust_models as adjust_once
from baarda.quality.statistics import analyse
from baarda.simulate.model_blocks import ModelPlan, simulate_models


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_correlations_equal_the_dense_ones(mode):
    blk, _ = simulate_models(ModelPlan(strips=2, models_per_strip=4, control_spacing=1,
                                       height_chains=1, seed=4))
    model = IndependentModel(adjust_once(blk, mode))
    q = analyse(model)
    a = dense_design(model)
    p = np.where(model.active, 1 / model.sigma**2, 0.0)
    qll = a @ np.linalg.solve(a.T @ (p[:, None] * a), a.T)
    qvv = -qll
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.sqrt(model.sigma**2 - np.diag(qll))
        rho = np.abs(qvv) / np.outer(d, d)
    np.fill_diagonal(rho, 0.0)
    pt, fr = np.asarray(model.point, object), np.asarray(model.frame, object)
    near = (((pt[:, None] == pt[None, :]) & (pt[:, None] != ""))
            | ((fr[:, None] == fr[None, :]) & (fr[:, None] != "")))
    t = q.controlled & model.active
    near &= t[:, None] & t[None, :]
    want = np.where(near, rho, 0.0).max(axis=1)
    assert np.max(np.abs(q.rho_max[t] - want[t])) < 1e-6
    assert np.all(q.msb[t] >= q.mdb[t])
