"""Command line: a thin layer over the API.  Each command lives in its own module with
`register(subparsers)`; the module list below is the only place that knows them all."""

from __future__ import annotations

import argparse
import errno
import importlib
import os
import signal
import sys
import threading
from contextlib import contextmanager

from baarda.cli.common import (
    BAD_INPUT,
    EXIT_CODES,
    INTERRUPTED,
    TERMINATED,
    WRITE_FAILED,
)
from baarda.cli.console import GuardedStdout, console
from baarda.errors import GeometryError, OutputError, ProjectError
from baarda.io.formats import titles  # the format registry (no reader imported)
from baarda.output.run_folder import package_version

#: errors of writing, never of reading: a full disk or quota, a file over the size limit
#: (ulimit -f), a read-only file system
WRITE_ERRNOS = {errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EROFS}

# every command: the module that registers it and its one-line help (what `baarda --help`
# shows without importing the commands; tests/cli/test_cli.py checks they agree)
COMMANDS = {
    "adjust": ("baarda.cli.adjust", "bundle block adjustment with observation statistics"),
    "snoop": ("baarda.cli.adjust", "bundle adjustment with iterative data snooping"),
    "simulate": ("baarda.cli.simulate", "simulate an aerial block with known truth"),
    "online": ("baarda.cli.online", "on-line QC: strip bridging model by model (relative "
               "orientation with scale transfer), or a bundle block tested measurement by "
               "measurement (--bundle, --replay)"),
    "pattern": ("baarda.cli.pattern", "point-pattern design for relative orientation with "
                "scale transfer (Kratky's Figures 2, 4, 7)"),
    "plan": ("baarda.cli.plan", "design-stage reliability of a planned block (no "
             "measurements): sqrt(qvv), MDB, external reliability, precision, advice"),
    "modified-snoop": ("baarda.cli.plan", "Gruen's modified data snooping: approximate "
                       "sqrt(qvv) from a reliability table, exact values only where needed"),
    "report": ("baarda.cli.report", "adjustment report: HTML (plots embedded) or text"),
    "residuals": ("baarda.cli.residuals", "post-processor: group statistics and histograms of "
                  "residuals listed by another program (see docs/report.md)"),
    "convert": ("baarda.cli.convert", f"convert {titles()} input (or a project, or a "
                "result folder) into a native project folder or, with --to, another "
                "program's files"),
    "models": ("baarda.cli.models", "independent-model block adjustment with data snooping "
               "and tests of model deformations (FOTEF)"),
    "simulate-models": ("baarda.cli.models", "simulate an independent-model block with "
                        "known truth (truth.json)"),
    "evaluate": ("baarda.cli.evaluate", "detection power, measured: blunder-detection "
                 "strategies on simulated blocks with planted blunders"),
    "compile": ("baarda.cli.compile", "compile the numerical kernels into numba's cache now "
                "(after installing)"),
    "check": ("baarda.cli.check", "check a result folder's invariants: sum of r = "
              "redundancy, sigma0 from every used observation, the global test, every RMS "
              "line"),
    "review": ("baarda.cli.review", "review a block in the browser: the suspicious "
               "observations, their image chips, reject / restore / re-measure / set aside, "
               "each answered by the test at once"),
    "screen": ("baarda.cli.screen", "pre-adjustment screening: photo pairs, strip formation, "
               "control; writes a cleaned project and the screening log"),
}


class Formatter(argparse.HelpFormatter):
    """Help that shows every option's default unless its text already says it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        d = action.default
        if ("default" in text or d is None or d is False or d is argparse.SUPPRESS
                or d == [] or action.const is not None and d is True):
            return text
        shown = " ".join(str(v) for v in d) if isinstance(d, (list, tuple)) else str(d)
        return f"{text} (default: {shown.replace('%', '%%')})"


class Parser(argparse.ArgumentParser):
    """argparse's parser, except that an option written `--opt=--` gives its type the text
    '--' (argparse drops it and hands the option an empty list, which no type checks)."""

    def _get_values(self, action, arg_strings):
        if arg_strings == ["--"] and action.option_strings and action.nargs is None:
            return self._get_value(action, "--")
        return super()._get_values(action, arg_strings)


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command; with `command`, only that command's module is imported
    and the others are named with their one-line help (a fast `baarda --help`)."""
    parser = Parser(
        prog="baarda", description="Quality-controlled aerial triangulation: bundle adjustment, "
        "data snooping and reliability.", epilog=EXIT_CODES)
    parser.add_argument("--version", action="version", version=f"baarda {package_version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (module, text) in COMMANDS.items():
        if name in sub.choices:
            continue
        if command in (None, name) or COMMANDS.get(command, ("",))[0] == module:
            importlib.import_module(module).register(sub)
        else:
            sub.add_parser(name, help=text)
    for p in sub.choices.values():
        p.formatter_class = Formatter
    return parser


def _command(argv: list[str]) -> str:
    """The command named in `argv` ("" when none: top-level help or an error)."""
    return next((a for a in argv if not a.startswith("-")), "")


class Terminated(KeyboardInterrupt):
    """SIGTERM (what timeout, docker stop, systemd and Slurm send), handled as Ctrl-C: the run
    folder is discarded and the earlier run stays; exit 143."""


def _busy(frame) -> bool:
    """Whether an exception raised now could be lost or crash the process: numba compiles or
    loads a kernel (its compiler lock held), runs its own Python code inside a compiled
    function (a frame of numba or llvmlite on the stack: LLVM's callbacks, the unpickling of
    a kernel's constants) or Python imports a module (importlib's frames: a module lock's
    callback); an exception there is lost, turns into a SystemError or crashes the process."""
    lock = sys.modules.get("numba.core.compiler_lock")
    return (lock is not None and lock.global_compiler_lock.is_locked()) or _in_numba(frame)


def _in_numba(frame) -> bool:
    """Whether numba's or llvmlite's Python code, or importlib's, is on the stack of `frame`."""
    while frame is not None:
        name = frame.f_code.co_filename
        if (f"{os.sep}numba{os.sep}" in name or f"{os.sep}llvmlite{os.sep}" in name
                or name.startswith("<frozen importlib")):
            return True
        frame = frame.f_back
    return False


@contextmanager
def _safe_interrupts():
    """While a command runs in the main thread: Ctrl-C (SIGINT) raises KeyboardInterrupt and
    SIGTERM raises Terminated, except while `_busy`: then the exception comes 50 ms later
    (a timer, SIGALRM), again until numba or the import is done.  Only signals whose
    handlers are Python's defaults are taken over (another program's handler stays in
    charge); the handlers before are restored."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[type[BaseException]] = []

    def handle(signum, frame) -> None:
        if signum == signal.SIGTERM:
            pending.append(Terminated)
        elif signum == signal.SIGINT:
            pending.append(KeyboardInterrupt)
        if not pending:
            return  # a timer of nothing pending
        if _busy(frame):
            signal.setitimer(signal.ITIMER_REAL, 0.05)
            return
        exc = Terminated if Terminated in pending else KeyboardInterrupt
        pending.clear()
        raise exc

    ours = []
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        ours.append(signal.SIGINT)
    if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
        ours.append(signal.SIGTERM)
    if not ours:
        yield
        return
    before = {s: signal.signal(s, handle) for s in [*ours, signal.SIGALRM]}
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        for s, h in before.items():
            signal.signal(s, h)


def _tolerant_streams() -> None:
    """Standard output and error that cannot encode a character (PYTHONIOENCODING=ascii, a
    Latin-1 terminal) write it as an escape instead of failing."""
    import codecs

    for stream in (sys.stdout, sys.stderr):
        try:
            utf8 = codecs.lookup(stream.encoding or "utf-8").name.startswith("utf")
        except (AttributeError, LookupError, TypeError):
            continue
        if not utf8 and getattr(stream, "errors", "strict") == "strict" and \
                hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")


def main(argv: list[str] | None = None, closed: list[str] | None = None) -> int:
    """Run one command; the exit code (cli/common.py EXIT_CODES): 0 success, 2 bad input
    (a message names the file, line and field, the option, or the geometry), 3 not
    converged (results written and marked), 4 the results could not be written (the file
    named), 130 interrupted (Ctrl-C), 143 terminated (SIGTERM); after 4, 130 and 143 the
    output folder holds the earlier run as it was and no staging folder is left."""
    from baarda.process import closed_streams

    closed = [*(closed or []), *closed_streams()]
    argv = sys.argv[1:] if argv is None else list(argv)
    _tolerant_streams()
    parser = build_parser(_command(argv))
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # argparse's error (printed): a bad option is bad input
        if e.code == BAD_INPUT:
            return BAD_INPUT
        raise  # --help, --version
    args.argv = argv
    con = console(args)
    if "stdout" in closed:
        con.stdout_failed = "standard output is closed"
        if not getattr(args, "prints_results", False):
            con.warn("standard output is closed: the printout is lost (the files are "
                     "written)")
    stdout, sys.stdout = sys.stdout, GuardedStdout(sys.stdout, con)
    try:
        with _safe_interrupts():
            code = int(args.func(args) or 0)
        if con.stdout_failed and getattr(args, "prints_results", False):
            _error(f"baarda: error: could not write the results to standard output "
                   f"({con.stdout_failed})")
            return WRITE_FAILED
        return code
    except (ProjectError, GeometryError) as e:
        _error(f"baarda: error: {e}")
        return BAD_INPUT
    except (MemoryError, ImportError) as e:  # ulimit -v; pyarrow's ArrowMemoryError too
        from baarda.process import memory_limit_text, out_of_memory

        if not out_of_memory(e):
            raise
        detail = f": {e}" if str(e) else ""
        _error(f"baarda: error: out of memory{memory_limit_text()}{detail}; nothing of this "
               "run was written")
        return WRITE_FAILED
    except OSError as e:
        from baarda.process import memory_limit_text

        if e.errno == errno.ENOMEM or (e.errno is None and not isinstance(e, OutputError)
                                       and memory_limit_text()):  # a library not loaded
            _error(f"baarda: error: out of memory{memory_limit_text()}: {e}; nothing of "
                   "this run was written")
            return WRITE_FAILED
        if isinstance(e, OutputError) or e.errno in WRITE_ERRNOS:
            where = f"{e.filename}: " if e.filename else ""
            _error(f"baarda: error: could not write the results: {where}{e.strerror or e}")
            return WRITE_FAILED
        where = f"{e.filename}: " if e.filename else ""  # a file that cannot be read
        _error(f"baarda: error: {where}{e.strerror or e}")
        return BAD_INPUT
    except Terminated:
        _error(f"\nbaarda: terminated by SIGTERM ({_what_was_written(con)})")
        return TERMINATED
    except KeyboardInterrupt:
        _error(f"\nbaarda: interrupted ({_what_was_written(con)})")
        return INTERRUPTED
    except Exception as e:  # under ulimit -v, libraries fail in their own words
        from baarda.process import memory_limit_text

        limit = memory_limit_text()
        if not limit:
            raise
        _error(f"baarda: error: out of memory{limit}: {type(e).__name__}: {e}; nothing of "
               "this run was written")
        return WRITE_FAILED
    finally:
        con.close()
        sys.stdout = stdout


def _what_was_written(con) -> str:
    """What an interrupted command leaves: nothing, or its results complete."""
    if con.results_in_place is None:
        return "nothing of this run was written"
    return (f"after the results were written: {con.results_in_place} holds this run, "
            "complete; what was still to be printed is lost")


def _error(text: str) -> None:
    try:
        print(text, file=sys.stderr, flush=True)
    except OSError:
        pass


if __name__ == "__main__":
    sys.exit(main())
