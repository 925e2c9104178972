"""Block-sparse Cholesky factorisation and selected inversion for SPD block matrices.

Typical use for a reduced camera system with n photos and b = 6 unknowns per photo::

    pattern = BlockPattern.from_pairs(n, 6, rows, cols)   # once
    values = pattern.new_values()
    slot, tr = pattern.slots(r, c)                        # once, for the assembly pairs
    # each iteration: values[:] = 0; np.add.at(values, slot, blocks_with_tr_transposed)
    chol = BlockCholesky(pattern)
    chol.factorize(values)
    dx = chol.solve(rhs)
    qxx = chol.selected_inverse().diagonal_blocks()
"""

from .blocksparse import BlockCholesky, BlockPattern, NotPositiveDefinite, SelectedInverse

__all__ = ["BlockCholesky", "BlockPattern", "NotPositiveDefinite", "SelectedInverse"]
