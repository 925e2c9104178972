"""Scale: adjustment and rigorous statistics of every observation on large simulated blocks.

    PYTHONPATH=$PWD python benchmarks/bench_scale.py STRIPS PHOTOS_PER_STRIP SIDE_OVERLAP PATTERN
        [--write DIR] [--report] [--profile]

e.g. `50 100 0.6 5` (5,000 photos), `50 200 0.6 15` (10,000 photos with 15 x 15 points,
issue 16) or `250 200 0.6 3` (50,000 photos).  Prints the sizes, wall time and peak memory
of each phase (simulate, adjust, the statistics of every component and, apart, the
separability of issue 30 (rho_max, partner, MSB); with --write the result folder with
observations.csv and again with observations.parquet; with --report the HTML report of
each folder), the sum of the redundancy numbers (= redundancy) and the peak memory of the
process.  The peak of a phase is the resident-set high-water mark during it (reset through
/proc/self/clear_refs before it), so it includes what earlier phases left allocated.  No
peer: pycolmap's covariance estimation is the closest, and it stops far below this size (see
../shared/notes/peers.md).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

import numpy as np  # noqa: E402
from worker import peak, reset_peak  # noqa: E402

from baarda.pipeline import adjust  # noqa: E402
from baarda.simulate.aerial import FlightPlan, simulate_block  # noqa: E402


class Phases:
    """Wall time and peak resident memory of each phase."""

    def __init__(self, profile: bool):
        self.rows: list[tuple[str, float, float, float]] = []
        self.profile = profile
        self.profiles: list[str] = []

    def run(self, name: str, func):
        before = reset_peak()
        prof = cProfile.Profile() if self.profile else None
        t0 = time.perf_counter()
        out = prof.runcall(func) if prof else func()
        dt = time.perf_counter() - t0
        self.rows.append((name, dt, before, peak()))
        print(f"{name}: {dt:.2f} s, RSS before {before / 1024:.2f} GB, peak "
              f"{peak() / 1024:.2f} GB", flush=True)
        if prof:
            buf = io.StringIO()
            pstats.Stats(prof, stream=buf).sort_stats("tottime").print_stats(20)
            self.profiles.append(f"--- {name}\n{buf.getvalue()}")
        return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("strips", type=int)
    ap.add_argument("photos", type=int, help="photos per strip")
    ap.add_argument("side_overlap", type=float)
    ap.add_argument("pattern", type=int, help="n x n points per photo")
    ap.add_argument("--write", type=Path, help="write the result folder as DIR/csv and "
                    "DIR/parquet (observations.parquet) and time both")
    ap.add_argument("--report", action="store_true", help="with --write: read each folder "
                    "and make the HTML report (baarda report)")
    ap.add_argument("--profile", action="store_true", help="cProfile of each phase")
    a = ap.parse_args()
    adjust(simulate_block(FlightPlan(strips=2, photos_per_strip=3))[0])  # compile / load numba
    ph = Phases(a.profile)
    block, _ = ph.run("simulate", lambda: simulate_block(FlightPlan(
        strips=a.strips, photos_per_strip=a.photos, side_overlap=a.side_overlap,
        pattern=a.pattern, relief_m=100, seed=1)))
    res = ph.run("adjust", lambda: adjust(block))
    # the statistics as before issue 30, then the separability (rho_max, partner, MSB)
    from baarda.bundle.bundle_model import BundleModel
    from baarda.quality.assessment import Assessment
    from baarda.quality.statistics import analyse, with_separability

    model = BundleModel(res)
    q0 = ph.run("assess (statistics)", lambda: analyse(model, separability=False))
    q = ph.run("separability (rho_max, partner, MSB)", lambda: with_separability(model, q0))
    qc = Assessment(res, model, q)
    t = q.active & q.controlled
    print(f"rho_max >= 0.99: {int((q.rho_max[t] >= 0.99).sum())} of {int(t.sum())} tested; "
          f"MSB/MDB median {float(np.median(q.msb[t] / q.mdb[t])):.3f}", flush=True)
    print(block.summary())
    print(f"observation components {qc.model.n}, unknowns {res.n_unknowns}, redundancy "
          f"{res.redundancy}, {res.iterations} iterations")
    print(f"sum of redundancy numbers {qc.quality.sum_redundancy_numbers:.3f}, sigma0 "
          f"{res.sigma0:.4f}", flush=True)
    if a.write:
        from baarda.output.bundle_results import write_results

        del block
        table = ph.run("observation table (qc.table())", qc.table)
        print(f"observation table: {len(table)} rows, "
              f"{table.memory_usage(deep=True).sum() / 1e9:.2f} GB in memory", flush=True)
        del table
        for kind in ("csv", "parquet"):
            ph.run(f"write_results ({kind})",
                   lambda kind=kind: write_results(a.write / kind, qc, parquet=kind == "parquet"))
            for f in sorted((a.write / kind).iterdir()):
                print(f"  {f.name}: {f.stat().st_size / 1e6:.1f} MB")
        if a.report:
            from baarda.io.result_folder import read_results
            from baarda.report.html_report import html_report

            del qc, res
            for kind in ("csv", "parquet"):
                r = ph.run(f"read_results ({kind})", lambda kind=kind: read_results(
                    a.write / kind))
                text = ph.run(f"html_report ({kind})", lambda r=r: html_report(r))
                (a.write / f"report_{kind}.html").write_text(text, encoding="utf-8")
                print(f"  report_{kind}.html: {len(text) / 1e6:.1f} MB")
                del r, text
    print("\n| phase | wall s | RSS before GB | peak GB |\n|---|---|---|---|")
    for name, dt, before, top in ph.rows:
        print(f"| {name} | {dt:.1f} | {before / 1024:.2f} | {top / 1024:.2f} |")
    print(f"max RSS of the process "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 / 1024:.2f} GB")
    for p in ph.profiles:
        print(p)


if __name__ == "__main__":
    main()
