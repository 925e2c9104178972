"""Benchmark of baarda.linalg on aerial-block patterns (not a test).

Times the symbolic analysis, the numeric block Cholesky factorisation and the selected inverse
for regular aerial blocks (photos coupled within +-2 along the strip and +-1 strip across, b = 6)
and compares with a dense scipy Cholesky + inverse (LAPACK dpotrf/dpotri) at 1,000 photos.

    python benchmarks/bench_linalg.py                 # 1,000 and 5,000 photos
    python benchmarks/bench_linalg.py --photos 20000  # add sizes
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_linalg.py  # single-threaded BLAS

Timings are the best of ``--repeat`` runs after a warm-up call (numba compilation excluded):
wall-clock seconds, and in brackets the process CPU seconds (all threads), which is the better
measure on a busy shared machine when BLAS runs single-threaded.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
import scipy.linalg

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from baarda.linalg import BlockCholesky, BlockPattern  # noqa: E402
from baarda.linalg.synthetic import (  # noqa: E402
    aerial_block_pairs,
    assemble,
    random_spd_blocks,
    to_dense,
)

B = 6


def block_shape(photos: int) -> tuple[int, int]:
    """Strips x photos per strip, strips about 2.5 times longer than the block is wide."""
    strips = max(1, round(math.sqrt(photos / 2.5)))
    return strips, math.ceil(photos / strips)


def best(fn, repeat: int) -> tuple[float, float]:
    """Best wall-clock and best CPU time of ``repeat`` calls."""
    wall, cpu = [], []
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return min(wall), min(cpu)


def bench(photos: int, repeat: int, dense: bool, across: int) -> None:
    strips, per_strip = block_shape(photos)
    n, rows, cols = aerial_block_pairs(strips, per_strip, along=2, across=across)
    rng = np.random.default_rng(0)
    t = time.perf_counter()
    pattern = BlockPattern.from_pairs(n, B, rows, cols)
    t_sym = time.perf_counter() - t
    r, c, blk = random_spd_blocks(n, B, rows, cols, rng)
    t = time.perf_counter()
    values = assemble(pattern, r, c, blk)
    t_asm = time.perf_counter() - t
    chol = BlockCholesky(pattern)
    chol.factorize(values)
    sel = chol.selected_inverse()  # warm-up (compilation / cache load)
    t_fac, c_fac = best(lambda: chol.factorize(values), repeat)
    holder = {}
    t_sel, c_sel = best(lambda: holder.update(sel=chol.selected_inverse()), repeat)
    sel = holder["sel"]
    mb = (pattern.panel_size * 8 * 2 + values.nbytes) / 2**20
    print(
        f"{n:6d} photos ({strips}x{per_strip}, {n * B} unknowns): blocks(L)={pattern.nnz_blocks}, "
        f"supernodes={pattern.symbolic.nsup}, symbolic {t_sym:.3f} s, assembly {t_asm:.3f} s, "
        f"factor {t_fac:.3f} s [{c_fac:.3f}], selected inverse {t_sel:.3f} s [{c_sel:.3f}], "
        f"factor+selinv {t_fac + t_sel:.3f} s [{c_fac + c_sel:.3f}], ~{mb:.0f} MB (values+L+Z)"
    )
    if not dense:
        return
    a = to_dense(n, B, r, c, blk)

    t, c = time.perf_counter(), time.process_time()
    cf = scipy.linalg.cholesky(a, lower=True, check_finite=False)
    t_dfac, c_dfac = time.perf_counter() - t, time.process_time() - c
    t, c = time.perf_counter(), time.process_time()
    inv, _ = scipy.linalg.lapack.dpotri(cf, lower=1)
    t_dinv, c_dinv = time.perf_counter() - t, time.process_time() - c
    inv = np.tril(inv) + np.tril(inv, -1).T
    ref = inv.reshape(n, B, n, B)[np.arange(n), :, np.arange(n), :]
    err = np.abs(sel.diagonal_blocks() - ref).max() / np.abs(ref).max()
    ratio = (t_dfac + t_dinv) / (t_fac + t_sel)
    cratio = (c_dfac + c_dinv) / (c_fac + c_sel)
    print(
        f"{'':6s} dense scipy: factor {t_dfac:.3f} s [{c_dfac:.3f}], inverse {t_dinv:.3f} s "
        f"[{c_dinv:.3f}], total {t_dfac + t_dinv:.3f} s [{c_dfac + c_dinv:.3f}] -> block-sparse "
        f"factor+selinv is {ratio:.0f}x faster [{cratio:.0f}x in CPU time]; max rel. diff of the "
        f"diagonal blocks {err:.1e}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", type=int, nargs="*", default=[1000, 5000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--across", type=int, default=1, help="strips coupled across (1 or 2)")
    ap.add_argument("--no-dense", action="store_true", help="skip the dense comparison")
    args = ap.parse_args()
    t = time.perf_counter()
    bench(200, 1, dense=False, across=args.across)  # compile / load the numba cache
    print(f"(first call incl. numba compile/cache load: {time.perf_counter() - t:.1f} s)")
    for photos in args.photos:
        bench(photos, args.repeat, dense=photos <= 1000 and not args.no_dense, across=args.across)


if __name__ == "__main__":
    main()
