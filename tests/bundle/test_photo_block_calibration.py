"""Cameras in their photo's block (issue 32): the free parameters of a camera that one photo
uses are unknowns of that photo (9 per BAL photo), eliminated with it, instead of border
columns.  Checked against a dense brute-force adjustment whose design matrix is the
numerical derivative of the problem's own misclosures (r, w, MDB, the standard deviations of
the camera parameters and orientations), and against the same problem with every camera in
the border (the sums in another order: equal to rounding)."""

from dataclasses import replace

import numpy as np
import pytest
from bal_reference import bal_residuals

import baarda.bundle.calibration as calibration
from baarda.block.photo_block import Distances
from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.bundle_quality import calibration_tests
from baarda.bundle.calibration import Calibration
from baarda.io.bal import BalProblem, bal_to_block, rotation_vector
from baarda.options import TestOptions
from baarda.pipeline import assess, prepare
from baarda.simulate.aerial import FlightPlan, simulate_block

TESTS = TestOptions(0.001, 0.8)


def _bal(ncam: int = 8, npt: int = 80, seed: int = 5, shared: int | None = None) -> BalProblem:
    """Cameras round a cloud of points, BAL's projection with 0.5 px noise; cameras
    `shared`.. are one camera (the same f, k1, k2)."""
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-1, 1, (npt, 3)) * [2, 2, 0.5]
    cams = np.zeros((ncam, 9))
    for i in range(ncam):
        ang = 2 * np.pi * i / ncam
        centre = np.array([3 * np.cos(ang), 3 * np.sin(ang), 2.0 + 0.3 * (i % 3)])
        z = centre / np.linalg.norm(centre)
        x = np.cross([0, 0, 1.0], z)
        x /= np.linalg.norm(x)
        r = np.vstack([x, np.cross(z, x), z])
        cams[i, :3] = rotation_vector(r)
        cams[i, 3:6] = -r @ centre
        cams[i, 6:9] = [500 + 20 * i, -0.05 + 0.01 * i, 0.01]
    if shared is not None:
        cams[shared:, 6:9] = cams[shared, 6:9]
    cam, pt = np.repeat(np.arange(ncam), npt), np.tile(np.arange(npt), ncam)
    p = BalProblem(cams, pts, cam, pt, np.zeros((ncam * npt, 2)))
    p.obs_xy = bal_residuals(p) + rng.normal(0, 0.5, (ncam * npt, 2))
    return p


def _fit(block):
    res = prepare(block).fit()
    return res, BundleModel(res), assess(res, TESTS)


@pytest.fixture(scope="module")
def bal_case():
    return _fit(bal_to_block(_bal()))


@pytest.fixture(scope="module")
def mixed_case():
    """Five photos with a camera of their own (camera 0: only c free), three sharing camera
    5 (c, k1, k2 free: in the border), and a distance between two points (border points,
    whose image rows depend on the photos' camera columns)."""
    block = bal_to_block(_bal(shared=5))
    c = block.cameras
    keep = np.arange(6)
    free = (("c",),) + tuple(block.settings.calibration_free[1:6])
    cams = replace(c, ids=[c.ids[i] for i in keep], focal_mm=c.focal_mm[keep],
                   principal_point_mm=c.principal_point_mm[keep], model=c.model[keep],
                   coefficients=c.coefficients[keep])
    photos = replace(block.photos, camera=np.minimum(block.photos.camera, 5))
    a, b = 3, 40
    length = float(np.linalg.norm(block.points.xyz[a] - block.points.xyz[b]))
    dist = Distances(["bar"], np.array([a]), np.array([b]), np.array([length + 0.002]),
                     np.array([0.005]))
    return _fit(replace(block, cameras=cams, photos=photos, distances=dist,
                        settings=replace(block.settings, calibration_free=free)))


def _dense(res):
    """Dense design matrix (numerical derivatives of the problem's misclosures, central
    differences) over every unknown that is not held, and the misclosures."""
    pb = res.problem
    state = [np.array(s, float) for s in res.state]
    held = [pb.held_frame if pb.held_frame is not None else
            np.zeros(state[0].shape, bool), pb.held_points]
    if len(state) == 3:
        hg = np.zeros(pb.system.ng, bool)
        hg[pb.held_globals] = True
        held.append(hg)
    cols = [(part, k) for part in range(len(state))
            for k in np.flatnonzero(~held[part].ravel())]

    def misclosures(st):
        lin = pb.linearize(tuple(st))
        return pb.layout.flat(lin.e, lin.ec, lin.ex)

    e0 = misclosures(state)
    a = np.zeros((len(e0), len(cols)))
    for j, (part, k) in enumerate(cols):
        h = 1e-6 * max(1.0, abs(state[part].ravel()[k]))
        plus = [s.copy() for s in state]
        minus = [s.copy() for s in state]
        plus[part].ravel()[k] += h
        minus[part].ravel()[k] -= h
        a[:, j] = -(misclosures(plus) - misclosures(minus)) / (2 * h)
    return a, e0, cols


def _check_against_dense(res, model, qc):
    a, e, cols = _dense(res)
    p = np.where(model.active, 1.0 / model.sigma**2, 0.0)
    qxx = np.linalg.inv(a.T @ (p[:, None] * a))
    x = qxx @ (a.T @ (p * e))  # stationary: no correction left
    assert np.max(np.abs(x) / np.sqrt(np.diag(qxx))) < 1e-3
    assert res.redundancy == len(e) - len(cols)
    qll = np.einsum("ij,jk,ik->i", a, qxx, a)
    q = qc.quality
    r = 1 - p * qll
    ok = q.controlled
    assert ok.sum() > 0.9 * len(ok)
    assert np.allclose(q.redundancy_number[ok], r[ok], atol=1e-6)
    sv = model.sigma * np.sqrt(r)
    assert np.allclose(q.w[ok], -model.residuals[ok] / sv[ok], rtol=1e-5, atol=1e-6)
    assert np.allclose(q.mdb[ok], q.delta0 * model.sigma[ok] / np.sqrt(r[ok]), rtol=1e-5)
    # standard deviations of the camera parameters and of the orientations
    std = np.sqrt(np.diag(qxx)) * res.sigma0
    pb = res.problem
    cal = pb.calibration
    index = {c: j for j, c in enumerate(cols)}
    table = res.camera_table()
    for i, cid in enumerate(pb.block.cameras.ids):
        rows = [t for t in table if t["camera"] == cid and t["estimated"]]
        assert len(rows) == len(cal.free_index[i])
        for s, t in enumerate(rows):
            if cal.owner[i] >= 0:
                col = index[(0, cal.owner[i] * pb.b + 6 + s)]
            else:
                col = index[(2, int(cal.columns[i][s]))]
            assert t["sigma"] == pytest.approx(std[col], rel=1e-4)
    free = ~pb.held_frame[:, :6] if pb.held_frame is not None else np.ones((pb.block.photos
                                                                            .__len__(), 6))
    for f, k in zip(*np.nonzero(free), strict=True):
        assert res.eo_std[f, k] == pytest.approx(std[index[(0, f * pb.b + k)]], rel=1e-4)
    return qxx, cols


def test_bal_cameras_are_in_their_photos_blocks(bal_case):
    res, model, qc = bal_case
    pb = res.problem
    assert pb.b == pb.system.b == 9 and pb.system.ng == 0  # no border at all
    assert np.array_equal(pb.calibration.owner, np.arange(8))
    assert pb.calibration.n == 24 and pb.calibration.n_global == 0
    assert res.camera_covariance().shape == (0, 0)
    assert res.converged and res.state[0].shape == (8, 9) and res.eo.shape == (8, 6)


def test_bal_statistics_equal_the_dense_adjustment(bal_case):
    _check_against_dense(*bal_case)


def test_mixed_statistics_equal_the_dense_adjustment(mixed_case):
    res, model, qc = mixed_case
    pb = res.problem
    cal = pb.calibration
    assert pb.b == 9 and list(cal.owner) == [0, 1, 2, 3, 4, -1]
    assert cal.n_global == 3 and len(pb.border_ids) == 2  # camera 5 and two points
    # held: photo 0's two unused camera columns, the sharing photos' three, the datum's six
    assert int(pb.held_frame[:, 6:].sum()) == 2 + 3 * 3 and int(pb.held_frame.sum()) == 17
    qxx, cols = _check_against_dense(res, model, qc)
    # the camera parameters' test of significance: their cofactors as the dense ones
    index = {c: j for j, c in enumerate(cols)}
    k = [index[(0, 1 * pb.b + 6 + s)] for s in range(3)]  # camera 1 in photo 1's block
    assert np.allclose(res.camera_cofactors(1), qxx[np.ix_(k, k)], rtol=1e-4,
                       atol=1e-4 * np.abs(qxx[np.ix_(k, k)]).max())
    k = [index[(2, s)] for s in range(3)]  # the shared camera in the border
    assert np.allclose(res.camera_cofactors(5), qxx[np.ix_(k, k)], rtol=1e-4,
                       atol=1e-4 * np.abs(qxx[np.ix_(k, k)]).max())


def test_statistics_with_sparse_jacobians_equal_dense_ones(bal_case, mixed_case):
    """With the linearisation's own Jacobians, the algebra of the 9-unknown photo blocks
    (and of held camera columns beside a border) equals dense brute force to 1e-9."""
    from dense import dense_system

    for _, model, qc in (bal_case, mixed_case):
        a, p = dense_system(model)
        qxx = np.linalg.inv(a.T @ (p[:, None] * a))
        qll = np.einsum("ij,jk,ik->i", a, qxx, a)
        assert np.allclose(model.adjusted_cofactor_diag(), qll, rtol=1e-9,
                           atol=1e-12 * qll.max())
        ok = qc.quality.controlled
        assert np.allclose(qc.quality.redundancy_number[ok], 1 - p[ok] * qll[ok], atol=1e-9)


def test_separability_equals_the_dense_one(bal_case, mixed_case):
    """rho_max, its partner and the MSB (issue 30) with the camera parameters in the
    photos' blocks (and a shared camera in the border) equal dense brute force."""
    from separability_dense import check

    for _, model, _ in (bal_case, mixed_case):
        check(model)


@pytest.mark.parametrize("which", ["bal", "mixed"])
def test_the_same_numbers_as_with_every_camera_in_the_border(which, bal_case, mixed_case,
                                                             monkeypatch):
    res, model, qc = {"bal": bal_case, "mixed": mixed_case}[which]
    monkeypatch.setattr(calibration, "PHOTO_BLOCK_SHARE", 2.0)  # never in the photo blocks
    border, _, qb = _fit(res.problem.block)
    assert border.problem.b == 6 and border.problem.calibration.n_global == \
        res.problem.calibration.n
    assert res.vtpv == pytest.approx(border.vtpv, rel=1e-12)
    assert np.allclose(res.eo, border.eo, rtol=0, atol=1e-12)
    q, r = qc.quality, qb.quality
    ok = q.controlled
    assert np.array_equal(ok, r.controlled)
    assert np.allclose(q.redundancy_number[ok], r.redundancy_number[ok], rtol=0, atol=1e-11)
    assert np.allclose(q.w[ok], r.w[ok], rtol=1e-8, atol=1e-10)
    assert np.allclose(q.mdb[ok], r.mdb[ok], rtol=1e-10)
    assert np.allclose(res.eo_std, border.eo_std, rtol=1e-9)
    for a, b in zip(res.camera_table(), border.camera_table(), strict=True):
        assert a["value"] == pytest.approx(b["value"], rel=1e-11, abs=1e-14)
        assert (a["sigma"] is None) == (b["sigma"] is None)
        if a["sigma"] is not None:
            assert a["sigma"] == pytest.approx(b["sigma"], rel=1e-9)
    ta, tb = calibration_tests(res, TESTS), calibration_tests(border, TESTS)
    assert [t.name for t in ta] == [t.name for t in tb] and len(ta) > 8
    assert np.allclose([t.statistic for t in ta], [t.statistic for t in tb], rtol=1e-8)
    # the correlations of each camera's parameters; those beyond 0.95 within a photo's block
    for a, b in zip(res.camera_correlations(), border.camera_correlations(), strict=True):
        assert a["parameters"] == b["parameters"]
        assert np.allclose(a["matrix"], b["matrix"], atol=2e-6)
    within = [t for t in border.high_correlations() if " of photo " not in t
              and t.split(" of camera ")[1].split()[0] == t.split(" of camera ")[2].split()[0]]
    assert [t for t in res.high_correlations() if " of photo " not in t] == within


def test_which_cameras_go_into_their_photos_blocks():
    block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=4, seed=2))
    cal = Calibration(block.cameras, block.photos.camera, free=(("c", "x0", "y0"),))
    assert np.all(cal.owner == -1) and cal.n_global == 3 and cal.photo_width == 0
    bal = bal_to_block(_bal(ncam=6))
    bal_free = bal.settings.calibration_free
    cal = Calibration(bal.cameras, bal.photos.camera, free=bal_free)
    assert np.array_equal(cal.owner, np.arange(6)) and cal.photo_width == 3
    assert cal.global_labels == [] and len(cal.labels) == 18
    # fewer than half of the photos with a camera of their own: the border is cheaper
    cal = Calibration(bal.cameras, np.array([0, 1, 2, 2, 2, 2, 2]), free=bal_free)
    assert np.all(cal.owner == -1)
    four = bal_to_block(_bal(ncam=4))
    cal = Calibration(four.cameras, np.array([0, 1, 2, 3, 3, 3]),
                      free=four.settings.calibration_free)
    assert list(cal.owner) == [0, 1, 2, -1]
    assert cal.held_photo_columns.sum() == 9 and cal.n_global == 3  # photos 3-5 share 3
    # without the photos' cameras every camera is in the border (as before issue 32)
    assert np.all(Calibration(bal.cameras, free=bal_free).owner == -1)
