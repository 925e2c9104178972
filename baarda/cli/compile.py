"""`baarda compile`: compile the numerical kernels into numba's cache now (linalg/precompile.py),
e.g. after `pip install` in a container image, so that no later run waits for the compiler.

`python -m baarda.cli.compile --record` (with NUMBA_CACHE_DIR an empty folder) writes the
table of kernels and argument types that the compile covers, from an adjustment's workload;
`python -m baarda.cli.compile --bundle` compiles every kernel of that table in an empty cache
and writes the package's compiled kernels (linalg/kernel_bundle.py) from it: run it after a
kernel module changed (a stale bundle is ignored, and the first run compiles)."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from baarda.cli.argtypes import integer
from baarda.cli.common import add_quiet_option
from baarda.cli.console import console
from baarda.linalg.precompile import TABLE_FILE, signature_spec

HELP = "compile the numerical kernels into numba's cache now (after installing)"


def register(sub) -> None:
    p = sub.add_parser("compile", help=HELP, description=HELP + "; a run that finds them "
                       "missing compiles them itself")
    p.add_argument("-j", "--jobs", type=integer(1, 256), default=None,
                   help="processes (default: the CPUs this process may use, at most 8)")
    add_quiet_option(p, "report of what was compiled")
    p.set_defaults(func=run_compile)


def run_compile(args) -> int:
    from numba.core import config

    from baarda.linalg.precompile import compile_kernels, pending_kernels

    con = console(args)
    todo = pending_kernels()
    if not todo:
        con.print(f"every kernel is compiled already (numba's cache: "
                  f"{config.CACHE_DIR or 'beside the package'})")  # type: ignore[attr-defined]
        return 0
    t0 = time.perf_counter()
    failed = compile_kernels(jobs=args.jobs, entries=todo)
    if failed:
        print(f"could not compile {len(failed)} kernel(s): {', '.join(failed)}; the runs "
              "will compile them when they need them")
        return 1
    con.print(f"compiled {len(todo)} kernels in {time.perf_counter() - t0:.1f} s (numba's "
              f"cache: {config.CACHE_DIR or 'beside the package'})")  # type: ignore[attr-defined]
    return 0


def record_workload() -> None:
    """What the table must cover: the demo's adjustment with data snooping and its result
    folder (serial kernels, the CSV writer), a self-calibration (lens terms, the border's
    columns) and a block large enough for the multi-threaded kernels."""
    import tempfile

    from baarda.block.camera import with_calibration
    from baarda.output.bundle_results import write_results
    from baarda.output.run_folder import RunFolder
    from baarda.pipeline import adjust, assess, snoop
    from baarda.simulate.aerial import FlightPlan, simulate_block

    small, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=8, pattern=5, seed=3))
    qc = snoop(small)
    with tempfile.TemporaryDirectory() as tmp, RunFolder(Path(tmp) / "run") as run:
        write_results(run, qc)
    assess(adjust(with_calibration(small, "brown", "all")))
    large, _ = simulate_block(FlightPlan(strips=16, photos_per_strip=40, side_overlap=0.6,
                                          pattern=5, seed=3))
    assess(adjust(large))


def record(path: Path = TABLE_FILE) -> list[dict]:
    """Run the workload with an empty cache, then write each compiled kernel with its
    argument types and compile time (run with ``NUMBA_CACHE_DIR`` set to an empty folder)."""
    from numba.core import event

    from baarda.linalg._jit import KERNELS

    seconds: dict[int, float] = {}  # compiles started from Python (not inside another)
    stack: list[tuple[int, float]] = []

    class Timer(event.Listener):
        def on_start(self, ev):
            stack.append((id(ev.data["dispatcher"]), time.perf_counter()))

        def on_end(self, ev):
            key, t0 = stack.pop()
            if not stack:
                seconds[key] = seconds.get(key, 0.0) + time.perf_counter() - t0

    event.register("numba:compile", Timer())
    record_workload()
    rows = []
    for disp in KERNELS:
        if id(disp) not in seconds:  # compiled only inside other kernels, with them
            continue
        try:
            sigs = [signature_spec(s) for s in disp.signatures]
        except ValueError:
            continue
        module = sys.modules[disp.py_func.__module__]
        name = next((k for k, v in vars(module).items() if v is disp), None)
        if name is None:  # not reachable by a name of its module
            continue
        rows.append({"module": module.__name__, "name": name,
                     "parallel": bool(disp.targetoptions.get("parallel")),
                     "seconds": round(seconds.get(id(disp), 0.0), 3), "signatures": sigs})
    path.write_text(json.dumps({"kernels": rows}, indent=1) + "\n", encoding="utf-8")
    return rows


def bundle(path: Path | None = None) -> int:
    """Compile every kernel of the table into an empty cache (child processes, the package's
    bundle switched off) and write the bundle from that cache; the number of kernels in it."""
    import os
    import subprocess
    import tempfile

    from baarda.linalg.kernel_bundle import BUNDLE_FILE

    with tempfile.TemporaryDirectory(prefix="baarda-bundle-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "BAARDA_KERNEL_BUNDLE": "0"}
        script = ("import sys; from pathlib import Path\n"
                  "from baarda.linalg import precompile\n"
                  "from baarda.linalg._jit import KERNELS\n"
                  "from baarda.linalg.kernel_bundle import make_bundle\n"
                  "failed = precompile.compile_kernels(entries=precompile.load_table())\n"
                  "if failed: sys.exit('could not compile: ' + ', '.join(failed))\n"
                  "for e in precompile.load_table(): precompile._dispatcher(e)\n"
                  "print(make_bundle(KERNELS, Path(sys.argv[1])))\n")
        out = subprocess.run([sys.executable, "-c", script, str(path or BUNDLE_FILE)],
                             env=env, check=True, capture_output=True, text=True).stdout
    return int(out.split()[-1])


if __name__ == "__main__":
    if sys.argv[1:2] == ["--bundle"]:
        n = bundle(Path(sys.argv[2]) if len(sys.argv) > 2 else None)
        print(f"{n} kernels in the bundle")
        sys.exit(0)
    if sys.argv[1:2] != ["--record"]:
        sys.exit("usage: NUMBA_CACHE_DIR=EMPTY python -m baarda.cli.compile --record [FILE] | "
                 "--bundle [FILE]")
    rows = record(Path(sys.argv[2]) if len(sys.argv) > 2 else TABLE_FILE)
    print(f"{len(rows)} kernels, {sum(r['seconds'] for r in rows):.1f} s of compiling")
