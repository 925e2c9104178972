"""Issue 16 in one run: every row of its table, baarda and pycolmap measured side by side.

    PYTHONPATH=$PWD python benchmarks/bench_issue16.py [--repeat 5] [--out FILE.md]

Rows: the aerial block of 1000 photos with 5x5 and 15x15 points per photo (adjust, and
adjust + the statistics of every observation, against pycolmap's BA: bench_quality.py's
workers, each engine in its own process); the three BAL problems' core solve with the
intrinsics fixed and (Trafalgar, Dubrovnik) estimated (bench_bal.py); the whole `baarda adjust
FILE -o OUT -q --calibrate none` on Ladybug-49 against a pycolmap user's script that reads the
file and solves (pycolmap_bal_user.py), both timed as processes; `import baarda` and `baarda
--help`; the first run of the README's demo with an empty numba cache.  Each line says whether
the final costs agree to 1e-10.  The scale and output rows come from bench_scale.py (minutes;
not repeated here).  Prints a Markdown table (and writes it to --out).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import bench_bal  # noqa: E402
import common  # noqa: E402

LADYBUG = bench_bal.DEFAULT / bench_bal.FILES[0]


def _wall(cmd: list[str], env: dict | None = None, repeat: int = 5,
          before=None) -> tuple[float, str]:
    """Median wall time of a process (and its last output line)."""
    times, out = [], ""
    for _ in range(repeat):
        if before:
            before()
        t0 = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT,
                           env={**os.environ, **(env or {})})
        times.append(time.perf_counter() - t0)
        if p.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode}): {p.stderr[-2000:]}")
        out = (p.stdout.strip().splitlines() or [""])[-1]
    return statistics.median(times), out


def aerial(pattern: int, repeat: int) -> list[tuple]:
    args = common.parser("").parse_args(["--repeat", str(repeat), "--keep-numba-cache",
                                         "--pattern", str(pattern)])
    recs = common.run_engines(args, quality=True)
    a, p = recs["baarda"], recs["pycolmap"]
    ta = common.med([r["adjust_s"] for r in a["runs"]])
    tt = common.med([r["adjust_s"] + r["assess_s"] for r in a["runs"]])
    tp = common.med([r["seconds"] for r in p["runs"]])
    rel = abs(a["final_vtpv"] - p["final_vtpv"]) / a["final_vtpv"]
    name = f"aerial 1,000 photos, {pattern}x{pattern} points ({a['n_observations']:,} comp.)"
    return [(f"{name}: adjust", ta, tp, 0.5, rel, f"{a['iterations']} GN / {p['iterations']} LM"),
            (f"{name}: adjust + statistics of every observation", tt, tp, 0.8, rel, "")]


def bal(repeat: int) -> list[tuple]:
    rows = []
    for refine in (False, True):
        for k, name in enumerate(bench_bal.FILES):
            if refine and "49-" in name:  # diverges in both programs (benchmarks/README.md)
                continue
            r = bench_bal.measure(bench_bal.DEFAULT / name, refine, repeat, warm=k == 0)
            rel = abs(r["cost"] - r["colmap_cost"]) / r["colmap_cost"]
            what = "f, k1, k2 free" if refine else "intrinsics fixed"
            rows.append((f"BAL {name.split('-pre')[0]}, core solve, {what}", r["seconds"],
                         r["colmap_seconds"], 1.0, rel,
                         f"{r['iterations']} / {r['colmap_iterations']} it."))
    return rows


def whole_command(repeat: int) -> tuple:
    out = Path(tempfile.mkdtemp(prefix="b16-"))
    target = out / "run"

    def clean():
        shutil.rmtree(target, ignore_errors=True)

    baarda = shutil.which("baarda") or "baarda"
    t_b, _ = _wall([baarda, "adjust", str(LADYBUG), "-o", str(target), "-q", "--calibrate",
                    "none"], repeat=repeat, before=clean)
    t_p, line = _wall([sys.executable, str(HERE / "pycolmap_bal_user.py"), str(LADYBUG)],
                      repeat=repeat)
    import json

    cost = 0.5 * json.loads((target / "summary.json").read_text())["vtpv"]
    colmap = float(line.split()[-1])
    shutil.rmtree(out, ignore_errors=True)
    return ("BAL Ladybug-49, whole `baarda adjust FILE -o OUT -q` (read, adjust, statistics, "
            "write) vs a pycolmap script that reads and solves", t_b, t_p, 2.0,
            abs(cost - colmap) / colmap, "processes")


def startup(repeat: int) -> list[tuple]:
    baarda = shutil.which("baarda") or "baarda"
    t_imp, _ = _wall([sys.executable, "-c", "import baarda"], repeat=repeat)
    t_help, _ = _wall([baarda, "--help"], repeat=repeat)
    t_py, _ = _wall([sys.executable, "-c", "pass"], repeat=repeat)
    return [("`import baarda` (process; bare interpreter "
             f"{t_py:.2f} s)", t_imp, None, 0.3, None, "s, target absolute"),
            ("`baarda --help` (process)", t_help, None, 0.4, None, "s, target absolute")]


def first_run() -> tuple:
    cache = Path(tempfile.mkdtemp(prefix="b16-numba-"))
    out = Path(tempfile.mkdtemp(prefix="b16-demo-")) / "run"
    baarda = shutil.which("baarda") or "baarda"
    t, _ = _wall([baarda, "adjust", "examples/demo", "-o", str(out), "--snoop", "-q"],
                 env={"NUMBA_CACHE_DIR": str(cache)}, repeat=1)
    shutil.rmtree(cache, ignore_errors=True)
    shutil.rmtree(out.parent, ignore_errors=True)
    return ("first run of the README's demo, empty numba cache (compile in parallel "
            f"processes on {len(os.sched_getaffinity(0))} CPUs)", t, None, 5.0, None,
            "s, 'a few seconds'")


def table(rows: list[tuple]) -> str:
    lines = ["| work | baarda s | pycolmap s | ratio | target | met | costs equal | note |",
             "|---|---|---|---|---|---|---|---|"]
    for name, tb, tp, target, rel, note in rows:
        ratio = tb / tp if tp else tb
        met = "yes" if ratio <= target else "no"
        eq = "-" if rel is None else (f"yes ({rel:.0e})" if rel <= 1e-10 else f"NO ({rel:.0e})")
        lines.append(f"| {name} | {tb:.3f} | {'' if tp is None else f'{tp:.3f}'} | "
                     f"{'' if tp is None else f'{ratio:.2f}'} | {target:g} | {met} | {eq} | "
                     f"{note} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--skip", nargs="*", default=[],
                    choices=["aerial5", "aerial15", "bal", "whole", "startup", "first"])
    args = ap.parse_args(argv)
    rows: list[tuple] = []
    t0 = time.perf_counter()
    load = " ".join(Path("/proc/loadavg").read_text().split()[:3])
    steps = [("aerial5", lambda: aerial(5, args.repeat)),
             ("aerial15", lambda: aerial(15, max(3, args.repeat // 2))),
             ("bal", lambda: bal(args.repeat)),
             ("whole", lambda: [whole_command(args.repeat)]),
             ("startup", lambda: startup(args.repeat)),
             ("first", lambda: [first_run()])]
    for key, step in steps:
        if key not in args.skip:
            print(f"measuring {key} ...", file=sys.stderr, flush=True)
            rows += step()
    text = (f"{table(rows)}\n\n{len(os.sched_getaffinity(0))} CPUs, load average {load} "
            f"before; {time.perf_counter() - t0:.0f} s in all; median of {args.repeat} "
            "(the 15x15 block: of fewer).\n")
    print(text)
    if args.out:
        args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
