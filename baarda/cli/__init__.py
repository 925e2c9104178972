"""Command line: a thin layer over the API.  Each command lives in its own module with
`register(subparsers)`; the module list below is the only place that knows them all."""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import threading
from contextlib import contextmanager

from baarda.errors import GeometryError, ProjectError
from baarda.output.run_folder import package_version

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
    "convert": ("baarda.cli.convert", "convert a COLMAP, BAL, DBAT, PhotoModeler, AICON, "
                "MicMac or OpenSfM input (or a project) into a native project folder"),
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


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command; with `command`, only that command's module is imported
    and the others are named with their one-line help (a fast `baarda --help`)."""
    parser = argparse.ArgumentParser(
        prog="baarda", description="Quality-controlled aerial triangulation: bundle adjustment, "
        "data snooping and reliability.", epilog="exit codes: 0 success, 2 bad input (the "
        "message names the file, line and field, or the geometry), 3 not converged (results "
        "written and marked NOT CONVERGED; also snooping stopped at its step limit), 5 an "
        "invariant of a result folder does not hold (baarda check), 130 interrupted "
        "(nothing written)")
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


def _interrupt(signum, frame) -> None:
    """Ctrl-C: KeyboardInterrupt, except while numba compiles or loads a kernel (its compiler
    lock held), runs its own Python code inside a compiled function (a frame of numba or
    llvmlite on the stack: LLVM's callbacks, the unpickling of a kernel's constants) or Python
    imports a module (importlib's frames: a module lock's callback): an exception there is
    lost, turns into a SystemError or crashes the process.  Then it comes 50 ms later, again
    until numba or the import is done."""
    lock = sys.modules.get("numba.core.compiler_lock")
    if (lock is not None and lock.global_compiler_lock.is_locked()) or _in_numba(frame):
        signal.setitimer(signal.ITIMER_REAL, 0.05)
        return
    raise KeyboardInterrupt


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
    """_interrupt as the handler of SIGINT (and of the timer that repeats it) while a command
    runs in the main thread; the handlers before it are restored."""
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield  # another program's handler (or none) stays in charge
        return
    before = signal.signal(signal.SIGINT, _interrupt), signal.signal(signal.SIGALRM, _interrupt)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGINT, before[0])
        signal.signal(signal.SIGALRM, before[1])


def main(argv: list[str] | None = None) -> int:
    """Run one command; the exit code: 0 success, 2 bad input (a message names the file,
    line and field, or the geometry), 3 not converged (results written and marked),
    130 interrupted (nothing half-written is left)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(_command(argv))
    args = parser.parse_args(argv)
    args.argv = argv
    try:
        with _safe_interrupts():
            return int(args.func(args) or 0)
    except (ProjectError, GeometryError) as e:
        print(f"baarda: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:  # a file that cannot be read or written (disk full, permissions)
        where = f"{e.filename}: " if e.filename else ""
        print(f"baarda: error: {where}{e.strerror or e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\nbaarda: interrupted (nothing of this run was written)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
