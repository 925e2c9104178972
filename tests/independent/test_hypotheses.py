"""Non-conventional alternative hypotheses: deformations, control clusters, user H."""

import numpy as np
import pytest

from baarda.block.model_deformations import deformation_rows, model_radius
from baarda.errors import ProjectError
from baarda.independent.model_hypotheses import (
    UserHypotheses,
    cluster_tests,
    decision,
    deformation_h,
    deformation_tests,
)
from baarda.independent.model_problem import adjust_models
from baarda.independent.model_quality import assess, snoop
from baarda.io.hypotheses_files import read_hypotheses
from baarda.quality import hypotheses as hyp
from baarda.quality.dense_model import DenseModel
from baarda.simulate.model_blocks import ModelPlan, simulate_models


@pytest.mark.parametrize("name,size,mode,seed", [("affinity", 12.0, "2d", 5),
                                                 ("torsion", 25.0, "3d", 1)])
def test_planted_block_invariant_deformation_found_by_its_test_not_by_snooping(
        name, size, mode, seed):
    plan = dict(strips=3, models_per_strip=5, layout="fotef", seed=seed, tilt_rad=0.01)
    blk, _ = simulate_models(ModelPlan(deformations={name: size}, **plan))
    qc = snoop(blk, mode)
    assert len(qc.run.log) == 0  # single-observation snooping finds nothing
    tests = {t.name: t for t in deformation_tests(qc.model)}
    t = tests[f"block-invariant {name}"]
    assert t.rejected and t.statistic > 2 * t.critical
    assert t.nabla[0] == pytest.approx(size, rel=0.35)
    assert "systematic-error model needed" in decision(list(tests.values()))
    # the same block without the deformation: accepted
    blk0, _ = simulate_models(ModelPlan(deformations={}, **plan))
    q0 = assess(adjust_models(blk0, mode))
    h, _ = deformation_h(q0.model, name)
    assert not hyp.hypothesis_test(q0.model, h).rejected


def test_deformation_h_is_the_planted_field(small3d):
    """H of a block-invariant deformation reproduces what the simulator plants."""
    blk, _, res = small3d
    qc = assess(res)
    h, labels = deformation_h(qc.model, "radial")
    assert labels == ["radial"]
    field = deformation_rows(blk, "radial")  # per µm, mm = 1e-3 * field
    pb = qc.model.problem
    np.testing.assert_allclose(h[: qc.model.m * 3, 0], 1e-3 * field[pb.rows].ravel())
    hs, ls = deformation_h(qc.model, "radial", "strip")
    assert hs.shape[1] == 2 and len(ls) == 2
    np.testing.assert_allclose(hs.sum(axis=1), h[:, 0])
    assert model_radius(blk) > 0
    assert deformation_h(assess(adjust_models(blk, "height", mu=np.full(blk.n_models, 0.2)))
                         .model, "affinity") is None


def hypothesis_test_tests_agree_with_dense(small2d):
    from model_dense import dense_design

    blk, _, res = small2d
    qc = assess(res)
    dm = DenseModel(dense_design(qc.model), qc.model.sigma, qc.model.residuals)
    h, _ = deformation_h(qc.model, "affinity", "strip")
    a, b = hyp.hypothesis_test(qc.model, h), hyp.hypothesis_test(dm, h)
    assert a.statistic == pytest.approx(b.statistic, rel=1e-8)
    np.testing.assert_allclose(a.nabla, b.nabla, rtol=1e-7)


def test_control_cluster_shift_is_found(tmp_path):
    blk, _ = simulate_models(ModelPlan(strips=2, models_per_strip=4, layout="fotef", seed=3))
    idx = np.flatnonzero(blk.controlled[:, 0])
    near = idx[np.argsort(np.linalg.norm(blk.xyz[idx, :2] - blk.xyz[idx[0], :2], axis=1))]
    ctrl = [blk.points[j] for j in near]
    cluster = ctrl[:3]  # three neighbouring control points shifted together
    for p in cluster:
        blk.xyz[blk.points.index(p), :2] += [0.3, -0.2]  # 6 and 4 sigma
    qc = assess(adjust_models(blk, "2d"))
    t = cluster_tests(qc.model, {"A": cluster, "B": ctrl[-3:]})
    assert t[0].rejected and not t[1].rejected
    np.testing.assert_allclose(t[0].nabla, [0.3, -0.2], atol=0.08)
    # the same hypothesis from a user file
    f = tmp_path / "hypotheses.csv"
    rows = ["hypothesis,kind,model,point,component,value,column"]
    rows += [f"shift,control,,{p},X,1,1" for p in cluster]
    rows += [f"shift,control,,{p},Y,1,2" for p in cluster]
    f.write_text("\n".join(rows) + "\n")
    u = UserHypotheses(read_hypotheses(f)).tests(qc.model)
    assert u[0].statistic == pytest.approx(t[0].statistic)
    f.write_text("hypothesis,kind,model,point,component,value\nx,model,,P1,x,1\n")
    with pytest.raises(ProjectError, match="line 2"):
        UserHypotheses(read_hypotheses(f))
    f.write_text(f"hypothesis,kind,model,point,component,value\nx,model,9.99,{ctrl[0]},x,1\n")
    with pytest.raises(ProjectError, match="not in model"):
        UserHypotheses(read_hypotheses(f)).tests(qc.model)


def test_absorbed_deformation_is_reported_not_testable():
    """z_scale of a flat block moves only the free projection-centre heights: absorbed.
    Without the guard its statistic is rounding noise (it was 'rejected' at T = 39)."""
    blk, _ = simulate_models(ModelPlan(strips=3, models_per_strip=6, seed=0))
    qc = assess(adjust_models(blk, "3d"))
    t = {x.name.split(" (")[0]: x for x in deformation_tests(qc.model, ("z_scale", "torsion"))}
    assert t["block-invariant z_scale"].q == 0 and not t["block-invariant z_scale"].rejected
    assert "not testable" in [x.name for x in deformation_tests(qc.model, ("z_scale",))][0]
    assert t["block-invariant torsion"].q == 1
    joint = [x for x in deformation_tests(qc.model, ("z_scale", "torsion", "bend"))
             if x.name.startswith("all")][0]
    assert joint.q == 2 and "z_scale" not in joint.name
