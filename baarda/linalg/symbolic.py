"""Symbolic block Cholesky factorisation (elimination tree and block pattern of L).

Everything here works on the *block graph* of an already permuted symmetric matrix: vertex ``j``
is block row/column ``j`` in elimination order. The pattern of the factor ``L`` is stored in
block-CSC form: the blocks of block column ``j`` occupy slots ``colptr[j]:colptr[j + 1]``, their
block row indices are ``rowind[colptr[j]:colptr[j + 1]]``, the diagonal block comes first and the
rows are strictly increasing. The slot order is therefore the order of the keys ``j * n + i``.

Supernodes: consecutive block columns ``f..l`` with ``parent[j] = j + 1`` and
``struct(j) = {j} + struct(j + 1)`` share one row structure ``R = struct(f)``. The numeric factor
keeps each supernode as one dense row-major panel of ``len(R) * b`` rows and ``(l - f + 1) * b``
columns in a flat buffer, so that the block updates become dense matrix products (BLAS).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

__all__ = [
    "SymbolicFactor",
    "elimination_tree",
    "lower_rows",
    "supernodes",
    "symbolic_factor",
]


@dataclass(frozen=True)
class SymbolicFactor:
    """Block pattern of the Cholesky factor of a permuted symmetric block matrix.

    Attributes
    ----------
    n : number of block columns.
    parent : elimination tree, ``parent[j]`` is the parent of column ``j`` or -1 for a root.
    colptr : (n + 1,) slot range of each block column.
    rowind : (nnz,) block row index of each slot (diagonal first, increasing in each column).
    colind : (nnz,) block column index of each slot.
    sn_start : (nsup + 1,) first block column of each supernode.
    col_to_sn : (n,) supernode of each block column.
    """

    n: int
    parent: np.ndarray
    colptr: np.ndarray
    rowind: np.ndarray
    colind: np.ndarray
    sn_start: np.ndarray
    col_to_sn: np.ndarray

    @property
    def nsup(self) -> int:
        """Number of supernodes."""
        return int(self.sn_start.size - 1)

    def panel_layout(self, b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Flat-buffer layout of the supernodal panels for block size ``b``.

        Returns ``(sn_off, slot_pos, slot_stride)``: panel ``J`` starts at ``sn_off[J]``
        (``sn_off[-1]`` is the buffer length); block slot ``q`` starts at ``slot_pos[q]`` and its
        rows are ``slot_stride[q]`` apart (the panel width).
        """
        return _panel_layout(self.sn_start, self.colptr, b)

    @property
    def nnz(self) -> int:
        """Number of stored blocks of L (lower triangle including diagonal and fill)."""
        return int(self.colptr[-1])

    def keys(self) -> np.ndarray:
        """Sorted int64 keys ``col * n + row`` of the stored blocks, in slot order."""
        return self.colind * self.n + self.rowind


def lower_rows(
    n: int, indptr: np.ndarray, indices: np.ndarray, iperm: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Strictly lower row structure of the permuted graph.

    Given the symmetric adjacency (CSR, original numbering, no self loops) and ``iperm`` (old ->
    new), return CSR arrays (``rptr``, ``rcol``) such that ``rcol[rptr[i]:rptr[i + 1]]`` are the
    columns ``k < i`` of the permuted matrix with a nonzero block ``(i, k)``.
    """
    indptr = np.asarray(indptr, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    iperm = np.asarray(iperm, dtype=np.int64)
    src = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr))
    i = iperm[src]
    k = iperm[indices]
    keep = k < i
    i, k = i[keep], k[keep]
    order = np.lexsort((k, i))
    rptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(i, minlength=n), out=rptr[1:])
    return rptr, np.ascontiguousarray(k[order])


@njit(cache=True)
def elimination_tree(n: int, rptr: np.ndarray, rcol: np.ndarray) -> np.ndarray:
    """Elimination tree from the strictly lower row structure (Liu, with path compression)."""
    parent = np.full(n, -1, dtype=np.int64)
    ancestor = np.full(n, -1, dtype=np.int64)
    for i in range(n):
        for p in range(rptr[i], rptr[i + 1]):
            r = rcol[p]
            while r != -1 and r < i:
                nxt = ancestor[r]
                ancestor[r] = i
                if nxt == -1:
                    parent[r] = i
                r = nxt
    return parent


@njit(cache=True)
def _column_counts(n: int, rptr: np.ndarray, rcol: np.ndarray, parent: np.ndarray) -> np.ndarray:
    """Number of blocks in each column of L (diagonal included), via row subtrees."""
    counts = np.ones(n, dtype=np.int64)
    mark = np.full(n, -1, dtype=np.int64)
    for i in range(n):
        mark[i] = i
        for p in range(rptr[i], rptr[i + 1]):
            k = rcol[p]
            while mark[k] != i:
                counts[k] += 1
                mark[k] = i
                k = parent[k]
    return counts


@njit(cache=True)
def _fill_rows(
    n: int, rptr: np.ndarray, rcol: np.ndarray, parent: np.ndarray, colptr: np.ndarray
) -> np.ndarray:
    """Row indices of L in block-CSC order (diagonal first, rows increasing)."""
    rowind = np.empty(colptr[n], dtype=np.int64)
    nxt = colptr[:-1].copy()
    mark = np.full(n, -1, dtype=np.int64)
    for i in range(n):
        rowind[nxt[i]] = i
        nxt[i] += 1
        mark[i] = i
        for p in range(rptr[i], rptr[i + 1]):
            k = rcol[p]
            while mark[k] != i:
                rowind[nxt[k]] = i
                nxt[k] += 1
                mark[k] = i
                k = parent[k]
    return rowind


def symbolic_factor(n: int, rptr: np.ndarray, rcol: np.ndarray) -> SymbolicFactor:
    """Symbolic block Cholesky factorisation of a permuted symmetric block graph.

    ``rptr``/``rcol`` give the strictly lower row structure (see :func:`lower_rows`). Row ``i`` of
    L is the union of the elimination-tree paths from each ``k`` in row ``i`` of A up to ``i``; the
    rows are visited in increasing order, so every column's row indices come out sorted.
    """
    rptr = np.ascontiguousarray(rptr, dtype=np.int64)
    rcol = np.ascontiguousarray(rcol, dtype=np.int64)
    parent = elimination_tree(n, rptr, rcol)
    counts = _column_counts(n, rptr, rcol, parent)
    colptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=colptr[1:])
    rowind = _fill_rows(n, rptr, rcol, parent, colptr)
    colind = np.repeat(np.arange(n, dtype=np.int64), counts)
    sn_start = supernodes(parent, counts)
    col_to_sn = np.repeat(np.arange(sn_start.size - 1, dtype=np.int64), np.diff(sn_start))
    return SymbolicFactor(
        n=n,
        parent=parent,
        colptr=colptr,
        rowind=rowind,
        colind=colind,
        sn_start=sn_start,
        col_to_sn=col_to_sn,
    )


def supernodes(parent: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Fundamental-chain supernode partition: ``sn_start`` (nsup + 1,) of the block columns.

    Column ``j`` joins the supernode of ``j - 1`` when ``parent[j - 1] == j`` and
    ``counts[j - 1] == counts[j] + 1`` (then the structure of ``j - 1`` is ``{j - 1}`` plus that
    of ``j``).
    """
    n = parent.size
    if n == 0:
        return np.zeros(1, dtype=np.int64)
    j = np.arange(1, n)
    chain = (parent[:-1] == j) & (counts[:-1] == counts[1:] + 1)
    starts = np.concatenate([[0], j[~chain], [n]])
    return starts.astype(np.int64)


@njit(cache=True)
def _panel_layout(
    sn_start: np.ndarray, colptr: np.ndarray, b: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    nsup = sn_start.size - 1
    sn_off = np.zeros(nsup + 1, dtype=np.int64)
    nnz = colptr[-1]
    slot_pos = np.empty(nnz, dtype=np.int64)
    slot_stride = np.empty(nnz, dtype=np.int64)
    for s in range(nsup):
        f = sn_start[s]
        ncols = sn_start[s + 1] - f
        width = ncols * b
        nrows = colptr[f + 1] - colptr[f]
        sn_off[s + 1] = sn_off[s] + nrows * b * width
        for c in range(ncols):
            j = f + c
            for q in range(colptr[j], colptr[j + 1]):
                a = q - colptr[j] + c  # position of the row in the supernode's structure
                slot_pos[q] = sn_off[s] + a * b * width + c * b
                slot_stride[q] = width
    return sn_off, slot_pos, slot_stride
