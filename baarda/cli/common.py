"""Helpers shared by the commands: progress display and output folder checks."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from baarda.errors import ProjectError
from baarda.options import TestOptions


def progress(quiet: bool):
    """A progress printer to stderr with elapsed time, or None when quiet."""
    if quiet:
        return None
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:7.1f} s] {msg}", file=sys.stderr, flush=True)

    return say


def tests_option(settings, args) -> TestOptions:
    """TestOptions from --alpha0/--beta0 over the project's settings; bad values are input
    errors."""
    try:
        return TestOptions.resolve(settings, getattr(args, "alpha0", None),
                                   getattr(args, "beta0", None))
    except ValueError as e:
        raise ProjectError("command line", str(e)) from None


def check_output(out: Path, inputs: list[Path]) -> None:
    """Refuse to write results into an input folder (inputs are never overwritten)."""
    out = out.resolve()
    for p in inputs:
        if p.resolve() == out:
            raise FileExistsError(f"output folder {out} is the input folder; choose another "
                                  "with -o (inputs are never overwritten)")


def add_flight_plan_arguments(p, d) -> None:
    """Options of a regular block shared by `simulate` and `plan` (defaults from FlightPlan d)."""
    p.add_argument("--strips", type=int, default=d.strips)
    p.add_argument("--photos", type=int, default=d.photos_per_strip, help="photos per strip")
    p.add_argument("--forward-overlap", type=float, default=d.forward_overlap)
    p.add_argument("--side-overlap", type=float, default=d.side_overlap)
    p.add_argument("--scale", type=float, default=d.image_scale, help="image scale 1:SCALE")
    p.add_argument("--focal", type=float, default=d.focal_mm, help="focal length in mm")
    p.add_argument("--format", type=float, default=d.format_mm, help="image format in mm")
    p.add_argument("--pattern", type=int, default=d.pattern, help="n x n points per photo")
    p.add_argument("--stereo", action="store_true", help="stereo mode (twin rays)")
