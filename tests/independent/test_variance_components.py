"""Variance components of an independent-model block (issue 18): the groups model XY,
model Z, projection centres and control X, Y, Z (pooled when too weak) against a dense
brute force, mis-stated sigmas recovered by --vce, and `baarda models --vce` = the API."""

import json
from dataclasses import replace

import numpy as np
import pytest
from model_dense import dense_design

from baarda.independent.independent_model import IndependentModel
from baarda.independent.model_problem import adjust_models as adjust_once
from baarda.pipeline import adjust_models, read_models
from baarda.quality.variance_components import estimate, iterate
from baarda.simulate.model_blocks import ModelPlan, simulate_models


def _dense_components(model):
    """(group -> (r_k, v'Pv / r_k)) from a dense A and a dense inverse of N."""
    a = dense_design(model)
    p = np.where(model.active, 1 / model.sigma**2, 0.0)
    qxx = np.linalg.inv(a.T @ (p[:, None] * a))
    r = np.where(model.active, 1 - p * np.einsum("ij,jk,ik->i", a, qxx, a), 0.0)
    return r, p * model.residuals**2


@pytest.mark.parametrize("full_control", [True, False])
def test_group_redundancies_and_estimates_equal_dense(full_control):
    """3D with projection centres: every group's redundancy and estimate, pooled ones
    included, equal a dense brute force to 1e-9; they add up to the redundancy."""
    blk, _ = simulate_models(ModelPlan(strips=2, models_per_strip=4, full_control=full_control,
                                       control_spacing=1, height_chains=1, seed=4))
    model = IndependentModel(adjust_once(blk, "3d"))
    groups = model.variance_groups()
    assert {"model XY", "model Z", "model PC", "control X", "control Z"} <= set(groups)
    r, vpv = _dense_components(model)
    comps = estimate(model, pool=True)
    assert any(c.members for c in comps) or all(c.redundancy >= 5 for c in comps)
    for c in comps:
        sel = model.active & np.isin(groups, c.groups)
        rk = float(r[sel].sum())
        assert abs(c.redundancy - rk) < 1e-9 * max(1.0, rk), c.group
        if np.isfinite(c.factor):
            assert abs(c.factor - float(vpv[sel].sum()) / rk) < 1e-9 * c.factor, c.group
    own = [c for c in comps if not c.members]
    assert sum(c.redundancy for c in own) == pytest.approx(model.redundancy, rel=1e-9)


def _mis_stated(seed: int = 5):
    """Model planimetry 10 µm given as 6 µm, height 15 µm given as 25 µm (not the
    projection centres), control 2 cm given as 5 cm."""
    blk, _ = simulate_models(ModelPlan(strips=4, models_per_strip=10, sigma_control_m=(0.02,) * 3,
                                       control_spacing=1, height_chains=1, full_control=True,
                                       seed=seed))
    sig = blk.obs_sigma.copy()
    pts = ~blk.pc[blk.obs_point]
    sig[pts, :2] = 0.006
    sig[pts, 2] = 0.025
    return blk, replace(blk, obs_sigma=sig, sigma=np.where(np.isfinite(blk.sigma), 0.05, np.nan))


def test_mis_stated_sigmas_are_recovered():
    """--vce on a 40-model block: model XY x 10/6 and model Z x 15/25 within 10 %; the
    projection centres (right a priori, r 47: sigma known to +-10 %) x 1 within 2.5 of the
    estimate's standard deviations."""
    _, wrong = _mis_stated()
    est = iterate(IndependentModel(adjust_once(wrong, "3d")))
    assert est.converged
    s = {k: np.sqrt(v) for k, v in est.group_factor.items()}
    assert abs(s["model XY"] / (10 / 6) - 1) < 0.1, s
    assert abs(s["model Z"] / (15 / 25) - 1) < 0.1, s
    pc = next(c for c in est.last if c.group == "model PC")
    assert abs(s["model PC"] - 1) < 2.5 * np.sqrt(0.5 / pc.redundancy), s
    bq = adjust_models(wrong, "3d", snoop=False, vce=True, deformations=None)
    vc = {c.group: c for c in bq.part("3d").variance_components}
    assert vc["model XY"].estimated == pytest.approx(est.group_factor["model XY"], rel=1e-9)
    # the statistics use the estimated sigmas: the global test accepts them
    assert bq.part("3d").quality.sigma0_hat == pytest.approx(1.0, abs=0.01)


def test_snooping_with_vce_in_the_model_workflow():
    """With snooping, estimation and snooping alternate: a planted model blunder is
    rejected, and the same block with the true sigmas rejects the same components."""
    right, wrong = _mis_stated(seed=6)
    i = int(np.flatnonzero(~right.pc[right.obs_point])[17])
    bad = right.obs_xyz.copy()
    bad[i, 0] += 0.08  # 8 sigma of the true 10 µm
    right, wrong = replace(right, obs_xyz=bad), replace(wrong, obs_xyz=bad)
    a = adjust_models(wrong, "3d", vce=True, deformations=None).part("3d")
    b = adjust_models(right, "3d", deformations=None).part("3d")
    assert np.array_equal(a.quality.active, b.quality.active)
    assert (~a.quality.active).sum() >= 1
    assert any(c.group == "model XY" and np.isfinite(c.estimated)
               for c in a.variance_components)


def test_command_line_equals_api(tmp_path):
    """`baarda models --vce` writes the API's variance components (summary.json, per
    adjustment), the text report and the HTML report show them."""
    import contextlib
    import io

    from baarda.cli import main

    proj = tmp_path / "m"
    assert main(["simulate-models", "-o", str(proj), "--strips", "2", "--models", "4",
                 "--seed", "3"]) == 0
    out = tmp_path / "o"
    assert main(["models", str(proj), "-o", str(out), "--2d", "--vce", "-q",
                 "--deformations", "none"]) == 0
    doc = json.loads((out / "summary.json").read_text())
    bq = adjust_models(read_models(proj), "2d", vce=True, deformations=None)
    for part in bq.parts:
        got = doc["adjustments"][part.name]["variance_components"]
        want = [c.to_dict() for c in part.variance_components]
        assert [g["group"] for g in got] == [w["group"] for w in want]
        for g, w in zip(got, want, strict=True):
            for key in ("redundancy", "vtpv", "factor", "estimated_variance_factor"):
                assert (g[key] is None and w[key] is None) or g[key] == pytest.approx(
                    w[key], rel=1e-12), (g["group"], key)
    assert {"2d", "height"} <= set(doc["adjustments"])
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        assert main(["report", str(out), "--text"]) == 0
    assert "variance components per group" in text.getvalue()
    assert "RESIDUALS W, MODEL XY" in text.getvalue().upper()
    assert "RESIDUALS W, MODEL Z" in text.getvalue().upper()
    assert main(["report", str(out), "-o", str(out / "r.html")]) == 0
    html = (out / "r.html").read_text()
    assert "Variance components per group" in html and "model XY" in html


def test_an_alternation_that_does_not_settle_says_so():
    """One round of estimation and snooping cannot settle when snooping rejects something:
    the note says so (and a round count that lets it settle gives no note)."""
    from baarda.independent.model_quality import snoop
    from baarda.quality.variance_components import alternate

    right, _ = _mis_stated(seed=6)
    bad = right.obs_xyz.copy()
    bad[int(np.flatnonzero(~right.pc[right.obs_point])[17]), 0] += 0.08
    res = adjust_once(replace(right, obs_xyz=bad), "3d")
    start = res.problem.active

    def run(rounds):
        qc, _ = alternate(IndependentModel(res), lambda f: snoop(res.refit(start, f)),
                          max_rounds=rounds)
        return [n for n in qc.quality.notes if "did not settle" in n]

    assert run(1) == ["variance components and data snooping did not settle in 1 rounds: "
                      "the last snooping and its estimate are reported"]
    assert run(10) == []
