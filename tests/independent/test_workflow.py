"""Pre-adjustment search, data snooping and the whole procedure on simulated blocks."""

import numpy as np
import pytest

from baarda.errors import GeometryError
from baarda.independent.model_problem import ModelProblem, adjust_models
from baarda.independent.planimetric import check_tilts, level
from baarda.independent.preadjust import preadjust
from baarda.independent.workflow import process
from baarda.simulate.model_blocks import ModelPlan, simulate_models


def planted_block():
    blk, truth = simulate_models(ModelPlan(strips=2, models_per_strip=4, layout="fotef",
                                           seed=7, tilt_rad=0.01, height_chains=2))
    rows = {}
    # a 1.5 mm error in x of a tie point in model 1.03 (150 sigma)
    i = np.flatnonzero((blk.obs_model == 2) & ~blk.pc[blk.obs_point])[3]
    blk.obs_xyz[i, 0] += 1.5
    rows["x"] = i
    # an identification error: two points of model 2.02 exchanged
    r = np.flatnonzero((blk.obs_model == 5) & ~blk.pc[blk.obs_point])[[0, 5]]
    blk.obs_xyz[r] = blk.obs_xyz[r[::-1]].copy()
    rows["swap"] = r
    # a 4 m error in a control X
    j = np.flatnonzero(blk.controlled[:, 0])[4]
    blk.xyz[j, 0] += 4.0
    rows["control"] = j
    return blk, rows


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_preadjustment_finds_the_large_errors_first(mode):
    blk, rows = planted_block()
    pre = preadjust(ModelProblem(blk, mode))
    found = {f.point: f for f in pre.findings}
    # the 1.5 mm error: a point in two models, found in full size (either model)
    p = blk.points[blk.obs_point[rows["x"]]]
    assert np.hypot(*found[p].discrepancy[:2]) == pytest.approx(1500, rel=0.1)
    # the exchanged points: the one in four models is put on the right model
    swapped = [blk.points[blk.obs_point[r]] for r in rows["swap"]]
    four = [q for q in swapped if blk.models_per_point()[blk.points.index(q)] == 4]
    named = {f.model for f in pre.findings if f.point == four[0]}
    if mode == "2d":  # strips connected in one sub-block: the leave-one-out verdict
        assert named == {"2.02"}
    else:  # strips joined by points on a line are not compared (drift): two rows in strip 2
        assert named & {"2.02", "2.01 (or the other model of this point)"}
    pts_swapped = np.isin(blk.obs_point, blk.obs_point[rows["swap"]])
    assert pre.obs_flag[pts_swapped].any(axis=1).sum() >= 2
    if mode == "2d":
        assert pre.obs_flag[rows["swap"]].any(axis=1).sum() >= 1
    assert pre.control_flag[rows["control"], 0]
    # nothing else (3d: also the join of the strips names the point), large errors first
    assert len(pre.findings) == (4 if mode == "2d" else 5)
    ratios = [f.ratio for f in pre.findings if f.kind == "connection"]
    assert ratios == sorted(ratios, reverse=True)


def test_process_cleans_the_block_and_the_result_is_right():
    blk, rows = planted_block()
    _, truth = simulate_models(ModelPlan(strips=2, models_per_strip=4, layout="fotef",
                                         seed=7, tilt_rad=0.01, height_chains=2))
    bq = process(blk, "3d", deformations=("affinity",))
    qc = bq.part("3d")
    assert qc.quality.global_test.passed
    rej = ~qc.quality.active
    m = qc.model
    p = blk.obs_point[rows["x"]]
    assert np.any(rej & np.isin(m.block_row, np.flatnonzero(blk.obs_point == p)))
    # the exchanged point in four models: snooping rejects the wrong row (model 2.02) even
    # where the pre-adjustment could only name the other model of its strip
    swapped = blk.obs_point[rows["swap"]]
    four = [j for j in swapped if blk.models_per_point()[j] == 4][0]
    wrong = [r for r in rows["swap"] if blk.obs_point[r] == four][0]
    assert np.all(rej[m.block_row == wrong])
    others = np.flatnonzero((blk.obs_point == four) & (np.arange(len(blk.obs_point)) != wrong))
    assert not np.any(rej[np.isin(m.block_row, others)])
    assert np.any(rej & (m.block_point == rows["control"]) & (m.xyz_col == 0))
    res = qc.adjustment
    pts = np.array([truth["points"][blk.points[j]] for j in res.problem.point_ids])
    err = np.abs(res.xyz - pts) / res.xyz_std
    assert np.percentile(err, 95) < 3.5
    assert "pre-adjustment search" in bq.summary()
    d = bq.to_dict()
    assert d["adjustments"]["3d"]["n_rejected"] == int(rej.sum())


def test_snooping_finds_moderate_blunders():
    blk, truth = simulate_models(ModelPlan(strips=2, models_per_strip=4, layout="fotef",
                                           seed=11, blunders=3, blunder_sigma=(12, 20)))
    bq = process(blk, "3d", deformations=None)
    qc = bq.part("3d")
    found = {(lab.split()[1], lab.split()[3], lab.split()[4]) for s in qc.run.log
             for lab in s.labels if s.action == "reject"}
    planted = {(b["model"], b["point"], b["component"]) for b in truth["blunders"]}
    assert planted <= found | {(m, p, c) for m, p, c in planted
                               if blk.models_per_point()[blk.points.index(p)] == 1}


def test_levelling_removes_tilt_effects_on_planimetry():
    plan = dict(strips=2, models_per_strip=4, layout="fotef", seed=2, height_chains=1,
                noise=False)
    flat, _ = simulate_models(ModelPlan(tilt_rad=0.0, **plan))
    tilted, _ = simulate_models(ModelPlan(tilt_rad=0.02, **plan))
    r_flat = adjust_models(flat, "2d")
    r_tilt = adjust_models(tilted, "2d")
    lev, tilt = level(tilted)
    r_lev = adjust_models(lev, "2d")
    assert r_flat.sigma0 < 1e-6 and r_lev.sigma0 < 1e-6  # exact again after levelling
    assert r_tilt.sigma0 > 0.1
    np.testing.assert_allclose(r_lev.xyz, r_flat.xyz, atol=1e-6)
    assert 0.005 < np.max(tilt) < 0.1
    rh = adjust_models(lev, "height", mu=r_lev.params[:, 3])
    check_tilts(rh)
    assert rh.sigma0 < 1e-6


def test_height_adjustment_refuses_undetermined_tilts():
    blk, _ = simulate_models(ModelPlan(strips=2, models_per_strip=4, height_chains=3))
    r2 = adjust_models(blk, "2d")
    rh = adjust_models(blk, "height", mu=r2.params[:, 3])
    with pytest.raises(GeometryError, match="tilts of model"):
        check_tilts(rh)
    with pytest.raises(GeometryError, match="spatial adjustment"):
        process(blk, "2d")


def test_datum_defect_is_reported():
    blk, _ = simulate_models(ModelPlan(strips=1, models_per_strip=3))
    blk.sigma[:] = np.nan
    blk.role[:] = "tie"
    with pytest.raises(GeometryError, match="planimetric"):
        adjust_models(blk, "3d")
