"""Subtree parallelism for the supernodal Cholesky and the selected inverse.

With a nested-dissection ordering the supernodal elimination tree splits below its top
separators into independent subtrees. :func:`parallel_plan` picks disjoint subtrees (each a
contiguous range of supernodes, thanks to the postorder) and spreads them over the threads; the
other supernodes (the *top*: every ancestor of a chosen subtree, closed upwards) stay sequential.

* Cholesky (bottom-up): the subtrees are factored concurrently, each by the serial left-looking
  loop with its own linked-list heads and row map; updates aimed at top supernodes wait in the
  subtree's own lists, which are then merged (in subtree order) before the top is factored.
* Selected inverse (top-down): the top first, then the subtrees concurrently.

Every panel is computed by one thread in a fixed order, so the results do not depend on the
thread timing (the Cholesky factor differs from the serial kernel's only by the order in which
updates are summed into top panels; the selected inverse is identical). BLAS stays at one thread
(:mod:`baarda.linalg.threads`); the threads are numba's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numba import prange

from ._jit import parallel_kernel
from .kernels import cholesky_supernode, cholesky_workspace
from .selinv import selinv_supernode, selinv_workspace
from .symbolic import SymbolicFactor

__all__ = ["PARALLEL_MIN_WORK", "ParallelPlan", "parallel_plan"]

#: Smallest estimated factorisation work (``sum w * rows^2`` over the supernodes, scalar flops
#: order) for which :func:`parallel_plan` splits the tree; below it the serial kernels are used.
#: Measured on 2 cores (simulated blocks): 1.5e6 (30 photos) both paths take 0.2 ms, 8.8e6 (80
#: photos) parallel is 4 % faster, 3.4e7 (150 photos) 30 %, 1.1e9 (1,000 photos) 36 %.
PARALLEL_MIN_WORK = 5e6


@dataclass(frozen=True)
class ParallelPlan:
    """Disjoint subtrees of the supernodal elimination tree and their threads.

    Attributes
    ----------
    sub_lo, sub_hi : (nsub,) supernode range ``sub_lo[s]..sub_hi[s]`` (inclusive, ``sub_hi`` is
        the subtree root) of each chosen subtree, in increasing order.
    bin_ptr, bin_sub : CSR lists of the subtrees handled by each thread (bin).
    top : increasing supernodes outside every chosen subtree.
    """

    sub_lo: np.ndarray
    sub_hi: np.ndarray
    bin_ptr: np.ndarray
    bin_sub: np.ndarray
    top: np.ndarray

    def arrays(self) -> tuple[np.ndarray, ...]:
        """``(sub_lo, sub_hi, bin_ptr, bin_sub, top)`` as passed to the parallel kernels."""
        return self.sub_lo, self.sub_hi, self.bin_ptr, self.bin_sub, self.top


def _supernode_tree(sym: SymbolicFactor, b: int) -> tuple[np.ndarray, np.ndarray]:
    """Supernodal parent (-1 for roots) and work estimate ``w * rows^2`` of every supernode."""
    ss = sym.sn_start
    last = ss[1:] - 1
    pc = sym.parent[last]
    sparent = np.where(pc >= 0, sym.col_to_sn[np.maximum(pc, 0)], -1)
    w = np.diff(ss).astype(np.float64) * b
    rows = (sym.colptr[ss[:-1] + 1] - sym.colptr[ss[:-1]]).astype(np.float64) * b
    return sparent, w * rows * rows


def _lpt(costs: list[float], nbins: int) -> tuple[float, list[list[int]]]:
    """Longest-processing-time assignment of items to bins: (largest bin load, bins)."""
    loads = [0.0] * nbins
    bins: list[list[int]] = [[] for _ in range(nbins)]
    for i in sorted(range(len(costs)), key=lambda i: (-costs[i], i)):
        k = min(range(nbins), key=lambda k: (loads[k], k))
        loads[k] += costs[i]
        bins[k].append(i)
    return max(loads), bins


def parallel_plan(
    sym: SymbolicFactor, b: int, nthreads: int, min_work: float = PARALLEL_MIN_WORK
) -> ParallelPlan | None:
    """Split the supernodal tree for ``nthreads`` threads, or None where it does not pay.

    Starting from the roots, the subtree with the most work is repeatedly replaced by its
    children (its root joins the sequential top); the split with the smallest estimated time
    (top work + largest thread load) is kept. None when ``nthreads < 2``, the total work is
    below ``min_work`` or no split gives two subtrees.
    """
    nsup = sym.nsup
    if nthreads < 2 or nsup < 2:
        return None
    sparent, cost = _supernode_tree(sym, b)
    if cost.sum() < min_work:
        return None
    sub = cost.copy()
    first = np.arange(nsup)
    children: list[list[int]] = [[] for _ in range(nsup)]
    for j in range(nsup):  # children precede parents
        p = sparent[j]
        if p >= 0:
            sub[p] += sub[j]
            first[p] = min(first[p], first[j])
            children[p].append(j)
    chosen = [int(j) for j in np.flatnonzero(sparent < 0)]
    top_cost = 0.0
    best: tuple[float, list[int]] | None = None
    for _ in range(4 * nsup):
        load, _bins = _lpt([float(sub[j]) for j in chosen], nthreads)
        est = top_cost + load
        if len(chosen) >= 2 and (best is None or est < best[0]):
            best = (est, list(chosen))
        splittable = [j for j in chosen if children[j]]
        if not splittable or (best is not None and top_cost >= best[0]):
            break
        j = max(splittable, key=lambda j: (sub[j], j))
        chosen.remove(j)
        chosen.extend(children[j])
        top_cost += float(cost[j])
    if best is None:
        return None
    roots = sorted(best[1])
    _, bins = _lpt([float(sub[j]) for j in roots], nthreads)
    sub_hi = np.array(roots, dtype=np.int64)
    sub_lo = first[sub_hi].astype(np.int64)
    in_sub = np.zeros(nsup, dtype=bool)
    for lo, hi in zip(sub_lo, sub_hi, strict=True):
        in_sub[lo : hi + 1] = True
    bins = [sorted(bn) for bn in bins if bn]
    bin_ptr = np.zeros(len(bins) + 1, dtype=np.int64)
    np.cumsum([len(bn) for bn in bins], out=bin_ptr[1:])
    bin_sub = np.array([s for bn in bins for s in bn], dtype=np.int64)
    top = np.flatnonzero(~in_sub).astype(np.int64)
    return ParallelPlan(sub_lo, sub_hi, bin_ptr, bin_sub, top)


def num_threads() -> int:
    """Number of numba threads."""
    return int(numba.get_num_threads())


@parallel_kernel
def parallel_cholesky(
    sn_start: np.ndarray,
    col_to_sn: np.ndarray,
    colptr: np.ndarray,
    rowind: np.ndarray,
    sn_off: np.ndarray,
    buf: np.ndarray,
    b: int,
    rtol: float,
    sub_lo: np.ndarray,
    sub_hi: np.ndarray,
    bin_ptr: np.ndarray,
    bin_sub: np.ndarray,
    top: np.ndarray,
) -> int:
    """:func:`~baarda.linalg.kernels.supernodal_cholesky` with the subtrees of a
    :class:`ParallelPlan` factored concurrently; same return value (the first failing pivot in
    elimination order)."""
    nsup = sn_start.size - 1
    n = colptr.size - 1
    nsub = sub_lo.size
    heads = np.full((nsub, nsup), -1, dtype=np.int64)
    link = np.full(nsup, -1, dtype=np.int64)
    nextpos = np.zeros(nsup, dtype=np.int64)
    infos = np.full(nsub, -1, dtype=np.int64)
    for k in prange(bin_ptr.size - 1):
        relpos = np.zeros(n, dtype=np.int64)
        for q in range(bin_ptr[k], bin_ptr[k + 1]):
            s = bin_sub[q]
            lo = sub_lo[s]
            hi = sub_hi[s] + 1
            tmp, work, work2, diag0 = cholesky_workspace(sn_start, colptr, sn_off, b, lo, hi)
            head = heads[s]
            for J in range(lo, hi):
                info = cholesky_supernode(
                    J, sn_start, col_to_sn, colptr, rowind, sn_off, buf, b, rtol,
                    head, link, nextpos, relpos, tmp, work, work2, diag0,
                )  # fmt: skip
                if info >= 0:
                    infos[s] = info
                    break
    first_bad = -1
    for s in range(nsub):
        if infos[s] >= 0 and (first_bad < 0 or infos[s] < first_bad):
            first_bad = infos[s]
    # merge the subtrees' waiting lists (targets in the top) in subtree order
    head = np.full(nsup, -1, dtype=np.int64)
    for s in range(nsub):
        for J in top:
            K = heads[s, J]
            while K != -1:
                knext = link[K]
                link[K] = head[J]
                head[J] = K
                K = knext
    relpos = np.zeros(n, dtype=np.int64)
    tmp, work, work2, diag0 = cholesky_workspace(sn_start, colptr, sn_off, b, 0, nsup)
    for J in top:
        if first_bad >= 0 and sn_start[J] * b > first_bad:
            break
        info = cholesky_supernode(
            J, sn_start, col_to_sn, colptr, rowind, sn_off, buf, b, rtol,
            head, link, nextpos, relpos, tmp, work, work2, diag0,
        )  # fmt: skip
        if info >= 0:
            return info
    return first_bad


@parallel_kernel
def parallel_selected_inverse(
    sn_start: np.ndarray,
    col_to_sn: np.ndarray,
    colptr: np.ndarray,
    rowind: np.ndarray,
    sn_off: np.ndarray,
    lbuf: np.ndarray,
    zbuf: np.ndarray,
    b: int,
    sub_lo: np.ndarray,
    sub_hi: np.ndarray,
    bin_ptr: np.ndarray,
    bin_sub: np.ndarray,
    top: np.ndarray,
) -> None:
    """:func:`~baarda.linalg.selinv.supernodal_selected_inverse`: the top supernodes first,
    then the subtrees of a :class:`ParallelPlan` concurrently (identical results)."""
    ws = selinv_workspace(sn_start, colptr, b, top)
    for i in range(top.size - 1, -1, -1):
        selinv_supernode(top[i], sn_start, col_to_sn, colptr, rowind, sn_off, lbuf, zbuf, b, ws)
    for k in prange(bin_ptr.size - 1):
        for q in range(bin_ptr[k], bin_ptr[k + 1]):
            s = bin_sub[q]
            lo = sub_lo[s]
            hi = sub_hi[s]
            wsk = selinv_workspace(sn_start, colptr, b, np.arange(lo, hi + 1))
            for J in range(hi, lo - 1, -1):
                selinv_supernode(J, sn_start, col_to_sn, colptr, rowind, sn_off, lbuf, zbuf, b, wsk)
