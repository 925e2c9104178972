"""One engine on one simulated block, in its own process (run by bench_bundle.py).

    python benchmarks/worker.py {baarda,pycolmap} --photos N --out DIR [--repeat R]
                                [--quality] [--profile] [--fixed-control]

Writes DIR/ENGINE.json (times, iterations, costs, memory) and DIR/ENGINE.npz (solution).
Memory: before each timed call free heap memory is given back (malloc_trim) and the process's
resident-set high-water mark (VmHWM) is reset through /proc/self/clear_refs, so `peak_mb` is the
largest RSS during the call and `delta_mb` its growth over the RSS just before it (Python, NumPy,
numba and C++ allocations alike; a lower bound where the call reuses memory freed before it).
"""

from __future__ import annotations

import argparse
import cProfile
import ctypes
import gc
import io
import json
import math
import os
import pstats
import sys
import time
from pathlib import Path

import numpy as np


def block_plan(photos: int, strips: int | None = None, relief: float = 100.0, seed: int = 1,
               pattern: int = 5):
    from baarda.simulate.aerial import FlightPlan

    if strips is None:  # the largest divisor of `photos` not above sqrt(photos / 2.5)
        limit = max(2, int(math.sqrt(photos / 2.5)))
        strips = max(d for d in range(2, limit + 1) if photos % d == 0) if any(
            photos % d == 0 for d in range(2, limit + 1)) else limit
    per_strip = math.ceil(photos / strips)
    return FlightPlan(strips=strips, photos_per_strip=per_strip, forward_overlap=0.6,
                      side_overlap=0.6, pattern=pattern, relief_m=relief, seed=seed)


def _status(key: str) -> float:
    """VmRSS / VmHWM of this process in MB."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(key + ":"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def reset_peak() -> float:
    """Give free heap memory back to the system and reset the RSS high-water mark;
    returns the current RSS (MB)."""
    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
    except OSError:
        pass
    return _status("VmRSS")


def peak() -> float:
    return _status("VmHWM")


def profile_text(func, lines: int = 25):
    prof = cProfile.Profile()
    out = prof.runcall(func)
    buf = io.StringIO()
    pstats.Stats(prof, stream=buf).sort_stats("cumulative").print_stats(lines)
    return out, buf.getvalue()


def run_baarda(args, block, out: Path) -> dict:
    from baarda.pipeline import adjust, assess
    from baarda.simulate.aerial import simulate_block

    rec: dict = {"engine": "baarda", "numba_cache": os.environ.get("NUMBA_CACHE_DIR", "default")}
    # numba: the first call compiles the kernels (or loads them from the cache); warm up on a
    # tiny block so that the first call on the real block finds a fresh heap
    tiny, _ = simulate_block(block_plan(10, 2, args.relief, args.seed))
    t0 = time.perf_counter()
    res = adjust(tiny)
    rec["compile_adjust_s"] = time.perf_counter() - t0
    if args.quality:
        t0 = time.perf_counter()
        assess(res)
        rec["compile_assess_s"] = time.perf_counter() - t0
    del res
    runs = []
    for _ in range(args.repeat):
        r: dict = {}
        base = reset_peak()
        t0 = time.perf_counter()
        res = adjust(block)
        r["adjust_s"] = time.perf_counter() - t0
        r["adjust_peak_mb"] = peak()
        r["adjust_delta_mb"] = r["adjust_peak_mb"] - base
        if args.quality:
            t0 = time.perf_counter()
            qc = assess(res)
            r["assess_s"] = time.perf_counter() - t0
            r["total_peak_mb"] = peak()
            r["total_delta_mb"] = r["total_peak_mb"] - base
            q = qc.quality
            rec["sum_r"] = q.sum_redundancy_numbers
            rec["n_components"] = int(len(q.w))
            rec["max_abs_w"] = float(np.nanmax(np.abs(q.w)))
            del qc, q
        runs.append(r)
        rec.update(iterations=res.iterations, converged=res.converged, final_vtpv=res.vtpv,
                   sigma0=res.sigma0, redundancy=res.redundancy,
                   n_observations=res.n_observations, n_unknowns=res.n_unknowns)
        np.savez(out / "baarda.npz", eo=res.eo, xyz=res.xyz)
        del res
    rec["runs"] = runs
    if args.profile:
        res, text = profile_text(lambda: adjust(block))
        (out / "profile_adjust.txt").write_text(text)
        if args.quality:
            _, text = profile_text(lambda: assess(res))
            (out / "profile_assess.txt").write_text(text)
    return rec


def run_pycolmap(args, block, out: Path) -> dict:
    import colmap_block as cbm

    from baarda.bundle.bundle_problem import BundleProblem

    pb = BundleProblem(block)
    eo0, xyz0 = (a.copy() for a in pb.approximations)
    rec: dict = {"engine": "pycolmap", "pyceres": cbm.pyceres is not None}
    t0 = time.perf_counter()
    cb = cbm.build(block, pb.obs, pb.point_ids, xyz0, eo0, pb.control, args.pixel_mm)
    rec["build_s"] = time.perf_counter() - t0
    rec["projection_check_px"] = cbm.verify_projection(cb, block, pb.obs, xyz0, eo0,
                                                       pb.point_ids)
    if not rec["projection_check_px"] < 1e-6:
        raise SystemExit(f"conversion to pycolmap is wrong: projections differ by "
                         f"{rec['projection_check_px']:.3g} px")
    rec["baarda_initial_vtpv"] = pb.linearize((eo0, xyz0)).cost
    template = cb.rec
    runs = []
    for k in range(args.repeat + 1):  # the first run is the cold one
        cb.rec = cbm.pycolmap.Reconstruction(template)
        base = reset_peak()
        info = cbm.adjust(cb, weighted=not args.fixed_control,
                          function_tolerance=args.function_tolerance, threads=args.threads)
        info["peak_mb"] = peak()
        info["delta_mb"] = info["peak_mb"] - base
        if k == 0:
            rec["cold_s"] = info["seconds"]
        else:
            runs.append(info)
    rec["runs"] = runs
    rec.update({k: v for k, v in runs[-1].items() if k not in ("seconds", "peak_mb",
                                                                "delta_mb")})
    eo, xyz = cbm.solution(cb)
    # the solution in baarda's terms: its cost by baarda's own equations
    rec["baarda_vtpv_of_solution"] = pb.linearize((eo, xyz)).cost
    np.savez(out / "pycolmap.npz", eo=eo, xyz=xyz)
    return rec


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("engine", choices=["baarda", "pycolmap"])
    ap.add_argument("--photos", type=int, default=1000)
    ap.add_argument("--strips", type=int, default=None)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--relief", type=float, default=100.0)
    ap.add_argument("--pattern", type=int, default=5)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quality", action="store_true")
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--fixed-control", action="store_true")
    ap.add_argument("--pixel-mm", type=float, default=0.01)
    ap.add_argument("--function-tolerance", type=float, default=1e-10)
    ap.add_argument("--threads", type=int, default=-1)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    from baarda.simulate.aerial import simulate_block

    plan = block_plan(args.photos, args.strips, args.relief, args.seed, args.pattern)
    block, _ = simulate_block(plan)
    args.out.mkdir(parents=True, exist_ok=True)
    run = run_baarda if args.engine == "baarda" else run_pycolmap
    rec = run(args, block, args.out)
    rec["block"] = block.summary()
    rec["strips"], rec["photos_per_strip"] = plan.strips, plan.photos_per_strip
    (args.out / f"{args.engine}.json").write_text(json.dumps(rec, indent=1, default=str))


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    main()
