"""Symbolic factorisation: elimination tree, pattern of L, supernodes, panel layout."""

from __future__ import annotations

import numpy as np
import pytest
from helpers_linalg import make_pairs

from baarda.linalg import BlockPattern
from baarda.linalg.ordering import adjacency_from_pairs, inverse_permutation
from baarda.linalg.symbolic import (
    RelaxRule,
    elimination_tree,
    etree_postorder,
    lower_rows,
    postordered,
    symbolic_factor,
)

EXACT = RelaxRule(ncols=(1, 1, 1), zeros=(0.0, 0.0, 0.0))
KINDS = ["single", "diagonal", "random", "components", "dense", "aerial"]


def brute_force_fill(n, rptr, rcol):
    """Boolean dense elimination: pattern of L (lower, with diagonal) and the etree."""
    a = np.eye(n, dtype=bool)
    for i in range(n):
        a[i, rcol[rptr[i] : rptr[i + 1]]] = True
    for k in range(n):
        below = np.flatnonzero(a[k + 1 :, k]) + k + 1
        a[np.ix_(below, below)] = True
    a = np.tril(a)
    parent = np.array(
        [
            (np.flatnonzero(a[j + 1 :, j])[0] + j + 1) if a[j + 1 :, j].any() else -1
            for j in range(n)
        ]
    )
    return a, parent


def permuted_rows(kind, seed=0):
    n, rows, cols = make_pairs(kind, np.random.default_rng(seed))
    indptr, indices = adjacency_from_pairs(n, rows, cols)
    perm = np.random.default_rng(seed + 1).permutation(n)
    rptr, rcol = lower_rows(n, indptr, indices, inverse_permutation(perm))
    return n, rptr, rcol, (indptr, indices, perm)


@pytest.mark.parametrize("kind", KINDS)
def test_exact_pattern_and_etree(kind):
    n, rptr, rcol, _ = permuted_rows(kind)
    ref, ref_parent = brute_force_fill(n, rptr, rcol)
    sym = symbolic_factor(n, rptr, rcol, EXACT)
    assert np.array_equal(sym.parent, ref_parent)
    assert np.array_equal(elimination_tree(n, rptr, rcol), ref_parent)
    got = np.zeros((n, n), dtype=bool)
    got[sym.rowind, sym.colind] = True
    assert np.array_equal(got, ref)
    assert sym.nnz == ref.sum()


@pytest.mark.parametrize("kind", KINDS)
def test_relaxed_pattern_is_closed_superset(kind):
    n, rptr, rcol, (indptr, indices, perm) = permuted_rows(kind, seed=3)
    perm = postordered(n, indptr, indices, perm)
    rptr, rcol = lower_rows(n, indptr, indices, inverse_permutation(perm))
    ref, _ = brute_force_fill(n, rptr, rcol)
    sym = symbolic_factor(n, rptr, rcol, RelaxRule(ncols=(8, 16, 48), zeros=(0.9, 0.5, 0.2)))
    got = np.zeros((n, n), dtype=bool)
    got[sym.rowind, sym.colind] = True
    assert np.all(got[ref])  # superset of the true fill
    # closed under elimination: every column's off-diagonal rows form a clique of the pattern
    for j in range(n):
        rows = sym.rowind[sym.colptr[j] + 1 : sym.colptr[j + 1]]
        sub = got[np.ix_(rows, rows)]
        assert np.all(sub | sub.T)
    # columns: diagonal first, strictly increasing
    for j in range(n):
        rows = sym.rowind[sym.colptr[j] : sym.colptr[j + 1]]
        assert rows[0] == j and np.all(np.diff(rows) > 0)
    # supernodes are dense trapezoids: column j + 1 has the rows of column j minus j
    for s in range(sym.nsup):
        for j in range(sym.sn_start[s], sym.sn_start[s + 1] - 1):
            a = sym.rowind[sym.colptr[j] + 1 : sym.colptr[j + 1]]
            b = sym.rowind[sym.colptr[j + 1] : sym.colptr[j + 2]]
            assert np.array_equal(a, b)
    assert np.array_equal(sym.col_to_sn[sym.sn_start[:-1]], np.arange(sym.nsup))


def test_postorder():
    n, rptr, rcol, (indptr, indices, perm) = permuted_rows("aerial", seed=5)
    parent = elimination_tree(n, rptr, rcol)
    post = etree_postorder(parent)
    assert np.array_equal(np.sort(post), np.arange(n))
    rank = np.empty(n, dtype=int)
    rank[post] = np.arange(n)
    has_parent = parent >= 0
    assert np.all(rank[has_parent] < rank[parent[has_parent]])
    # postordering keeps the fill and makes every parent follow some child directly
    perm2 = postordered(n, indptr, indices, perm)
    rp2, rc2 = lower_rows(n, indptr, indices, inverse_permutation(perm2))
    s1 = symbolic_factor(n, rptr, rcol, EXACT)
    s2 = symbolic_factor(n, rp2, rc2, EXACT)
    assert s1.nnz == s2.nnz
    par2 = s2.parent
    kids = np.flatnonzero(par2 >= 0)
    assert np.all(par2[kids] > kids)


@pytest.mark.parametrize("b", [1, 6])
def test_panel_layout_covers_distinct_positions(b):
    n, rows, cols = make_pairs("aerial", np.random.default_rng(0))
    pat = BlockPattern.from_pairs(n, b, rows, cols)
    sym = pat.symbolic
    pos = pat.slot_pos[:, None, None] + (
        np.arange(b)[None, :, None] * pat.slot_stride[:, None, None] + np.arange(b)[None, None, :]
    )
    flat = pos.ravel()
    assert flat.min() >= 0 and flat.max() < pat.panel_size
    assert np.unique(flat).size == flat.size
    # stored size = slots plus the upper triangles of the supernodes' diagonal parts
    w = np.diff(sym.sn_start)
    assert pat.panel_size == b * b * (sym.nnz + (w * (w - 1) // 2).sum())
