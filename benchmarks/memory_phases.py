"""Peak resident memory phase by phase (issue 40): a BAL-format problem with a camera per
photo (bench_bal_scale.simulate), read, prepared, adjusted, assessed (every observation's
statistics) and written, in one fresh process.

    PYTHONPATH=$PWD python benchmarks/memory_phases.py 100 [--drop]

Printed per phase: the resident memory after it and the process' peak so far (MB, from
/proc/self/statm and getrusage), and the largest NumPy arrays and sparse matrices the
objects still reachable from the result hold (MB).  Counts, not seconds: the figures do
not depend on the machine's load.
"""

from __future__ import annotations

import argparse
import gc
import os
import resource
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))


def rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def held(obj, depth: int = 3, seen=None, path: str = "") -> list[tuple[float, str]]:
    """(MB, attribute path) of the arrays reachable through attributes of `obj`."""
    import scipy.sparse as sp

    seen = set() if seen is None else seen
    if id(obj) in seen or depth < 0:
        return []
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        base = obj if obj.base is None else None
        return [(obj.nbytes / 2**20, path)] if base is not None else []
    if sp.issparse(obj):
        return [(sum(getattr(obj, a).nbytes for a in ("data", "indices", "indptr", "row",
                                                        "col") if hasattr(obj, a)) / 2**20,
                 path)]
    out = []
    items = []
    if isinstance(obj, (list, tuple)):
        items = [(f"[{i}]", v) for i, v in enumerate(obj[:50])]
    elif isinstance(obj, dict):
        items = [(f"[{k!r}]", v) for k, v in list(obj.items())[:200]]
    else:
        d = getattr(obj, "__dict__", None)
        if d is None and hasattr(obj, "__slots__"):
            d = {s: getattr(obj, s, None) for s in obj.__slots__}
        if d is not None and type(obj).__module__.split(".")[0] in ("baarda", "__main__"):
            items = list(d.items())
        for name in ("__dataclass_fields__",):
            if hasattr(obj, name):
                items = [(k, getattr(obj, k, None)) for k in getattr(obj, name)]
    for k, v in items:
        out += held(v, depth - 1, seen, f"{path}.{k}" if not k.startswith("[") else path + k)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cameras", type=int, nargs="?", default=100)
    ap.add_argument("--pycolmap", action="store_true",
                    help="then pycolmap's read + solve of the same file in its own process "
                         "(bench_bal_scale.worker_pycolmap): its peak, the ratio")
    args = ap.parse_args(argv)
    from bench_bal_scale import simulate, write

    tmp = Path(tempfile.mkdtemp())
    path = tmp / f"bal-{args.cameras}.txt"
    write(simulate(args.cameras), path)
    gc.collect()
    rec = None
    if args.pycolmap:  # first: a child's peak counts the parent's pages at the fork
        from bench_bal_scale import _spawn

        rec = _spawn("pycolmap", path, tmp / "pycolmap.json")
    rows = [("start (numpy, the simulation done)", rss_mb(), peak_mb())]
    import baarda
    from baarda.output.bundle_results import write_results
    from baarda.pipeline import prepare

    rows.append(("imports", rss_mb(), peak_mb()))
    block = baarda.read(str(path))
    rows.append(("read", rss_mb(), peak_mb()))
    problem = prepare(block)
    rows.append(("prepare", rss_mb(), peak_mb()))
    res = problem.fit()
    gc.collect()
    rows.append(("adjust (factor)", rss_mb(), peak_mb()))
    qc = baarda.assess(res)
    gc.collect()
    rows.append(("statistics (assess)", rss_mb(), peak_mb()))
    write_results(tmp / "out", qc)
    gc.collect()
    rows.append(("write", rss_mb(), peak_mb()))
    print(f"{args.cameras} cameras, {res.n_observations} observations, converged "
          f"{res.converged}, load average {os.getloadavg()[0]:.1f}")
    print(f"{'phase':38s} {'RSS after MB':>12s} {'peak so far MB':>14s}")
    for name, now, peak in rows:
        print(f"{name:38s} {now:12.0f} {peak:14.0f}")
    if rec:
        ours = max(p for _, _, p in rows)
        print(f"pycolmap's process (read, solve): peak {rec['peak_mb']:.0f} MB, "
              f"{rec.get('iterations')} iterations; baarda's peak / pycolmap's: "
              f"{ours / rec['peak_mb']:.2f}")
    big = sorted(held(qc, 6, path="qc"), reverse=True)[:15]
    print("largest arrays reachable from the assessment (MB):")
    for mb, p in big:
        print(f"  {mb:8.1f}  {p}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
