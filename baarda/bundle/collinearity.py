"""Collinearity equations and their analytic Jacobians, vectorised over observations.

    u = R^T (X - X0)                      (camera frame, R from rotation.py)
    x = x0 - c * u1 / u3,   y = y0 - c * u2 / u3      (mm)

Parameters of a photo: X0, Y0, Z0 [m], omega, phi, kappa [rad]; of a point: X, Y, Z [m].
`camera_projection` adds a camera model (block/camera_models.py) and the Jacobians with
respect to the camera's parameters c, x0, y0 and coefficients, by the chain rule.
"""

from __future__ import annotations

import numpy as np

from baarda.block.camera_models import CameraModel
from baarda.block.rotation import rotation_and_derivatives, rotation_matrix


def project(eo: np.ndarray, xyz: np.ndarray, focal: np.ndarray, pp: np.ndarray,
            photo: np.ndarray | None = None) -> np.ndarray:
    """Image coordinates (m, 2) in mm of points xyz (m, 3) on photos eo (m, 6) (no lens
    model); with `photo`, eo holds one row per photo and photo[i] names the photo of
    point i."""
    r = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])
    if photo is not None:
        r, eo = r[photo], eo[photo]
    u = np.einsum("mji,mj->mi", r, xyz - eo[:, :3])
    return pp - focal[:, None] * u[:, :2] / u[:, 2:3]


def camera_depth(eo: np.ndarray, xyz: np.ndarray, photo: np.ndarray | None = None) -> np.ndarray:
    """-u3: distance of each point in front of the camera along its axis (positive = in front).

    With `photo`, eo holds one row per photo and photo[i] names the photo of point i.
    """
    r = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])
    if photo is not None:
        r, eo = r[photo], eo[photo]
    return -np.einsum("mj,mj->m", r[:, :, 2], xyz - eo[:, :3])


def project_with_jacobians(eo: np.ndarray, xyz: np.ndarray, focal: np.ndarray,
                           pp: np.ndarray, photo: np.ndarray | None = None,
                           rotations: tuple | None = None):
    """Image coordinates (m, 2) and Jacobians d(x, y)/d(eo) (m, 2, 6) and d(x, y)/d(X) (m, 2, 3)
    (no lens model).

    With `photo`, eo holds one row per photo (rotations are computed once per photo) and
    photo[i] names the photo of observation i; rotations: rotation_and_derivatives of eo's
    angles when the caller has them already.
    """
    from baarda.bundle.projection_kernel import project_rows

    r, dro, drp, drk = rotations or rotation_and_derivatives(eo[:, 3], eo[:, 4], eo[:, 5])
    m = len(xyz)
    photo = np.arange(m) if photo is None else np.asarray(photo, np.int64)
    xy, je, jp = np.empty((m, 2)), np.empty((m, 2, 6)), np.empty((m, 2, 3))
    project_rows(np.ascontiguousarray(r), np.ascontiguousarray(np.stack([dro, drp, drk], 1)),
                 np.ascontiguousarray(eo[:, :3], dtype=float), photo,
                 np.ascontiguousarray(xyz, dtype=float),
                 np.ascontiguousarray(np.broadcast_to(focal, (m,)), dtype=float),
                 np.ascontiguousarray(np.broadcast_to(pp, (m, 2)), dtype=float), xy, je, jp)
    return xy, je, jp


def camera_projection(eo: np.ndarray, xyz: np.ndarray, photo: np.ndarray,
                      params: np.ndarray, model: CameraModel, const: np.ndarray,
                      observed: np.ndarray, rotations: tuple | None = None):
    """The observation equations of the image points of cameras of one model.

    eo (n_photos, 6); xyz (m, 3) the observed points; photo (m,) the photo of each row;
    params = [c, x0, y0, coefficients...] of the camera (mm; the model's units), or one such
    row per observation; const the model's constants (likewise); observed (m, 2) the
    measured coordinates (mm); rotations: those of eo, when known.  Returns f (m, 2), the
    value the observation is compared with (e = observed - f), and its Jacobians with
    respect to the photo (m, 2, 6), the point (m, 2, 3) and the camera parameters
    (m, 2, 3 + k):

    * forward models: f = pp + s (u + delta(u)), u = (ideal - pp) / s (s = c if normalised,
      else 1), delta evaluated at the projection;
    * backward models: f = ideal - delta(observed - pp): the corrected observation equals
      the projection, with delta evaluated at the observation (DBAT's and the
      photogrammetric programs' formulation; the observation keeps its own weight).
    """
    m = len(photo)
    params = np.asarray(params, float)  # one row per observation (a view of one row for all)
    params = np.broadcast_to(params, (m, params.shape[-1]))
    const = np.asarray(const, float)
    const = np.broadcast_to(const, (m, const.shape[-1]))
    c, pp, coef = params[:, 0], params[:, 1:3], params[:, 3:]
    cr = c[:, None]
    xy, je, jp = project_with_jacobians(eo, xyz, c, pp, photo=photo, rotations=rotations)
    ideal = xy - pp  # reduced to the principal point, mm
    jpar = np.zeros((m, 2, 3 + coef.shape[1]))
    if model.side == "backward":
        delta, ddu, ddc = model.correction(observed - pp, coef, const)
        f = xy - delta
        jpar[:, :, 0] = ideal / cr
        jpar[:, :, 1:3] = np.eye(2) + ddu  # d(-delta(observed - pp)) / d pp = + d delta/du
        jpar[:, :, 3:] = -ddc
        return f, je, jp, jpar
    s = cr if model.normalized else 1.0
    delta, ddu, ddc = model.correction(ideal / s, coef, const)
    f = pp + ideal + s * delta
    dd = np.eye(2) + ddu  # d f / d ideal
    je, jp = dd @ je, dd @ jp
    jpar[:, :, 0] = ideal / cr + delta if model.normalized else np.einsum(
        "mab,mb->ma", dd, ideal / cr)
    jpar[:, :, 1:3] = np.eye(2)
    jpar[:, :, 3:] = (cr[:, :, None] if model.normalized else 1.0) * ddc
    return f, je, jp, jpar
