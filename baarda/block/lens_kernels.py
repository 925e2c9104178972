"""Brown's distortion terms row by row (numba): the building block of the Brown, DBAT and
OpenCV-style camera models (camera_models.py), with the same expressions in the same order
as the array code they replace, so every number is the same to the last bit.

Imported by camera_models when a model is first evaluated, not with the data model: reading
a project does not pay for numba.
"""

from __future__ import annotations

import numpy as np

from baarda.linalg._jit import kernel


def _brown_rows(u: np.ndarray, c: np.ndarray, delta: np.ndarray, jac: np.ndarray,
                dc: np.ndarray) -> None:
    """delta (m, 2), d delta / du (m, 2, 2), d delta / dc (m, 2, 5) of Brown's terms at
    u (m, 2) with c = (k1, k2, k3, p1, p2) (m, 5)."""
    for i in range(u.shape[0]):
        x, y = u[i, 0], u[i, 1]
        k1, k2, k3, p1, p2 = c[i, 0], c[i, 1], c[i, 2], c[i, 3], c[i, 4]
        r2 = x * x + y * y
        radial = r2 * (k1 + r2 * (k2 + r2 * k3))
        g = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d radial / d r2
        tx0, tx1 = r2 + 2 * x * x, 2 * x * y  # d delta / d p1
        ty0, ty1 = 2 * x * y, r2 + 2 * y * y  # d delta / d p2
        delta[i, 0] = x * radial + p1 * tx0 + p2 * ty0
        delta[i, 1] = y * radial + p1 * tx1 + p2 * ty1
        cross = 2 * g * x * y + 2 * p1 * y + 2 * p2 * x
        jac[i, 0, 0] = radial + 2 * g * x * x + 6 * p1 * x + 2 * p2 * y
        jac[i, 0, 1] = cross
        jac[i, 1, 0] = cross
        jac[i, 1, 1] = radial + 2 * g * y * y + 2 * p1 * x + 6 * p2 * y
        r4 = r2 * r2
        r6 = r4 * r2
        dc[i, 0, 0], dc[i, 1, 0] = x * r2, y * r2
        dc[i, 0, 1], dc[i, 1, 1] = x * r4, y * r4
        dc[i, 0, 2], dc[i, 1, 2] = x * r6, y * r6
        dc[i, 0, 3], dc[i, 1, 3] = tx0, tx1
        dc[i, 0, 4], dc[i, 1, 4] = ty0, ty1


# numpy's error model: overflow and division give inf and NaN as the array code did
brown_rows = kernel(_brown_rows, error_model="numpy")
