"""Helpers shared by the commands: progress display and output folder checks."""

from __future__ import annotations

import sys
import time
from pathlib import Path


def progress(quiet: bool):
    """A progress printer to stderr with elapsed time, or None when quiet."""
    if quiet:
        return None
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:7.1f} s] {msg}", file=sys.stderr, flush=True)

    return say


def check_output(out: Path, inputs: list[Path]) -> None:
    """Refuse to write results into an input folder (inputs are never overwritten)."""
    out = out.resolve()
    for p in inputs:
        if p.resolve() == out:
            raise FileExistsError(f"output folder {out} is the input folder; choose another "
                                  "with -o (inputs are never overwritten)")
