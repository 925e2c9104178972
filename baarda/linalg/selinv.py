"""Numba kernels: block Takahashi selected inverse on the supernodal Cholesky factor.

Works on the panel storage described in :mod:`baarda.linalg.kernels`: from the root down,
every supernode's blocks of S^-1 on the pattern of L follow from the factor and the blocks of
its ancestors (Takahashi recurrences, in dense panels with BLAS products).
"""

from __future__ import annotations

import numpy as np

from ._jit import kernel
from .kernels import _chunk, _view

__all__ = ["selinv_supernode", "selinv_workspace", "supernodal_selected_inverse"]


@kernel
def _tri_inverse(
    p: np.ndarray,
    w: int,
    x: np.ndarray,
    b: int,
    work1: np.ndarray,
    work2: np.ndarray,
    work3: np.ndarray,
    work4: np.ndarray,
) -> None:
    """``x = inv(p[:w, :w])`` for lower-triangular ``p[:w, :w]`` (blocked, upper part zero)."""
    cw = _chunk(b)
    for i in range(w):
        for j in range(w):
            x[i, j] = 0.0
    nch = (w + cw - 1) // cw
    for kc in range(nch - 1, -1, -1):
        j0 = kc * cw
        j1 = min(w, j0 + cw)
        jb = j1 - j0
        for c in range(j0, j1):
            x[c, c] = 1.0 / p[c, c]
            for r in range(c + 1, j1):
                s = 0.0
                for t in range(c, r):
                    s -= p[r, t] * x[t, c]
                x[r, c] = s / p[r, r]
        if j1 < w:
            nt = w - j1
            xt = work1[: nt * nt].reshape(nt, nt)
            for i in range(nt):
                for j in range(i + 1):
                    xt[i, j] = x[j1 + i, j1 + j]
                for j in range(i + 1, nt):
                    xt[i, j] = 0.0
            lb = work2[: nt * jb].reshape(nt, jb)
            for i in range(nt):
                for j in range(jb):
                    lb[i, j] = p[j1 + i, j0 + j]
            t1 = work3[: nt * jb].reshape(nt, jb)
            np.dot(xt, lb, t1)
            dinv = work4[: jb * jb].reshape(jb, jb)
            for i in range(jb):
                for j in range(jb):
                    dinv[i, j] = x[j0 + i, j0 + j]
            np.dot(t1, dinv, lb)
            for i in range(nt):
                for j in range(jb):
                    x[j1 + i, j0 + j] = -lb[i, j]


@kernel
def selinv_workspace(
    sn_start: np.ndarray, colptr: np.ndarray, b: int, sns: np.ndarray
) -> tuple[np.ndarray, ...]:
    """Work arrays of :func:`selinv_supernode` for the supernodes ``sns``."""
    maxw = 1
    maxm = 1
    for s in sns:
        f = sn_start[s]
        w = (sn_start[s + 1] - f) * b
        maxw = max(maxw, w)
        maxm = max(maxm, (colptr[f + 1] - colptr[f]) * b - w)
    cw = _chunk(b)
    return (
        np.empty(maxw * maxw),
        np.empty(maxm * maxw),
        np.empty(maxm * maxm),
        np.empty(maxw * maxw),
        np.empty(maxw * maxw),
        np.empty(maxw * cw),
        np.empty(maxw * cw),
        np.empty(cw * cw),
    )


@kernel
def selinv_supernode(
    J: int,
    sn_start: np.ndarray,
    col_to_sn: np.ndarray,
    colptr: np.ndarray,
    rowind: np.ndarray,
    sn_off: np.ndarray,
    lbuf: np.ndarray,
    zbuf: np.ndarray,
    b: int,
    ws: tuple[np.ndarray, ...],
) -> None:
    """Z panel of supernode J (see :func:`supernodal_selected_inverse`); reads only the Z panels
    of J's ancestors and the L panel of J, writes only the Z panel of J."""
    linv, ybuf, zrr, tw, work1, work2, work3, work4 = ws
    f = sn_start[J]
    s = sn_start[J + 1] - f
    w = s * b
    p0 = colptr[f]
    nr = colptr[f + 1] - p0
    mr = nr - s
    m = mr * b
    off = sn_off[J]
    pj = _view(lbuf, off, nr * b, w)
    li = _view(linv, 0, w, w)
    _tri_inverse(pj, w, li, b, work1, work2, work3, work4)
    zcc = _view(zbuf, off, w, w)
    if m > 0:
        lr = _view(lbuf, off + w * w, m, w)
        y = _view(ybuf, 0, m, w)
        np.dot(lr, li, y)
    np.dot(li.T, li, zcc)
    if m > 0:
        zr = _view(zrr, 0, m, m)
        for cb in range(mr):
            lcol = rowind[p0 + s + cb]
            j2 = col_to_sn[lcol]
            f2 = sn_start[j2]
            w2 = (sn_start[j2 + 1] - f2) * b
            q2 = colptr[f2]
            c2 = (lcol - f2) * b
            z2 = _view(zbuf, sn_off[j2], (colptr[f2 + 1] - q2) * b, w2)
            a2 = lcol - f2
            for ra in range(cb, mr):
                row = rowind[p0 + s + ra]
                while rowind[q2 + a2] != row:
                    a2 += 1
                for r in range(b):
                    for c in range(b):
                        v = z2[a2 * b + r, c2 + c]
                        zr[ra * b + r, cb * b + c] = v
                        zr[cb * b + c, ra * b + r] = v
        zoff = _view(zbuf, off + w * w, m, w)
        np.dot(zr, y, zoff)
        for i in range(m):
            for j in range(w):
                zoff[i, j] = -zoff[i, j]
        t = _view(tw, 0, w, w)
        np.dot(y.T, zoff, t)
        for i in range(w):
            for j in range(w):
                zcc[i, j] -= t[i, j]
    for i in range(w):
        for j in range(i):
            v = 0.5 * (zcc[i, j] + zcc[j, i])
            zcc[i, j] = v
            zcc[j, i] = v


@kernel
def supernodal_selected_inverse(
    sn_start: np.ndarray,
    col_to_sn: np.ndarray,
    colptr: np.ndarray,
    rowind: np.ndarray,
    sn_off: np.ndarray,
    lbuf: np.ndarray,
    zbuf: np.ndarray,
    b: int,
) -> None:
    """Block Takahashi recurrences: blocks of ``A^-1`` on the pattern of L, supernode by supernode.

    For supernode J with diagonal part C and off-diagonal rows R (R is a clique of the filled
    graph, so ``Z[R, R]`` lies on the pattern of L and is already known when the supernodes are
    processed from last to first), with ``Y = L[R, C] L[C, C]^-1``:
    ``Z[R, C] = -Z[R, R] Y`` and ``Z[C, C] = L[C, C]^-T L[C, C]^-1 - Y^T Z[R, C]``.
    ``zbuf`` receives the panels of ``Z = A^-1`` (diagonal parts stored in full, symmetric).
    ``zbuf`` may be ``lbuf`` itself: panel J of L is fully read before panel J of Z is written,
    and only the Z panels of later supernodes are read.
    """
    nsup = sn_start.size - 1
    ws = selinv_workspace(sn_start, colptr, b, np.arange(nsup))
    for J in range(nsup - 1, -1, -1):
        selinv_supernode(J, sn_start, col_to_sn, colptr, rowind, sn_off, lbuf, zbuf, b, ws)
