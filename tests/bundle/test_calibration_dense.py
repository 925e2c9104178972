"""Self-calibration, fixed control, per-axis sigmas and distances against a dense brute-force
oracle whose design matrix is the numerical derivative of the problem's own misclosures:
the adjustment is stationary, and the redundancy numbers, w-tests, MDBs and the camera
parameters' cofactors equal the dense ones (issue 13)."""

from dataclasses import replace

import numpy as np
import pytest

from baarda.block.photo_block import Distances
from baarda.bundle.bundle_model import BundleModel
from baarda.pipeline import adjust, assess
from baarda.simulate.aerial import FlightPlan, simulate_block


@pytest.fixture(scope="module")
def case():
    block, truth = simulate_block(FlightPlan(strips=3, photos_per_strip=5, relief_m=150.0,
                                             side_overlap=0.6, seed=21))
    cams = replace(block.cameras, model=np.array(["brown"], dtype=object),
                   coefficients=np.array([[1e-6, 0, 0, 2e-6, -1e-6, 0, 0]]))
    pts = block.points
    sigma = pts.sigma.copy()
    ctrl = np.flatnonzero(pts.role == "control")
    sigma[ctrl[0]] = 0.0  # a fixed control point
    tie = np.flatnonzero(pts.role == "tie")
    a, b = tie[2], tie[-3]
    xa, xb = (np.array(truth["points"][pts.ids[j]]) for j in (a, b))
    length = float(np.linalg.norm(xa - xb)) + 0.01
    dist = Distances(["bar"], np.array([a]), np.array([b]), np.array([length]),
                     np.array([0.02]))
    im = block.image
    rng = np.random.default_rng(4)
    sxy = im.sigma_mm[:, None] * rng.uniform(0.7, 1.4, (len(im), 2))
    block = replace(block, cameras=cams,
                    settings=replace(block.settings,
                                     calibration_free=(("c", "k1", "p1", "p2", "b1"),)),
                    points=replace(pts, sigma=sigma), distances=dist,
                    image=replace(im, sigma_xy_mm=sxy))
    res = adjust(block)
    return res, BundleModel(res)


def _unknown_columns(pb):
    """(state part, flat index) of every unknown that is not held, in a fixed order."""
    cols = []
    held = pb.held if pb.held is not None else np.zeros((len(pb.block.photos), 6), bool)
    cols += [(0, k) for k in np.flatnonzero(~held.ravel())]
    cols += [(1, k) for k in np.flatnonzero(~pb.held_points.ravel())]
    ng = pb.system.ng
    held_g = np.zeros(ng, bool)
    held_g[pb.global_layout.start("points"):] = pb.held_border.ravel()
    cols += [(2, k) for k in np.flatnonzero(~held_g)]
    return cols


def _misclosures(pb, state):
    lin = pb.linearize(state)
    return pb.layout.flat(lin.e, lin.ec, lin.ex)


def _central(pb, state, part, k, h):
    """-d(misclosures)/d(unknown k of state part) by central differences of step h."""
    plus = [s.copy() for s in state]
    minus = [s.copy() for s in state]
    plus[part].ravel()[k] += h
    minus[part].ravel()[k] -= h
    return -(_misclosures(pb, tuple(plus)) - _misclosures(pb, tuple(minus))) / (2 * h)


def _dense(res):
    pb = res.problem
    state = [np.array(s, float) for s in res.state]
    cols = _unknown_columns(pb)
    e0 = _misclosures(pb, tuple(state))
    a = np.zeros((len(e0), len(cols)))
    for j, (part, k) in enumerate(cols):
        h = 1e-6 * max(1.0, abs(state[part].ravel()[k]))
        if part == 2 and k < pb.global_layout.start("points"):  # camera parameters: their own scale
            h = 1e-6 * max(abs(state[part][k]), 1e-3) if k == 0 else 1e-7 * max(
                1e-5, abs(state[part][k]))
        a[:, j] = _central(pb, state, part, k, h)
        if part == 2 and 0 < k < pb.global_layout.start("points"):
            # a step of 1e-7 of a small coefficient moves the misclosures so little that
            # their rounding (about 1e-15 mm) shows in the derivative at 1e-7 and in r at
            # 1e-6: again with the step that moves them by 1e-3 mm (the misclosures are
            # nearly linear in the coefficients)
            a[:, j] = _central(pb, state, part, k, 1e-3 / max(np.abs(a[:, j]).max(), 1e-300))
    return a, e0, cols


def test_dense_oracle(case):
    res, model = case
    pb = res.problem
    assert pb.calibration.n == 5 and len(pb.border_ids) == 2 and pb.held_points.sum() == 3
    a, e, cols = _dense(res)
    p = np.where(model.active, 1.0 / model.sigma**2, 0.0)
    n = a.T @ (p[:, None] * a)
    qxx = np.linalg.inv(n)
    # stationary: the remaining correction is negligible against each unknown's precision
    x = qxx @ (a.T @ (p * e))
    assert np.max(np.abs(x) / np.sqrt(np.diag(qxx))) < 1e-3
    qll = np.einsum("ij,jk,ik->i", a, qxx, a)
    assert np.allclose(model.adjusted_cofactor_diag(), qll, rtol=1e-5,
                       atol=1e-7 * qll.max())
    q = assess(res).quality
    r = 1 - p * qll
    ok = q.controlled
    assert np.allclose(q.redundancy_number[ok], r[ok], atol=1e-6)
    assert abs(q.redundancy_number.sum() - res.redundancy) < 1e-6
    assert res.redundancy == len(e) - len(cols)
    # the camera parameters' cofactors
    first = pb.global_layout.start("points")
    g_cols = [j for j, (part, k) in enumerate(cols) if part == 2 and k < first]
    dense_cam = qxx[np.ix_(g_cols, g_cols)]
    cam = res.camera_covariance()
    d = np.sqrt(np.diag(dense_cam))
    assert np.allclose(cam / np.outer(d, d), dense_cam / np.outer(d, d), atol=1e-4)
    assert np.allclose(np.sqrt(np.diag(cam)), d, rtol=1e-4)
    # the distance is an observation with its own redundancy and test
    k = np.flatnonzero(model.kind == "distance")
    assert len(k) == 1 and 0 < q.redundancy_number[k[0]] < 1 and np.isfinite(q.w[k[0]])


def test_fixed_control_is_held_and_not_tested(case):
    res, model = case
    pb = res.problem
    j = pb.control[np.flatnonzero(pb.held_points[pb.eremap[pb.control]].all(axis=1))[0]]
    assert np.allclose(res.xyz[pb.remap[j]], pb.block.points.xyz[j], atol=1e-9)
    assert np.allclose(res.xyz_std[pb.remap[j]], 0.0, atol=1e-6)
    assert not np.any(model.control_index == j)  # not an observation


def test_statistics_equal_the_dense_system_of_the_same_jacobians(case):
    """With the linearisation's own Jacobians the sparse statistics equal dense brute force
    to 1e-9 (the algebra of global unknowns, extra rows and held unknowns)."""
    from dense import dense_system

    res, model = case
    a, p = dense_system(model)
    qxx = np.linalg.inv(a.T @ (p[:, None] * a))
    qll = np.einsum("ij,jk,ik->i", a, qxx, a)
    assert np.allclose(model.adjusted_cofactor_diag(), qll, rtol=1e-9, atol=1e-12 * qll.max())
    q = assess(res).quality
    r = 1 - p * qll
    ok = q.controlled
    assert np.allclose(q.redundancy_number[ok], r[ok], atol=1e-9)
    sv = model.sigma * np.sqrt(np.maximum(r, 0))
    w = np.where(ok, -model.residuals / np.where(ok, sv, 1.0), np.nan)
    assert np.allclose(q.w[ok], w[ok], rtol=1e-8, atol=1e-9)
    assert np.allclose(q.mdb[ok], q.delta0 * model.sigma[ok] / np.sqrt(r[ok]), rtol=1e-8)
    n = res.problem.calibration.n
    assert np.allclose(res.camera_covariance(), qxx[-res.problem.system.ng:, :][:, -res.problem
                       .system.ng:][:n, :n], rtol=1e-8, atol=1e-12 * np.abs(qxx).max())
