"""`baarda compile`: compile the numerical kernels into numba's cache now (linalg/precompile.py),
e.g. after `pip install` in a container image, so that no later run waits for the compiler."""

from __future__ import annotations

import time

HELP = "compile the numerical kernels into numba's cache now (after installing)"


def register(sub) -> None:
    p = sub.add_parser("compile", help=HELP, description=HELP + "; a run that finds them "
                       "missing compiles them itself")
    p.add_argument("-j", "--jobs", type=int, default=None,
                   help="processes (default: the CPUs this process may use, at most 8)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=run_compile)


def run_compile(args) -> int:
    from numba.core import config

    from baarda.linalg.precompile import compile_kernels, pending_kernels

    todo = pending_kernels()
    if not todo:
        if not args.quiet:
            print(f"every kernel is compiled already (numba's cache: "
                  f"{config.CACHE_DIR or 'beside the package'})")
        return 0
    t0 = time.perf_counter()
    failed = compile_kernels(jobs=args.jobs, entries=todo)
    if failed:
        print(f"could not compile {len(failed)} kernel(s): {', '.join(failed)}; the runs "
              "will compile them when they need them")
        return 1
    if not args.quiet:
        print(f"compiled {len(todo)} kernels in {time.perf_counter() - t0:.1f} s (numba's "
              f"cache: {config.CACHE_DIR or 'beside the package'})")
    return 0
