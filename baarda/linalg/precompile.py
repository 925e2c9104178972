"""Compile the numba kernels once, in parallel processes, before the first run needs them.

Numba compiles a kernel when it is first called, one after the other under its compiler
lock: about 12 s of CPU on a first run of the demo.  Each kernel's code goes into numba's
cache (one index file per kernel), so independent processes can compile different kernels
at the same time.  :func:`compile_kernels` spreads the kernels whose cache is missing over
the CPUs by their measured compile time (longest first), compiles its own share of the
serial kernels in this process and the rest in child processes (``python -m
baarda.linalg.precompile``), and waits for them; whatever a child could not compile is
compiled on demand as before.  Kernels with ``parallel=True`` are compiled in children
only: compiling them starts numba's thread pool, after which this process could not fork.

The kernels and their argument types are data (:data:`TABLE_FILE`, written by
``python -m baarda.cli.compile --record`` from an adjustment's workload;
``tests/linalg/test_precompile.py`` checks it against the types that workload compiles).
"""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ._jit import is_cached

__all__ = ["TABLE_FILE", "compile_kernels", "pending_kernels", "signature_spec",
           "spec_signature"]

TABLE_FILE = Path(__file__).with_name("kernel_signatures.json")


# ------------------------------------------------------------------ argument types as text
def signature_spec(sig: Iterable[Any]) -> list[str]:
    """numba argument types as text: ``float64[3C]`` (array: dtype, ndim, layout, ``r`` when
    read-only) or the scalar's name (``int64``)."""
    from numba.core import types

    out = []
    for t in sig:
        if isinstance(t, types.Array):
            out.append(f"{t.dtype}[{t.ndim}{t.layout}{'' if t.mutable else 'r'}]")
        elif isinstance(t, (types.Integer, types.Float, types.Boolean)):
            out.append(str(t))
        else:
            raise ValueError(f"no text form for the argument type {t}")
    return out


def spec_signature(spec: Iterable[str]) -> tuple[Any, ...]:
    """The inverse of :func:`signature_spec`."""
    from numba.core import types

    out = []
    for s in spec:
        if s.endswith("]"):
            name, rest = s[:-1].split("[")
            ndim, layout, readonly = int(rest[0]), rest[1], rest.endswith("r")
            out.append(types.Array(getattr(types, name), ndim, layout, readonly=readonly))  # type: ignore[call-overload]
        else:
            out.append(getattr(types, s))
    return tuple(out)


# ------------------------------------------------------------------ the table
def load_table() -> list[dict]:
    """Kernels: ``{"module", "name", "parallel", "seconds", "signatures": [[spec...]]}``."""
    try:
        return json.loads(TABLE_FILE.read_text(encoding="utf-8"))["kernels"]
    except (OSError, ValueError, KeyError):
        return []


def _dispatcher(entry: dict):
    return getattr(importlib.import_module(entry["module"]), entry["name"])


def pending_kernels(parallel: bool = True) -> list[dict]:
    """The table's kernels that have no code in numba's cache yet (with `parallel`, also the
    multi-threaded ones)."""
    out = []
    for entry in load_table():
        if entry.get("parallel") and not parallel:
            continue
        try:
            disp = _dispatcher(entry)
        except (ImportError, AttributeError):
            continue
        if not is_cached(disp):
            out.append(entry)
    return out


def _compile(entries: list[dict]) -> list[str]:
    """Compile the entries' signatures in this process; the names that failed."""
    failed = []
    for entry in entries:
        try:
            disp = _dispatcher(entry)
            for spec in entry["signatures"]:
                disp.compile(spec_signature(spec))
        except Exception:  # noqa: BLE001 - the run compiles it on demand instead
            failed.append(f"{entry['module']}.{entry['name']}")
    return failed


def _bins(entries: list[dict], n: int) -> list[list[dict]]:
    """Longest compile first, each to the least loaded bin; bin 0 (this process) takes no
    parallel kernel."""
    loads = [0.0] * n
    bins: list[list[dict]] = [[] for _ in range(n)]
    for entry in sorted(entries, key=lambda e: -float(e.get("seconds", 1.0))):
        choices = range(1, n) if entry.get("parallel") and n > 1 else range(n)
        k = min(choices, key=lambda i: (loads[i], i))
        loads[k] += float(entry.get("seconds", 1.0))
        bins[k].append(entry)
    return bins


def compile_kernels(jobs: int | None = None, parallel: bool = True,
                    entries: list[dict] | None = None, in_process: bool = True) -> list[str]:
    """Compile the kernels that are not cached yet with `jobs` processes (default: the CPUs
    this process may use, at most 8); returns the names that could not be compiled (the run
    compiles those on demand).  With one job nothing is done in advance unless `entries`
    are given.  `parallel`: also the multi-threaded kernels (large blocks use them).
    `in_process` False: every kernel in a child process (under a memory limit LLVM aborts
    the process that runs out, with no Python error: then a child, not this one)."""
    todo = pending_kernels(parallel) if entries is None else list(entries)
    if not todo:
        return []
    if jobs is None:
        try:
            jobs = len(os.sched_getaffinity(0))
        except AttributeError:  # pragma: no cover - not Linux
            jobs = os.cpu_count() or 1
        jobs = min(jobs, 8)
        if jobs < 2 and entries is None:  # nothing gained: the run compiles on demand
            return []
    jobs = max(1, min(int(jobs), len(todo)))
    if any(e.get("parallel") for e in todo):
        jobs = max(jobs, 2)  # parallel kernels never compile in this process
    bins = _bins(todo, jobs)
    env = dict(os.environ)
    from numba.core import config

    # the same cache (e.g. the fallback folder of _jit.kernel)
    if config.CACHE_DIR:  # type: ignore[attr-defined]
        env["NUMBA_CACHE_DIR"] = str(config.CACHE_DIR)  # type: ignore[attr-defined]
    children = []
    failed: list[str] = []
    try:
        for part in (bins if not in_process else bins[1:]):
            if part:
                children.append((part, subprocess.Popen(
                    [sys.executable, "-m", "baarda.linalg.precompile", "--compile"],
                    stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                    env=env, text=True)))
                assert children[-1][1].stdin is not None  # stdin=PIPE
                children[-1][1].stdin.write(json.dumps(part))
                children[-1][1].stdin.close()
        if in_process:
            failed += _compile(bins[0])
        for part, proc in children:
            assert proc.stdout is not None  # stdout=PIPE
            out = proc.stdout.read()
            if proc.wait() != 0:
                failed += [f"{e['module']}.{e['name']}" for e in part]
            else:
                failed += json.loads(out or "[]")
    finally:
        for _, proc in children:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    return failed


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--compile"]:
        print(json.dumps(_compile(json.loads(sys.stdin.read()))))
        return 0
    print("usage: python -m baarda.linalg.precompile --compile < JSON", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
