"""Public classes: block pattern, block Cholesky factor and selected inverse.

Numbering conventions
---------------------
Users speak in ORIGINAL block numbers (e.g. photo indices). Internally blocks are permuted by a
fill-reducing ordering (``perm[new] = old``). Values live in *pattern storage*: an array of shape
``(nnz_blocks, b, b)`` with one slot per block of the lower block triangle of the permuted matrix,
fill-in included. :meth:`BlockPattern.slots` translates original block pairs to slots.

Internally the factor and the selected inverse are kept as dense supernodal panels in one flat
buffer each (see :mod:`baarda.linalg.kernels`); ``slot_pos``/``slot_stride`` locate every slot's
block in such a buffer.
"""

from __future__ import annotations

import numpy as np

from .kernels import (
    add_blocks,
    gather_blocks,
    scatter_blocks,
    supernodal_backward,
    supernodal_cholesky,
    supernodal_forward,
    supernodal_logdet,
)
from .ordering import adjacency_from_pairs, fill_reducing_ordering, inverse_permutation
from .parallel import (
    PARALLEL_MIN_WORK,
    ParallelPlan,
    num_threads,
    parallel_cholesky,
    parallel_plan,
    parallel_selected_inverse,
)
from .selinv import supernodal_selected_inverse
from .symbolic import (
    RelaxRule,
    SymbolicFactor,
    find_slots,
    lower_rows,
    postordered,
    symbolic_factor,
)
from .threads import single_threaded_blas

__all__ = ["BlockCholesky", "BlockPattern", "NotPositiveDefinite", "SelectedInverse"]

#: Default relative pivot tolerance of :meth:`BlockCholesky.factorize`.
DEFAULT_PIVOT_RTOL = 1e-12


class NotPositiveDefinite(np.linalg.LinAlgError):
    """A pivot block of the Cholesky factorisation is not positive definite.

    Attributes
    ----------
    block : original index of the block whose pivot failed (e.g. the photo that is not
        determined).
    component : index (0..b-1) of the failing scalar pivot inside that block.
    """

    def __init__(self, block: int, message: str, component: int = -1) -> None:
        super().__init__(message)
        self.block = int(block)
        self.component = int(component)


class BlockPattern:
    """Symbolic structure of a symmetric block-sparse matrix with n blocks of size b.

    Holds the fill-reducing ordering, the symbolic factor (block pattern of L including fill and
    supernode padding) and the supernodal panel layout. Computed once and reused for every
    factorisation with the same sparsity pattern.

    ``parallel_min_work``: estimated work above which the factorisation and the selected inverse
    run independent subtrees on numba's threads (see :mod:`baarda.linalg.parallel`); ``0``
    always, ``math.inf`` never.

    Attributes
    ----------
    n, b : number of blocks and block size.
    perm, iperm : ordering, ``perm[new] = old``, ``iperm[old] = new``.
    symbolic : :class:`~baarda.linalg.symbolic.SymbolicFactor` in permuted numbering.
    sn_off, slot_pos, slot_stride : supernodal panel layout for block size b (see
        :meth:`~baarda.linalg.symbolic.SymbolicFactor.panel_layout`).
    """

    def __init__(
        self, n: int, b: int, perm: np.ndarray, iperm: np.ndarray, symbolic: SymbolicFactor
    ) -> None:
        self.n = int(n)
        self.b = int(b)
        self.perm = perm
        self.iperm = iperm
        self.symbolic = symbolic
        self.sn_off, self.slot_pos, self.slot_stride = symbolic.panel_layout(self.b)
        self._plans: dict[tuple[int, float], ParallelPlan | None] = {}  # by (threads, min_work)
        self._spare: list[np.ndarray] = []  # panel storage of factors no longer in use

    def take_panels(self) -> np.ndarray:
        """Storage for the panels of one factor: a spare one if there is, else new."""
        return self._spare.pop() if self._spare else np.empty(self.panel_size)

    def give_back_panels(self, buf: np.ndarray) -> None:
        """Panel storage a factor no longer needs (kept for the next one; at most two)."""
        if len(self._spare) < 2 and buf.size == self.panel_size:
            self._spare.append(buf)

    @classmethod
    def from_pairs(
        cls,
        n: int,
        b: int,
        rows: np.ndarray,
        cols: np.ndarray,
        *,
        ordering: str = "auto",
        relax: RelaxRule | None = None,
    ) -> BlockPattern:
        """Pattern from block coupling pairs in ORIGINAL numbering.

        ``rows``/``cols`` may come in any order and either triangle, with duplicates; the diagonal
        blocks are always included. ``ordering`` is passed to
        :func:`~baarda.linalg.ordering.fill_reducing_ordering` (``"auto"``: METIS nested
        dissection, reverse Cuthill-McKee fallback); the ordering is then postordered along its
        elimination tree. ``relax`` sets the supernode amalgamation (default
        :data:`~baarda.linalg.symbolic.DEFAULT_RELAX`).
        """
        n = int(n)
        b = int(b)
        if n < 1 or b < 1:
            raise ValueError("n and b must be positive")
        indptr, indices = adjacency_from_pairs(n, rows, cols)
        perm, _ = fill_reducing_ordering(n, indptr, indices, method=ordering)
        perm = postordered(n, indptr, indices, perm)
        iperm = inverse_permutation(perm)
        rptr, rcol = lower_rows(n, indptr, indices, iperm)
        return cls(n, b, perm, iperm, symbolic_factor(n, rptr, rcol, relax))

    @property
    def nnz_blocks(self) -> int:
        """Number of stored blocks (lower triangle of L, diagonal and fill included)."""
        return self.symbolic.nnz

    def new_values(self) -> np.ndarray:
        """Zero value array of shape (nnz_blocks, b, b) in pattern storage."""
        return np.zeros((self.nnz_blocks, self.b, self.b))

    def slots(self, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Storage slots of block pairs given in ORIGINAL numbering (either triangle).

        Returns ``(slot, transposed)``: ``values[slot[m]]`` stores block ``(rows[m], cols[m])``,
        or its transpose where ``transposed[m]`` is True. Diagonal pairs are never transposed (the
        full symmetric diagonal block is stored). Raises ValueError if a pair is not in the
        pattern (of L, i.e. of S plus fill).
        """
        rows = np.asarray(rows, dtype=np.int64)
        cols = np.asarray(cols, dtype=np.int64)
        if rows.shape != cols.shape:
            raise ValueError("rows and cols must have the same shape")
        n = self.n
        if rows.size and (min(rows.min(), cols.min()) < 0 or max(rows.max(), cols.max()) >= n):
            raise ValueError(f"block indices must lie in [0, {n})")
        flat_r = np.ascontiguousarray(rows.ravel())
        flat_c = np.ascontiguousarray(cols.ravel())
        slot: np.ndarray = np.empty(flat_r.size, dtype=np.int64)
        transposed: np.ndarray = np.empty(flat_r.size, dtype=np.bool_)
        sym = self.symbolic
        bad = find_slots(sym.colptr, sym.rowind, self.iperm, flat_r, flat_c, slot, transposed)
        if bad >= 0:
            raise ValueError(
                f"block pair ({int(flat_r[bad])}, {int(flat_c[bad])}) is not in the pattern"
            )
        slot = slot.reshape(rows.shape)
        transposed = transposed.reshape(rows.shape)
        return slot, transposed

    @property
    def panel_size(self) -> int:
        """Length of the flat supernodal panel buffer of a factor (float64 entries)."""
        return int(self.sn_off[-1])

    def add_blocks(
        self, values: np.ndarray, slot: np.ndarray, transposed: np.ndarray, blocks: np.ndarray
    ) -> None:
        """Fast ``np.add.at(values, slot, blocks)`` with ``blocks[m].T`` added where
        ``transposed[m]`` (the output of :meth:`slots`). ``blocks``: (m, b, b)."""
        slot = np.ascontiguousarray(slot, dtype=np.int64).ravel()
        transposed = np.ascontiguousarray(transposed, dtype=np.bool_).ravel()
        blocks = np.ascontiguousarray(blocks, dtype=np.float64)
        if blocks.shape != (slot.size, self.b, self.b) or transposed.size != slot.size:
            raise ValueError("slot, transposed and blocks (m, b, b) must have matching lengths")
        if values.shape != (self.nnz_blocks, self.b, self.b) or values.dtype != np.float64:
            raise ValueError("values must be a float64 array from new_values()")
        if slot.size and (slot.min() < 0 or slot.max() >= self.nnz_blocks):
            raise ValueError("slot out of range")
        add_blocks(values, slot, transposed, blocks)

    def parallel_plan(self, min_work: float = PARALLEL_MIN_WORK) -> ParallelPlan | None:
        """Subtree split for numba's current thread count (cached), or None: serial kernels."""
        key = (num_threads(), float(min_work))
        plans = self.__dict__.setdefault("_plans", {})  # also for patterns pickled without it
        if key not in plans:
            plans[key] = parallel_plan(self.symbolic, self.b, key[0], min_work)
        return plans[key]

    def diagonal_slots(self) -> np.ndarray:
        """Slot of the diagonal block of every original block index (shape (n,))."""
        return self.symbolic.colptr[:-1][self.iperm]

    def __repr__(self) -> str:
        return f"BlockPattern(n={self.n}, b={self.b}, nnz_blocks={self.nnz_blocks})"


class BlockCholesky:
    """Block Cholesky factor ``P S P^T = L L^T`` on a fixed :class:`BlockPattern`.

    Call :meth:`factorize` with new values at every iteration; the pattern (ordering, symbolic
    factor, panel layout) and the factor storage are reused.
    """

    def __init__(self, pattern: BlockPattern, parallel_min_work: float = PARALLEL_MIN_WORK) -> None:
        self.pattern = pattern
        self.parallel_min_work = float(parallel_min_work)
        self._buf: np.ndarray | None = None
        self._factored = False

    @single_threaded_blas
    def factorize(self, values: np.ndarray, rtol: float = DEFAULT_PIVOT_RTOL) -> None:
        """Numeric factorisation of S given in pattern storage.

        ``values``: (nnz_blocks, b, b) assembled lower-triangle blocks of S (fill slots zero;
        of the diagonal blocks only the lower triangle is read). ``values`` is not modified.

        A scalar pivot fails when it is NaN or not larger than ``rtol`` times the corresponding
        diagonal element of S; then :class:`NotPositiveDefinite` is raised naming the ORIGINAL
        block index of the failing pivot block. Non-finite values raise ValueError.
        """
        pat = self.pattern
        shape = (pat.nnz_blocks, pat.b, pat.b)
        values = np.ascontiguousarray(values, dtype=np.float64)
        if values.shape != shape:
            raise ValueError(f"values must have shape {shape}, got {values.shape}")
        if self._buf is None:
            self._buf = pat.take_panels()
        self._factored = False
        sym = pat.symbolic
        bad = scatter_blocks(values, pat.slot_pos, pat.slot_stride, self._buf)
        if bad >= 0:
            i, j = int(pat.perm[sym.rowind[bad]]), int(pat.perm[sym.colind[bad]])
            raise ValueError(f"values contain non-finite numbers (block ({i}, {j}))")
        args = (sym.sn_start, sym.col_to_sn, sym.colptr, sym.rowind, pat.sn_off, self._buf)
        plan = pat.parallel_plan(self.parallel_min_work)
        if plan is None:
            info = supernodal_cholesky(*args, pat.b, float(rtol))
        else:
            info = parallel_cholesky(*args, pat.b, float(rtol), *plan.arrays())
        if info >= 0:
            j, t = divmod(int(info), pat.b)
            orig = int(pat.perm[j])
            raise NotPositiveDefinite(
                orig,
                f"block {orig} is not positive definite: pivot {t} of its {pat.b}x{pat.b} "
                f"block failed in the Cholesky factorisation (elimination step {j} of "
                f"{pat.n}); the unknowns of block {orig} are not determined",
                component=t,
            )
        self._factored = True

    def __del__(self) -> None:
        # the storage goes back to the pattern: the next factorisation (the next iteration of
        # an adjustment) reuses it instead of touching new memory
        buf = getattr(self, "_buf", None)
        if buf is not None:
            self.pattern.give_back_panels(buf)

    def _check(self) -> np.ndarray:
        if not self._factored or self._buf is None:
            raise RuntimeError("no valid factorisation; call factorize() first")
        return self._buf

    def _permuted(self, rhs: np.ndarray) -> tuple[np.ndarray, bool]:
        """Copy rhs ((N,) or (N, k), original order) to a permuted (N, k) work array."""
        pat = self.pattern
        rhs = np.asarray(rhs, dtype=np.float64)
        vec = rhs.ndim == 1
        if rhs.ndim not in (1, 2) or rhs.shape[0] != pat.n * pat.b:
            raise ValueError(f"rhs must have shape ({pat.n * pat.b},) or ({pat.n * pat.b}, k)")
        x = rhs.reshape(pat.n, pat.b, -1)[pat.perm]
        return np.ascontiguousarray(x.reshape(pat.n * pat.b, -1)), vec

    def _forward(self, x: np.ndarray) -> None:
        pat = self.pattern
        sym = pat.symbolic
        supernodal_forward(
            sym.sn_start, sym.colptr, sym.rowind, pat.sn_off, self._check(), pat.b, x
        )

    @single_threaded_blas
    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve ``S x = rhs``; rhs (n*b,) or (n*b, k) in ORIGINAL ordering, result same shape."""
        pat = self.pattern
        sym = pat.symbolic
        x, vec = self._permuted(rhs)
        self._forward(x)
        supernodal_backward(
            sym.sn_start, sym.colptr, sym.rowind, pat.sn_off, self._check(), pat.b, x
        )
        out = np.empty_like(x).reshape(pat.n, pat.b, -1)
        out[pat.perm] = x.reshape(pat.n, pat.b, -1)
        return out.reshape(-1) if vec else out.reshape(pat.n * pat.b, -1)

    @single_threaded_blas
    def forward(self, rhs: np.ndarray) -> np.ndarray:
        """``W = L^-1 P rhs`` (permuted order), so that ``rhs^T S^-1 rhs = ||W||^2``.

        rhs (n*b,) or (n*b, k) in ORIGINAL ordering; W has the same shape (rows permuted).
        """
        x, vec = self._permuted(rhs)
        self._forward(x)
        return x.reshape(-1) if vec else x

    def logdet(self) -> float:
        """``log det S``."""
        pat = self.pattern
        sym = pat.symbolic
        return float(supernodal_logdet(sym.sn_start, sym.colptr, pat.sn_off, self._check(), pat.b))

    @single_threaded_blas
    def selected_inverse(self, overwrite_factor: bool = False) -> SelectedInverse:
        """Blocks of ``S^-1`` on the pattern of L (which contains the pattern of S).

        With ``overwrite_factor=True`` the selected inverse is computed in the factor's own
        storage (saving one factor's worth of memory); the factor is consumed and must be
        recomputed by :meth:`factorize` before the next solve.
        """
        buf = self._check()
        pat = self.pattern
        sym = pat.symbolic
        if overwrite_factor:
            zbuf = buf
            self._factored = False
            self._buf = None
        else:
            zbuf = np.empty_like(buf)
        args = (sym.sn_start, sym.col_to_sn, sym.colptr, sym.rowind, pat.sn_off, buf, zbuf, pat.b)
        plan = pat.parallel_plan(self.parallel_min_work)
        if plan is None:
            supernodal_selected_inverse(*args)
        else:
            parallel_selected_inverse(*args, *plan.arrays())
        return SelectedInverse(pat, zbuf)


class SelectedInverse:
    """Blocks of ``S^-1`` on the pattern of the Cholesky factor, addressed in ORIGINAL numbering.

    Any block pair of the pattern of L can be read (this includes every pair given to
    :meth:`BlockPattern.from_pairs` and every diagonal block).
    """

    def __init__(self, pattern: BlockPattern, panels: np.ndarray) -> None:
        self.pattern = pattern
        self._panels = panels

    def _gather(self, slot: np.ndarray, transposed: np.ndarray) -> np.ndarray:
        pat = self.pattern
        slot = np.ascontiguousarray(slot, dtype=np.int64).ravel()
        transposed = np.ascontiguousarray(transposed, dtype=np.bool_).ravel()
        out = np.empty((slot.size, pat.b, pat.b))
        gather_blocks(self._panels, pat.slot_pos[slot], pat.slot_stride[slot], transposed, out)
        return out

    def block(self, i: int, j: int) -> np.ndarray:
        """Block ``(i, j)`` of ``S^-1`` (b, b); the pair must be in the pattern."""
        slot, tr = self.pattern.slots(np.array([i]), np.array([j]))
        return self._gather(slot, tr)[0]

    def blocks(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Blocks ``(rows[m], cols[m])`` of ``S^-1``, shape (m, b, b)."""
        rows = np.asarray(rows, dtype=np.int64).ravel()
        cols = np.asarray(cols, dtype=np.int64).ravel()
        return self._gather(*self.pattern.slots(rows, cols))

    def diagonal_blocks(self) -> np.ndarray:
        """All diagonal blocks of ``S^-1`` in ORIGINAL numbering, shape (n, b, b)."""
        slot = self.pattern.diagonal_slots()
        return self._gather(slot, np.zeros(slot.size, dtype=np.bool_))

    def pattern_values(self) -> np.ndarray:
        """All stored blocks in pattern storage (nnz_blocks, b, b), slots as in
        :meth:`BlockPattern.slots` (block ``(i, j)``, ``i >= j`` in elimination order)."""
        slot = np.arange(self.pattern.nnz_blocks, dtype=np.int64)
        return self._gather(slot, np.zeros(slot.size, dtype=np.bool_))
