"""Fill-reducing orderings of the block graph."""

from __future__ import annotations

import numpy as np
import pytest
from helpers_linalg import make_pairs

from baarda.linalg import ordering
from baarda.linalg.ordering import (
    adjacency_from_pairs,
    fill_reducing_ordering,
    inverse_permutation,
)
from baarda.linalg.synthetic import aerial_block_pairs


def _check_perm(perm, iperm, n):
    assert perm.dtype == np.int64 and iperm.dtype == np.int64
    assert np.array_equal(np.sort(perm), np.arange(n))
    assert np.array_equal(iperm[perm], np.arange(n))


def test_adjacency_symmetric_dedup_no_self_loops():
    rows = np.array([0, 1, 1, 2, 3, 3, 0])
    cols = np.array([1, 0, 1, 0, 3, 2, 1])
    indptr, indices = adjacency_from_pairs(4, rows, cols)
    adj = [set(indices[indptr[i] : indptr[i + 1]].tolist()) for i in range(4)]
    assert adj == [{1, 2}, {0}, {0, 3}, {2}]
    for i in range(4):
        nb = indices[indptr[i] : indptr[i + 1]]
        assert np.all(np.diff(nb) > 0)
    with pytest.raises(ValueError):
        adjacency_from_pairs(3, np.array([0]), np.array([3]))
    with pytest.raises(ValueError):
        adjacency_from_pairs(3, np.array([0, 1]), np.array([1]))


@pytest.mark.parametrize("method", ["auto", "metis", "rcm", "natural"])
@pytest.mark.parametrize("kind", ["single", "diagonal", "random", "components", "aerial"])
def test_orderings_are_permutations(method, kind):
    n, rows, cols = make_pairs(kind, np.random.default_rng(0))
    indptr, indices = adjacency_from_pairs(n, rows, cols)
    perm, iperm = fill_reducing_ordering(n, indptr, indices, method=method)
    _check_perm(perm, iperm, n)
    if method == "natural":
        assert np.array_equal(perm, np.arange(n))


def test_metis_convention_separator_last():
    # star graph: the centre must be eliminated last (perm[new] = old)
    n = 30
    rows = np.zeros(n - 1, dtype=np.int64)
    cols = np.arange(1, n)
    indptr, indices = adjacency_from_pairs(n, rows, cols)
    perm, iperm = fill_reducing_ordering(n, indptr, indices, method="metis")
    assert perm[-1] == 0 and iperm[0] == n - 1


def test_metis_failure_falls_back_to_rcm(monkeypatch):
    def boom(*args, **kwargs):
        raise RuntimeError("no metis here")

    monkeypatch.setattr(ordering, "_metis", boom)
    n, rows, cols = aerial_block_pairs(5, 8)
    indptr, indices = adjacency_from_pairs(n, rows, cols)
    with pytest.warns(UserWarning, match="reverse Cuthill-McKee"):
        perm, iperm = fill_reducing_ordering(n, indptr, indices)
    _check_perm(perm, iperm, n)
    ref = ordering._rcm(n, indptr, indices)
    assert np.array_equal(perm, ref)


def test_tiny_graph_uses_rcm(monkeypatch):
    called = []
    monkeypatch.setattr(ordering, "_metis", lambda *a: called.append(1))
    n, rows, cols = aerial_block_pairs(2, 3)
    assert n < ordering.METIS_MIN_BLOCKS
    indptr, indices = adjacency_from_pairs(n, rows, cols)
    perm, iperm = fill_reducing_ordering(n, indptr, indices)
    _check_perm(perm, iperm, n)
    assert not called


def test_unknown_method():
    with pytest.raises(ValueError):
        fill_reducing_ordering(2, np.array([0, 1, 2]), np.array([1, 0]), method="amd")


def test_inverse_permutation():
    perm = np.array([2, 0, 3, 1])
    iperm = inverse_permutation(perm)
    assert np.array_equal(iperm[perm], np.arange(4))
    assert np.array_equal(perm[iperm], np.arange(4))


def test_metis_reduces_fill_on_aerial_block():
    from baarda.linalg import BlockPattern

    n, rows, cols = aerial_block_pairs(20, 50)
    nnz_metis = BlockPattern.from_pairs(n, 1, rows, cols, ordering="metis").nnz_blocks
    nnz_nat = BlockPattern.from_pairs(n, 1, rows, cols, ordering="natural").nnz_blocks
    assert nnz_metis < nnz_nat
