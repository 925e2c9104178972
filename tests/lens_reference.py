"""Reference implementations of the Brown lens terms (the fixed lens models baarda had before
block/camera_models.py), kept as an independent oracle for the tests."""

import numpy as np


def brown_terms(u: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """delta(u) (m, 2) and its Jacobian d delta / d u (m, 2, 2) for coefficients d (m, 5)."""
    x, y = u[:, 0], u[:, 1]
    k1, k2, k3, p1, p2 = (d[:, i] for i in range(5))
    r2 = x * x + y * y
    radial = r2 * (k1 + r2 * (k2 + r2 * k3))
    g = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d radial / d r2
    delta = np.empty_like(u)
    delta[:, 0] = x * radial + p1 * (r2 + 2 * x * x) + 2 * p2 * x * y
    delta[:, 1] = y * radial + 2 * p1 * x * y + p2 * (r2 + 2 * y * y)
    jac = np.empty((len(u), 2, 2))
    cross = 2 * g * x * y + 2 * p1 * y + 2 * p2 * x
    jac[:, 0, 0] = radial + 2 * g * x * x + 6 * p1 * x + 2 * p2 * y
    jac[:, 0, 1] = cross
    jac[:, 1, 0] = cross
    jac[:, 1, 1] = radial + 2 * g * y * y + 2 * p1 * x + 6 * p2 * y
    return delta, jac


def distort(xy_ideal: np.ndarray, pp: np.ndarray, focal: np.ndarray,
            d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward model: projected coordinates (m, 2) and d projected / d ideal (m, 2, 2)."""
    n = (xy_ideal - pp) / focal[:, None]
    delta, jac = brown_terms(n, d)
    jac[:, 0, 0] += 1.0
    jac[:, 1, 1] += 1.0
    return pp + focal[:, None] * (n + delta), jac
