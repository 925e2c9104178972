"""The low-rank update of the on-line bundle (online/lowrank.py) against the dense
adjustment at the same linearisation point: residuals, their cofactors, the corrections of
old and new unknowns, the old observations' cofactors and the prediction before inclusion."""

from dataclasses import replace

import numpy as np
import pytest
from dense import dense_system

from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.bundle_result import BundleResult
from baarda.online.bundle import OnlineBundle
from baarda.options import SolveOptions
from baarda.simulate.aerial import FlightPlan, simulate_block

TIGHT = SolveOptions(max_iterations=50, tolerance=1e-10, min_step=1e-3, final_step=True)


def labels(model):
    return [(str(k), str(f), str(p), str(c)) for k, f, p, c in
            zip(model.kind, model.frame, model.point, model.component, strict=True)]


@pytest.fixture(scope="module")
def case():
    """A 2 x 5 block with GNSS; the on-line bundle starts without one tie point (all its
    rays), two image points of other points and one GNSS position, which are then added
    (held in the low-rank update: no refactorisation)."""
    block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=5, pattern=4,
                                         relief_m=30.0, gnss_sigma_m=0.05, seed=8))
    im, pts = block.image, block.points
    rays = np.bincount(im.point, minlength=len(pts))
    new = int(np.flatnonzero((rays >= 3) & (pts.role == "tie"))[0])
    others = np.flatnonzero((im.point != new) & (rays[im.point] >= 3))[[0, 7]]
    drop = (im.point == new) | np.isin(np.arange(len(im)), others)
    start = replace(block.select_image(~drop), gnss=replace(
        block.gnss, photo=block.gnss.photo[1:], xyz=block.gnss.xyz[1:],
        sigma=block.gnss.sigma[1:]))
    ob = OnlineBundle(start, solve=TIGHT, max_rows=10_000, linear_limit=np.inf)
    ids, pids = block.photos.ids, pts.ids
    single = ob.add_image_point(ids[im.photo[others[0]]], pids[im.point[others[0]]],
                                *im.xy_mm[others[0]])
    for r in np.flatnonzero(im.point == new):
        ob.add_image_point(ids[im.photo[r]], pids[new], *im.xy_mm[r])
    ob.add_image_point(ids[im.photo[others[1]]], pids[im.point[others[1]]],
                       *im.xy_mm[others[1]])
    ob.add_gnss(ids[block.gnss.photo[0]], block.gnss.xyz[0], block.gnss.sigma[0])
    assert not any(a.refactorised for a in ob.answers[1:])
    assert len(ob._pending) == 2 + 2 * rays[new] + 2 + 3  # image, new point, image, GNSS
    assert [k for (k, _), _ in ob._ycol.items()] == ["point"]
    return block, ob, single, pids[new]


def dense_at_linearisation(block, ob):
    """The full block linearised where the low-rank update linearised it (the
    factorisation's estimate, the new point at its approximation): dense A, P, e and the
    one-step solution."""
    f = ob._f
    m = ob.m
    problem = BundleProblem(ob.m.state_block(np.array(m.photo_eo),
                                             np.full((len(m.point_ids), 3), np.nan))[0])
    ids = [problem.block.points.ids[j] for j in problem.elim_ids]
    xyz = np.empty((len(ids), 3))
    for n, pid in enumerate(ids):
        j = m.point_at[pid]
        c = ob._ycol.get(("point", j))
        xyz[n] = ob._y0[c:c + 3] if c is not None else f.result.state[1][f.elim_of[j]]
    state = (f.result.state[0], xyz)
    lin = problem.linearize(state)
    result = BundleResult(problem, state, lin, problem.factorize(lin), 0, True)
    model = BundleModel(result)
    a, p = dense_system(model)
    e = -model.residuals
    n = a.T @ (p[:, None] * a)
    q = np.linalg.inv(n)
    dx = q @ (a.T @ (p * e))
    return model, a, p, e, q, dx, ids


def test_new_rows_equal_the_dense_step(case):
    block, ob, _, new_point = case
    f = ob._f
    sol = f.lowrank.solution()
    model, a, p, e, q, dx, ids = dense_at_linearisation(block, ob)
    at = {k: n for n, k in enumerate(labels(model))}
    rows = [at[ob._label(k)[:1] + (ob._label(k)[1] if ob._label(k)[0] != "control" else "",)
               + ob._label(k)[2:]] for k in ob._pending]
    v = a @ dx - e
    qvv = np.diag(1.0 / p) - a @ q @ a.T
    assert np.allclose(sol.v, v[rows], rtol=1e-8, atol=1e-12)
    assert np.allclose(sol.qvv, qvv[np.ix_(rows, rows)], rtol=1e-7, atol=1e-14)
    nf = len(ob.m.photo_ids)
    assert np.allclose(sol.dxf, dx[:6 * nf].reshape(nf, 6), rtol=1e-7, atol=1e-10)
    c = ob._ycol[("point", ob.m.point_at[new_point])]
    k = ids.index(new_point)
    assert np.allclose(sol.dy[c:c + 3], dx[6 * nf + 3 * k:6 * nf + 3 * k + 3], rtol=1e-7,
                       atol=1e-9)
    # the old observations: v0 + a dx and q0 - (a H) W (a H)^T, every one of them
    from baarda.online.rows import factor_rows

    flat = np.arange(len(f.keys))
    qo, vo = f.lowrank.old_rows(factor_rows(f.problem, f.result.factor, flat), f.q0, f.v0)
    old = [at[ob._label(k)[:1] + (ob._label(k)[1] if ob._label(k)[0] != "control" else "",)
              + ob._label(k)[2:]] for k in f.keys]
    assert np.allclose(vo, v[old], rtol=1e-7, atol=1e-12)
    assert np.allclose(qo, (a @ q @ a.T)[old, old], rtol=1e-7, atol=1e-14)


def test_prediction_before_inclusion(case):
    """The first addition (an image point on a photo and a point of the block): predicted
    misclosure l - f(x0) with variance sigma^2 + a N0^-1 a^T (the dense cofactor of the
    block before it)."""
    block, ob, single, _ = case
    f = ob._f
    model = f.model
    a0, p0 = dense_system(model)
    q0 = np.linalg.inv(a0.T @ (p0[:, None] * a0))
    from baarda.online.rows import image_rows

    t = single.tested
    photo, point = t[0].photo, t[0].point
    i, j = ob.m.photo_at[photo], ob.m.point_at[point]
    r = [r for r in ob.m.rows_of_photo[i] if ob.m.im_point[r] == j][0]
    e, je, jp, _ = image_rows(f.problem.block, f.problem, np.array([ob.m.photo_cam[i]]),
                              f.result.state[0][[f.frame_of[i]]],
                              f.result.state[1][[f.elim_of[j]]], ob.m.im_xy[r][None], np.zeros(0))
    nf = len(f.result.state[0])
    arow = np.zeros((2, a0.shape[1]))
    arow[:, 6 * f.frame_of[i]:6 * f.frame_of[i] + 6] = je[0]
    arow[:, 6 * nf + 3 * f.elim_of[j]:6 * nf + 3 * f.elim_of[j] + 3] = jp[0]
    var = ob.m.im_sigma[r] ** 2 + np.diag(arow @ q0 @ arow.T)
    assert np.allclose([t[0].predicted, t[1].predicted], e[0], rtol=1e-12)
    assert np.allclose([t[0].sigma_predicted, t[1].sigma_predicted], np.sqrt(var), rtol=1e-8)
    # after inclusion: r = sigma^2 W_ii sigma^2 / sigma^2 and w from the 2 x 2 problem
    c = np.diag(ob.m.im_sigma[r] ** 2) + arow @ q0 @ arow.T
    w = np.linalg.inv(c)
    v = -np.diag(ob.m.im_sigma[r] ** 2) @ w @ e[0]
    qvv = np.diag(ob.m.im_sigma[r] ** 2) @ w @ np.diag(ob.m.im_sigma[r] ** 2)
    assert np.allclose([t[0].residual, t[1].residual], v, rtol=1e-8)
    assert np.allclose([t[0].redundancy, t[1].redundancy],
                       np.diag(qvv) / ob.m.im_sigma[r] ** 2, rtol=1e-8)
    assert np.allclose([t[0].w, t[1].w], -v / np.sqrt(np.diag(qvv)), rtol=1e-8)


def test_block_products_grouped_equal_the_gathered_ones():
    """times() groups the rows by photo or point when the gather would copy k b q numbers
    (a snapshot of 400 points on 12 photos: 52 s -> 6 s); the same numbers either way."""
    from baarda.online.lowrank import GATHER, _block_times, quad_diag

    rng = np.random.default_rng(3)
    k, b, q, n = 900, 6, 300, 40
    assert k * q > GATHER
    j, h = rng.normal(size=(k, b)), rng.normal(size=(n, b, q))
    idx = rng.integers(0, n, k)
    ref = np.einsum("kb,kbq->kq", j, h[idx])
    assert np.abs(_block_times(j, idx, h) - ref).max() < 1e-12 * np.abs(ref).max()
    z, w = rng.normal(size=(k, q)), rng.normal(size=(q, q))
    w = w @ w.T
    ref = np.einsum("kr,rs,ks->k", z, w, z)
    assert np.abs(quad_diag(z, w) - ref).max() < 1e-12 * np.abs(ref).max()


def test_a_large_photo_goes_straight_into_a_factorisation():
    """A group of more rows than a factorisation takes is factored with the block at once
    (no r x r problem of hundreds of rows): its predictions are the low-rank path's, its
    tests the exact ones (the low-rank path's are first order in the new photo's
    approximation: r to 5e-3, w to 2e-3 here)."""
    block = simulate_block(FlightPlan(strips=2, photos_per_strip=6, pattern=5, seed=8))[0]
    im, ids, pids = block.image, block.photos.ids, block.points.ids
    late = [i for i, s in enumerate(block.photos.strip) if s == block.photos.strip[-1]][-2:]
    # and 8 image points of photo 2 whose points stay in the block by their other rays
    rays = np.bincount(im.point, minlength=len(pids))
    again = [r for r in np.flatnonzero(im.photo == 2) if rays[im.point[r]] >= 3][:8]
    keep = ~np.isin(im.photo, late)
    keep[again] = False
    start = block.select_image(keep)
    steps = [(ids[2], again)] + [(ids[i], np.flatnonzero(im.photo == i)) for i in late]
    answers = {}
    for max_rows in (5, 10_000):
        ob = OnlineBundle(start, max_rows=max_rows)
        answers[max_rows] = [ob.add_photo(photo, {pids[im.point[r]]: tuple(im.xy_mm[r])
                                                  for r in rows}) for photo, rows in steps]
    for big, small in zip(answers[5], answers[10_000], strict=True):
        assert big.refactorised and not small.refactorised and len(big.tested) > 5
        assert [t.verdict for t in big.tested] == [t.verdict for t in small.tested]
        for a, b in zip(big.tested, small.tested, strict=True):
            assert (a.photo, a.point, a.component) == (b.photo, b.point, b.component)
            assert a.redundancy == pytest.approx(b.redundancy, rel=5e-3, abs=1e-5)
            assert a.w == pytest.approx(b.w, abs=2e-3, nan_ok=True)
    # photo 2's points, the first step: predicted from the same block by both paths
    known = zip(answers[5][0].tested, answers[10_000][0].tested, strict=True)
    for a, b in known:
        assert np.isfinite(a.predicted)
        assert a.predicted == pytest.approx(b.predicted, rel=1e-9, abs=1e-12)
        assert a.sigma_predicted == pytest.approx(b.sigma_predicted, rel=1e-9)
    assert len(answers[5][0].tested) == 16
