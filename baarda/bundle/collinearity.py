"""Collinearity equations and their analytic Jacobians, vectorised over observations.

    u = R^T (X - X0)                      (camera frame, R from rotation.py)
    x = x0 - c * u1 / u3,   y = y0 - c * u2 / u3      (mm)

Parameters of a photo: X0, Y0, Z0 [m], omega, phi, kappa [rad]; of a point: X, Y, Z [m].
With `distortion` (m, 5) the forward lens model of block/camera.py is applied to (x, y) and
the Jacobians follow by the chain rule.
"""

from __future__ import annotations

import numpy as np

from baarda.block.camera import distort
from baarda.block.rotation import rotation_and_derivatives, rotation_matrix


def project(eo: np.ndarray, xyz: np.ndarray, focal: np.ndarray, pp: np.ndarray,
            distortion: np.ndarray | None = None, photo: np.ndarray | None = None
            ) -> np.ndarray:
    """Image coordinates (m, 2) in mm of points xyz (m, 3) on photos eo (m, 6); with
    `photo`, eo holds one row per photo and photo[i] names the photo of point i."""
    r = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])
    if photo is not None:
        r, eo = r[photo], eo[photo]
    u = np.einsum("mji,mj->mi", r, xyz - eo[:, :3])
    xy = pp - focal[:, None] * u[:, :2] / u[:, 2:3]
    return xy if distortion is None else distort(xy, pp, focal, distortion)[0]


def camera_depth(eo: np.ndarray, xyz: np.ndarray, photo: np.ndarray | None = None) -> np.ndarray:
    """-u3: distance of each point in front of the camera along its axis (positive = in front).

    With `photo`, eo holds one row per photo and photo[i] names the photo of point i.
    """
    r = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])
    if photo is not None:
        r, eo = r[photo], eo[photo]
    return -np.einsum("mj,mj->m", r[:, :, 2], xyz - eo[:, :3])


def project_with_jacobians(eo: np.ndarray, xyz: np.ndarray, focal: np.ndarray,
                           pp: np.ndarray, distortion: np.ndarray | None = None,
                           photo: np.ndarray | None = None):
    """Image coordinates (m, 2) and Jacobians d(x, y)/d(eo) (m, 2, 6) and d(x, y)/d(X) (m, 2, 3).

    With `photo`, eo holds one row per photo (rotations are computed once per photo) and
    photo[i] names the photo of observation i.
    """
    rot = rotation_and_derivatives(eo[:, 3], eo[:, 4], eo[:, 5])
    if photo is not None:
        rot = [a[photo] for a in rot]
        eo = eo[photo]
    r, dro, drp, drk = rot
    d = xyz - eo[:, :3]
    u = np.einsum("mji,mj->mi", r, d)
    c = focal
    inv3 = 1.0 / u[:, 2]
    xy = pp - c[:, None] * u[:, :2] * inv3[:, None]
    # d(x, y)/du, (m, 2, 3)
    ju = np.zeros((len(u), 2, 3))
    ju[:, 0, 0] = -c * inv3
    ju[:, 1, 1] = -c * inv3
    ju[:, 0, 2] = c * u[:, 0] * inv3**2
    ju[:, 1, 2] = c * u[:, 1] * inv3**2
    rt = np.swapaxes(r, 1, 2)
    jp = ju @ rt  # d/dX
    je = np.empty((len(u), 2, 6))
    je[:, :, :3] = -jp
    for k, dr in enumerate((dro, drp, drk)):
        du = np.einsum("mji,mj->mi", dr, d)
        je[:, :, 3 + k] = np.einsum("mab,mb->ma", ju, du)
    if distortion is not None:
        xy, dd = distort(xy, pp, c, distortion)
        je, jp = dd @ je, dd @ jp
    return xy, je, jp
