"""What a command tells its user, by verbosity (`-q` counted):

- standard output: the command's printout (summaries, tables): shown unless `-q`;
- standard error: the progress display (tqdm: a status line, or a bar with the ETA), only
  when standard error is a terminal and without `-q`; notes and warnings, and one closing
  line with the verdict: shown unless `-qq`.  Errors are always shown.

A standard output that fails (closed pipe, full disk) is a warning and is silenced from then
on: the results in the output folder are complete.  `Console.stdout_failed` tells the
command line whether it happened (for the commands whose printout is their result)."""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable
from pathlib import Path


def _isatty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


class GuardedStdout:
    """Standard output for the length of one command: a write or flush that fails (a closed
    pipe, a full disk) tells the console once (a warning, then silence) instead of raising
    in the middle of the command, so that every printout, also a plain print(), follows
    the one rule of the module docstring."""

    def __init__(self, stream, console: Console):
        self._stream = stream
        self._console = console

    def write(self, text: str) -> int:
        if self._console.stdout_failed:
            return len(text)
        try:
            return self._stream.write(text)
        except OSError as e:
            self._console._stdout_failed(e)
            return len(text)

    def flush(self) -> None:
        if self._console.stdout_failed:
            return
        try:
            self._stream.flush()
        except OSError as e:
            self._console._stdout_failed(e)

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


class Console:
    """The channels of one command run (module docstring); `quiet` 0, 1 (-q) or 2 (-qq)."""

    def __init__(self, quiet: int = 0):
        self.quiet = int(quiet or 0)
        self.stdout_failed: str | None = None
        #: the output folder this command has put its results in (an interruption after
        #: that says so instead of "nothing of this run was written")
        self.results_in_place: Path | None = None
        self._bar = None
        self._t0 = time.perf_counter()

    # ------------------------------------------------------------------ standard output
    def print(self, text: str = "", end: str = "\n") -> None:
        """The command's printout on stdout (not with -q)."""
        if self.quiet or self.stdout_failed:
            return
        self.close()
        try:
            sys.stdout.write(text + end)
            sys.stdout.flush()
        except OSError as e:
            self._stdout_failed(e)

    def _stdout_failed(self, e: OSError) -> None:
        self.stdout_failed = e.strerror or str(e)
        try:  # what is still buffered goes nowhere, also at exit (no second error there)
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            os.close(devnull)
        except (OSError, AttributeError, ValueError):
            pass
        self.warn(f"could not print to standard output ({self.stdout_failed}); the "
                  "printout is lost, the files written are complete")

    # ------------------------------------------------------------------ standard error
    def _err(self, text: str) -> None:
        try:
            if self._bar is not None:
                self._bar.write(text, file=sys.stderr)
            else:
                print(text, file=sys.stderr, flush=True)
        except OSError:
            pass  # nowhere left to say it

    def note(self, text: str) -> None:
        """A note on stderr (not with -qq)."""
        if self.quiet < 2:
            self._err(f"note: {text}")

    def warn(self, text: str) -> None:
        """A warning on stderr (not with -qq)."""
        if self.quiet < 2:
            self._err(f"baarda: warning: {text}")

    def verdict(self, command: str, text: str) -> None:
        """The one closing line of a command on stderr (not with -qq)."""
        self.close()
        if self.quiet < 2:
            self._err(f"baarda {command}: {text}")

    # ------------------------------------------------------------------ progress display
    def showing_progress(self) -> bool:
        return not self.quiet and _isatty(sys.stderr)

    def progress(self) -> Callable[[str], None] | None:
        """A function that shows a progress message on the status line, or None (with -q,
        or when stderr is not a terminal)."""
        if not self.showing_progress():
            return None

        def say(msg: str) -> None:
            bar = self._status()
            bar.set_description_str(msg, refresh=False)
            bar.refresh()

        return say

    def counter(self, what: str) -> Callable[[int, int], None] | None:
        """A function show(done, total) that shows a bar with the ETA, or None."""
        if not self.showing_progress():
            return None

        def show(done: int, total: int) -> None:
            bar = self._status(total, what)
            bar.update(done - bar.n)
            if done == total:
                bar.refresh()  # the last count shown, however soon it came

        return show

    def _status(self, total: int | None = None, unit: str = ""):
        from tqdm import tqdm

        if self._bar is None or (total is not None and self._bar.total != total):
            self.close()
            fmt = ("[{elapsed}] {desc}" if total is None else
                   "{l_bar}{bar}| {n_fmt}/{total_fmt} " + unit + " [{elapsed}<{remaining}]")
            self._bar = tqdm(total=total, file=sys.stderr, bar_format=fmt, leave=False,
                             dynamic_ncols=True, mininterval=0.2)
        return self._bar

    def close(self) -> None:
        """Remove the progress display (before the printout and at the end)."""
        if self._bar is not None:
            try:
                self._bar.close()
            except OSError:
                pass
            self._bar = None


def console(args) -> Console:
    """The console of a parsed command line (one made from its -q when it has none)."""
    c = getattr(args, "console", None)
    if c is None:
        c = Console(getattr(args, "quiet", 0))
        args.console = c
    return c
