"""Scale: adjustment and rigorous statistics of every observation on large simulated blocks.

    PYTHONPATH=$PWD python benchmarks/bench_scale.py STRIPS PHOTOS_PER_STRIP SIDE_OVERLAP PATTERN

e.g. `50 100 0.6 5` (5,000 photos) or `100 200 0.3 3` (20,000 photos).  Prints the sizes,
wall times of simulate / adjust / assess, the sum of the redundancy numbers (= redundancy)
and the peak memory of the process.  No peer: pycolmap's covariance estimation is the
closest, and it stops far below this size (see ../shared/notes/peers.md).
"""

from __future__ import annotations

import argparse
import resource
import time

from baarda.pipeline import adjust, assess
from baarda.simulate.aerial import FlightPlan, simulate_block


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("strips", type=int)
    ap.add_argument("photos", type=int, help="photos per strip")
    ap.add_argument("side_overlap", type=float)
    ap.add_argument("pattern", type=int, help="n x n points per photo")
    a = ap.parse_args()
    adjust(simulate_block(FlightPlan(strips=2, photos_per_strip=3))[0])  # compile / load numba
    t0 = time.perf_counter()
    block, _ = simulate_block(FlightPlan(strips=a.strips, photos_per_strip=a.photos,
                                         side_overlap=a.side_overlap, pattern=a.pattern,
                                         relief_m=100, seed=1))
    t1 = time.perf_counter()
    res = adjust(block)
    t2 = time.perf_counter()
    qc = assess(res)
    t3 = time.perf_counter()
    print(block.summary())
    print(f"observation components {qc.model.n}, unknowns {res.n_unknowns}, redundancy "
          f"{res.redundancy}")
    print(f"simulate {t1 - t0:.1f} s, adjust {t2 - t1:.1f} s ({res.iterations} iterations), "
          f"assess (qvv, r, w, tau, MDB, external of every component) {t3 - t2:.1f} s")
    print(f"sum of redundancy numbers {qc.quality.sum_redundancy_numbers:.3f}, sigma0 "
          f"{res.sigma0:.4f}, peak memory "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


if __name__ == "__main__":
    main()
