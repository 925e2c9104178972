"""The parallel point elimination (schur_kernels.reduce_points_parallel) against the serial
loop over points it replaced: the same S, right-hand side, Hpp factors and inverses to the
last bit, on an aerial block, a free network and with a singular point, for one and for
two numba threads."""

import numba
import numpy as np
import pytest
from numba import njit

from baarda.adjustment import schur_kernels as kernels
from baarda.adjustment.schur_kernels import _chol_inv
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.free_network import FreeBundleProblem
from baarda.simulate.aerial import FlightPlan, simulate_block


@njit(cache=False)
def reduce_points(ptr, frame, hfp, hpp, gp, gf, values, diag_slot, hff, pair_slot, pair_tr,
                  hpp_l, hpp_inv, bad):
    """Form S = Hff - sum_j Hfp_j Hpp_j^-1 Hpf_j and the reduced right-hand side.

    hfp (m, b, d) per observation (sorted by point), frame (m,) sorted likewise; hpp
    (np, d, d) and gp (np, d) per point; hff (nf, b, b) frame diagonal blocks; gf (nf, b)
    is reduced in place.  Writes Cholesky factors and inverses of Hpp; bad[j] = 1 for a
    point whose Hpp is not positive definite.
    """
    nf = hff.shape[0]
    b = hff.shape[1]
    d = hpp.shape[1]
    for f in range(nf):
        s = diag_slot[f]
        for r in range(b):
            for c in range(b):
                values[s, r, c] += hff[f, r, c]
    k = 0
    npnt = len(ptr) - 1
    t = np.empty((hfp.shape[0], b, d))
    for j in range(npnt):
        lo, hi = ptr[j], ptr[j + 1]
        ok = _chol_inv(hpp[j], hpp_l[j], hpp_inv[j])
        if not ok:
            bad[j] = 1
            for a in range(lo, hi):
                for c in range(lo, hi):
                    if frame[a] >= frame[c]:
                        k += 1
            continue
        hinv = hpp_inv[j]
        for a in range(lo, hi):
            fa = frame[a]
            for p in range(b):
                for q in range(d):
                    acc = 0.0
                    for r in range(d):
                        acc += hfp[a, p, r] * hinv[r, q]
                    t[a, p, q] = acc
                g = 0.0
                for q in range(d):
                    g += t[a, p, q] * gp[j, q]
                gf[fa, p] -= g
        for a in range(lo, hi):
            fa = frame[a]
            for c in range(lo, hi):
                if fa < frame[c]:
                    continue
                s = pair_slot[k]
                tr = pair_tr[k]
                for p in range(b):
                    for q in range(b):
                        acc = 0.0
                        for r in range(d):
                            acc += t[a, p, r] * hfp[c, q, r]
                        if tr:
                            values[s, q, p] -= acc
                        else:
                            values[s, p, q] -= acc
                k += 1
    return d


def _captured(problem, monkeypatch):
    """The arguments of every call of the parallel kernel while `problem` is fitted."""
    calls = []
    parallel = kernels.reduce_points_parallel

    def spy(*args):
        calls.append([a.copy() if isinstance(a, np.ndarray) else a for a in args])
        return parallel(*args)

    monkeypatch.setattr(kernels, "reduce_points_parallel", spy)
    problem.fit()
    monkeypatch.setattr(kernels, "reduce_points_parallel", parallel)
    return calls


def _compare(system, args, threads):
    """Both kernels on copies of one call's inputs: every output equal to the last bit."""
    (ptr, point, hfp, hpp, gp, gf, values, hff, slot_diag, slot_ptr, slot_pairs, pa, pc, pj,
     tr, frame_ptr, frame_obs, hpp_l, hpp_inv, bad) = args
    ref = [gf.copy(), values.copy(), hpp_l.copy(), hpp_inv.copy(), bad.copy()]
    reduce_points(ptr, system.frame_sorted, hfp, hpp, gp, ref[0], ref[1], system.diag_slot,
                  hff, system.pair_slot, system.pair_tr, ref[2], ref[3], ref[4])
    out = [gf.copy(), values.copy(), hpp_l.copy(), hpp_inv.copy(), bad.copy()]
    before = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        kernels.reduce_points_parallel(ptr, point, hfp, hpp, gp, out[0], out[1], hff,
                                       slot_diag, slot_ptr, slot_pairs, pa, pc, pj, tr,
                                       frame_ptr, frame_obs, out[2], out[3], out[4])
    finally:
        numba.set_num_threads(before)
    for r, o in zip(ref, out, strict=True):
        assert np.array_equal(r, o)
    return ref


@pytest.mark.parametrize("threads", [1, 2])
def test_the_same_as_the_serial_loop(monkeypatch, threads):
    block, _ = simulate_block(FlightPlan(strips=4, photos_per_strip=8, relief_m=80, seed=7))
    free, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=5, relief_m=60,
                                        control="none", height_chains=0, seed=4))
    for problem in (BundleProblem(block), FreeBundleProblem(free)):
        calls = _captured(problem, monkeypatch)
        assert len(calls) >= 3
        for args in calls:
            _compare(problem.system, args, threads)


def test_a_singular_point_is_flagged_and_left_out(monkeypatch):
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=6, relief_m=60, seed=3))
    problem = BundleProblem(block)
    args = _captured(problem, monkeypatch)[0]
    hpp = args[3]
    j = 5
    hpp[j] = 0.0  # a point without geometry
    ref = _compare(problem.system, args, 2)
    assert ref[4][j] == 1 and ref[4].sum() == 1
