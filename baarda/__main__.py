"""`python -m baarda` and the `baarda` script: the command line (baarda.cli.main), with what
must hold before it is even imported: closed standard streams replaced by the null device
(so that no file the run opens takes their place, and no print fails), Ctrl-C during the
imports and a second Ctrl-C while the first is handled end the process with 130 and one
line, and running out of memory (ulimit -v) is exit 4 with one line (under a small limit
the numerical libraries run one thread each: SMALL_ADDRESS_SPACE)."""

import os
import signal
import sys

from baarda.process import (
    INTERRUPTED,
    MIN_ADDRESS_SPACE,
    SMALL_ADDRESS_SPACE,
    TERMINATED,
    WRITE_FAILED,
    address_space,
    closed_streams,
    memory_limit_text,
    out_of_memory,
    quiet_unraisable_memory_errors,
)

MESSAGE = "\nbaarda: interrupted (nothing of this run was written)"


def _say(text: str) -> None:
    try:
        print(text, file=sys.stderr, flush=True)
    except (OSError, ValueError, AttributeError, MemoryError):
        pass


def _ignore_interrupts() -> None:
    """A later Ctrl-C is the same request: ignored until the process ends (else one that
    comes while Python shuts down, in its threads' exit hooks, prints a traceback)."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except (ValueError, OSError):
        pass


def _interrupted() -> int:
    _ignore_interrupts()  # a second Ctrl-C now is the same request
    _say(MESSAGE)
    return INTERRUPTED


def run(argv: list[str] | None = None) -> int:
    """Run the command line (module docstring); the exit code."""
    try:
        try:
            closed = closed_streams()
            if address_space() < MIN_ADDRESS_SPACE:
                _say(f"baarda: error: out of memory{memory_limit_text()}: baarda's libraries "
                     f"(NumPy, pandas, pyarrow, numba) need at least "
                     f"{MIN_ADDRESS_SPACE / 2**20:.0f} MB of address space to load; raise "
                     "the limit (ulimit -v)")
                return WRITE_FAILED
            if address_space() < float("inf"):
                quiet_unraisable_memory_errors()
            if address_space() < SMALL_ADDRESS_SPACE:  # each thread reserves memory
                for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
                             "NUMBA_NUM_THREADS"):
                    os.environ.setdefault(name, "1")
            from baarda.cli import main

            code = main(argv, closed=closed)
            if code in (INTERRUPTED, TERMINATED):  # said once, by the command line
                _ignore_interrupts()
            return code
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
