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
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from baarda.linalg._jit import kernel


@intrinsic
def _fma(typingctx, x, y, z):
    """x * y + z rounded once (LLVM's fma): the 2 x 2 products of NumPy's matmul, which
    OpenBLAS computes as fma(a1, b1, a0 * b0), so the linearisation keeps their numbers."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        dbl = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [dbl],
                                              ir.FunctionType(dbl, [dbl, dbl, dbl]))
        return builder.call(fn, args)

    return sig, codegen


def _camera_vector_of(rot, x0, xyz, p, m):
    """d = X_m - X0_p and u = R_p^T d (the point in photo p's camera frame) [m]."""
    d0 = xyz[m, 0] - x0[p, 0]
    d1 = xyz[m, 1] - x0[p, 1]
    d2 = xyz[m, 2] - x0[p, 2]
    u0 = rot[p, 0, 0] * d0 + rot[p, 1, 0] * d1 + rot[p, 2, 0] * d2
    u1 = rot[p, 0, 1] * d0 + rot[p, 1, 1] * d1 + rot[p, 2, 1] * d2
    u2 = rot[p, 0, 2] * d0 + rot[p, 1, 2] * d1 + rot[p, 2, 2] * d2
    return d0, d1, d2, u0, u1, u2


_camera_vector = kernel(_camera_vector_of, inline="always")


def _project_rows(rot: np.ndarray, drot: np.ndarray, x0: np.ndarray, photo: np.ndarray,
                 xyz: np.ndarray, focal: np.ndarray, pp: np.ndarray, xy: np.ndarray,
                 je: np.ndarray, jp: np.ndarray) -> None:
    """Fill xy (m, 2), je (m, 2, 6) and jp (m, 2, 3) of observations m of points xyz (m, 3)
    on photos photo (m,) with rotations rot (n, 3, 3), their derivatives drot (n, 3, 3, 3)
    by omega, phi, kappa, projection centres x0 (n, 3), focal (m,) and pp (m, 2) [mm]."""
    for m in range(len(photo)):
        p = photo[m]
        d0, d1, d2, u0, u1, u2 = _camera_vector(rot, x0, xyz, p, m)
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


def _brown_forward_rows(rot: np.ndarray, drot: np.ndarray, x0: np.ndarray, photo: np.ndarray,
                        xyz: np.ndarray, rows: np.ndarray, table: np.ndarray,
                        which: np.ndarray, columns: np.ndarray, f: np.ndarray, je: np.ndarray,
                        jp: np.ndarray, jpar: np.ndarray) -> None:
    """The observation equations of cameras of the `brown_forward` model (BAL, COLMAP,
    OpenSfM), projection, lens and chain rule in one pass per row: what
    collinearity.camera_projection computes with the model's array code, in the same
    order (the 2 x 2 products as NumPy's matmul rounds them, `_fma`).  For rows[i] (of
    f, je, jp, jpar, photo, xyz): the camera's parameters table[which[i]] = c, x0, y0,
    k1, k2, k3, p1, p2, a; f (m, 2), je (m, 2, 6 + k), jp (m, 2, 3), jpar (m, 2, >= 9)
    or (0, 2, w) when not wanted; the derivative by parameter j also goes to
    je[:, :, columns[which[i], j]] where that is >= 0 (a camera in its photo's block)."""
    for i in range(len(rows)):
        m = rows[i]
        p = photo[m]
        q = which[i]
        c, pp0, pp1 = table[q, 0], table[q, 1], table[q, 2]
        k1, k2, k3, p1, p2, asp = (table[q, 3], table[q, 4], table[q, 5], table[q, 6],
                                   table[q, 7], table[q, 8])
        d0, d1, d2, u0, u1, u2 = _camera_vector(rot, x0, xyz, p, m)
        inv3 = 1.0 / u2
        xy0 = pp0 - c * u0 * inv3
        xy1 = pp1 - c * u1 * inv3
        a = -c * inv3
        b0 = c * u0 * inv3**2
        b1 = c * u1 * inv3**2
        # Brown's terms on n = (projection - pp) / c (lens_kernels.brown_rows)
        i0 = xy0 - pp0
        i1 = xy1 - pp1
        x = i0 / c
        y = i1 / c
        r2 = x * x + y * y
        radial = r2 * (k1 + r2 * (k2 + r2 * k3))
        g = k1 + r2 * (2 * k2 + 3 * k3 * r2)
        tx0, tx1 = r2 + 2 * x * x, 2 * x * y
        ty0, ty1 = 2 * x * y, r2 + 2 * y * y
        bd0 = x * radial + p1 * tx0 + p2 * ty0
        bd1 = y * radial + p1 * tx1 + p2 * ty1
        cross = 2 * g * x * y + 2 * p1 * y + 2 * p2 * x
        bj00 = radial + 2 * g * x * x + 6 * p1 * x + 2 * p2 * y
        bj11 = radial + 2 * g * y * y + 2 * p1 * x + 6 * p2 * y
        # the aspect a (camera_models._brown_forward)
        s = 1 + asp
        delta0 = bd0
        delta1 = s * bd1 + asp * y
        dd00 = 1.0 + bj00
        dd01 = 0.0 + cross
        dd10 = 0.0 + cross * s
        dd11 = 1.0 + (bj11 * s + asp)
        f[m, 0] = pp0 + i0 + c * delta0
        f[m, 1] = pp1 + i1 + c * delta1
        for k in range(3):  # d/dX, then d/dX0 = -d/dX, through I + d delta / dn
            e0 = a * rot[p, k, 0] + b0 * rot[p, k, 2]
            e1 = a * rot[p, k, 1] + b1 * rot[p, k, 2]
            jp[m, 0, k] = _fma(dd01, e1, dd00 * e0)  # type: ignore[call-arg]  # numba @intrinsic
            jp[m, 1, k] = _fma(dd11, e1, dd10 * e0)
            je[m, 0, k] = _fma(dd01, -e1, dd00 * -e0)
            je[m, 1, k] = _fma(dd11, -e1, dd10 * -e0)
        for k in range(3):  # d/d(omega, phi, kappa)
            v0 = drot[p, k, 0, 0] * d0 + drot[p, k, 1, 0] * d1 + drot[p, k, 2, 0] * d2
            v1 = drot[p, k, 0, 1] * d0 + drot[p, k, 1, 1] * d1 + drot[p, k, 2, 1] * d2
            v2 = drot[p, k, 0, 2] * d0 + drot[p, k, 1, 2] * d1 + drot[p, k, 2, 2] * d2
            e0 = a * v0 + b0 * v2
            e1 = a * v1 + b1 * v2
            je[m, 0, 3 + k] = _fma(dd01, e1, dd00 * e0)  # type: ignore[call-arg]
            je[m, 1, 3 + k] = _fma(dd11, e1, dd10 * e0)
        # d f / d(c, x0, y0, k1, k2, k3, p1, p2, a)
        r4 = r2 * r2
        r6 = r4 * r2
        dx = (i0 / c + delta0, 1.0, 0.0, c * (x * r2), c * (x * r4), c * (x * r6), c * tx0,
              c * ty0, c * 0.0)
        dy = (i1 / c + delta1, 0.0, 1.0, c * ((y * r2) * s), c * ((y * r4) * s),
              c * ((y * r6) * s), c * (tx1 * s), c * (ty1 * s), c * (y + bd1))
        if jpar.shape[0]:
            for j in range(9):
                jpar[m, 0, j] = dx[j]
                jpar[m, 1, j] = dy[j]
        for j in range(9):
            col = columns[q, j]
            if col >= 0:
                je[m, 0, col] = dx[j]
                je[m, 1, col] = dy[j]


brown_forward_rows = kernel(_brown_forward_rows, error_model="numpy")


@kernel
def take_columns(src: np.ndarray, rows: np.ndarray, cols: np.ndarray, dst: np.ndarray,
                 first: int) -> None:
    """dst[r, :, first + s] = src[r, :, cols[s]] for the rows r (a camera's free parameters
    among the columns of its photo's block)."""
    for i in range(len(rows)):
        r = rows[i]
        for a in range(src.shape[1]):
            for s in range(len(cols)):
                dst[r, a, first + s] = src[r, a, cols[s]]


@kernel
def all_in_front(rot: np.ndarray, x0: np.ndarray, photo: np.ndarray, point: np.ndarray,
                 xyz: np.ndarray) -> bool:
    """Whether every observed point xyz[point[i]] lies in front of its photo photo[i]
    (rotations rot (n, 3, 3), projection centres x0 (n, 3)): -u3 > 0
    (collinearity.camera_depth), checked row by row up to the first point behind."""
    for i in range(len(photo)):
        p = photo[i]
        j = point[i]
        depth = -(rot[p, 0, 2] * (xyz[j, 0] - x0[p, 0]) + rot[p, 1, 2] * (xyz[j, 1] - x0[p, 1])
                  + rot[p, 2, 2] * (xyz[j, 2] - x0[p, 2]))
        if not depth > 0.0:
            return False
    return True
