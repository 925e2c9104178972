"""The coplanarity condition of relative orientation (Kratky and El-Hakim 1983, eq. 1).

    F_p = b . (x' x x'') = (b x x') . (R'' u'')

with the base b = (1, beta_y, beta_z) normalised by its x component, x' the left ray (fixed:
R' u'), x'' = R'' u'' the right ray, u = (x, y, -c) the image vector in mm and R the
omega-phi-kappa rotation of baarda.block.rotation (camera -> strip frame).  F_p is linear in
the right image coordinates, so the y'' correction that makes the rays coplanar is exactly
-F_p / a_p with a_p = dF_p/dy'' (Kratky: a_p = -z' for a photo without rotation).

Parameter order everywhere in this package: (beta_x, beta_y, beta_z, kappa, phi, omega);
beta_x is the scale of the base (used by the scale transfer only, dF_p/dbeta_x = 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.block.rotation import rotation_and_derivatives

E_X = np.array([1.0, 0.0, 0.0])
E_Y = np.array([0.0, 1.0, 0.0])
E_Z = np.array([0.0, 0.0, 1.0])


def image_vectors(xy: np.ndarray, c: float) -> np.ndarray:
    """u = (x, y, -c) for image coordinates xy (n, 2) in mm; returns (n, 3)."""
    xy = np.asarray(xy, float)
    return np.column_stack([xy[:, 0], xy[:, 1], np.full(len(xy), -float(c))])


def right_rotation(angles: np.ndarray):
    """R'' and (dR/dkappa, dR/dphi, dR/domega) for angles (kappa, phi, omega) in rad."""
    kappa, phi, omega = angles
    r, d_om, d_ph, d_ka = rotation_and_derivatives(omega, phi, kappa)
    return r, (d_ka, d_ph, d_om)


@dataclass
class ConditionLinearisation:
    """A condition F (n,) with its partials: dF/dg (n, 6), a = dF/dl (n,), da/dg (n, 6)."""

    f: np.ndarray
    df_dg: np.ndarray
    a: np.ndarray
    da_dg: np.ndarray


def coplanarity(beta: np.ndarray, x_left: np.ndarray, u_right: np.ndarray,
                rotation, rotation_partials) -> ConditionLinearisation:
    """F_p and analytic partials for the rays x_left (n, 3) and image vectors u_right (n, 3).

    beta = (beta_x, beta_y, beta_z); rotation R'' (3, 3) with partials (kappa, phi, omega).
    The observation is y'' (mm): a = dF_p/dy''.
    """
    b = np.array([1.0, beta[1], beta[2]])
    m = np.cross(b, x_left)  # (n, 3)
    x2 = u_right @ rotation.T
    ry = rotation @ E_Y
    n = len(x_left)
    df = np.zeros((n, 6))
    da = np.zeros((n, 6))
    my = np.cross(E_Y, x_left)
    mz = np.cross(E_Z, x_left)
    df[:, 1] = np.einsum("ij,ij->i", my, x2)
    df[:, 2] = np.einsum("ij,ij->i", mz, x2)
    da[:, 1] = my @ ry
    da[:, 2] = mz @ ry
    for k, dr in enumerate(rotation_partials):
        df[:, 3 + k] = np.einsum("ij,ij->i", m, u_right @ dr.T)
        da[:, 3 + k] = m @ (dr @ E_Y)
    return ConditionLinearisation(np.einsum("ij,ij->i", m, x2), df, m @ ry, da)


