"""Blocks of S^-1 beyond the pattern of L: the selected inverse on a larger pattern.

The Takahashi recurrences give S^-1 on any pattern that is closed under elimination
(each column's rows a clique) and contains the pattern of L.  Such a pattern is the pattern
of the Cholesky factor of S with extra (zero) blocks at the wanted pairs, in the same
elimination order postordered along its new elimination tree: a topological order of the
old tree as well (every edge of the old tree is a path of the new one), so the numbers of L
stay what they are, the new slots hold zeros, and no second factorisation is needed: L is
copied into the larger pattern and inverted there (`selected_inverse_including`).
"""

from __future__ import annotations

import numpy as np

from ._jit import kernel
from .blocksparse import BlockCholesky, BlockPattern, SelectedInverse
from .kernels import gather_blocks, scatter_blocks
from .ordering import adjacency_from_pairs, inverse_permutation
from .symbolic import lower_rows, postordered, slot_of, symbolic_factor

__all__ = ["block_lookup", "in_pattern", "read_block", "selected_inverse_including"]


@kernel
def _contains(colptr: np.ndarray, rowind: np.ndarray, iperm: np.ndarray, rows: np.ndarray,
              cols: np.ndarray, out: np.ndarray) -> None:
    """out[m] = whether block pair (rows[m], cols[m]) (original numbering) has a slot."""
    for m in range(rows.size):
        a = iperm[rows[m]]
        c = iperm[cols[m]]
        out[m] = slot_of(colptr, rowind, min(a, c), max(a, c)) >= 0


def in_pattern(pattern: BlockPattern, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(m,) bool: whether each block pair (original numbering, either triangle) lies on the
    pattern of L."""
    rows = np.ascontiguousarray(rows, dtype=np.int64).ravel()
    cols = np.ascontiguousarray(cols, dtype=np.int64).ravel()
    out = np.zeros(rows.size, dtype=np.bool_)
    sym = pattern.symbolic
    _contains(sym.colptr, sym.rowind, pattern.iperm, rows, cols, out)
    return out


def selected_inverse_including(chol: BlockCholesky, rows: np.ndarray,
                               cols: np.ndarray) -> SelectedInverse:
    """Blocks of S^-1 on the pattern of L and at the block pairs (rows, cols) (original
    numbering, either triangle), from the factor `chol` (not changed).

    Costs one symbolic factorisation of the larger pattern and one selected inversion on it
    (no numeric factorisation); when every pair is on the pattern already, the plain selected
    inverse."""
    pat = chol.pattern
    rows = np.asarray(rows, dtype=np.int64).ravel()
    cols = np.asarray(cols, dtype=np.int64).ravel()
    new = ~in_pattern(pat, rows, cols)
    if not new.any():
        return chol.selected_inverse()
    lbuf = chol._check()
    sym, n, b = pat.symbolic, pat.n, pat.b
    # every slot of L (padding included) and the new pairs, in original numbering
    r0, c0 = pat.perm[sym.rowind], pat.perm[sym.colind]
    indptr, indices = adjacency_from_pairs(n, np.concatenate([r0, rows[new]]),
                                           np.concatenate([c0, cols[new]]))
    perm = postordered(n, indptr, indices, pat.perm)
    iperm = inverse_permutation(perm)
    rptr, rcol = lower_rows(n, indptr, indices, iperm)
    big = BlockPattern(n, b, perm, iperm, symbolic_factor(n, rptr, rcol))
    # L in the larger pattern: the same blocks, zeros in the new slots
    old = np.empty((sym.nnz, b, b))
    gather_blocks(lbuf, pat.slot_pos, pat.slot_stride, np.zeros(sym.nnz, np.bool_), old)
    diag = sym.rowind == sym.colind
    old[diag] = np.tril(old[diag])
    slot, tr = big.slots(r0, c0)
    if tr.any():  # cannot happen: the new order keeps every ancestor after its descendants
        raise RuntimeError("the larger pattern reversed a pair of the factor")
    values = np.zeros((big.nnz_blocks, b, b))
    values[slot] = old
    factor = BlockCholesky(big)
    factor._buf = np.zeros(big.panel_size)
    scatter_blocks(values, big.slot_pos, big.slot_stride, factor._buf)
    factor._factored = True
    return factor.selected_inverse(overwrite_factor=True)


def block_lookup(sel: SelectedInverse) -> tuple[np.ndarray, ...]:
    """The arrays by which a numba kernel reads block (i, j) (original numbering) of a
    selected inverse: (colptr, rowind, iperm, slot_pos, slot_stride, panels); see
    `read_block`."""
    pat = sel.pattern
    sym = pat.symbolic
    return sym.colptr, sym.rowind, pat.iperm, pat.slot_pos, pat.slot_stride, sel._panels


@kernel
def read_block(colptr: np.ndarray, rowind: np.ndarray, iperm: np.ndarray,
               slot_pos: np.ndarray, slot_stride: np.ndarray, panels: np.ndarray,
               i: int, j: int, out: np.ndarray) -> bool:
    """out (b, b) = block (i, j) of the selected inverse (`block_lookup`); False when the pair
    is not on its pattern (out untouched)."""
    a = iperm[i]
    c = iperm[j]
    s = slot_of(colptr, rowind, min(a, c), max(a, c))
    if s < 0:
        return False
    p = slot_pos[s]
    st = slot_stride[s]
    b = out.shape[0]
    for r in range(b):
        for q in range(b):
            v = panels[p + r * st + q]
            if a >= c:
                out[r, q] = v
            else:
                out[q, r] = v
    return True
