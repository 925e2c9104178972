"""Block Cholesky, solves and selected inverse against dense numpy."""

from __future__ import annotations

import numpy as np
import pytest
from helpers_linalg import dense_block, make_pairs, make_problem, rel_err

from baarda.linalg import BlockCholesky, BlockPattern, NotPositiveDefinite, SelectedInverse
from baarda.linalg.symbolic import RelaxRule
from baarda.linalg.synthetic import assemble, random_spd_blocks

TOL = 1e-10
KINDS = ["single", "diagonal", "random", "components", "dense", "aerial"]
SIZES = [1, 3, 6, 7]


@pytest.fixture(scope="module", params=[(k, b) for k in KINDS for b in SIZES], ids=str)
def factored(request):
    kind, b = request.param
    prob = make_problem(kind, b, seed=hash(request.param) % 1000)
    chol = BlockCholesky(prob.pattern)
    chol.factorize(prob.values)
    return prob, chol


def test_solve_matches_dense(factored):
    prob, chol = factored
    rng = np.random.default_rng(1)
    size = prob.n * prob.b
    rhs = rng.standard_normal(size)
    x = chol.solve(rhs)
    assert x.shape == rhs.shape
    assert rel_err(x, np.linalg.solve(prob.dense, rhs)) < TOL
    rhs2 = rng.standard_normal((size, 3))
    x2 = chol.solve(rhs2)
    assert x2.shape == rhs2.shape
    assert rel_err(x2, np.linalg.solve(prob.dense, rhs2)) < TOL
    assert rel_err(prob.dense @ x2, rhs2) < TOL


def test_selected_inverse_every_block(factored):
    prob, chol = factored
    inv = prob.inverse
    sel = chol.selected_inverse()
    assert isinstance(sel, SelectedInverse)
    pat, b = prob.pattern, prob.b
    sym = pat.symbolic
    rows = pat.perm[sym.rowind]
    cols = pat.perm[sym.colind]
    for r, c in ((rows, cols), (cols, rows)):  # both triangles
        got = sel.blocks(r, c)
        ref = prob.inverse_blocks(r, c)
        assert got.shape == (pat.nnz_blocks, b, b)
        scale = np.abs(inv).max()
        assert np.abs(got - ref).max() <= TOL * scale
    diag = sel.diagonal_blocks()
    ref_diag = prob.inverse_blocks(np.arange(prob.n), np.arange(prob.n))
    assert rel_err(diag, ref_diag) < TOL
    i, j = int(rows[-1]), int(cols[-1])
    assert rel_err(sel.block(i, j), dense_block(inv, b, i, j)) < TOL
    assert rel_err(sel.block(j, i), dense_block(inv, b, j, i)) < TOL
    pv = sel.pattern_values()
    assert rel_err(pv, sel.blocks(rows, cols)) == 0.0


def test_logdet(factored):
    prob, chol = factored
    sign, ref = np.linalg.slogdet(prob.dense)
    assert sign == 1.0
    assert abs(chol.logdet() - ref) <= TOL * max(1.0, abs(ref))


def test_forward_norm_identity(factored):
    prob, chol = factored
    rng = np.random.default_rng(2)
    rhs = rng.standard_normal(prob.n * prob.b)
    w = chol.forward(rhs)
    assert w.shape == rhs.shape
    quad = rhs @ prob.inverse @ rhs
    assert abs(w @ w - quad) <= TOL * quad
    rhs2 = rng.standard_normal((prob.n * prob.b, 2))
    w2 = chol.forward(rhs2)
    quad2 = np.einsum("ik,ik->k", rhs2, prob.inverse @ rhs2)
    assert np.allclose((w2 * w2).sum(axis=0), quad2, rtol=TOL, atol=0)


def test_selected_inverse_covers_input_pairs():
    rng = np.random.default_rng(3)
    for kind in ("random", "components", "aerial"):
        prob = make_problem(kind, 6, seed=4)
        chol = BlockCholesky(prob.pattern)
        chol.factorize(prob.values)
        sel = chol.selected_inverse()
        inv = prob.inverse.reshape(prob.n, 6, prob.n, 6)
        r, c = prob.rows, prob.cols
        for rr, cc in ((r, c), (c, r)):
            assert np.abs(sel.blocks(rr, cc) - inv[rr, :, cc, :]).max() < TOL * np.abs(inv).max()
        k = rng.integers(0, r.size)
        assert np.allclose(sel.block(r[k], c[k]), inv[r[k], :, c[k], :], rtol=0, atol=1e-12)


def test_slots_and_transposed():
    prob = make_problem("components", 3, seed=5)
    pat, b = prob.pattern, prob.b
    sym = pat.symbolic
    rows = np.concatenate([pat.perm[sym.rowind], pat.perm[sym.colind]])
    cols = np.concatenate([pat.perm[sym.colind], pat.perm[sym.rowind]])
    slot, tr = pat.slots(rows, cols)
    assert slot.dtype == np.int64 and tr.dtype == np.bool_
    half = sym.nnz
    # the slot order of the pattern itself
    assert np.array_equal(slot[:half], np.arange(half))
    assert not tr[:half].any()
    assert np.array_equal(tr[half:], rows[half:] != cols[half:])
    # the stored block, transposed where tr, is block (row, col) of S
    for k in range(rows.size):
        blk = prob.values[slot[k]]
        ref = dense_block(prob.dense, b, rows[k], cols[k])
        if rows[k] == cols[k]:
            assert not tr[k]
        np.testing.assert_allclose(blk.T if tr[k] else blk, ref, rtol=0, atol=1e-14)
    # shape is preserved
    s2, t2 = pat.slots(rows[:6].reshape(2, 3), cols[:6].reshape(2, 3))
    assert s2.shape == (2, 3) and t2.shape == (2, 3)


def test_add_blocks_matches_add_at():
    prob = make_problem("random", 3, seed=6)
    pat = prob.pattern
    r, c, blk = prob.blocks
    slot, tr = pat.slots(r, c)
    ref = pat.new_values()
    np.add.at(ref, slot, np.where(tr[:, None, None], blk.transpose(0, 2, 1), blk))
    got = pat.new_values()
    pat.add_blocks(got, slot, tr, blk)
    np.testing.assert_allclose(got, ref, rtol=1e-14, atol=1e-14)


def test_assembly_from_both_triangles_via_slots():
    """The documented caller workflow: add each unordered pair once, either orientation."""
    rng = np.random.default_rng(7)
    n, rows, cols = make_pairs("random", rng)
    b = 6
    pat = BlockPattern.from_pairs(n, b, rows, cols)
    r, c, blk = random_spd_blocks(n, b, rows, cols, rng)
    dense = np.zeros((n * b, n * b))
    for i, j, x in zip(r, c, blk, strict=True):
        dense[i * b : (i + 1) * b, j * b : (j + 1) * b] += x
    keep = r >= c  # one orientation per pair (in original numbering) plus the diagonal
    slot, tr = pat.slots(r[keep], c[keep])
    values = pat.new_values()
    pat.add_blocks(values, slot, tr, blk[keep])
    chol = BlockCholesky(pat)
    chol.factorize(values)
    rhs = rng.standard_normal(n * b)
    assert rel_err(chol.solve(rhs), np.linalg.solve(dense, rhs)) < TOL


def test_slots_errors():
    pat = BlockPattern.from_pairs(4, 2, np.array([0, 2]), np.array([1, 3]))
    with pytest.raises(ValueError, match="not in the pattern"):
        pat.slots(np.array([0]), np.array([3]))
    with pytest.raises(ValueError, match="lie in"):
        pat.slots(np.array([4]), np.array([0]))
    with pytest.raises(ValueError, match="lie in"):
        pat.slots(np.array([-1]), np.array([0]))
    with pytest.raises(ValueError):
        BlockPattern.from_pairs(4, 2, np.array([0, 5]), np.array([1, 3]))
    slot, tr = pat.slots(np.array([], dtype=int), np.array([], dtype=int))
    assert slot.size == 0 and tr.size == 0


@pytest.mark.parametrize("b", [1, 6, 7])
def test_not_positive_definite_block_index(b):
    prob = make_problem("aerial", b, seed=8)
    pat = prob.pattern
    chol = BlockCholesky(pat)
    for bad in (0, 17, prob.n - 1):
        values = prob.values.copy()
        slot, _ = pat.slots(np.array([bad]), np.array([bad]))
        values[slot[0]] = -np.eye(b)
        with pytest.raises(NotPositiveDefinite) as info:
            chol.factorize(values)
        assert info.value.block == bad
        assert f"block {bad} " in str(info.value)
        with pytest.raises(RuntimeError):
            chol.solve(np.zeros(prob.n * b))
    chol.factorize(prob.values)  # recovers with good values
    assert np.isfinite(chol.logdet())


def test_undetermined_unknown_is_reported():
    """A zero row/column (e.g. one orientation angle of photo 23 not observed)."""
    b, bad, comp = 6, 23, 4
    prob = make_problem("aerial", b, seed=9)
    dense = prob.dense.copy()
    k = bad * b + comp
    dense[k, :] = 0.0
    dense[:, k] = 0.0
    pat = prob.pattern
    sym = pat.symbolic
    rows, cols = pat.perm[sym.rowind], pat.perm[sym.colind]
    values = np.stack([dense_block(dense, b, i, j) for i, j in zip(rows, cols, strict=True)])
    with pytest.raises(NotPositiveDefinite) as info:
        BlockCholesky(pat).factorize(values)
    assert info.value.block == bad
    assert info.value.component == comp


def test_nearly_singular_block_fails_with_rtol():
    b = 3
    prob = make_problem("random", b, seed=10)
    chol = BlockCholesky(prob.pattern)
    # rank-deficient photo: its diagonal block is a rank-1 matrix and it is uncoupled
    pat = prob.pattern
    bad = 5
    values = prob.values.copy()
    sym = pat.symbolic
    rows, cols = pat.perm[sym.rowind], pat.perm[sym.colind]
    values[(rows == bad) | (cols == bad)] = 0.0
    u = np.array([1.0, 2.0, 3.0])
    slot, _ = pat.slots(np.array([bad]), np.array([bad]))
    values[slot[0]] = np.outer(u, u) * 1e6
    with pytest.raises(NotPositiveDefinite) as info:
        chol.factorize(values)
    assert info.value.block == bad


def test_nonfinite_values_rejected():
    prob = make_problem("random", 3, seed=11)
    values = prob.values.copy()
    values[7, 1, 2] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        BlockCholesky(prob.pattern).factorize(values)
    values[7, 1, 2] = np.inf
    with pytest.raises(ValueError, match="non-finite"):
        BlockCholesky(prob.pattern).factorize(values)


def test_refactorize_same_pattern_new_values():
    prob = make_problem("aerial", 6, seed=12)
    pat = prob.pattern
    chol = BlockCholesky(pat)
    rng = np.random.default_rng(13)
    for _ in range(3):
        r, c, blk = random_spd_blocks(prob.n, 6, prob.rows, prob.cols, rng)
        values = assemble(pat, r, c, blk)
        before = values.copy()
        chol.factorize(values)
        assert np.array_equal(values, before)  # input not modified
        dense = np.zeros((prob.n * 6, prob.n * 6))
        for i, j, x in zip(r, c, blk, strict=True):
            dense[i * 6 : (i + 1) * 6, j * 6 : (j + 1) * 6] += x
        inv = np.linalg.inv(dense)
        diag = chol.selected_inverse().diagonal_blocks()
        ref = inv.reshape(prob.n, 6, prob.n, 6)[np.arange(prob.n), :, np.arange(prob.n), :]
        assert rel_err(diag, ref) < TOL


@pytest.mark.parametrize("ordering", ["auto", "metis", "rcm", "natural"])
@pytest.mark.parametrize(
    "relax", [None, RelaxRule(ncols=(1, 1, 1), zeros=(0.0, 0.0, 0.0))], ids=["relaxed", "exact"]
)
def test_orderings_and_amalgamation(ordering, relax):
    prob = make_problem("aerial", 6, seed=14, ordering=ordering, relax=relax)
    chol = BlockCholesky(prob.pattern)
    chol.factorize(prob.values)
    rhs = np.arange(prob.n * 6, dtype=float)
    assert rel_err(chol.solve(rhs), prob.inverse @ rhs) < TOL
    sym = prob.pattern.symbolic
    rows, cols = prob.pattern.perm[sym.rowind], prob.pattern.perm[sym.colind]
    got = chol.selected_inverse().blocks(rows, cols)
    ref = prob.inverse_blocks(rows, cols)
    assert np.abs(got - ref).max() < TOL * np.abs(prob.inverse).max()


def test_bad_shapes():
    prob = make_problem("random", 3, seed=15)
    chol = BlockCholesky(prob.pattern)
    with pytest.raises(RuntimeError):
        chol.logdet()
    with pytest.raises(ValueError):
        chol.factorize(prob.values[:-1])
    chol.factorize(prob.values)
    with pytest.raises(ValueError):
        chol.solve(np.zeros(prob.n * 3 + 1))
    with pytest.raises(ValueError):
        BlockPattern.from_pairs(0, 3, np.array([]), np.array([]))


def test_selected_inverse_in_place():
    prob = make_problem("aerial", 6, seed=16)
    chol = BlockCholesky(prob.pattern)
    chol.factorize(prob.values)
    ref = chol.selected_inverse().pattern_values()
    got = chol.selected_inverse(overwrite_factor=True).pattern_values()
    np.testing.assert_array_equal(got, ref)
    with pytest.raises(RuntimeError):
        chol.solve(np.zeros(prob.n * 6))
    chol.factorize(prob.values)
    assert rel_err(chol.selected_inverse(overwrite_factor=True).pattern_values(), ref) == 0.0
