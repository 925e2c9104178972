"""A two-photo normal case worked by hand.

Photos at (0, 0, H) and (B, 0, H), vertical, c.  A point at (B/2, 0, 0) has x' = cB/(2h),
x'' = -cB/(2h), y' = y'' = 0 with h = H.  Intersection with the photos fixed:
    Z = H - cB/p  with parallax p = x' - x''
    sigma_Z = sqrt(2) sigma h^2 / (c B),   sigma_X = sigma h / (c sqrt(2)),   sigma_Y likewise
(normal equations N_XX = N_YY = 2c^2/h^2, N_hh = c^2 B^2 / (2 h^4), N_Xh = 0).  The photos
are held by many error-free control points measured 10^4 times more precisely than the
tie point, so the tie point's precision is that of the intersection alone.
"""

import numpy as np
import pytest

from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.bundle.collinearity import project
from baarda.pipeline import adjust

H, B, C, SIG = 1500.0, 600.0, 150.0, 0.005  # m, m, mm, mm


def make_block(tie_xy_mm=None):
    eo = np.array([[0.0, 0.0, H, 0, 0, 0], [B, 0.0, H, 0, 0, 0]])
    gx, gy = np.meshgrid(np.linspace(-200, 800, 6), np.linspace(-400, 400, 5))
    ctrl = np.column_stack([gx.ravel(), gy.ravel(), 20.0 * np.sin(gx.ravel() / 150)])
    tie = np.array([[B / 2, 0.0, 0.0]])
    xyz = np.vstack([ctrl, tie])
    n = len(xyz)
    ph = np.repeat([0, 1], n)
    pt = np.tile(np.arange(n), 2)
    xy = project(eo[ph], xyz[pt], np.full(2 * n, C), np.zeros((2 * n, 2)))
    if tie_xy_mm is not None:
        xy[pt == n - 1] = tie_xy_mm
    sigma = np.full((n, 3), 1e-7)
    sigma[-1] = np.nan
    role = np.array(["control"] * (n - 1) + ["tie"], dtype=object)
    given = xyz.copy()
    given[-1] = np.nan
    eo0 = eo + np.array([1.0, -1.0, 2.0, 0.002, -0.001, 0.003])
    return Block(Settings(), Cameras(["c"], np.array([C]), np.zeros((1, 2))),
                 Photos(["L", "R"], np.zeros(2, int), np.array(["1", "1"], dtype=object), eo0),
                 ImagePoints(ph, pt, xy, np.where(pt == n - 1, SIG, SIG * 1e-4)),
                 GroundPoints([f"C{i}" for i in range(n - 1)] + ["T"], given, sigma, role))


def test_height_from_parallax_and_precision():
    p_hand = 64.0  # mm: x' = 32, x'' = -32 -> Z = H - cB/p
    block = make_block(np.array([[32.0, 1.0], [-32.0, 1.0]]))
    res = adjust(block)
    z_hand = H - C * B / p_hand
    h = H - z_hand
    x_hand = 32.0 * h / C  # x' = c X / h
    y_hand = 1.0 * h / C
    tie = res.problem.remap[len(block.points) - 1]
    assert res.xyz[tie] == pytest.approx([x_hand, y_hand, z_hand], abs=1e-6)
    # precision at the exact point (B/2, 0, 0): from the cofactor (sigma0 = 1 a priori)
    res = adjust(make_block())
    q = res.factor.point_covariance()[tie]
    s = np.sqrt(np.diag(q))
    assert s[2] == pytest.approx(np.sqrt(2) * SIG * 1e-3 * H**2 / (C * 1e-3 * B), rel=1e-5)
    assert s[0] == pytest.approx(SIG * H / (C * np.sqrt(2)), rel=1e-5)
    assert s[1] == pytest.approx(SIG * H / (C * np.sqrt(2)), rel=1e-5)
