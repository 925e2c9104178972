"""Additional-parameter sets linear in their coefficients, for camera_models.py: Ebner's 12
orthogonal parameters on a 3x3 grid, and 44 fields orthonormal over a 5x5 grid that span the
space of Gruen's 44 parameters (a documented construction, not Gruen's numbering;
docs/camera_models.md).  Each field is a correction (x, y) [mm] at a reduced image
coordinate u [mm]; a model's correction is the sum of its fields times the coefficients.
"""

from __future__ import annotations

from functools import cache

import numpy as np

Terms = tuple[np.ndarray, np.ndarray, np.ndarray]


def _linear(f: np.ndarray, df: np.ndarray, coef: np.ndarray) -> Terms:
    """A model linear in its coefficients: fields f (m, 2, k), their derivatives
    df (m, 2, 2, k) [component, d/dx or d/dy, field]."""
    return (np.einsum("mck,mk->mc", f, coef), np.einsum("mcdk,mk->mcd", df, coef), f)



def ebner_fields(u: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ebner's 12 fields (m, 2, 12) and their derivatives (m, 2, 2, 12) at u (m, 2) [mm],
    grid spacing b (m,) [mm]."""
    x, y = u[:, 0], u[:, 1]
    q = 2 * b * b / 3
    xq, yq = x * x - q, y * y - q
    m = len(u)
    f = np.zeros((m, 2, 12))
    df = np.zeros((m, 2, 2, 12))
    one = np.ones(m)
    # (field index, component, value, d/dx, d/dy)
    entries = [
        (0, 0, x, one, 0), (0, 1, -y, 0, -one),
        (1, 0, y, 0, one), (1, 1, x, one, 0),
        (2, 0, -2 * xq, -4 * x, 0), (2, 1, x * y, y, x),
        (3, 0, x * y, y, x), (3, 1, -2 * yq, 0, -4 * y),
        (4, 0, yq, 0, 2 * y),
        (5, 1, xq, 2 * x, 0),
        (6, 0, x * yq, yq, 2 * x * y),
        (7, 1, y * xq, 2 * x * y, xq),
        (8, 0, y * xq, 2 * x * y, xq),
        (9, 1, x * yq, yq, 2 * x * y),
        (10, 0, xq * yq, 2 * x * yq, 2 * y * xq),
        (11, 1, xq * yq, 2 * x * yq, 2 * y * xq),
    ]
    for k, c, val, ddx, ddy in entries:
        f[:, c, k] = val
        df[:, c, 0, k] = ddx
        df[:, c, 1, k] = ddy
    return f, df


def ebner_terms(u: np.ndarray, coef: np.ndarray, const: np.ndarray) -> Terms:
    """The model 'ebner': Ebner's fields with the grid spacing b = const[:, 0]."""
    return _linear(*ebner_fields(u, const[:, 0]), coef)


# ------------------------------------------------------------------ Gruen's 44 (a construction)
GRID5 = np.array([(i, j) for j in range(-2, 3) for i in range(-2, 3)], dtype=float)


def exterior_fields(u: np.ndarray) -> np.ndarray:
    """The 6 fields (m, 2, 6) that the exterior orientation absorbs: translations x, y,
    rotation (-y, x), scale (x, y), projective tilts (x^2, xy), (xy, y^2)."""
    x, y = u[:, 0], u[:, 1]
    one, zero = np.ones(len(u)), np.zeros(len(u))
    return np.stack([np.stack(p, axis=1) for p in
                     ((one, zero), (zero, one), (-y, x), (x, y), (x * x, x * y),
                      (x * y, y * y))], axis=2)


def _monomials(s: np.ndarray) -> np.ndarray:
    """x^i y^j (m, 5, 5) of s (m, 2), 0 <= i, j <= 4."""
    p = s[:, :, None] ** np.arange(5)
    return p[:, 0, :, None] * p[:, 1, None, :]


@cache
def gruen_coefficients() -> np.ndarray:
    """Polynomial coefficients (44, 2, 5, 5) of the 44 fields in s = u / b:
    field k = (sum_ij A[k,0,i,j] s_x^i s_y^j, sum_ij A[k,1,i,j] s_x^i s_y^j).

    Gram-Schmidt over the 25 points of the grid {-2..2}^2 (inner product: the sum over the
    points of the dot product of the two vectors), starting from the 6 exterior-orientation
    fields (dropped afterwards), then Ebner's 12 fields in Ebner's order (spacing 1), then
    the fields (x^i y^j, 0) and (0, x^i y^j) in the order (i + j, j), x before y, each
    skipped when it adds nothing.  Each field is scaled to an RMS of 1 over the grid (a
    coefficient of 1 um moves the grid points by 1 um RMS).
    """
    seeds = []  # (2, 5, 5) coefficient arrays

    def mono(terms):
        a = np.zeros((2, 5, 5))
        for c, i, j, v in terms:
            a[c, i, j] += v
        return a

    q = 2.0 / 3.0
    seeds += [mono([(0, 0, 0, 1)]), mono([(1, 0, 0, 1)]), mono([(0, 0, 1, -1), (1, 1, 0, 1)]),
              mono([(0, 1, 0, 1), (1, 0, 1, 1)]), mono([(0, 2, 0, 1), (1, 1, 1, 1)]),
              mono([(0, 1, 1, 1), (1, 0, 2, 1)])]
    seeds += [
        mono([(0, 1, 0, 1), (1, 0, 1, -1)]),
        mono([(0, 0, 1, 1), (1, 1, 0, 1)]),
        mono([(0, 2, 0, -2), (0, 0, 0, 2 * q), (1, 1, 1, 1)]),
        mono([(0, 1, 1, 1), (1, 0, 2, -2), (1, 0, 0, 2 * q)]),
        mono([(0, 0, 2, 1), (0, 0, 0, -q)]),
        mono([(1, 2, 0, 1), (1, 0, 0, -q)]),
        mono([(0, 1, 2, 1), (0, 1, 0, -q)]),
        mono([(1, 2, 1, 1), (1, 0, 1, -q)]),
        mono([(0, 2, 1, 1), (0, 0, 1, -q)]),
        mono([(1, 1, 2, 1), (1, 1, 0, -q)]),
        mono([(0, 2, 2, 1), (0, 2, 0, -q), (0, 0, 2, -q), (0, 0, 0, q * q)]),
        mono([(1, 2, 2, 1), (1, 2, 0, -q), (1, 0, 2, -q), (1, 0, 0, q * q)]),
    ]
    for i, j in sorted(((i, j) for i in range(5) for j in range(5)),
                       key=lambda ij: (ij[0] + ij[1], ij[1])):
        seeds += [mono([(0, i, j, 1)]), mono([(1, i, j, 1)])]
    mon = _monomials(GRID5)  # (25, 5, 5)

    def values(a):
        return np.einsum("pij,cij->pc", mon, a).ravel()

    basis_v: list[np.ndarray] = []
    basis_a: list[np.ndarray] = []
    for a in seeds:
        v = values(a)
        norm0 = np.linalg.norm(v)
        for _ in range(2):  # Gram-Schmidt twice, for orthogonality to rounding
            for bv, ba in zip(basis_v, basis_a, strict=True):
                t = bv @ v / (bv @ bv)
                v = v - t * bv
                a = a - t * ba
        if np.linalg.norm(v) > 1e-9 * norm0:
            scale = np.sqrt(len(GRID5)) / np.linalg.norm(v)
            basis_v.append(v * scale)
            basis_a.append(a * scale)
    out = np.array(basis_a[6:])
    assert out.shape == (44, 2, 5, 5), out.shape
    return out


def gruen_fields(u: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The 44 fields (m, 2, 44) at u (m, 2) [mm] for grid spacing b (m,) [mm]."""
    return np.einsum("kcij,mij->mck", gruen_coefficients(), _monomials(u / b[:, None]))


def gruen_terms(u: np.ndarray, coef: np.ndarray, const: np.ndarray) -> Terms:
    """The model 'gruen': the 44 fields with the grid spacing b = const[:, 0]."""
    b = const[:, 0]
    s = u / b[:, None]
    a = gruen_coefficients()
    p = s[:, :, None] ** np.arange(5)  # (m, 2, 5)
    dp = np.zeros_like(p)
    dp[:, :, 1:] = p[:, :, :-1] * np.arange(1, 5)
    mon = p[:, 0, :, None] * p[:, 1, None, :]
    f = np.einsum("kcij,mij->mck", a, mon)
    per_row = np.einsum("kcij,mk->mcij", a, coef)  # the polynomial of each row
    delta = np.einsum("mcij,mij->mc", per_row, mon)
    jac = np.empty((len(u), 2, 2))
    jac[:, :, 0] = np.einsum("mcij,mi,mj->mc", per_row, dp[:, 0], p[:, 1]) / b[:, None]
    jac[:, :, 1] = np.einsum("mcij,mi,mj->mc", per_row, p[:, 0], dp[:, 1]) / b[:, None]
    return delta, jac, f
