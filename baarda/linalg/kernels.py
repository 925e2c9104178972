"""Numba kernels: supernodal block Cholesky and triangular solves (selected inverse: selinv.py).

The kernels work in the permuted (elimination) numbering. The block pattern of L is described in
:mod:`baarda.linalg.symbolic`; numerically every supernode ``J`` (consecutive block columns
``f..l`` sharing the row structure ``R = rowind[colptr[f]:colptr[f + 1]]``) is a dense row-major
panel of ``len(R) * b`` rows and ``w = (l - f + 1) * b`` columns, stored at ``buf[sn_off[J]:
sn_off[J + 1]]``. Its first ``w`` rows are the (lower-triangular) diagonal part; block row ``a``
of the panel belongs to block row ``R[a]``. A supernode of one block column is exactly one block
column of b x b blocks: a b x b dense Cholesky plus b x b block updates; wider supernodes turn the
block updates into dense matrix products that go to BLAS.

Numba caches the compiled kernels (``cache=True``, see :mod:`baarda.linalg._jit`); where no cache
folder is writable they are compiled in memory (with one warning).
"""

from __future__ import annotations

import math

import numpy as np

from ._jit import kernel

__all__ = [
    "add_blocks",
    "gather_blocks",
    "scatter_blocks",
    "supernodal_backward",
    "supernodal_cholesky",
    "supernodal_forward",
    "supernodal_logdet",
]

#: Target width (scalar columns) of the column chunks in the dense panel kernels.
CHUNK = 48


@kernel
def _chunk(b: int) -> int:
    """Chunk width: a multiple of b close to CHUNK."""
    return b * max(1, CHUNK // b)


@kernel
def _view(buf: np.ndarray, off: int, rows: int, cols: int) -> np.ndarray:
    """C-contiguous (rows, cols) view of ``buf[off:off + rows * cols]``."""
    return buf[off : off + rows * cols].reshape(rows, cols)


@kernel
def scatter_blocks(
    values: np.ndarray, slot_pos: np.ndarray, slot_stride: np.ndarray, buf: np.ndarray
) -> int:
    """Copy pattern-storage blocks ``values`` (nnz, b, b) into the panel buffer.

    Returns -1, or the first slot holding a non-finite number.
    """
    b = values.shape[1]
    bad = -1
    for q in range(values.shape[0]):
        p = slot_pos[q]
        st = slot_stride[q]
        acc = 0.0
        for r in range(b):
            for c in range(b):
                v = values[q, r, c]
                acc += v - v
                buf[p + r * st + c] = v
        if bad < 0 and acc != 0.0:  # v - v is NaN for inf and NaN
            bad = q
    return bad


@kernel
def add_blocks(
    values: np.ndarray, slot: np.ndarray, transposed: np.ndarray, blocks: np.ndarray
) -> None:
    """``values[slot[m]] += blocks[m]`` (``blocks[m].T`` where ``transposed[m]``)."""
    b = values.shape[1]
    for m in range(slot.size):
        v = values[slot[m]]
        x = blocks[m]
        if transposed[m]:
            for r in range(b):
                for c in range(b):
                    v[r, c] += x[c, r]
        else:
            for r in range(b):
                for c in range(b):
                    v[r, c] += x[r, c]


@kernel
def gather_blocks(
    buf: np.ndarray, pos: np.ndarray, stride: np.ndarray, transposed: np.ndarray, out: np.ndarray
) -> None:
    """``out[m]`` = block at ``pos[m]`` (row stride ``stride[m]``), transposed where requested."""
    b = out.shape[1]
    for m in range(pos.size):
        p = pos[m]
        st = stride[m]
        if transposed[m]:
            for r in range(b):
                for c in range(b):
                    out[m, c, r] = buf[p + r * st + c]
        else:
            for r in range(b):
                for c in range(b):
                    out[m, r, c] = buf[p + r * st + c]


@kernel
def _panel_cholesky(
    p: np.ndarray,
    diag0: np.ndarray,
    w: int,
    b: int,
    rtol: float,
    work: np.ndarray,
    work2: np.ndarray,
) -> int:
    """Dense Cholesky of a supernode panel ``p`` (N x w), in place.

    The leading w x w part is factored into a lower-triangular ``L_CC`` (upper triangle zeroed),
    the rows below are overwritten by ``L_RC = A_RC L_CC^-T``. Right-looking in column chunks;
    the trailing updates are BLAS products. A pivot fails when it is NaN or not larger than
    ``rtol * |diag0|``. Returns the failing scalar column or -1.
    """
    n_rows = p.shape[0]
    cw = _chunk(b)
    for c0 in range(0, w, cw):
        c1 = min(w, c0 + cw)
        for j in range(c0, c1):
            d = p[j, j]
            for t in range(c0, j):
                d -= p[j, t] * p[j, t]
            if not d > rtol * abs(diag0[j]) or not d > 0.0:
                return j
            d = math.sqrt(d)
            p[j, j] = d
            for i in range(j + 1, c1):
                s = p[i, j]
                for t in range(c0, j):
                    s -= p[i, t] * p[j, t]
                p[i, j] = s / d
        for i in range(c1, n_rows):
            for j in range(c0, c1):
                s = p[i, j]
                for t in range(c0, j):
                    s -= p[i, t] * p[j, t]
                p[i, j] = s / p[j, j]
        if c1 < w:
            jb = c1 - c0
            nr = n_rows - c1
            nc = w - c1
            x = work[: nr * jb].reshape(nr, jb)
            for i in range(nr):
                for t in range(jb):
                    x[i, t] = p[c1 + i, c0 + t]
            xt = work[: nc * jb].reshape(nc, jb)
            prod = work2[: nr * nc].reshape(nr, nc)
            np.dot(x, xt.T, prod)
            for i in range(nr):
                for c in range(min(nc, i + 1)):
                    p[c1 + i, c1 + c] -= prod[i, c]
    for i in range(w):
        for j in range(i + 1, w):
            p[i, j] = 0.0
    return -1


@kernel
def cholesky_workspace(
    sn_start: np.ndarray, colptr: np.ndarray, sn_off: np.ndarray, b: int, lo: int, hi: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Work arrays ``(tmp, work, work2, diag0)`` for target supernodes ``lo..hi - 1``."""
    maxpanel = 1
    maxrows = 1
    maxw = 1
    for s in range(lo, hi):
        maxpanel = max(maxpanel, sn_off[s + 1] - sn_off[s])
        maxrows = max(maxrows, (colptr[sn_start[s] + 1] - colptr[sn_start[s]]) * b)
        maxw = max(maxw, (sn_start[s + 1] - sn_start[s]) * b)
    return np.empty(maxpanel), np.empty(maxrows * _chunk(b)), np.empty(maxpanel), np.empty(maxw)


@kernel
def cholesky_supernode(
    J: int,
    sn_start: np.ndarray,
    col_to_sn: np.ndarray,
    colptr: np.ndarray,
    rowind: np.ndarray,
    sn_off: np.ndarray,
    buf: np.ndarray,
    b: int,
    rtol: float,
    head: np.ndarray,
    link: np.ndarray,
    nextpos: np.ndarray,
    relpos: np.ndarray,
    tmp: np.ndarray,
    work: np.ndarray,
    work2: np.ndarray,
    diag0: np.ndarray,
) -> int:
    """One step of :func:`supernodal_cholesky`: apply the updates waiting in ``head[J]``, factor
    panel J and put J in the list of the supernode of its first off-diagonal row.

    Returns -1 or ``j * b + t`` for a failing pivot (see :func:`supernodal_cholesky`).
    """
    f = sn_start[J]
    lj = sn_start[J + 1]
    w = (lj - f) * b
    p0 = colptr[f]
    nr = colptr[f + 1] - p0
    pj = _view(buf, sn_off[J], nr * b, w)
    for a in range(nr):
        relpos[rowind[p0 + a]] = a
    for t in range(w):
        diag0[t] = pj[t, t]
    K = head[J]
    while K != -1:
        knext = link[K]
        fk = sn_start[K]
        wk = (sn_start[K + 1] - fk) * b
        pk = colptr[fk]
        nrk = colptr[fk + 1] - pk
        a0 = nextpos[K]
        a1 = a0
        while a1 < nrk and rowind[pk + a1] < lj:
            a1 += 1
        m = nrk - a0
        mc = a1 - a0
        src = _view(buf, sn_off[K] + a0 * b * wk, m * b, wk)
        srct = _view(buf, sn_off[K] + a0 * b * wk, mc * b, wk)
        prod = _view(tmp, 0, m * b, mc * b)
        np.dot(src, srct.T, prod)
        for ra in range(m):
            ti = relpos[rowind[pk + a0 + ra]] * b
            for cb in range(min(ra + 1, mc)):
                tc = (rowind[pk + a0 + cb] - f) * b
                for r in range(b):
                    for c in range(b):
                        pj[ti + r, tc + c] -= prod[ra * b + r, cb * b + c]
        nextpos[K] = a1
        if a1 < nrk:
            j2 = col_to_sn[rowind[pk + a1]]
            link[K] = head[j2]
            head[j2] = K
        K = knext
    head[J] = -1
    info = _panel_cholesky(pj, diag0, w, b, rtol, work, work2)
    if info >= 0:
        return f * b + info
    s = lj - f
    if nr > s:
        nextpos[J] = s
        j2 = col_to_sn[rowind[p0 + s]]
        link[J] = head[j2]
        head[j2] = J
    return -1


@kernel
def supernodal_cholesky(
    sn_start: np.ndarray,
    col_to_sn: np.ndarray,
    colptr: np.ndarray,
    rowind: np.ndarray,
    sn_off: np.ndarray,
    buf: np.ndarray,
    b: int,
    rtol: float,
) -> int:
    """Left-looking supernodal block Cholesky ``A = L L^T`` in place on the panel buffer.

    On entry the panels hold the lower block triangle of A (only the lower triangle of the
    diagonal blocks is read). Supernode ``J`` gathers the updates of every earlier supernode
    ``K`` with rows in ``J`` (linked lists: ``K`` waits in the list of the supernode of its next
    unused row), each as one product ``L[R_K >= f_J, K] L[R_K in J, K]^T`` scattered into J's
    panel, then factors its panel.

    Returns -1 on success, otherwise ``j * b + t`` for the failing scalar pivot ``t`` of block
    column ``j`` (permuted numbering).
    """
    nsup = sn_start.size - 1
    n = colptr.size - 1
    head = np.full(nsup, -1, dtype=np.int64)
    link = np.full(nsup, -1, dtype=np.int64)
    nextpos = np.zeros(nsup, dtype=np.int64)
    relpos = np.zeros(n, dtype=np.int64)
    tmp, work, work2, diag0 = cholesky_workspace(sn_start, colptr, sn_off, b, 0, nsup)
    for J in range(nsup):
        info = cholesky_supernode(
            J, sn_start, col_to_sn, colptr, rowind, sn_off, buf, b, rtol,
            head, link, nextpos, relpos, tmp, work, work2, diag0,
        )  # fmt: skip
        if info >= 0:
            return info
    return -1


@kernel
def supernodal_forward(
    sn_start: np.ndarray,
    colptr: np.ndarray,
    rowind: np.ndarray,
    sn_off: np.ndarray,
    buf: np.ndarray,
    b: int,
    x: np.ndarray,
) -> None:
    """Solve ``L y = x`` in place; ``x`` is (n * b, k) in permuted numbering.  A supernode
    whose part of x is zero is skipped (its solution is zero and changes nothing): a sparse
    right-hand side costs only the supernodes on its paths to the root."""
    k = x.shape[1]
    for J in range(sn_start.size - 1):
        f = sn_start[J]
        s = sn_start[J + 1] - f
        w = s * b
        x0 = f * b
        zero = True
        for r in range(w):
            for c in range(k):
                if x[x0 + r, c] != 0.0:
                    zero = False
                    break
            if not zero:
                break
        if zero:
            continue
        p0 = colptr[f]
        nr = colptr[f + 1] - p0
        pj = _view(buf, sn_off[J], nr * b, w)
        for r in range(w):
            for t in range(r):
                lrt = pj[r, t]
                for c in range(k):
                    x[x0 + r, c] -= lrt * x[x0 + t, c]
            d = pj[r, r]
            for c in range(k):
                x[x0 + r, c] /= d
        for a in range(s, nr):
            i0 = rowind[p0 + a] * b
            for r in range(b):
                for t in range(w):
                    lrt = pj[a * b + r, t]
                    for c in range(k):
                        x[i0 + r, c] -= lrt * x[x0 + t, c]


@kernel
def supernodal_backward(
    sn_start: np.ndarray,
    colptr: np.ndarray,
    rowind: np.ndarray,
    sn_off: np.ndarray,
    buf: np.ndarray,
    b: int,
    x: np.ndarray,
) -> None:
    """Solve ``L^T z = x`` in place; ``x`` is (n * b, k) in permuted numbering."""
    k = x.shape[1]
    for J in range(sn_start.size - 2, -1, -1):
        f = sn_start[J]
        s = sn_start[J + 1] - f
        w = s * b
        p0 = colptr[f]
        nr = colptr[f + 1] - p0
        pj = _view(buf, sn_off[J], nr * b, w)
        x0 = f * b
        for a in range(s, nr):
            i0 = rowind[p0 + a] * b
            for r in range(b):
                for t in range(w):
                    lrt = pj[a * b + r, t]
                    for c in range(k):
                        x[x0 + t, c] -= lrt * x[i0 + r, c]
        for r in range(w - 1, -1, -1):
            d = pj[r, r]
            for c in range(k):
                x[x0 + r, c] /= d
            for t in range(r):
                lrt = pj[r, t]
                for c in range(k):
                    x[x0 + t, c] -= lrt * x[x0 + r, c]


@kernel
def supernodal_logdet(
    sn_start: np.ndarray, colptr: np.ndarray, sn_off: np.ndarray, buf: np.ndarray, b: int
) -> float:
    """``log det A = 2 * sum(log diag L)``."""
    total = 0.0
    for J in range(sn_start.size - 1):
        f = sn_start[J]
        w = (sn_start[J + 1] - f) * b
        nr = colptr[f + 1] - colptr[f]
        pj = _view(buf, sn_off[J], nr * b, w)
        for t in range(w):
            total += math.log(pj[t, t])
    return 2.0 * total
