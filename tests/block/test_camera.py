"""Lens models of block/camera.py and their use in the collinearity projection.

Jacobians are checked against central differences; the forward model against the BAL
formula written out independently and against pycolmap's OPENCV camera; inverses by
round trips.
"""

import numpy as np
import pytest

from baarda.block.camera import (
    brown_terms,
    correct_backward,
    distort,
    uncorrect_backward,
    undistort,
)
from baarda.block.rotation import rotation_matrix
from baarda.bundle.collinearity import project, project_with_jacobians

rng = np.random.default_rng(7)


def _numeric(f, x, h):
    cols = []
    for k in range(x.shape[1]):
        e = np.zeros_like(x)
        e[:, k] = h
        cols.append((f(x + e) - f(x - e)) / (2 * h))
    return np.stack(cols, axis=-1)


def test_brown_terms_jacobian():
    u = rng.uniform(-0.8, 0.8, (50, 2))
    d = rng.normal(0, 0.1, (50, 5))
    _, jac = brown_terms(u, d)
    num = _numeric(lambda v: brown_terms(v, d)[0], u, 1e-6)
    assert np.allclose(jac, num, atol=1e-8)


def _setup(m=40):
    eo = np.column_stack([rng.normal(0, 5, (m, 3)) + [0, 0, 100],
                          rng.normal(0, 0.1, (m, 3))])
    xyz = rng.normal(0, 20, (m, 3))
    focal = rng.uniform(20, 60, m)
    pp = rng.normal(0, 0.5, (m, 2))
    d = np.column_stack([rng.normal(0, 0.1, m), rng.normal(0, 0.05, m),
                         rng.normal(0, 0.01, m), rng.normal(0, 0.01, (m, 2))])
    return eo, xyz, focal, pp, d


def test_projection_jacobians_with_forward_distortion():
    eo, xyz, focal, pp, d = _setup()
    xy, je, jp = project_with_jacobians(eo, xyz, focal, pp, d)
    assert np.allclose(xy, project(eo, xyz, focal, pp, d), atol=1e-12)
    ne = _numeric(lambda e: project(e, xyz, focal, pp, d), eo, 1e-7)
    npt = _numeric(lambda p: project(eo, p, focal, pp, d), xyz, 1e-6)
    scale = np.abs(je).max()
    assert np.allclose(je, ne, atol=1e-7 * scale)
    assert np.allclose(jp, npt, atol=1e-7 * np.abs(jp).max())
    # zero coefficients: identical to the undistorted projection
    assert np.allclose(project(eo, xyz, focal, pp, np.zeros_like(d)), project(eo, xyz, focal, pp))


def test_forward_model_is_bal_formula():
    """BAL: P = R X + t, p = -P/P.z, x = f (1 + k1 |p|^2 + k2 |p|^4) p (independent code)."""
    m = 30
    eo, xyz, focal, _, _ = _setup(m)
    k1, k2 = rng.normal(0, 0.2, m), rng.normal(0, 0.05, m)
    r = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])
    rb = np.swapaxes(r, 1, 2)  # BAL rotation maps world -> camera
    t = -np.einsum("mij,mj->mi", rb, eo[:, :3])
    pc = np.einsum("mij,mj->mi", rb, xyz) + t
    p = -pc[:, :2] / pc[:, 2:3]
    n2 = np.sum(p**2, axis=1)
    expect = (focal * (1 + k1 * n2 + k2 * n2**2))[:, None] * p
    d = np.column_stack([k1, k2, np.zeros((m, 3))])
    got = project(eo, xyz, focal, np.zeros((m, 2)), d)
    assert np.allclose(got, expect, rtol=1e-12, atol=1e-12)


def test_forward_model_matches_pycolmap_opencv():
    pycolmap = pytest.importorskip("pycolmap")
    f, cx, cy = 1200.0, 640.3, 479.7
    k1, k2, p1, p2 = -0.21, 0.07, 0.0013, -0.0021
    cam = pycolmap.Camera(model="OPENCV", width=1280, height=960,
                          params=[f, f, cx, cy, k1, k2, p1, p2])
    pts = np.column_stack([rng.uniform(-0.4, 0.4, (20, 2)), np.ones(20)])
    pix = cam.img_from_cam(pts)
    # baarda frame: x right, y up, pixel size 1 (units of pixels), c = f
    n = pts[:, :2]
    ideal = np.column_stack([n[:, 0], -n[:, 1]]) * f
    d = np.tile([k1, k2, 0.0, p2, -p1], (20, 1))  # OpenCV order, y flipped
    got, _ = distort(ideal, np.zeros((20, 2)), np.full(20, f), d)
    assert np.allclose(got[:, 0] + cx, pix[:, 0], atol=1e-9)
    assert np.allclose(cy - got[:, 1], pix[:, 1], atol=1e-9)


def test_inverses():
    m = 25
    _, _, focal, pp, d = _setup(m)
    d = d * 0.3
    xy = pp + rng.uniform(-10, 10, (m, 2))
    assert np.allclose(undistort(distort(xy, pp, focal, d)[0], pp, focal, d), xy, atol=1e-10)
    db = np.column_stack([rng.normal(0, 1e-4, m), rng.normal(0, 1e-7, m), np.zeros(m),
                          rng.normal(0, 1e-5, (m, 2))])
    assert np.allclose(uncorrect_backward(correct_backward(xy, pp, db), pp, db), xy,
                       atol=1e-10)
