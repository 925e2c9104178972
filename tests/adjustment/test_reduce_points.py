"""The parallel point elimination (schur_kernels.reduce_points_parallel, large blocks) against
the serial loop over points (reduce_points, small blocks): the same S, right-hand side, Hpp
factors and inverses to the last bit, on an aerial block, a free network and with a singular
point, for one and for two numba threads; and which of them a system uses."""

import numba
import numpy as np
import pytest

from baarda.adjustment import schur_kernels as kernels
from baarda.adjustment.schur_kernels import reduce_points
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.free_network import FreeBundleProblem
from baarda.simulate.aerial import FlightPlan, simulate_block


def _captured(problem, monkeypatch):
    """The arguments of every call of the parallel kernel while `problem` is fitted (made to
    use it whatever its size)."""
    calls = []
    parallel = kernels.reduce_points_parallel

    def spy(*args):
        calls.append([a.copy() if isinstance(a, np.ndarray) else a for a in args])
        return parallel(*args)

    monkeypatch.setattr(kernels, "reduce_points_parallel", spy)
    monkeypatch.setattr(type(problem.system), "parallel_reduction", lambda self: True)
    problem.fit()
    monkeypatch.undo()
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


def test_small_blocks_stay_on_one_thread():
    """A small block never starts numba's threads (a process pool forked after it is safe);
    a 1000-photo block's elimination is parallel work."""
    small, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=6, relief_m=60, seed=3))
    assert not BundleProblem(small).system.parallel_reduction()
    large, _ = simulate_block(FlightPlan(strips=20, photos_per_strip=50, forward_overlap=0.6,
                                         side_overlap=0.6, pattern=5, relief_m=100, seed=1))
    system = BundleProblem(large).system
    assert system.parallel_reduction() == (numba.get_num_threads() > 1)
