"""Symbolic block Cholesky factorisation (elimination tree and block pattern of L).

Everything here works on the *block graph* of an already permuted symmetric matrix: vertex ``j``
is block row/column ``j`` in elimination order. The pattern of the factor ``L`` is stored in
block-CSC form: the blocks of block column ``j`` occupy slots ``colptr[j]:colptr[j + 1]``, their
block row indices are ``rowind[colptr[j]:colptr[j + 1]]``, the diagonal block comes first and the
rows are strictly increasing. The slot order is therefore the order of the keys ``j * n + i``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

__all__ = ["SymbolicFactor", "elimination_tree", "lower_rows", "symbolic_factor"]


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
    """

    n: int
    parent: np.ndarray
    colptr: np.ndarray
    rowind: np.ndarray
    colind: np.ndarray

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
    return SymbolicFactor(n=n, parent=parent, colptr=colptr, rowind=rowind, colind=colind)
