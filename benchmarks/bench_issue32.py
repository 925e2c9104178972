"""Issue 32 in one run: every row of its table, baarda and pycolmap side by side.

    PYTHONPATH=$PWD python benchmarks/bench_issue32.py [--repeat 5] [--scale 100 256 1000]
                                                       [--out FILE.md]

Rows (each engine in its own process; the median of --repeat runs, the BAL-scale rows of
--scale-repeat):

* BAL scale (bench_bal_scale.py): simulated BAL problems with a camera per photo, f, k1, k2
  free; baarda reads, adjusts and computes the statistics of every observation, pycolmap
  reads and solves (refining f and k1, k2).  Two rows per size: the whole processes (wall
  time, peak memory), and baarda's adjustment + statistics against pycolmap's solve alone
  (the issue's target: at most pycolmap's time and memory);
* BAL core solve, intrinsics fixed and free (bench_bal.py, in this process as before);
* the whole `baarda adjust` of Ladybug-49 against pycolmap_bal_user.py (processes);
* the aerial block of 1000 photos, 5 x 5 points: adjust, and adjust + statistics;
* the first run of the README's demo with an empty numba cache.

Each row says whether the final costs agree to 1e-10.  Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bench_bal_scale  # noqa: E402
import bench_issue16  # noqa: E402


def bal_scale(sizes: list[int], repeat: int, folder: Path) -> list[tuple]:
    rows = []
    for n in sizes:
        path = folder / f"problem-{n}-sim.txt"
        if not path.exists():
            bench_bal_scale.write(bench_bal_scale.simulate(n), path)
        runs: dict[str, list[dict]] = {"baarda": [], "pycolmap": []}
        for _ in range(repeat):  # interleaved
            for engine in runs:
                rec = bench_bal_scale._spawn(engine, path, folder / f"{engine}-{n}.json")
                if "failed" in rec:
                    raise SystemExit(f"{engine} failed on {path.name}: {rec}")
                runs[engine].append(rec)
        a, p = runs["baarda"], runs["pycolmap"]

        def med(recs, *keys):
            return statistics.median(sum(r[k] for k in keys) for r in recs)

        rel = abs(a[-1]["cost"] - p[-1]["cost"]) / p[-1]["cost"]
        obs = a[-1]["observations"]
        name = f"BAL scale, {n} cameras ({obs:,} comp.), f, k1, k2 free"
        rows.append((f"{name}: whole processes (baarda: read, adjust, statistics of every "
                     "observation; pycolmap: read, solve)", med(a, "wall_s"), med(p, "wall_s"),
                     None, rel, f"peak {med(a, 'peak_mb'):.0f} / {med(p, 'peak_mb'):.0f} MB; "
                     f"{a[-1]['iterations']} / {p[-1]['iterations']} it."))
        rows.append((f"{name}: baarda adjust + statistics vs pycolmap's solve alone",
                     med(a, "adjust_s", "assess_s"), med(p, "solve_s"), 1.0, rel,
                     f"memory: {med(a, 'peak_mb') / med(p, 'peak_mb'):.2f} x pycolmap's "
                     "process peak" + ("" if a[-1]["converged"] else
                                       "; baarda NOT converged")))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--scale", type=int, nargs="*", default=[100, 256, 1000])
    ap.add_argument("--scale-repeat", type=int, default=3)
    ap.add_argument("--folder", type=Path, default=None, help="the simulated BAL files")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--skip", nargs="*", default=[],
                    choices=["scale", "bal", "whole", "aerial5", "first"])
    args = ap.parse_args(argv)
    folder = args.folder or Path(tempfile.mkdtemp(prefix="bal-scale-"))
    folder.mkdir(parents=True, exist_ok=True)
    load = " ".join(Path("/proc/loadavg").read_text().split()[:3])
    t0 = time.perf_counter()
    steps = [("scale", lambda: bal_scale(args.scale, args.scale_repeat, folder)),
             ("bal", lambda: bench_issue16.bal(args.repeat)),
             ("whole", lambda: [bench_issue16.whole_command(args.repeat)]),
             ("aerial5", lambda: bench_issue16.aerial(5, args.repeat)),
             ("first", lambda: [bench_issue16.first_run()])]
    rows: list[tuple] = []
    for key, step in steps:
        if key not in args.skip:
            print(f"measuring {key} ...", file=sys.stderr, flush=True)
            rows += step()
    rows = [(n, tb, tp, 0.0 if target is None else target, rel, note)
            for n, tb, tp, target, rel, note in rows]
    text = bench_issue16.table(rows).replace("| 0 | no |", "| - | - |").replace(
        "| 0 | yes |", "| - | - |")
    text += (f"\n\n{len(os.sched_getaffinity(0))} CPUs, load average {load} before; "
             f"{time.perf_counter() - t0:.0f} s in all; median of {args.repeat} (BAL scale: "
             f"of {args.scale_repeat}).\n")
    print(text)
    if args.out:
        args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
