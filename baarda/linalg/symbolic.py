"""Symbolic block Cholesky factorisation (elimination tree and block pattern of L).

Everything here works on the *block graph* of an already permuted symmetric matrix: vertex ``j``
is block row/column ``j`` in elimination order. The pattern of the factor ``L`` is stored in
block-CSC form: the blocks of block column ``j`` occupy slots ``colptr[j]:colptr[j + 1]``, their
block row indices are ``rowind[colptr[j]:colptr[j + 1]]``, the diagonal block comes first and the
rows are strictly increasing. The slot order is therefore the order of the keys ``j * n + i``.

Supernodes: consecutive block columns ``f..l`` forming a chain of the elimination tree
(``parent[j] = j + 1``) share one row structure ``R = {f..l} + struct(l)``. Fundamental
supernodes have exactly this structure; relaxed amalgamation (:class:`RelaxRule`) also merges
chains whose structures differ a little and pads the pattern of L with explicit zero blocks. The
ordering is postordered first (:func:`postordered`) so that most parents directly follow a child.
The numeric factor keeps each supernode as one dense row-major panel of ``len(R) * b`` rows and
``(l - f + 1) * b`` columns in a flat buffer, so that block updates become dense matrix products.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._jit import kernel

__all__ = [
    "DEFAULT_RELAX",
    "RelaxRule",
    "SymbolicFactor",
    "elimination_tree",
    "etree_postorder",
    "find_slots",
    "lower_rows",
    "postordered",
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


@kernel
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


@kernel
def etree_postorder(parent: np.ndarray) -> np.ndarray:
    """Postorder of a forest (``post[k]`` is the k-th vertex); children in increasing order."""
    n = parent.size
    head = np.full(n, -1, dtype=np.int64)
    nxt = np.full(n, -1, dtype=np.int64)
    for j in range(n - 1, -1, -1):
        if parent[j] != -1:
            nxt[j] = head[parent[j]]
            head[parent[j]] = j
    post = np.empty(n, dtype=np.int64)
    stack = np.empty(n, dtype=np.int64)
    k = 0
    for root in range(n):
        if parent[root] != -1:
            continue
        top = 0
        stack[0] = root
        while top >= 0:
            p = stack[top]
            child = head[p]
            if child == -1:
                top -= 1
                post[k] = p
                k += 1
            else:
                head[p] = nxt[child]
                top += 1
                stack[top] = child
    return post


def postordered(n: int, indptr: np.ndarray, indices: np.ndarray, perm: np.ndarray) -> np.ndarray:
    """Compose ``perm`` (new -> old) with a postorder of its elimination tree.

    The postordered matrix has the same fill, but every subtree is numbered contiguously and a
    parent directly follows its last child, which creates the chains that supernodes are made of.
    """
    perm = np.asarray(perm, dtype=np.int64)
    iperm = np.empty_like(perm)
    iperm[perm] = np.arange(n, dtype=np.int64)
    rptr, rcol = lower_rows(n, indptr, indices, iperm)
    parent = elimination_tree(n, rptr, rcol)
    return perm[etree_postorder(parent)]


@kernel
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


@kernel
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


def symbolic_factor(
    n: int, rptr: np.ndarray, rcol: np.ndarray, relax: RelaxRule | None = None
) -> SymbolicFactor:
    """Symbolic block Cholesky factorisation of a permuted symmetric block graph.

    ``rptr``/``rcol`` give the strictly lower row structure (see :func:`lower_rows`). Row ``i`` of
    L is the union of the elimination-tree paths from each ``k`` in row ``i`` of A up to ``i``; the
    rows are visited in increasing order, so every column's row indices come out sorted.

    Chains of the elimination tree are then merged into supernodes (see :func:`supernodes`);
    with relaxed amalgamation (``relax``, default :data:`DEFAULT_RELAX`) the pattern of L is
    padded with explicit zero blocks so that every supernode is a dense trapezoid. The padded
    pattern is still closed under elimination (each column's off-diagonal rows form a clique),
    which the selected inversion needs.
    """
    rptr = np.ascontiguousarray(rptr, dtype=np.int64)
    rcol = np.ascontiguousarray(rcol, dtype=np.int64)
    parent = elimination_tree(n, rptr, rcol)
    counts = _column_counts(n, rptr, rcol, parent)
    colptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=colptr[1:])
    rowind = _fill_rows(n, rptr, rcol, parent, colptr)
    sn_start = supernodes(parent, counts, DEFAULT_RELAX if relax is None else relax)
    colptr, rowind = _supernodal_pattern(sn_start, colptr, rowind)
    colind = np.repeat(np.arange(n, dtype=np.int64), np.diff(colptr))
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


@dataclass(frozen=True)
class RelaxRule:
    """Relaxed supernode amalgamation (in the spirit of CHOLMOD's ``nrelax``/``zrelax``).

    A block column joins the supernode of its elimination-tree child ``j - 1`` if the merged
    supernode (``s`` block columns) is exact (no explicit zeros), or ``s <= ncols[0]``, or
    ``s <= ncols[1]`` and the fraction of explicit zero blocks is below ``zeros[0]``, or
    ``s <= ncols[2]`` and that fraction is below ``zeros[1]``, or it is below ``zeros[2]``.
    ``RelaxRule(ncols=(1, 1, 1), zeros=(0, 0, 0))`` gives fundamental supernodes only.
    """

    ncols: tuple[int, int, int] = (4, 16, 48)
    zeros: tuple[float, float, float] = (0.8, 0.1, 0.05)


#: Default amalgamation rule.
DEFAULT_RELAX = RelaxRule()


def supernodes(parent: np.ndarray, counts: np.ndarray, relax: RelaxRule) -> np.ndarray:
    """Supernode partition along elimination-tree chains: ``sn_start`` (nsup + 1,).

    Only column pairs with ``parent[j - 1] == j`` are merged, so a supernode is a chain whose row
    structure is its own columns plus the off-diagonal rows of its last column.
    """
    parent = np.ascontiguousarray(parent, dtype=np.int64)
    counts = np.ascontiguousarray(counts, dtype=np.int64)
    nc = np.array(relax.ncols, dtype=np.int64)
    zr = np.array(relax.zeros, dtype=np.float64)
    return _relaxed_supernodes(parent, counts, nc, zr)


@kernel
def _relaxed_supernodes(
    parent: np.ndarray, counts: np.ndarray, nc: np.ndarray, zr: np.ndarray
) -> np.ndarray:
    n = parent.size
    starts = np.empty(n + 1, dtype=np.int64)
    ns = 0
    starts[0] = 0
    f = 0
    true_nnz = 0
    for j in range(n):
        merge = False
        if j > 0 and parent[j - 1] == j:
            s = j - f + 1
            nrows = (j - f) + counts[j]
            stored = s * nrows - s * (s - 1) // 2
            tot = true_nnz + counts[j]
            z = 1.0 - tot / stored
            merge = (
                tot == stored
                or s <= nc[0]
                or (s <= nc[1] and z < zr[0])
                or (s <= nc[2] and z < zr[1])
                or z < zr[2]
            )
        if merge:
            true_nnz += counts[j]
        else:
            if j > 0:
                ns += 1
                starts[ns] = j
            f = j
            true_nnz = counts[j]
    if n > 0:
        ns += 1
        starts[ns] = n
    return starts[: ns + 1].copy()


@kernel
def _supernodal_pattern(
    sn_start: np.ndarray, colptr: np.ndarray, rowind: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pad the pattern of L so that each supernode ``f..l`` has rows ``{f..l} + struct(l)``."""
    nsup = sn_start.size - 1
    n = colptr.size - 1
    new_ptr = np.zeros(n + 1, dtype=np.int64)
    for J in range(nsup):
        f = sn_start[J]
        last = sn_start[J + 1] - 1
        nrows = (last - f) + (colptr[last + 1] - colptr[last])
        for c in range(last - f + 1):
            new_ptr[f + c + 1] = nrows - c
    for j in range(n):
        new_ptr[j + 1] += new_ptr[j]
    new_rows = np.empty(new_ptr[n], dtype=np.int64)
    for J in range(nsup):
        f = sn_start[J]
        last = sn_start[J + 1] - 1
        for j in range(f, last + 1):
            q = new_ptr[j]
            for i in range(j, last):
                new_rows[q] = i
                q += 1
            for p in range(colptr[last], colptr[last + 1]):
                new_rows[q] = rowind[p]
                q += 1
    return new_ptr, new_rows


@kernel
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


def _slot_of(colptr: np.ndarray, rowind: np.ndarray, lo: int, hi: int) -> int:
    """The slot of block row `hi` in block column `lo` (elimination order, hi >= lo) by
    binary search within the column; -1 when the pair is not in the pattern."""
    a = colptr[lo]
    z = colptr[lo + 1]
    while a < z:
        mid = (a + z) >> 1
        if rowind[mid] < hi:
            a = mid + 1
        else:
            z = mid
    if a == colptr[lo + 1] or rowind[a] != hi:
        return -1
    return a


slot_of = kernel(_slot_of, inline="always")


@kernel
def find_slots(
    colptr: np.ndarray,
    rowind: np.ndarray,
    iperm: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    slot: np.ndarray,
    transposed: np.ndarray,
) -> int:
    """Slots of block pairs given in original numbering (binary search within the column).

    Fills ``slot`` and ``transposed`` (True where the stored block is the transpose of block
    ``(rows[m], cols[m])``). Returns -1, or the index of the first pair not in the pattern.
    Indices must already be range-checked.
    """
    for m in range(rows.size):
        pr = iperm[rows[m]]
        pc = iperm[cols[m]]
        if pr >= pc:
            hi = pr
            lo = pc
            transposed[m] = False
        else:
            hi = pc
            lo = pr
            transposed[m] = True
        a = slot_of(colptr, rowind, lo, hi)
        if a < 0:
            return m
        slot[m] = a
    return -1
