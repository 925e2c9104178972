"""Fill-reducing orderings of a block graph.

The graph has one vertex per block row/column of a symmetric block matrix and an edge for every
nonzero off-diagonal block. The preferred ordering is METIS nested dissection (via ``pymetis``);
reverse Cuthill-McKee from scipy is the fallback for tiny graphs or when METIS is unavailable or
fails.

All permutations follow one convention: ``perm[new] = old`` and ``iperm[old] = new``.
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = [
    "METIS_MIN_BLOCKS",
    "adjacency_from_pairs",
    "fill_reducing_ordering",
    "inverse_permutation",
]

#: Graphs with fewer vertices than this are ordered by reverse Cuthill-McKee (METIS gains nothing).
METIS_MIN_BLOCKS = 16


def inverse_permutation(perm: np.ndarray) -> np.ndarray:
    """Return ``iperm`` with ``iperm[perm[k]] = k``."""
    perm = np.asarray(perm, dtype=np.int64)
    iperm = np.empty_like(perm)
    iperm[perm] = np.arange(perm.size, dtype=np.int64)
    return iperm


def adjacency_from_pairs(
    n: int, rows: np.ndarray, cols: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Symmetric adjacency (CSR ``indptr``, ``indices``) of the block graph without self loops.

    ``rows``/``cols`` are block coupling pairs in any order and either triangle; duplicates and
    diagonal pairs are allowed. Neighbour lists come out sorted and free of duplicates.
    """
    rows = np.asarray(rows, dtype=np.int64).ravel()
    cols = np.asarray(cols, dtype=np.int64).ravel()
    if rows.shape != cols.shape:
        raise ValueError("rows and cols must have the same length")
    if rows.size and (min(rows.min(), cols.min()) < 0 or max(rows.max(), cols.max()) >= n):
        raise ValueError(f"block indices must lie in [0, {n})")
    off = rows != cols
    r = np.concatenate([rows[off], cols[off]])
    c = np.concatenate([cols[off], rows[off]])
    keys = np.unique(r * n + c)
    r = keys // n
    indices = keys - r * n
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(r, minlength=n), out=indptr[1:])
    return indptr, indices


def _rcm(n: int, indptr: np.ndarray, indices: np.ndarray) -> np.ndarray:
    # imported here: scipy.sparse costs a command 0.1-0.2 s, and METIS orders all but tiny
    # graphs
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    graph = csr_matrix(
        (np.ones(indices.size, dtype=np.int8), indices.astype(np.int32), indptr.astype(np.int32)),
        shape=(n, n),
    )
    return np.asarray(reverse_cuthill_mckee(graph, symmetric_mode=True), dtype=np.int64)


def _metis(n: int, indptr: np.ndarray, indices: np.ndarray) -> np.ndarray:
    import pymetis

    if hasattr(pymetis, "CSRAdjacency"):
        perm, _ = pymetis.nested_dissection(adjacency=pymetis.CSRAdjacency(indptr, indices))
    else:  # pymetis < 2025.2
        perm, _ = pymetis.nested_dissection(xadj=indptr, adjncy=indices)
    return np.asarray(perm, dtype=np.int64)


def _is_permutation(perm: np.ndarray, n: int) -> bool:
    return perm.shape == (n,) and np.array_equal(np.sort(perm), np.arange(n))


def fill_reducing_ordering(
    n: int, indptr: np.ndarray, indices: np.ndarray, method: str = "auto"
) -> tuple[np.ndarray, np.ndarray]:
    """Fill-reducing ordering of a symmetric graph given as CSR adjacency without self loops.

    Parameters
    ----------
    n : number of vertices (blocks).
    indptr, indices : symmetric adjacency, e.g. from :func:`adjacency_from_pairs`.
    method : ``"auto"`` (METIS nested dissection, RCM for tiny graphs or if METIS fails),
        ``"metis"``, ``"rcm"`` or ``"natural"`` (identity).

    Returns
    -------
    perm, iperm : int64 arrays, ``perm[new] = old`` and ``iperm[old] = new``.
    """
    indptr = np.ascontiguousarray(indptr, dtype=np.int64)
    indices = np.ascontiguousarray(indices, dtype=np.int64)
    if method not in ("auto", "metis", "rcm", "natural"):
        raise ValueError(f"unknown ordering method {method!r}")
    perm = None
    if method == "natural" or n <= 1 or indices.size == 0:
        perm = np.arange(n, dtype=np.int64)
    elif method == "metis" or (method == "auto" and n >= METIS_MIN_BLOCKS):
        try:
            perm = _metis(n, indptr, indices)
            if not _is_permutation(perm, n):
                raise RuntimeError("METIS returned an invalid permutation")
        except Exception as exc:  # noqa: BLE001 - any METIS failure falls back to RCM
            warnings.warn(
                f"METIS ordering failed ({exc}); using reverse Cuthill-McKee", stacklevel=2
            )
            perm = None
    if perm is None:
        perm = _rcm(n, indptr, indices)
    return perm, inverse_permutation(perm)
