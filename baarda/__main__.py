"""`python -m baarda` and the `baarda` script: the command line (baarda.cli.main), with what
must hold before it is even imported: closed standard streams replaced by the null device
(so that no file the run opens takes their place, and no print fails), Ctrl-C during the
imports and a second Ctrl-C while the first is handled end the process with 130 and one
line, and running out of memory (ulimit -v) is exit 4 with one line (under a small limit
the numerical libraries run one thread each: SMALL_ADDRESS_SPACE)."""

import os
import signal
import sys

INTERRUPTED, WRITE_FAILED = 130, 4
MESSAGE = "\nbaarda: interrupted (nothing of this run was written)"


def _say(text: str) -> None:
    try:
        print(text, file=sys.stderr, flush=True)
    except (OSError, ValueError, AttributeError, MemoryError):
        pass


def closed_streams() -> list[str]:
    """Put the null device where a standard stream is closed (`baarda ... >&-`: Python makes
    it None); the names of those that were."""
    closed = []
    for name, mode in (("stdin", "r"), ("stdout", "w"), ("stderr", "w")):
        if getattr(sys, name) is None:
            setattr(sys, name, open(os.devnull, mode, encoding="utf-8"))  # noqa: SIM115
            closed.append(name)
    return closed


#: below this address space (ulimit -v, bytes) the numerical libraries run one thread each:
#: a thread's stack and arena reserve address space, and a thread that cannot get it aborts
#: the process in C (no Python error to report)
SMALL_ADDRESS_SPACE = 2 * 2**30


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


def _interrupted() -> int:
    try:  # a second Ctrl-C now is the same request
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except (ValueError, OSError):
        pass
    _say(MESSAGE)
    return INTERRUPTED


def run(argv: list[str] | None = None) -> int:
    """Run the command line (module docstring); the exit code."""
    try:
        try:
            closed = closed_streams()
            if address_space() < SMALL_ADDRESS_SPACE:  # each thread reserves memory
                for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
                             "NUMBA_NUM_THREADS"):
                    os.environ.setdefault(name, "1")
            from baarda.cli import main

            return main(argv, closed=closed)
        except KeyboardInterrupt:
            return _interrupted()
        except MemoryError:  # while importing the command line
            _say(f"baarda: error: out of memory{memory_limit_text()}")
            return WRITE_FAILED
        except ImportError as e:
            if not out_of_memory(e):
                raise
            _say(f"baarda: error: out of memory{memory_limit_text()}: {e}")
            return WRITE_FAILED
    except KeyboardInterrupt:  # a second Ctrl-C while the first was handled
        return _interrupted()


if __name__ == "__main__":
    sys.exit(run())
