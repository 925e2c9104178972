"""Issue 40's rows that fit a shared machine, in one run: each command a process, its wall
time, CPU time (user + system, children included) and peak resident memory; baarda and
pycolmap alternate, the median of --repeat.

    PYTHONPATH=$PWD python benchmarks/bench_issue40.py --repeat 3

* the whole `baarda adjust` of BAL Ladybug-49 (`--calibrate none`, the options of
  bench_issue16.whole_command) against pycolmap_bal_user.py (reads and solves);
* the BAL-scale problem of 100 cameras (bench_bal_scale.simulate, f, k1, k2 free): the whole
  `baarda adjust FILE -o OUT -q` (read, adjust, statistics of every observation, write)
  against pycolmap's process that reads and solves (bench_bal_scale.worker_pycolmap);
* the README's demo (`--snoop`) with an empty numba cache: with the package's compiled
  kernels (linalg/kernel_bundle.py) and without them (BAARDA_KERNEL_BUNDLE=0: compiled).

CPU time is given beside the wall time because on a machine shared with other work the wall
time of a process is mostly its wait for a core (the load average is printed).
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
LADYBUG = Path("/work/shared/data/bal/problem-49-7776-pre.txt.bz2")
sys.path.insert(0, str(HERE))


def measure(cmd: list[str], env: dict | None = None) -> dict:
    """One process: wall s, CPU s (user + system), peak MB."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env={**os.environ, **(env or {})}, cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, ru = os.wait4(proc.pid, 0)
    rc = os.waitstatus_to_exitcode(status)
    if rc not in (0, 3):
        raise SystemExit(f"{' '.join(cmd)}: exit {rc}")
    return {"wall": time.perf_counter() - t0, "cpu": ru.ru_utime + ru.ru_stime,
            "peak": ru.ru_maxrss / 1024}


def median(runs: list[dict]) -> dict:
    return {k: statistics.median(r[k] for r in runs) for k in runs[0]}


def pair(name: str, ours: list[str], theirs: list[str], repeat: int,
         before=None) -> tuple[str, dict, dict]:
    a, b = [], []
    for _ in range(repeat):
        if before:
            before()
        a.append(measure(ours))
        b.append(measure(theirs))
    return name, median(a), median(b)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--rows", nargs="*", default=["ladybug", "scale100", "first"],
                    choices=["ladybug", "scale100", "first"])
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="issue40-"))
    out = tmp / "run"
    py = sys.executable
    load0 = " ".join(Path("/proc/loadavg").read_text().split()[:3])
    rows = []

    def clean():
        shutil.rmtree(out, ignore_errors=True)

    if "ladybug" in args.rows:
        rows.append(pair("BAL Ladybug-49: whole `baarda adjust` (--calibrate none) vs "
                         "pycolmap_bal_user.py", [py, "-m", "baarda", "adjust", str(LADYBUG),
                                                  "-o", str(out), "-q", "--calibrate", "none"],
                         [py, str(HERE / "pycolmap_bal_user.py"), str(LADYBUG)], args.repeat,
                         clean))
    if "scale100" in args.rows:
        from bench_bal_scale import simulate, write

        path = tmp / "problem-100-sim.txt"
        write(simulate(100), path)
        rows.append(pair("BAL scale 100 cameras: whole `baarda adjust` vs pycolmap's "
                         "process (read, solve)",
                         [py, "-m", "baarda", "adjust", str(path), "-o", str(out), "-q"],
                         [py, str(HERE / "bench_bal_scale.py"), "--worker", "pycolmap",
                          str(path), str(tmp / "p.json")], args.repeat, clean))
    if "first" in args.rows:
        runs = {}
        for label, env in (("bundle", {}), ("compiled", {"BAARDA_KERNEL_BUNDLE": "0"})):
            cache = tmp / f"cache-{label}"
            clean()
            runs[label] = measure([py, "-m", "baarda", "adjust", str(ROOT / "examples" / "demo"),
                                   "-o", str(out), "--snoop", "-q"],
                                  {**env, "NUMBA_CACHE_DIR": str(cache)})
        rows.append(("README demo, empty numba cache: with the package's compiled kernels "
                     "vs compiling them (BAARDA_KERNEL_BUNDLE=0)", runs["bundle"],
                     runs["compiled"]))
    load1 = " ".join(Path("/proc/loadavg").read_text().split()[:3])
    print(f"\n{os.cpu_count()} CPUs, load average {load0} before, {load1} after; median of "
          f"{args.repeat}")
    print("| row | baarda wall s | baarda CPU s | baarda peak MB | other wall s | other CPU s "
          "| other peak MB | wall ratio | CPU ratio | peak ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, a, b in rows:
        print(f"| {name} | {a['wall']:.2f} | {a['cpu']:.2f} | {a['peak']:.0f} | "
              f"{b['wall']:.2f} | {b['cpu']:.2f} | {b['peak']:.0f} | "
              f"{a['wall'] / b['wall']:.2f} | {a['cpu'] / b['cpu']:.2f} | "
              f"{a['peak'] / b['peak']:.2f} |")
    shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
