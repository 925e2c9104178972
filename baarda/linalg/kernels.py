"""Numba kernels for block-sparse Cholesky, triangular solves and block Takahashi inversion.

All kernels work in the permuted (elimination) numbering on the block-CSC pattern described in
:mod:`baarda.linalg.symbolic`: ``colptr`` (n + 1), ``rowind`` (nnz, diagonal first, increasing),
and a value array of shape ``(nnz, b, b)`` whose slot ``q`` holds the dense block
``A[rowind[q], j]`` of block column ``j`` (row-major b x b). Every block column is treated as a
small dense supernode: a b x b Cholesky of the pivot block plus b x b block updates.

Numba caches the compiled kernels (``cache=True``); if the cache folder is not writable numba
only warns and compiles in memory.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = [
    "block_cholesky",
    "block_forward",
    "block_backward",
    "block_selected_inverse",
    "block_logdet",
]


@njit(cache=True, inline="always")
def _sub_abt(dst: np.ndarray, a: np.ndarray, bt: np.ndarray, b: int) -> None:
    """dst -= a @ bt.T for b x b blocks."""
    for r in range(b):
        for c in range(b):
            s = 0.0
            for t in range(b):
                s += a[r, t] * bt[c, t]
            dst[r, c] -= s


@njit(cache=True, inline="always")
def _sub_ab(dst: np.ndarray, a: np.ndarray, m: np.ndarray, b: int) -> None:
    """dst -= a @ m for b x b blocks."""
    for r in range(b):
        for t in range(b):
            art = a[r, t]
            for c in range(b):
                dst[r, c] -= art * m[t, c]


@njit(cache=True, inline="always")
def _sub_atb(dst: np.ndarray, a: np.ndarray, m: np.ndarray, b: int) -> None:
    """dst -= a.T @ m for b x b blocks."""
    for t in range(b):
        for r in range(b):
            atr = a[t, r]
            for c in range(b):
                dst[r, c] -= atr * m[t, c]


@njit(cache=True)
def _dense_cholesky(a: np.ndarray, diag0: np.ndarray, rtol: float, b: int) -> int:
    """In-place lower Cholesky of the b x b block ``a`` (upper triangle set to zero).

    A pivot fails when it is not larger than ``rtol`` times the original diagonal ``diag0`` (the
    diagonal of the matrix before any elimination); NaN pivots fail too. Returns the index of the
    failing pivot or -1.
    """
    for j in range(b):
        d = a[j, j]
        for t in range(j):
            d -= a[j, t] * a[j, t]
        if not d > rtol * abs(diag0[j]) or not d > 0.0:
            return j
        d = math.sqrt(d)
        a[j, j] = d
        for i in range(j + 1, b):
            s = a[i, j]
            for t in range(j):
                s -= a[i, t] * a[j, t]
            a[i, j] = s / d
    for i in range(b):
        for j in range(i + 1, b):
            a[i, j] = 0.0
    return -1


@njit(cache=True)
def block_cholesky(colptr: np.ndarray, rowind: np.ndarray, lval: np.ndarray, rtol: float) -> int:
    """Left-looking block Cholesky ``A = L L^T``, in place on ``lval`` (n_slots, b, b).

    On entry ``lval`` holds the lower block triangle of A (fill slots zero; of the diagonal blocks
    only the lower triangle is read). Column ``j`` collects its updates from the columns ``k`` with
    ``L[j, k] != 0`` via linked lists (each column waits in the list of its next row), then factors
    its pivot block and scales its off-diagonal blocks by ``L[j, j]^-T``.

    Returns -1 on success, otherwise ``j * b + t`` for the failing scalar pivot ``t`` of block
    column ``j`` (permuted numbering).
    """
    n = colptr.size - 1
    b = lval.shape[1]
    head = np.full(n, -1, dtype=np.int64)
    link = np.full(n, -1, dtype=np.int64)
    cur = np.zeros(n, dtype=np.int64)
    pos = np.full(n, -1, dtype=np.int64)
    diag0 = np.empty(b)
    ljk = np.empty((b, b))
    for j in range(n):
        p0 = colptr[j]
        p1 = colptr[j + 1]
        for q in range(p0, p1):
            pos[rowind[q]] = q
        for t in range(b):
            diag0[t] = lval[p0, t, t]
        k = head[j]
        while k != -1:
            knext = link[k]
            p = cur[k]
            kend = colptr[k + 1]
            for r in range(b):
                for c in range(b):
                    ljk[r, c] = lval[p, r, c]
            # diagonal target: only the lower triangle is needed
            dst = lval[p0]
            for r in range(b):
                for c in range(r + 1):
                    s = 0.0
                    for t in range(b):
                        s += ljk[r, t] * ljk[c, t]
                    dst[r, c] -= s
            for q in range(p + 1, kend):
                _sub_abt(lval[pos[rowind[q]]], lval[q], ljk, b)
            p += 1
            if p < kend:
                cur[k] = p
                i = rowind[p]
                link[k] = head[i]
                head[i] = k
            k = knext
        d = lval[p0]
        info = _dense_cholesky(d, diag0, rtol, b)
        if info >= 0:
            return j * b + info
        for q in range(p0 + 1, p1):
            x = lval[q]
            for r in range(b):
                for c in range(b):
                    s = x[r, c]
                    for t in range(c):
                        s -= x[r, t] * d[c, t]
                    x[r, c] = s / d[c, c]
        if p1 > p0 + 1:
            cur[j] = p0 + 1
            i = rowind[p0 + 1]
            link[j] = head[i]
            head[i] = j
    return -1


@njit(cache=True)
def block_forward(colptr: np.ndarray, rowind: np.ndarray, lval: np.ndarray, x: np.ndarray) -> None:
    """Solve ``L y = x`` in place; ``x`` has shape (n, b, k) in permuted numbering."""
    n = colptr.size - 1
    b = lval.shape[1]
    nrhs = x.shape[2]
    for j in range(n):
        p0 = colptr[j]
        d = lval[p0]
        xj = x[j]
        for r in range(b):
            for c in range(nrhs):
                s = xj[r, c]
                for t in range(r):
                    s -= d[r, t] * xj[t, c]
                xj[r, c] = s / d[r, r]
        for q in range(p0 + 1, colptr[j + 1]):
            xi = x[rowind[q]]
            lq = lval[q]
            for r in range(b):
                for t in range(b):
                    lrt = lq[r, t]
                    for c in range(nrhs):
                        xi[r, c] -= lrt * xj[t, c]


@njit(cache=True)
def block_backward(colptr: np.ndarray, rowind: np.ndarray, lval: np.ndarray, x: np.ndarray) -> None:
    """Solve ``L^T z = x`` in place; ``x`` has shape (n, b, k) in permuted numbering."""
    n = colptr.size - 1
    b = lval.shape[1]
    nrhs = x.shape[2]
    for j in range(n - 1, -1, -1):
        p0 = colptr[j]
        xj = x[j]
        for q in range(p0 + 1, colptr[j + 1]):
            xi = x[rowind[q]]
            lq = lval[q]
            for t in range(b):
                for r in range(b):
                    ltr = lq[t, r]
                    for c in range(nrhs):
                        xj[r, c] -= ltr * xi[t, c]
        d = lval[p0]
        for r in range(b - 1, -1, -1):
            for c in range(nrhs):
                s = xj[r, c]
                for t in range(r + 1, b):
                    s -= d[t, r] * xj[t, c]
                xj[r, c] = s / d[r, r]


@njit(cache=True)
def block_logdet(colptr: np.ndarray, lval: np.ndarray) -> float:
    """``log det A = 2 * sum(log diag L)``."""
    n = colptr.size - 1
    b = lval.shape[1]
    s = 0.0
    for j in range(n):
        d = lval[colptr[j]]
        for t in range(b):
            s += math.log(d[t, t])
    return 2.0 * s


@njit(cache=True)
def _lower_inverse(d: np.ndarray, out: np.ndarray, b: int) -> None:
    """``out = d^-1`` for a lower-triangular b x b block ``d``."""
    for c in range(b):
        for r in range(b):
            out[r, c] = 0.0
        out[c, c] = 1.0 / d[c, c]
        for r in range(c + 1, b):
            s = 0.0
            for t in range(c, r):
                s -= d[r, t] * out[t, c]
            out[r, c] = s / d[r, r]


@njit(cache=True)
def block_selected_inverse(
    colptr: np.ndarray, rowind: np.ndarray, lval: np.ndarray, zval: np.ndarray
) -> None:
    """Block Takahashi recurrences: blocks of ``A^-1`` on the pattern of L.

    With ``Y = L[I, j] L[j, j]^-1`` for the off-diagonal rows ``I`` of column ``j``:
    ``Z[I, j] = -Z[I, I] Y`` and ``Z[j, j] = L[j, j]^-T L[j, j]^-1 - Y^T Z[I, j]``. Columns are
    processed from last to first; ``Z[I, I]`` lies on the pattern of L because ``I`` is a clique
    of the filled graph. ``zval`` (n_slots, b, b) receives the lower blocks of ``A^-1``.
    """
    n = colptr.size - 1
    b = lval.shape[1]
    maxm = 1
    for j in range(n):
        maxm = max(maxm, colptr[j + 1] - colptr[j])
    y = np.empty((maxm, b, b))
    dinv = np.empty((b, b))
    loc = np.full(n, -1, dtype=np.int64)
    for j in range(n - 1, -1, -1):
        p0 = colptr[j]
        p1 = colptr[j + 1]
        m = p1 - p0 - 1
        _lower_inverse(lval[p0], dinv, b)
        for a in range(m):
            q = p0 + 1 + a
            loc[rowind[q]] = a
            lq = lval[q]
            ya = y[a]
            for r in range(b):
                for c in range(b):
                    s = 0.0
                    for t in range(c, b):
                        s += lq[r, t] * dinv[t, c]
                    ya[r, c] = s
            zq = zval[q]
            for r in range(b):
                for c in range(b):
                    zq[r, c] = 0.0
        # Z[I, j] = -Z[I, I] Y, visiting each stored block Z[k, l] (k > l, both in I) once
        for a in range(m):
            l = rowind[p0 + 1 + a]
            ql = colptr[l]
            za = zval[p0 + 1 + a]
            _sub_ab(za, zval[ql], y[a], b)
            remaining = m - a - 1
            q = ql + 1
            while remaining > 0:
                c = loc[rowind[q]]
                if c >= 0:
                    zkl = zval[q]
                    _sub_ab(zval[p0 + 1 + c], zkl, y[a], b)
                    _sub_atb(za, zkl, y[c], b)
                    remaining -= 1
                q += 1
        # Z[j, j] = Dinv^T Dinv - Y^T Z[I, j]
        zd = zval[p0]
        for r in range(b):
            for c in range(b):
                s = 0.0
                for t in range(max(r, c), b):
                    s += dinv[t, r] * dinv[t, c]
                zd[r, c] = s
        for a in range(m):
            _sub_atb(zd, y[a], zval[p0 + 1 + a], b)
        for r in range(b):
            for c in range(r):
                s = 0.5 * (zd[r, c] + zd[c, r])
                zd[r, c] = s
                zd[c, r] = s
        for a in range(m):
            loc[rowind[p0 + 1 + a]] = -1
