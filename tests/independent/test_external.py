"""FOTEF's external reliability (detail points, distances) against a dense brute force."""

import numpy as np
import pytest
from model_dense import dense_design

from baarda.independent import similarity
from baarda.independent.external import external_reliability
from baarda.independent.independent_model import IndependentModel
from baarda.independent.model_problem import adjust_models
from baarda.quality.statistics import analyse
from baarda.simulate.model_blocks import ModelPlan, simulate_models


def brute_force(res, idx):
    """Largest detail-point, same-model and adjacent-model distance effect of unit errors."""
    qm = IndependentModel(res)
    pb, bl = qm.problem, qm.problem.block
    a = dense_design(qm)
    p = np.where(qm.active, 1 / qm.sigma**2, 0)
    n = a.T @ (p[:, None] * a)
    nf, b = res.params.shape
    out = []
    rows = [i for i in range(len(pb.rows)) if not bl.pc[bl.obs_point[pb.rows[i]]]]
    for i in idx:
        dx = np.linalg.solve(n, a.T @ (p * np.eye(qm.n)[i]))
        dpar = dx[: nf * b].reshape(nf, b)
        eps = 1e-4

        def terrain(params):
            m = pb.frame[rows]
            x = bl.obs_xyz[pb.rows[rows]]
            c = pb.centroid[m]
            if pb.mode == "3d":
                return similarity.forward3d(params[m], x, c)[0]
            return similarity.forward2d(params[m], x[:, :2], c[:, :2])[0]

        x0 = terrain(res.params)
        disp = (terrain(res.params + eps * dpar) - terrain(res.params - eps * dpar)) / (2 * eps)
        pt = np.max(np.linalg.norm(disp, axis=1))
        frames = pb.frame[rows]
        pid = bl.obs_point[pb.rows[rows]]
        share = {(m1, m2) for j in set(pid) for m1 in frames[pid == j] for m2 in frames[pid == j]}
        same = diff = 0.0
        for r1 in range(len(rows)):
            for r2 in range(r1 + 1, len(rows)):
                u = x0[r2] - x0[r1]
                dd = abs(u @ (disp[r2] - disp[r1])) / np.linalg.norm(u)
                if frames[r1] == frames[r2]:
                    same = max(same, dd)
                elif (frames[r1], frames[r2]) in share and pid[r1] != pid[r2]:
                    diff = max(diff, dd)
        out.append((pt, same, diff))
    return np.array(out)


@pytest.mark.parametrize("fixture", ["small3d", "small2d"])
def test_external_matches_brute_force(fixture, request):
    _, _, res = request.getfixturevalue(fixture)
    qm = IndependentModel(res)
    q = analyse(qm)
    ok = np.flatnonzero(q.active & q.controlled)
    idx = ok[np.linspace(0, len(ok) - 1, 7).astype(int)]
    ext = external_reliability(qm, q, idx, chunk=3)
    ref = brute_force(res, idx) * q.mdb[idx][:, None]
    np.testing.assert_allclose(ext.point, ref[:, 0], rtol=1e-5)
    np.testing.assert_allclose(ext.dist_same, ref[:, 1], rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(ext.dist_diff, ref[:, 2], rtol=1e-5, atol=1e-9)
    # nabla in the terrain: model MDB (mm) times the model scale 1/mu
    np.testing.assert_allclose(ext.nabla, q.mdb[idx] * qm.terrain_per_unit[idx])
    mod = qm.kind[idx] == "model"
    mu = res.params[qm.problem.frame[qm.group[idx[mod]]], -1]
    np.testing.assert_allclose(ext.nabla[mod], q.mdb[idx][mod] / mu)


def test_model_and_terrestrial_error_of_a_one_model_control_point_are_twins():
    """FOTEF App. II: a control point in one model gives the same boundary value and the
    same effects for an error in its terrestrial or in its model coordinate (10 µm at
    1:5000 = 5 cm = the control sigma)."""
    blk, _ = simulate_models(ModelPlan(strips=2, models_per_strip=3, kappa_rad=0.0, seed=5))
    res = adjust_models(blk, "2d")
    qm = IndependentModel(res)
    q = analyse(qm)
    once = [j for j in np.flatnonzero(blk.models_per_point() == 1) if blk.controlled[j, 0]]
    assert once
    for j in once[:3]:
        pid = blk.points[j]
        for comp in ("x", "y"):
            i_t = np.flatnonzero((qm.kind == "control") & (qm.point == pid)
                                 & (qm.component == comp.upper()))[0]
            i_m = np.flatnonzero((qm.kind == "model") & (qm.point == pid)
                                 & (qm.component == comp))[0]
            ext = external_reliability(qm, q, np.array([i_t, i_m]))
            assert q.redundancy_number[i_t] == pytest.approx(q.redundancy_number[i_m], rel=2e-3)
            assert ext.nabla[0] == pytest.approx(ext.nabla[1], rel=2e-3)
            np.testing.assert_allclose(ext.point_prop[0], ext.point_prop[1], rtol=2e-3)
            np.testing.assert_allclose(ext.same_prop[0], ext.same_prop[1], rtol=2e-3)
