"""Subtree-parallel Cholesky and selected inverse against the serial kernels and dense numpy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers_linalg import make_problem, rel_err

from baarda.linalg import BlockCholesky, NotPositiveDefinite
from baarda.linalg.kernels import scatter_blocks, supernodal_cholesky
from baarda.linalg.parallel import (
    num_threads,
    parallel_cholesky,
    parallel_plan,
    parallel_selected_inverse,
)
from baarda.linalg.selinv import supernodal_selected_inverse

CASES = [("aerial", 1), ("aerial", 6), ("components", 3), ("random", 6), ("aerial", 7)]


def _supernode_parent(sym) -> np.ndarray:
    pc = sym.parent[sym.sn_start[1:] - 1]
    return np.where(pc >= 0, sym.col_to_sn[np.maximum(pc, 0)], -1)


def _serial_and_parallel(prob, nthreads):
    pat = prob.pattern
    sym = pat.symbolic
    plan = parallel_plan(sym, pat.b, nthreads, min_work=0.0)
    args = (sym.sn_start, sym.col_to_sn, sym.colptr, sym.rowind, pat.sn_off)
    bufs = []
    for par in (False, True):
        buf = np.zeros(pat.panel_size)
        scatter_blocks(prob.values, pat.slot_pos, pat.slot_stride, buf)
        if par:
            info = parallel_cholesky(*args, buf, pat.b, 1e-12, *plan.arrays())
        else:
            info = supernodal_cholesky(*args, buf, pat.b, 1e-12)
        assert info == -1
        bufs.append(buf)
    return plan, args, bufs


@pytest.mark.parametrize(("kind", "b"), CASES, ids=str)
@pytest.mark.parametrize("nthreads", [2, 3])
def test_plan_is_a_valid_split(kind, b, nthreads):
    prob = make_problem(kind, b, seed=21)
    sym = prob.pattern.symbolic
    plan = parallel_plan(sym, b, nthreads, min_work=0.0)
    assert plan is not None
    nsup = sym.nsup
    sp = _supernode_parent(sym)
    owner = np.full(nsup, -1)
    for s, (lo, hi) in enumerate(zip(plan.sub_lo, plan.sub_hi, strict=True)):
        assert np.all(owner[lo : hi + 1] == -1)  # disjoint
        owner[lo : hi + 1] = s
        for j in range(lo, hi):  # closed: every member but the root has its parent inside
            assert lo <= sp[j] <= hi
    assert plan.sub_lo.size >= 2
    np.testing.assert_array_equal(plan.top, np.flatnonzero(owner == -1))
    for j in plan.top:  # the top is closed upwards
        assert sp[j] == -1 or owner[sp[j]] == -1
    assert sorted(plan.bin_sub.tolist()) == list(range(plan.sub_lo.size))
    assert plan.bin_ptr.size - 1 <= nthreads
    assert parallel_plan(sym, b, 1, min_work=0.0) is None
    assert parallel_plan(sym, b, nthreads, min_work=math.inf) is None


@pytest.mark.parametrize(("kind", "b"), CASES, ids=str)
@pytest.mark.parametrize("nthreads", [2, 3])
def test_parallel_kernels_match_serial(kind, b, nthreads):
    prob = make_problem(kind, b, seed=22)
    pat = prob.pattern
    plan, args, (ls, lp) = _serial_and_parallel(prob, nthreads)
    assert np.abs(lp - ls).max() <= 1e-12 * np.abs(ls).max()
    # deterministic: a second parallel run gives the same numbers bit for bit
    _, _, (_, lp2) = _serial_and_parallel(prob, nthreads)
    np.testing.assert_array_equal(lp, lp2)
    zs = np.empty_like(ls)
    zp = np.empty_like(ls)
    supernodal_selected_inverse(*args, ls, zs, pat.b)
    parallel_selected_inverse(*args, ls, zp, pat.b, *plan.arrays())
    assert np.abs(zp - zs).max() <= 1e-12 * np.abs(zs).max()
    zp2 = np.empty_like(ls)
    parallel_selected_inverse(*args, ls, zp2, pat.b, *plan.arrays())
    np.testing.assert_array_equal(zp, zp2)


@pytest.mark.parametrize(("kind", "b"), CASES, ids=str)
def test_block_cholesky_parallel_path_matches_dense(kind, b):
    if num_threads() < 2:
        pytest.skip("numba runs one thread: BlockCholesky never takes the parallel path")
    prob = make_problem(kind, b, seed=23)
    pat = prob.pattern
    assert pat.parallel_plan(0.0) is not None
    chol = BlockCholesky(pat, parallel_min_work=0.0)
    chol.factorize(prob.values)
    rhs = np.linspace(-1.0, 1.0, prob.n * b)
    assert rel_err(chol.solve(rhs), prob.inverse @ rhs) < 1e-10
    sym = pat.symbolic
    rows, cols = pat.perm[sym.rowind], pat.perm[sym.colind]
    got = chol.selected_inverse().blocks(rows, cols)
    ref = prob.inverse_blocks(rows, cols)
    assert np.abs(got - ref).max() < 1e-10 * np.abs(prob.inverse).max()


@pytest.mark.parametrize("kind", ["aerial", "random"])
@pytest.mark.parametrize("b", [1, 6])
def test_parallel_path_reports_the_same_failing_block(kind, b):
    prob = make_problem(kind, b, seed=24)
    pat = prob.pattern
    sym = pat.symbolic
    plan = parallel_plan(sym, b, 2, min_work=0.0)
    args = (sym.sn_start, sym.col_to_sn, sym.colptr, sym.rowind, pat.sn_off)
    perm_sn = sym.col_to_sn[pat.iperm]  # supernode of every original block
    in_top = np.isin(perm_sn, plan.top)
    first_top = int(np.flatnonzero(in_top)[np.argmin(perm_sn[in_top])])
    last_sub = int(np.flatnonzero(~in_top)[np.argmax(perm_sn[~in_top])])
    tried = [0, prob.n - 1, first_top, last_sub]
    cases = [[t] for t in tried] + [[first_top, last_sub], [last_sub, 0], [0, prob.n - 1]]
    if kind == "random":  # a top supernode precedes a failing subtree supernode
        assert perm_sn[first_top] < perm_sn[last_sub]
    for bads in cases:
        values = prob.values.copy()
        slot, _ = pat.slots(np.array(bads), np.array(bads))
        values[slot] = -np.eye(b)
        infos = []
        for par in (False, True):
            buf = np.zeros(pat.panel_size)
            scatter_blocks(values, pat.slot_pos, pat.slot_stride, buf)
            if par:
                infos.append(parallel_cholesky(*args, buf, b, 1e-12, *plan.arrays()))
            else:
                infos.append(supernodal_cholesky(*args, buf, b, 1e-12))
        assert infos[0] == infos[1] >= 0  # the first failure in elimination order
        assert pat.perm[infos[0] // b] == bads[np.argmin(pat.iperm[bads])]
    if num_threads() >= 2:
        values = prob.values.copy()
        slot, _ = pat.slots(np.array([tried[3]]), np.array([tried[3]]))
        values[slot[0]] = -np.eye(b)
        with pytest.raises(NotPositiveDefinite) as info:
            BlockCholesky(pat, parallel_min_work=0.0).factorize(values)
        assert info.value.block == tried[3]


def test_single_chain_stays_serial():
    """A dense matrix is one supernode: nothing to split, BlockCholesky uses the serial kernel."""
    prob = make_problem("dense", 2, seed=25)
    assert parallel_plan(prob.pattern.symbolic, 2, 2, min_work=0.0) is None
    chol = BlockCholesky(prob.pattern, parallel_min_work=0.0)
    chol.factorize(prob.values)
    diag = chol.selected_inverse().diagonal_blocks()
    ref = prob.inverse_blocks(np.arange(prob.n), np.arange(prob.n))
    assert rel_err(diag, ref) < 1e-10
