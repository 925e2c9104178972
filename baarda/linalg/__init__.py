"""Block-sparse Cholesky factorisation and selected inversion for SPD block matrices.

Typical use for a reduced camera system with n photos and b = 6 unknowns per photo::

    pattern = BlockPattern.from_pairs(n, 6, rows, cols)   # once
    values = pattern.new_values()
    slot, tr = pattern.slots(r, c)                        # once, for the assembly pairs
    chol = BlockCholesky(pattern)
    # each iteration (one (r, c) orientation per photo pair, plus the full diagonal blocks):
    values[:] = 0.0
    pattern.add_blocks(values, slot, tr, blocks)          # = np.add.at with blocks.T where tr
    chol.factorize(values)                                # NotPositiveDefinite(.block) on failure
    dx = chol.solve(rhs)
    qxx = chol.selected_inverse().diagonal_blocks()       # (n, 6, 6) blocks of S^-1

Modules: :mod:`~baarda.linalg.ordering` (METIS / RCM), :mod:`~baarda.linalg.symbolic`
(elimination tree, pattern of L, supernodes), :mod:`~baarda.linalg.kernels` (numba numeric
kernels), :mod:`~baarda.linalg.blocksparse` (these classes), :mod:`~baarda.linalg.synthetic`
(test and benchmark problems).
"""

from .blocksparse import BlockCholesky, BlockPattern, NotPositiveDefinite, SelectedInverse

__all__ = ["BlockCholesky", "BlockPattern", "NotPositiveDefinite", "SelectedInverse"]
