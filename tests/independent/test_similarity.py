"""Similarity transformations: Jacobians against central differences, closed-form fits."""

import numpy as np
import pytest

from baarda.block.rotation import rotation_matrix
from baarda.independent import similarity as sim


def numeric(f, x, h):
    cols = []
    for i in range(x.shape[1]):
        dx = np.zeros_like(x)
        dx[:, i] = h[i]
        cols.append((f(x + dx) - f(x - dx)) / (2 * h[i]))
    return np.stack(cols, -1)


@pytest.fixture
def data():
    rng = np.random.default_rng(3)
    m = 20
    p3 = np.column_stack([rng.normal(1000, 50, (m, 3)), rng.normal(0, 0.2, (m, 2)),
                          rng.uniform(-3, 3, m), rng.uniform(0.1, 0.3, m)])
    x = rng.normal(0, 300, (m, 3))
    c = rng.normal(0, 20, (m, 3))
    return p3, x, c


def test_inverse3d_jacobians(data):
    p, xyz, c = data
    f = lambda pp: sim.inverse3d(pp, xyz, c)[0]  # noqa: E731
    _, jf, jp = sim.inverse3d(p, xyz, c)
    np.testing.assert_allclose(jf, numeric(f, p, [1e-3] * 3 + [1e-7] * 3 + [1e-7]),
                               rtol=1e-6, atol=1e-6)
    g = lambda xx: sim.inverse3d(p, xx, c)[0]  # noqa: E731
    np.testing.assert_allclose(jp, numeric(g, xyz, [1e-3] * 3), rtol=1e-7, atol=1e-9)


def test_forward3d_inverts_and_jacobian(data):
    p, xyz, c = data
    x = sim.inverse3d(p, xyz, c)[0]
    back, jf = sim.forward3d(p, x, c)
    np.testing.assert_allclose(back, xyz, rtol=0, atol=1e-9)
    f = lambda pp: sim.forward3d(pp, x, c)[0]  # noqa: E731
    np.testing.assert_allclose(jf, numeric(f, p, [1e-3] * 3 + [1e-7] * 3 + [1e-8]),
                               rtol=1e-5, atol=1e-5)


def test_inverse2d_and_forward2d(data):
    p3, xyz, c = data
    p = p3[:, [0, 1, 5, 6]]
    f = lambda pp: sim.inverse2d(pp, xyz[:, :2], c[:, :2])[0]  # noqa: E731
    x, jf, jp = sim.inverse2d(p, xyz[:, :2], c[:, :2])
    np.testing.assert_allclose(jf, numeric(f, p, [1e-3, 1e-3, 1e-7, 1e-7]), rtol=1e-6,
                               atol=1e-6)
    g = lambda xx: sim.inverse2d(p, xx, c[:, :2])[0]  # noqa: E731
    np.testing.assert_allclose(jp, numeric(g, xyz[:, :2], [1e-3] * 2), rtol=1e-7, atol=1e-9)
    back, jb = sim.forward2d(p, x, c[:, :2])
    np.testing.assert_allclose(back, xyz[:, :2], atol=1e-9)
    h = lambda pp: sim.forward2d(pp, x, c[:, :2])[0]  # noqa: E731
    np.testing.assert_allclose(jb, numeric(h, p, [1e-3, 1e-3, 1e-7, 1e-8]), rtol=1e-5,
                               atol=1e-5)
    # the 2D form is the 3D form with omega = phi = 0
    p0 = p3.copy()
    p0[:, 3:5] = 0
    np.testing.assert_allclose(sim.inverse3d(p0, xyz, c)[0][:, :2], x, atol=1e-9)


def test_closed_form_fits_recover_known_transform():
    rng = np.random.default_rng(5)
    src = rng.normal(0, 50, (8, 3))
    r = rotation_matrix(0.1, -0.2, 2.5)
    dst = np.array([100.0, -20, 7]) + 4.0 * src @ r.T
    s, rr, t = sim.fit3d(src, dst)
    assert s == pytest.approx(4.0, rel=1e-12)
    np.testing.assert_allclose(rr, r, atol=1e-12)
    np.testing.assert_allclose(t, [100, -20, 7], atol=1e-9)
    k = 1.1
    r2 = np.array([[np.cos(k), -np.sin(k)], [np.sin(k), np.cos(k)]])
    s2, k2, t2 = sim.fit2d(src[:, :2], 3.0 * src[:, :2] @ r2.T + [5, 6])
    assert (s2, k2) == (pytest.approx(3.0), pytest.approx(k))
    np.testing.assert_allclose(t2, [5, 6], atol=1e-9)
    # parameters about a centroid reproduce the transformation
    c = np.array([1.0, 2.0, 3.0])
    p = sim.params3d(4.0, r, np.array([100.0, -20, 7]), c)
    np.testing.assert_allclose(sim.forward3d(p[None].repeat(8, 0), src, c[None].repeat(8, 0))[0],
                               dst, atol=1e-9)

