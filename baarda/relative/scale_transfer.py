"""Scale transfer: the collinearity condition in the XZ plane at tie points (Kratky eq. 1).

The right projection centre of a new model is O'' = O' + b_x (1, beta_y, beta_z) with
b_x = beta_x * b_ref (b_ref: the base of the preceding model, beta_x ~ 1 dimensionless).
A tie point whose strip coordinates (X, Y, Z) were fixed by the preceding model constrains
the right ray x'' = R'' u'' in the XZ plane:

    F_L = dX z'' - dZ x'' = 0,     dX = X - O''_X,  dZ = Z - O''_Z

The observation is x'' (mm): a_L = dF_L/dx'' (Kratky: a_L = -dZ without rotation).
"""

from __future__ import annotations

import numpy as np

from baarda.relative.coplanarity import E_X, ConditionLinearisation


def collinearity_xz(beta: np.ndarray, base_ref: float, left_centre: np.ndarray,
                    tie_xyz: np.ndarray, u_right: np.ndarray, rotation,
                    rotation_partials) -> ConditionLinearisation:
    """F_L and analytic partials for tie points tie_xyz (m, 3) with image vectors u_right (m, 3).

    beta = (beta_x, beta_y, beta_z); partials in the order (beta_x, beta_y, beta_z, kappa,
    phi, omega).
    """
    bx = beta[0] * base_ref
    centre = left_centre + bx * np.array([1.0, beta[1], beta[2]])
    dxz = tie_xyz - centre
    ddx, ddz = dxz[:, 0], dxz[:, 2]
    x2 = u_right @ rotation.T
    rx = rotation @ E_X
    m = len(tie_xyz)
    df = np.zeros((m, 6))
    da = np.zeros((m, 6))
    # d(dX)/dbeta_x = -b_ref, d(dZ)/dbeta_x = -b_ref beta_z, d(dZ)/dbeta_z = -b_x
    df[:, 0] = -base_ref * x2[:, 2] + base_ref * beta[2] * x2[:, 0]
    df[:, 2] = bx * x2[:, 0]
    da[:, 0] = -base_ref * rx[2] + base_ref * beta[2] * rx[0]
    da[:, 2] = bx * rx[0]
    for k, dr in enumerate(rotation_partials):
        dx2 = u_right @ dr.T
        df[:, 3 + k] = ddx * dx2[:, 2] - ddz * dx2[:, 0]
        drx = dr @ E_X
        da[:, 3 + k] = ddx * drx[2] - ddz * drx[0]
    f = ddx * x2[:, 2] - ddz * x2[:, 0]
    return ConditionLinearisation(f, df, ddx * rx[2] - ddz * rx[0], da)
