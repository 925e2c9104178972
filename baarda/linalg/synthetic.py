"""Synthetic block patterns and SPD block matrices for tests and benchmarks."""

from __future__ import annotations

import numpy as np

from .blocksparse import BlockPattern

__all__ = ["aerial_block_pairs", "random_spd_blocks", "assemble", "to_dense"]


def aerial_block_pairs(
    strips: int, photos_per_strip: int, along: int = 2, across: int = 1
) -> tuple[int, np.ndarray, np.ndarray]:
    """Photo coupling pairs of a regular aerial block.

    Photo ``s * photos_per_strip + k`` (strip ``s``, position ``k``) is coupled to every photo in
    strips ``s - across .. s + across`` at positions ``k - along .. k + along`` (60 % forward
    overlap: ``along=2``). Returns ``(n, rows, cols)`` with each unordered pair once (``rows >
    cols``).
    """
    n = strips * photos_per_strip
    s, k = np.divmod(np.arange(n), photos_per_strip)
    rows, cols = [], []
    for ds in range(-across, across + 1):
        for dk in range(-along, along + 1):
            s2, k2 = s + ds, k + dk
            ok = (s2 >= 0) & (s2 < strips) & (k2 >= 0) & (k2 < photos_per_strip)
            j = s2 * photos_per_strip + k2
            ok &= j < np.arange(n)
            rows.append(np.arange(n)[ok])
            cols.append(j[ok])
    return n, np.concatenate(rows), np.concatenate(cols)


def random_spd_blocks(
    n: int,
    b: int,
    rows: np.ndarray,
    cols: np.ndarray,
    rng: np.random.Generator,
    shift: float = 0.1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random SPD matrix on a block pattern, as a list of blocks to assemble.

    Every coupling pair ``(i, j)`` (``i != j``) contributes ``G G^T`` of a random (2b, 2b) ``G`` to
    the blocks ``(i, i), (i, j), (j, i), (j, j)``; every diagonal block also gets ``shift * I`` plus
    a random PSD term. Returns ``(r, c, blocks)`` with full blocks for both triangles
    (duplicates allowed), suitable for :func:`assemble` or :func:`to_dense`.
    """
    rows = np.asarray(rows, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int64)
    off = rows != cols
    rows, cols = rows[off], cols[off]
    m = rows.size
    g = rng.standard_normal((m, 2 * b, 2 * b)) / np.sqrt(2 * b)
    gg = g @ g.transpose(0, 2, 1)
    h = rng.standard_normal((n, b, b)) / np.sqrt(b)
    diag = h @ h.transpose(0, 2, 1) + shift * np.eye(b)
    ar = np.arange(n)
    r = np.concatenate([ar, rows, rows, cols, cols])
    c = np.concatenate([ar, rows, cols, rows, cols])
    blocks = np.concatenate(
        [diag, gg[:, :b, :b], gg[:, :b, b:], gg[:, b:, :b], gg[:, b:, b:]], axis=0
    )
    return r, c, blocks


def assemble(pattern: BlockPattern, r: np.ndarray, c: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    """Assemble blocks ``(r[m], c[m])`` into pattern storage (lower triangle of L's pattern).

    Blocks of the upper triangle (in elimination order) are skipped, since they mirror the lower
    ones; diagonal blocks are added in full.
    """
    slot, tr = pattern.slots(r, c)
    pr = pattern.iperm[np.asarray(r)]
    pc = pattern.iperm[np.asarray(c)]
    keep = pr >= pc
    values = pattern.new_values()
    pattern.add_blocks(values, slot[keep], tr[keep], blocks[keep])
    return values


def to_dense(n: int, b: int, r: np.ndarray, c: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    """Dense (n*b, n*b) matrix from blocks (for tests only)."""
    a = np.zeros((n, b, n, b))
    np.add.at(a, (np.asarray(r), slice(None), np.asarray(c)), blocks)  # type: ignore[arg-type]  # numpy: slice in the index
    return a.reshape(n * b, n * b)
