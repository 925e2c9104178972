"""Shared helpers for the baarda.linalg tests: random block patterns and SPD problems."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.linalg import BlockPattern
from baarda.linalg.synthetic import aerial_block_pairs, assemble, random_spd_blocks, to_dense


def random_pairs(n: int, density: float, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """Random coupling pairs (both triangles mixed, with duplicates) of an n-vertex graph."""
    m = int(density * n * (n - 1) / 2) + 1
    r = rng.integers(0, n, m)
    c = rng.integers(0, n, m)
    dup = rng.integers(0, m, m // 4 + 1)
    return np.concatenate([r, c[dup]]), np.concatenate([c, r[dup]])


def components_pairs(sizes: list[int], density: float, rng: np.random.Generator):
    """Disconnected union of random graphs with the given vertex counts (shuffled numbering)."""
    n = sum(sizes)
    shuffle = rng.permutation(n)
    rows, cols, off = [], [], 0
    for size in sizes:
        if size > 1:
            r, c = random_pairs(size, density, rng)
            rows.append(shuffle[r + off])
            cols.append(shuffle[c + off])
        off += size
    if not rows:
        return n, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    return n, np.concatenate(rows), np.concatenate(cols)


def make_pairs(kind: str, rng: np.random.Generator) -> tuple[int, np.ndarray, np.ndarray]:
    """Named test patterns: (n, rows, cols)."""
    if kind == "single":
        return 1, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    if kind == "diagonal":
        return 5, np.array([0, 3]), np.array([0, 3])
    if kind == "random":
        r, c = random_pairs(40, 0.08, rng)
        return 40, r, c
    if kind == "components":
        return components_pairs([12, 1, 20, 2, 9], 0.2, rng)
    if kind == "dense":
        i, j = np.tril_indices(24, -1)
        return 24, i, j
    if kind == "aerial":
        return aerial_block_pairs(6, 9, along=2, across=1)
    raise ValueError(kind)


@dataclass
class Problem:
    n: int
    b: int
    rows: np.ndarray
    cols: np.ndarray
    pattern: BlockPattern
    values: np.ndarray
    dense: np.ndarray
    blocks: tuple[np.ndarray, np.ndarray, np.ndarray]
    key: tuple

    @property
    def inverse(self) -> np.ndarray:
        """Dense inverse (computed once per matrix; the matrix depends on kind, b and seed)."""
        if self.key not in _INVERSES:
            _INVERSES[self.key] = np.linalg.inv(self.dense)
        return _INVERSES[self.key]

    def inverse_blocks(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Blocks (rows[m], cols[m]) of the dense inverse, shape (m, b, b)."""
        return self.inverse.reshape(self.n, self.b, self.n, self.b)[rows, :, cols, :]


_INVERSES: dict[tuple, np.ndarray] = {}


def make_problem(kind: str, b: int, seed: int = 0, **pattern_kw) -> Problem:
    """Random SPD block matrix on a named pattern, in pattern storage and dense."""
    rng = np.random.default_rng(seed)
    n, rows, cols = make_pairs(kind, rng)
    pattern = BlockPattern.from_pairs(n, b, rows, cols, **pattern_kw)
    r, c, blk = random_spd_blocks(n, b, rows, cols, rng)
    values = assemble(pattern, r, c, blk)
    dense = to_dense(n, b, r, c, blk)
    return Problem(n, b, rows, cols, pattern, values, dense, (r, c, blk), (kind, b, seed))


def rel_err(x: np.ndarray, ref: np.ndarray) -> float:
    """Norm-wise relative error."""
    return float(np.linalg.norm(x - ref) / max(np.linalg.norm(ref), 1e-300))


def dense_block(a: np.ndarray, b: int, i: int, j: int) -> np.ndarray:
    return a[i * b : (i + 1) * b, j * b : (j + 1) * b]
