"""The cofactor of the mean of the check points' adjusted coordinates.

The adjusted coordinates of different points are correlated: they share the datum that the
control defines (a common shift, rotation and scale of the whole block with the errors of
the control) and the orientations of the photos that see them.  The mean miss of n check
points therefore has the variance g' Q g, g = (1/n) per check point and axis, not sigma^2 / n
as if the misses were independent.  One forward substitution through the factor of the
normal equations gives it (W' W = g' N^-1 g, three columns: X, Y, Z), without any matrix
that grows with the block.
"""

from __future__ import annotations

import numpy as np

from baarda.bundle.bundle_result import BundleResult


def check_mean_cofactor(result: BundleResult, points: np.ndarray | None = None
                        ) -> np.ndarray | None:
    """(3, 3) cofactor matrix (unscaled: times sigma0^2 a covariance, m^2) of the mean of the
    adjusted X, Y, Z of the check points (the local frame the block was adjusted in);
    `points`: block indices of the points to average (default: every adjusted check point).
    None for a free network (its check points are compared after a similarity onto them,
    which takes their mean out) or without such points."""
    if result.free_network:
        return None
    pb, pts = result.problem, result.block.points
    if points is None:
        points = np.flatnonzero((pts.role == "check") & (pb.remap >= 0))
    points = np.asarray(points, np.int64)
    if not len(points):
        return None
    n = len(points)
    s = result.factor.system
    gf = np.zeros((s.nf, s.b, 3))
    gp = np.zeros((s.np, s.d, 3))
    gg = np.zeros((s.ng, 3)) if s.ng else None
    axes = np.arange(3)
    elim = pb.eremap[points]
    e = elim[elim >= 0]
    np.add.at(gp, (e[:, None], axes[None, :], axes[None, :]), 1.0 / n)
    border = pb.bremap[points]
    b = border[border >= 0]
    if len(b):
        assert gg is not None  # border points are global unknowns
        cols = pb.global_layout.start("points") + 3 * b[:, None] + axes[None, :]
        np.add.at(gg, (cols, axes[None, :]), 1.0 / n)
    w = result.factor.forward(gf, gp, gg)
    return w.T @ w
