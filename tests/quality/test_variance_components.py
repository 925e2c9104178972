"""Variance components per observation group (issue 18, part 2): Foerstner's estimate
against dense brute force, recovery of wrong a-priori sigmas, snooping with the estimated
sigmas equal to snooping with the true ones."""

from dataclasses import replace

import numpy as np
import pytest
from gnss_blocks import with_gnss

from baarda.bundle.bundle_model import BundleModel
from baarda.pipeline import adjust, prepare, snoop, snoop_with_variance_components
from baarda.quality.variance_components import estimate, iterate
from baarda.simulate.aerial import FlightPlan, simulate_block


def test_group_redundancies_and_estimates_equal_dense():
    from dense import dense_system

    block, truth = simulate_block(FlightPlan(strips=3, photos_per_strip=6, pattern=5,
                                             relief_m=100.0, control="corners", seed=3))
    res = adjust(with_gnss(block, truth, offsets="block"))
    model = BundleModel(res)
    a, p = dense_system(model)
    qxx = np.linalg.inv(a.T @ (p[:, None] * a))
    r = 1 - p * np.einsum("ij,jk,ik->i", a, qxx, a)
    groups = model.variance_groups()
    comps = {c.group: c for c in estimate(model)}
    assert {"image", "control X", "gnss Z", "imu"} <= set(comps)
    v = model.residuals
    for g, c in comps.items():
        sel = groups == g
        rk = float(r[sel].sum())
        assert np.isclose(c.redundancy, rk, rtol=1e-9, atol=1e-9), g
        if np.isfinite(c.factor):
            assert np.isclose(c.factor, float(np.sum(p[sel] * v[sel] ** 2)) / rk, rtol=1e-9)
    assert np.isclose(sum(c.redundancy for c in comps.values()), res.redundancy)


def _wrong_sigmas(blunders: int = 0):
    """Image noise 5 µm given as 3 µm, control noise 2 cm given as 5 cm (dense control)."""
    block, truth = simulate_block(FlightPlan(
        strips=6, photos_per_strip=12, pattern=5, relief_m=100.0, sigma_image_um=5.0,
        control_spacing=1, height_chains=1, blunders=blunders, blunder_sigma=(8.0, 12.0),
        seed=3))
    pts = block.points
    ctrl = np.isfinite(pts.sigma)
    true = np.array([truth["points"][q] for q in pts.ids])
    given = np.where(ctrl, true + np.random.default_rng(9).normal(0, 0.02, true.shape),
                     pts.xyz)
    def with_sigmas(image_mm, control_m):
        return replace(block, image=replace(block.image, sigma_mm=np.full(
            len(block.image), image_mm)), points=replace(pts, xyz=given, sigma=np.where(
                ctrl, control_m, np.nan)))
    return with_sigmas(0.003, 0.05), with_sigmas(0.005, 0.02)


def test_the_factors_are_recovered():
    wrong, _ = _wrong_sigmas()
    est = iterate(BundleModel(adjust(wrong)))
    assert est.converged
    s = {k: np.sqrt(v) for k, v in est.group_factor.items()}
    assert abs(s["image"] / (5 / 3) - 1) < 0.1, s
    assert abs(s["control Z"] / 0.4 - 1) < 0.1, s  # r 170; X and Y have r 15 each


@pytest.mark.slow
def test_snooping_with_estimated_sigmas_equals_snooping_with_the_true_ones():
    """Four image blunders of 8-12 sigma: snooping alternated with the estimation
    (pipeline.snoop_with_variance_components) rejects exactly what snooping with the true
    sigmas rejects.  One of them, control Y of point 025013 (|w| 3.43 with the true sigmas,
    critical 3.29), hides behind its own group's estimate while it is part of it (control Y,
    r 14: sigma estimated 0.63 x a priori instead of 0.4); tested against the group
    estimated without it (variance_components.challenge) it has |w| 3.30 and is rejected."""
    wrong, right = _wrong_sigmas(blunders=4)
    qc, _ = snoop_with_variance_components(prepare(wrong))
    truth = snoop(prepare(right))
    labels = lambda a: {s for st in a.run.log for s in st.labels}  # noqa: E731
    est, ref = labels(qc), labels(truth)
    assert est == ref and len(ref) == 5, (est, ref)
    assert np.array_equal(qc.quality.active, truth.quality.active)
    factors = {c.group: c.estimated for c in qc.variance_components}
    assert abs(np.sqrt(factors["image"]) / (5 / 3) - 1) < 0.1, factors
    assert abs(np.sqrt(factors["control Z"]) / 0.4 - 1) < 0.1, factors


@pytest.mark.slow
def test_command_line_summary_and_report(tmp_path):
    """`adjust --vce`: summary.json lists the groups; the text and HTML reports show them."""
    import contextlib
    import io
    import json

    from baarda.cli import main

    proj = tmp_path / "p"
    assert main(["simulate", "-o", str(proj), "--pattern", "5", "--relief", "100"]) == 0
    assert main(["adjust", str(proj), "-o", str(tmp_path / "o"), "--vce", "-q"]) == 0
    doc = json.loads((tmp_path / "o" / "summary.json").read_text())
    groups = {c["group"]: c for c in doc["variance_components"]}
    assert {"image", "control Z"} <= set(groups)
    g = groups["image"]
    assert abs(g["redundancy"] - doc["sum_redundancy_numbers"]) < doc["redundancy"]
    f = g["estimated_variance_factor"]
    assert f is not None and abs(f - 1) < 0.3
    assert g["estimated_sigma_factor"] == pytest.approx(np.sqrt(f), rel=1e-12)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["report", str(tmp_path / "o"), "--text"]) == 0
    assert "variance components per group" in out.getvalue()
    assert main(["report", str(tmp_path / "o"), "-o", str(tmp_path / "o" / "r.html")]) == 0
    assert "Variance components per group" in (tmp_path / "o" / "r.html").read_text()


def test_w_histograms_per_group():
    """The report's histograms of w per observation group (control X, Y, Z, GNSS, IMU)."""
    import pandas as pd

    from baarda.output.results import observation_groups
    from baarda.report.text_report import ReportOptions, w_hists

    n = 40
    obs = pd.DataFrame({
        "kind": ["image"] * n + ["control"] * n + ["gnss"] * n + ["imu"] * n,
        "component": ["x"] * n + ["Z"] * n + ["X"] * n + ["omega"] * n,
        "photo": [""] * (4 * n), "point": ["p"] * (4 * n),
        "w": np.linspace(-3, 3, 4 * n), "rejected": [False] * (4 * n)})
    names = [name for name, _ in w_hists(obs, ReportOptions(), observation_groups(obs))]
    assert names == ["image x", "image x and y", "control Z", "gnss X", "imu",
                     "all observations"]


def test_the_estimate_applies_to_every_method():
    """Independent models: the same estimate from their adjusted model (groups model XY,
    model Z, projection centres, control X, Y, Z: tests/independent/test_variance_components.py);
    the group redundancies add up to the redundancy and the estimate equals v'Pv / r_k of
    the model's own redundancy numbers."""
    from baarda.independent.workflow import process
    from baarda.quality.statistics import cofactors
    from baarda.simulate.model_blocks import ModelPlan, simulate_models

    blk, _ = simulate_models(ModelPlan(strips=2, models_per_strip=4, layout="fotef", seed=11))
    models = [process(blk, "3d", deformations=None).part("3d").model]
    for model in models:
        comps = estimate(model)
        assert comps and {c.group for c in comps} >= {"model XY", "model Z"}
        _, r = cofactors(model)
        assert np.isclose(sum(c.redundancy for c in comps), float(r[model.active].sum()))
        for c in comps:
            if np.isfinite(c.factor):
                assert np.isclose(c.factor, c.vtpv / c.redundancy, rtol=1e-12)


def test_the_pooling_rule():
    """Control axes too weak alone (r < 5) are estimated together: X and Y as planimetry
    when Z stands alone (a pooled XY still too weak is reported, not estimated), else X, Y
    and Z."""
    from baarda.quality.variance_components import VarianceComponent, pooling_plan

    def comps(**r):
        return [VarianceComponent(f"control {k}", 10, 0.05, v, v, 1.0, 0.1, 0.5, False)
                for k, v in r.items()] + [
            VarianceComponent("image", 100, 0.003, 400.0, 400.0, 1.0, 0.1, 0.5, False)]

    xy, xyz = ("control X", "control Y"), ("control X", "control Y", "control Z")
    assert pooling_plan(comps(X=6, Y=7, Z=9)) == {}
    assert pooling_plan(comps(X=3, Y=4, Z=9)) == {"control XY": xy}
    assert pooling_plan(comps(X=2, Y=2, Z=9)) == {"control XY": xy}  # 4: reported
    assert pooling_plan(comps(X=6, Y=7, Z=1)) == {"control XYZ": xyz}
    assert pooling_plan(comps(X=2, Y=2)) == {"control XY": xy}
    assert pooling_plan(comps(Z=2)) == {}  # nothing to pool with


@pytest.mark.parametrize("layout, pooled, estimated", [
    (dict(strips=2, photos_per_strip=8, control_spacing=2, height_chains=0),
     "control XYZ", True),   # r X 2.3, Y 1.8, Z 2.0: together 6.1
    (dict(strips=3, photos_per_strip=10, control_spacing=2, height_chains=4),
     "control XY", True),    # r X 3.0, Y 2.5 (together 5.5), Z 17
    (dict(strips=3, photos_per_strip=6, control="corners"),
     "control XY", False),   # r X 0.2, Y 0.2, Z 7.9: XY too weak even together
])
def test_weak_control_axes_pooled_in_small_blocks(layout, pooled, estimated):
    """Small blocks whose control axes have r < 5 each: pooled as the rule says, the pooled
    group's redundancy and estimate equal a dense brute force (1e-9); --vce re-weights its
    members by the one factor; the summary says it in words."""
    from dense import dense_system

    from baarda.pipeline import assess, with_variance_components

    block, _ = simulate_block(FlightPlan(pattern=5, relief_m=100.0, seed=3, **layout))
    model = BundleModel(adjust(block))
    comps = {c.group: c for c in estimate(model, pool=True)}
    group = comps[pooled]
    assert all(comps[m].redundancy < 5 for m in group.members if m != "control Z")
    assert all(comps[m].pooled_into == pooled for m in group.members)
    assert np.isfinite(group.factor) == estimated
    a, p = dense_system(model)
    qxx = np.linalg.inv(a.T @ (p[:, None] * a))
    r = 1 - p * np.einsum("ij,jk,ik->i", a, qxx, a)
    sel = np.isin(model.variance_groups(), group.members)
    rk = float(r[sel].sum())
    assert abs(group.redundancy - rk) < 1e-9 * rk
    if estimated:
        assert abs(group.factor - float(np.sum(p[sel] * model.residuals[sel] ** 2)) / rk) \
            < 1e-9 * group.factor
    problem, est = with_variance_components(prepare(block))
    f = est.factors[sel]
    assert np.ptp(f) == 0 and (f[0] != 1.0) == estimated
    qc = replace(assess(adjust(problem)), variance_components=est.components())
    text = qc.summary()
    assert f"estimated together with the other axes as {pooled}" in text
    assert (f"{pooled} (" + ", ".join(group.members)) in text
    if not estimated:
        assert "too little redundancy even together" in text


def _helmert(a, v1, p0, groups, estimated, tolerance=1e-12, max_iterations=500):
    """Helmert's iteration, dense, on the linearised model of a first adjustment: with
    l = -v1 the residuals for any weights P are v = (I - A (A'PA)^-1 A'P) v1 (exact in the
    linear model).  `estimated`: name -> the groups it re-weights, for exactly the groups the
    report says are estimated; a group whose r_k falls below 5 is frozen, as reported.
    Returns (cumulative variance factor per name, {name: iteration frozen})."""
    p = p0.copy()
    cum = dict.fromkeys(estimated, 1.0)
    frozen = {}
    for it in range(1, max_iterations + 1):
        n = a.T @ (p[:, None] * a)
        q = np.linalg.solve(n, a.T * p)  # (A'PA)^-1 A'P
        v = v1 - a @ (q @ v1)
        r = 1 - np.einsum("ij,ji->i", a, q)
        f = {}
        for name, members in estimated.items():
            sel = np.isin(groups, members) & (p > 0)
            rk = r[sel].sum()
            if name not in frozen and rk < 5:
                frozen[name] = it
            f[name] = float(np.sum(p[sel] * v[sel] ** 2) / rk)
        live = [k for k in estimated if k not in frozen]
        if max((abs(f[k] - 1) for k in live), default=0) < tolerance:
            return cum, frozen
        for k in live:
            p[np.isin(groups, estimated[k])] /= f[k]
            cum[k] *= f[k]
    raise AssertionError("the dense Helmert iteration did not converge")


def _vce_case(image_um, control_m, true_control_m, plan):
    """A simulated block whose a-priori sigmas are image_um and control_m (control noise
    true_control_m); the bundle's estimation (tight tolerance) and its first adjustment."""
    block, truth = simulate_block(plan)
    pts = block.points
    ctrl = np.isfinite(pts.sigma)
    true = np.array([truth["points"][q] for q in pts.ids])
    noise = np.random.default_rng(4).normal(0, true_control_m, true.shape)
    block = replace(block, image=replace(block.image, sigma_mm=np.full(len(block.image),
                                                                       image_um * 1e-3)),
                    points=replace(pts, xyz=np.where(ctrl, true + noise, pts.xyz),
                                   sigma=np.where(ctrl, control_m, np.nan)))
    first = BundleModel(adjust(block))
    return first, iterate(first, tolerance=1e-10)


def _check_against_dense(first, est):
    """The summary's words and factors equal a dense Helmert iteration that holds or
    estimates each group as the summary says."""
    from dense import dense_system

    comps = est.components()
    estimated = {}
    for c in comps:
        if c.reweights:
            estimated[c.group] = c.groups
    a, p0 = dense_system(first)
    cum, frozen = _helmert(a, first.residuals, p0, first.variance_groups(), estimated)
    for c in comps:
        text = c.summary()
        if c.group in estimated:
            assert np.isclose(c.estimated, cum[c.group], rtol=1e-3), (c.group, c.estimated,
                                                                      cum[c.group])
            assert c.frozen_at == frozen.get(c.group, 0), c.group
            assert ("frozen at iteration" in text) == bool(c.frozen_at)
        elif not c.pooled_into:  # reported as not estimated: held at its a-priori sigma
            assert "not estimated" in text and not np.isfinite(c.estimated)
            assert np.all(est.factors[np.isin(first.variance_groups(), c.groups)] == 1.0)
    return comps


def test_a_group_reported_not_estimated_is_never_reweighted():
    """Issue 26, item 3 (a): image 4 µm given as 6 µm, control 9 cm given as 3 cm, control
    too weak even pooled (r 4.25 < 5): it keeps its a-priori sigma through every iteration
    (it was re-weighted by 12.99 from iteration 2 on, although reported not estimated)."""
    first, est = _vce_case(6.0, 0.03, 0.09, FlightPlan(strips=4, photos_per_strip=10,
                                                        pattern=3, sigma_image_um=4.0,
                                                        seed=3))
    comps = {c.group: c for c in _check_against_dense(first, est)}
    pooled = comps["control XYZ"]
    assert pooled.members and not pooled.reweights and pooled.redundancy < 5
    assert abs(np.sqrt(comps["image"].estimated) - 4 / 6) < 0.1


def test_a_group_whose_redundancy_falls_is_frozen_as_reported():
    """Issue 26, item 3 (b): control noise 1 cm given as 50 cm: the control groups start
    with r >= 5, their factors fall towards 0.0004 and so do their redundancies; each is
    frozen at the iteration its r_k falls below 5, reported so, and the dense iteration
    with the same rule freezes it at the same iteration with the same factor."""
    first, est = _vce_case(5.0, 0.5, 0.01, FlightPlan(strips=4, photos_per_strip=10,
                                                       pattern=5, control_spacing=1,
                                                       height_chains=1, seed=5))
    comps = _check_against_dense(first, est)
    frozen = [c for c in comps if c.frozen_at]
    assert frozen, [c.summary() for c in comps]
    for c in frozen:
        assert c.frozen_at > 1 and c.frozen_redundancy < 5


def test_the_default_stop_equals_a_converged_dense_helmert_iteration():
    """Issue 44: `iterate` with its default stop (every factor of an iteration within 1e-5
    of one: the relative change of each estimate) equals Helmert's iteration run dense to
    1e-12 within 1e-4, weak groups included: GNSS noise 5 cm given as 1.5 cm, GNSS Z (r 6.2)
    estimated from 2.24 to 6.5; the stop at 1 % left it more than 1 % short."""
    from dense import dense_system

    block, truth = simulate_block(FlightPlan(strips=4, photos_per_strip=8, pattern=5,
                                             relief_m=100.0, control="corners", seed=3))
    b = with_gnss(block, truth, sigma_m=0.05, imu=False)
    b = replace(b, gnss=replace(b.gnss, sigma=np.full_like(b.gnss.sigma, 0.015)))
    first = BundleModel(adjust(b))
    est = iterate(first)
    assert est.converged
    comps = est.components()
    estimated = {c.group: c.groups for c in comps if c.reweights}
    assert any(g.startswith("gnss") for g in estimated)
    a, p0 = dense_system(first)
    cum, _ = _helmert(a, first.residuals, p0, first.variance_groups(), estimated)
    for c in comps:
        if c.group in estimated:
            assert abs(c.estimated / cum[c.group] - 1) < 1e-4, (c.group, c.estimated,
                                                                 cum[c.group])
    assert cum["gnss Z"] > 5  # r 6.2: from 2.24 in the first estimate
    old = iterate(first, tolerance=0.01).group_factor["gnss Z"]  # the stop at 1 %
    assert abs(old / cum["gnss Z"] - 1) > 1e-2
