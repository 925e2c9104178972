"""Rotation matrices of the omega-phi-kappa convention, vectorised.

Convention (used everywhere in baarda, documented in docs/format.md):

    R(omega, phi, kappa) = R_x(omega) @ R_y(phi) @ R_z(kappa)

rotates vectors from the image (camera) frame into the object (ground) frame.  The
camera frame has x along the image x axis, y along the image y axis and z towards the
projection centre from the image plane (the image plane lies at z = -c).  A photo with
omega = phi = kappa = 0 looks straight down with its x axis along object X.  Object
coordinates of a point relative to the projection centre map into the camera frame by
R^T:  u = R^T (X - X0).
"""

from __future__ import annotations

import numpy as np

ANGLE_FACTORS = {"rad": 1.0, "deg": np.pi / 180.0, "gon": np.pi / 200.0}


def angle_to_rad(values: np.ndarray, unit: str) -> np.ndarray:
    """Convert angles from `unit` (rad, deg or gon) to radians."""
    return np.asarray(values, dtype=float) * ANGLE_FACTORS[unit]


def rad_to_angle(values: np.ndarray, unit: str) -> np.ndarray:
    """Convert angles in radians to `unit` (rad, deg or gon)."""
    return np.asarray(values, dtype=float) / ANGLE_FACTORS[unit]


def _axes(omega, phi, kappa):
    so, co = np.sin(omega), np.cos(omega)
    sp, cp = np.sin(phi), np.cos(phi)
    sk, ck = np.sin(kappa), np.cos(kappa)
    n = np.broadcast(omega, phi, kappa).shape
    one, zero = np.ones(n), np.zeros(n)
    rx = np.stack([np.stack([one, zero, zero], -1),
                   np.stack([zero, co, -so], -1),
                   np.stack([zero, so, co], -1)], -2)
    ry = np.stack([np.stack([cp, zero, sp], -1),
                   np.stack([zero, one, zero], -1),
                   np.stack([-sp, zero, cp], -1)], -2)
    rz = np.stack([np.stack([ck, -sk, zero], -1),
                   np.stack([sk, ck, zero], -1),
                   np.stack([zero, zero, one], -1)], -2)
    drx = np.stack([np.stack([zero, zero, zero], -1),
                    np.stack([zero, -so, -co], -1),
                    np.stack([zero, co, -so], -1)], -2)
    dry = np.stack([np.stack([-sp, zero, cp], -1),
                    np.stack([zero, zero, zero], -1),
                    np.stack([-cp, zero, -sp], -1)], -2)
    drz = np.stack([np.stack([-sk, -ck, zero], -1),
                    np.stack([ck, -sk, zero], -1),
                    np.stack([zero, zero, zero], -1)], -2)
    return rx, ry, rz, drx, dry, drz


def rotation_matrix(omega, phi, kappa) -> np.ndarray:
    """R = R_x(omega) R_y(phi) R_z(kappa), image to object; angles in radians; shape (..., 3, 3)."""
    rx, ry, rz, *_ = _axes(np.asarray(omega, float), np.asarray(phi, float),
                           np.asarray(kappa, float))
    return rx @ ry @ rz


def rotation_and_derivatives(omega, phi, kappa):
    """R and its partial derivatives dR/domega, dR/dphi, dR/dkappa, each (..., 3, 3)."""
    rx, ry, rz, drx, dry, drz = _axes(np.asarray(omega, float), np.asarray(phi, float),
                                      np.asarray(kappa, float))
    r = rx @ ry @ rz
    return r, drx @ ry @ rz, rx @ dry @ rz, rx @ ry @ drz


def angles_from_matrix(r: np.ndarray) -> np.ndarray:
    """Inverse of rotation_matrix: (..., 3, 3) -> (..., 3) omega, phi, kappa in radians.

    R[0, 2] = sin(phi); R[1, 2] = -sin(omega) cos(phi); R[2, 2] = cos(omega) cos(phi);
    R[0, 1] = -cos(phi) sin(kappa); R[0, 0] = cos(phi) cos(kappa).
    """
    r = np.asarray(r, float)
    phi = np.arcsin(np.clip(r[..., 0, 2], -1.0, 1.0))
    omega = np.arctan2(-r[..., 1, 2], r[..., 2, 2])
    kappa = np.arctan2(-r[..., 0, 1], r[..., 0, 0])
    return np.stack([omega, phi, kappa], -1)


def quaternion_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4) w x y z (not normalised
    here)."""
    q = np.asarray(q, float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)],
        axis=-2)


# ------------------------------------------------------------------ rotation vectors
MAX_ANGLE = 1e6  # rad: the largest angle |r| of a rotation vector read (files hold up to ~2 pi)


def rodrigues(r: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation (angle-axis) vectors r (..., 3), angle |r|."""
    r = np.asarray(r, float)
    theta = np.linalg.norm(r, axis=-1)[..., None, None]
    k = np.zeros(r.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -r[..., 2], r[..., 1], -r[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = r[..., 2], -r[..., 1], r[..., 0]
    small = theta < 1e-8
    t = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta**2 / 6, np.sin(t) / t)
    b = np.where(small, 0.5 - theta**2 / 24, (1 - np.cos(t)) / t**2)
    return np.eye(3) + a * k + b * (k @ k)


def rotation_vector(m: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) of rotation matrices (..., 3, 3): the inverse of `rodrigues`
    (angle in [0, pi]; robust near 0 and pi)."""
    m = np.asarray(m, float)
    shape = m.shape[:-2]
    m = m.reshape(-1, 3, 3)
    w = np.stack([m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]], -1)
    theta = np.arctan2(np.linalg.norm(w, axis=-1) / 2, (np.trace(m, axis1=1, axis2=2) - 1) / 2)
    small = theta < 1e-6
    s = np.where(small, 1.0, 2 * np.sin(theta))
    out = np.where(small, 0.5, theta / s)[:, None] * w
    for i in np.flatnonzero(np.pi - theta < 1e-4):  # near pi: the axis from the symmetric
        c = np.cos(theta[i])                           # part, cos I + (1 - cos) a a^T
        b = ((m[i] + m[i].T) / 2 - c * np.eye(3)) / (1 - c)
        axis = b[int(np.argmax(np.diag(b)))]
        axis = axis / np.linalg.norm(axis)
        out[i] = (-axis if w[i] @ axis < 0 else axis) * theta[i]
    return out.reshape(shape + (3,))


def not_a_rotation(r: np.ndarray, tolerance: float) -> str | None:
    """None when the matrix `r` (3, 3) is a rotation: orthonormal (|R R^T - I| <= tolerance,
    elementwise) with determinant +1; else why not, for a reader's message: "not a rotation
    (|R R^T - I| = .., det ..; expected an orthonormal matrix with determinant +1)"."""
    r = np.asarray(r, float)
    err = float(np.abs(r @ r.T - np.eye(3)).max())
    det = float(np.linalg.det(r))
    if err <= tolerance and det > 0:
        return None
    return (f"not a rotation (|R R^T - I| = {err:.3g}, det {det:.3g}; expected an "
            "orthonormal matrix with determinant +1)")


# ------------------------------------------------------------------ camera poses
FLIP = np.diag([1.0, -1.0, -1.0])  # camera frame x right, y down, z forward <-> baarda's


def eo_of_pose(r: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Exterior orientations (..., 6) X0, Y0, Z0, omega, phi, kappa (rad) of world-to-camera
    poses x_cam = r X + t (r (..., 3, 3), t (..., 3)) in the camera frame of COLMAP and
    OpenSfM (x right, y down, z forward): R_b = r^T FLIP, X0 = -r^T t."""
    rt = np.swapaxes(np.asarray(r, float), -1, -2)
    x0 = -(rt @ np.asarray(t, float)[..., None])[..., 0]
    return np.concatenate([x0, angles_from_matrix(rt @ FLIP)], -1)


def pose_of_eo(eo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The inverse of `eo_of_pose`: (r (..., 3, 3), t (..., 3)) of EO (..., 6)."""
    eo = np.asarray(eo, float)
    r = FLIP @ np.swapaxes(rotation_matrix(eo[..., 3], eo[..., 4], eo[..., 5]), -1, -2)
    return r, -(r @ eo[..., :3, None])[..., 0]


def similarity(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """The 7-parameter similarity (scale s, rotation R, translation t) with
    s R src + t closest to dst in least squares (Umeyama 1991; 3 or more points not on a
    line).  src, dst (n, 3)."""
    ms, md = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - ms, dst - md
    u, d, vt = np.linalg.svd(b.T @ a / len(src))
    sign = np.ones(3)
    sign[2] = np.sign(np.linalg.det(u @ vt)) or 1.0
    r = u @ np.diag(sign) @ vt
    s = float(np.sum(d * sign) / (np.sum(a**2) / len(src)))
    return s, r, md - s * r @ ms
