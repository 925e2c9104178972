"""What a process of baarda needs before anything else is imported: the standard streams
(closed ones replaced by the null device), the memory limit (ulimit -v) it runs under and
the exit codes (used by __main__ and the command line; no import of baarda's own)."""

import os
import sys

# exit codes (the parser's epilog, README; cli/common.py and __main__ import them): 130 and
# 143 are 128 + the number of SIGINT and SIGTERM, as a shell reports a process those
# signals end
OK, BAD_INPUT, NOT_CONVERGED, WRITE_FAILED, INTERRUPTED, TERMINATED = 0, 2, 3, 4, 130, 143

#: below this address space (ulimit -v, bytes) the numerical libraries run one thread each:
#: a thread's stack and arena reserve address space, and a thread that cannot get it aborts
#: the process in C (no Python error to report)
SMALL_ADDRESS_SPACE = 2 * 2**30
#: below this address space not even the libraries load reliably: a C++ library (pyarrow's
#: thread pools, LLVM) may end the process with std::bad_alloc and no Python error (seen at
#: 300 MB, now and then), so the command line refuses to start
MIN_ADDRESS_SPACE = 768 * 2**20
#: below this address space the numerical kernels cannot run: numba's LLVM (or a C++
#: library) aborts the process with no Python error (measured: the demo's adjust aborts at
#: 977 MB with "LLVM ERROR: out of memory" or std::bad_alloc, fails with a Python
#: MemoryError at 1465 MB and runs at 1953 MB; at 1700 MB OpenBLAS' start-up, importing
#: scipy.special, retried its failing 32 MB buffer mmap for ever: a hang, not an error)
MIN_KERNEL_ADDRESS_SPACE = 2.0 * 2**30


def closed_streams() -> list[str]:
    """Put the null device where a standard stream is closed (`baarda ... >&-`: Python makes
    it None); the names of those that were."""
    closed = []
    for name, mode in (("stdin", "r"), ("stdout", "w"), ("stderr", "w")):
        if getattr(sys, name) is None:
            setattr(sys, name, open(os.devnull, mode, encoding="utf-8"))  # noqa: SIM115
            closed.append(name)
    return closed


def address_space() -> float:
    """The process's address-space limit in bytes (ulimit -v), inf when there is none."""
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    except (ImportError, OSError, ValueError, AttributeError):
        return float("inf")
    return float("inf") if soft == resource.RLIM_INFINITY else float(soft)


def memory_limit_text() -> str:
    """' (limit N MB, ulimit -v)' when the address space is limited, else ''."""
    soft = address_space()
    return "" if soft == float("inf") else f" (limit {soft / 2**20:.0f} MB, ulimit -v)"


def out_of_memory(e: BaseException) -> bool:
    """Whether `e` says that memory ran out: a MemoryError (also pyarrow's), an OSError
    ENOMEM, or an ImportError of a library that could not be mapped into memory."""
    if isinstance(e, MemoryError):
        return True
    if isinstance(e, OSError) and e.errno == 12:  # ENOMEM
        return True
    text = str(e).lower()
    return isinstance(e, ImportError) and ("memory" in text or "map segment" in text)


def quiet_unraisable_memory_errors() -> None:
    """Under a memory limit a MemoryError raised while a generator or object is finalised
    is 'ignored' by Python with a traceback on stderr: say nothing of it (the error that
    stops the run is reported), other such errors as before."""
    default = sys.unraisablehook

    def hook(unraisable) -> None:
        if isinstance(unraisable.exc_value, MemoryError) or \
                isinstance(getattr(unraisable.exc_value, "__context__", None), MemoryError):
            return
        default(unraisable)

    sys.unraisablehook = hook

