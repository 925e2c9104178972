"""Global (border) unknowns and extra observations in the Schur system equal dense brute
force: the step, every covariance block, the adjusted cofactors, point effects and the
column products (random Jacobians, so every term is exercised)."""

import numpy as np
import pytest

from baarda.adjustment.schur_system import Linearization, SchurSystem

NF, B, NP, D, K, NG, KX = 5, 3, 7, 2, 2, 4, 2


@pytest.fixture(scope="module")
def case():
    rng = np.random.default_rng(7)
    frame, point = [], []
    for j in range(NP):  # every point on 2 or 3 frames
        for f in rng.choice(NF, size=2 + j % 2, replace=False):
            frame.append(f)
            point.append(j)
    frame, point = np.array(frame), np.array(point)
    m = len(frame)
    gcol = rng.integers(-1, NG, size=(m, 2))
    gcol[gcol[:, 0] == gcol[:, 1], 1] = -1  # no column twice in one row
    control = np.array([0, 3])
    x_frame = np.array([1, -1, 4])
    system = SchurSystem(NF, B, NP, D, frame, point, control, ng=NG, gcol=gcol,
                         x_frame=x_frame, n_fixed=2)
    mx = len(x_frame)
    lin = Linearization(
        jf=rng.normal(size=(m, K, B)), jp=rng.normal(size=(m, K, D)),
        w=rng.uniform(0.5, 2, size=(m, K)), e=rng.normal(size=(m, K)),
        jc=rng.normal(size=(2, D, D)), wc=rng.uniform(0.5, 2, size=(2, D)),
        ec=rng.normal(size=(2, D)), jg=rng.normal(size=(m, K, 2)),
        jxf=rng.normal(size=(mx, KX, B)), jxg=rng.normal(size=(mx, KX, NG)),
        wx=rng.uniform(0.5, 2, size=(mx, KX)), ex=rng.normal(size=(mx, KX)),
        wp=np.where(np.arange(NP * D).reshape(NP, D) == 5, 1e6, 0.0),
        ep=np.zeros((NP, D)), wg=np.array([0, 0, 3e5, 0.0]), eg=np.zeros(NG))
    return system, lin


def dense(system, lin):
    """Design rows of every observation (frame-point, control, extra), and of the direct
    constraints, with weights and misclosures."""
    nu = NF * B + NP * D + NG
    rows, w, e = [], [], []
    for i in range(len(system.frame)):
        for r in range(K):
            a = np.zeros(nu)
            a[system.frame[i] * B:(system.frame[i] + 1) * B] = lin.jf[i, r]
            a[NF * B + system.point[i] * D:NF * B + (system.point[i] + 1) * D] = lin.jp[i, r]
            for c, col in enumerate(system.gcol[i]):
                if col >= 0:
                    a[NF * B + NP * D + col] = lin.jg[i, r, c]
            rows.append(a), w.append(lin.w[i, r]), e.append(lin.e[i, r])
    for i, j in enumerate(system.control_point):
        for r in range(D):
            a = np.zeros(nu)
            a[NF * B + j * D:NF * B + (j + 1) * D] = lin.jc[i, r]
            rows.append(a), w.append(lin.wc[i, r]), e.append(lin.ec[i, r])
    for i, f in enumerate(system.x_frame):
        for r in range(KX):
            a = np.zeros(nu)
            if f >= 0:
                a[f * B:(f + 1) * B] = lin.jxf[i, r]
            a[NF * B + NP * D:] = lin.jxg[i, r]
            rows.append(a), w.append(lin.wx[i, r]), e.append(lin.ex[i, r])
    n_obs = len(rows)
    for u, (wt, et) in enumerate(zip(lin.wp.ravel(), lin.ep.ravel(), strict=True)):
        if wt:
            a = np.zeros(nu)
            a[NF * B + u] = 1.0
            rows.append(a), w.append(wt), e.append(et)
    for g in range(NG):
        if lin.wg[g]:
            a = np.zeros(nu)
            a[NF * B + NP * D + g] = 1.0
            rows.append(a), w.append(lin.wg[g]), e.append(lin.eg[g])
    return np.array(rows), np.array(w), np.array(e), n_obs


def test_step_and_covariances(case):
    system, lin = case
    f = system.factorize(lin)
    a, w, e, n_obs = dense(system, lin)
    n = a.T @ (w[:, None] * a)
    x = np.linalg.solve(n, a.T @ (w * e))
    xf, xp, xg = f.step()
    assert np.allclose(np.concatenate([xf.ravel(), xp.ravel(), xg]), x, rtol=1e-10, atol=1e-12)
    q = np.linalg.inv(n)
    sf = f.frame_covariance()
    for k in range(NF):
        assert np.allclose(sf[k], q[k * B:(k + 1) * B, k * B:(k + 1) * B], atol=1e-12)
    sp = f.point_covariance()
    o = NF * B
    for j in range(NP):
        assert np.allclose(sp[j], q[o + j * D:o + (j + 1) * D, o + j * D:o + (j + 1) * D],
                           atol=1e-12)
    assert np.allclose(f.global_covariance(), q[-NG:, -NG:], atol=1e-12)
    assert np.allclose(f.frame_global_covariance().reshape(NF * B, NG), q[:NF * B, -NG:],
                       atol=1e-12)
    assert system.n_unknowns == NF * B + NP * D + NG - 2


def test_adjusted_cofactors_and_point_effects(case):
    system, lin = case
    f = system.factorize(lin)
    a, w, e, n_obs = dense(system, lin)
    q = np.linalg.inv(a.T @ (w[:, None] * a))
    ao = a[:n_obs]
    qll = ao @ q @ ao.T
    qm, qc, qx = f.adjusted_cofactors()
    m = len(system.frame)
    blocks = qm
    for i in range(m):
        assert np.allclose(blocks[i], qll[i * K:(i + 1) * K, i * K:(i + 1) * K], atol=1e-12)
    o = m * K
    for i in range(2):
        assert np.allclose(qc[i], qll[o + i * D:o + (i + 1) * D, o + i * D:o + (i + 1) * D],
                           atol=1e-12)
    o += 2 * D
    for i in range(len(system.x_frame)):
        assert np.allclose(qx[i], qll[o + i * KX:o + (i + 1) * KX, o + i * KX:o + (i + 1) * KX],
                           atol=1e-12)
    # effect of each row's unit error on its own point: Sigma_(point, x) a_i^T p_i
    g, gc, gx = f.point_effect()
    eff = q @ (ao.T * w[:n_obs])  # (nu, n_obs)
    for i in range(m):
        j = system.point[i]
        ref = eff[NF * B + j * D:NF * B + (j + 1) * D, i * K:(i + 1) * K].T
        assert np.allclose(g[i], ref, atol=1e-12)
    for i, j in enumerate(system.control_point):
        c = m * K + i * D
        ref = eff[NF * B + j * D:NF * B + (j + 1) * D, c:c + D].T
        assert np.allclose(gc[i], ref, atol=1e-12)
    assert gx.shape == (3, KX, D)


def test_column_products(case):
    system, lin = case
    f = system.factorize(lin)
    a, w, e, n_obs = dense(system, lin)
    nmat = a.T @ (w[:, None] * a)
    ao, wo = a[:n_obs], w[:n_obs]
    rng = np.random.default_rng(3)
    h = rng.normal(size=(n_obs, 3))
    m = len(system.frame)
    hm = h[:m * K].reshape(m, K, 3)
    hc = h[m * K:m * K + 2 * D].reshape(2, D, 3)
    hx = h[m * K + 2 * D:].reshape(3, KX, 3)
    gf, gp, gg = f.apply_AtP(hm, hc, hx)
    g = ao.T @ (wo[:, None] * h)
    assert np.allclose(np.concatenate([gf.reshape(-1, 3), gp.reshape(-1, 3), gg]), g,
                       atol=1e-12)
    xf, xp, xg = f.solve_normal(gf, gp, gg)
    x = np.linalg.solve(nmat, g)
    assert np.allclose(np.concatenate([xf.reshape(-1, 3), xp.reshape(-1, 3), xg]), x,
                       atol=1e-10)
    wmat = f.forward(gf, gp, gg)
    assert np.allclose(wmat.T @ wmat, g.T @ x, rtol=1e-10)
    rows, rows_c, rows_x = f.apply_A(xf, xp, xg)
    ref = ao @ x
    got = np.concatenate([rows.reshape(-1, 3), rows_c.reshape(-1, 3), rows_x.reshape(-1, 3)])
    assert np.allclose(got, ref, atol=1e-10)


def test_an_undetermined_global_is_named(case):
    from dataclasses import replace

    from baarda.errors import GeometryError

    system, lin = case
    s2 = SchurSystem(NF, B, NP, D, system.frame, system.point, system.control_point,
                     ng=NG + 1, gcol=system.gcol, x_frame=system.x_frame,
                     global_names=[f"parameter {i}" for i in range(NG + 1)])
    jxg = np.concatenate([lin.jxg, np.zeros((3, KX, 1))], axis=2)
    bad = replace(lin, jxg=jxg, wg=np.append(lin.wg, 0.0), eg=np.append(lin.eg, 0.0))
    with pytest.raises(GeometryError, match="parameter 4 is not determined"):
        s2.factorize(bad)
