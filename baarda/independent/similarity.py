"""Similarity transformations of independent models and their Jacobians, vectorised.

Model coordinates x (mm, model scale) and terrain coordinates X (m) of one point in one
model are related by a spatial similarity transformation about the model's fixed centroid c:

    X = T + (1 / mu) R (x - c)          x = c + mu R^T (X - T)          (3D, 7 parameters)

with T (m) the terrain position of the centroid, R = R(omega, phi, kappa) of
baarda.block.rotation (model frame -> terrain frame) and mu (mm per m) the inverse scale.
The planimetric form (4 parameters) is the same with R the 2 x 2 rotation by kappa:

    x = c + mu R(kappa)^T (X - T),   R(kappa) = [[cos k, -sin k], [sin k, cos k]].

The observation equations of the adjustment use the inverse form (model coordinates are the
observations).  Parameter order: 3D (TX, TY, TZ, omega, phi, kappa, mu); 2D (TX, TY, kappa, mu).
"""

from __future__ import annotations

import numpy as np

from baarda.block.rotation import angles_from_matrix, rotation_and_derivatives, rotation_matrix

B3, B2 = 7, 4


def inverse3d(params: np.ndarray, xyz: np.ndarray, centroid: np.ndarray):
    """Model coordinates (m, 3) of terrain points xyz (m, 3) and the Jacobians.

    params (m, 7) and centroid (m, 3) per observation.  Returns x (m, 3) [mm],
    d x / d params (m, 3, 7) and d x / d X (m, 3, 3).
    """
    r, dro, drp, drk = rotation_and_derivatives(params[:, 3], params[:, 4], params[:, 5])
    mu = params[:, 6]
    d = xyz - params[:, :3]
    rtd = np.einsum("mji,mj->mi", r, d)  # R^T d
    x = centroid + mu[:, None] * rtd
    jp = mu[:, None, None] * np.swapaxes(r, 1, 2)
    jf = np.empty((len(x), 3, B3))
    jf[:, :, :3] = -jp
    for k, dr in enumerate((dro, drp, drk)):
        jf[:, :, 3 + k] = mu[:, None] * np.einsum("mji,mj->mi", dr, d)
    jf[:, :, 6] = rtd
    return x, jf, jp


def forward3d(params: np.ndarray, x: np.ndarray, centroid: np.ndarray):
    """Terrain coordinates (m, 3) of model points and d X / d params (m, 3, 7)."""
    r, dro, drp, drk = rotation_and_derivatives(params[:, 3], params[:, 4], params[:, 5])
    s = 1.0 / params[:, 6]
    d = x - centroid
    rd = np.einsum("mij,mj->mi", r, d)
    xyz = params[:, :3] + s[:, None] * rd
    jf = np.zeros((len(x), 3, B3))
    jf[:, [0, 1, 2], [0, 1, 2]] = 1.0
    for k, dr in enumerate((dro, drp, drk)):
        jf[:, :, 3 + k] = s[:, None] * np.einsum("mij,mj->mi", dr, d)
    jf[:, :, 6] = -(s**2)[:, None] * rd
    return xyz, jf


def _rot2(kappa: np.ndarray):
    c, s = np.cos(kappa), np.sin(kappa)
    r = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    dr = np.stack([np.stack([-s, -c], -1), np.stack([c, -s], -1)], -2)
    return r, dr


def inverse2d(params: np.ndarray, xy: np.ndarray, centroid: np.ndarray):
    """Planimetric model coordinates (m, 2) [mm] and Jacobians (m, 2, 4), (m, 2, 2)."""
    r, dr = _rot2(params[:, 2])
    mu = params[:, 3]
    d = xy - params[:, :2]
    rtd = np.einsum("mji,mj->mi", r, d)
    x = centroid + mu[:, None] * rtd
    jp = mu[:, None, None] * np.swapaxes(r, 1, 2)
    jf = np.empty((len(x), 2, B2))
    jf[:, :, :2] = -jp
    jf[:, :, 2] = mu[:, None] * np.einsum("mji,mj->mi", dr, d)
    jf[:, :, 3] = rtd
    return x, jf, jp


def forward2d(params: np.ndarray, x: np.ndarray, centroid: np.ndarray):
    """Planimetric terrain coordinates (m, 2) of model points and d X / d params (m, 2, 4)."""
    r, dr = _rot2(params[:, 2])
    s = 1.0 / params[:, 3]
    d = x - centroid
    rd = np.einsum("mij,mj->mi", r, d)
    xy = params[:, :2] + s[:, None] * rd
    jf = np.zeros((len(x), 2, B2))
    jf[:, [0, 1], [0, 1]] = 1.0
    jf[:, :, 2] = s[:, None] * np.einsum("mij,mj->mi", dr, d)
    jf[:, :, 3] = -(s**2)[:, None] * rd
    return xy, jf


# ------------------------------------------------------------------ closed-form fits
def fit3d(src: np.ndarray, dst: np.ndarray, weights: np.ndarray | None = None):
    """Least-squares similarity dst ~ t + s R src (Umeyama 1991); returns (s, R, t).

    src, dst (n, 3) with n >= 3 points not on one line; weights (n,) optional.
    """
    w = np.ones(len(src)) if weights is None else np.asarray(weights, float)
    w = w / w.sum()
    ms, md = w @ src, w @ dst
    a, b = src - ms, dst - md
    cov = (b * w[:, None]).T @ a
    u, sv, vt = np.linalg.svd(cov)
    e = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        e[2, 2] = -1.0
    r = u @ e @ vt
    with np.errstate(over="ignore"):  # coordinates beyond 1e154: var inf, s 0, which the
        var = float(np.sum(w * np.sum(a**2, axis=1)))  # callers report as degenerate
    s = float(np.sum(sv * np.diag(e)) / var)
    return s, r, md - s * r @ ms


def fit2d(src: np.ndarray, dst: np.ndarray, weights: np.ndarray | None = None):
    """Least-squares 2D similarity dst ~ t + s R(kappa) src; returns (s, kappa, t)."""
    w = np.ones(len(src)) if weights is None else np.asarray(weights, float)
    w = w / w.sum()
    ms, md = w @ src, w @ dst
    a, b = src - ms, dst - md
    p = np.sum(w * (a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]))
    q = np.sum(w * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]))
    var = np.sum(w * np.sum(a**2, axis=1))
    kappa = float(np.arctan2(q, p))
    s = float(np.hypot(p, q) / var)
    r, _ = _rot2(np.array([kappa]))
    return s, kappa, md - s * r[0] @ ms


def params3d(s: float, r: np.ndarray, t: np.ndarray, centroid: np.ndarray) -> np.ndarray:
    """Parameters (7,) of X = t + s R x expressed about the centroid."""
    return np.concatenate([t + s * r @ centroid, angles_from_matrix(r), [1.0 / s]])


def params2d(s: float, kappa: float, t: np.ndarray, centroid: np.ndarray) -> np.ndarray:
    r, _ = _rot2(np.array([kappa]))
    return np.concatenate([t + s * r[0] @ centroid, [kappa, 1.0 / s]])


def rotation3d(params: np.ndarray) -> np.ndarray:
    return rotation_matrix(params[..., 3], params[..., 4], params[..., 5])

