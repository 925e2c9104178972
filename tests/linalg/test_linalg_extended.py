"""The selected inverse beyond the pattern of L (linalg/extended.py) against a dense inverse."""

import numpy as np

from baarda.linalg import BlockCholesky, BlockPattern
from baarda.linalg.extended import in_pattern, selected_inverse_including
from baarda.linalg.synthetic import aerial_block_pairs, assemble, random_spd_blocks, to_dense


def _factor(strips=6, photos=12, b=6, seed=1):
    n, rows, cols = aerial_block_pairs(strips, photos)
    rng = np.random.default_rng(seed)
    r, c, blocks = random_spd_blocks(n, b, rows, cols, rng)
    pat = BlockPattern.from_pairs(n, b, rows, cols)
    chol = BlockCholesky(pat)
    chol.factorize(assemble(pat, r, c, blocks))
    return n, b, chol, np.linalg.inv(to_dense(n, b, r, c, blocks))


def test_blocks_off_the_pattern_equal_the_dense_inverse():
    n, b, chol, inv = _factor()
    # every pair of photos two positions apart in neighbouring strips and beyond
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    i, j = i.ravel(), j.ravel()
    pick = (i > j) & (np.abs(i // 12 - j // 12) <= 2) & (np.abs(i % 12 - j % 12) <= 4)
    i, j = i[pick], j[pick]
    outside = ~in_pattern(chol.pattern, i, j)
    assert outside.sum() > 50  # the test asks for blocks that L does not have
    sel = selected_inverse_including(chol, i, j)
    got = sel.blocks(i, j)
    want = inv.reshape(n, b, n, b)[i, :, j, :]
    assert np.max(np.abs(got - want)) < 1e-10 * np.max(np.abs(inv))
    # the factor is still usable, and its own selected inverse unchanged
    diag = chol.selected_inverse().diagonal_blocks()
    assert np.allclose(diag, inv.reshape(n, b, n, b)[np.arange(n), :, np.arange(n), :])


def test_pairs_on_the_pattern_need_nothing_new():
    n, b, chol, inv = _factor(3, 6)
    pat = chol.pattern
    sym = pat.symbolic
    r, c = pat.perm[sym.rowind], pat.perm[sym.colind]
    assert in_pattern(pat, r, c).all()
    sel = selected_inverse_including(chol, r[:10], c[:10])
    assert sel.pattern is pat
