"""The collinearity equations and their Jacobians, one observation at a time (numba).

The same arithmetic, in the same order, as the array expressions this kernel replaced
(collinearity.py documents the equations): u = R^T (X - X0), x = x0 - c u1 / u3,
y = y0 - c u2 / u3, and the Jacobians d(x, y)/d(X0, Y0, Z0, omega, phi, kappa) and
d(x, y)/d(X, Y, Z).  The rotations and their derivatives come once per photo; each
observation is independent (a loop on one thread: the rows of one camera are too few
to pay for starting numba's threads).
"""

from __future__ import annotations

import numpy as np

from baarda.linalg._jit import kernel


def _project_rows(rot: np.ndarray, drot: np.ndarray, x0: np.ndarray, photo: np.ndarray,
                 xyz: np.ndarray, focal: np.ndarray, pp: np.ndarray, xy: np.ndarray,
                 je: np.ndarray, jp: np.ndarray) -> None:
    """Fill xy (m, 2), je (m, 2, 6) and jp (m, 2, 3) of observations m of points xyz (m, 3)
    on photos photo (m,) with rotations rot (n, 3, 3), their derivatives drot (n, 3, 3, 3)
    by omega, phi, kappa, projection centres x0 (n, 3), focal (m,) and pp (m, 2) [mm]."""
    for m in range(len(photo)):
        p = photo[m]
        d0 = xyz[m, 0] - x0[p, 0]
        d1 = xyz[m, 1] - x0[p, 1]
        d2 = xyz[m, 2] - x0[p, 2]
        u0 = rot[p, 0, 0] * d0 + rot[p, 1, 0] * d1 + rot[p, 2, 0] * d2
        u1 = rot[p, 0, 1] * d0 + rot[p, 1, 1] * d1 + rot[p, 2, 1] * d2
        u2 = rot[p, 0, 2] * d0 + rot[p, 1, 2] * d1 + rot[p, 2, 2] * d2
        c = focal[m]
        inv3 = 1.0 / u2
        xy[m, 0] = pp[m, 0] - c * u0 * inv3
        xy[m, 1] = pp[m, 1] - c * u1 * inv3
        # d(x, y)/du: [[a, 0, b0], [0, a, b1]]
        a = -c * inv3
        b0 = c * u0 * inv3**2
        b1 = c * u1 * inv3**2
        for k in range(3):  # d/dX = du/dX (R^T) chained
            jp[m, 0, k] = a * rot[p, k, 0] + b0 * rot[p, k, 2]
            jp[m, 1, k] = a * rot[p, k, 1] + b1 * rot[p, k, 2]
            je[m, 0, k] = -jp[m, 0, k]
            je[m, 1, k] = -jp[m, 1, k]
        for k in range(3):  # d/d(omega, phi, kappa)
            v0 = drot[p, k, 0, 0] * d0 + drot[p, k, 1, 0] * d1 + drot[p, k, 2, 0] * d2
            v1 = drot[p, k, 0, 1] * d0 + drot[p, k, 1, 1] * d1 + drot[p, k, 2, 1] * d2
            v2 = drot[p, k, 0, 2] * d0 + drot[p, k, 1, 2] * d1 + drot[p, k, 2, 2] * d2
            je[m, 0, 3 + k] = a * v0 + b0 * v2
            je[m, 1, 3 + k] = a * v1 + b1 * v2


# numpy's error model: a point in the projection plane (u3 = 0) gives inf, as the array
# expressions did, for the caller's checks, not ZeroDivisionError
project_rows = kernel(_project_rows, error_model="numpy")
