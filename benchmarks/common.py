"""Run baarda and pycolmap on the same simulated block, each in its own process.

Shared by bench_bundle.py (issue 2) and bench_quality.py (issue 3).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def parser(description: str) -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--photos", type=int, default=1000, help="photos in the block (1000)")
    ap.add_argument("--strips", type=int, default=None,
                    help="strips (default: 20 for 1000 photos, about photos/2.5 per strip)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per engine (3)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--relief", type=float, default=100.0, help="terrain relief amplitude, m")
    ap.add_argument("--pattern", type=int, default=5,
                    help="points per photo: a PATTERN x PATTERN grid (5; 15 for a dense block)")
    ap.add_argument("--fixed-control", action="store_true",
                    help="pycolmap: hold control points constant even if pyceres is there")
    ap.add_argument("--threads", type=int, default=-1,
                    help="Ceres threads (-1: pycolmap's own choice)")
    ap.add_argument("--keep-numba-cache", action="store_true",
                    help="use numba's normal cache (first call loads it) instead of a fresh, "
                         "empty cache folder (first call compiles)")
    ap.add_argument("--blas-threads", type=int, default=None,
                    help="set OPENBLAS_NUM_THREADS and OMP_NUM_THREADS for both engines "
                         "(default: the environment as it is)")
    ap.add_argument("--profile", action="store_true",
                    help="also profile baarda (cProfile, top 25 by cumulative time)")
    ap.add_argument("--out", type=Path, default=None, help="keep the raw results here")
    return ap


def _spawn(cmd: list[str], env: dict) -> tuple[int, float, float]:
    """Run cmd; returns (exit code, wall s, max RSS of the child in MB)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, cwd=ROOT)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return proc.returncode, time.perf_counter() - t0, usage.ru_maxrss / 1024.0


def run_engines(args, quality: bool) -> dict:
    """Both engines on the block of `args`; returns their records and the comparison."""
    out = args.out or Path(tempfile.mkdtemp(prefix="baarda-bench-"))
    out.mkdir(parents=True, exist_ok=True)
    common = ["--photos", str(args.photos), "--repeat", str(args.repeat), "--seed",
              str(args.seed), "--relief", str(args.relief), "--out", str(out),
              "--pattern", str(getattr(args, "pattern", 5))]
    if args.strips:
        common += ["--strips", str(args.strips)]
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), str(HERE)]
                                        + [p for p in [env.get("PYTHONPATH")] if p])
    if args.blas_threads:
        env["OPENBLAS_NUM_THREADS"] = env["OMP_NUM_THREADS"] = str(args.blas_threads)
    recs = {"load_before": _loadavg(), "blas_threads": env.get("OPENBLAS_NUM_THREADS",
                                                                "unset (all cores)")}
    for engine in ("baarda", "pycolmap"):
        cmd = [sys.executable, str(HERE / "worker.py"), engine] + common
        e = dict(env)
        if engine == "baarda":
            if quality:
                cmd.append("--quality")
            if args.profile:
                cmd.append("--profile")
            if not args.keep_numba_cache:
                e["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="numba-", dir=out)
        else:
            cmd += ["--threads", str(args.threads)]
            if args.fixed_control:
                cmd.append("--fixed-control")
        print(f"running {engine} on {args.photos} photos ...", file=sys.stderr, flush=True)
        code, wall, maxrss = _spawn(cmd, e)
        if code != 0:
            raise SystemExit(f"{engine} worker failed (exit {code})")
        rec = json.loads((out / f"{engine}.json").read_text())
        rec["process_max_rss_mb"] = maxrss
        rec["process_wall_s"] = wall
        recs[engine] = rec
    a, b = np.load(out / "baarda.npz"), np.load(out / "pycolmap.npz")
    recs["diff"] = {
        "centre_m": float(np.max(np.abs(a["eo"][:, :3] - b["eo"][:, :3]))),
        "angle_rad": float(np.max(np.abs(np.angle(np.exp(1j * (a["eo"][:, 3:]
                                                               - b["eo"][:, 3:])))))),
        "point_m": float(np.max(np.abs(a["xyz"] - b["xyz"]))),
    }
    recs["out"] = str(out)
    recs["load_after"] = _loadavg()
    (out / "records.json").write_text(json.dumps(recs, indent=1, default=str))
    return recs


def _loadavg() -> str:
    try:
        with open("/proc/loadavg") as fh:
            return " ".join(fh.read().split()[:3])
    except OSError:
        return "?"


def med(values) -> float:
    return float(statistics.median(values))


def header(recs: dict, args) -> list[str]:
    a, p = recs["baarda"], recs["pycolmap"]
    return [
        f"block: {a['block']} ({a['strips']} strips x {a['photos_per_strip']} photos, 60 %/60 %"
        f" overlap, {args.pattern}x{args.pattern} points, relief {args.relief} m, seed "
        f"{args.seed})",
        f"observations {a['n_observations']} (image components + control coordinates), "
        f"unknowns {a['n_unknowns']}, redundancy {a['redundancy']}",
        f"pycolmap {p['control']} control; Ceres {p['linear_solver']}, {p['threads']} "
        f"thread(s), function_tolerance 1e-10; conversion check: projections agree to "
        f"{p['projection_check_px']:.1e} px, initial v'Pv baarda {p['baarda_initial_vtpv']:.6e} "
        f"/ Ceres {p['initial_vtpv']:.6e}",
        f"timed runs per engine: {args.repeat} (median shown, min in brackets); memory: RSS "
        "growth during the first timed call / max RSS of the whole engine process",
        f"machine: {os.cpu_count()} cores, load average {recs['load_before']} before, "
        f"{recs['load_after']} after; OPENBLAS_NUM_THREADS {recs['blas_threads']}; numba "
        f"{'cache as found' if args.keep_numba_cache else 'compiled afresh (empty cache)'}",
    ]


def agreement(recs: dict) -> list[str]:
    a, p, d = recs["baarda"], recs["pycolmap"], recs["diff"]
    rel = abs(a["final_vtpv"] - p["final_vtpv"]) / a["final_vtpv"]
    return [
        f"final v'Pv (sum of squared normalised residuals): baarda {a['final_vtpv']:.10g}, "
        f"pycolmap {p['final_vtpv']:.10g} (relative difference {rel:.1e}; pycolmap's solution "
        f"in baarda's equations {p['baarda_vtpv_of_solution']:.10g})",
        f"largest difference of the solutions: projection centres {d['centre_m']:.2e} m, "
        f"angles {d['angle_rad']:.2e} rad, points {d['point_m']:.2e} m",
    ] + ([] if p["control"].startswith("weighted") else [
        "NOTE: pycolmap held the control points fixed (pyceres missing or --fixed-control): "
        "its objective differs from baarda's (no control residuals, height-only points "
        "free), so the costs and solutions are not expected to agree"])


def table(rows: list[list[str]]) -> str:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = []
    for k, r in enumerate(rows):
        lines.append("  ".join(c.ljust(w) if i == 0 else c.rjust(w)
                               for i, (c, w) in enumerate(zip(r, widths, strict=True))))
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def fmt_t(values) -> str:
    return f"{med(values):.3f} ({min(values):.3f})"


def profiles(recs: dict) -> str:
    out = Path(recs["out"])
    text = []
    for name in ("profile_adjust.txt", "profile_assess.txt"):
        f = out / name
        if f.exists():
            text.append(f"--- {name} (cProfile, sorted by cumulative time) ---\n"
                        + f.read_text())
    return "\n".join(text)
